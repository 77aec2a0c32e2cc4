"""Static detection: a raw recording in, its rests found by a model of the recording, one pose per rest out.

The model (:mod:`optcal.data.rest_model`): a recording is a sequence of rests and moves; in a rest the
accelerometer reads a constant plus stationary noise whose level is the rest's own and whose colour is
the sensor's, and the gyro reads its bias plus noise.  The usable samples are cut into blocks
(``window_s`` long, doubled while the noise is still correlated beyond the block,
:func:`choose_block`); a block belongs to a rest when

* its mean does not step away from its neighbours' beyond the noise of those means (**step**; a jump
  between two holds with no motion samples between them is a boundary too);
* its variance is not an outlier among its neighbours' (**spread**: a move starting in the block);
* with a gyro, its mean rate sits at the bias within the noise of that mean (**gyro**: the primary
  evidence of motion where it exists, and the only one for a turn about the vertical);

and a run of such blocks (a **stretch**) is a rest when its block means do not follow a line in time
beyond their own scatter about it (**drift**: a slow turn or a creep, tested scale-free against the
stretch's own noise of the mean) and it lasts at least ``min_dwell_s``.  The minimum dwell is a
duration prior on rests: a stretch shorter than a dwell is not a rest, and an interruption shorter than
a dwell between two stretches whose means agree within their noise is a twitch, not a move (the two are
one pose).  Each test has the stated false-alarm probability ``false_alarm`` (a block, a pair of blocks
or a stretch at rest fails it by chance with that probability); the threshold settings multiply the
deviation each test tolerates (``1``: exactly that probability).  "Never rests" is the model's
conclusion when no stretch passes, printed with its evidence and the flag that overrides each test.

Every sample that does not end in a pose is counted by reason.  Each rest gives one pose
(:func:`optcal.data.static_poses.reduce_interval`): the mean, the per-axis standard deviation, the
standard deviation of the mean ``σ_k`` by batch means (Lu 2017 eq. 14's weights), the sample count,
the mid time, the mean temperature and the mean gyro reading.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.poses import PoseTable
from optcal.data.recording import Recording
from optcal.data.rest_model import (
    MIN_TREND_BLOCKS,
    MIN_COLOUR_PAIRS,
    REST_QUANTILE_WHITE,
    Blocks,
    effective_dof,
    f_quantile,
    bias_wander,
    chi2_quantile,
    gyro_statistic,
    half_sample_mode,
    make_blocks,
    noise_colour,
    step_statistic,
    t_quantile,
    trend_statistic,
)
from optcal.data.static_poses import StaticInterval, reduce_interval
from optcal.data.units import MAX_REST_NOISE_G, nominal_conversion
from optcal.data.window_stats import resolution
from optcal.errors import InputError

MOVING = "samples in moving blocks (a step or a gyro rate beyond the noise of a rest, or louder than a rest)"
SHORT = "samples in quiet stretches shorter than the minimum dwell (or than the drift test's four blocks)"
SHORT_STRETCHES = "quiet stretches shorter than the minimum dwell (or than the drift test's four blocks)"
TRIMMED = "samples trimmed at the ends of static intervals"
DRIFTING = "samples in quiet stretches whose mean drifts beyond its own noise (a slow turn or a creep)"
DRIFTING_STRETCHES = "quiet stretches rejected because their mean drifts beyond its own noise"
ISOLATED = "samples isolated between holes in the time stamps (a block of one sample)"
#: Fewest samples in a block: a variance needs a few degrees of freedom per axis.
MIN_BLOCK_SAMPLES: int = 5
#: Largest per-sample noise of a rest (norm over the axes), g: the bound of the units check of the poses
#: (:data:`optcal.data.units.MAX_REST_NOISE_G`); a block above it is moving, whatever its neighbours do.
RESTING_NOISE_MAX_G: float = MAX_REST_NOISE_G
#: Batches a stretch is pooled into for the drift test (:func:`_drift_ratio`).
DRIFT_BATCHES: int = 8


@dataclass(frozen=True)
class StaticSettings:
    """Settings of the static detector (:mod:`optcal.data.static`).

    Attributes
    ----------
    window_s : float
        Length of the blocks the tests compare, seconds (at least :data:`MIN_BLOCK_SAMPLES` samples;
        doubled up to :data:`optcal.data.rest_model.MAX_BLOCK_GROWTH` times while the noise is still
        correlated beyond the block).
    threshold : float
        Multiplies the step and spread an accelerometer block may show at rest (1: the false-alarm
        probability ``false_alarm``; larger accepts more).
    gyro_threshold : float
        Multiplies the mean rate a gyro block may show at rest.
    drift_threshold : float
        Multiplies the drift a stretch may show at rest (``inf``: no drift test).
    min_dwell_s : float
        Shortest rest, seconds (the duration prior).
    trim_s : float
        Cut from each end of every rest, seconds.
    false_alarm : float
        Probability that a block, a pair of blocks or a stretch at rest fails its test by chance.
    use_gyro : bool
        Whether the gyro is evidence of motion (``False``: rests from the accelerometer alone).
    max_gap_s : float or None
        A time step longer than this is a hole: no block straddles it (default: 5 sample periods).
    sigma_blocks : int
        Blocks for the batch-means standard deviation of each pose mean (0: white noise, ``σ/√n``).
    """

    window_s: float = 0.25
    threshold: float = 1.0
    gyro_threshold: float = 1.0
    drift_threshold: float = 1.0
    min_dwell_s: float = 0.5
    trim_s: float = 0.0
    false_alarm: float = 1e-3
    use_gyro: bool = True
    max_gap_s: float | None = None
    sigma_blocks: int = 10

    def __post_init__(self) -> None:
        for name in ("window_s", "threshold", "gyro_threshold", "drift_threshold"):
            if not getattr(self, name) > 0:
                raise InputError(f"static detection: {name} must be positive, got {getattr(self, name)}")
        if self.min_dwell_s < 0 or self.trim_s < 0:
            raise InputError("static detection: the minimum dwell and the trim must not be negative")
        if self.sigma_blocks < 0 or self.sigma_blocks == 1:
            raise InputError("static detection: sigma_blocks must be 0 (white noise) or at least 2")
        if not 0 < self.false_alarm < 0.5:
            raise InputError(f"static detection: the false-alarm probability must lie in (0, 0.5), got {self.false_alarm}")

    @classmethod
    def from_options(cls, **options: Any) -> "StaticSettings":
        """Settings from keyword options, ignoring those left as ``None``."""
        return cls(**{k: v for k, v in options.items() if v is not None})

    def assumptions(self) -> list[str]:
        """What the settings assume where they loosen the model's tests (printed as warnings)."""
        out = []
        if self.threshold > 1:
            out.append(f"--static-threshold {self.threshold:g} accepts accelerometer steps and spreads {self.threshold:g}× "
                       "what the noise of a rest explains: moves that slow may be taken for rests")
        if self.gyro_threshold > 1:
            out.append(f"--gyro-threshold {self.gyro_threshold:g} accepts mean rates {self.gyro_threshold:g}× what the "
                       "gyro noise of a rest explains: slow turns may be taken for rests")
        if self.drift_threshold > 1:
            out.append("the drift test is off: stretches whose mean moves are taken for rests" if not np.isfinite(self.drift_threshold)
                       else f"--drift-threshold {self.drift_threshold:g} accepts drifts {self.drift_threshold:g}× what a "
                       "rest's noise explains: slow turns and creeps may be taken for rests")
        if not self.use_gyro:
            out.append("--no-gyro-rests: the gyro is not used as evidence of motion; a turn about the vertical is taken for a rest")
        return out


