"""The magnetometer's diagnosis: the fitted ellipsoid's prediction against the samples, a local disturbance, a
temperature and a current named, the model extended, the gain on held-out samples (``optcal diagnose --sensor mag``).

The model (:mod:`optcal.families.mag.fit`): ``|T (m − o)| = 1`` for every sample of an undisturbed field.

1. **The band.**  The norm residual ``r = |T(m − o)| − 1`` of each sample is the model's error; its noise is
   measured, not assumed: the samples' white noise from the first differences of ``r`` (a smooth model error does
   not change from one sample to the next), and the noise of a mean of :data:`BLOCK` samples from the scatter of
   the blocks' means (batch means: correlated noise, slow turns through a misfit).  A block whose mean leaves
   ``±z σ_block`` (``z`` the normal quantile at the family-wise level α over the blocks) leaves the band.
2. **A local disturbance** (a magnet, steel, a powered device near the sensor for part of the session) adds a field
   for a contiguous stretch: the epidemic change-point model on the blocks' means (a stretch ``[a, b)`` whose mean
   differs from the rest's), its statistic ``n_in n_out / N · (r̄_in − r̄_out)² / σ²_block`` maximised over the
   stretches, against χ²₁ at the Bonferroni share of α over the ``B(B+1)/2`` stretches.  A significant stretch is
   named when it is **relevant**: the calibration fitted without it moves ``o`` or the field strength by more than
   :data:`RELEVANT_SE` of their standard errors.  Its field is estimated as an offset ``δ`` added inside the stretch
   (least squares on the stretch's samples with the undisturbed ``T``, ``o``); the extended model leaves the stretch
   out (counted).  Up to :data:`MAX_DISTURBANCES` stretches, each on what the previous left.
3. **Temperature and current** (a column of the recording: ``temp``; ``current``, else ``throttle``): the offsets
   linear in it, ``o + k (x − x̄)`` (ArduPilot's ``COMPASS_MOT`` idea for the current), fitted by Gauss–Newton with
   ``T`` held; named when the likelihood ratio, scaled to the residuals' effective sample size (the batch-means
   variance ratio), passes χ²₃ at the Bonferroni share of α and the held-out samples improve.
4. **The gain**: the rms norm residual on held-out samples (alternate blocks of :data:`HELD_OUT_BLOCKS` blocks, each
   half fitted on the other) outside every named stretch, of the plain model over the extended one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core import quantiles
from optcal.core.model import AXES
from optcal.core.norm_residual import norm_residuals
from optcal.errors import InputError
from optcal.families.mag.fit import MagSettings, fit_form
from optcal.families.mag.samples import MagSamples

#: Samples per block of the band and the change-point search: long enough for a block mean to average the white
#: noise of a 10-100 Hz magnetometer, short enough to place a disturbance's ends within a fraction of a second.
BLOCK: int = 25
#: Blocks per held-out half: alternate stretches of this many blocks fit and test each other (a disturbance and a
#: slow turn span several blocks, so both halves see each).
HELD_OUT_BLOCKS: int = 4
#: A disturbance is relevant when leaving it out moves the offsets or the field strength by more than this many
#: of their standard errors: a shift within one standard error changes no calibration.
RELEVANT_SE: float = 1.0
#: Most disturbed stretches looked for.
MAX_DISTURBANCES: int = 3
#: Fewest blocks in a stretch (shorter: a twitch of a hand, not a field).
MIN_STRETCH_BLOCKS: int = 2
#: Fewest samples the diagnosis needs (the calibration's minimum is lower; the blocks' scatter needs many blocks).
MIN_SAMPLES: int = 20 * BLOCK


@dataclass(frozen=True)
class MagFinding:
    """An effect named in the magnetometer (``"sensor": "magnetometer"``)."""

    effect: str
    axes: list[str]
    estimate: dict[str, float]
    evidence: dict[str, float]
    stretch: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"sensor": "magnetometer", "effect": self.effect, "axes": list(self.axes),
                               "estimate": dict(self.estimate), "evidence": dict(self.evidence)}
        if self.stretch is not None:
            out.update(self.stretch)
        return out

    def describe(self, units: str) -> str:
        values = ", ".join(f"{a} {v:+.4g}" for a, v in self.estimate.items())
        if self.effect == "local_disturbance" and self.stretch is not None:
            s = self.stretch
            when = (f"{s['start_s']:.2f}-{s['stop_s']:.2f} s" if s.get("start_s") is not None
                    else f"samples {s['start_sample']}-{s['stop_sample']}")
            return (f"local_disturbance {when}: a field of {values} {units} added ({s['stop_sample'] - s['start_sample']} "
                    f"samples left out; χ² {self.evidence['statistic']:.1f}, offsets moved {self.evidence['moved_se']:.1f} SE)")
        per = {"temperature_offset": f"{units} per °C", "current_interference": f"{units} per unit of the column"}
        return f"{self.effect}: {values} {per.get(self.effect, units)} (likelihood ratio {self.evidence['lr']:.1f}, held-out {self.evidence['heldout_ratio']:.3f}×)"


@dataclass
class MagDiagnosis:
    """What :func:`diagnose_mag` found."""

    findings: list[MagFinding]
    units: str
    n_samples: int
    block_means: NDArray[np.float64]
    band: float
    sigma_sample: float
    colour: float
    heldout_plain: float
    heldout_extended: float
    plain: dict[str, Any]
    extended: dict[str, Any]
    excluded: int
    notes: list[str] = field(default_factory=list)

    @property
    def gain(self) -> float:
        return self.heldout_plain / self.heldout_extended if self.heldout_extended > 0 else 1.0

    def to_dict(self) -> dict[str, Any]:
        outside = np.flatnonzero(np.abs(self.block_means) > self.band)
        return {
            "sensor": "magnetometer", "n_samples": self.n_samples, "findings": [f.to_dict() for f in self.findings],
            "gain": self.gain, "heldout_rms_norm_residual": {"plain": self.heldout_plain, "extended": self.heldout_extended},
            "band": {"block_samples": BLOCK, "half_width": self.band, "sigma_sample": self.sigma_sample,
                     "colour": self.colour, "blocks": int(self.block_means.size),
                     "blocks_outside": [[int(k) * BLOCK, (int(k) + 1) * BLOCK] for k in outside]},
            "plain": self.plain, "extended": self.extended, "excluded_samples": self.excluded, "notes": self.notes,
        }

    def report_lines(self) -> list[str]:
        outside = int(np.sum(np.abs(self.block_means) > self.band))
        out = ["MAGNETOMETER",
               f"  norm residual: {self.n_samples} samples, white σ {self.sigma_sample:.3g}, blocks of {BLOCK} "
               f"(noise colour {self.colour:.2g}); {outside} of {self.block_means.size} blocks outside the band "
               f"±{self.band:.3g} (family-wise over the blocks)"]
        if self.findings:
            out.append("  named:")
            out += [f"    {f.describe(self.units)}" for f in self.findings]
        else:
            out.append("  none named (an effect below the tests' power is not ruled out)")
        out.append(f"  held-out rms |T(m − o)| − 1 (outside every named stretch): {self.heldout_plain:.4g} → "
                   f"{self.heldout_extended:.4g} (gain {self.gain:.3f})")
        out.append(f"  extended model: o {np.round(self.extended['o'], 6).tolist()} {self.units}, field "
                   f"{self.extended['field_strength']:.6g} {self.units}; {self.excluded} samples left out")
        out += [f"  note: {n}" for n in self.notes]
        return out


def _blocks(r: NDArray[np.float64]) -> NDArray[np.float64]:
    k = r.size // BLOCK
    return np.asarray(r[: k * BLOCK].reshape(k, BLOCK).mean(axis=1))


#: Degree of the polynomial in the calibrated field's direction that carries the model's misfit with orientation (the
#: ellipsoid's own terms are degree 2; what is left of a real sensor's misfit, a nonlinearity or a field not quite
#: uniform over the turns, repeats wherever the sensor points the same way, and a disturbance does not).
ORIENTATION_DEGREE: int = 4


def _direction_basis(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """Monomials ``x^a y^b z^c`` (``a + b + c ≤`` :data:`ORIENTATION_DEGREE`) of unit vectors ``u`` (n, 3)."""
    cols = [u[:, 0] ** a * u[:, 1] ** b * u[:, 2] ** c
            for a in range(ORIENTATION_DEGREE + 1) for b in range(ORIENTATION_DEGREE + 1 - a)
            for c in range(ORIENTATION_DEGREE + 1 - a - b)]
    return np.column_stack(cols)


def orientation_misfit(r: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
    """The part of the norm residuals ``r`` that depends on the direction ``u`` alone (module docstring, 2): a
    polynomial in ``u`` fitted by Tukey's biweight on the blocks' means, so that a disturbance over a minority of
    the session, which does not repeat at the same orientation, is not absorbed."""
    X = _direction_basis(u)
    k = r.size // BLOCK
    Xb = X[: k * BLOCK].reshape(k, BLOCK, -1).mean(axis=1)
    rb = _blocks(r)
    w = np.ones(k)
    coef = np.zeros(X.shape[1])
    for _ in range(6):
        sw = np.sqrt(w)
        coef = np.linalg.lstsq(Xb * sw[:, None], rb * sw, rcond=None)[0]
        e = rb - Xb @ coef
        scale = max(1.4826 * float(np.median(np.abs(e))), 1e-300)
        z = e / (4.685 * scale)
        w = np.where(np.abs(z) < 1.0, (1.0 - z * z) ** 2, 0.0)
    return np.asarray(X @ coef)


def _noise(r: NDArray[np.float64]) -> tuple[float, float, float]:
    """The samples' white σ (first differences, robust), a block mean's σ (the blocks' own scatter about their
    median, robust: a disturbance over a minority of the blocks does not widen it) and the colour (a block mean's
    variance over the white noise's ``σ²/BLOCK``), of residuals ``r`` less their orientation misfit."""
    d = np.diff(r)
    white = float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))
    b = _blocks(r)
    block = float(1.4826 * np.median(np.abs(b - np.median(b)))) if b.size else white
    block = max(block, white / math.sqrt(BLOCK))
    return white, block, block**2 / max(white**2 / BLOCK, 1e-300)


