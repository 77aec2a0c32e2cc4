"""Gyroscope calibration from the rotations between static poses (Tedaldi, Pretto, Menegatti, ICRA 2014).

* :mod:`optcal.core.gyro_model` — the gyro error model and its identifiable parameterisation.
* :mod:`optcal.families.gyro.moves` — the moves between consecutive static intervals of a recording.
* :mod:`optcal.families.gyro.propagation` — gravity direction carried across a move by the corrected
  gyro (exponential map with analytic sensitivities, numpy), the residual and the convention-free angle metric.
* :mod:`optcal.families.gyro.identifiability` — which rotation axes a recording excites.
* :mod:`optcal.families.gyro.estimator` — bias from the still intervals, scale and misalignment by
  IPOPT nonlinear least squares; the accelerometer fixed or estimated jointly.
* :mod:`optcal.families.gyro.consistency` — is a fitted gyro supported by the moves: the residual
  against a noise model, a gyro that sees the moves, axes and scale of a sensor (refused otherwise).
* :mod:`optcal.families.gyro.check` — a saved calibration's gravity prediction on other data, tested likewise.
* :mod:`optcal.families.gyro.result` — the whole-IMU calibration (``cal_type`` ``imu``).
* :mod:`optcal.families.simulate.gyro` — synthetic IMU recordings with known truth.
* :mod:`optcal.data.units` — the gyro units of a recording (counts, rad/s, °/s), decided from the data.
"""
