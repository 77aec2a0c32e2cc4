"""Sun 2011: ten-position calibration of the accelerometers (and gyroscopes) of a SINS on a turntable.

A paper layer on top of the core: :mod:`optcal.applications.papers.sun2011.turntable` simulates the turntable session,
:mod:`optcal.applications.papers.sun2011.alignment` is the 10-state fine-alignment Kalman filter run at each position,
:mod:`optcal.applications.papers.sun2011.tenposition` the four-step scheme and the closed forms of eq. 28-30.
``optcal reproduce sun2011`` (:mod:`optcal.applications.papers.sun2011.reproduce`) runs the paper's Monte Carlo.
"""
