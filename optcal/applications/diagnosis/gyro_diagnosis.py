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
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.gyro_problem import (
    GYRO_EFFECTS,
    GyroData,
    GyroParams,
    Noise,
    Term,
    casadi_fit,
    corrected_rates,
    evaluate,
    gauss_newton,
    gyro_data,
    screen,
    measured_noise,
    move_angles,
    move_budget,
    predict,
)
from optcal.core import quantiles
from optcal.core.model import AXES, EARTH_RATE, STANDARD_GRAVITY
from optcal.core.stats import mean_and_se
from optcal.core.rotations import exponential_map, skew
from optcal.errors import InputError
from optcal.families.gyro.moves import MoveSet
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows

#: Fewest moves the held-out folds and the time offset's t test need (two per fold and a scatter of several).
MIN_DIAGNOSIS_MOVES: int = 8
#: What the time offset's estimate is: the shift between the two streams as the file holds them, whatever put it
#: there (a driver's or a logger's own offset, a filter's group delay, a shift written into the file); a shift added
#: to a file adds to the one it had (the Xsens log's gyro is 2.3 ms early: 3.5 ms made late reads +1.4 ms).
TIME_OFFSET_MEASURES: str = ("the gyro's samples against the accelerometer's as the file holds them (positive: the "
                             "gyro's late), the recording's own offset included: a shift added to the file adds to it")

#: The angular acceleration of the lever arm's term ``α × r`` is the derivative of the rates averaged over this
#: span (s; its running mean passes a hand's turn, whose power is below a few Hz, and its first zero is at 10 Hz):
#: the rates' white noise differentiated sample by sample grows with the sampling rate, and a noisy regressor fits
#: less than the lever arm's acceleration, leaving the rest in δ (a 0.3 m lever arm written into imu0's file moved
#: its offset 15.2 -> 12.1 ms with the raw derivative; imu0 and the Xsens log keep theirs named).
LEVER_SMOOTHING_S: float = 0.1

#: One-sided level at which a term's improvement of the held-out moves (and rests) must be told from none
#: (Student's t of the paired differences: the mean gain over its standard error from the units' own scatter): a
#: term that fits the fitted moves' noise moves the held-out ones both ways, and a real effect's improvement holds
#: move after move.  At 0.05 the gain must exceed about 1.7 of its standard errors (m − 1 = 20 to 40 dof).
HELDOUT_LEVEL: float = 0.05
#: Standard errors by which the time offset's paired gain on the held-out moves must exceed zero: the held-out
#: moves' own noise gives a gain within one standard error.  The offset's significance is its own t on the moves
#: (the family-wise level); this asks that its correction generalise beyond noise.  Under white misfit the held-out
#: t is about half the estimate's (a held-out move gains δ²|u̇|² against noise 2δ n·u̇; measured 0.39-0.50 on the
#: Xsens log, imu0 and mgiurato's log), so a real offset that passes its t passes this; a lever arm's unfollowed
#: motion, which scatters the moves, does not (0.3 m planted in imu0: t 3.8 past 3.25, held-out 0.77 SE).
OFFSET_HELDOUT_SE: float = 1.0
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


