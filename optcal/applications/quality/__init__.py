"""Is a calibration good?  Held-out validation, the evidence and the verdict of the reports."""
