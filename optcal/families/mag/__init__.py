"""The magnetometer: hard and soft iron as the accelerometer's ellipsoid problem, aligned with gravity.

:func:`optcal.families.mag.samples.read_mag` reads the samples, :func:`optcal.families.mag.calibration.calibrate_mag`
fits them (:mod:`optcal.families.mag.fit`: the convex fit, maximum likelihood and the baseline
of :mod:`optcal.families.accel`, reduced forms by evidence) and estimates the dip and the
frames' rotation (:mod:`optcal.families.mag.dip`).
"""