def _fit(samples: MagSamples, keep: NDArray[np.bool_], form: str, settings: MagSettings) -> Any:
    sub = MagSamples(samples.m[keep], samples.units, path=samples.path)
    return fit_form(sub, form, settings)


def _stretch(b: NDArray[np.float64], sigma_b: float) -> tuple[int, int, float]:
    """The blocks ``[a, z)`` whose mean differs most from the rest's (epidemic change point), and its χ²₁ statistic."""
    B = b.size
    c = np.r_[0.0, np.cumsum(b)]
    best = (0, 0, 0.0)
    total = c[-1]
    for a in range(B):
        z = np.arange(a + MIN_STRETCH_BLOCKS, B + 1)
        if not z.size:
            break
        n_in = z - a
        n_out = B - n_in
        ok = n_out >= MIN_STRETCH_BLOCKS
        if not ok.any():
            continue
        s_in = c[z] - c[a]
        mean_in = s_in / n_in
        mean_out = (total - s_in) / np.maximum(n_out, 1)
        stat = np.where(ok, n_in * n_out / B * (mean_in - mean_out) ** 2 / sigma_b**2, 0.0)
        k = int(np.argmax(stat))
        if stat[k] > best[2]:
            best = (a, int(z[k]), float(stat[k]))
    return best


