"""optcal's calibration problems as formulations a user can take out and solve with any solver.

Each builder takes the data of one problem and returns a
:class:`~optcal.solvers.formulation.Formulation` (an NLP: variables, parameters, objective,
constraints, bounds, scaling, the equation it comes from) or, for the convex ellipsoid fit, a
:class:`~optcal.solvers.formulation.ConicFormulation` (a cvxpy problem).  They are the problems
the estimators solve, built by the same functions (:func:`optcal.families.accel.mle.ml_nlp`, the
convex problem of :mod:`optcal.families.accel.ellipsoid`, the prior problem of
:mod:`optcal.applications.fleet.prior`, the callbacks of the gyroscope and of the pose planner):

=========================  ===================================================  =================================
builder                    problem                                              source
=========================  ===================================================  =================================
:func:`convex_fit`         ``min ‖Rη‖²`` s.t. ``A ⪰ εI``, ``tr A = 3``          Lu 2017, eq. 18-23 (cvxpy)
:func:`norm_residual_ml`   ``min c Σ ρ(√w_k r_k(θ))``, ``r_k = ‖T(a_k−o)‖−1``  Lu 2017, eq. 13-14 (+ losses, user constraints)
:func:`exact_ml`           ``min Σ w_k ‖a_k − o − C ā_k‖²`` s.t. ``‖ā_k‖ = 1``  Lu 2017, eq. 8 (errors in variables)
:func:`gyroscope`          ``min ½ c Σ ‖v_j(T_g) − u_j‖²`` over the moves         Tedaldi 2014, eq. 20-22
:func:`fleet_prior`        ``min c [Σ w_k r_k² + ‖L(θ − μ)‖²]``                  eq. 14 + −2 log of the population prior
:func:`pose_refinement`    ``max Φ(Σ h(d_k) h(d_k)ᵀ)`` s.t. ``‖d_k‖ = 1``        optimal design on the sphere
=========================  ===================================================  =================================

Example::

    from optcal.problems import norm_residual_ml
    problem = norm_residual_ml(poses)
    print(problem.describe())
    for solver in ("ipopt", "sqpmethod", "fatrop"):
        print(solver, problem.solve(solver).x)
"""

from optcal.problems.accel import convex_fit, exact_ml, norm_residual_ml, theta_of
from optcal.problems.others import fleet_prior, gyroscope, pose_refinement

__all__ = ["convex_fit", "exact_ml", "fleet_prior", "gyroscope", "norm_residual_ml", "pose_refinement", "theta_of"]
