"""Findings: every effect of the final model with per-axis estimates, standard errors and evidence.

Estimates are first-order coefficients in the units of :data:`optcal.applications.diagnosis.effects.UNITS`
(higher orders in ``coefficients``), standard errors from the Fisher information with the
noise scale from the residuals; the evidence is that of dropping the effect from the final
model (ΔBIC, p value), and the held-out rms without and with it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from optcal.applications.diagnosis.effects import BIAS_STEP, CAUSE_STEPS, CAUSES, PARAMETRIC, SESSION_BIAS, UNITS
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.problem import BETA_INDEX, active_mask
from optcal.applications.diagnosis.acceptance import BIC_TIE
from optcal.applications.diagnosis.selection import Step
from optcal.core.model import AXES
from optcal.core.stats import rms

if TYPE_CHECKING:
    from optcal.applications.diagnosis.sessions import SessionOffsets


@dataclass
class Evidence:
    """Evidence for an effect: ΔBIC of the final model against the model without it, and the p value."""

    delta_bic: float
    p_value: float


@dataclass
class Finding:
    """One effect of the final model (JSON ``findings[]``).

    Attributes
    ----------
    effect : str
    axes : list of str
        Axes carrying it (empty for outliers).
    estimate, stderr : dict of str to float
        First-order coefficient and its standard error per axis (units :attr:`units`).
    units : str
    cause : str
        The physical cause, in plain words.
    evidence : Evidence
    heldout_rms_g_before, heldout_rms_g_after : float
        Held-out rms of the final model without and with the effect.
    order : dict of str to int
        Polynomial order per axis.
    coefficients : dict of str to list of float
        Coefficients of orders 1.. per axis (units/°C^p, /s^p).
    reference : dict of str to float
        ``temp_ref_c`` or ``t_ref_s``: where the polynomial is centred.
    rows : list of int or None
        For outliers, the rows given zero weight (each file's own row numbers).
    row_sessions : list of str or None
        For outliers in several sessions diagnosed together: the session (file) of each row.
    pose_index : list of int or None
        For outliers: their positions among the diagnosed poses (unique across sessions).
    alternatives : list of dict
        Terms the data cannot tell apart from this one (:func:`alternatives`): each ``{"effect", "axes", "order",
        "term", "delta_bic", "p_value"}`` as tried in the step that named this effect; empty when none.
    sensor : str
        The sensor the effect belongs to (``accelerometer``: the pose diagnosis; JSON ``"sensor"``, so that one
        list of findings can hold a gyroscope's too).
    change_over_data : dict of str to float
        Peak-to-peak change of the term over the fitted poses per axis: g for a bias term,
        relative for a scale term, g at 1 g for the nonlinearity (what the polynomial does,
        whatever its order); the range of the sessions' biases for ``session_bias``.
    step : dict or None
        For ``bias_step``: where the step is, ``{"poses_before"`` (poses before it in time order),
        ``"pose_index"`` (the first pose after it, among the diagnosed poses), ``"row"`` (that pose's row),
        ``"previous_row"`` (the last pose's before it), ``"t_s"`` and ``"previous_t_s"`` (their times, when the
        poses have a time column)``}``; :attr:`estimate` is the step of each axis's bias (g, after minus before).
        With a second step (a knock, then another; :data:`~optcal.applications.diagnosis.effects.MAX_STEPS`) those
        keys are the first step's, and ``"steps"`` lists each step's keys with its ``"estimate"`` (axis → g, after
        minus before that step, for the axes it moved in the model); :attr:`coefficients` holds them per axis, and
        :attr:`estimate` (with :attr:`stderr`) each axis's larger step: a knock on x and a later one on y read
        ``{"x": the x knock, "y": the y knock}``.
    sessions : SessionOffsets or None
        For ``session_bias``: every session's offset with its standard error; :attr:`estimate`
        is then their spread (the turn-on repeatability, g) and :attr:`stderr` the sampling
        error of that spread, ``spread/√(2(S − 1))``.
    """

    effect: str
    axes: list[str]
    estimate: dict[str, float]
    stderr: dict[str, float]
    units: str
    cause: str
    evidence: Evidence
    heldout_rms_g_before: float
    heldout_rms_g_after: float
    order: dict[str, int] = field(default_factory=dict)
    coefficients: dict[str, list[float]] = field(default_factory=dict)
    reference: dict[str, float] = field(default_factory=dict)
    rows: list[int] | None = None
    change_over_data: dict[str, float] = field(default_factory=dict)
    sessions: "SessionOffsets | None" = None
    row_sessions: list[str] | None = None
    pose_index: list[int] | None = None
    sensor: str = "accelerometer"
    alternatives: list[dict[str, Any]] = field(default_factory=list)
    step: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("rows", "row_sessions", "pose_index", "step"):
            if out[key] is None:
                del out[key]
        if self.sessions is None:
            del out["sessions"]
        return out


def reference_of(fitter: Fitter, effect: str) -> dict[str, float]:
    """Where an effect's polynomial is centred."""
    if effect.startswith("temperature"):
        return {"temp_ref_c": fitter.reg.temp_ref}
    if effect == "bias_drift":
        return {"t_ref_s": fitter.reg.t_ref}
    return {}


def change_over_data(fitter: Fitter, fit: Fit, effect: str, axis: int) -> float:
    """Peak-to-peak of a term's polynomial over the kept poses (normalised regressor, so no unit juggling)."""
    if effect in ("scale_nonlinearity", BIAS_STEP):
        return abs(float(fit.x[9 + BETA_INDEX[(effect, axis, 1)]]))
    values = (fitter.reg.tau if effect.startswith("temperature") else fitter.reg.s)[fit.kept(fitter.n)]
    order = fit.terms[(effect, axis)]
    term = sum(fit.x[9 + BETA_INDEX[(effect, axis, p)]] * values**p for p in range(1, order + 1))
    return float(np.ptp(term))


def step_location(fitter: Fitter, k: int) -> dict[str, Any]:
    """Where a bias step of the fitter's model is, after the first ``k`` poses in time order (:attr:`Finding.step`)."""
    after, before = int(fitter.time_order[k]), int(fitter.time_order[k - 1])
    out: dict[str, Any] = {"poses_before": int(k), "pose_index": after, "row": int(fitter.poses.rows[after]),
                           "previous_row": int(fitter.poses.rows[before])}
    if fitter.reg.has_time and fitter.poses.t is not None:
        out["t_s"], out["previous_t_s"] = float(fitter.poses.t[after]), float(fitter.poses.t[before])
    return out


def alternatives(steps: list[Step], final: Fit, effect: str, axis: str) -> list[dict[str, Any]]:
    """The terms the data cannot tell apart from ``effect`` on ``axis``, in the step that named it.

    A term tried in that step whose BIC is within :data:`~optcal.applications.diagnosis.acceptance.BIC_TIE` of the
    named one's (equal numbers of coefficients: a likelihood ratio under e³ ≈ 20, short of Kass & Raftery's
    "strong" evidence either way) explains the change about as well: a temperature rising through the session
    makes a temperature bias, a temperature scale and a drift on one axis nearly collinear, and a 14-rest session's
    poses can leave x and y biases close.  Each is listed (best order per effect and axis), unless it is in the final
    model itself, made the BIC worse, or was set aside by the held-out test or stepped down to an order listed.
    """
    for step in steps:
        chosen = step.accepted
        if chosen is None or chosen.effect != effect or chosen.axis != axis:
            continue
        best: dict[tuple[str, str | None], Any] = {}
        for c in step.candidates:
            key = (c.effect, c.axis)
            if (c is chosen or key == (effect, axis) or c.effect == "outliers" or c.rejected_because is not None
                    or c.axis is None or (c.effect, AXES.index(c.axis)) in final.terms
                    or not c.delta_bic < min(0.0, chosen.delta_bic + BIC_TIE)):
                continue
            if key not in best or c.delta_bic < best[key].delta_bic:
                best[key] = c
        return [{"effect": c.effect, "axes": [c.axis], "order": c.order, "term": c.term, "delta_bic": c.delta_bic,
                 "p_value": c.p_value} for c in sorted(best.values(), key=lambda c: c.delta_bic)]
    return []


def build_findings(fitter: Fitter, final: Fit, steps: list[Step], session_names: Sequence[str] = ()) -> list[Finding]:
    """One finding per effect of the final model, with the evidence of dropping it (``session_names``: one per session)."""
    out: list[Finding] = []
    cov = fitter.covariance(final)
    free_beta = np.flatnonzero(active_mask(final.terms))
    position = {int(b): 9 + i for i, b in enumerate(free_beta)}
    bic_final = fitter.bic(final)
    mask = final.kept(fitter.n)
    after = rms(fitter.heldout(final), mask)
    for effect in (*PARAMETRIC, BIAS_STEP):
        axes = sorted(a for (e, a) in final.terms if e == effect)
        if not axes:
            continue
        without = fitter.fit({k: v for k, v in final.terms.items() if k[0] != effect}, final.outliers, final.x)
        h = fitter.reg.half_span(effect)
        finding = Finding(
            effect, [AXES[a] for a in axes], {}, {}, UNITS[effect], CAUSES[effect],
            Evidence(bic_final - fitter.bic(without), fitter.f_test(without, final)),
            rms(fitter.heldout(without), mask), after, reference=reference_of(fitter, effect),
        )
        for a in axes:
            b = BETA_INDEX[(effect, a, 1)]
            if effect == BIAS_STEP and final.terms[(effect, a)] > 1:
                # two steps: the axis's own knock, the larger of its offsets (a second axis carries an offset at
                # the first step's place as well, about zero where only the second knock moved it)
                b = max((BETA_INDEX[(effect, a, i)] for i in range(1, final.terms[(effect, a)] + 1)),
                        key=lambda k: abs(float(final.x[9 + k])))
            finding.estimate[AXES[a]] = float(final.x[9 + b] / h)
            finding.stderr[AXES[a]] = float(np.sqrt(max(cov[position[b], position[b]], 0.0)) / h)
            finding.order[AXES[a]] = final.terms[(effect, a)]
            finding.coefficients[AXES[a]] = [
                float(final.x[9 + BETA_INDEX[(effect, a, p)]] / h**p) for p in range(1, final.terms[(effect, a)] + 1)
            ]
            finding.change_over_data[AXES[a]] = change_over_data(fitter, final, effect, a)
            finding.alternatives += alternatives(steps, final, effect, AXES[a])
        if effect == BIAS_STEP:
            finding.step = step_location(fitter, fitter.steps_at[0])
            if len(fitter.steps_at) > 1:  # each step where it is and its offset on each axis (g, after minus before)
                finding.cause = CAUSE_STEPS
                finding.step["steps"] = [
                    {**step_location(fitter, k), "estimate": {AXES[a]: float(final.x[9 + BETA_INDEX[(effect, a, i)]])
                                                             for a in axes if final.terms[(effect, a)] >= i}}
                    for i, k in enumerate(fitter.steps_at, start=1)]
            # each position is a fitted unknown (selection)
            finding.evidence.delta_bic += len(fitter.steps_at) * float(np.log(fitter.n))
        out.append(finding)
    session_axes = sorted(a for (e, a) in final.terms if e == SESSION_BIAS)
    if session_axes:
        from optcal.applications.diagnosis.sessions import session_offsets

        names = list(session_names) or [f"session {k + 1}" for k in range(fitter.reg.n_sessions)]
        offsets = session_offsets(fitter, final, names)
        assert offsets is not None
        without = fitter.fit({k: v for k, v in final.terms.items() if k[0] != SESSION_BIAS}, final.outliers, final.x)
        finding = Finding(
            SESSION_BIAS, [AXES[a] for a in session_axes], dict(offsets.repeatability_g), {}, UNITS[SESSION_BIAS],
            CAUSES[SESSION_BIAS], Evidence(bic_final - fitter.bic(without), fitter.f_test(without, final)),
            rms(fitter.heldout(without), mask), after, sessions=offsets,
        )
        for axis in offsets.axes:
            finding.stderr[axis] = offsets.repeatability_g[axis] / np.sqrt(2 * (fitter.reg.n_sessions - 1))
            finding.order[axis] = fitter.reg.n_sessions - 1
            finding.change_over_data[axis] = float(np.ptp(offsets.offsets_g[axis]))
        out.append(finding)
    if final.outliers:
        without = fitter.fit(final.terms, frozenset(), final.x)
        p_values = [s.accepted.p_value for s in steps if s.accepted and s.accepted.effect == "outliers"]
        out.append(Finding(
            "outliers", [], {}, {}, UNITS["outliers"], CAUSES["outliers"],
            Evidence(bic_final - fitter.bic(without), float(min(p_values)) if p_values else 0.0),
            rms(fitter.heldout(without), mask), after,
            rows=[int(fitter.poses.rows[k]) for k in sorted(final.outliers)],
            row_sessions=None if fitter.reg.n_sessions < 2 else [
                (list(session_names) or [f"session {j + 1}" for j in range(fitter.reg.n_sessions)])[
                    int(fitter.reg.session[k])] for k in sorted(final.outliers)],
            pose_index=[int(k) for k in sorted(final.outliers)],
        ))
    return out