def _offset_in(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The field ``δ`` (data units) added to samples ``m`` of a fitted ``T``, ``o``: least squares of
    ``|T(m − o − δ)| − 1`` by Gauss–Newton; with its standard errors."""
    delta = np.zeros(3)
    for _ in range(20):
        v = (m - o - delta) @ T.T
        n = np.linalg.norm(v, axis=1)
        r = n - 1.0
        J = -(v / n[:, None]) @ T
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        delta = delta + step
        if np.linalg.norm(step) < 1e-12 * (1.0 + np.linalg.norm(delta)):
            break
    v = (m - o - delta) @ T.T
    n = np.linalg.norm(v, axis=1)
    J = -(v / n[:, None]) @ T
    r = n - 1.0
    dof = max(m.shape[0] - 3, 1)
    cov = np.linalg.pinv(J.T @ J) * float(r @ r) / dof
    return delta, np.sqrt(np.clip(np.diag(cov), 0.0, None))


#: The six entries of a symmetric ``T`` (upper triangle).
_SYM = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]


def _column_fit(m: NDArray[np.float64], x: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``T`` (symmetric), ``o`` and ``k`` of ``|T (m − o − k (x − x̄))| = 1`` by Gauss–Newton from ``T``, ``o``
    (all refitted: a column that changed with the session's turns pulled the plain fit's ``T`` and ``o`` too)."""
    xc = x - x.mean()
    p = np.r_[[T[i, j] for i, j in _SYM], o, np.zeros(3)]

    def unpack(q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        S = np.zeros((3, 3))
        for (i, j), v in zip(_SYM, q[:6]):
            S[i, j] = S[j, i] = v
        return S, q[6:9], q[9:12]

    for _ in range(30):
        S, oo, k = unpack(p)
        d = m - oo - np.outer(xc, k)
        v = d @ S.T
        n = np.linalg.norm(v, axis=1)
        r = n - 1.0
        e = v / n[:, None]
        cols = [e[:, i] * d[:, j] + (e[:, j] * d[:, i] if i != j else 0.0) for i, j in _SYM]
        g = -e @ S
        J = np.column_stack(cols + [g, g * xc[:, None]])
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        p = p + step
        if np.linalg.norm(step) < 1e-12 * (1.0 + np.linalg.norm(p)):
            break
    return unpack(p)


def _halves(n: int) -> NDArray[np.bool_]:
    """Alternate stretches of :data:`HELD_OUT_BLOCKS` blocks: True in one half."""
    return np.asarray((np.arange(n) // (BLOCK * HELD_OUT_BLOCKS)) % 2 == 0)


def _column_test(samples: MagSamples, x: NDArray[np.float64], keep: NDArray[np.bool_], T: NDArray[np.float64],
                 o: NDArray[np.float64], n_eff: float, halves: NDArray[np.bool_]
                 ) -> tuple[float, float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """The column's offsets ``o + k (x − x̄)`` against the plain model: the likelihood ratio at the effective sample
    size, the held-out ratio (each half's fits predicting the other), and the fit (T, o, k, x̄)."""
    m = samples.m
    ok = keep & np.isfinite(x)
    r0 = norm_residuals(T, o, m[ok])
    T1, o1, k1 = _column_fit(m[ok], x[ok], T, o)
    xm = float(x[ok].mean())
    r1 = np.linalg.norm((m[ok] - o1 - np.outer(x[ok] - xm, k1)) @ T1.T, axis=1) - 1.0
    lr = n_eff * math.log(float(r0 @ r0) / max(float(r1 @ r1), 1e-300))
    err0, err1 = [], []
    for train in (halves, ~halves):
        tr, te = ok & train, ok & ~train
        if tr.sum() < 10 or te.sum() < 10:
            continue
        Tt, ot, kt = _column_fit(m[tr], x[tr], T, o)
        T0, o0, _ = _column_fit(m[tr], np.zeros(int(tr.sum())), T, o)  # the plain model on the same half
        err1.append(np.linalg.norm((m[te] - ot - np.outer(x[te] - x[tr].mean(), kt)) @ Tt.T, axis=1) - 1.0)
        err0.append(norm_residuals(T0, o0, m[te]))
    ratio = float(np.sqrt(np.mean(np.concatenate(err0) ** 2) / np.mean(np.concatenate(err1) ** 2))) if err0 else 1.0
    return lr, ratio, T1, o1, k1, xm


def _heldout(samples: MagSamples, keep: NDArray[np.bool_], form: str, s: MagSettings, halves: NDArray[np.bool_],
             test_keep: NDArray[np.bool_], shift: Any = None) -> float:
    """The rms norm residual of each half's samples in ``test_keep`` under the model fitted to the other half's
    samples in ``keep`` (``shift(m, rows)``: the column terms' offsets removed first)."""
    m = samples.m if shift is None else shift(samples.m)
    sub = MagSamples(m, samples.units, path=samples.path)
    errors = []
    for train in (halves, ~halves):
        fit = _fit(sub, train & keep, form, s)
        errors.append(norm_residuals(fit.T, fit.o, m[~train & test_keep]))
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))


def diagnose_mag(samples: MagSamples, calibration: Any, settings: MagSettings | None = None,
                 alpha: float = 0.02) -> MagDiagnosis:
    """Diagnose a magnetometer's calibration on its samples (module docstring).

    Parameters
    ----------
    samples : MagSamples
    calibration : MagCalibrationResult
        The plain fit (:func:`optcal.families.mag.calibration.calibrate_mag`) of the same samples.
    settings : MagSettings, optional
        How the extended model is refitted (the plain fit's form is kept).
    alpha : float
        Family-wise false-finding level of each test.
    """
    if samples.n < MIN_SAMPLES:
        raise InputError(f"{samples.n} magnetometer samples; the diagnosis needs at least {MIN_SAMPLES} "
                         f"({MIN_SAMPLES // BLOCK} blocks of {BLOCK}) to measure the noise of a block mean")
    s = settings or MagSettings()
    fit = calibration.fit.fit
    form = fit.form
    m = samples.m
    T, o = fit.T, fit.o
    r = norm_residuals(T, o, m)
    u = ((m - o) @ T.T) / (r + 1.0)[:, None]
    misfit_free = r - orientation_misfit(r, u)
    white, sigma_b, colour = _noise(misfit_free)
    b = _blocks(misfit_free)
    b = b - np.median(b)  # the band is about the blocks' median: the misfit's own offset is not a departure
    B = b.size
    band = sigma_b * quantiles.norm_isf(0.5 * alpha / B)
    notes: list[str] = []
    findings: list[MagFinding] = []
    keep = np.ones(samples.n, dtype=bool)
    halves = _halves(samples.n)
    n_eff = max(samples.n / max(colour, 1.0), 4.0)
    # ------------------------------------------------------------------ temperature and current (named causes first)
    columns = []
    if samples.temp is not None:
        columns.append(("temperature_offset", samples.temp))
    if samples.current is not None:
        columns.append(("current_interference", samples.current))
    elif samples.throttle is not None:
        columns.append(("current_interference", samples.throttle))
    terms: list[tuple[str, NDArray[np.float64], NDArray[np.float64], float]] = []  # effect, x, k, x̄
    current_o = o
    for effect, x in columns:
        finite = x[np.isfinite(x)]
        if finite.size < MIN_SAMPLES or not np.ptp(finite) > 0:
            notes.append(f"{effect}: its column does not change (or holds fewer than {MIN_SAMPLES} numbers)")
            continue
        lr, ratio, _, o1, k1, xm = _column_test(samples, x, keep, T, current_o, n_eff, halves)
        critical = quantiles.chi2_isf(alpha / len(columns), 3)
        if lr > critical and ratio > 1.0:
            findings.append(MagFinding(effect, list(AXES), {a: float(v) for a, v in zip(AXES, k1)},
                                       {"lr": lr, "critical": critical, "heldout_ratio": ratio}))
            terms.append((effect, x, k1, xm))
            current_o = o1
        else:
            notes.append(f"{effect}: not named (likelihood ratio {lr:.1f} against {critical:.1f}, held-out {ratio:.3f}×)")

    def shifted(mm: NDArray[np.float64]) -> NDArray[np.float64]:
        out = mm
        for _, x, k, xm in terms:
            out = out - np.outer(np.nan_to_num(x - xm), k)
        return out

    m_used = shifted(m)
    base = MagSamples(m_used, samples.units, path=samples.path)
    current = _fit(base, keep, form, s) if terms else fit
    current_T, current_o = current.T, current.o
    se_o = np.array([fit.stderr.get(f"o_{a}", np.nan) for a in AXES])
    t_axis = samples.t if samples.t is not None and samples.t.size == samples.n else None
    # ------------------------------------------------------------------ local disturbances
    searched = np.ones(B, dtype=bool)
    for _ in range(MAX_DISTURBANCES):
        rr = norm_residuals(current_T, current_o, m_used)
        uu = ((m_used - current_o) @ current_T.T) / (rr + 1.0)[:, None]
        rb = _blocks(rr - orientation_misfit(rr, uu))
        live = np.flatnonzero(searched)
        if live.size < 2 * MIN_STRETCH_BLOCKS + 1:
            break
        a, z, stat = _stretch(rb[live] - np.median(rb[live]), sigma_b)
        pairs = live.size * (live.size + 1) / 2.0
        critical = quantiles.chi2_isf(alpha / pairs, 1)
        if stat <= critical:
            break
        if z - a > live.size // 2:  # a majority is the undisturbed field, not a local disturbance
            notes.append(f"the norm residual departs over {z - a} of {live.size} blocks: a majority, not a local "
                         "disturbance (the calibration itself, or a field that changed for good)")
            break
        lo, hi = int(live[a]) * BLOCK, int(live[z - 1] + 1) * BLOCK
        searched[int(live[a]):int(live[z - 1]) + 1] = False
        trial_keep = keep.copy()
        trial_keep[lo:hi] = False
        refit = _fit(base, trial_keep, form, s)
        moved = float(np.max(np.abs(refit.o - current_o) / np.where(se_o > 0, se_o, np.inf)))
        before_h = _heldout(base, keep, form, s, halves, trial_keep)
        after_h = _heldout(base, trial_keep, form, s, halves, trial_keep)
        if not (moved > RELEVANT_SE and after_h < before_h):
            notes.append(f"samples {lo}-{hi}: the norm residual departs (χ² {stat:.1f} > {critical:.1f}) but leaving "
                         f"them out moves the offsets by {moved:.2f} standard errors and the held-out residual "
                         f"{before_h:.4g} → {after_h:.4g}: not named")
            continue
        delta, delta_se = _offset_in(m_used[lo:hi], current_T, current_o)
        axes = [AXES[j] for j in range(3) if abs(delta[j]) > 2.0 * delta_se[j]]
        stretch = {"start_sample": lo, "stop_sample": hi,
                   "start_s": float(t_axis[lo]) if t_axis is not None else None,
                   "stop_s": float(t_axis[hi - 1]) if t_axis is not None else None}
        findings.append(MagFinding("local_disturbance", axes or list(AXES), {a: float(v) for a, v in zip(AXES, delta)},
                                   {"statistic": stat, "critical": critical, "moved_se": moved,
                                    "heldout_ratio": before_h / after_h}, stretch))
        keep = trial_keep
        current_T, current_o = refit.T, refit.o
    # ------------------------------------------------------------------ the gain on held-out samples
    heldout_plain = _heldout(samples, np.ones(samples.n, dtype=bool), form, s, halves, keep)
    heldout_ext = _heldout(samples, keep, form, s, halves, keep, shifted if terms else None)
    extended = {"T": current_T.tolist(), "o": list(map(float, current_o)),
                "field_strength": float(np.linalg.det(current_T) ** (-1.0 / 3.0)),
                "rms_norm_residual": float(np.sqrt(np.mean(norm_residuals(current_T, current_o, m_used[keep]) ** 2))),
                "terms": {e: {"k": k.tolist(), "reference": xm} for e, _, k, xm in terms}}
    plain = {"T": T.tolist(), "o": list(map(float, o)), "field_strength": float(np.linalg.det(T) ** (-1.0 / 3.0)),
             "rms_norm_residual": float(np.sqrt(np.mean(r**2)))}
    return MagDiagnosis(findings, samples.units.units, samples.n, b, band, white, colour, heldout_plain, heldout_ext,
                        plain, extended, int(samples.n - keep.sum()), notes)
