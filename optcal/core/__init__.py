"""Layer 1, core maths: numpy and scipy only (and :mod:`optcal.errors`).

The lumped model and its θ packing, the extended model, the gyro error model, unit tables,
rotations, small statistics, the norm-residual kernel, identifiability, the chain covariance,
the pose table and the fit-result base.  Nothing here reads a file, builds a solver or prints.
"""