@dataclass
class Segmentation:
    """What static detection found in a recording.

    Attributes
    ----------
    recording : Recording
    settings : StaticSettings
    intervals : list of StaticInterval
    noise_floor : dict of str to float
        The model's noise evidence: the noise colour of each sensor axis (``acc_colour_x``, ...) and the
        block length (``block_samples``).
    thresholds : dict of str to float
        The quantile each test's statistic is compared with (``step``, ``spread``, ``gyro``, ``drift``).
    gyro_bias : ndarray or None
    exclusions : dict of str to int
        Everything excluded, from reading to trimming.
    trace : dict of str to ndarray
        Per usable sample: ``t``, ``norm_g``, each test's statistic over its threshold, the static mask.
    joined : int
        Stretches joined to the one before as the same pose (an interruption shorter than a dwell).
    evidence : dict of str to Any
        Counts behind the decision: blocks, blocks failing each test, stretches, stretches rejected.
    """

    recording: Recording
    settings: StaticSettings
    intervals: list[StaticInterval]
    noise_floor: dict[str, float]
    thresholds: dict[str, float]
    gyro_bias: NDArray[np.float64] | None
    exclusions: dict[str, int]
    trace: dict[str, Any] = field(default_factory=dict)
    joined: int = 0
    evidence: dict[str, Any] = field(default_factory=dict)

    @property
    def n_used(self) -> int:
        return int(sum(iv.n_samples for iv in self.intervals))

    def meta(self) -> dict[str, Any]:
        """JSON-safe description for ``PoseTable.meta``."""
        rec = self.recording
        return {
            "settings": {k: (v if not isinstance(v, float) or np.isfinite(v) else None)
                         for k, v in asdict(self.settings).items()},
            "window_samples": int(self.trace.get("window_samples", 0)),
            "noise_floor": dict(self.noise_floor),
            "thresholds": dict(self.thresholds),
            "evidence": dict(self.evidence),
            "assumptions": self.settings.assumptions(),
            "gyro_bias": None if self.gyro_bias is None else self.gyro_bias.tolist(),
            "gyro_units": rec.gyro_units,
            "n_samples": rec.n,
            "n_samples_in_poses": self.n_used,
            "stretches_joined": self.joined,
            "intervals": [iv.to_dict() for iv in self.intervals],
        }

    def summary(self) -> str:
        """One line: the model's evidence and what it concluded."""
        ev = self.evidence
        colour = self.noise_floor
        text = (
            f"rests by the model: blocks of {ev.get('block_samples', 0)} samples "
            f"({ev.get('block_s', float('nan')):.3g} s), accelerometer noise colour "
            f"{colour.get('acc_colour', 1.0):.3g}× white; {ev.get('blocks', 0)} blocks, "
            f"{ev.get('step_blocks', 0)} at a step, {ev.get('loud_blocks', 0)} louder than a rest"
        )
        if self.recording.gyro is not None and self.settings.use_gyro:
            text += f", {ev.get('gyro_blocks', 0)} turning (gyro)"
        text += (
            f"; {ev.get('stretches', 0)} quiet stretches: {ev.get('short', 0)} shorter than "
            f"{self.settings.min_dwell_s:g} s, {ev.get('drifting', 0)} drifting, {len(self.intervals)} rests "
            f"(false-alarm probability {self.settings.false_alarm:g} per test)"
        )
        return text

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
    """Why no rest was found, with the evidence and the flag that overrides the test that decided."""
    rec = seg.recording
    ev = seg.evidence
    head = f"{rec.path}: the recording never rests by its model ({rec.n} samples, {rec.duration_s:.1f} s): "
    if ev.get("drifting"):
        return head + (
            f"{ev['drifting']} quiet stretch(es) drift (their means follow a line in time beyond their own noise: a slow "
            "turn or a creep), " + _others(ev, seg) + "; if the sensor did rest, pass --drift-threshold inf "
            "(no drift test) or a factor above 1"
        )
    if ev.get("short") and not ev.get("stretches_long"):
        return head + (
            f"{ev['short']} quiet stretch(es), all shorter than the minimum dwell {seg.settings.min_dwell_s:g} s (longest "
            f"{ev.get('longest_s', 0):.3g} s); pass --min-dwell {max(ev.get('longest_s', 0) * 0.9, 0.01):.2g} if those are rests"
        )
    gyro_part = ""
    if rec.gyro is not None and seg.settings.use_gyro and ev.get("gyro_blocks"):
        gyro_part = (f", {ev['gyro_blocks']} of {ev['blocks']} blocks turn by the gyro (pass --no-gyro-rests if the gyro "
                     "columns are not the rates, or --gyro-threshold above 1)")
    return head + (
        f"{ev.get('step_blocks', 0)} of {ev.get('blocks', 0)} blocks step beyond the noise of a rest and "
        f"{ev.get('loud_blocks', 0)} are louder than a rest ({RESTING_NOISE_MAX_G:g} g per sample){gyro_part}, and no quiet stretch lasts {seg.settings.min_dwell_s:g} s; if the sensor did "
        "rest, pass --static-threshold above 1 (the factor on the tolerated step) or a shorter --static-window"
    )


