"""The pose plan as a readable page (``optcal plan --report FILE.html``).

The recommended poses as a sphere map (:func:`optcal.report.plan_figure.sphere_figure`) and a table a
person can follow (which axis points up, the tilt from vertical, the description of
:mod:`optcal.applications.plan.describe`, the gravity direction), the design criterion and its value against
the certified bound, and the expected standard error of every parameter at the planning noise,
before and after the plan when it adds poses to a session (:class:`optcal.applications.plan.PosePlan`), or
before and after the next pose (:class:`optcal.applications.plan.NextPose`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import AXES, PARAM_NAMES
from optcal.applications.plan import NextPose, PosePlan, Prior
from optcal.applications.plan.describe import describe_direction
from optcal.report.document import ReportDocument, Section, Table, now_utc, significant, versions
from optcal.report.figures import EmbeddedFigure, embed
from optcal.applications.quality.verdict import judge_next_pose, judge_plan

#: The criteria in words.
CRITERION_WORDS: dict[str, str] = {
    "D": "D-optimal: the largest log det of the Fisher information (the smallest confidence ellipsoid of all nine parameters)",
    "A": "A-optimal: the smallest trace of the inverse information (the sum of the parameter variances)",
    "E": "E-optimal: the largest smallest eigenvalue of the information (the worst-determined combination)",
}


def orientation_rows(directions: NDArray[np.float64], labels: list[str] | None = None) -> list[list[str]]:
    """One row per pose: number, axis up, tilt from vertical, how to hold it, gravity direction (and gimbal angles)."""
    rows = []
    for k, d in enumerate(np.asarray(directions, float).reshape(-1, 3)):
        d = d / np.linalg.norm(d)
        main = int(np.argmax(np.abs(d)))
        tilt = float(np.rad2deg(np.arccos(min(abs(d[main]), 1.0))))
        row = [str(k + 1), ("+" if d[main] > 0 else "−") + AXES[main], f"{tilt:.0f}", describe_direction(d),
               f"{d[0]:+.3f}, {d[1]:+.3f}, {d[2]:+.3f}"]
        rows.append(row + ([labels[k]] if labels else []))
    return rows


def _orientation_table(directions: NDArray[np.float64], labels: list[str] | None) -> Table:
    header = ["pose", "axis pointing up", "tilt from vertical (°)", "how to hold it", "gravity direction (x, y, z)"]
    return Table(header + (["turntable gimbals"] if labels else []), orientation_rows(directions, labels),
                 "Put the device down still in each orientation; 'x up, tilted 35° toward −y' means: x pointing up, "
                 "then turn it so that −y rises by 35°")


def _stderr_table(before: dict[str, float], after: dict[str, float], prior: Prior, before_label: str,
                  after_label: str) -> Table:
    """Expected standard errors in the prior's raw units, and relative (T entries in % of the scale, o in mg)."""
    relative = 1.0 / np.diag(prior.to_raw)  # raw → normalised: T relative to the scale, o in g
    rows = []
    for i, p in enumerate(PARAM_NAMES):
        cells = [p, (f"g/{prior.units}" if prior.units != "g" else "1") if i < 6 else prior.units]
        for values in ((before,) if before else ()) + (after,):
            x = values[p]
            words = f"{100 * x * relative[i]:.3g} %" if i < 6 else f"{1e3 * x * relative[i]:.3g} mg"
            cells.append(f"{significant(x, 3)} ({words})" if np.isfinite(x) else "not determined")
        rows.append(cells)
    return Table(["parameter", "unit", *([before_label] if before else []), after_label], rows,
                 "Expected standard error of each entry of T (lower triangle) and o; in brackets: T in % of the "
                 "sensor's scale, o in mg")


def _map(planned: NDArray, given: NDArray, candidates: NDArray | None, cap: Any, title: str) -> EmbeddedFigure:
    from optcal.report.plan_figure import sphere_figure

    return embed(sphere_figure(planned, given if len(given) else None, candidates, cap, title),
                 "Sphere map: the gravity direction of each pose in the sensor frame, both hemispheres (equal-area); "
                 "planned poses numbered as in the table, poses already taken as crosses")