@dataclass(frozen=True)
class GyroFinding:
    """An effect named in the gyroscope, with its evidence.

    Attributes
    ----------
    effect : str
        One of :data:`GYRO_EFFECTS`.
    axes : list of str
    estimate : dict
        Axis → value in SI (rad/s per m/s² for the g-sensitivity's diagonal term, (rad/s)⁻¹ for the scale
        nonlinearity, rad/s per °C, rad/s per s), or ``{"dt_s": ...}`` for the time offset.
    evidence : dict
        The likelihood ratio (or t), p, ΔBIC and the held-out ratio of the step that named it; the held-out moves'
        paired gain (``heldout_gain_deg``: the mean improvement of a held-out move's gravity-prediction angle, or of
        its rms inside-move misfit for the time offset, degrees), its standard error (``heldout_se_deg``), its t
        (``heldout_moves_t``) and the t it had to exceed (``heldout_moves_critical_t``).
    extra : dict
        The g-sensitivity's whole rows (rad/s per m/s²); the time offset's standard error and what it measures
        (:data:`TIME_OFFSET_MEASURES`).
    """

    effect: str
    axes: list[str]
    estimate: dict[str, Any]
    evidence: dict[str, float]
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"sensor": "gyroscope", "effect": self.effect, "axes": list(self.axes), "estimate": dict(self.estimate),
                "evidence": dict(self.evidence), **self.extra}

    def describe(self) -> str:
        if self.effect == "time_offset":
            dt = float(self.estimate["dt_s"])
            se = self.extra.get("stderr", {}).get("dt_s")
            return (f"time_offset: the gyro's samples are {abs(dt) * 1e3:.2f}"
                    + (f" ± {float(se) * 1e3:.2f}" if se is not None else "")
                    + f" ms {'late' if dt > 0 else 'early'} against the accelerometer's as the file holds them, its own "
                    f"offset included (t = {self.evidence['t']:.1f}, held-out {self.evidence['heldout_ratio']:.3f}×"
                    f"{_heldout_words(self.evidence, 'rms inside-move misfit')})")
        unit = {"g_sensitivity": "rad/s per m/s²", "gyro_scale_nonlinearity": "(rad/s)⁻¹",
                "gyro_temperature_bias": "rad/s per °C", "gyro_bias_drift": "rad/s per s"}[self.effect]
        values = ", ".join(f"{a} {float(v):.3g}" for a, v in self.estimate.items())
        rows = self.extra.get("row_rad_s_per_m_s2")
        if rows:  # the whole row: an axis' rate error may follow another axis' specific force (off-diagonal)
            values = "; ".join(f"{a} row (per x, y, z) " + ", ".join(f"{float(v):.3g}" for v in row)
                               for a, row in rows.items())
        return (f"{self.effect}({','.join(self.axes)}): {values} {unit} (likelihood ratio {self.evidence['lr']:.1f}, "
                f"p {self.evidence['p']:.2g}, ΔBIC {self.evidence['delta_bic']:.1f}, held-out {self.evidence['heldout_ratio']:.2f}×"
                f"{_heldout_words(self.evidence, 'angle')})")


def _heldout_words(evidence: dict[str, Any], what: str) -> str:
    """The held-out moves' paired gain in words (``""`` when ``evidence`` has none): the mean improvement per
    held-out move of its ``what``, its standard error and t against the t it had to exceed; and their response to
    the term (:func:`moves_response`)."""
    if "heldout_gain_deg" not in evidence:
        return ""
    words = (f"; held-out moves' {what} {float(evidence['heldout_gain_deg']):+.2g} ± "
             f"{float(evidence['heldout_se_deg']):.2g}° better per move, t {float(evidence['heldout_moves_t']):.2f} "
             f"against {float(evidence['heldout_moves_critical_t']):.2f}")
    response = evidence.get("moves_response_t")
    if isinstance(response, float) and math.isfinite(response):
        words += (f"; their response to it {float(evidence['moves_response']):.2f} ± "
                  f"{float(evidence['moves_response_se']):.2f} (1: they carried what it removes, 0: none of it), "
                  f"t {response:.2f}")
    return words