def _others(ev: dict[str, Any], seg: Segmentation) -> str:
    return (f"{ev.get('short', 0)} shorter than the minimum dwell {seg.settings.min_dwell_s:g} s, "
            f"{ev.get('blocks', 0)} blocks of {ev.get('block_s', float('nan')):.3g} s")


# ----------------------------------------------------------------------------- detection
@dataclass
class _Pass:
    """One pass of the tests over the blocks, for one noise colour."""

    quiet: NDArray[np.bool_]
    stepping: NDArray[np.bool_]
    loud: NDArray[np.bool_]
    gyro_flag: NDArray[np.bool_]
    step: NDArray[np.float64]
    step_limit: NDArray[np.float64]
    gyro_stat: NDArray[np.float64] | None
    thresholds: dict[str, float]
    accepted: list[tuple[int, int]]
    counts: dict[str, Any]


def detect_static(rec: Recording, settings: StaticSettings | None = None) -> Segmentation:
    """Find the rests of a recording by its model (module docstring).

    Parameters
    ----------
    rec : Recording
    settings : StaticSettings, optional

    Returns
    -------
    Segmentation
        The rests (possibly none: :meth:`Segmentation.pose_table` then raises :class:`InputError`
        with the model's evidence), the tests' thresholds, the noise colours and every exclusion counted.
    """
    s = settings or StaticSettings()
    use = None if bool(rec.usable.all()) else np.flatnonzero(rec.usable)
    t = rec.t if use is None else rec.t[use]
    acc = rec.acc if use is None else rec.acc[use]
    gyro_all = (rec.gyro if use is None else rec.gyro[use]) if rec.gyro is not None else None
    gyro = gyro_all if s.use_gyro else None
    m = acc.shape[0]
    rate = rec.rate_hz if np.isfinite(rec.rate_hz) and rec.rate_hz > 0 else 1.0
    first = max(MIN_BLOCK_SAMPLES, int(round(s.window_s * rate)))
    max_gap = s.max_gap_s if s.max_gap_s is not None else 5.0 / rate
    acc_floor = resolution(acc) ** 2
    gyro_floor = resolution(gyro) ** 2 if gyro is not None else 0.0
    blocks = make_blocks(t, acc, gyro, first, max_gap, acc_floor, gyro_floor)
    nominal = rec.nominal if rec.nominal is not None else nominal_conversion(rec.units, acc)
    # a rest's per-sample noise is far below RESTING_NOISE_MAX_G (in the recording's units)
    loud = np.sqrt(np.sum(blocks.acc_var, axis=1)) > RESTING_NOISE_MAX_G * float(nominal.sensitivity)
    doubled = make_blocks(t, acc, gyro, 2 * first, max_gap, acc_floor, gyro_floor)
    colour = noise_colour(blocks, doubled=doubled)
    kappa = np.ones(3) if colour is None else colour
    gyro_bias = kappa_g = None
    if gyro is not None and blocks.gyro_mean is not None:
        # a MEMS gyro at rest is white at the block's scale (angle random walk; its bias-instability corner lies
        # at tens of seconds): the first pass assumes it, the second measures the colour inside the rests found
        kappa_g = np.ones(3)
    first_pass = _test_blocks(blocks, kappa, kappa_g, None, loud, s, t, rate)
    gyro_bias = first_pass.counts.get("gyro_bias")
    # the noise colour again, measured inside the rests the first pass found (the quiet quarter of the steps
    # of a recording that moves most of its time is not a rest's)
    inside = _colour_inside(first_pass.accepted, blocks, "acc")
    if inside is not None:
        kappa = inside
        if kappa_g is not None:
            kappa_g = _colour_inside(first_pass.accepted, blocks, "gyro")
    result = (_test_blocks(blocks, kappa, kappa_g, gyro_bias, loud, s, t, rate, first_pass.accepted)
              if inside is not None else first_pass)
    return _segmentation(rec, s, use, t, acc, gyro_all, blocks, kappa, kappa_g, result, nominal, rate, m)


