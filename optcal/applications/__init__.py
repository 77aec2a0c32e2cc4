"""Layer 5, applications: quality assessment, diagnosis, pose planning, fleets, exporters and
the paper reproductions, built on the sensor families below."""
