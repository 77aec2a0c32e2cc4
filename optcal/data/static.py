"""Static detection: a raw recording in, its rests found by a model of the recording, one pose per rest out.

The model (:mod:`optcal.data.rest_model`): the samples are cut into blocks of ``window_s`` (never
across a time gap); at rest, consecutive block means differ only by the noise of a block mean,
measured where they are (the two blocks' own variance, times the noise colour ``κ²`` the recording
shows between quiet blocks); the gyro's block mean sits at its bias within the noise of its mean and
the bias' wander between rests; a rest's batch means show no trend.  Each test has a threshold at
its distribution's ``1 − false_alarm`` quantile (``false_alarm`` = 10⁻³ per test by default), times
the user's multiplier (``--static-threshold`` for steps, ``--gyro-threshold``, ``--drift-threshold``).

A **rest** is then a run of blocks with no step between them and no gyro motion in them, its first
and last blocks peeled off while their mean differs from the rest of the run (a low-pass filter's
tail, a hand settling), that shows no trend of its accelerometer means (a slow turn) nor, with a
gyro, a mean rate off the bias beyond its batch means' scatter (a turn about the vertical, which the
accelerometer does not see), that is no noisier per sample than :data:`~optcal.data.units.MAX_REST_NOISE_G`
of 1 g, and that lasts at least ``min_dwell_s`` (and two blocks).  The minimum dwell is also the prior
that joins two rests of one orientation separated by less than a dwell (a twitch: their means differ by
less than one sample's noise); a longer interruption is joined when the gyro shows no net turn through it
or, without the gyro as evidence, when the accelerometer's block means never leave the pose
(:func:`~optcal.data.static_stretches.stays_in_pose`: a knock, or a filter's smoothing that the step test cut).  A jump between two holds is a step like any other, so a logger that
stores only its holds is cut at each jump.  When no run qualifies, the recording **never rests**, a
conclusion printed with its evidence and the flag that overrides each test.  Every sample that does not
end in a pose is counted by reason.

Each rest gives one pose (:func:`optcal.data.static_poses.reduce_interval`): the mean, the per-axis
standard deviation, the standard deviation of the mean ``σ_k`` (for the maximum-likelihood weights,
Lu 2017 eq. 14; by batch means, :func:`optcal.data.static_poses.sigma_of_mean`, since sensor noise
is not white), the sample count, the mid time, the mean temperature and the mean gyro reading.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.poses import PoseTable
from optcal.data.recording import Recording
from optcal.data.static_poses import StaticInterval, counted_interval, reduce_interval
from optcal.data.quantiles import np_median
from optcal.data.rest_model import MIN_INDEPENDENT_ACC, MIN_INDEPENDENT_GYRO, WOBBLE_DWELLS, WOBBLE_SHRINK
from optcal.data.rest_tests import RestModel
from optcal.data.static_stretches import group_positions, join_twitches, touches, wobbles
from optcal.data.units import MAX_REST_NOISE_G, nominal_conversion
from optcal.errors import InputError

MOVING = "samples in blocks that move (a step between block means, or a gyro rate off its bias)"
EDGES = "samples at the ends of still stretches whose mean still settles"
SHORT = "samples in still stretches shorter than the minimum dwell"
SHORT_STRETCHES = "still stretches shorter than the minimum dwell"
FEW = ("samples in still stretches holding too few independent samples for the tests of their mean (shorter than a "
       "few correlation times of their noise)")
FEW_STRETCHES = "still stretches rejected as holding too few independent samples (a few correlation times of their noise)"
TRIMMED = "samples trimmed at the ends of static intervals"
SWEEPING = "samples in still stretches whose mean creeps (a trend of its batch means: a slow turn)"
SWEEPING_STRETCHES = "still stretches rejected because their mean creeps (a slow turn)"
TURNING = "samples in still stretches whose gyro mean is off the bias beyond its noise (a slow turn)"
TURNING_STRETCHES = "still stretches rejected because their gyro mean is off the bias (a slow turn)"
WOBBLE = "samples in still stretches whose orientation wobbles (by the gyro) beyond what a pose mean tolerates"
WOBBLE_STRETCHES = "still stretches rejected because their orientation wobbles (by the gyro)"
ODD = "samples in still stretches far noisier than the recording's rests (a move's settling oscillation)"
ODD_STRETCHES = "still stretches rejected as far noisier than the recording's rests"
LOUD = "samples in still stretches noisier per sample than a resting accelerometer"
LOUD_STRETCHES = "still stretches rejected as noisier per sample than a resting accelerometer"
SPINNING = "samples in still stretches no rest can give: their |a| is not gravity's (a steady spin; --keep-spins keeps them)"
SPINNING_STRETCHES = "still stretches rejected as no rest's: their |a| is not gravity's (a steady spin)"
TOUCH = "samples of a pose's end piece shifted after a twitch next to a move (a touch; --keep-touches keeps them)"
TOUCH_STRETCHES = "pose end pieces left out as a touch next to a move (--keep-touches keeps them)"
RAIL = "samples in still stretches holding the gyro at its rail (besides those at the rail, counted while reading; --keep-gyro-rail keeps them)"
RAIL_STRETCHES = "still stretches rejected as holding the gyro at its rail (no rest's rate)"
#: Fewest samples in a block: a variance needs two, the test's F distribution a few more.
MIN_BLOCK_SAMPLES: int = 4
#: Fewest blocks in a rest: one pair of block means is the least that shows that the mean does not move.
MIN_REST_BLOCKS: int = 2


@dataclass(frozen=True)
class StaticSettings:
    """Settings of the rest detector (:mod:`optcal.data.rest_model`).

    Attributes
    ----------
    window_s : float
        Block length, seconds (at least :data:`MIN_BLOCK_SAMPLES` samples).
    threshold : float
        Multiplier of the step test's critical value (``--static-threshold``; above 1 accepts larger steps).
    gyro_threshold : float
        Multiplier of the gyro test's critical value.
    drift_threshold : float
        Multiplier of the trend test's critical value.
    min_dwell_s : float
        Shortest rest, seconds; also the longest interruption joined inside one pose without other evidence.
    trim_s : float
        Cut from each end of every rest, seconds.
    false_alarm : float
        Probability that a test calls motion where the sensor rests (per test).
    use_gyro : bool
        Whether the gyro columns are evidence of motion (``--no-gyro-gate`` turns them off).
    max_gap_s : float or None
        A time step longer than this ends a block and a rest (default: 5 sample periods).
    sigma_blocks : int
        Blocks for the batch-means standard deviation of each pose mean (0: white noise only, ``σ/√n``).
    min_independent : float or None
        Fewest independent samples (samples over the noise colour) a rest holds, of the accelerometer and of
        the gyro alike (``--min-independent``); ``None``: :data:`~optcal.data.rest_model.MIN_INDEPENDENT_ACC`
        and :data:`~optcal.data.rest_model.MIN_INDEPENDENT_GYRO`.
    keep_touches : bool
        Keep a pose's end pieces that :func:`~optcal.data.static_stretches.touches` would leave out
        (``--keep-touches``).
    keep_spins : bool
        Take no bound on a rest's readings (``--keep-spins``): by default a still stretch whose |a| is not
        gravity's is no rest, and a still block whose gyro rate is beyond any MEMS gyro's bias does not set its bias
        (:class:`~optcal.data.rest_bounds.RestBounds`: a steady spin).
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
    min_independent: float | None = None
    keep_touches: bool = False
    keep_spins: bool = False

    def __post_init__(self) -> None:
        for name in ("window_s", "threshold", "gyro_threshold", "drift_threshold"):
            if not getattr(self, name) > 0:
                raise InputError(f"static detection: {name} must be positive, got {getattr(self, name)}")
        if self.min_dwell_s < 0 or self.trim_s < 0:
            raise InputError("static detection: the minimum dwell and the trim must not be negative")
        if self.sigma_blocks < 0 or self.sigma_blocks == 1:
            raise InputError("static detection: sigma_blocks must be 0 (white noise) or at least 2")
        if self.min_independent is not None and not self.min_independent >= 0:
            raise InputError("static detection: min_independent must not be negative")
        if not 0 < self.false_alarm < 0.5:
            raise InputError("static detection: false_alarm must lie between 0 and 0.5")

    def independent_minimums(self) -> tuple[float, float]:
        """Fewest independent samples a rest holds, of the accelerometer and of the gyro, as applied."""
        if self.min_independent is None:
            return MIN_INDEPENDENT_ACC, MIN_INDEPENDENT_GYRO
        return self.min_independent, self.min_independent

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
    noise_floor : dict of str to float
        The noise the model measured: the quietest and the median rest's per-sample noise (raw
        units, norm over the axes), the noise colour ``κ²`` per axis (accelerometer, gyro), the gyro
        bias' wander.
    thresholds : dict of str to float
        The critical values of the tests (step, gyro, trend) with the multipliers applied.
    gyro_bias : ndarray or None
    exclusions : dict of str to int
        Everything excluded, from reading to trimming.
    trace : dict of str to ndarray
        Per usable sample: ``t``, ``norm_g``, the step and gyro statistics over their critical
        values (``step``, ``gyro``) and the pose mask ``static`` (for plots).
    joined : int
        Rests joined to the previous one as the same pose (an interruption shorter than the dwell, with no net
        turn by the gyro, or that never left the pose by the accelerometer).
    evidence : dict of str to float
        Counts of the still stretches each test rejected, and the blocks and pairs tested.
    gyro_unit : str
        How the gyro's unit (its radians per second per unit) was decided: stated, or measured on the moves
        (:func:`optcal.data.static_stretches.decide_gyro_scale`); empty without a gyro.
    rest_bounds : str
        The still blocks the bounds of a rest set aside from the gyro's bias, in words (empty when none).
    pose_statistics : bool
        False when the intervals were only counted (:func:`detect_static` with ``pose_statistics=False``: no
        means, spreads or standard errors, no per-sample curves in ``trace``; :meth:`pose_table` refuses them)
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
    evidence: dict[str, float] = field(default_factory=dict)
    gyro_unit: str = ""
    pose_statistics: bool = True
    rest_bounds: str = ""

    def override_warnings(self) -> list[str]:
        """What each flag that loosened a test of the rest model assumes (printed as warnings)."""
        s, out = self.settings, []
        if not s.use_gyro and self.recording.gyro is not None:
            out.append("--no-gyro-gate: the gyro is not evidence of motion; a turn about the vertical, which the "
                       "accelerometer does not see, passes as a rest")
        for value, flag, what in ((s.threshold, "--static-threshold", "steps between block means"),
                                  (s.gyro_threshold, "--gyro-threshold", "gyro rates off the bias and orientation wobble"),
                                  (s.drift_threshold, "--drift-threshold", "a creep of a stretch's mean")):
            if value > 1:
                out.append(f"{flag} {value:g}: {what} up to {value:g}× the test's critical value are taken for noise "
                           f"(a false-alarm probability far below {s.false_alarm:g}); a slow motion may pass as a rest")
        if s.keep_spins:
            out.append("--keep-spins: a still stretch is a rest whatever its |a| and its gyro rate; a steady spin, "
                       "whose centripetal acceleration is not gravity, may pass as a rest")
        n = s.min_independent
        if n is not None and (n < MIN_INDEPENDENT_ACC or (n < MIN_INDEPENDENT_GYRO and s.use_gyro and self.recording.gyro is not None)):
            out.append(f"--min-independent {n:g}: a still stretch holding {n:g} independent samples is a rest (the "
                       f"model asks for {MIN_INDEPENDENT_ACC:g} of the accelerometer, {MIN_INDEPENDENT_GYRO:g} of the gyro); "
                       "a pause of a slow motion, shorter than a few correlation times of its noise, may pass as a rest")
        return out

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
            "gyro_unit_decision": self.gyro_unit,
            "rest_bounds": self.rest_bounds,
            "n_samples": rec.n,
            "n_samples_in_poses": self.n_used,
            "stretches_joined": self.joined,
            "evidence": dict(self.evidence),
            "intervals": [iv.to_dict() for iv in self.intervals],
        }

    def pose_table(self) -> PoseTable:
        """One pose per interval (``source="raw recording"``)."""
        rec = self.recording
        if not self.intervals:
            raise InputError(no_static_message(self))
        if not self.pose_statistics:
            raise ValueError("this segmentation counted its rests only (detect_static(..., pose_statistics=False))")
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
    """Why no rest was found: the model's conclusion with its evidence, and the flag that overrides each test."""
    rec = seg.recording
    s = seg.settings
    ev = seg.exclusions
    head = f"{rec.path}: no static interval found in {rec.n} samples ({rec.duration_s:.1f} s): "
    reasons = []
    if ev.get(SWEEPING_STRETCHES):
        reasons.append(f"{ev[SWEEPING_STRETCHES]} still stretch(es) whose mean creeps beyond the trend test "
                       f"(|t| > {seg.thresholds.get('trend', float('nan')):.3g}; a slow turn: --drift-threshold N accepts "
                       "N times more)")
    if ev.get(SPINNING_STRETCHES):
        reasons.append(f"{ev[SPINNING_STRETCHES]} still stretch(es) no rest can give: their |a| is not gravity's (a "
                       "steady spin's centripetal acceleration: --keep-spins keeps them)")
    if ev.get(TURNING_STRETCHES):
        reasons.append(f"{ev[TURNING_STRETCHES]} still stretch(es) whose gyro mean is off the bias (a turn the "
                       "accelerometer does not see: --gyro-threshold N accepts N times more, --no-gyro-gate ignores the gyro"
                       + (f"; gyro read as {seg.gyro_unit}" if seg.gyro_unit else "") + ")")
    if ev.get(WOBBLE_STRETCHES):
        reasons.append(f"{ev[WOBBLE_STRETCHES]} still stretch(es) whose orientation wobbles by more than "
                       f"{np.degrees(np.sqrt(2 * WOBBLE_SHRINK)):.2g}° rms by the gyro (a pose mean would shrink by more than "
                       f"{WOBBLE_SHRINK * 1e3:g} mg: --gyro-threshold N accepts N times more)")
    if ev.get(ODD_STRETCHES):
        reasons.append(f"{ev[ODD_STRETCHES]} still stretch(es) far noisier than the recording's rests (a move's settling "
                       "oscillation: --static-threshold N accepts more)")
    if ev.get(LOUD_STRETCHES):
        reasons.append(f"{ev[LOUD_STRETCHES]} still stretch(es) noisier than {MAX_REST_NOISE_G:g} g per sample, a "
                       f"resting accelerometer's most (the quietest: "
                       f"{seg.evidence.get('loud_noise_min_g', float('nan')):.3g} g by the nominal conversion): a "
                       "vibration, or columns that are not an accelerometer's (gyroscope columns? map the "
                       "accelerometer's with --columns)")
    if ev.get(FEW_STRETCHES):
        reasons.append(f"{ev[FEW_STRETCHES]} still stretch(es) holding fewer independent samples than the tests of "
                       f"their mean need ({MIN_INDEPENDENT_ACC:g} of the accelerometer, {MIN_INDEPENDENT_GYRO:g} of the "
                       "gyro: shorter than a few correlation times of their noise, so not told from a pause of a slow "
                       "motion; --min-independent N accepts N, --no-gyro-gate ignores the gyro)")
    if ev.get(SHORT_STRETCHES):
        reasons.append(f"{ev[SHORT_STRETCHES]} still stretch(es) shorter than the minimum dwell {s.min_dwell_s:g} s "
                       "(--min-dwell S, --static-window S for shorter blocks)")
    if not reasons and seg.evidence.get("blocks_turning"):
        reasons.append(f"{int(seg.evidence['blocks_turning'])} block(s) that the accelerometer calls still turn by the "
                       "gyro (its mean rate off the bias beyond the noise of its mean: a turn about the vertical; "
                       "--gyro-threshold N accepts N times more, --no-gyro-gate ignores the gyro)")
    if not reasons:
        reasons.append(f"every pair of {s.window_s:g} s blocks differs by more than the noise of their means allows "
                       f"(false-alarm {s.false_alarm:g}; --static-threshold N accepts steps N times larger, "
                       "--static-window S changes the blocks)")
    return head + "the recording never rests by the model: " + "; ".join(reasons) + "; record the sensor at rest between moves"