def _test_blocks(blocks: Blocks, kappa: NDArray[np.float64], kappa_g: NDArray[np.float64] | None,
                 gyro_bias: NDArray[np.float64] | None, loud: NDArray[np.bool_], s: StaticSettings,
                 t: NDArray[np.float64], rate: float, rests: list[tuple[int, int]] | None = None) -> _Pass:
    """The block tests and the stretch tests at one noise colour (module docstring).

    ``rests`` are the stretches a first pass accepted: the gyro bias's wander is measured inside them
    (:func:`~optcal.data.rest_model.bias_wander`); without them (the first pass) the bias does not wander.
    """
    n, k_blocks = blocks.n, blocks.count
    p = s.false_alarm
    dof = np.asarray(effective_dof(n, kappa))
    # step: consecutive block means against the noise of the two means (an F(3, dof) at rest)
    step = step_statistic(blocks.acc_mean, blocks.acc_var, n, kappa)
    step_limit = f_quantile(p, 3.0, dof[:-1] + dof[1:]) * s.threshold**2
    boundary = (step > step_limit) | blocks.after_hole[1:]
    stepping = np.zeros(k_blocks, dtype=bool)
    stepping[:-1] |= step > step_limit
    stepping[1:] |= step > step_limit
    quiet = ~loud & (n >= 2)
    thresholds = {"step": float(np.median(step_limit)) if step_limit.size else float("nan")}
    counts: dict[str, Any] = {}
    gyro_flag = np.zeros(k_blocks, dtype=bool)
    gyro_stat = None
    if kappa_g is not None and blocks.gyro_mean is not None and blocks.gyro_var is not None:
        if gyro_bias is None:
            calm = quiet & ~stepping
            base = blocks.gyro_mean[calm] if calm.sum() >= 3 else blocks.gyro_mean
            # the bias: the densest value of the block means (every rest sits there; moves spread)
            gyro_bias = np.array([half_sample_mode(base[:, j]) for j in range(3)])
        counts["gyro_bias"] = gyro_bias
        wander = np.zeros(3) if rests is None else bias_wander(
            blocks.gyro_mean, blocks.gyro_var, n, kappa_g, gyro_bias, _inside_blocks(rests, k_blocks))
        counts["gyro_wander"] = wander
        gyro_stat = gyro_statistic(blocks.gyro_mean, blocks.gyro_var, n, kappa_g, gyro_bias,
                                   quiet & ~stepping, wander)
        gyro_limit = chi2_quantile(p) * s.gyro_threshold**2
        gyro_flag = gyro_stat > gyro_limit
        quiet &= ~gyro_flag
        thresholds["gyro"] = gyro_limit
    # stretches: runs of quiet blocks with no boundary between them
    starts_b, stops_b = _stretches(quiet, boundary)
    accepted: list[tuple[int, int]] = []
    n_short = n_drift = short_samples = drift_samples = 0
    longest = 0.0
    drift_ratios: list[float] = []
    bstarts, bstops = blocks.starts, blocks.stops
    for a, b in zip(starts_b, stops_b):
        i0, i1 = int(bstarts[a]), int(bstops[b - 1])
        duration = float(t[i1 - 1] - t[i0]) + 1.0 / rate
        longest = max(longest, duration)
        if duration < s.min_dwell_s or (b - a < MIN_TREND_BLOCKS and np.isfinite(s.drift_threshold)):
            # too short for the dwell, or for the drift test to show that its mean does not move
            n_short += 1
            short_samples += i1 - i0
            continue
        ratio = _drift_ratio(blocks, a, b, p, s.drift_threshold)
        if ratio is not None:
            drift_ratios.append(ratio)
            if ratio > 1.0:
                n_drift += 1
                drift_samples += i1 - i0
                continue
        accepted.append((a, b))
    thresholds["drift"] = float(t_quantile(p / 3.0, DRIFT_BATCHES - 2) * s.drift_threshold)
    counts.update(stretches=int(len(starts_b)), short=n_short, short_samples=short_samples, drifting=n_drift,
                  drift_samples=drift_samples, longest_s=longest,
                  largest_drift_ratio=max(drift_ratios) if drift_ratios else None)
    return _Pass(quiet, stepping, loud, gyro_flag, step, step_limit, gyro_stat,
                 thresholds, accepted, counts)


