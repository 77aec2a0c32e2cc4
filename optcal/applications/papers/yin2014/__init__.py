"""Yin 2014: six-position calibration, Allan-variance noise analysis and an EKF for compensation.

A paper layer on top of the core: :mod:`optcal.families.noise.allan` reads velocity random walk, bias
instability and rate random walk off a static log (section 2.2), :mod:`optcal.applications.papers.yin2014.ekf` is the
compensation filter (eqs. 7-13).  The six-position least squares itself (eq. 3-4) is the core
estimator :mod:`optcal.families.accel.sixpos`; ``optcal reproduce yin2014``
(:mod:`optcal.applications.papers.yin2014.reproduce`) runs the paper's experiments.
"""
