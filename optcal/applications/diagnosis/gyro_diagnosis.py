"""The gyroscope's diagnosis: the fitted IMU model's gravity prediction across the moves against its noise band,
the cause named by forward selection, the extended model fitted in CasADi, the gain on held-out moves.

1. **The band.**  Each move's gravity-prediction angle under the paper's model (Tedaldi 2014, eq. 13-14) against
   that model simulated along the recorded moves with the measured noise (:func:`simulated_move_rad2`; with no
   simulations, the linearised noise model of :func:`optcal.families.gyro.consistency.residual_budget`): the
   angle's two components across gravity are normal with variance ``E/2`` each, ``E`` the simulated mean square,
   so the angle exceeds ``√(E ln(m/α))`` with probability ``α/m`` (Rayleigh), and a move beyond that bound leaves
   the band at the family-wise level ``α`` over the ``m`` moves.
2. **The candidates** (:mod:`~optcal.applications.diagnosis.gyro_problem`), per gyro axis: ``g_sensitivity`` (the
   axis' rate error linear in the specific force, a row of ``G``), ``gyro_scale_nonlinearity`` (``ω + s ω²``),
   ``gyro_temperature_bias`` (with a temperature column), ``gyro_bias_drift``; and ``time_offset`` (the gyro's
   stream against the accelerometer's).  Forward selection as the accelerometer's: at each step every remaining
   term is fitted from the current model, the one with the largest likelihood ratio is named when it passes all
   three of the likelihood-ratio test (the moves' and the rests' noise scales profiled: a scatter beyond the noise
   model is absorbed by its scale, not read as an effect), at the step's Bonferroni share of ``α``; the Bayesian
   information criterion; and the held-out units (k-fold over the moves and the rests): their paired improvement
   must hold unit after unit (Student's t), and so must the improvement of the gravity prediction on the moves it
   was not fitted to (the gain) by itself -- a term the rests' means carry but the moves do not is not named: each
   held-out gain must exceed its paired standard error (:func:`~optcal.core.stats.mean_and_se`, the held-out units
   as the independent units) by Student's one-sided quantile at :data:`HELDOUT_LEVEL` (about 1.7 of them: the
   likelihood ratio draws on the rests too, so the moves' held-out t is the terms' one test on the moves alone), and
   the report states the gain, its standard error and t (``optcal diagnose --gyro-heldout-se K``: K standard errors
   instead, for every gyro finding).  A g-sensitivity, which the rests measure and a move sees only integrated
   over it, may be confirmed instead by the held-out moves' response to it (:func:`moves_response`: linear in their
   noise, where the angles' gain is second order) beyond the same quantile (:data:`G_EVIDENCE`,
   ``--gyro-g-evidence``).  The chosen model is
   refitted by IPOPT in CasADi.
3. **The time offset** shows inside the moves, not at their ends (a move's whole turn is the same whichever way
   its samples are shifted): along each move the gravity direction the gyro predicts, ``û(t)``, against the
   accelerometer's, ``â(t)``; a gyro whose samples are late by ``δ`` predicts ``û(t) = u(t − δ)``, so
   ``â − û ≈ δ u̇`` with ``u̇ = −ω × û``, and each move gives its own least-squares ``δ_i``, with a constant and
   the linear acceleration of a turn about a centre off the sensor (a lever arm ``r`` per move:
   ``α × r + ω × (ω × r)`` across gravity over g) fitted beside it.  The moves' estimates
   are combined by their weights (``Σ|u̇|²``) and tested by Student's t on their scatter (the moves' linear
   accelerations, which the accelerometer's direction carries, are noise of unknown size: measured by that
   scatter, not assumed); held out by move like the others: each held-out move's rms inside-move misfit with and
   without the offset of the other folds: their paired improvement must exceed :data:`OFFSET_HELDOUT_SE` of its
   standard errors (a held-out rms ratio above 1 alone passed on a 0.1 % change, whatever the moves' scatter).
4. **The gain**: the held-out gravity prediction's rms angle of the paper's model over the final model's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

# the diagnosis's concepts, one module each (and importable from here, as before): the band, the held-out units,
# the time offset's test, the findings and their text
from optcal.applications.diagnosis.gyro_frame_check import frame_check
from optcal.applications.diagnosis.gyro_band import SIMULATION_CHUNK, band, simulated_move_rad2
from optcal.applications.diagnosis.gyro_heldout import (MIN_DIAGNOSIS_MOVES, HeldOut, heldout, heldout_gain_t,
                                                        interleaved_folds, moves_response, paired_gain)
from optcal.applications.diagnosis.gyro_problem import (
    GYRO_EFFECTS,
    GyroData,
    GyroParams,
    Noise,
    Term,
    casadi_fit,
    evaluate,
    gauss_newton,
    gyro_data,
    screen,
    measured_noise,
    move_angles,
)
from optcal.applications.diagnosis.gyro_result import GyroDiagnosis, GyroFinding
from optcal.applications.diagnosis.gyro_time_offset import (LEVER_SMOOTHING_S, OFFSET_HELDOUT_SE,
                                                            TIME_OFFSET_MEASURES, time_offset_test)
from optcal.core import quantiles
from optcal.core.model import AXES, STANDARD_GRAVITY
from optcal.errors import InputError
from optcal.families.gyro.moves import MoveSet

#: One-sided level at which a term's improvement of the held-out moves (and rests) must be told from none
#: (Student's t of the paired differences: the mean gain over its standard error from the units' own scatter): a
#: term that fits the fitted moves' noise moves the held-out ones both ways, and a real effect's improvement holds
#: move after move.  At 0.05 the gain must exceed about 1.7 of its standard errors (m − 1 = 20 to 40 dof).
HELDOUT_LEVEL: float = 0.05
#: What the held-out moves must show to confirm a g-sensitivity (``--gyro-g-evidence``): ``angles``, their paired
#: gain of the gravity-prediction angle beyond :data:`HELDOUT_LEVEL`, as every term; ``response`` (the default), that
#: or their response to it (:func:`moves_response`) beyond the same level.  The rests measure a g-sensitivity to their
#: noise (each rest's bias turns with the pose, ``G f``); a move sees it only integrated over its second or two, a
#: small change ``Δ`` to its prediction, and the paired gain of its angle is second order in a small ``Δ`` (the
#: moves' noise decides its sign), where the response is linear in it.  0.1 °/s per g (a MEMS gyro's datasheet value)
#: written into imu0's file and imu_tk's data1 and data4: held-out moves' angle t −0.42, 1.67 and 1.19 against 1.7
#: (missed), response 0.58 ± 0.14, 1.38 ± 0.36, 1.42 ± 0.45 (t 3.2-4.1); the g-sensitivities the moves' angles confirm
#: respond 0.87-1.31 (the Xsens log, data3); a bias that follows the pose in the rests alone responds 0.19 ± 0.28.
G_EVIDENCE: tuple[str, ...] = ("response", "angles")


@dataclass(frozen=True)
class GyroDiagnosisSettings:
    """Settings of :func:`diagnose_gyro`.

    Attributes
    ----------
    alpha : float
        Family-wise false-finding level of each selection step (and of the band over the moves).
    folds : int
        Folds of the held-out moves.
    effects : tuple of str, optional
        The candidates (:data:`GYRO_EFFECTS`); all that the data support by default.
    solver : str, optional
        The CasADi NLP solver of the final fit (IPOPT by default).
    max_terms : int
        Most terms the selection adds.
    simulations : int
        Runs of the fitted model along the recorded moves with the measured noise (the band); 0 keeps the
        linearised band alone.
    seed : int
        Seed of the simulations.
    heldout_se : float, optional
        Standard errors by which every finding's paired gain on the held-out moves must exceed zero (0: any
        positive gain); ``None``: Student's one-sided quantile at :data:`HELDOUT_LEVEL` for the terms (their units'
        held-out t at it too) and :data:`OFFSET_HELDOUT_SE` for the time offset.
    g_evidence : str
        One of :data:`G_EVIDENCE`: whether the held-out moves' response to a g-sensitivity (:func:`moves_response`)
        may confirm it where their paired angle gain does not.
    frame_check : bool
        Refit the accelerometer's frame jointly with the moves when they leave the band unexplained
        (:mod:`~optcal.applications.diagnosis.gyro_frame_check`; ``--no-gyro-frame-check`` skips it).
    """

    alpha: float = 0.02
    folds: int = 5
    effects: tuple[str, ...] | None = None
    solver: str | None = None
    max_terms: int = 6
    simulations: int = 200
    seed: int = 0
    heldout_se: float | None = None
    g_evidence: str = "response"
    frame_check: bool = True

    def __post_init__(self) -> None:
        if self.g_evidence not in G_EVIDENCE:
            raise InputError(f"unknown g-sensitivity evidence {self.g_evidence!r}; valid: {', '.join(G_EVIDENCE)} "
                             "(--gyro-g-evidence)")
        if not 0.0 < self.alpha < 1.0:
            raise InputError(f"alpha must be in (0, 1), got {self.alpha}")
        if self.heldout_se is not None and not 0.0 <= self.heldout_se < math.inf:
            raise InputError(f"the held-out standard errors must be finite and at least 0, got {self.heldout_se} "
                             "(--gyro-heldout-se)")
        if self.folds < 2:
            raise InputError(f"folds must be at least 2, got {self.folds}")
        if self.simulations < 0:
            raise InputError(f"simulations must be at least 0, got {self.simulations}")
        unknown = sorted(set(self.effects or ()) - set(GYRO_EFFECTS))
        if unknown:
            raise InputError(f"unknown gyroscope effect(s) {', '.join(unknown)}; valid: {', '.join(GYRO_EFFECTS)}")


def _chi2_sf(x: float, dof: int) -> float:
    """P(χ²_dof > x)."""
    return float(quantiles.gamma_upper(0.5 * dof, 0.5 * max(x, 0.0))) if x > 0 else 1.0


def _lr(before: tuple[float, float], after: tuple[float, float], counts: tuple[int, int]) -> float:
    """The likelihood ratio with each residual kind's noise scale profiled (Gaussian):
    ``Σ_g n_g ln(RSS₀_g / RSS₁_g)``."""
    out = 0.0
    for r0, r1, n in zip(before, after, counts):
        if r0 > 0 and r1 > 0:
            out += n * math.log(r0 / r1)
    return out


def _candidates(data: GyroData, effects: tuple[str, ...]) -> tuple[list[Term], dict[str, str]]:
    skipped: dict[str, str] = {}
    terms: list[Term] = []
    for effect in effects:
        if effect == "time_offset":
            continue
        if effect == "gyro_temperature_bias" and data.temp_mid is None:
            skipped[effect] = "no temperature column"
            continue
        if effect == "gyro_bias_drift" and float(np.ptp(data.rest_t)) <= 0:
            skipped[effect] = "no time stamps across the rests"
            continue
        terms += [Term(effect, axis) for axis in range(3)]
    return terms, skipped


def _estimate(term_values: list[tuple[Term, NDArray[np.float64]]], effect: str) -> tuple[dict[str, float], dict[str, Any]]:
    est: dict[str, float] = {}
    rows: dict[str, list[float]] = {}
    for term, value in term_values:
        assert term.axis is not None
        axis = AXES[term.axis]
        if effect == "g_sensitivity":
            row = np.asarray(value) / STANDARD_GRAVITY
            est[axis] = float(row[term.axis])
            rows[axis] = row.tolist()
        else:
            est[axis] = float(value[0])
    return est, ({"row_rad_s_per_m_s2": rows} if rows else {})


def _without(p: GyroParams, index: int) -> GyroParams:
    return GyroParams(p.T, p.b, p.terms[:index] + p.terms[index + 1:], p.values[:index] + p.values[index + 1:])


def _backward(data: GyroData, noise: Noise, p: GyroParams, rss: tuple[float, float], counts: tuple[int, int],
              alpha: float, steps: list[dict[str, Any]], notes: list[str]) -> tuple[GyroParams, tuple[float, float]]:
    """The named terms tested again in the final model, each against the model without it, at the Bonferroni share
    of ``alpha`` over the named terms: a term that entered as a proxy of one named after it (a drift standing in
    for a temperature that rose with time) is dropped."""
    changed = True
    while changed and p.terms:
        changed = False
        level = alpha / len(p.terms)
        tests = []
        for i, term in enumerate(p.terms):
            reduced = gauss_newton(data, noise, _without(p, i))
            reduced_rss = evaluate(data, noise, reduced, jac=False).rss()
            lr = _lr(reduced_rss, rss, counts)
            tests.append((_chi2_sf(lr, term.size), i, term, reduced, reduced_rss, lr))
        worst = max(tests, key=lambda x: x[0])
        if worst[0] >= level:
            pv, i, term, reduced, reduced_rss, lr = worst
            steps.append({"term": term.label, "removed": True, "lr": lr, "p": pv, "level": level})
            notes.append(f"{term.label} dropped: with the terms named after it, it no longer explains the data "
                         f"(likelihood ratio {lr:.1f}, p {pv:.2g} ≥ {level:.2g})")
            p, rss, changed = reduced, reduced_rss, True
    return p, rss


def diagnose_gyro(moves: MoveSet, accelerometer: Any, gyro: Any, settings: GyroDiagnosisSettings | None = None
                  ) -> GyroDiagnosis:
    """Diagnose the gyroscope of an IMU calibration on the moves it was fitted to (module docstring).

    Parameters
    ----------
    moves : MoveSet
        The recording's moves (:func:`optcal.families.gyro.moves.moves_from_segmentation`).
    accelerometer : CalibrationResult
        The accelerometer's calibration (its gravity directions are data).
    gyro : GyroModel
        The paper's gyro model fitted to the moves (the start).
    settings : GyroDiagnosisSettings, optional

    Raises
    ------
    InputError
        Fewer than :data:`MIN_DIAGNOSIS_MOVES` moves.
    """
    s = settings or GyroDiagnosisSettings()
    if moves.n_moves < MIN_DIAGNOSIS_MOVES:
        raise InputError(f"{moves.n_moves} moves; the gyroscope's diagnosis needs at least {MIN_DIAGNOSIS_MOVES} "
                         "(held-out folds and the time offset's scatter): record more moves between rests")
    data = gyro_data(moves, accelerometer)
    effects = s.effects or GYRO_EFFECTS
    base = GyroParams(np.asarray(gyro.T, float), np.asarray(gyro.bias, float), (), ())
    noise = measured_noise(data, base)
    base = gauss_newton(data, noise, base, iterations=4)  # the paper's model, its bias with the rests' noise
    folds = interleaved_folds(data.n_moves, min(s.folds, data.n_moves // 2))
    counts = (2 * data.n_moves, 3 * data.rest_raw.shape[0])  # two directions across gravity per move
    n_obs = sum(counts)
    candidates, skipped = _candidates(data, effects)
    current = base
    current_rss = evaluate(data, noise, current, jac=False).rss()
    rest_folds = interleaved_folds(data.rest_raw.shape[0], len(folds))
    current_out = heldout(data, noise, current, folds, rest_folds)
    current_heldout = baseline_heldout = current_out.rms_deg
    heldout_critical = (quantiles.t_isf(HELDOUT_LEVEL, data.n_moves + data.rest_raw.shape[0] - 1)
                        if s.heldout_se is None else s.heldout_se)
    moves_critical = (quantiles.t_isf(HELDOUT_LEVEL, data.n_moves - 1)  # the held-out moves' own t: m − 1 dof
                      if s.heldout_se is None else s.heldout_se)
    steps: list[dict[str, Any]] = []
    evidence: dict[Term, dict[str, float]] = {}
    while len(current.terms) < s.max_terms:
        remaining = [t for t in candidates if t not in current.terms]
        if not remaining:
            break
        # every remaining term screened by its one-step score; in that order each is fitted (Gauss-Newton) for its
        # likelihood ratio, and the first that passes all three tests is named (one that passes the ratio and the
        # BIC but not the held-out moves, a rest-only effect behind a larger one the moves show, makes way)
        scored = sorted(screen(data, noise, current, remaining), key=lambda x: -_lr(current_rss, x[1], counts))
        level = s.alpha / len(remaining)
        named = None
        for term, _ in scored:
            trial = gauss_newton(data, noise, current.extend(term))
            rss = evaluate(data, noise, trial, jac=False).rss()
            lr = _lr(current_rss, rss, counts)
            p = _chi2_sf(lr, term.size)
            delta_bic = -lr + term.size * math.log(n_obs)
            passes = p < level and delta_bic < 0
            out = heldout(data, noise, trial, folds, rest_folds) if passes else None
            held = out.rms_deg if out is not None else float("nan")
            t_heldout = heldout_gain_t(current_out, out) if out is not None else float("nan")
            # and the held-out moves' gravity prediction (the gain the diagnosis reports) must improve move after move
            # at the same level: the rests' mean rates alone cannot tell a g-sensitivity or a drift from a bias that
            # wanders between rests beyond their white noise (bias instability, the Earth's rate turning with the
            # pose); an effect that matters to the calibration also moves the moves' prediction (the issue sizes
            # effects by that rise)
            # paired on the angles, not their squares: under noise a move's angle is Rayleigh (sd 0.52 of its
            # mean) but its square exponential (sd equal to its mean), so squares' differences are ruled by the few
            # largest moves, and an effect that changes along the session (a warming curve, fastest after power-on)
            # improves a few moves much and the rest little (imu0, a 0.76 mrad/s/°C bias on a 10 °C warming: held-out
            # moves 0.241° -> 0.169°, t 1.58 on squares, 2.01 on angles)
            gain_moves, se_moves, t_moves = (paired_gain(np.sqrt(current_out.angles2) - np.sqrt(out.angles2))
                                             if out is not None else (float("nan"),) * 3)
            response = moves_response(current_out, out) if out is not None else (float("nan"),) * 2
            response_t = response[0] / response[1] if response[1] > 0 else float("nan")
            # a g-sensitivity the moves' angles cannot resolve is confirmed by their response to it (G_EVIDENCE)
            by_response = (s.g_evidence == "response" and term.effect == "g_sensitivity"
                           and response_t > moves_critical)
            accepted = passes and t_heldout > heldout_critical and (t_moves > moves_critical or by_response)
            steps.append({"term": term.label, "lr": lr, "p": p, "level": level, "delta_bic": delta_bic,
                          "heldout_rms_deg": held, "heldout_before_deg": current_heldout, "heldout_t": t_heldout,
                          "heldout_critical_t": heldout_critical, "heldout_moves_t": t_moves,
                          "heldout_moves_critical_t": moves_critical, "heldout_gain_deg": gain_moves,
                          "heldout_se_deg": se_moves, "moves_response": response[0], "moves_response_se": response[1],
                          "moves_response_t": response_t, "accepted": accepted})
            if accepted and out is not None:
                named = (term, trial, rss, out, lr, p, delta_bic, {
                    "heldout_t": t_heldout, "heldout_critical_t": heldout_critical, "heldout_gain_deg": gain_moves,
                    "heldout_se_deg": se_moves, "heldout_moves_t": t_moves, "heldout_moves_critical_t": moves_critical,
                    "moves_response": response[0], "moves_response_se": response[1], "moves_response_t": response_t})
                break
            if not passes:
                break  # the screen's order: the later terms explain less
        if named is None:
            break
        term, trial, rss, out, lr, p, delta_bic, held_gain = named
        evidence[term] = {"lr": lr, "p": p, "delta_bic": delta_bic, "heldout_ratio": current_heldout / out.rms_deg,
                          **held_gain}
        current, current_rss, current_heldout, current_out = trial, rss, out.rms_deg, out
    notes: list[str] = []
    current, current_rss = _backward(data, noise, current, current_rss, counts, s.alpha, steps, notes)
    solver: dict[str, Any] = {}
    final = current
    if current.terms:
        fitted, stats = casadi_fit(data, noise, current, s.solver)
        solver = {"name": s.solver or "ipopt", "success": bool(stats.get("success", False)),
                  "return_status": str(stats.get("return_status", ""))}
        # kept when IPOPT says it converged, or its cost (moves' and rests' together) is not above the selection's fit
        if stats.get("success") or sum(evaluate(data, noise, fitted, jac=False).rss()) <= 1.000001 * sum(current_rss):
            final = fitted
        else:
            notes.append("the CasADi refit did not improve on the selection's Gauss-Newton fit; that fit is kept")
        current_heldout = heldout(data, noise, final, folds, rest_folds).rms_deg
    findings: list[GyroFinding] = []
    for effect in GYRO_EFFECTS:
        chosen = [(t, v) for t, v in zip(final.terms, final.values) if t.effect == effect]
        if not chosen:
            continue
        est, extra = _estimate(chosen, effect)
        ev = evidence[chosen[0][0]]
        findings.append(GyroFinding(effect, [AXES[t.axis] for t, _ in chosen if t.axis is not None], est, ev, extra))
    offset: dict[str, Any] = {"tested": False, "reason": "not asked"}
    if "time_offset" in effects:
        offset = time_offset_test(data, final, s.alpha, folds,
                                  OFFSET_HELDOUT_SE if s.heldout_se is None else s.heldout_se)
        if offset.get("significant"):
            findings.append(GyroFinding("time_offset", [], {"dt_s": offset["dt_s"]},
                                        {"t": offset["t"], "critical_t": offset["critical_t"],
                                         "heldout_ratio": offset["heldout_ratio"],
                                         **{k: offset[k] for k in ("heldout_gain_deg", "heldout_se_deg", "heldout_moves_t",
                                                                   "heldout_moves_critical_t")}},
                                        {"stderr": {"dt_s": offset["se_s"]}, "measures": TIME_OFFSET_MEASURES}))
    angles = move_angles(data, base)
    linearised = band(angles, noise, s.alpha)
    moves_band = linearised
    if s.simulations > 0:
        # the band of the paper's model simulated along the recorded moves; its tail at the family-wise level by
        # the same Rayleigh law with the simulated mean square (a per-move quantile at 1 − α/m would need some
        # 10·m/α runs)
        simulated = Noise(simulated_move_rad2(data, base, s.simulations, s.seed), noise.rest_var)
        moves_band = band(angles, simulated, s.alpha)
    final_angles = move_angles(data, final)
    # the moves the selection leaves outside the band: does the accelerometer's frame explain them?
    frame = (frame_check(moves, accelerometer, bool(np.any(final_angles > moves_band)), s.alpha, folds,
                         moves_critical, s.solver) if s.frame_check else None)
    return GyroDiagnosis(findings, steps, angles, moves_band, final_angles,
                         baseline_heldout, current_heldout, offset, [t.label for t in candidates] + (
                             ["time_offset"] if "time_offset" in effects else []), skipped, final, notes, solver,
                         s.simulations, linearised, dict(moves.exclusions), frame)
