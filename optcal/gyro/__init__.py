"""Gyroscope calibration from the rotations between static poses (Tedaldi, Pretto, Menegatti, ICRA 2014).

* :mod:`optcal.gyro.model` — the gyro error model and its identifiable parameterisation.
* :mod:`optcal.gyro.moves` — the moves between consecutive static intervals of a recording.
* :mod:`optcal.gyro.propagation` — gravity direction carried across a move by the corrected
  gyro (exponential map with analytic sensitivities, numpy), the residual and the convention-free angle metric.
* :mod:`optcal.gyro.identifiability` — which rotation axes a recording excites.
* :mod:`optcal.gyro.estimator` — bias from the still intervals, scale and misalignment by
  IPOPT nonlinear least squares; the accelerometer fixed or estimated jointly.
* :mod:`optcal.gyro.result` — the whole-IMU calibration (``cal_type`` ``imu``).
* :mod:`optcal.gyro.simulate` — synthetic IMU recordings with known truth.
* :mod:`optcal.gyro.units` — gyro units (counts, rad/s, °/s).
"""