def _drift_ratio(blocks: Blocks, a: int, b: int, p: float, scale: float) -> float | None:
    """The largest trend t statistic of a stretch over its quantile (above 1: it drifts), or ``None`` (too short).

    The stretch's blocks are pooled into at most :data:`DRIFT_BATCHES` consecutive batches; the slope of
    each axis's batch means on time is tested against their own scatter about the line (Student's t with
    ``batches − 2`` degrees of freedom, Bonferroni over the three axes).  Batches, not samples: the scatter
    of batch means includes the noise's colour (flicker, filtering) at the stretch's own scale.
    """
    k = b - a
    if k < MIN_TREND_BLOCKS or not np.isfinite(scale):
        return None
    batches = min(k, DRIFT_BATCHES)
    edges = np.linspace(a, b, batches + 1).round().astype(int)
    w = blocks.n[a:b]
    cw = np.concatenate(([0.0], np.cumsum(w)))
    cm = np.vstack([np.zeros(3), np.cumsum(blocks.acc_mean[a:b] * w[:, None], axis=0)])
    ct = np.concatenate(([0.0], np.cumsum(blocks.t_mid[a:b] * w)))
    lo, hi = edges[:-1] - a, edges[1:] - a
    weight = cw[hi] - cw[lo]
    means = (cm[hi] - cm[lo]) / weight[:, None]
    times = (ct[hi] - ct[lo]) / weight
    tstat = float(np.max(trend_statistic(means, times)))
    return tstat / (t_quantile(p / 3.0, batches - 2) * scale)