@dataclass
class GyroDiagnosis:
    """What the gyroscope's diagnosis found (:func:`diagnose_gyro`)."""

    findings: list[GyroFinding]
    steps: list[dict[str, Any]]
    angles_deg: NDArray[np.float64]
    band_deg: NDArray[np.float64]
    final_angles_deg: NDArray[np.float64]
    heldout_baseline_deg: float
    heldout_final_deg: float
    time_offset: dict[str, Any]
    tested: list[str]
    skipped: dict[str, str]
    final: GyroParams
    notes: list[str]
    solver: dict[str, Any]
    #: How the band was found: the runs simulated (0: linearised only) and the linearised band beside it.
    band_runs: int = 0
    linearised_band_deg: NDArray[np.float64] | None = None
    #: The moves left out before the diagnosis, by reason (:attr:`optcal.families.gyro.moves.MoveSet.exclusions`).
    moves_excluded: dict[str, int] = field(default_factory=dict)

    @property
    def gain(self) -> float:
        """Held-out rms gravity-prediction angle of the paper's model over the final model's."""
        return self.heldout_baseline_deg / self.heldout_final_deg if self.heldout_final_deg > 0 else 1.0

    @property
    def outside(self) -> NDArray[np.bool_]:
        return np.asarray(self.angles_deg > self.band_deg)

    def to_dict(self) -> dict[str, Any]:
        return {
            "findings": [f.to_dict() for f in self.findings],
            "gain": self.gain,
            "heldout_rms_deg": {"baseline": self.heldout_baseline_deg, "final": self.heldout_final_deg},
            "moves": [{"angle_deg": float(a), "band_deg": float(b), "outside": bool(a > b), "final_angle_deg": float(f)}
                      for a, b, f in zip(self.angles_deg, self.band_deg, self.final_angles_deg)],
            "moves_outside_band": int(np.sum(self.outside)),
            "moves_excluded": dict(self.moves_excluded),
            "band": {"runs": self.band_runs, "method": ("simulated: the fitted model integrated along each recorded move with the measured noise"
                                if self.band_runs else "linearised noise budget"),
                     "linearised_deg": None if self.linearised_band_deg is None else self.linearised_band_deg.tolist()},
            "rms_deg": {"baseline": float(np.sqrt(np.mean(self.angles_deg**2))),
                        "final": float(np.sqrt(np.mean(self.final_angles_deg**2)))},
            "steps": self.steps,
            "time_offset": self.time_offset,
            "tested": self.tested,
            "skipped": self.skipped,
            "final_model": {"T": self.final.T.tolist(), "bias": self.final.b.tolist(),
                            "terms": {t.label: v.tolist() for t, v in zip(self.final.terms, self.final.values)}},
            "solver": self.solver,
            "notes": self.notes,
        }

    def report_lines(self) -> list[str]:
        out = ["GYROSCOPE",
               f"  gravity prediction across {self.angles_deg.size} moves: {np.sqrt(np.mean(self.angles_deg**2)):.3f}° rms "
               f"under the paper's model; {int(np.sum(self.outside))} move(s) outside the "
               + (f"band of {self.band_runs} simulations of the fitted model along the recorded moves with the measured "
                  "noise" if self.band_runs else "noise band") + " (family-wise over the moves)"]
        out.extend(f"  {k}: {v}" for k, v in self.moves_excluded.items())
        for i in np.flatnonzero(self.outside)[:10]:
            out.append(f"    move {i + 1}: {self.angles_deg[i]:.3f}° (band {self.band_deg[i]:.3f}°)")
        if self.findings:
            out.append("  named:")
            for f in self.findings:
                out.append(f"    {f.describe()}")
                if f.effect == "g_sensitivity":
                    # the Earth's rate's vertical component (Ω sin φ along gravity) turns with the pose as a specific
                    # force along the axis would: a diagonal g-sensitivity of Ω sin φ / g at latitude φ
                    out.append(f"      (its diagonal terms include the Earth's rate along gravity, up to "
                               f"{EARTH_RATE / STANDARD_GRAVITY:.2g} rad/s per m/s² at the poles, which no recording "
                               "tells from the sensor's)")
        elif np.any(self.outside):
            # the band's excess left unexplained: said, not "nothing" (the effect is outside the five candidates, or
            # the noise model understates the moves' noise)
            effects = list(dict.fromkeys(label.split("(")[0] for label in self.tested))
            out.append(f"  none named: the {int(np.sum(self.outside))} move(s) beyond the band are explained by none of "
                       f"the candidates tested ({', '.join(effects)}); the cause is outside them (motion during the "
                       "rests, a time base that is not the samples', a filter) or the noise model understates the "
                       "moves' noise")
            tried = [s for s in self.steps if not s.get("removed")][:1]
            for step in tried:
                moves_t = step.get("heldout_moves_t")
                out.append(f"    best candidate: {step['term']} (likelihood ratio {step['lr']:.1f}, p {step['p']:.2g} against "
                           f"{step['level']:.2g}, ΔBIC {step['delta_bic']:.1f}"
                           + (f", held-out moves' t {moves_t:.2f} against "
                              f"{step.get('heldout_moves_critical_t', step['heldout_critical_t']):.2f}"
                              + (f" (their angle {step['heldout_gain_deg']:+.2g} ± {step['heldout_se_deg']:.2g}° better "
                                 "per move)" if "heldout_gain_deg" in step else "")
                              if isinstance(moves_t, float) and math.isfinite(moves_t) else "")
                           + (f", their response {step['moves_response']:.2f} ± {step['moves_response_se']:.2f}"
                              if isinstance(step.get("moves_response_t"), float)
                              and math.isfinite(step["moves_response_t"]) else "") + ")")
        else:
            out.append("  none named (an effect below the tests' power is not ruled out)")
        if "dt_s" in self.time_offset and not self.time_offset.get("significant"):
            # measured whether named or not: a user who shifted a stream reads the total here (TIME_OFFSET_MEASURES)
            o = self.time_offset
            out.append(f"  time offset between the streams: {o['dt_s'] * 1e3:+.2f} ± {o['se_s'] * 1e3:.2f} ms (gyro "
                       f"late when positive; t {o['t']:.1f} against {o['critical_t']:.1f}, held-out "
                       f"{o['heldout_ratio']:.3f}×{_heldout_words(o, 'rms inside-move misfit')}): not named")
        out.append(f"  held-out gravity prediction: {self.heldout_baseline_deg:.3f}° → {self.heldout_final_deg:.3f}° rms "
                   f"(gain {self.gain:.2f})")
        for name, why in self.skipped.items():
            out.append(f"  not tested: {name}: {why}")
        out += [f"  note: {n}" for n in self.notes]
        return out


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


