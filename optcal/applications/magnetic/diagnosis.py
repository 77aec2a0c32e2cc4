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

Each step is its own module, this one runs them (:func:`diagnose_mag`): the band and its noise
(:mod:`~optcal.applications.magnetic.band`), the dip channel (:mod:`~optcal.applications.magnetic.dip_channel`), the
disturbance search and its relevance (:mod:`~optcal.applications.magnetic.stretches`), temperature and current
(:mod:`~optcal.applications.magnetic.columns`), the held-out comparison (:mod:`~optcal.applications.magnetic.heldout`)
and what was found (:mod:`~optcal.applications.magnetic.findings`); their public names are importable from here too.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

# the diagnosis's concepts, one module each (and importable from here, as before)
from optcal.applications.magnetic.band import BLOCK, _blocks, _noise, batch_means_se
from optcal.applications.magnetic.orientation import ORIENTATION_DEGREE, misfit_degree, orientation_misfit
from optcal.applications.magnetic.columns import _column_test
from optcal.applications.magnetic.dip_channel import (DIP_BLOCK_SHARE, DIP_ORIENTATION_DEGREE, DipChannel, _dip_fit,
                                                      _dip_noise, _dip_residuals, dip_block_means)
from optcal.applications.magnetic.findings import MagDiagnosis, MagFinding
from optcal.applications.magnetic.heldout import (HELD_OUT_BLOCKS, _fit, _halves, _heldout, _heldout_dip, _rms,
                                                  heldout_gain)
from optcal.applications.magnetic.stretches import (MIN_STRETCH_BLOCKS, _offset_in, _stretch, _stretch_statistic,
                                                    calibration_change, calibration_covariance)
from optcal.core import quantiles
from optcal.core.model import AXES
from optcal.core.norm_residual import norm_residuals
from optcal.errors import InputError
from optcal.data.rest_tests import unit_rows
from optcal.families.mag.dip import MIN_STILL, rest_gate
from optcal.families.mag.fit import MagSettings
from optcal.families.mag.samples import MagSamples

#: A disturbance is relevant when leaving it out turns the heading or changes the field strength by more than this
#: many of their standard errors (:func:`calibration_change`): a change within the calibration's own uncertainty
#: is one a user cannot tell from the calibration's error.
RELEVANT_SE: float = 1.0
#: ... and lowers the held-out mean square residual by more than this many of that gain's standard errors
#: (:func:`heldout_gain`): a misfit that depends on which turns the fit sees lowers it a little for any stretch.
HELDOUT_SE: float = 1.0
#: Most disturbed stretches looked for.
MAX_DISTURBANCES: int = 3
#: Fewest usable blocks for the dip channel: their robust scatter is the block mean's noise (with fewer, the MAD's
#: own relative error, about 0.8/√k, is over 25 %), and a stretch needs blocks on both sides.
MIN_DIP_BLOCKS: int = 10
#: Fewest samples the diagnosis needs (the calibration's minimum is lower; the blocks' scatter needs many blocks).
MIN_SAMPLES: int = 20 * BLOCK


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