def _inside_blocks(rests: list[tuple[int, int]], count: int) -> NDArray[np.bool_]:
    """Mask of the blocks inside the given stretches."""
    mask = np.zeros(count, dtype=bool)
    for a, b in rests:
        mask[a:b] = True
    return mask


def _colour_inside(accepted: list[tuple[int, int]], blocks: Blocks, sensor: str) -> NDArray[np.float64] | None:
    """The noise colour from the pairs of blocks inside the given rests (median ratio over χ²₁'s median)."""
    mean, var = (blocks.acc_mean, blocks.acc_var) if sensor == "acc" else (blocks.gyro_mean, blocks.gyro_var)
    if mean is None or var is None or not accepted:
        return None
    inside = np.zeros(blocks.count - 1, dtype=bool)
    for a, b in accepted:
        inside[a:b - 1] = True
    inside &= blocks.linked()
    if inside.sum() < MIN_COLOUR_PAIRS:
        return None
    d = np.diff(mean, axis=0)[inside]
    w = var / blocks.n[:, None]
    r = d * d / (w[:-1] + w[1:])[inside]
    return np.maximum(np.median(r, axis=0) / REST_QUANTILE_WHITE, 1.0)


def _segmentation(rec: Recording, s: StaticSettings, use: NDArray[np.int64] | None, t: NDArray[np.float64],
                  acc: NDArray[np.float64], gyro_all: NDArray[np.float64] | None, blocks: Blocks,
                  kappa: NDArray[np.float64], kappa_g: NDArray[np.float64] | None, res: _Pass, nominal: Any,
                  rate: float, m: int) -> Segmentation:
    """The poses of the accepted stretches (twitches joined, ends trimmed) and every exclusion counted."""
    n, k_blocks = blocks.n, blocks.count
    bstarts, bstops = blocks.starts, blocks.stops
    groups = _join_twitches(res.accepted, blocks, t, s.threshold, s.min_dwell_s)
    exclusions = dict(rec.exclusions)
    trim = int(round(s.trim_s * rate))
    intervals: list[StaticInterval] = []
    in_pose = np.zeros(m, dtype=bool)
    n_trim = 0
    for group in groups:
        ranges = [(int(bstarts[a]), int(bstops[b - 1])) for a, b in group]
        g0, g1 = ranges[0][0], ranges[-1][1]
        ranges[0] = (min(g0 + trim, ranges[0][1] - 1), ranges[0][1])
        ranges[-1] = (ranges[-1][0], max(g1 - trim, ranges[-1][0] + 1))
        n_trim += (ranges[0][0] - g0) + (g1 - ranges[-1][1])
        pos: slice | NDArray[np.int64] = (slice(ranges[0][0], ranges[0][1]) if len(ranges) == 1
                                          else np.concatenate([np.arange(i0, i1) for i0, i1 in ranges]))
        for i0, i1 in ranges:
            in_pose[i0:i1] = True
        intervals.append(reduce_interval(len(intervals) + 1, rec, use, pos, gyro_all, s.sigma_blocks))
    single = n < 2
    c = res.counts
    _add(exclusions, ISOLATED, int(np.sum(n[single])))
    _add(exclusions, MOVING, int(np.sum(n[~res.quiet & ~single])))
    _add(exclusions, SHORT, c["short_samples"])
    _add(exclusions, SHORT_STRETCHES, c["short"])
    _add(exclusions, DRIFTING, c["drift_samples"])
    _add(exclusions, DRIFTING_STRETCHES, c["drifting"])
    _add(exclusions, TRIMMED, n_trim)
    floors = {"block_samples": float(np.median(n)) if k_blocks else 0.0, "acc_colour": float(np.mean(kappa))}
    floors.update({f"acc_colour_{a}": float(v) for a, v in zip("xyz", kappa)})
    if kappa_g is not None:
        floors["gyro_colour"] = float(np.mean(kappa_g))
    evidence: dict[str, Any] = {
        "block_samples": int(np.median(n)) if k_blocks else 0,
        "block_s": float(np.median(n)) / rate if k_blocks else float("nan"),
        "blocks": k_blocks,
        "step_blocks": int(np.sum(res.stepping)),
        "loud_blocks": int(np.sum(res.loud)),
        "gyro_blocks": int(np.sum(res.gyro_flag)),
        "stretches": c["stretches"],
        "short": c["short"],
        "drifting": c["drifting"],
        "stretches_long": c["stretches"] - c["short"],
        "longest_s": c["longest_s"],
        "largest_drift_ratio": c["largest_drift_ratio"],
    }
    block_of = np.repeat(np.arange(k_blocks), n.astype(np.int64))
    ratio = res.step / res.step_limit
    trace: dict[str, Any] = {
        "t": t,
        "window_samples": evidence["block_samples"],
        "step": np.maximum(np.append(ratio, 0.0), np.insert(ratio, 0, 0.0))[block_of],
        "static": in_pose,
    }
    if res.gyro_stat is not None:
        trace["gyro"] = (res.gyro_stat / res.thresholds["gyro"])[block_of]
    trace["norm_g"] = np.linalg.norm(acc - nominal.offset, axis=1) / nominal.sensitivity
    gyro_bias = c.get("gyro_bias")
    seg = Segmentation(rec, s, intervals, floors, dict(res.thresholds), gyro_bias, exclusions, trace)
    seg.joined = sum(len(g) - 1 for g in groups)
    seg.evidence = evidence
    return seg


