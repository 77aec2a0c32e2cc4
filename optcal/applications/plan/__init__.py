"""Pose planning: which orientations to take, and which one to take next.

Optimal experiment design for the lumped model (Lu 2017) with the gravity directions as
nuisance parameters: the Fisher information of :mod:`optcal.core.identifiability`, a convex
relaxation over candidate directions in cvxpy (D, A or E criterion) with a certified bound,
rounding to K poses and refinement on the sphere in CasADi/IPOPT (:func:`plan_poses`), and
the next best pose after the poses taken so far (:func:`next_pose`).
"""

from optcal.applications.plan.candidates import Cap, CandidateSet, given_candidates, sphere_candidates, turntable_candidates
from optcal.applications.plan.information import Criterion, Prior
from optcal.applications.plan.next_pose import NextPose, next_pose
from optcal.applications.plan.planner import PosePlan, plan_poses

__all__ = [
    "CandidateSet",
    "Cap",
    "Criterion",
    "NextPose",
    "PosePlan",
    "Prior",
    "given_candidates",
    "next_pose",
    "plan_poses",
    "sphere_candidates",
    "turntable_candidates",
]
