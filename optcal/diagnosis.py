"""Diagnosis: where the calibrated model's simulation disagrees with the measurements, why, and the gain.

Four steps (:func:`diagnose` runs them all):

1. **Baseline** — the paper's model ``a = C ā + o + n`` (Lu 2017, eq. 5) fitted by maximum
   likelihood (eq. 13-14, :mod:`optcal.estimators.mle`), with its held-out error (k-fold over
   poses: the held-out residual of a pose is its norm residual under the model fitted without
   it, the model inverted at the pose's own measurement).
2. **Simulation check** (parametric bootstrap) — the fitted model is simulated on the same
   poses (fitted directions, temperatures and times; the noise the model claims: the given
   per-pose σ, or the residual scale when none was given) and refitted many times.  For each
   statistic of the residuals — rms, whiteness along pose order and time (lag-1
   autocorrelation, Ljung–Box), partial correlation with the regressor of every candidate
   effect, tails (excess kurtosis, largest standardised residual) — the measured value is
   compared with the simulated band; what falls outside is what the simulation gets wrong.
3. **Selection** — forward selection over the vocabulary of :mod:`optcal.effects`, per axis,
   each candidate fitted jointly with ``T`` and ``o``.  A term is added when

   * its likelihood-ratio test is significant: the F form (noise scale estimated from the
     residuals, so a wrong σ claim cannot manufacture findings), ``q`` = number of new
     coefficients, at level ``α/(2m)`` for ``m`` candidates in the step (Bonferroni: the
     family-wise false-finding rate of the first step is at most ``α/2``);
   * it lowers the BIC (``n log(RSS/n) + p log n``);
   * it lowers the held-out rms (k-fold).

   Among the candidates passing the first two, the best BIC is tried first.  A term's
   polynomial order is raised (one coefficient at a time, same tests) where the data support
   it.  **Outliers** enter as mean-shift terms (a free offset per flagged pose, i.e. the pose
   gets zero weight): a Cauchy-loss fit of the current model in CasADi marks suspects
   (standardised residual > 3), and each suspect is kept only if its deleted residual, tested
   against the fit without the suspects (t distribution, Bonferroni over the n poses), is
   significant at ``α/2``.  Selection stops when nothing more passes.
4. **Findings** — every effect of the final model with per-axis estimates (first-order
   coefficient, units of :data:`optcal.effects.UNITS`), standard errors (Fisher
   information, noise scale from the residuals), the evidence of dropping it from the final
   model (ΔBIC, p value) and the held-out rms without and with it; the final model's held-out
   rms and the gain (baseline held-out rms / final held-out rms).

When temperature and time are both candidates and both explain a bias on the same axis (a
sensor warming up), the one with the better BIC enters first and the other is then tested
*given* it; the report says which was chosen, by how much, and whether the other adds
anything (and that the two cannot be told apart when the recording makes them collinear).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats as sps

from optcal.effects import (
    BETA_INDEX,
    CAUSES,
    EFFECTS,
    MAX_ORDER,
    N_X,
    PARAMETRIC,
    UNITS,
    ExtendedProblem,
    PoseData,
    Regressors,
    active_mask,
    describe_term,
    format_value,
    parse_effects,
    to_model,
)
from optcal.errors import InputError
from optcal.estimators.base import Normaliser
from optcal.model import AXES, theta_from
from optcal.poses import PoseTable

#: Degrees of freedom that must remain with every candidate term in the model.
MIN_DOF: int = 10
#: Standardised residual (Cauchy fit) above which a pose is a suspected outlier.
SUSPECT_Z: float = 3.0
#: Scale of the Cauchy loss, in standard deviations (95 % efficiency at the Gaussian).
CAUCHY_SCALE: float = 2.385
#: Relative partial Fisher information below which a candidate is not identifiable from the poses.
IDENTIFIABLE_TOL: float = 1e-6
#: ΔBIC difference below which two competing explanations count as indistinguishable (Kass & Raftery).
BIC_TIE: float = 6.0
BASELINE_MODEL = "T, o, white noise (Lu 2017, eq. 5)"

Terms = tuple[tuple[tuple[str, int], int], ...]  # sorted ((effect, axis), order) pairs


def _terms_key(terms: dict[tuple[str, int], int]) -> Terms:
    return tuple(sorted(terms.items(), key=lambda kv: (PARAMETRIC.index(kv[0][0]), kv[0][1])))


@dataclass
class Fit:
    """One fitted model: terms ``{(effect, axis): order}``, outlier poses, solution and residuals."""

    terms: dict[tuple[str, int], int]
    outliers: frozenset[int]
    x: NDArray[np.float64]
    residuals: NDArray[np.float64]
    rss: float
    n_params: int
    success: bool

    def kept(self, n: int) -> NDArray[np.bool_]:
        mask = np.ones(n, dtype=bool)
        mask[list(self.outliers)] = False
        return mask

    def describe(self) -> str:
        parts = [BASELINE_MODEL.split(" (")[0]]
        parts += [describe_term(e, a, o) for (e, a), o in _terms_key(self.terms)]
        if self.outliers:
            parts.append(f"outliers({len(self.outliers)} poses zero-weighted)")
        return " + ".join(parts)


@dataclass
class Step:
    """One forward-selection step: every candidate tried, and what was accepted."""

    candidates: list[dict[str, Any]]
    accepted: dict[str, Any] | None


@dataclass
class Diagnosis:
    """Everything :func:`diagnose` found (text with :meth:`report`, JSON with :meth:`to_json`)."""

    poses: PoseTable
    regressors: Regressors
    effects_tested: tuple[str, ...]
    skipped: dict[str, str]
    notes: list[str]
    baseline: Fit
    baseline_heldout: NDArray[np.float64]
    final: Fit
    final_heldout: NDArray[np.float64]
    simulation: dict[str, Any]
    simulation_after: dict[str, Any] | None
    steps: list[Step]
    findings: list[dict[str, Any]]
    competitions: list[dict[str, Any]]
    settings: dict[str, Any]
    units_scale: float
    fitted_directions: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))

    # ------------------------------------------------------------------ numbers
    @property
    def n(self) -> int:
        return self.poses.n

    def baseline_rms(self) -> float:
        return float(np.sqrt(np.mean(self.baseline.residuals**2)))

    def baseline_heldout_rms(self, mask: NDArray[np.bool_] | None = None) -> float:
        r = self.baseline_heldout if mask is None else self.baseline_heldout[mask]
        return float(np.sqrt(np.mean(r**2)))

    def final_rms(self) -> float:
        return float(np.sqrt(np.mean(self.final.residuals[self.final.kept(self.n)] ** 2)))

    def final_heldout_rms(self) -> float:
        return float(np.sqrt(np.mean(self.final_heldout[self.final.kept(self.n)] ** 2)))

    def gain(self) -> float:
        return self.baseline_heldout_rms() / self.final_heldout_rms()

    def to_json(self) -> dict[str, Any]:
        """The one JSON object of ``optcal diagnose --json`` (see the issue's shape)."""
        kept = self.final.kept(self.n)
        return {
            "n_poses": self.n,
            "baseline": {
                "model": BASELINE_MODEL,
                "rms_g": self.baseline_rms(),
                "heldout_rms_g": self.baseline_heldout_rms(),
            },
            "simulation_check": {**self.simulation, "after": self.simulation_after},
            "findings": self.findings,
            "final": {
                "model": self.final.describe(),
                "rms_g": self.final_rms(),
                "heldout_rms_g": self.final_heldout_rms(),
                "gain": self.gain(),
                "heldout_poses": int(kept.sum()),
                "gain_on_kept_poses": self.baseline_heldout_rms(kept) / self.final_heldout_rms(),
            },
            "effects_tested": list(self.effects_tested),
            "effects_skipped": self.skipped,
            "temperature_time_decisions": self.competitions,
            "selection": [
                {"accepted": s.accepted["term"] if s.accepted else None, "candidates": s.candidates} for s in self.steps
            ],
            "settings": self.settings,
            "notes": self.notes,
        }

    # ------------------------------------------------------------------ text
    def report(self) -> str:
        """Readable report: what the simulation gets wrong, the causes, the extended model, the gain."""
        mg = 1e3
        lines = [
            f"Diagnosis of {self.n} poses ({self.poses.source}, units {self.poses.units})",
            "",
            "1. Baseline: the paper's model (T, o, white noise), maximum likelihood",
            f"   rms norm residual {self.baseline_rms() * mg:.3g} mg; held-out ({self.settings['folds']}-fold over poses) "
            f"{self.baseline_heldout_rms() * mg:.3g} mg",
        ]
        lines += ["", "2. " + simulation_text(self.simulation, indent="   ")]
        tested = ", ".join(self.effects_tested) or "none"
        lines += ["", f"3. Candidate effects tested: {tested}"]
        for effect, why in self.skipped.items():
            lines.append(f"   not tested: {effect} ({why})")
        alpha = self.settings["alpha"]
        lines.append(
            f"   forward selection: F/likelihood-ratio test at family-wise level {alpha:g} (Bonferroni over the "
            "candidates of each step), lower BIC, and lower held-out rms, all three required"
        )
        for k, step in enumerate(self.steps, 1):
            best = sorted(step.candidates, key=lambda c: c["delta_bic"])[:3]
            tried = "; ".join(
                f"{c['term']} ΔBIC {c['delta_bic']:+.1f}, p {c['p_value']:.2g}" for c in best
            )
            verdict = f"added {step.accepted['term']}" if step.accepted else "nothing passes: stop"
            lines.append(f"   step {k}: {verdict}  [best candidates: {tried or 'none'}]")
        for c in self.competitions:
            lines.append("   " + c["text"])
        lines += ["", "4. Findings"]
        if not self.findings:
            if "rms_g" in self.simulation["outside_band"]:
                lines.append(
                    "   none: no candidate effect passes the tests, although the residuals are larger than the given "
                    "per-pose noise predicts (see 2): the excess is not one of the tested effects"
                )
            else:
                lines.append("   none: the paper's model explains these data (no candidate passes the tests)")
        for f in self.findings:
            lines.append(f"   {f['effect']}: {CAUSES[f['effect']]}")
            if f["effect"] == "outliers":
                lines.append(f"      rows {', '.join(str(r) for r in f['rows'])} given zero weight")
            else:
                for ax in f["axes"]:
                    order = f["order"][ax]
                    lines.append(
                        f"      axis {ax}: {format_value(f['effect'], f['estimate'][ax], f['stderr'][ax])}"
                        + (f" (polynomial order {order} supported by the data; slope at the reference shown)" if order > 1 else "")
                    )
            ev = f["evidence"]
            lines.append(
                f"      evidence: ΔBIC {ev['delta_bic']:+.1f}, p = {ev['p_value']:.2g}; held-out rms "
                f"{f['heldout_rms_g_before'] * mg:.3g} → {f['heldout_rms_g_after'] * mg:.3g} mg"
            )
        lines += [
            "",
            "5. Final model: " + self.final.describe(),
            f"   rms {self.final_rms() * mg:.3g} mg; held-out {self.final_heldout_rms() * mg:.3g} mg; "
            f"gain {self.gain():.3g}× (baseline held-out / final held-out)",
        ]
        if self.final.outliers:
            kept = self.final.kept(self.n)
            lines.append(
                f"   (held-out rms over the {int(kept.sum())} kept poses; on those same poses the baseline's is "
                f"{self.baseline_heldout_rms(kept) * mg:.3g} mg, a gain of {self.baseline_heldout_rms(kept) / self.final_heldout_rms():.3g}×)"
            )
        if self.simulation_after is not None:
            lines += ["", "6. " + simulation_text(self.simulation_after, indent="   ", after=True)]
        for note in self.notes:
            lines.append(f"note: {note}")
        return "\n".join(lines)


# ----------------------------------------------------------------------------- statistics
def _autocorr(e: NDArray, lag: int) -> float:
    e = e - e.mean()
    den = float(np.sum(e * e))
    return float(np.sum(e[lag:] * e[:-lag]) / den) if den > 0 and len(e) > lag else 0.0


def _ljung_box(e: NDArray, lags: int) -> float:
    n = len(e)
    return float(n * (n + 2) * sum(_autocorr(e, k) ** 2 / (n - k) for k in range(1, lags + 1)))


STAT_MEANING: dict[str, str] = {
    "rms_g": "rms of the norm residuals (g)",
    "lag1_pose_order": "lag-1 autocorrelation along pose order",
    "ljung_box_pose_order": "Ljung-Box whiteness statistic along pose order",
    "lag1_time": "lag-1 autocorrelation along time",
    "ljung_box_time": "Ljung-Box whiteness statistic along time",
    "excess_kurtosis": "excess kurtosis of the standardised residuals (tails)",
    "max_abs_z": "largest standardised residual (tails)",
}


def simulation_text(sim: dict[str, Any], indent: str = "", after: bool = False) -> str:
    """Plain-words summary of a simulation check."""
    if not sim["simulations"]:
        return f"Simulation check{' of the final model' if after else ''}: not run (0 simulations requested)"
    head = (
        f"Simulation check{' of the final model' if after else ''}: the fitted model simulated {sim['simulations']} times on "
        f"the same poses ({sim['noise']}); {sim['band'] * 100:g} % bands"
    )
    out = [head]
    outside = sim["outside_band"]
    if not outside:
        out.append(f"{indent}every residual statistic is inside its simulated band: the simulation reproduces the measurements")
    else:
        out.append(f"{indent}where the measurement leaves the simulated band (what the simulation gets wrong):")
        for name in outside:
            st = sim["statistics"][name]
            lo, hi = st["band"]
            out.append(
                f"{indent}  {st['meaning']}: measured {st['measured']:.3g}, simulated {lo:.3g} .. {hi:.3g} (p = {st['p_value']:.2g})"
            )
    if sim.get("multiplicity_note"):
        out.append(f"{indent}{sim['multiplicity_note']}")
    return ("\n" + indent).join([out[0]]) + ("\n" + "\n".join(out[1:]) if len(out) > 1 else "")


# ----------------------------------------------------------------------------- the diagnoser
class Diagnoser:
    """Runs the diagnosis of one pose table (see the module docstring).

    Parameters
    ----------
    poses : PoseTable
    effects : iterable of str or str, optional
        Candidate effects (names from :data:`optcal.effects.EFFECTS`); default: every effect
        the data's columns support.  Asking for an effect the data cannot support raises
        :class:`~optcal.errors.InputError`.
    folds : int
        k of the k-fold held-out error.
    simulations : int
        Parametric-bootstrap replications of the simulation check.
    alpha : float
        Family-wise false-finding level of a selection step.
    band : float
        Coverage of the simulated bands.
    seed : int
        Seed of the simulations.
    progress : callable, optional
        Called with a short message at each stage.
    """

    def __init__(
        self,
        poses: PoseTable,
        effects: Iterable[str] | str | None = None,
        folds: int = 10,
        simulations: int = 200,
        alpha: float = 0.02,
        band: float = 0.99,
        seed: int = 0,
        progress: Callable[[str], None] | None = None,
    ) -> None:
        from optcal.calibration import calibrate
        from optcal.norm_residual import normal_gain

        poses.validate()
        if not 0 < alpha < 1:
            raise InputError("alpha must be between 0 and 1")
        if not 0 < band < 1:
            raise InputError("band must be between 0 and 1")
        if folds < 2:
            raise InputError("folds must be at least 2")
        if simulations < 0:
            raise InputError("simulations must be non-negative")
        self.poses = poses
        self.n = poses.n
        self.reg = Regressors.of(poses)
        self.folds_k = min(int(folds), self.n)
        self.simulations = int(simulations)
        self.alpha = float(alpha)
        self.band = float(band)
        self.seed = int(seed)
        self.progress = progress or (lambda msg: None)
        self.notes: list[str] = []
        self.effects, self.skipped = self._choose_effects(effects)
        self.candidates = [(e, a) for e in self.effects if e in PARAMETRIC for a in range(3)]
        self._check_size()
        self.norm = Normaliser.of(poses.acc)
        self.data = PoseData(self.norm.forward(poses.acc), self.reg.tau, self.reg.s)
        self.problem = ExtendedProblem.get(self.n, "squared")
        self.progress("fitting the paper's model by maximum likelihood")
        start = calibrate(poses, "mle")
        sigma = np.ones(self.n) if poses.sigma is None else poses.sigma
        w_abs = 1.0 / (sigma * normal_gain(start.T, start.o, poses.acc)) ** 2
        self.w_mean = float(np.mean(w_abs))
        self.w = w_abs / self.w_mean
        r0 = start.residuals
        self.s0 = max(float(np.sqrt(np.sum(self.w * r0**2) / max(self.n - 9, 1))), 1e-12)
        x0 = np.zeros(N_X)
        x0[:9] = self.norm.theta_to_normalised(theta_from(start.T, start.o))
        self.x_start = x0
        order = np.argsort(poses.t, kind="stable") if self.reg.has_time else np.arange(self.n)
        self.fold = np.empty(self.n, dtype=int)
        self.fold[order] = np.arange(self.n) % self.folds_k
        self.time_order = order
        self._heldout_cache: dict[tuple[Terms, frozenset[int]], NDArray] = {}

    # ------------------------------------------------------------------ setup
    def _choose_effects(self, effects: Iterable[str] | str | None) -> tuple[tuple[str, ...], dict[str, str]]:
        asked = parse_effects(effects) if effects is not None else None
        skipped: dict[str, str] = {}
        if asked is None:
            chosen = []
            for e in EFFECTS:
                if self.reg.supports(e):
                    chosen.append(e)
                else:
                    skipped[e] = self.reg.reason_unsupported(e)
            return tuple(chosen), skipped
        if not asked:
            return (), {e: "not asked for (--effects none)" for e in EFFECTS}
        bad = [f"{e}: {self.reg.reason_unsupported(e)}" for e in asked if not self.reg.supports(e)]
        if bad:
            raise InputError(
                "cannot test " + "; ".join(bad) + ". Give DATA with a varying temp column (°C) and a time column, "
                "or leave those effects out of --effects"
            )
        return asked, skipped

    def _check_size(self) -> None:
        q = len(self.candidates)
        if not self.effects:  # baseline and simulation check only: a few residual degrees of freedom
            if self.n < 9 + 3:
                raise InputError(
                    f"{self.n} poses are too few for a diagnosis: at least 12 are needed (9 calibration parameters "
                    "and 3 residual degrees of freedom)"
                )
            return
        need = 9 + q + MIN_DOF
        if self.n < need:
            what = f"{q} candidate effect coefficients ({', '.join(e for e in self.effects if e in PARAMETRIC)} on x, y, z)" if q else "outliers"
            raise InputError(
                f"{self.n} poses are too few to test {what}: at least {need} poses are needed (9 calibration "
                f"parameters + {q} effect coefficients + {MIN_DOF} degrees of freedom left for the tests); record more "
                "poses, or test fewer effects with --effects (--effects none: the baseline and its simulation check only)"
            )

    # ------------------------------------------------------------------ fitting
    def _params(self, w: NDArray, data: PoseData | None = None, scale: float | None = None, delta: float = 1.0) -> NDArray:
        s = self.s0 if scale is None else scale
        return (data or self.data).parameters(w / s**2, delta)

    def fit(
        self,
        terms: dict[tuple[str, int], int],
        outliers: frozenset[int] = frozenset(),
        x0: NDArray | None = None,
        data: PoseData | None = None,
    ) -> Fit:
        """Least-squares fit of the model with ``terms``, the ``outliers`` given zero weight."""
        w = self.w.copy()
        w[list(outliers)] = 0.0
        p = self._params(w, data)
        x, stats = self.problem.solve(self.x_start if x0 is None else x0, p, active_mask(terms))
        r = self.problem.residual_values(x, p)
        kept = np.ones(self.n, dtype=bool)
        kept[list(outliers)] = False
        rss = float(np.sum(self.w[kept] * r[kept] ** 2))
        n_params = 9 + sum(terms.values()) + len(outliers)
        return Fit(dict(terms), frozenset(outliers), x, r, rss, n_params, bool(stats.get("success", False)))

    def bic(self, fit: Fit) -> float:
        """``n log(RSS/n) + p log n`` (outliers as mean-shift parameters, so n is every pose)."""
        return float(self.n * np.log(max(fit.rss, 1e-300) / self.n) + fit.n_params * np.log(self.n))

    def f_test(self, small: Fit, big: Fit) -> float:
        """p value of the F form of the likelihood-ratio test of ``small`` inside ``big``."""
        q = big.n_params - small.n_params
        dof = self.n - big.n_params
        if q <= 0 or dof <= 0:
            return 1.0
        F = max(small.rss - big.rss, 0.0) / q / (big.rss / dof)
        return float(sps.f.sf(F, q, dof))

    def heldout(self, fit: Fit) -> NDArray[np.float64]:
        """Held-out residual of every pose (k-fold; the model fitted without the pose's fold)."""
        key = (_terms_key(fit.terms), fit.outliers)
        if key in self._heldout_cache:
            return self._heldout_cache[key]
        out = np.empty(self.n)
        mask = active_mask(fit.terms)
        for f in range(self.folds_k):
            w = self.w.copy()
            w[list(fit.outliers)] = 0.0
            w[self.fold == f] = 0.0
            p = self._params(w)
            x, _ = self.problem.solve(fit.x, p, mask)
            out[self.fold == f] = self.problem.residual_values(x, p)[self.fold == f]
        self._heldout_cache[key] = out
        return out

    def _rms(self, r: NDArray, mask: NDArray[np.bool_]) -> float:
        return float(np.sqrt(np.mean(r[mask] ** 2)))

    def _free_jacobian(self, fit: Fit, w: NDArray) -> tuple[NDArray, NDArray]:
        """Weighted Jacobian of the free parameters and the full weighted Jacobian."""
        p = self._params(w)
        J = self.problem.jacobian_values(fit.x, p)
        free = np.concatenate([np.ones(9, dtype=bool), active_mask(fit.terms)])
        sw = np.sqrt(w)[:, None]
        return sw * J[:, free], sw * J

    def covariance(self, fit: Fit) -> NDArray[np.float64]:
        """Covariance of the free normalised parameters (θ, then active β in layout order)."""
        w = self.w.copy()
        w[list(fit.outliers)] = 0.0
        G, _ = self._free_jacobian(fit, w)
        s2 = fit.rss / max(self.n - fit.n_params, 1)
        return s2 * np.linalg.pinv(G.T @ G, rcond=1e-13, hermitian=True)

    # ------------------------------------------------------------------ simulation check
    def _candidate_columns(self, fit: Fit) -> list[tuple[str, int]]:
        return [(e, a) for (e, a) in self.candidates if (e, a) not in fit.terms]

    def residual_statistics(self, fit: Fit, r: NDArray, J_full: NDArray, G: NDArray) -> dict[str, float]:
        """The statistics compared in the simulation check (module docstring)."""
        kept = fit.kept(self.n)
        e = np.sqrt(self.w) * r
        scale = np.sqrt(np.sum(e[kept] ** 2) / max(kept.sum() - fit.n_params + len(fit.outliers), 1))
        out = {"rms_g": float(np.sqrt(np.mean(r[kept] ** 2)))}
        ek = e[kept]
        lags = max(1, min(5, int(kept.sum()) // 8))
        out["lag1_pose_order"] = _autocorr(ek, 1)
        out["ljung_box_pose_order"] = _ljung_box(ek, lags)
        if self.reg.has_time and not np.array_equal(self.time_order, np.arange(self.n)):
            et = e[self.time_order][kept[self.time_order]]
            out["lag1_time"] = _autocorr(et, 1)
            out["ljung_box_time"] = _ljung_box(et, lags)
        z = ek / max(scale, 1e-300)
        out["excess_kurtosis"] = float(sps.kurtosis(z, fisher=True, bias=False)) if len(z) > 3 else 0.0
        out["max_abs_z"] = float(np.max(np.abs(z)))
        Gk = G[kept]
        pinv = np.linalg.pinv(Gk, rcond=1e-12)
        for effect, axis in self._candidate_columns(fit):
            g = J_full[kept, 9 + BETA_INDEX[(effect, axis, 1)]]
            g_perp = g - Gk @ (pinv @ g)
            den = float(np.linalg.norm(g_perp) * np.linalg.norm(ek))
            out[f"corr_{effect}_{AXES[axis]}"] = float(ek @ g_perp / den) if den > 0 else 0.0
        return out

    def _statistics_of(self, fit: Fit) -> dict[str, float]:
        G, J = self._free_jacobian(fit, np.where(fit.kept(self.n), self.w, 0.0))
        return self.residual_statistics(fit, fit.residuals, J, G)

    def simulation_check(self, fit: Fit) -> dict[str, Any]:
        """Parametric bootstrap of ``fit``: measured residual statistics against simulated bands."""
        rng = np.random.default_rng(self.seed)
        model = to_model(fit.x, self.norm.centre, self.norm.scale, self.reg)
        temp, t = self.poses.temp, self.poses.t
        directions = model.correct(self.poses.acc, temp if self.reg.has_temp else None, t if self.reg.has_time else None)
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        clean = model.measure(directions, temp if self.reg.has_temp else None, t if self.reg.has_time else None)
        kept = fit.kept(self.n)
        lam = float(np.sqrt(fit.rss * self.w_mean / max(kept.sum() - (fit.n_params - len(fit.outliers)), 1)))
        known = self.poses.sigma is not None
        sigma = (self.poses.sigma if known else np.ones(self.n) * lam) * np.ones(self.n)
        noise = (
            "noise: the per-pose σ given with the data" if known
            else "noise: estimated from these residuals (no per-pose σ given), so the rms is matched by construction"
        )
        measured = self._statistics_of(fit)
        sims: dict[str, list[float]] = {k: [] for k in measured}
        for _ in range(self.simulations):
            acc = clean + rng.standard_normal((self.n, 3)) * sigma[:, None]
            data = PoseData(self.norm.forward(acc), self.reg.tau, self.reg.s)
            sim_fit = self.fit(fit.terms, fit.outliers, fit.x, data)
            w = np.where(kept, self.w, 0.0)
            p = self._params(w, data)
            J = self.problem.jacobian_values(sim_fit.x, p)
            free = np.concatenate([np.ones(9, dtype=bool), active_mask(fit.terms)])
            sw = np.sqrt(w)[:, None]
            st = self.residual_statistics(sim_fit, sim_fit.residuals, sw * J, sw * J[:, free])
            for k in sims:
                sims[k].append(st[k])
        lo_q, hi_q = (1 - self.band) / 2, 1 - (1 - self.band) / 2
        table: dict[str, dict[str, Any]] = {}
        outside: list[str] = []
        for name, value in measured.items():
            s = np.asarray(sims[name])
            if s.size:
                lo, hi = float(np.quantile(s, lo_q)), float(np.quantile(s, hi_q))
                p = min(1.0, 2 * min((np.sum(s >= value) + 1) / (s.size + 1), (np.sum(s <= value) + 1) / (s.size + 1)))
                med = float(np.median(s))
            else:
                lo = hi = med = float("nan")
                p = 1.0
            out = bool(s.size and (value < lo or value > hi))
            if name == "rms_g" and not known:
                out = False
            meaning = STAT_MEANING.get(name) or self._corr_meaning(name)
            if name.endswith("pose_order") and self.reg.has_time and np.array_equal(self.time_order, np.arange(self.n)):
                meaning += " (= time order)"
            table[name] = {"measured": value, "simulated_median": med, "band": [lo, hi], "p_value": float(p),
                           "outside": out, "meaning": meaning}
            if out:
                outside.append(name)
        result: dict[str, Any] = {
            "model": fit.describe(),
            "simulations": self.simulations,
            "noise": noise,
            "noise_scale": lam if known else None,
            "band": self.band,
            "statistics": table,
            "outside_band": outside,
        }
        if known:
            result["noise_scale_meaning"] = (
                "rms of the standardised residuals: 1 when the given per-pose σ describes the pose-to-pose error"
            )
        if self.simulations and len(table) > 1:
            result["multiplicity_note"] = (
                f"({len(table)} statistics at {self.band * 100:g} % each: about {len(table) * (1 - self.band):.2g} would "
                "fall outside by chance; the selection below is the test)"
            )
        return result

    def _corr_meaning(self, name: str) -> str:
        body = name[len("corr_"):]
        effect, axis = body.rsplit("_", 1)
        reg = {"temperature_bias": "temperature", "temperature_scale": "temperature × force",
               "bias_drift": "time", "scale_nonlinearity": "force²"}[effect]
        return f"partial correlation with the {effect} regressor of axis {axis} ({reg} on {axis})"

    # ------------------------------------------------------------------ outliers
    def detect_outliers(self, fit: Fit) -> tuple[frozenset[int], float, Fit] | None:
        """New outlier poses under ``fit`` (Cauchy fit → suspects → deleted-residual t test)."""
        kept = fit.kept(self.n)
        e = np.sqrt(self.w) * fit.residuals
        scale = max(1.4826 * float(np.median(np.abs(e[kept]))), 1e-12)
        cauchy = ExtendedProblem.get(self.n, "cauchy")
        mask = active_mask(fit.terms)
        w = np.where(kept, self.w, 0.0)
        x = fit.x
        for _ in range(2):
            p = self.data.parameters(w / scale**2, CAUCHY_SCALE)
            x, _ = cauchy.solve(x, p, mask)
            e = np.sqrt(self.w) * cauchy.residual_values(x, p)
            scale = max(1.4826 * float(np.median(np.abs(e[kept]))), 1e-12)
        suspects = frozenset(int(k) for k in np.flatnonzero(kept & (np.abs(e) / scale > SUSPECT_Z)))
        if not suspects:
            return None
        inner = self.fit(fit.terms, fit.outliers | suspects, x)
        dof = self.n - inner.n_params
        if dof <= 0:
            return None
        s2 = inner.rss / dof
        w_in = np.where(inner.kept(self.n), self.w, 0.0)
        G, _ = self._free_jacobian(inner, w_in)
        M = np.linalg.pinv(G.T @ G, rcond=1e-13, hermitian=True)
        p_full = self._params(w_in)
        J = self.problem.jacobian_values(inner.x, p_full)
        free = np.concatenate([np.ones(9, dtype=bool), mask])
        flagged: dict[int, float] = {}
        for k in suspects:
            jk = J[k, free]
            v = s2 * (1.0 / self.w[k] + float(jk @ M @ jk))
            tk = inner.residuals[k] / np.sqrt(v)
            pk = min(1.0, self.n * 2 * float(sps.t.sf(abs(tk), dof)))
            if pk < self.alpha_outliers:
                flagged[k] = pk
        if not flagged:
            return None
        final = self.fit(fit.terms, fit.outliers | frozenset(flagged), inner.x)
        return frozenset(flagged), min(flagged.values()), final

    # ------------------------------------------------------------------ selection
    @property
    def alpha_terms(self) -> float:
        return self.alpha / 2 if "outliers" in self.effects else self.alpha

    @property
    def alpha_outliers(self) -> float:
        return self.alpha / 2

    def _identifiable(self, fit: Fit, effect: str, axis: int, order: int) -> bool:
        w = np.where(fit.kept(self.n), self.w, 0.0)
        G, J = self._free_jacobian(fit, w)
        g = J[:, 9 + BETA_INDEX[(effect, axis, order)]]
        if not np.any(g):
            return False
        g_perp = g - G @ (np.linalg.pinv(G, rcond=1e-12) @ g)
        return float(g_perp @ g_perp) > IDENTIFIABLE_TOL * float(g @ g)

    def _term_candidates(self, fit: Fit) -> list[tuple[str, int, int]]:
        out = [(e, a, 1) for (e, a) in self.candidates if (e, a) not in fit.terms]
        for (e, a), order in fit.terms.items():
            if order < MAX_ORDER[e]:
                values = self.reg.tau if e.startswith("temperature") else self.reg.s
                if np.unique(np.round(values, 6)).size >= order + 3:
                    out.append((e, a, order + 1))
        return out

    def select(self, baseline: Fit) -> tuple[Fit, list[Step], list[dict[str, Any]]]:
        """Forward selection from ``baseline`` (module docstring)."""
        current = baseline
        steps: list[Step] = []
        rivalries: list[dict[str, Any]] = []
        for _ in range(4 * len(self.candidates) + 3):
            bic0 = self.bic(current)
            term_cands = self._term_candidates(current)
            m = max(len(term_cands), 1)
            tried: list[dict[str, Any]] = []
            for effect, axis, order in term_cands:
                if not self._identifiable(current, effect, axis, order):
                    self._note(f"{describe_term(effect, axis, order)} is not identifiable from these poses; not tested")
                    continue
                terms = dict(current.terms)
                terms[(effect, axis)] = order
                cand = self.fit(terms, current.outliers, current.x)
                p = self.f_test(current, cand)
                tried.append({
                    "term": describe_term(effect, axis, order), "effect": effect, "axis": AXES[axis], "order": order,
                    "delta_bic": self.bic(cand) - bic0, "p_value": p, "threshold": self.alpha_terms / m,
                    "significant": bool(p < self.alpha_terms / m and self.bic(cand) < bic0), "_fit": cand,
                })
            if "outliers" in self.effects:
                found = self.detect_outliers(current)
                if found is not None:
                    rows_new, p, cand = found
                    tried.append({
                        "term": f"outliers({len(rows_new)} poses)", "effect": "outliers", "axis": None, "order": None,
                        "delta_bic": self.bic(cand) - bic0, "p_value": p, "threshold": self.alpha_outliers,
                        "significant": bool(self.bic(cand) < bic0), "_fit": cand,
                        "rows": [int(self.poses.rows[k]) for k in sorted(rows_new)],
                    })
            accepted = None
            for c in sorted((c for c in tried if c["significant"]), key=lambda c: c["delta_bic"]):
                cand = c["_fit"]
                mask = cand.kept(self.n)
                before = self._rms(self.heldout(current), mask)
                after = self._rms(self.heldout(cand), mask)
                c["heldout_rms_g_before"], c["heldout_rms_g_after"] = before, after
                if after < before:
                    accepted = c
                    break
                c["significant"] = False
                c["rejected_because"] = "held-out rms did not fall"
            if accepted is not None:
                rivalries += self._rivalry(accepted, tried)
            steps.append(Step([{k: v for k, v in c.items() if k != "_fit"} for c in tried],
                              None if accepted is None else {k: v for k, v in accepted.items() if k != "_fit"}))
            if accepted is None:
                break
            current = accepted["_fit"]
        return current, steps, rivalries

    def _rivalry(self, accepted: dict[str, Any], tried: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Temperature vs time on the same axis: both significant in the step that chose one."""
        if accepted["effect"] not in ("temperature_bias", "temperature_scale", "bias_drift") or accepted["order"] != 1:
            return []
        rivals = ("bias_drift",) if accepted["effect"] != "bias_drift" else ("temperature_bias", "temperature_scale")
        out = []
        for c in tried:
            if c["effect"] in rivals and c["axis"] == accepted["axis"] and c["order"] == 1 and c["p_value"] < self.alpha_terms:
                out.append({"axis": accepted["axis"], "chosen": accepted["effect"], "other": c["effect"],
                            "delta_bic_chosen": accepted["delta_bic"], "delta_bic_other": c["delta_bic"]})
        return out

    def _explain_rivalries(self, final: Fit, rivalries: list[dict[str, Any]]) -> list[dict[str, Any]]:
        corr = self.reg.correlation()
        out = []
        for r in rivalries:
            axis = AXES.index(r["axis"])
            key = (r["other"], axis)
            gap = r["delta_bic_other"] - r["delta_bic_chosen"]
            if key in final.terms:
                given = "both are in the final model: each explains something the other does not"
                p_other = None
            else:
                terms = dict(final.terms)
                terms[key] = 1
                with_other = self.fit(terms, final.outliers, final.x)
                p_other = self.f_test(final, with_other)
                given = (
                    f"with {r['chosen']} in the model, {r['other']} adds nothing significant (p = {p_other:.2g})"
                    if p_other >= self.alpha_terms else
                    f"even with {r['chosen']} in the model, {r['other']} still explains more (p = {p_other:.2g})"
                )
            corr_txt = f"temperature and time correlate (r = {corr:+.2f})" if corr is not None else ""
            if gap < BIC_TIE and corr is not None and abs(corr) > 0.9:
                verdict = (
                    f"axis {r['axis']}: {r['chosen']} and {r['other']} cannot be told apart from this recording "
                    f"({corr_txt}; ΔBIC {r['delta_bic_chosen']:+.1f} vs {r['delta_bic_other']:+.1f}); {r['chosen']} "
                    "was kept by a small margin: record a temperature profile that is not monotone in time to separate them"
                )
            else:
                verdict = (
                    f"axis {r['axis']}: temperature or time? both explain the change on their own ({corr_txt}); "
                    f"{r['chosen']} explains it better (ΔBIC {r['delta_bic_chosen']:+.1f} vs {r['delta_bic_other']:+.1f} "
                    f"for {r['other']}), and {given}"
                )
            out.append({**r, "temperature_time_correlation": corr, "p_other_given_chosen": p_other, "text": verdict})
        return out

    def _note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    # ------------------------------------------------------------------ findings
    def findings(self, final: Fit, steps: list[Step]) -> list[dict[str, Any]]:
        """One finding per effect of the final model, with the evidence of dropping it."""
        out = []
        cov = self.covariance(final)
        free_beta = np.flatnonzero(active_mask(final.terms))
        position = {int(b): 9 + i for i, b in enumerate(free_beta)}
        bic_final = self.bic(final)
        mask = final.kept(self.n)
        after = self._rms(self.heldout(final), mask)
        for effect in PARAMETRIC:
            axes = sorted(a for (e, a) in final.terms if e == effect)
            if not axes:
                continue
            reduced = {k: v for k, v in final.terms.items() if k[0] != effect}
            without = self.fit(reduced, final.outliers, final.x)
            estimate, stderr, order, coefficients = {}, {}, {}, {}
            for a in axes:
                b = BETA_INDEX[(effect, a, 1)]
                h = self.reg.half_span(effect)
                estimate[AXES[a]] = float(final.x[9 + b] / h)
                stderr[AXES[a]] = float(np.sqrt(max(cov[position[b], position[b]], 0.0)) / h)
                order[AXES[a]] = final.terms[(effect, a)]
                coefficients[AXES[a]] = [
                    float(final.x[9 + BETA_INDEX[(effect, a, p)]] / h**p) for p in range(1, final.terms[(effect, a)] + 1)
                ]
            out.append({
                "effect": effect,
                "axes": [AXES[a] for a in axes],
                "estimate": estimate,
                "stderr": stderr,
                "units": UNITS[effect],
                "order": order,
                "coefficients": coefficients,
                "reference": self._reference(effect),
                "cause": CAUSES[effect],
                "evidence": {"delta_bic": bic_final - self.bic(without), "p_value": self.f_test(without, final)},
                "heldout_rms_g_before": self._rms(self.heldout(without), mask),
                "heldout_rms_g_after": after,
            })
        if final.outliers:
            without = self.fit(final.terms, frozenset(), final.x)
            p_values = [s.accepted["p_value"] for s in steps if s.accepted and s.accepted["effect"] == "outliers"]
            out.append({
                "effect": "outliers",
                "axes": [],
                "rows": [int(self.poses.rows[k]) for k in sorted(final.outliers)],
                "estimate": {},
                "stderr": {},
                "units": "rows",
                "cause": CAUSES["outliers"],
                "evidence": {"delta_bic": bic_final - self.bic(without), "p_value": float(min(p_values)) if p_values else 0.0},
                "heldout_rms_g_before": self._rms(self.heldout(without), mask),
                "heldout_rms_g_after": after,
            })
        return out

    def _reference(self, effect: str) -> dict[str, float]:
        if effect.startswith("temperature"):
            return {"temp_ref_c": self.reg.temp_ref}
        if effect == "bias_drift":
            return {"t_ref_s": self.reg.t_ref}
        return {}

    # ------------------------------------------------------------------ all
    def run(self) -> Diagnosis:
        baseline = self.fit({}, frozenset(), self.x_start)
        self.progress("k-fold held-out error of the baseline")
        base_heldout = self.heldout(baseline)
        self.progress(f"simulating the fitted model {self.simulations} times")
        sim = self.simulation_check(baseline)
        self.progress("forward selection over the candidate effects")
        final, steps, rivalries = self.select(baseline)
        findings = self.findings(final, steps)
        competitions = self._explain_rivalries(final, rivalries)
        sim_after = None
        if findings:
            self.progress("simulating the extended model")
            sim_after = self.simulation_check(final)
        model = to_model(final.x, self.norm.centre, self.norm.scale, self.reg)
        temp = self.poses.temp if self.reg.has_temp else None
        t = self.poses.t if self.reg.has_time else None
        d = model.correct(self.poses.acc, temp, t)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return Diagnosis(
            poses=self.poses,
            regressors=self.reg,
            effects_tested=self.effects,
            skipped=self.skipped,
            notes=self.notes,
            baseline=baseline,
            baseline_heldout=base_heldout,
            final=final,
            final_heldout=self.heldout(final),
            simulation=sim,
            simulation_after=sim_after,
            steps=steps,
            findings=findings,
            competitions=competitions,
            settings={"folds": self.folds_k, "simulations": self.simulations, "alpha": self.alpha, "band": self.band,
                      "seed": self.seed, "min_dof": MIN_DOF},
            units_scale=self.norm.scale,
            fitted_directions=d,
        )


def diagnose(poses: PoseTable, effects: Iterable[str] | str | None = None, **settings: Any) -> Diagnosis:
    """Diagnose a pose table: baseline, simulation check, selection, findings (module docstring).

    Parameters
    ----------
    poses : PoseTable
    effects : str or iterable of str, optional
        Candidate effects; default every effect the data support.
    **settings
        ``folds``, ``simulations``, ``alpha``, ``band``, ``seed``, ``progress`` (see :class:`Diagnoser`).
    """
    if not isinstance(poses, PoseTable):
        raise InputError("diagnose() takes a PoseTable; load DATA with optcal.data.load")
    return Diagnoser(poses, effects, **settings).run()


# ----------------------------------------------------------------------------- figures
def save_figures(diag: Diagnosis, directory: str) -> list[str]:
    """Residuals against temperature, time and each axis, before and after; the simulation check.

    Returns the paths written.
    """
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(directory)
    out_dir.mkdir(parents=True, exist_ok=True)
    poses = diag.poses
    xs: list[tuple[str, NDArray]] = []
    if poses.temp is not None:
        xs.append(("temperature (°C)", poses.temp))
    if poses.t is not None:
        xs.append(("time (s)", poses.t))
    for i, ax in enumerate(AXES):
        xs.append((f"force along {ax} (g)", diag.fitted_directions[:, i]))
    kept = diag.final.kept(diag.n)
    fig, axes = plt.subplots(2, len(xs), figsize=(3.2 * len(xs), 6), sharey="row", squeeze=False)
    for col, (label, x) in enumerate(xs):
        for row, (name, r) in enumerate((("baseline", diag.baseline.residuals), ("final", diag.final.residuals))):
            a = axes[row][col]
            a.axhline(0, color="0.6", lw=0.8)
            a.plot(x[kept], 1e3 * r[kept], "o", ms=3, color="C0" if row == 0 else "C2")
            if (~kept).any():
                a.plot(x[~kept], 1e3 * r[~kept], "x", ms=6, color="C3", label="outlier (zero weight)")
                a.legend(fontsize=7)
            a.set_xlabel(label)
            if col == 0:
                a.set_ylabel(f"{name} residual (mg)")
    fig.suptitle(f"Norm residuals before (baseline) and after ({diag.final.describe()})", fontsize=9)
    fig.tight_layout()
    paths = [str(out_dir / "residuals.png")]
    fig.savefig(paths[0], dpi=110)
    plt.close(fig)

    stats = diag.simulation["statistics"]
    names = [k for k, v in stats.items() if np.all(np.isfinite(v["band"]))]
    if names:
        fig, a = plt.subplots(figsize=(7, 0.32 * len(names) + 1.2))
        for k, name in enumerate(names):
            st = stats[name]
            lo, hi = st["band"]
            mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-300)
            a.plot([-1, 1], [k, k], color="0.7", lw=6, solid_capstyle="butt")
            z = (st["measured"] - mid) / half
            a.plot(np.clip(z, -4, 4), k, "o", color="C3" if st["outside"] else "C0")
        a.set_yticks(range(len(names)))
        a.set_yticklabels(names, fontsize=7)
        a.set_xlim(-4.2, 4.2)
        a.set_xlabel(f"measured statistic, scaled so that the simulated {diag.simulation['band'] * 100:g} % band is [-1, 1]")
        a.set_title("Simulation check of the baseline: red = outside the simulated band", fontsize=9)
        fig.tight_layout()
        paths.append(str(out_dir / "simulation_check.png"))
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths
