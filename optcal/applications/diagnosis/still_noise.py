"""The noise of a pose mean measured on the recording's own still parts (the measured route of the noise model).

A pose's σ from its own samples (``σ/√n``, batch means within its interval) cannot see noise
correlated at the time scale of the pose.  The Allan deviation can: for an averaging time τ,
``σ_A(τ)`` is the scatter of successive τ-second means (Yin 2014, eq. 5), so ``σ_A(τ_k)`` at a
pose's dwell ``τ_k`` is the noise of that pose's mean, white or not (for white noise it equals
``σ/√n``).  It is measured on the longest still stretch of the recording with the project's one
Allan deviation (:func:`optcal.families.noise.allan.allan_deviation`), the three axes pooled (rms).

Two routes, the first that reaches the poses' time scale:

* **the longest still stretch**, when it is long enough for the Allan deviation to reach the
  median dwell (nine clusters, :func:`optcal.families.noise.allan.octave_taus`);
* otherwise **every still interval pooled** (a raw recording's poses are rarely longer than a
  few seconds): the overlapping Allan variance of each interval at octave τ up to half its
  length (:func:`optcal.families.noise.allan.overlapping_adev`, the numbers of allantools' ``oadev``), pooled over the
  intervals and axes with their numbers of differences as weights.  Each interval's own mean
  drops out of the differences, so the pose means do not enter.

A dwell longer than the largest τ measured is extrapolated along the curve's last log-log
slope, clipped to [−½, 0]: no steeper fall than white noise, no rise beyond a flicker floor
(a still-rising curve is held at its last value, which can only understate).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.core.poses import PoseTable

if TYPE_CHECKING:
    from optcal.data.static import Segmentation
    from optcal.families.noise.allan import AllanCurve

#: Why a pose table alone allows only the residual route.
POSE_TABLE_ONLY = ("a pose table without raw samples: the noise of a pose mean cannot be measured, "
                   "only estimated from the residuals (the residual route)")


@dataclass
class MeasuredPoseNoise:
    """The noise of every pose mean measured from still samples, or why it could not be.

    Attributes
    ----------
    sigma : ndarray, shape (n,) or None
        Standard deviation of each pose's mean (raw units, pooled over the axes); ``None`` when
        not measured.
    source : str
        Where it was measured (or why not).
    stretch_s : float
        Length of the still stretch(es) used, s (the longest per session).
    taus_s, adev : ndarray
        The pooled Allan deviation curve (raw units) of the (first) stretch.
    curves : list of AllanCurve or None
        Each axis's Allan curve (with its equivalent degrees of freedom) when the longest still
        stretch alone was long enough; ``None`` for the pooled intervals.
    """

    sigma: NDArray[np.float64] | None
    source: str
    stretch_s: float = 0.0
    taus_s: NDArray[np.float64] | None = None
    adev: NDArray[np.float64] | None = None
    curves: "list[AllanCurve] | None" = None

    @property
    def measured(self) -> bool:
        return self.sigma is not None


def mean_noise_at(taus: NDArray[np.float64], adev: NDArray[np.float64], tau: NDArray[np.float64]) -> NDArray[np.float64]:
    """``σ_A(τ)`` at the dwells ``tau``: log-log interpolation, beyond the curve its last slope clipped to [−½, 0]."""
    log_t, log_a = np.log(taus), np.log(adev)
    inside = np.interp(np.log(tau), log_t, log_a)
    slope = 0.0 if taus.size < 2 else float(np.clip((log_a[-1] - log_a[-2]) / (log_t[-1] - log_t[-2]), -0.5, 0.0))
    beyond = log_a[-1] + slope * (np.log(tau) - log_t[-1])
    return np.exp(np.where(tau > taus[-1], beyond, inside))


def pooled_interval_adev(acc: NDArray[np.float64], spans: Sequence[tuple[int, int]],
                         rate_hz: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Overlapping Allan deviation at octave τ pooled over the still intervals ``spans`` and the axes (module docstring)."""
    from optcal.families.noise.allan import overlapping_adev, phase_from_rate

    longest = max(stop - start for start, stop in spans)
    ms = 2 ** np.arange(int(np.floor(np.log2(max((longest - 1) // 2, 1)))) + 1)
    total, count = np.zeros(ms.size), np.zeros(ms.size)
    for start, stop in spans:
        length = stop - start
        usable = ms[ms <= (length - 1) // 2]
        if usable.size == 0:
            continue
        for axis in range(3):
            x = acc[start:stop, axis]
            if np.ptp(x) == 0:
                continue
            adev, n = overlapping_adev(phase_from_rate(x, rate_hz), rate_hz, usable)
            index = np.searchsorted(ms, usable)
            total[index] += n * adev**2
            count[index] += n
    keep = count > 0
    return ms[keep] / rate_hz, np.sqrt(total[keep] / count[keep])


def pose_noise_from_still_parts(poses: PoseTable, segmentation: "Segmentation | None") -> MeasuredPoseNoise:
    """Measure the noise of every pose mean of ``poses`` on the still parts of its recording (module docstring).

    ``segmentation`` is the static detection ``poses`` came from (``None`` for a pose table).
    """
    from optcal.families.noise.allan import allan_deviation

    if segmentation is None or not segmentation.intervals:
        return MeasuredPoseNoise(None, POSE_TABLE_ONLY)
    rec = segmentation.recording
    by_number = {iv.number: iv for iv in segmentation.intervals}
    if not all(int(r) in by_number for r in poses.rows):
        raise InputError("the poses do not come from this segmentation (their rows are not its interval numbers)")
    dwell = np.array([by_number[int(r)].n_samples / rec.rate_hz for r in poses.rows])
    longest = max(segmentation.intervals, key=lambda iv: iv.n_samples)
    try:
        samples = rec.acc[longest.start:longest.stop]
        curves = [allan_deviation(samples[:, i], rec.rate_hz) for i in range(3)]
        taus = curves[0].taus
        adev = np.sqrt(np.mean([c.adev**2 for c in curves], axis=0))  # the axes pooled, as a pose's σ is
        reaches = bool(taus[-1] >= np.median(dwell))
    except InputError:
        reaches = False
    if reaches:
        source = (f"Allan deviation of the longest still stretch ({longest.duration_s:.3g} s, pose {longest.number}) "
                  "at each pose's dwell")
        return MeasuredPoseNoise(mean_noise_at(taus, adev, dwell), source, float(longest.duration_s), taus, adev,
                                 curves)
    spans = [(iv.start, iv.stop) for iv in segmentation.intervals]
    taus, adev = pooled_interval_adev(rec.acc, spans, rec.rate_hz)
    if taus.size == 0:
        return MeasuredPoseNoise(None, "the still intervals are too short for an Allan variance; "
                                       "only the residual route is available")
    source = (f"Allan variance of all {len(spans)} still intervals pooled (τ up to {taus[-1]:.3g} s; the longest "
              f"stretch, {longest.duration_s:.3g} s, is too short to reach the {np.median(dwell):.3g} s dwell alone) "
              "at each pose's dwell")
    return MeasuredPoseNoise(mean_noise_at(taus, adev, dwell), source, float(longest.duration_s), taus, adev)


def stack_measured(parts: Sequence[MeasuredPoseNoise]) -> MeasuredPoseNoise:
    """The measured noise of several sessions, pose after pose (not measured when any session is not)."""
    missing = [p.source for p in parts if not p.measured]
    if missing:
        return MeasuredPoseNoise(None, missing[0])
    sigma = np.concatenate([p.sigma for p in parts if p.sigma is not None])
    return MeasuredPoseNoise(sigma, "per session: " + "; ".join(p.source for p in parts),
                             min(p.stretch_s for p in parts), parts[0].taus_s, parts[0].adev, parts[0].curves)