def plan_document(plan: PosePlan | NextPose, prior: Prior, command: str, candidates: NDArray | None = None,
                  cap: Any = None, given_from: str = "") -> ReportDocument:
    """Report of ``optcal plan``: the poses to take, the design and the expected standard errors.

    Parameters
    ----------
    plan : PosePlan or NextPose
        From :func:`optcal.applications.plan.plan_poses` (``--poses K``) or :func:`optcal.applications.plan.next_pose` (``--next DATA``).
    prior : Prior
        The sensor it was planned for (its scale turns the standard errors into relative terms).
    command : str
        The exact command line.
    candidates : ndarray, shape (m, 3), optional
        A fixed set of feasible directions to show on the map.
    cap : optcal.applications.plan.Cap, optional
        The constraint cap to draw.
    given_from : str
        The file of the poses already taken.
    """
    noise = f"pose noise σ = {significant(plan.sigma, 3)} {plan.units} per axis"
    if isinstance(plan, NextPose):
        verdict = judge_next_pose(plan)
        directions, labels = plan.direction[None, :], [plan.label] if plan.label else None
        gain = (f"{plan.gain_logdet:.4g}" if np.isfinite(plan.gain_logdet)
                else f"∞ (the rank of the information goes from {plan.rank_before} to {plan.rank_after} of 9)")
        design = Section("The next pose", [
            f"After the {plan.n_poses} poses in {given_from or 'the data'}, the one orientation that adds the most "
            f"information (D criterion, the matrix determinant lemma): {plan.description}.",
            f"Expected gain in log det of the Fisher information: {gain}. Prior: {plan.prior_source}; {noise}.",
        ] + ([f"Target standard error {plan.target_stderr:g} (normalised): "
              + (plan.stop_message if plan.stop else "not reached yet, continue.")] if plan.target_stderr is not None else []),
            [_orientation_table(directions, labels)],
            [_map(directions, plan.given_directions, candidates, cap, "the next pose (1) after the poses taken (×)")])
        errors = Section("Expected standard errors", [
            f"At {noise}: with the poses taken, and with the next pose added."],
            [_stderr_table(plan.stderr_before, plan.stderr_after, prior, "now", "with the next pose")])
        title = f"Next pose after {given_from or 'the poses taken'}"
    else:
        verdict = judge_plan(plan)
        name = {"D": "log det M", "A": "−tr M⁻¹", "E": "λ_min(M)"}[plan.criterion.value]
        after_given = f" after the {plan.n_given} poses already taken in {given_from or 'the data'}" if plan.n_given else ""
        design = Section("Poses to take", [
            f"{plan.n_poses} orientations{after_given}, chosen for the lumped model (Lu 2017) with the gravity "
            f"directions as nuisance parameters. Criterion: {CRITERION_WORDS[plan.criterion.value]}.",
            f"{name} (normalised units, unit noise): {plan.value:.6g} for the plan; {plan.relaxation_value:.6g} for the "
            f"convex relaxation over the grid ({plan.solver}); no {plan.n_poses} poses can exceed {plan.bound:.6g}. "
            f"Efficiency against that bound: {100 * plan.efficiency:.2f} %. Refinement on the sphere: {plan.refinement}.",
            f"Feasible set: {plan.feasible_set}"
            + (f" ({plan.excluded_candidates} directions outside the cap excluded)" if plan.excluded_candidates else "")
            + f". Prior: {plan.prior_source}.",
        ], [_orientation_table(plan.directions, plan.labels or None)],
            [_map(plan.directions, plan.given_directions, candidates, cap, "")])
        before = plan.stderr_given if plan.n_given else {}
        errors = Section("Expected standard errors", [
            f"At {noise}" + (": from the poses already taken alone, and with the plan added." if before else
                             " with the planned poses.")],
            [_stderr_table(before, plan.stderr, prior, "poses taken alone", "with the plan")])
        title = f"Plan of {plan.n_poses} poses" + (f" after {given_from}" if plan.n_given and given_from else "")
    return ReportDocument(title, given_from or "pose plan", verdict, [design, errors], command, versions(), now_utc())


__all__ = ["CRITERION_WORDS", "orientation_rows", "plan_document"]
