"""Layer 4, sensor families: the estimators and the calibrations they produce.

``accel`` (accelerometer estimators), ``gyro`` (gyroscope calibration from the moves),
``caltypes`` (saved calibrations and how they apply), ``noise`` (Allan analysis of both
sensors) and ``simulate`` (recordings and pose tables with known truth).
"""