def _folds(m: int, k: int) -> list[NDArray[np.bool_]]:
    """Held-out moves of each fold (interleaved: every ``k``-th move, so each fold spans the session)."""
    return [np.arange(m) % k == j for j in range(k)]


@dataclass(frozen=True)
class HeldOut:
    """Each move's squared gravity-prediction angle (degrees²) and each move's and rest's squared residual over its
    noise, every one under the model refitted without its fold."""

    angles2: NDArray[np.float64]
    moves: NDArray[np.float64]
    rests: NDArray[np.float64]
    #: Each move's residual (m, 3) over its noise, under the model refitted without its fold.
    move_residuals: NDArray[np.float64] | None = None

    @property
    def rms_deg(self) -> float:
        return float(np.sqrt(np.mean(self.angles2)))


def heldout(data: GyroData, noise: Noise, p: GyroParams, folds: list[NDArray[np.bool_]],
            rest_folds: list[NDArray[np.bool_]]) -> HeldOut:
    """:class:`HeldOut` of ``p`` (k-fold: the moves and rests of each fold predicted by the model fitted to the
    others, one Gauss–Newton step from ``p``)."""
    angles2 = np.zeros(data.n_moves)
    moves = np.zeros(data.n_moves)
    residuals = np.zeros((data.n_moves, 3))
    rests = np.zeros(data.rest_raw.shape[0])
    for test, test_rests in zip(folds, rest_folds):
        refit = gauss_newton(data, noise, p, iterations=1, train=~test, train_rests=~test_rests)
        e = evaluate(data, noise, refit, jac=False)
        angles2[test] = move_angles(data, refit, test) ** 2
        moves[test] = np.sum(e.moves[test] ** 2, axis=1)
        residuals[test] = e.moves[test]
        rests[test_rests] = np.sum(e.rests[test_rests] ** 2, axis=1)
    return HeldOut(angles2, moves, rests, residuals)