# ----------------------------------------------------------------------------- detection
def detect_static(rec: Recording, settings: StaticSettings | None = None, pose_statistics: bool = True) -> Segmentation:
    """Find the rests of a recording by the model of :mod:`optcal.data.rest_model`.

    Parameters
    ----------
    rec : Recording
    settings : StaticSettings, optional
    pose_statistics : bool
        False: the rests found and counted (the same rests), without each pose's mean, spread and standard error
        and without the trace's per-sample curves (``norm_g``, ``step``, ``gyro``) (a still log's still fraction:
        the Allan command's check, a quarter of the time on a 12-hour log).

    Returns
    -------
    Segmentation
        The intervals (possibly none: :meth:`Segmentation.pose_table` then raises
        :class:`InputError` with the model's conclusion), the noise measured, the tests'
        critical values and every exclusion counted.
    """
    s = settings or StaticSettings()
    usable = rec.gyro_usable  # a rest's gyro gates it and gives its bias: a sample the log marks unhealthy is a hole
    every = bool(usable.all())
    use = None if every else np.flatnonzero(usable)
    t = rec.t if use is None else rec.t[use]
    acc = rec.acc if use is None else _usable_rows(rec.acc, use)
    gyro_rows = None if rec.gyro is None else (rec.gyro if use is None else _usable_rows(rec.gyro, use))
    gyro = gyro_rows if s.use_gyro else None  # the gyro as evidence of motion (its means go into the poses anyway)
    m = acc.shape[0]
    rate = rec.rate_hz if np.isfinite(rec.rate_hz) else 1.0
    block = max(MIN_BLOCK_SAMPLES, int(round(s.window_s * rate)))
    max_gap = s.max_gap_s if s.max_gap_s is not None else 5.0 / rate
    breaks = _gaps(t, max_gap)
    nominal = rec.nominal if rec.nominal is not None else nominal_conversion(rec.units, acc)
    exclusions = dict(rec.exclusions)
    noise: dict[str, float] = {}
    limits: dict[str, float] = {}
    evidence: dict[str, float] = {}
    trace: dict[str, Any] = {"t": t, "window_samples": block}
    rail = None if rec.gyro_rail is None or rec.gyro_rail_kept else rec.gyro_rail.samples
    rail = rail if rail is None or use is None else rail[use]  # a rate at the gyro's full scale is no rest's
    # the samples at the gyro's rail are counted while reading (recording.GYRO_SATURATED, the cause of their
    # exclusion, which --keep-gyro-rail undoes); each count below is of the other samples, so that every sample
    # is counted once in a sum of the exclusions
    rail_before = None  # the samples at the rail before each sample (none allocated without a rail)
    if rail is not None:
        rail_before = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(rail, out=rail_before[1:])

    def off_rail(a: int, z: int) -> int:
        """The samples of ``[a, z)`` not at the gyro's rail."""
        return (z - a) - (0 if rail_before is None else int(rail_before[z] - rail_before[a]))

    if m < 2 * MIN_BLOCK_SAMPLES:
        _add(exclusions, MOVING, off_rail(0, m))
        trace["static"] = np.zeros(m, dtype=bool)
        return Segmentation(rec, s, [], noise, limits, None, exclusions, trace, 0, evidence)

    model = RestModel(rec, s, t, acc, gyro, block, breaks, rate)
    runs = model.runs()
    evidence.update(blocks=model.b.count, pairs=int(model.valid.sum()), blocks_turning=model.turning_blocks())
    # ------------------------------------------------------------- each run judged as a rest
    one_g = float(nominal.sensitivity)
    in_pose = np.zeros(m, dtype=bool)
    trim = int(round(s.trim_s * rate))
    kept: list[tuple[int, int, int, int]] = []  # sample range and block range
    counts = {key: 0 for key in (SPINNING, SPINNING_STRETCHES, EDGES, SHORT, SHORT_STRETCHES, FEW, FEW_STRETCHES, SWEEPING, SWEEPING_STRETCHES, TURNING,
                                 TURNING_STRETCHES, WOBBLE, WOBBLE_STRETCHES, LOUD, LOUD_STRETCHES, ODD, ODD_STRETCHES,
                                 TOUCH, TOUCH_STRETCHES, TRIMMED, RAIL, RAIL_STRETCHES)}
    rest_noise: list[float] = []
    gyro_scale = model.gyro_scale
    min_acc, min_gyro = s.independent_minimums()
    wobble_window = max(3, int(round(WOBBLE_DWELLS * s.min_dwell_s * rate)))
    if gyro_scale is not None:
        evidence["gyro_rad_per_unit"] = gyro_scale
    b = model.b
    pieces = model.split_by_noise(runs)
    rejected: list[tuple[float, float, str]] = []  # each still stretch rejected: its time span and reason

    def reject(a: int, z: int, samples: str, stretches: str) -> None:
        counts[samples] += off_rail(a, z)
        counts[stretches] += 1
        rejected.append((float(t[a]), float(t[max(a, z - 1)]), stretches))

    candidates: list[tuple[int, int, int, int]] = []  # sample range and block range of each piece long enough
    for k0, k1 in pieces:
        j0, j1 = model.peel(k0, k1)
        a, z = int(b.start[j0]), int(b.stop[j1 - 1])
        a1, z1 = model.trim_outlying_samples(acc, a, z, j0, j1)
        counts[EDGES] += off_rail(int(b.start[k0]), int(b.stop[k1 - 1])) - off_rail(a1, z1)
        a, z = a1, z1
        duration = t[z - 1] - t[a] + 1.0 / rate
        if duration < s.min_dwell_s or j1 - j0 < MIN_REST_BLOCKS:
            reject(a, z, SHORT, SHORT_STRETCHES)
            continue
        candidates.append((a, z, j0, j1))
    verdicts = model.judge(candidates) if candidates else None
    wobble_limit = np.sqrt(2.0 * WOBBLE_SHRINK) * s.gyro_threshold
    wobbling = np.zeros(len(candidates), dtype=bool)
    if gyro is not None and gyro_scale is not None and candidates:
        wobbling = wobbles(gyro, t, gyro_scale, wobble_window, [(c[0], c[1]) for c in candidates],
                           wobble_limit, b) > wobble_limit
    for i, (a, z, j0, j1) in enumerate(candidates):
        assert verdicts is not None
        per_sample = float(verdicts.per_sample[i])
        if rail is not None and rail[a:z].any():
            reject(a, z, RAIL, RAIL_STRETCHES)
        elif verdicts.cannot_rest[i]:
            reject(a, z, SPINNING, SPINNING_STRETCHES)
        elif per_sample > MAX_REST_NOISE_G * one_g:
            reject(a, z, LOUD, LOUD_STRETCHES)
            evidence["loud_noise_min_g"] = min(evidence.get("loud_noise_min_g", np.inf), per_sample / one_g)
        elif verdicts.creeps[i]:
            reject(a, z, SWEEPING, SWEEPING_STRETCHES)
        elif wobbling[i]:
            reject(a, z, WOBBLE, WOBBLE_STRETCHES)
        elif verdicts.turns[i]:
            reject(a, z, TURNING, TURNING_STRETCHES)
        # last: what no test above could show moving but holds too little independent evidence to show at rest
        elif verdicts.independent[i] < min_acc or verdicts.independent_gyro[i] < min_gyro:
            reject(a, z, FEW, FEW_STRETCHES)
        elif z - a - 2 * trim < 2:
            reject(a, z, SHORT, SHORT_STRETCHES)
        else:
            counts[TRIMMED] += 2 * trim
            kept.append((a + trim, z - trim, j0, j1))
            rest_noise.append(per_sample)
    kept, odd = model.drop_odd_noise(kept)
    for a, z, _, _ in odd:
        reject(a, z, ODD, ODD_STRETCHES)
    groups = join_twitches(kept, t, model, s.min_dwell_s, gyro, gyro_scale, max_gap)
    touched: list[tuple[int, int]] = []
    if not s.keep_touches:
        groups, touched = touches(groups, kept, model)
        for a, z in touched:
            reject(a, z, TOUCH, TOUCH_STRETCHES)
    for group in groups:
        for a, z in group:
            in_pose[a:z] = True
    if pose_statistics:
        intervals = [reduce_interval(i + 1, rec, use, group_positions(group), gyro_rows, s.sigma_blocks)
                     for i, group in enumerate(groups)]
    else:
        intervals = [counted_interval(i + 1, rec, use, group) for i, group in enumerate(groups)]
    in_runs = sum(off_rail(int(b.start[k0]), int(b.stop[k1 - 1])) for k0, k1 in pieces)
    _add(exclusions, MOVING, off_rail(0, m) - in_runs)  # the rest of the runs' samples are counted by reason below
    for key, value in counts.items():
        _add(exclusions, key, value)
    for key in (SPINNING_STRETCHES, SHORT_STRETCHES, FEW_STRETCHES, SWEEPING_STRETCHES, TURNING_STRETCHES, WOBBLE_STRETCHES, LOUD_STRETCHES, ODD_STRETCHES,
                TOUCH_STRETCHES):
        evidence[key] = counts[key]
    evidence["still_stretches"] = len(runs)
    noise.update(model.noise())
    if rest_noise:
        noise["rest_noise_min"] = float(min(rest_noise))
        noise["rest_noise_median"] = float(np_median(rest_noise))
    limits.update(model.limits())
    trace["static"] = in_pose
    trace["rejected"] = rejected
    if pose_statistics:  # the per-sample curves of the plots (three arrays of the samples' length)
        trace.update(model.trace(m))
        norm = _distance(acc, nominal.offset)
        trace["norm_g"] = np.divide(norm, nominal.sensitivity, out=norm)
    return Segmentation(rec, s, intervals, noise, limits, model.bias, exclusions, trace,
                        len(kept) - len(touched) - len(groups), evidence, model.gyro_unit_reason, pose_statistics,
                        model.set_aside())