def _per_sample(x: NDArray[np.float64], block_of: NDArray[np.int64]) -> NDArray[np.float64]:
    out: NDArray[np.float64] = x[block_of]
    return out


def _stretches(quiet: NDArray[np.bool_], boundary: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Runs of quiet blocks not cut by a boundary (``boundary[k]``: between blocks ``k`` and ``k + 1``)."""
    k = quiet.size
    if k == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    begins = quiet.copy()
    begins[1:] &= ~quiet[:-1] | boundary
    ends = quiet.copy()
    ends[:-1] &= ~quiet[1:] | boundary
    return np.flatnonzero(begins), np.flatnonzero(ends) + 1


def _join_twitches(
    accepted: list[tuple[int, int]], blocks: Blocks, t: NDArray[np.float64], threshold: float, min_dwell: float,
) -> list[list[tuple[int, int]]]:
    """Group consecutive rests separated by less than a dwell whose means agree within their noise (one pose)."""
    groups: list[list[tuple[int, int]]] = []
    for a, b in accepted:
        if groups:
            pa, pb = groups[-1][-1]
            gap = float(t[blocks.starts[a]] - t[blocks.stops[pb - 1] - 1])
            no_hole = not bool(blocks.after_hole[pb:a + 1].any())
            if gap < min_dwell and no_hole and _means_agree(groups[-1], (a, b), blocks, threshold):
                groups[-1].append((a, b))
                continue
        groups.append([(a, b)])
    return groups


def _means_agree(group: list[tuple[int, int]], nxt: tuple[int, int], blocks: Blocks, threshold: float) -> bool:
    """Whether an interruption moved the sensor by less than the noise of one sample (one pose, interrupted).

    No sample can tell apart two orientations whose mean specific forces differ by less than the per-sample
    noise (norm over the axes; the larger of the two stretches'); the merged mean's norm then shrinks by
    ``δ²/(8 |a|)``, second order in the angle, and the merged pose's batch-means noise keeps the difference.
    ``threshold`` (``--static-threshold``) multiplies the tolerance.
    """
    def moments(ranges: list[tuple[int, int]]) -> tuple[NDArray[np.float64], float]:
        idx = np.concatenate([np.arange(a, b) for a, b in ranges])
        w = blocks.n[idx]
        mean = (blocks.acc_mean[idx] * w[:, None]).sum(axis=0) / w.sum()
        noise = float(np.sqrt(np.sum((blocks.acc_var[idx] * w[:, None]).sum(axis=0) / w.sum())))
        return mean, noise

    m1, s1 = moments(group)
    m2, s2 = moments([nxt])
    return float(np.linalg.norm(m1 - m2)) <= threshold * max(s1, s2)


def _add(d: dict[str, int], key: str, value: int) -> None:
    if value:
        d[key] = d.get(key, 0) + int(value)