def moves_response(before: HeldOut, after: HeldOut) -> tuple[float, float]:
    """How much of the change a term makes to the held-out moves' gravity prediction their misfit without it held:
    ``β = −Σ r·Δ / Σ |Δ|²`` (``r`` a held-out move's residual without the term, ``Δ`` the change the term makes to
    it), 1 when the moves carried the effect the term removes, 0 when they carried none of it (the term then adds
    ``Δ`` as an error), and its standard error (:func:`~optcal.core.stats.mean_and_se` of the moves' own ratios,
    weighted by ``|Δ|²``).  Linear in the moves' noise, where the paired gain of their angles is second order in a
    small ``Δ``: a term the rests fix well and the moves see faintly is judged by it."""
    assert before.move_residuals is not None and after.move_residuals is not None
    delta = after.move_residuals - before.move_residuals
    x = np.sum(delta * delta, axis=1)
    keep = x > 0
    if np.count_nonzero(keep) < 2:
        return float("nan"), float("nan")
    y = -np.sum(before.move_residuals * delta, axis=1)
    beta, se = mean_and_se(y[keep] / x[keep], x[keep])
    return float(beta), float(se)


def heldout_gain_t(before: HeldOut, after: HeldOut) -> float:
    """Student's t of the held-out moves' and rests' paired improvement (each kind over its mean before, so that
    moves and rests weigh alike): a term that only fits the fitted units' noise improves some held-out ones and
    worsens others, its t near zero; a real effect's improvement holds unit after unit."""
    return _paired_t(np.concatenate([(before.moves - after.moves) / max(float(np.mean(before.moves)), 1e-300),
                                     (before.rests - after.rests) / max(float(np.mean(before.rests)), 1e-300)]))


def _paired_t(d: NDArray[np.float64]) -> float:
    """Student's t of the mean of paired differences ``d`` (improvements: positive when the term helps)."""
    return paired_gain(d)[2]


def paired_gain(d: NDArray[np.float64]) -> tuple[float, float, float]:
    """The mean of the paired held-out improvements ``d`` (one per held-out unit, positive when the finding helps),
    its standard error from their own scatter (:func:`~optcal.core.stats.mean_and_se`) and Student's t (infinite
    for a gain without scatter, 0 for none)."""
    gain, se = mean_and_se(d)
    t = gain / se if se > 0 else (math.inf if gain > 0 else 0.0)
    return gain, se, float(t)


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


def band(angles_deg: NDArray[np.float64], noise: Noise, alpha: float) -> NDArray[np.float64]:
    """Each move's bound of the gravity-prediction angle at the family-wise level ``alpha`` (Rayleigh, module
    docstring), degrees."""
    m = angles_deg.size
    return np.degrees(np.sqrt(noise.move_rad2 * math.log(m / alpha)))


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


#: Simulation runs integrated together (memory: the longest move's steps x the moves x the runs, 3x3 each).
SIMULATION_CHUNK: int = 20