#: Time steps compared at a time by :func:`_gaps`: their differences (512 KiB) stay in the processor's cache, where a
#: 12-hour log's whole ``np.diff(t)`` was 35 MB faulted in and read twice.  Speed only.
GAP_PIECE: int = 1 << 16


def _gaps(t: NDArray[np.float64], max_gap: float) -> NDArray[np.int64]:
    """The positions after a time step longer than ``max_gap`` (``np.flatnonzero(np.diff(t) > max_gap) + 1``), piece by
    piece through one buffer."""
    steps = max(t.size - 1, 0)
    if steps == 0:
        return np.zeros(0, dtype=np.int64)
    d = np.empty(min(GAP_PIECE, steps))
    found = []
    for a in range(0, steps, GAP_PIECE):
        z = min(a + GAP_PIECE, steps)
        piece = d[: z - a]
        np.subtract(t[a + 1:z + 1], t[a:z], out=piece)
        hits = np.flatnonzero(piece > max_gap)
        if hits.size:
            found.append(hits + (a + 1))
    return np.concatenate(found).astype(np.int64, copy=False) if found else np.zeros(0, dtype=np.int64)


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


def _usable_rows(x: NDArray[np.float64], use: NDArray[np.int64]) -> NDArray[np.float64]:
    """The rows ``use`` of ``x`` (n, k) as a column-major copy (contiguous columns, as a recording's)."""
    out = np.empty((use.size, x.shape[1]), order="F")
    for j in range(x.shape[1]):
        np.take(x[:, j], use, out=out[:, j])
    return out


def _add(d: dict[str, int], key: str, value: int) -> None:
    if value:
        d[key] = d.get(key, 0) + int(value)

