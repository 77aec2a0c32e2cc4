"""Applications of the magnetometer's calibration: its diagnosis (:mod:`~optcal.applications.magnetic.diagnosis`)."""