def simulated_move_rad2(data: GyroData, p: GyroParams, runs: int, seed: int) -> NDArray[np.float64]:
    """Each move's mean squared gravity-prediction angle (rad²) over ``runs`` simulations of the model ``p`` along
    the recorded moves with the measured noise.

    Each run takes the model's own prediction as the truth (``u₁ = Φ(ω)ᵀ u₀``, Tedaldi 2014, eq. 13-14) and
    integrates the corrected rates plus white rate noise of the rests' angle random walk (``N²/dt`` per step and
    raw axis, through ``T_g``) by the exponential map, from a start direction tilted by its pose's noise, to an end
    direction tilted by its pose's; the budget's sources a run does not simulate (the rests' bias offsets, the time
    base, the integration) tilt the prediction as Gaussian terms of their linearised variance.  The simulation
    follows each move's own axes against gravity (the linearised budget averages them: two thirds of an isotropic
    error) and the exponential map's nonlinearity.
    """
    moves = data.moves
    assert moves.noise is not None
    budget = move_budget(data, p)
    other = budget.bias + budget.time_base + budget.integration
    omega, _ = corrected_rates(data, p, data.raw, data.f_mid, data.t_mid, data.temp_mid, False)
    truth, _ = predict(data, omega)
    n, m = omega.shape[0], data.n_moves
    rate_sd = np.sqrt(moves.noise.arw2[None, :] / np.maximum(data.dt, 1e-12)[:, None])  # raw units, per step
    s0, s1 = data.pose_sigma[moves.move_from], data.pose_sigma[moves.move_to]
    rng = np.random.default_rng(seed)
    total = np.zeros(m)
    done = 0
    while done < runs:
        r = min(SIMULATION_CHUNK, runs - done)
        rates = omega[None] + (rng.standard_normal((r, n, 3)) * rate_sd) @ p.T.T
        theta = (rates * data.dt[None, :, None]).reshape(-1, 3)
        starts = (data.starts[None, :] + n * np.arange(r)[:, None]).ravel()
        u0 = unit_rows(np.tile(data.u0, (r, 1)) + rng.standard_normal((r * m, 3)) * np.tile(s0, r)[:, None])
        v = GravityPredictor.of_starts(starts, r * n).directions(theta, u0)
        v = unit_rows(v + rng.standard_normal((r * m, 3)) * np.sqrt(0.5 * np.tile(other, r))[:, None])
        u1 = unit_rows(np.tile(truth, (r, 1)) + rng.standard_normal((r * m, 3)) * np.tile(s1, r)[:, None])
        total += np.sum(np.radians(angles_deg(v, u1)).reshape(r, m) ** 2, axis=0)
        done += r
    return total / max(runs, 1)


