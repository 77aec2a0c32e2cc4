"""The ``optcal`` command line (click); each command lives in its own module."""
