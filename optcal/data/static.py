"""Static detection: a raw recording in, static intervals and one pose per interval out.

A sample is static when the centred moving window around it (``window_s``) is quiet:

* the moving standard deviation of the norm ``‖a − o_nom‖`` (``o_nom`` the nominal
  zero, :func:`optcal.data.units.nominal_conversion`) stays below ``threshold`` times
  its noise floor, **and**
* the moving standard deviation summed over the three axes (IMU-TK's statistic,
  Tedaldi et al. 2014) stays below ``threshold`` times its floor: the norm alone is blind
  to a rotation, the axes are not;
* the means of the two halves of the window differ by less than ``drift_threshold``
  times the noise of that difference (``2 σ_axes/√window``, from the axes floor): a slow
  creep that hides in the moving variance moves the mean;
* when gyro columns exist, the windowed mean rate ``‖mean(ω) − b_ω‖`` (``b_ω`` the gyro
  bias, the median gyro reading over the accelerometer-static samples) stays below
  ``gyro_threshold`` times the gyro's per-sample noise floor (the floor of its moving
  standard deviation, summed over the axes).  This is what catches a slow turn, above
  all one about the vertical, which no accelerometer statistic can see.  The gyro's
  spread itself is not gated: a hand-held pose trembles (the MPU-6050 log's poses show
  5× the table-top gyro spread) without moving its mean.

Each noise floor is measured on the recording itself: the ``floor_quantile`` quantile of
the statistic over all windows (a calibration recording is mostly at rest, so the low
quantiles are windows at rest), never below the resolution of the data; the axes floor
is capped at :data:`AXES_TO_NORM_MAX` times the norm floor, and the floor of quantised gyro
data at :data:`GYRO_FLOOR_MAX_QUANTA` steps, so that a recording that never rests (its
quietest windows still turn) is not taken for one at rest.  Windows at rest share one noise
level, so the low quantiles of the axes statistic form a plateau; a recording whose
``floor_quantile / 5`` quantile falls far below its floor (:func:`rest_plateau_limit`) has
no rest, only the slowest moments of a motion, and gives no pose (with a gyro whose
converter step does not settle it, or none).  Static runs are split at time gaps, runs
shorter than ``min_dwell_s`` are dropped, ``trim_s`` is cut from both ends of each remaining
run, runs of one orientation interrupted for less than a window by a hand's twitch are joined
into one pose (:func:`optcal.data.static_stretches.join_interrupted`), a stretch whose means
over one-window blocks sweep further than the accelerometer gate is a slow turn, not a rest
(:func:`optcal.data.static_stretches.sweep`: a turn about an axis near the vertical keeps ‖a‖
and moves the axes by less than the noise within a window), and every sample that does not
end in a pose is counted by reason.  The moving statistics take one cumulative sum per column
in one set of reused buffers (:class:`optcal.data.window_stats.MovingWindow`); the gyro's are
computed in a second thread beside the accelerometer's for recordings up to
:data:`PARALLEL_MAX_SAMPLES` samples.  Each interval gives one pose
(:func:`optcal.data.static_poses.reduce_interval`): the mean, the per-axis standard
deviation, the standard deviation of the mean ``σ_k`` (for the maximum-likelihood weights,
Lu 2017 eq. 14; by batch means, :func:`optcal.data.static_poses.sigma_of_mean`, since sensor
noise is not white), the sample count, the mid time, the mean temperature and the mean gyro
reading.

This module decides; the moving-window statistics and floors are
:mod:`optcal.data.window_stats`, the runs of static samples and their grouping
:mod:`optcal.data.static_stretches`, the pose of each interval :mod:`optcal.data.static_poses`.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.poses import PoseTable
from optcal.data.quantiles import median, quantiles
from optcal.data.recording import Recording
from optcal.data.static_poses import StaticInterval, reduce_interval
from optcal.data.static_stretches import (
    group_positions,
    join_interrupted,
    reject_sweeping,
    reject_turning,
    split_runs,
    true_runs,
)
from optcal.data.units import nominal_conversion
from optcal.data.window_stats import STEP_CHUNK, HalfWindowDrift, MovingWindow, noise_floor, quantum, resolution
from optcal.errors import InputError

MOVING = "samples in non-static stretches"
SHORT = "samples in static stretches shorter than the minimum dwell"
SHORT_STRETCHES = "static stretches shorter than the minimum dwell"
TRIMMED = "samples trimmed at the ends of static intervals"
TURNING = "samples in quiet stretches whose gyro noise is above a resting gyro's (the recording never rests)"
TURNING_STRETCHES = "quiet stretches rejected because their gyro noise is above a resting gyro's"
SWEEPING = "samples in quiet stretches whose mean moves along the axes by more than the accelerometer gate (a slow turn)"
SWEEPING_STRETCHES = "quiet stretches rejected because their mean moves along the axes by more than the accelerometer gate"
NO_REST = "samples in quiet stretches of a recording whose quietest windows share no noise level (it never rests)"
NO_REST_STRETCHES = "quiet stretches rejected because the recording never rests (no plateau of resting noise)"
#: Fraction of the white-noise expectation (:func:`rest_plateau_limit`) below which the ratio of
#: the low quantile (``floor_quantile / 5``) of the axes moving std to its floor quantile says
#: that the quietest windows share no noise level: the recording never rests.  Windows at rest
#: share the sensor's noise (the measured ratio is 0.94-0.96 on every resting recording of
#: ../shared/data); the quietest windows of a continuous motion are its slowest moments, spread
#: down to the noise (0.53-0.72 on the sunsided motion logs without their gyro).
REST_PLATEAU_FRACTION: float = 0.85
#: Windows a recording needs before the plateau of resting noise is looked for.
PLATEAU_MIN_WINDOWS: int = 10
#: Recordings up to this many samples compute the gyro's moving statistics in a second thread beside the
#: accelerometer's (≈ 0.1 s less wall time for 10⁶ samples on two cores); the thread's own buffers and the
#: three moving means it keeps until the gyro bias is known take seven columns (≤ 235 MB at this size).
#: Longer recordings compute them after the accelerometer's, in the same buffers, holding less.
PARALLEL_MAX_SAMPLES: int = 2**22
#: Largest ratio of the axes-std floor to the norm-std floor accepted as noise (√3 for
#: isotropic noise; twice that allows for axes of unequal noise).
AXES_TO_NORM_MAX: float = 2.0 * np.sqrt(3.0)
#: Largest gyro noise floor (per-sample std, norm over the axes) of quantised gyro data, in
#: quantisation steps: a resting 16-bit MEMS gyro shows tens of steps (MPU-6050: 22-24, the
#: Xsens MTi: 44); a floor of hundreds (the sunsided motion logs: 413-5245) means that the
#: recording never rests and its quietest windows still turn.
GYRO_FLOOR_MAX_QUANTA: float = 100.0


@dataclass(frozen=True)
class StaticSettings:
    """Settings of the static detector.

    Attributes
    ----------
    window_s : float
        Width of the centred moving window, seconds.
    threshold : float
        Accelerometer gates, in multiples of the measured noise floor.
    gyro_threshold : float
        Gate on the windowed mean rate, in multiples of the gyro's per-sample noise floor.
    drift_threshold : float
        Gate on the difference between the means of the two window halves, in multiples of
        its noise (from the accelerometer noise floor).
    min_dwell_s : float
        Shortest static interval kept, seconds (after the window, before trimming).
    trim_s : float
        Cut from each end of every interval, seconds.
    floor_quantile : float
        Quantile of each windowed statistic taken as its noise floor.
    max_gap_s : float or None
        A time step longer than this splits an interval (default: 5 sample periods).
    sigma_blocks : int
        Blocks for the batch-means standard deviation of each pose mean (0: white noise
        only, ``σ/√n``).
    """

    window_s: float = 1.0
    threshold: float = 3.0
    gyro_threshold: float = 3.0
    drift_threshold: float = 6.0
    min_dwell_s: float = 0.5
    trim_s: float = 0.0
    floor_quantile: float = 0.1
    max_gap_s: float | None = None
    sigma_blocks: int = 10

    def __post_init__(self) -> None:
        for name in ("window_s", "threshold", "gyro_threshold"):
            if not getattr(self, name) > 0:
                raise InputError(f"static detection: {name} must be positive, got {getattr(self, name)}")
        if self.min_dwell_s < 0 or self.trim_s < 0:
            raise InputError("static detection: the minimum dwell and the trim must not be negative")
        if self.sigma_blocks < 0 or self.sigma_blocks == 1:
            raise InputError("static detection: sigma_blocks must be 0 (white noise) or at least 2")
        if not 0 < self.floor_quantile < 1:
            raise InputError("static detection: floor_quantile must lie between 0 and 1")

    @classmethod
    def from_options(cls, **options: Any) -> "StaticSettings":
        """Settings from keyword options, ignoring those left as ``None``."""
        return cls(**{k: v for k, v in options.items() if v is not None})


@dataclass
class Segmentation:
    """What static detection found in a recording.

    Attributes
    ----------
    recording : Recording
    settings : StaticSettings
    intervals : list of StaticInterval
    noise_floor, thresholds : dict of str to float
        Per statistic (``acc_norm_std``, ``acc_axes_std``, ``acc_drift``, ``gyro_rate``), raw units.
    gyro_bias : ndarray or None
    exclusions : dict of str to int
        Everything excluded, from reading to trimming.
    trace : dict of str to ndarray
        Per usable sample: ``t``, the statistics and the static mask (for plots).
    joined : int
        Static stretches joined to the previous one as the same pose (:func:`optcal.data.static_stretches.join_interrupted`).
    rest_plateau : dict of str to float
        The evidence that the recording rests (:func:`rest_plateau_limit`): the axes moving std at
        its low quantile (``low``) and at the floor quantile (``floor``), and the smallest ratio
        ``low / floor`` of windows at rest (``limit``); empty when the recording is too short.
    """

    recording: Recording
    settings: StaticSettings
    intervals: list[StaticInterval]
    noise_floor: dict[str, float]
    thresholds: dict[str, float]
    gyro_bias: NDArray[np.float64] | None
    exclusions: dict[str, int]
    trace: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    joined: int = 0
    rest_plateau: dict[str, float] = field(default_factory=dict)

    @property
    def n_used(self) -> int:
        return int(sum(iv.n_samples for iv in self.intervals))

    def meta(self) -> dict[str, Any]:
        """JSON-safe description for ``PoseTable.meta``."""
        rec = self.recording
        return {
            "settings": asdict(self.settings),
            "window_samples": int(self.trace.get("window_samples", 0)),
            "noise_floor": dict(self.noise_floor),
            "thresholds": dict(self.thresholds),
            "gyro_bias": None if self.gyro_bias is None else self.gyro_bias.tolist(),
            "gyro_units": rec.gyro_units,
            "n_samples": rec.n,
            "n_samples_in_poses": self.n_used,
            "stretches_joined": self.joined,
            "rest_plateau": dict(self.rest_plateau),
            "intervals": [iv.to_dict() for iv in self.intervals],
        }

    def pose_table(self) -> PoseTable:
        """One pose per interval (``source="raw recording"``)."""
        rec = self.recording
        if not self.intervals:
            raise InputError(no_static_message(self))
        ivs = self.intervals
        acc = np.array([iv.mean for iv in ivs])
        gyro = np.array([iv.gyro_mean for iv in ivs]) if rec.gyro is not None else None
        temp = np.array([iv.temp_mean for iv in ivs]) if rec.temp is not None else None
        return PoseTable(
            acc=acc,
            sigma=np.array([iv.sigma for iv in ivs]),
            n_samples=np.array([iv.n_samples for iv in ivs], dtype=float),
            t=np.array([iv.t_mid for iv in ivs]),
            temp=temp,
            gyro=gyro,
            rows=np.array([iv.number for iv in ivs]),
            units=rec.units,
            source="raw recording",
            exclusions=dict(self.exclusions),
            meta={"segmentation": self.meta()},
        )


def no_static_message(seg: Segmentation) -> str:
    rec = seg.recording
    thr = seg.thresholds
    if seg.exclusions.get(NO_REST_STRETCHES):
        plateau = seg.rest_plateau
        return (
            f"{rec.path}: no static interval found in {rec.n} samples ({rec.duration_s:.1f} s): the recording "
            f"never rests: the quietest windows share no noise level (the axes moving std at its "
            f"{100 * seg.settings.floor_quantile / 5:g} % quantile is {plateau['low']:.3g}, "
            f"{plateau['low'] / plateau['floor']:.2f} of its "
            f"{100 * seg.settings.floor_quantile:g} % quantile {plateau['floor']:.3g} {rec.units}; windows at "
            f"rest give at least {plateau['limit']:.2f}), so the {seg.exclusions[NO_REST_STRETCHES]} quiet "
            "stretch(es) are the slowest moments of a motion, not rests; record the sensor at rest between moves"
        )
    if seg.exclusions.get(SWEEPING_STRETCHES) and not seg.exclusions.get(TURNING_STRETCHES):
        return (
            f"{rec.path}: no static interval found in {rec.n} samples ({rec.duration_s:.1f} s): the "
            f"{seg.exclusions[SWEEPING_STRETCHES]} quiet stretch(es) turn slowly: their means move along the axes "
            f"by more than the accelerometer gate ({thr.get('acc_axes_std', float('nan')):.3g} {rec.units}) while "
            "|a| stays the same (a slow turn, e.g. about an axis near the vertical); record the sensor at rest "
            "between moves, or add the gyro columns"
        )
    if seg.exclusions.get(TURNING_STRETCHES):
        return (
            f"{rec.path}: no static interval found in {rec.n} samples ({rec.duration_s:.1f} s): the recording "
            f"never rests: its gyro noise floor ({seg.noise_floor['gyro_rate_measured']:.3g}, norm over the axes) "
            f"is above a resting gyro's ({seg.noise_floor['gyro_rate']:.3g} = {GYRO_FLOOR_MAX_QUANTA:g} converter "
            f"steps), and the {seg.exclusions[TURNING_STRETCHES]} quiet stretch(es) still turn; record the sensor "
            "at rest between moves"
        )
    return (
        f"{rec.path}: no static interval found in {rec.n} samples ({rec.duration_s:.1f} s): "
        f"windows of {seg.settings.window_s:g} s must stay below {seg.settings.threshold:g}× the noise floor "
        f"(|a| std ≤ {thr.get('acc_norm_std', float('nan')):.3g} {rec.units}) for at least "
        f"{seg.settings.min_dwell_s:g} s; check that the sensor rests between moves, or loosen "
        "--static-threshold / shorten --min-dwell"
    )


# ----------------------------------------------------------------------------- detection
def detect_static(rec: Recording, settings: StaticSettings | None = None) -> Segmentation:
    """Find the static intervals of a recording.

    Parameters
    ----------
    rec : Recording
    settings : StaticSettings, optional

    Returns
    -------
    Segmentation
        The intervals (possibly none: :meth:`Segmentation.pose_table` then raises
        :class:`InputError`), thresholds, noise floors and every exclusion counted.
    """
    s = settings or StaticSettings()
    every = bool(rec.usable.all())  # then no copies, and no index array of every sample
    use = None if every else np.flatnonzero(rec.usable)
    t = rec.t if use is None else rec.t[use]
    acc = rec.acc if use is None else _usable_rows(rec.acc, use)
    gyro = (rec.gyro if use is None else _usable_rows(rec.gyro, use)) if rec.gyro is not None else None
    m = acc.shape[0]
    rate = rec.rate_hz if np.isfinite(rec.rate_hz) else 1.0
    window = max(3, int(round(s.window_s * rate)))
    nominal = rec.nominal if rec.nominal is not None else nominal_conversion(rec.units, acc)
    norm = _distance(acc, nominal.offset)
    # the gyro's statistics that do not need its bias in a second thread (numpy releases the GIL
    # in its loops), beside the accelerometer's: recordings up to PARALLEL_MAX_SAMPLES samples
    gyro_job: Future[GyroWindows] | None = None
    pool: ThreadPoolExecutor | None = None
    if gyro is not None and m <= PARALLEL_MAX_SAMPLES:
        pool = ThreadPoolExecutor(max_workers=1)
        gyro_job = pool.submit(_gyro_windows, gyro, window, s.floor_quantile, MovingWindow(m, window), None)
    # column by column in one set of buffers, the drift from the same cumulative sums
    moving = MovingWindow(m, window)
    sd_norm = np.sqrt(moving.column(norm)[1])
    del norm  # made again for the trace at the end: one column less while the statistics are held
    drift_sums = HalfWindowDrift(m, window)
    sd_axes = np.zeros(m)
    for j in range(3):
        sd_axes += moving.column(acc[:, j], drift_sums)[1]
    np.sqrt(sd_axes, out=sd_axes)
    res_acc = resolution(acc)
    floor_norm = noise_floor(sd_norm, s.floor_quantile, res_acc, moving.scratch())
    # At rest the three axes carry the noise of the norm about √3 times over; a much larger
    # axes floor means the quietest windows still rotate (the norm does not see rotation),
    # so the axes floor is capped at AXES_TO_NORM_MAX times the norm floor.
    # the floor and the rest plateau's low quantile of the axes statistic from one partition
    axes_quantiles = quantiles(sd_axes, [s.floor_quantile / 5, s.floor_quantile], moving.scratch())
    floor_axes = min(max(axes_quantiles[1], res_acc * np.sqrt(3)), AXES_TO_NORM_MAX * floor_norm)
    floors = {"acc_norm_std": floor_norm, "acc_axes_std": floor_axes}
    rest_plateau: dict[str, float] = {}
    never_rests = _never_rests(m, axes_quantiles, window, s.floor_quantile, res_acc * np.sqrt(3), rest_plateau)
    thresholds = {k: s.threshold * v for k, v in floors.items()}
    # drift: the two halves of the window must agree within the noise of their means
    drift = drift_sums.result()
    del drift_sums  # its three columns freed before the gyro's statistics
    floors["acc_drift"] = floor_axes * 2.0 / np.sqrt(window)
    thresholds["acc_drift"] = s.drift_threshold * floors["acc_drift"]
    static = (
        (sd_norm <= thresholds["acc_norm_std"])
        & (sd_axes <= thresholds["acc_axes_std"])
        & (drift <= thresholds["acc_drift"])
    )
    trace: dict[str, Any] = {
        "t": t,
        "acc_norm_std": sd_norm,
        "acc_axes_std": sd_axes,
        "acc_drift": drift,
        "window_samples": window,
    }

    gyro_bias = None
    resting_gyro_std: float | None = None
    if gyro is not None:
        base = static if static.any() else np.ones(m, dtype=bool)
        # column by column: the static samples gathered into a free window buffer, partitioned there
        gyro_bias = np.array([median(_gather(gyro[:, j], base, moving.scratch()), overwrite_input=True)
                              for j in range(3)])
        if gyro_job is not None and pool is not None:
            windows = gyro_job.result()
            pool.shutdown()
        else:  # after the accelerometer's, in its buffers, the mean rate from the bias at once
            windows = _gyro_windows(gyro, window, s.floor_quantile, moving, gyro_bias)
        del moving
        rate_dev = windows.rate_deviation(gyro_bias)
        # the per-sample gyro noise (norm over the axes) bounds the mean rate of a resting sensor
        floors["gyro_rate"] = windows.floor
        q = windows.quantum
        if q is not None and floors["gyro_rate"] > GYRO_FLOOR_MAX_QUANTA * q:
            # the quietest windows of a recording that never rests still turn: the floor is
            # capped at a resting gyro's noise, and so is the noise inside every interval kept
            floors["gyro_rate_measured"] = floors["gyro_rate"]
            floors["gyro_rate"] = resting_gyro_std = GYRO_FLOOR_MAX_QUANTA * q
        thresholds["gyro_rate"] = s.gyro_threshold * floors["gyro_rate"]
        static &= rate_dev <= thresholds["gyro_rate"]
        trace["gyro_rate"] = rate_dev

    # split at time gaps: a step longer than max_gap_s ends a run
    max_gap = s.max_gap_s if s.max_gap_s is not None else 5.0 / rate
    starts, stops = true_runs(static)
    gap_after = np.flatnonzero(np.diff(t) > max_gap)
    if gap_after.size:
        starts, stops = split_runs(starts, stops, gap_after + 1)

    exclusions = dict(rec.exclusions)
    in_pose = np.zeros(m, dtype=bool)
    n_short_samples = n_short = n_trim = 0
    trim = int(round(s.trim_s * rate))
    intervals: list[StaticInterval] = []
    kept: list[tuple[int, int]] = []
    for a, b in zip(starts, stops):
        duration = t[b - 1] - t[a] + 1.0 / rate
        if duration < s.min_dwell_s:
            n_short += 1
            n_short_samples += b - a
            continue
        a2, b2 = a + trim, b - trim
        if b2 - a2 < 2:
            n_short += 1
            n_short_samples += b - a
            continue
        n_trim += (a2 - a) + (b - b2)
        in_pose[a2:b2] = True
        kept.append((a2, b2))
    groups = join_interrupted(kept, t, acc, s.window_s, thresholds["acc_axes_std"])
    groups, n_sweeping, n_sweeping_samples = reject_sweeping(groups, acc, window, thresholds["acc_axes_std"], in_pose)
    _add(exclusions, SWEEPING, n_sweeping_samples)
    _add(exclusions, SWEEPING_STRETCHES, n_sweeping)
    if resting_gyro_std is not None and gyro is not None:
        groups, n_turning, n_turning_samples = reject_turning(groups, gyro, resting_gyro_std, in_pose)
        _add(exclusions, TURNING, n_turning_samples)
        _add(exclusions, TURNING_STRETCHES, n_turning)
    elif never_rests:
        n_dropped = sum(b - a for group in groups for a, b in group)
        _add(exclusions, NO_REST, n_dropped)
        _add(exclusions, NO_REST_STRETCHES, len(groups))
        in_pose[:] = False
        groups = []
    for group in groups:
        intervals.append(reduce_interval(len(intervals) + 1, rec, use, group_positions(group), gyro, s.sigma_blocks))
    _add(exclusions, MOVING, int(np.sum(~static)))
    _add(exclusions, SHORT, n_short_samples)
    _add(exclusions, SHORT_STRETCHES, n_short)
    _add(exclusions, TRIMMED, n_trim)
    trace["static"] = in_pose
    norm = _distance(acc, nominal.offset)
    trace["norm_g"] = np.divide(norm, nominal.sensitivity, out=norm)
    seg = Segmentation(rec, s, intervals, floors, thresholds, gyro_bias, exclusions, trace)
    seg.joined = len(kept) - len(groups)
    seg.rest_plateau = rest_plateau
    return seg


def _distance(acc: NDArray[np.float64], offset: NDArray[np.float64]) -> NDArray[np.float64]:
    """‖a − offset‖ of every sample, column by column into one array (no (m, 3) temporary)."""
    norm = np.subtract(acc[:, 0], offset[0])
    np.multiply(norm, norm, out=norm)
    term = np.empty_like(norm)
    for j in (1, 2):
        np.subtract(acc[:, j], offset[j], out=term)
        np.multiply(term, term, out=term)
        norm += term
    return np.sqrt(norm, out=norm)


@dataclass
class GyroWindows:
    """The gyro's moving statistics (:func:`_gyro_windows`).

    Attributes
    ----------
    floor : float
        The noise floor of the moving standard deviation, norm over the axes (the per-sample noise)
        (:func:`optcal.data.window_stats.noise_floor`, at least the data's resolution).
    quantum : float or None
        The gyro's converter step (:func:`optcal.data.window_stats.quantum`).
    means : list of ndarray or None
        Moving mean of each axis, kept when the bias was not known yet.
    squared_deviation : ndarray or None
        ``‖mean(ω) − b_ω‖²`` when the bias was given.
    """

    floor: float
    quantum: float | None
    means: list[NDArray[np.float64]] | None
    squared_deviation: NDArray[np.float64] | None

    def rate_deviation(self, bias: NDArray[np.float64]) -> NDArray[np.float64]:
        """The windowed mean rate ``‖mean(ω) − b_ω‖`` at each sample."""
        dev2 = self.squared_deviation
        if dev2 is None:
            assert self.means is not None
            dev2 = _add_squared_deviations(self.means, bias)
            self.means = None
        return np.sqrt(dev2, out=dev2)


def _add_squared_deviations(means: list[NDArray[np.float64]], bias: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Σ_j (mean_j − b_j)²`` column by column, each mean overwritten."""
    dev2 = np.zeros(means[0].size)
    for j, mean_j in enumerate(means):
        mean_j -= bias[j]
        mean_j *= mean_j
        dev2 += mean_j
    return dev2


def _gyro_windows(
    gyro: NDArray[np.float64], window: int, floor_quantile: float, moving: MovingWindow,
    bias: NDArray[np.float64] | None,
) -> GyroWindows:
    """The gyro's moving statistics in ``moving``'s buffers: without ``bias`` the three moving means kept
    (for :meth:`GyroWindows.rate_deviation`); with it (long recordings) the squared mean rate from a
    second pass over the columns, so that the noise's and the rate's sums are never held at once."""
    m = gyro.shape[0]
    var_sum = np.zeros(m)
    means: list[NDArray[np.float64]] = []
    for j in range(3):
        mean_j, var_j = moving.column(gyro[:, j])
        var_sum += var_j
        if bias is None:
            means.append(mean_j.copy())
    sd = np.sqrt(var_sum, out=var_sum)
    floor = noise_floor(sd, floor_quantile, resolution(gyro) * np.sqrt(3), moving.scratch())
    del sd, var_sum
    dev2 = None
    if bias is not None:
        dev2 = np.zeros(m)
        for j in range(3):  # as _add_squared_deviations, in the buffer
            mean_j = moving.column(gyro[:, j])[0]
            mean_j -= bias[j]
            mean_j *= mean_j
            dev2 += mean_j
    return GyroWindows(floor, quantum(gyro), means if bias is None else None, dev2)


def rest_plateau_limit(window: int, floor_quantile: float) -> float:
    """Smallest ratio of the axes moving std's ``floor_quantile / 5`` quantile to its ``floor_quantile``
    quantile that windows at rest give: :data:`REST_PLATEAU_FRACTION` of the ratio for white noise.

    For white noise the std over ``window`` samples, summed over three axes, has a relative
    spread ``r ≈ 1/√(6 (window − 1))`` (each axis ``1/√(2 (window − 1))``), so the ratio of
    the two quantiles is ``(1 + z_low r) / (1 + z_floor r)`` with ``z`` the normal quantiles.
    """
    from statistics import NormalDist

    r = 1.0 / np.sqrt(6.0 * max(1, window - 1))
    z = NormalDist().inv_cdf
    white = (1.0 + z(floor_quantile / 5) * r) / (1.0 + z(floor_quantile) * r)
    return REST_PLATEAU_FRACTION * max(0.0, white)


def _never_rests(
    m: int, axes_quantiles: list[float], window: int, floor_quantile: float, resolution: float,
    evidence: dict[str, float],
) -> bool:
    """Whether the quietest windows share no noise level (the recording never rests); the figures go to ``evidence``.

    ``axes_quantiles`` are the ``floor_quantile / 5`` and ``floor_quantile`` quantiles of the axes
    moving std over ``m`` samples.  Both are taken at least at the data's ``resolution``
    (noise-free or coarsely quantised rests sit there).  Decided only on recordings of at least
    :data:`PLATEAU_MIN_WINDOWS` windows (else ``False``).
    """
    if m < PLATEAU_MIN_WINDOWS * window:
        return False
    low, at_floor = (max(float(q), resolution) for q in axes_quantiles)
    if not at_floor > 0:
        return False
    limit = rest_plateau_limit(window, floor_quantile)
    evidence.update(low=float(low), floor=float(at_floor), limit=limit)
    return bool(low < limit * at_floor)


def _gather(x: NDArray[np.float64], mask: NDArray[np.bool_], out: NDArray[np.float64]) -> NDArray[np.float64]:
    """``x[mask]`` written into ``out`` chunk by chunk (no temporary of the data's length); a view of ``out``."""
    filled = 0
    for start in range(0, x.size, STEP_CHUNK):
        chunk = x[start:start + STEP_CHUNK][mask[start:start + STEP_CHUNK]]
        out[filled:filled + chunk.size] = chunk
        filled += chunk.size
    return out[:filled]


def _usable_rows(x: NDArray[np.float64], use: NDArray[np.int64]) -> NDArray[np.float64]:
    """The rows ``use`` of ``x`` (n, k) as a column-major copy (contiguous columns, as a recording's)."""
    out = np.empty((use.size, x.shape[1]), order="F")
    for j in range(x.shape[1]):
        np.take(x[:, j], use, out=out[:, j])
    return out


def _add(d: dict[str, int], key: str, value: int) -> None:
    if value:
        d[key] = d.get(key, 0) + int(value)
