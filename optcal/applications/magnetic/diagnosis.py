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
   named when it is **relevant**: the calibration fitted without it turns the heading or changes the field strength
   by more than :data:`RELEVANT_SE` of their standard errors (:func:`calibration_change`, from the coloured noise:
   :func:`calibration_covariance`), and lowers the held-out residual by more than :data:`HELDOUT_SE` of that gain's
   own standard error (:func:`heldout_gain`).  Its field is estimated as an offset ``δ`` added inside the stretch
   (least squares on the stretch's samples with the undisturbed ``T``, ``o``); the extended model leaves the stretch
   out (counted).  Up to :data:`MAX_DISTURBANCES` stretches, each on what the previous left.

   **The dip channel.**  Steel or a magnet can bend the field without changing its strength.  Where the recording
   has an accelerometer, the angle between the calibrated field and gravity is the same at every orientation of an
   undisturbed sensor (``â · R m̂ = −sin δ``: Kok & Schön 2016, sec. 3; Vasconcelos 2011, eq. 24).  Its residual,
   ``δ_k − δ`` (degrees), is measured on the samples where the accelerometer shows the sensor near rest
   (:func:`optcal.families.mag.dip.rest_gate`: a linear acceleration tilts the measured vertical; with a gyroscope,
   also a turn's centripetal acceleration across gravity, which ``|a|`` does not see, and a lag), its noise as the
   norm's (white from the first differences of consecutive still samples, a block mean's from the robust scatter of
   the blocks with at least :data:`DIP_BLOCK_SHARE` of their samples still) once its misfit with the gravity direction
   is taken out (the raw accelerometer's own errors tilt the measured vertical by an amount that depends on where it
   points: :func:`dip_block_means`).  Each channel is searched by the same change-point statistic at its Bonferroni
   share of α (half each): a stretch is found whether its strength, its dip or both depart.  A majority stretch in
   one channel (the dip's slow drift over a session, say) ends that channel's search, not the other's.  It is
   relevant when leaving it out moves the heading, the field **or the dip** by more than :data:`RELEVANT_SE` standard
   errors and improves that channel's held-out residual by more than :data:`HELDOUT_SE` of the gain's standard error
   (the dip's: ``R`` and ``δ`` fitted on one half's still samples, its errors on the other's).  The dip's standard
   error is by batch means (:func:`batch_means_se`): a dip drifting over the session is no disturbance.
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
from optcal.data.rest_tests import unit_rows
from optcal.applications.magnetic.orientation import (
    BLOCKS_PER_TERM, DIP_ORIENTATION_DEGREE, ORIENTATION_DEGREE, biweight_fit, direction_basis, misfit_degree,
    orientation_misfit,
)
from optcal.families.mag.dip import MAX_DIP_SAMPLES, MIN_STILL, fit_dip, per_sample_dip, rest_gate
from optcal.families.mag.fit import (SYMMETRIC_ENTRIES, MagSettings, batch_means_stderr, fit_form,
                                     norm_residual_jacobian)
from optcal.families.mag.samples import MagSamples

#: Samples per block of the band and the change-point search: long enough for a block mean to average the white
#: noise of a 10-100 Hz magnetometer, short enough to place a disturbance's ends within a fraction of a second.
BLOCK: int = 25
#: Blocks per held-out half: alternate stretches of this many blocks fit and test each other (a disturbance and a
#: slow turn span several blocks, so both halves see each).
HELD_OUT_BLOCKS: int = 4
#: A disturbance is relevant when leaving it out turns the heading or changes the field strength by more than this
#: many of their standard errors (:func:`calibration_change`): a change within the calibration's own uncertainty
#: is one a user cannot tell from the calibration's error.
RELEVANT_SE: float = 1.0
#: ... and lowers the held-out mean square residual by more than this many of that gain's standard errors
#: (:func:`heldout_gain`): a misfit that depends on which turns the fit sees lowers it a little for any stretch.
HELDOUT_SE: float = 1.0
#: Most disturbed stretches looked for.
MAX_DISTURBANCES: int = 3
#: Fewest blocks in a stretch (shorter: a twitch of a hand, not a field).
MIN_STRETCH_BLOCKS: int = 2
#: A block's dip mean is used when at least this share of its samples are still: its white noise is then at most
#: √2 times a full block's, so one scatter describes every block used (fewer still samples: a block of motion, whose
#: measured vertical is tilted by the hand's acceleration, is left out of the dip channel, and counted).
DIP_BLOCK_SHARE: float = 0.5
#: Fewest usable blocks for the dip channel: their robust scatter is the block mean's noise (with fewer, the MAD's
#: own relative error, about 0.8/√k, is over 25 %), and a stretch needs blocks on both sides.
MIN_DIP_BLOCKS: int = 10
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
            left = s["stop_sample"] - s["start_sample"]
            if s.get("channel") == "dip":
                return (f"local_disturbance {when}: the field bent by {s['dip_shift_deg']:+.2f}° of dip, its strength "
                        f"unchanged ({left} samples left out; χ² dip {self.evidence['statistic_dip']:.1f}, strength "
                        f"{self.evidence['statistic_strength']:.1f}; the dip moved {self.evidence['moved_dip_se']:.1f} SE)")
            shift = s.get("dip_shift_deg")
            dip = (f", dip {shift:+.2f}° (the dip moved {self.evidence['moved_dip_se']:.1f} SE, held-out gain "
                   f"{self.evidence['heldout_dip_gain_se']:.1f} SE)" if shift is not None and math.isfinite(shift) else "")
            return (f"local_disturbance {when}: a field of {values} {units} added{dip} ({left} "
                    f"samples left out; χ² {self.evidence['statistic']:.1f}; leaving it out turns the heading "
                    f"{self.evidence['heading_deg']:.3g}° ({self.evidence['moved_heading_se']:.1f} SE), the field "
                    f"{self.evidence['field']:+.3g} {units} ({self.evidence['moved_field_se']:.1f} SE), held-out "
                    f"gain {self.evidence['heldout_gain_se']:.1f} SE)")
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
    dip: DipChannel | None = None
    heldout_dip_plain: float | None = None
    heldout_dip_extended: float | None = None

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
            "dip_channel": None if self.dip is None else {
                **self.dip.to_dict(), "heldout_rms_deg": {"plain": self.heldout_dip_plain,
                                                          "extended": self.heldout_dip_extended}},
        }

    def report_lines(self) -> list[str]:
        outside = int(np.sum(np.abs(self.block_means) > self.band))
        out = ["MAGNETOMETER",
               f"  norm residual: {self.n_samples} samples, white σ {self.sigma_sample:.3g}, blocks of {BLOCK} "
               f"(noise colour {self.colour:.2g}); {outside} of {self.block_means.size} blocks outside the band "
               f"±{self.band:.3g} (family-wise over the blocks)"]
        if self.dip is not None:
            d = self.dip
            out.append(f"  dip residual: {d.n_still} still samples, white σ {d.sigma_sample:.3g}°, a block's mean "
                       f"σ {d.sigma_block:.3g}° over {d.blocks_used} of {d.blocks} blocks at least "
                       f"{100 * DIP_BLOCK_SHARE:g} % still; held-out rms {self.heldout_dip_plain:.3g}° → "
                       f"{self.heldout_dip_extended:.3g}°")
            out.append(f"  near rest: {d.near_rest}")
        else:
            out.append("  dip residual: not searched (no accelerometer, or too few still blocks)")
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


@dataclass(frozen=True)
class DipChannel:
    """The dip residual's noise (module docstring, 2: the dip channel).

    Attributes
    ----------
    n_still : int
        Samples where the accelerometer shows the sensor near rest.
    sigma_sample : float
        White noise of a still sample's dip, degrees (first differences of consecutive still samples, robust).
    sigma_block : float
        Noise of a block's mean dip, degrees (the usable blocks' robust scatter).
    blocks_used, blocks : int
        Blocks with at least :data:`DIP_BLOCK_SHARE` of their samples still, of all blocks.
    dip_deg, dip_se_deg : float
        The plain calibration's dip and its standard error by batch means of the still samples' dips
        (:func:`batch_means_se`).
    rate_bound : float or None
        The gyroscope's rate bound of near rest, rad/s (:func:`optcal.families.mag.dip.rest_gate`); ``None`` without
        a gyroscope in rad/s or deg/s.
    n_turning : int
        Samples with ``|a|`` near g left out because the sensor turned faster.
    near_rest : str
        How near rest was decided (printed).
    """

    n_still: int
    sigma_sample: float
    sigma_block: float
    blocks_used: int
    blocks: int
    dip_deg: float
    dip_se_deg: float
    rate_bound: float | None = None
    n_turning: int = 0
    near_rest: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"still_samples": self.n_still, "sigma_sample_deg": self.sigma_sample,
                "sigma_block_deg": self.sigma_block, "blocks_used": self.blocks_used, "blocks": self.blocks,
                "dip_deg": self.dip_deg, "dip_se_deg": self.dip_se_deg, "rate_bound_rad_s": self.rate_bound,
                "turning_samples": self.n_turning, "near_rest": self.near_rest}


def _dip_fit(a: NDArray[np.float64], rows: NDArray[np.bool_], m: NDArray[np.float64], T: NDArray[np.float64],
             o: NDArray[np.float64], R0: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], float]:
    """``R`` and ``sin δ`` on the still samples ``rows`` (at most :data:`MAX_DIP_SAMPLES`, evenly spaced) of the
    field calibrated by ``T``, ``o`` (:func:`optcal.families.mag.dip.fit_dip`)."""
    index = np.flatnonzero(rows)
    index = index[:: max(1, index.size // MAX_DIP_SAMPLES)]
    R, sin_dip, _ = fit_dip(a[index], unit_rows((m[index] - o) @ T.T), R0=R0)
    return R, sin_dip


def _dip_residuals(a: NDArray[np.float64], still: NDArray[np.bool_], m: NDArray[np.float64], T: NDArray[np.float64],
                   o: NDArray[np.float64], R: NDArray[np.float64], sin_dip: float) -> NDArray[np.float64]:
    """``δ_k − δ`` in degrees at the still samples, NaN elsewhere (module docstring, 2)."""
    d = per_sample_dip(a, unit_rows((m - o) @ T.T) @ R.T) - math.degrees(math.asin(sin_dip))
    return np.where(still, d, np.nan)


def _masked_blocks(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Blocks' means of the finite values of ``d``; NaN where fewer than :data:`DIP_BLOCK_SHARE` of a block's are."""
    k = d.size // BLOCK
    ok = np.isfinite(d[: k * BLOCK]).reshape(k, BLOCK)
    count = ok.sum(axis=1)
    sums = np.where(ok, d[: k * BLOCK].reshape(k, BLOCK), 0.0).sum(axis=1)
    return np.where(count >= DIP_BLOCK_SHARE * BLOCK, sums / np.maximum(count, 1), np.nan)


def _dip_noise(d: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[float, float, int]:
    """The still samples' white σ (first differences of the dip residuals ``d``, robust), a usable block mean's σ (the
    robust scatter of the block means ``b``, :func:`dip_block_means`) and the usable blocks (as :func:`_noise`)."""
    values = d[np.isfinite(d)]
    diff = np.diff(values)
    white = float(1.4826 * np.median(np.abs(diff - np.median(diff))) / math.sqrt(2.0)) if diff.size else 0.0
    b = b[np.isfinite(b)]
    block = float(1.4826 * np.median(np.abs(b - np.median(b)))) if b.size else white
    return white, max(block, white / math.sqrt(BLOCK)), int(b.size)


def batch_means_se(v: NDArray[np.float64]) -> float:
    """The standard error of the mean of the correlated sequence ``v`` (its finite values, in order) by batch means
    (:func:`optcal.families.mag.fit.batch_means_stderr` of the mean: a slow drift of the dip over a session widens
    it, however many samples measure it)."""
    v = v[np.isfinite(v)]
    if v.size < 2:
        return float("inf")
    return float(batch_means_stderr(np.ones((v.size, 1)), v - v.mean())[0])


def _heldout_dip(a: NDArray[np.float64], still: NDArray[np.bool_], m: NDArray[np.float64], T: NDArray[np.float64],
                 o: NDArray[np.float64], keep: NDArray[np.bool_], halves: NDArray[np.bool_],
                 test_keep: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The dip residual (degrees) of each half's still samples in ``test_keep`` under ``R``, ``δ`` fitted on the
    other half's still samples in ``keep`` (the field calibrated by ``T``, ``o``), in sample order; NaN elsewhere."""
    out = np.full(m.shape[0], np.nan)
    for train in (halves, ~halves):
        rows, test = still & keep & train, still & test_keep & ~train
        if np.count_nonzero(rows) < MIN_STILL or not test.any():
            continue
        R, sin_dip = _dip_fit(a, rows, m, T, o)
        out[test] = _dip_residuals(a, test, m, T, o, R, sin_dip)[test]
    return out


def _rms(e: NDArray[np.float64]) -> float:
    """The rms of the finite held-out errors ``e`` (NaN: none)."""
    return float(np.sqrt(np.nanmean(e**2))) if np.isfinite(e).any() else float("nan")


def heldout_gain(before: NDArray[np.float64], after: NDArray[np.float64]) -> tuple[float, float]:
    """The held-out mean square error's decrease from ``before`` to ``after`` (the same samples in order, NaN: not
    held out) and its standard error by batch means of the paired differences (:func:`batch_means_se`): coloured
    errors, a slow turn through a misfit, count once per correlation length, not once per sample."""
    d = before**2 - after**2
    d = d[np.isfinite(d)]
    return (float(np.mean(d)), batch_means_se(d)) if d.size else (0.0, float("inf"))


def _blocks(r: NDArray[np.float64]) -> NDArray[np.float64]:
    k = r.size // BLOCK
    return np.asarray(r[: k * BLOCK].reshape(k, BLOCK).mean(axis=1))


def dip_block_means(d: NDArray[np.float64], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """The blocks' mean dip residuals (:func:`_masked_blocks` of ``d``, NaN where not usable) less their misfit with
    the gravity direction ``a`` (unit rows): the raw accelerometer's own scale, bias and misalignment tilt the
    measured vertical by an amount that depends on its direction, a polynomial in ``a`` (as
    :func:`orientation_misfit`, biweight on the usable blocks); a disturbance over a minority is not absorbed."""
    b = _masked_blocks(d)
    ok = np.isfinite(b)
    still = np.isfinite(d)
    X = np.where(still[:, None], direction_basis(np.where(still[:, None], a, 0.0), DIP_ORIENTATION_DEGREE), 0.0)
    if np.count_nonzero(ok) <= BLOCKS_PER_TERM * X.shape[1]:
        return b  # under two usable blocks per term of the polynomial: the misfit is not determined
    k = b.size
    counts = np.maximum(still[: k * BLOCK].reshape(k, BLOCK).sum(axis=1), 1)
    Xb = X[: k * BLOCK].reshape(k, BLOCK, -1).sum(axis=1) / counts[:, None]
    out = np.full(k, np.nan)
    out[ok] = b[ok] - Xb[ok] @ biweight_fit(Xb[ok], b[ok])
    return out


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
    """The blocks ``[a, z)`` whose mean differs most from the rest's (epidemic change point) and its χ²₁ statistic
    ``n_in n_out / N · (b̄_in − b̄_out)² / σ²_block``; blocks whose mean ``b`` is NaN (the dip channel's blocks with
    too few still samples) count on neither side."""
    B = b.size
    usable = np.isfinite(b)
    cv = np.r_[0, np.cumsum(usable)]
    c = np.r_[0.0, np.cumsum(np.where(usable, b, 0.0))]
    V = int(cv[-1])
    best = (0, 0, 0.0)
    total = c[-1]
    for a in range(B):
        z = np.arange(a + MIN_STRETCH_BLOCKS, B + 1)
        if not z.size or not V:
            break
        ok = (B - (z - a)) >= MIN_STRETCH_BLOCKS  # the stretch leaves blocks outside it
        n_in = cv[z] - cv[a]
        n_out = V - n_in
        ok &= (n_in >= MIN_STRETCH_BLOCKS) & (n_out >= MIN_STRETCH_BLOCKS)
        if not ok.any():
            continue
        s_in = c[z] - c[a]
        mean_in = s_in / np.maximum(n_in, 1)
        mean_out = (total - s_in) / np.maximum(n_out, 1)
        stat = np.where(ok, n_in * n_out / V * (mean_in - mean_out) ** 2 / sigma_b**2, 0.0)
        k = int(np.argmax(stat))
        if stat[k] > best[2]:
            best = (a, int(z[k]), float(stat[k]))
    return best


def _stretch_statistic(b: NDArray[np.float64], sigma_b: float, a: int, z: int) -> tuple[float, float]:
    """:func:`_stretch`'s statistic of the blocks ``[a, z)`` and the difference of the means in and out (NaN: the
    stretch or the rest has no usable block)."""
    usable = np.isfinite(b)
    inside = np.zeros(b.size, dtype=bool)
    inside[a:z] = True
    n_in, n_out = int(np.count_nonzero(usable & inside)), int(np.count_nonzero(usable & ~inside))
    if not n_in or not n_out:
        return 0.0, float("nan")
    diff = float(np.mean(b[usable & inside]) - np.mean(b[usable & ~inside]))
    return n_in * n_out / (n_in + n_out) * diff**2 / sigma_b**2, diff


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


def _column_fit(m: NDArray[np.float64], x: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``T`` (symmetric), ``o`` and ``k`` of ``|T (m − o − k (x − x̄))| = 1`` by Gauss–Newton from ``T``, ``o``
    (all refitted: a column that changed with the session's turns pulled the plain fit's ``T`` and ``o`` too)."""
    xc = x - x.mean()
    p = np.r_[[T[i, j] for i, j in SYMMETRIC_ENTRIES], o, np.zeros(3)]

    def unpack(q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        S = np.zeros((3, 3))
        for (i, j), v in zip(SYMMETRIC_ENTRIES, q[:6]):
            S[i, j] = S[j, i] = v
        return S, q[6:9], q[9:12]

    for _ in range(30):
        S, oo, k = unpack(p)
        d = m - oo - np.outer(xc, k)
        v = d @ S.T
        n = np.linalg.norm(v, axis=1)
        r = n - 1.0
        e = v / n[:, None]
        cols = [e[:, i] * d[:, j] + (e[:, j] * d[:, i] if i != j else 0.0) for i, j in SYMMETRIC_ENTRIES]
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
             test_keep: NDArray[np.bool_], shift: Any = None) -> NDArray[np.float64]:
    """The norm residual of each half's samples in ``test_keep`` under the model fitted to the other half's samples
    in ``keep`` (``shift(m)``: the column terms' offsets removed first), in sample order; NaN elsewhere."""
    m = samples.m if shift is None else shift(samples.m)
    sub = MagSamples(m, samples.units, path=samples.path)
    out = np.full(samples.n, np.nan)
    for train in (halves, ~halves):
        fit = _fit(sub, train & keep, form, s)
        out[~train & test_keep] = norm_residuals(fit.T, fit.o, m[~train & test_keep])
    return out


def calibration_covariance(m: NDArray[np.float64], fit: Any, white: float, colour: float) -> NDArray[np.float64]:
    """The covariance of the symmetric ``T``'s six entries and ``o`` (:func:`norm_residual_jacobian`'s order) from
    the coloured noise: a block mean's variance is ``colour · σ²_white / BLOCK``, so ``n`` samples carry the
    information of ``n / colour`` white ones (``σ²_white (JᵀJ)⁻¹ · colour``, in the fitted form's parameters),
    scaled up to meet the fit's batch-means standard errors of ``o`` where larger (batches up to a tenth of the
    session see a correlation longer than a block)."""
    J = norm_residual_jacobian(m, fit.T, fit.o)
    P = np.eye(9)
    if fit.form == "diagonal":
        P = P[:, [0, 3, 5, 6, 7, 8]]
    elif fit.form == "offsets":
        P = np.column_stack([P[:, 0] + P[:, 3] + P[:, 5], P[:, 6:]])
    C = P @ np.linalg.pinv((J @ P).T @ (J @ P)) @ P.T * white**2 * max(colour, 1.0)
    se_bm = np.array([fit.stderr.get(f"o_{a}", 0.0) for a in AXES])
    ratio = np.max(se_bm / np.sqrt(np.maximum(np.diag(C)[6:], 1e-300)))
    return np.asarray(C * max(float(ratio), 1.0) ** 2)


def calibration_change(T: NDArray[np.float64], o: NDArray[np.float64], T1: NDArray[np.float64],
                       o1: NDArray[np.float64], C: NDArray[np.float64]) -> dict[str, float]:
    """How far the calibration ``T1``, ``o1`` is from ``T``, ``o`` in what a user reads, each over its standard
    error from ``C`` (:func:`calibration_covariance`).

    * **The heading**: an offset error ``Δo`` turns the calibrated field by ``|T Δo|`` radians at most (its part
      across the unit field; the horizontal heading's error is that over cos(dip), as is its standard error, so the
      ratio holds at any dip); the standard error ``√tr(T C_o Tᵀ)``.
    * **The field strength** ``F = det(T)^(−1/3)``: ``∂F/∂T_ij = −F/3 · (T⁻¹)_ij`` (twice off the diagonal, both
      entries of the symmetric ``T``), its standard error ``√(gᵀ C g)``.
    """
    F, F1 = float(np.linalg.det(T) ** (-1.0 / 3.0)), float(np.linalg.det(T1) ** (-1.0 / 3.0))
    Ti = np.linalg.inv(T)
    g = np.zeros(9)
    g[:6] = [-F / 3.0 * Ti[i, j] * (1.0 if i == j else 2.0) for i, j in SYMMETRIC_ENTRIES]
    se_heading = math.degrees(math.sqrt(max(float(np.trace(T @ C[6:, 6:] @ T.T)), 0.0)))
    heading = math.degrees(float(np.linalg.norm(T @ (o1 - o))))
    se_field = math.sqrt(max(float(g @ C @ g), 0.0))
    return {"heading_deg": heading, "heading_se_deg": se_heading, "moved_heading_se": heading / max(se_heading, 1e-300),
            "field": F1 - F, "field_se": se_field, "moved_field_se": abs(F1 - F) / max(se_field, 1e-300)}


def diagnose_mag(samples: MagSamples, calibration: Any, settings: MagSettings | None = None,
                 alpha: float = 0.02, gyro_units: str | None = None) -> MagDiagnosis:
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
    gyro_units : str, optional
        The gyroscope's units (``--gyro-units``), instead of the decision from its samples (the dip's near rest).
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
    misfit_free = r - orientation_misfit(r, u, BLOCK)
    white, sigma_b, colour = _noise(misfit_free)
    b = _blocks(misfit_free)
    b = b - np.median(b)  # the band is about the blocks' median: the misfit's own offset is not a departure
    B = b.size
    band = sigma_b * quantiles.norm_isf(0.5 * alpha / B)
    notes: list[str] = []
    if (degree := misfit_degree(r.size // BLOCK)) < ORIENTATION_DEGREE:
        notes.append(f"the misfit with the direction taken out to degree {degree}, not {ORIENTATION_DEGREE}: "
                     f"{r.size // BLOCK} blocks determine no more terms (more than 2 blocks a term)")
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
    cov = calibration_covariance(m, fit, white, colour)
    t_axis = samples.t if samples.t is not None and samples.t.size == samples.n else None
    # ------------------------------------------------------------------ the dip channel (with an accelerometer)
    dip_channel: DipChannel | None = None
    a_unit = still = None
    R_cur, sin_cur = np.eye(3), 0.0
    if samples.acc is not None and samples.acc.shape == m.shape:
        acc = samples.acc
        finite = np.all(np.isfinite(acc), axis=1) & (np.linalg.norm(np.nan_to_num(acc), axis=1) > 0)
        gate = rest_gate(acc, samples.gyro, t_axis, gyro_units)
        still = gate.still & finite
        a_unit = np.where(finite[:, None], unit_rows(np.where(finite[:, None], acc, 1.0)), np.nan)
        if np.count_nonzero(still) >= MIN_STILL:
            R_cur, sin_cur = _dip_fit(a_unit, still & keep, m_used, current_T, current_o)
            d0 = _dip_residuals(a_unit, still, m_used, current_T, current_o, R_cur, sin_cur)
            d_white, d_block, d_used = _dip_noise(d0, dip_block_means(d0, a_unit))
            if d_used >= MIN_DIP_BLOCKS:
                dip_channel = DipChannel(int(np.count_nonzero(still)), d_white, d_block, d_used, B,
                                         math.degrees(math.asin(sin_cur)), batch_means_se(d0), gate.rate_bound,
                                         gate.n_turning, gate.reason)
            else:
                notes.append(f"dip channel: {d_used} blocks with at least {100 * DIP_BLOCK_SHARE:g} % of their samples "
                             f"still (fewer than {MIN_DIP_BLOCKS}): only the field strength searched; near rest: "
                             f"{gate.reason}")
        else:
            notes.append(f"dip channel: {int(np.count_nonzero(still))} still samples (fewer than {MIN_STILL}): only the "
                         f"field strength searched; near rest: {gate.reason}")
    # ------------------------------------------------------------------ local disturbances
    searched = np.ones(B, dtype=bool)
    channels = {"strength"} | ({"dip"} if dip_channel is not None else set())
    tried = 0
    while tried < MAX_DISTURBANCES and channels:
        rr = norm_residuals(current_T, current_o, m_used)
        uu = ((m_used - current_o) @ current_T.T) / (rr + 1.0)[:, None]
        rb = _blocks(rr - orientation_misfit(rr, uu, BLOCK))
        live = np.flatnonzero(searched)
        if live.size < 2 * MIN_STRETCH_BLOCKS + 1:
            break
        rb = rb[live] - np.median(rb[live])
        bd = None
        if dip_channel is not None and a_unit is not None and still is not None:
            bd = dip_block_means(_dip_residuals(a_unit, still, m_used, current_T, current_o, R_cur, sin_cur), a_unit)[live]
            bd = bd - np.nanmedian(bd) if np.isfinite(bd).any() else bd
        # each channel searched at its Bonferroni share of α (over the channels and the stretches); the larger
        # statistic of those that pass is the stretch examined
        pairs = live.size * (live.size + 1) / 2.0
        critical = quantiles.chi2_isf(alpha / (len(channels) * pairs), 1)
        found = {"strength": _stretch(rb, sigma_b)}
        if "dip" in channels and bd is not None and dip_channel is not None:
            found["dip"] = _stretch(bd, dip_channel.sigma_block)
        passing = {c: v for c, v in found.items() if c in channels and v[2] > critical}
        if not passing:
            break
        channel = max(passing, key=lambda c: passing[c][2])
        a, z, stat = passing[channel]
        stat_n = _stretch_statistic(rb, sigma_b, a, z)[0]
        stat_d, dip_shift = (_stretch_statistic(bd, dip_channel.sigma_block, a, z) if bd is not None
                             and dip_channel is not None else (0.0, float("nan")))
        if z - a > live.size // 2:  # a majority is the undisturbed field, not a local disturbance
            what = "norm residual" if channel == "strength" else "dip"
            notes.append(f"the {what} departs over {z - a} of {live.size} blocks: a majority, not a local disturbance "
                         + ("(the calibration itself, or a field that changed for good)" if channel == "strength" else
                            "(the dip's slow change over the session: an accelerometer's bias drifting with "
                            "temperature tilts the measured vertical)") + f"; the {channel} channel searched no further")
            channels.discard(channel)
            continue
        tried += 1
        lo, hi = int(live[a]) * BLOCK, int(live[z - 1] + 1) * BLOCK
        searched[int(live[a]):int(live[z - 1]) + 1] = False
        trial_keep = keep.copy()
        trial_keep[lo:hi] = False
        refit = _fit(base, trial_keep, form, s)
        change = calibration_change(current_T, current_o, refit.T, refit.o, cov)
        moved = max(change["moved_heading_se"], change["moved_field_se"])
        before_e = _heldout(base, keep, form, s, halves, trial_keep)
        after_e = _heldout(base, trial_keep, form, s, halves, trial_keep)
        before_h, after_h = _rms(before_e), _rms(after_e)
        gain, gain_se = heldout_gain(before_e, after_e)
        strength_relevant = moved > RELEVANT_SE and gain > HELDOUT_SE * gain_se
        dip_info: dict[str, float] = {}
        dip_relevant = False
        R_new, sin_new = R_cur, sin_cur
        if bd is not None and dip_channel is not None and a_unit is not None and still is not None:
            R_new, sin_new = _dip_fit(a_unit, still & trial_keep, m_used, refit.T, refit.o, R_cur)
            # the standard error of the dip fitted without the stretch (batch means of what is left: the stretch's
            # own departure would otherwise widen the scatter it is measured against)
            se_dip = batch_means_se(_dip_residuals(a_unit, still & trial_keep, m_used, refit.T, refit.o, R_new, sin_new))
            moved_dip = abs(math.degrees(math.asin(sin_new)) - math.degrees(math.asin(sin_cur))) / se_dip
            before_de = _heldout_dip(a_unit, still, m_used, current_T, current_o, keep, halves, trial_keep)
            after_de = _heldout_dip(a_unit, still, m_used, refit.T, refit.o, trial_keep, halves, trial_keep)
            before_d, after_d = _rms(before_de), _rms(after_de)
            gain_d, gain_d_se = heldout_gain(before_de, after_de)
            dip_relevant = moved_dip > RELEVANT_SE and gain_d > HELDOUT_SE * gain_d_se
            # the bend: the stretch's mean dip residual under the dip fitted without it (the search's block means
            # are under the fit with it, which the bend pulls)
            inside = _dip_residuals(a_unit, still, m_used, refit.T, refit.o, R_new, sin_new)[lo:hi]
            if np.isfinite(inside).any():
                dip_shift = float(np.nanmean(inside))
            dip_info = {"statistic_dip": stat_d, "statistic_strength": stat_n, "moved_dip_se": moved_dip,
                        "heldout_dip_ratio": before_d / after_d if after_d > 0 else 1.0, "dip_shift_deg": dip_shift,
                        "heldout_dip_gain_se": gain_d / gain_d_se if gain_d_se > 0 else 0.0}
        if not (strength_relevant or dip_relevant):
            dip_text = (f"; the dip by {dip_info['moved_dip_se']:.2f} SE, its held-out residual "
                        f"×{1.0 / dip_info['heldout_dip_ratio']:.3f} ({dip_info['heldout_dip_gain_se']:.2f} SE)"
                        if dip_info else "")
            notes.append(f"samples {lo}-{hi}: the field departs (χ² {stat:.1f} > {critical:.1f}) but leaving "
                         f"them out turns the heading by {change['heading_deg']:.3g}° ({change['moved_heading_se']:.2f}"
                         f" SE), the field by {change['field']:+.3g} {samples.units.units} ({change['moved_field_se']:.2f}"
                         f" SE), the held-out residual {before_h:.4g} → {after_h:.4g} ({gain / gain_se:.2f} SE of its "
                         f"gain){dip_text}: not named (relevant: more than {RELEVANT_SE:g} SE and a held-out gain "
                         f"of more than {HELDOUT_SE:g} SE)")
            continue
        delta, delta_se = _offset_in(m_used[lo:hi], current_T, current_o)
        axes = [AXES[j] for j in range(3) if abs(delta[j]) > 2.0 * delta_se[j]]
        stretch: dict[str, Any] = {"start_sample": lo, "stop_sample": hi,
                                   "start_s": float(t_axis[lo]) if t_axis is not None else None,
                                   "stop_s": float(t_axis[hi - 1]) if t_axis is not None else None}
        if dip_info:
            # which channels depart (each at its share of α): a field that bends without changing its strength is
            # "dip", one that changes its strength alone "strength"
            both = stat_d > critical and stat_n > critical
            stretch.update(channel="both" if both else channel, dip_shift_deg=dip_info["dip_shift_deg"])
        findings.append(MagFinding("local_disturbance", axes or list(AXES), {a: float(v) for a, v in zip(AXES, delta)},
                                   {"statistic": stat, "critical": critical, "moved_se": moved,
                                    "heldout_ratio": before_h / after_h, "heldout_gain_se": gain / gain_se,
                                    **change, **dip_info}, stretch))
        keep = trial_keep
        current_T, current_o = refit.T, refit.o
        R_cur, sin_cur = R_new, sin_new
    # ------------------------------------------------------------------ the gain on held-out samples
    heldout_plain = _rms(_heldout(samples, np.ones(samples.n, dtype=bool), form, s, halves, keep))
    heldout_ext = _rms(_heldout(samples, keep, form, s, halves, keep, shifted if terms else None))
    dip_plain = dip_ext = None
    if dip_channel is not None and a_unit is not None and still is not None:
        dip_plain = _rms(_heldout_dip(a_unit, still, m, T, o, np.ones(samples.n, dtype=bool), halves, keep))
        dip_ext = _rms(_heldout_dip(a_unit, still, m_used, current_T, current_o, keep, halves, keep))
    extended = {"T": current_T.tolist(), "o": list(map(float, current_o)),
                "field_strength": float(np.linalg.det(current_T) ** (-1.0 / 3.0)),
                "rms_norm_residual": float(np.sqrt(np.mean(norm_residuals(current_T, current_o, m_used[keep]) ** 2))),
                "terms": {e: {"k": k.tolist(), "reference": xm} for e, _, k, xm in terms}}
    if dip_channel is not None:
        extended.update(dip_deg=math.degrees(math.asin(sin_cur)), R_mag_to_acc=R_cur.tolist())
    plain = {"T": T.tolist(), "o": list(map(float, o)), "field_strength": float(np.linalg.det(T) ** (-1.0 / 3.0)),
             "rms_norm_residual": float(np.sqrt(np.mean(r**2)))}
    return MagDiagnosis(findings, samples.units.units, samples.n, b, band, white, colour, heldout_plain, heldout_ext,
                        plain, extended, int(samples.n - keep.sum()), notes, dip_channel, dip_plain, dip_ext)