def _smoothed(omega: NDArray[np.float64], dt: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rates' running mean over :data:`LEVER_SMOOTHING_S` (centred; shorter at the move's ends)."""
    k = int(round(LEVER_SMOOTHING_S / float(np.median(dt))))
    if k < 2:
        return omega
    kernel = np.ones(k) / k
    ones = np.convolve(np.ones(omega.shape[0]), kernel, mode="same")
    return np.column_stack([np.convolve(omega[:, j], kernel, mode="same") / ones for j in range(3)])


def time_offset_test(data: GyroData, p: GyroParams, alpha: float, folds: list[NDArray[np.bool_]],
                     heldout_se: float = OFFSET_HELDOUT_SE) -> dict[str, Any]:
    """The time offset between the gyro's and the accelerometer's samples (module docstring, 3): named when its t
    passes the family-wise level ``alpha`` and its paired gain on the held-out moves exceeds ``heldout_se`` of its
    standard errors."""
    omega, _ = corrected_rates(data, p, data.raw, data.f_mid, data.t_mid, data.temp_mid, False)
    E = exponential_map(omega * data.dt[:, None])
    starts = data.starts
    ends = np.r_[starts[1:], omega.shape[0]]
    per_move: list[float] = []
    weights: list[float] = []
    pieces: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
    for i, (a, z) in enumerate(zip(starts, ends)):
        R = np.eye(3)
        after = np.empty((z - a, 3))
        for k in range(a, z):  # û after each step: (P_k)ᵀ u₀
            R = R @ E[k]
            after[k - a] = R.T @ data.u0[i]
        # at each step's middle, where its specific force is: half a step earlier than after it (the midpoint's
        # direction; compared after the step, a half step would read as a time offset)
        u = unit_rows(0.5 * (np.vstack([data.u0[i][None, :], after[:-1]]) + after))
        udot = -np.cross(omega[a:z], u)
        e = (unit_rows(data.f_mid[a:z]) - u).ravel()
        # what is not a shift in time, fitted on the move and projected out of both: a constant misfit (the
        # end-to-end residual's share), and the accelerometer's linear acceleration of a turn about a centre off
        # the sensor (the hand's wrist or elbow, r from it to the sensor, per move): a = α × r + ω × (ω × r),
        # its share across gravity P_u a / g (a rigid body's point acceleration; the moves' largest linear
        # acceleration, which scattered the moves' δ)
        alpha_dot = (np.gradient(_smoothed(omega[a:z], data.dt[a:z]), np.cumsum(data.dt[a:z]), axis=0)
                     if z - a > 2 else np.zeros((z - a, 3)))
        across = np.eye(3)[None] - u[:, :, None] * u[:, None, :]
        lever = across @ (skew(alpha_dot) + skew(omega[a:z]) @ skew(omega[a:z])) / STANDARD_GRAVITY
        nuisance = np.column_stack([np.tile(np.eye(3), (z - a, 1)), lever.reshape(-1, 3)])
        e = e - nuisance @ np.linalg.lstsq(nuisance, e, rcond=None)[0]
        q = udot.ravel()
        q = q - nuisance @ np.linalg.lstsq(nuisance, q, rcond=None)[0]
        wi = float(q @ q)
        per_move.append(float(e @ q) / wi if wi > 0 else 0.0)
        weights.append(wi)
        pieces.append((e, q))
    d = np.asarray(per_move)
    w = np.asarray(weights)
    m = d.size
    if m < MIN_DIAGNOSIS_MOVES or w.sum() <= 0:
        return {"tested": False, "reason": f"{m} moves (fewer than {MIN_DIAGNOSIS_MOVES})"}
    delta, se = mean_and_se(d, w)
    t = delta / se if se > 0 else 0.0
    critical = quantiles.t_isf(0.5 * alpha / len(GYRO_EFFECTS), m - 1)
    # held out: δ from the other folds' moves, the inside-move residual of each held-out move with and without it
    before: list[float] = []
    after_shift: list[float] = []
    gains: list[float] = []
    for test in folds:
        train = ~test
        dtrain = mean_and_se(d[train], w[train])[0] if w[train].sum() > 0 else 0.0
        for j in np.flatnonzero(test).tolist():
            e, udot_c = pieces[j]
            before.append(float(np.sum(e * e)))
            after_shift.append(float(np.sum((e - dtrain * udot_c) ** 2)))
            # the move's rms misfit across gravity (e holds three components per step), degrees: paired on the
            # rms, not the squares, as the terms' held-out moves are on their angles (a move's squared misfit is
            # ruled by its fastest turns, so a few moves would decide)
            steps = max(e.size // 3, 1)
            gains.append(math.degrees(math.sqrt(before[-1] / steps) - math.sqrt(after_shift[-1] / steps)))
    ratio = float(np.sqrt(np.sum(before) / np.sum(after_shift))) if np.sum(after_shift) > 0 else 1.0
    gain, gain_se, gain_t = paired_gain(np.asarray(gains))
    # named when the estimate passes its family-wise t and the held-out moves gain beyond their own noise
    # (OFFSET_HELDOUT_SE; the ratio of the summed misfits above 1 alone passed on a 0.1 % change: mgiurato's log
    # 1.0012, imu_tk's data3 1.0008, and on a lever arm's scatter)
    return {"tested": True, "dt_s": delta, "se_s": se, "t": t, "critical_t": critical, "moves": m,
            "heldout_ratio": ratio, "heldout_gain_deg": gain, "heldout_se_deg": gain_se, "heldout_moves_t": gain_t,
            "heldout_moves_critical_t": heldout_se,
            "significant": bool(abs(t) > critical and gain_t > heldout_se),
            "measures": TIME_OFFSET_MEASURES, "per_move_dt_s": d.tolist()}


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
    folds = _folds(data.n_moves, min(s.folds, data.n_moves // 2))
    counts = (2 * data.n_moves, 3 * data.rest_raw.shape[0])  # two directions across gravity per move
    n_obs = sum(counts)
    candidates, skipped = _candidates(data, effects)
    current = base
    current_rss = evaluate(data, noise, current, jac=False).rss()
    rest_folds = _folds(data.rest_raw.shape[0], len(folds))
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
    return GyroDiagnosis(findings, steps, angles, moves_band, move_angles(data, final),
                         baseline_heldout, current_heldout, offset, [t.label for t in candidates] + (
                             ["time_offset"] if "time_offset" in effects else []), skipped, final, notes, solver,
                         s.simulations, linearised, dict(moves.exclusions))
