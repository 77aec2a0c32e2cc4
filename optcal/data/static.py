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
less than one sample's noise).  A jump between two holds is a step like any other, so a logger that
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
from scipy import stats

from optcal.core.poses import PoseTable
from optcal.data import rest_model as rm
from optcal.data.recording import Recording
from optcal.data.static_poses import StaticInterval, reduce_interval
from optcal.data.static_stretches import group_positions, true_runs
from optcal.data.units import MAX_REST_NOISE_G, nominal_conversion
from optcal.core.units import RAD_PER_UNIT
from optcal.data.window_stats import quantum
from optcal.errors import InputError

MOVING = "samples in blocks that move (a step between block means, or a gyro rate off its bias)"
EDGES = "samples at the ends of still stretches whose mean still settles"
SHORT = "samples in still stretches shorter than the minimum dwell"
SHORT_STRETCHES = "still stretches shorter than the minimum dwell"
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
#: Fewest samples in a block: a variance needs two, the test's F distribution a few more.
MIN_BLOCK_SAMPLES: int = 4
#: Two rests closer than a dwell whose means differ by less than this many per-sample standard deviations are
#: one pose: the shift lies inside the samples' own ±3σ spread (a flicker noise wanders so between two
#: pieces of one rest), far below any change of orientation a calibration uses.
SAME_POSE_SAMPLE_SIGMAS: float = 3.0
#: Largest shrink of a pose mean's norm, relative to 1 g, that an orientation wobbling about its mean may cause:
#: a wobble of rms angle θ shrinks the mean of gravity's projection by about θ²/2, so a rest must hold its
#: orientation within θ = √(2 × 10⁻⁴) ≈ 0.8° rms (0.1 mg, the accuracy the calibrations here are judged at).
WOBBLE_SHRINK: float = 1e-4
#: Dwells over which the wobble is measured: long enough to see a hand's slow sway (about 1 Hz), short
#: enough that the gyro's own angle random walk and bias wander, integrated over it, stay far below the tolerance.
WOBBLE_DWELLS: float = 8.0
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
        Shortest rest, seconds; also the longest interruption joined inside one pose.
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
            raise InputError("static detection: false_alarm must lie between 0 and 0.5")

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
        Rests joined to the previous one as the same pose (an interruption shorter than the dwell).
    evidence : dict of str to float
        Counts of the still stretches each test rejected, and the blocks and pairs tested.
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
    if ev.get(TURNING_STRETCHES):
        reasons.append(f"{ev[TURNING_STRETCHES]} still stretch(es) whose gyro mean is off the bias (a turn the "
                       "accelerometer does not see: --gyro-threshold N accepts N times more, --no-gyro-gate ignores the gyro)")
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
def detect_static(rec: Recording, settings: StaticSettings | None = None) -> Segmentation:
    """Find the rests of a recording by the model of :mod:`optcal.data.rest_model`.

    Parameters
    ----------
    rec : Recording
    settings : StaticSettings, optional

    Returns
    -------
    Segmentation
        The intervals (possibly none: :meth:`Segmentation.pose_table` then raises
        :class:`InputError` with the model's conclusion), the noise measured, the tests'
        critical values and every exclusion counted.
    """
    s = settings or StaticSettings()
    every = bool(rec.usable.all())
    use = None if every else np.flatnonzero(rec.usable)
    t = rec.t if use is None else rec.t[use]
    acc = rec.acc if use is None else _usable_rows(rec.acc, use)
    gyro_rows = None if rec.gyro is None else (rec.gyro if use is None else _usable_rows(rec.gyro, use))
    gyro = gyro_rows if s.use_gyro else None  # the gyro as evidence of motion (its means go into the poses anyway)
    m = acc.shape[0]
    rate = rec.rate_hz if np.isfinite(rec.rate_hz) else 1.0
    block = max(MIN_BLOCK_SAMPLES, int(round(s.window_s * rate)))
    max_gap = s.max_gap_s if s.max_gap_s is not None else 5.0 / rate
    breaks = np.flatnonzero(np.diff(t) > max_gap) + 1 if m > 1 else np.zeros(0, dtype=np.int64)
    nominal = rec.nominal if rec.nominal is not None else nominal_conversion(rec.units, acc)
    exclusions = dict(rec.exclusions)
    noise: dict[str, float] = {}
    limits: dict[str, float] = {}
    evidence: dict[str, float] = {}
    trace: dict[str, Any] = {"t": t, "window_samples": block}
    if m < 2 * MIN_BLOCK_SAMPLES:
        _add(exclusions, MOVING, m)
        trace["static"] = np.zeros(m, dtype=bool)
        return Segmentation(rec, s, [], noise, limits, None, exclusions, trace, 0, evidence)

    model = _RestModel(rec, s, t, acc, gyro, block, breaks, rate)
    runs = model.runs()
    evidence.update(blocks=model.b.count, pairs=int(model.valid.sum()), blocks_turning=model.turning_blocks())
    # ------------------------------------------------------------- each run judged as a rest
    one_g = float(nominal.sensitivity)
    in_pose = np.zeros(m, dtype=bool)
    trim = int(round(s.trim_s * rate))
    kept: list[tuple[int, int, int, int]] = []  # sample range and block range
    counts = {key: 0 for key in (EDGES, SHORT, SHORT_STRETCHES, SWEEPING, SWEEPING_STRETCHES, TURNING,
                                 TURNING_STRETCHES, WOBBLE, WOBBLE_STRETCHES, LOUD, LOUD_STRETCHES, ODD, ODD_STRETCHES,
                                 TRIMMED)}
    rest_noise: list[float] = []
    gyro_scale = model.gyro_scale
    wobble_window = max(3, int(round(WOBBLE_DWELLS * s.min_dwell_s * rate)))
    if gyro_scale is not None:
        evidence["gyro_rad_per_unit"] = gyro_scale
    b = model.b
    pieces = model.split_by_noise(runs)
    for k0, k1 in pieces:
        j0, j1 = model.peel(k0, k1)
        counts[EDGES] += int(b.stop[k1 - 1] - b.start[k0]) - int(b.stop[j1 - 1] - b.start[j0])
        a, z = int(b.start[j0]), int(b.stop[j1 - 1])
        a1, z1 = model.trim_outlying_samples(acc, a, z, j0, j1)
        counts[EDGES] += (a1 - a) + (z - z1)
        a, z = a1, z1
        duration = t[z - 1] - t[a] + 1.0 / rate
        if duration < s.min_dwell_s or j1 - j0 < MIN_REST_BLOCKS or model.effective_samples(a, z) < MIN_REST_BLOCKS:
            counts[SHORT] += z - a
            counts[SHORT_STRETCHES] += 1
            continue
        per_sample = model.spread(j0, j1)
        if per_sample > MAX_REST_NOISE_G * one_g:
            counts[LOUD] += z - a
            counts[LOUD_STRETCHES] += 1
            evidence["loud_noise_min_g"] = min(evidence.get("loud_noise_min_g", np.inf), per_sample / one_g)
            continue
        if model.creeps(j0, j1):
            counts[SWEEPING] += z - a
            counts[SWEEPING_STRETCHES] += 1
            continue
        if gyro is not None and gyro_scale is not None and _wobble(
                gyro[a:z], t[a:z], gyro_scale, wobble_window) > np.sqrt(2.0 * WOBBLE_SHRINK) * s.gyro_threshold:
            counts[WOBBLE] += z - a
            counts[WOBBLE_STRETCHES] += 1
            continue
        if model.turns(j0, j1):
            counts[TURNING] += z - a
            counts[TURNING_STRETCHES] += 1
            continue
        a2, z2 = a + trim, z - trim
        if z2 - a2 < 2:
            counts[SHORT] += z - a
            counts[SHORT_STRETCHES] += 1
            continue
        counts[TRIMMED] += (a2 - a) + (z - z2)
        kept.append((a2, z2, j0, j1))
        rest_noise.append(per_sample)
    kept, n_odd, n_odd_samples = model.drop_odd_noise(kept)
    counts[ODD] += n_odd_samples
    counts[ODD_STRETCHES] += n_odd
    groups = _join_twitches(kept, t, model, s.min_dwell_s, gyro, gyro_scale, max_gap)
    for group in groups:
        for a, z in group:
            in_pose[a:z] = True
    intervals = [reduce_interval(i + 1, rec, use, group_positions(group), gyro_rows, s.sigma_blocks)
                 for i, group in enumerate(groups)]
    in_runs = sum(int(b.stop[k1 - 1] - b.start[k0]) for k0, k1 in pieces)
    _add(exclusions, MOVING, m - in_runs)  # the rest of the runs' samples are counted by reason below
    for key, value in counts.items():
        _add(exclusions, key, value)
    for key in (SHORT_STRETCHES, SWEEPING_STRETCHES, TURNING_STRETCHES, WOBBLE_STRETCHES, LOUD_STRETCHES, ODD_STRETCHES):
        evidence[key] = counts[key]
    evidence["still_stretches"] = len(runs)
    noise.update(model.noise())
    if rest_noise:
        noise["rest_noise_min"] = float(min(rest_noise))
        noise["rest_noise_median"] = float(np.median(rest_noise))
    limits.update(model.limits())
    trace.update(model.trace(m))
    trace["static"] = in_pose
    norm = _distance(acc, nominal.offset)
    trace["norm_g"] = np.divide(norm, nominal.sensitivity, out=norm)
    return Segmentation(rec, s, intervals, noise, limits, model.bias, exclusions, trace,
                        len(kept) - len(groups), evidence)


class _RestModel:
    """The blocks of one recording and the tests of :mod:`optcal.data.rest_model` on them, measured in two passes."""

    def __init__(self, rec: Recording, s: StaticSettings, t: NDArray[np.float64], acc: NDArray[np.float64],
                 gyro: NDArray[np.float64] | None, block: int, breaks: NDArray[np.int64], rate: float) -> None:
        self.s = s
        self.rate = rate
        qa = quantum(acc) or 0.0
        qg = (quantum(gyro) or 0.0) if gyro is not None else 0.0
        self.block = block
        self.b = b = rm.make_blocks(t, acc, gyro, block, breaks, qa, qg)
        self.half_width = max(1, int(np.ceil(s.min_dwell_s * rate / (2.0 * block))))
        self.dwell_blocks = max(1, int(np.ceil(s.min_dwell_s * rate / block)))
        b.var_ref = rm.local_noise(b.var, b.joined, self.half_width)
        self.valid = b.joined[1:]
        self.dof = b.n[1:] + b.n[:-1] - 2.0
        self.ratios = rm.pair_ratios(b.mean, b.var_ref, b.n)
        dof0 = float(np.median(self.dof)) if self.dof.size else 1.0
        # Noise colour, first from the pairs of the quietest quarter of the blocks (a motion adds to a block's
        # spread, so the quietest blocks are at rest, or the slowest moments of a recording that never rests)
        calm = rm.calm_pairs(b.var, self.valid)
        if calm.sum() >= rm.MIN_COLOUR_PAIRS:
            self.kappa2 = rm.noise_colour(self.ratios[calm], dof0, 0.5)
        else:
            self.kappa2 = rm.noise_colour(self.ratios[self.valid], dof0, rm.QUIET_PAIRS_QUANTILE)
        self.step_limit = rm.step_limit(s.false_alarm, self.dof) * s.threshold
        self.bias: NDArray[np.float64] | None = None
        self.gyro_scale: float | None = None  # rad/s per gyro unit, once the bias is known
        nominal = rec.nominal if rec.nominal is not None else nominal_conversion(rec.units, acc)
        self.one_g = float(nominal.sensitivity)
        self.gkappa2 = np.ones(3)
        self.gvar_ref: NDArray[np.float64] | None = None
        self.wander2 = np.zeros(3)
        self.gyro_limit = rm.step_limit(s.false_alarm, b.n - 1.0) * s.gyro_threshold
        self.still = np.ones(b.count, dtype=bool)
        self._pass(first=True)
        self.gyro_scale = _gyro_rad_per_unit(rec, gyro, self.bias, self.b)
        # Second pass: the noise colour and the gyro bias' wander measured inside the rests the first pass found
        inside = self._pairs_inside(self.runs())
        if inside.sum() >= 8:
            self.kappa2 = rm.noise_colour(self.ratios[inside], dof0, 0.5)
        self._pass(first=False)

    def _pass(self, first: bool) -> None:
        b = self.b
        self.step = rm.step_statistic(self.ratios, self.kappa2)
        if first:
            self.var_steps = rm.log_variance_steps(b.var)
            self.var_limit = rm.variance_step_limit(self.var_steps[self.valid], self.s.false_alarm) * self.s.threshold
        self.quiet = self.valid & (self.step <= self.step_limit) & (self.var_steps <= self.var_limit)
        if b.gmean is None or b.gvar is None:
            return
        acc_still = np.zeros(b.count, dtype=bool)
        acc_still[1:] |= self.quiet
        acc_still[:-1] |= self.quiet
        base = acc_still if acc_still.sum() >= 3 else np.ones(b.count, dtype=bool)
        if first:
            self.bias = np.array([rm.half_sample_mode(b.gmean[base, j]) for j in range(3)])
            self.gvar_ref = rm.local_noise(b.gvar, b.joined, self.half_width)
            gratios = rm.pair_ratios(b.gmean, self.gvar_ref, b.n)
            pairs = self.quiet if self.quiet.sum() >= 8 else self.valid
            self.gkappa2 = rm.noise_colour(gratios[pairs], float(np.median(self.dof)), rm.QUIET_PAIRS_QUANTILE)
        else:
            self._measure_wander()
        assert self.bias is not None and self.gvar_ref is not None
        self.gstat = rm.gyro_statistic(b.gmean, self.gvar_ref, b.n, self.bias, self.gkappa2, self.wander2)
        self.still = self.gstat <= self.gyro_limit

    def _measure_wander(self) -> None:
        """The gyro bias' wander between rests: the scatter of the first rests' mean rates beyond their noise."""
        b = self.b
        assert self.bias is not None and b.gmean is not None and b.gvar is not None
        means, noise2 = [], []
        for k0, k1 in self.runs():
            n = b.n[k0:k1].sum()
            means.append((b.gmean[k0:k1] * b.n[k0:k1, None]).sum(axis=0) / n)
            noise2.append(self.gkappa2 * np.median(b.gvar[k0:k1], axis=0) / n)
        if means:
            # the bias re-estimated from the rests themselves (the half-sample mode of all still blocks is a start:
            # its own error, integrated over a long rest, would look like a turn)
            self.bias = np.median(np.asarray(means), axis=0)
        if len(means) >= 3:
            dev = np.asarray(means) - self.bias
            robust2 = (1.4826 * np.median(np.abs(dev), axis=0)) ** 2
            self.wander2 = np.maximum(robust2 - np.median(noise2, axis=0), 0.0)
            if self.gyro_scale is not None:  # a scatter beyond any MEMS gyro's bias change is of false rests
                self.wander2 = np.minimum(self.wander2, (MAX_BIAS_WANDER_RAD_S / self.gyro_scale) ** 2)

    def turning_blocks(self) -> int:
        """Blocks the accelerometer calls still (a quiet pair on either side) whose gyro mean is off the bias."""
        acc_still = np.zeros(self.b.count, dtype=bool)
        acc_still[1:] |= self.quiet
        acc_still[:-1] |= self.quiet
        return int(np.sum(acc_still & ~self.still))

    def runs(self) -> list[tuple[int, int]]:
        """Block ranges ``[k0, k1)`` of still blocks joined by quiet pairs."""
        link = self.quiet & self.still[1:] & self.still[:-1]
        out: list[tuple[int, int]] = []
        k0 = 0
        for k in range(1, self.b.count + 1):
            if k == self.b.count or not link[k - 1]:
                if k - k0 >= 1 and self.still[k0:k].all():
                    out.append((k0, k))
                k0 = k
        return out

    def _pairs_inside(self, runs: list[tuple[int, int]]) -> NDArray[np.bool_]:
        inside = np.zeros(self.valid.size, dtype=bool)
        for k0, k1 in runs:
            inside[k0:k1 - 1] = True
        return inside & self.valid

    def split_by_noise(self, runs: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Cut out of each run the blocks far noisier than the run's quieter quarter: a rest has one noise level.

        A smooth motion (all of a low-pass filtered recording's motion) changes the block means and the
        block variances gradually, so that no pair of consecutive blocks tells it from the noise; its
        blocks are still many times noisier than the rest around them.  The critical value is the
        variance-step test's (:func:`optcal.data.rest_model.variance_step_limit`).
        """
        b = self.b
        out: list[tuple[int, int]] = []
        total = np.maximum(b.var.sum(axis=1), np.finfo(float).tiny)
        for k0, k1 in runs:
            # the quieter blocks of the run and of a dwell on either side: a short stretch of a move's tail is
            # measured against the rest it settles into
            w = self.dwell_blocks
            level = float(np.quantile(total[max(0, k0 - w):min(b.count, k1 + w)], rm.QUIET_PAIRS_QUANTILE))
            calm = np.log(total[k0:k1] / level) <= self.var_limit
            starts, stops = true_runs(calm)
            out.extend((k0 + int(a), k0 + int(z)) for a, z in zip(starts, stops))
        return out

    def peel(self, k0: int, k1: int) -> tuple[int, int]:
        """Drop the run's end blocks while their mean differs from the rest of the run's (a settling tail)."""
        b = self.b
        while k1 - k0 >= 3:
            changed = False
            for end in (k0, k1 - 1):
                # against the blocks next to it: a rest's mean may wander (flicker) over its length
                others = slice(k0 + 1, min(k1, k0 + 1 + self.half_width)) if end == k0 else slice(max(k0, k1 - 1 - self.half_width), k1 - 1)
                n_rest = float(b.n[others].sum())
                rest_mean = (b.mean[others] * b.n[others, None]).sum(axis=0) / n_rest
                stat = rm.mean_shift_statistic(b.mean[end], b.var_ref[end], float(b.n[end]), rest_mean, self.kappa2, n_rest)
                if stat > float(rm.step_limit(self.s.false_alarm, b.n[end] - 1.0)) * self.s.threshold:
                    if end == k0:
                        k0 += 1
                    else:
                        k1 -= 1
                    changed = True
                    break
            if not changed:
                break
        return k0, k1

    def spread(self, k0: int, k1: int) -> float:
        """Per-sample standard deviation of the stretch about its mean (norm over the axes; the spread of its
        block means included, so that a stretch that moves is as loud as its motion)."""
        b = self.b
        w = b.n[k0:k1, None]
        mean = (b.mean[k0:k1] * w).sum(axis=0) / w.sum()
        total = ((b.var[k0:k1] * (w - 1.0)).sum(axis=0) + (w * (b.mean[k0:k1] - mean) ** 2).sum(axis=0)) / (w.sum() - 1.0)
        return float(np.sqrt(total.sum()))

    def effective_samples(self, a: int, z: int) -> float:
        """Independent samples in ``[a, z)``: the samples over the noise colour per sample (a block's ``κ²`` samples
        carry the information of one when the noise is correlated over them)."""
        per_sample = max(float(np.median(self.kappa2)) / self.block, 1.0 / self.block)
        return (z - a) / max(per_sample * self.block, 1.0)

    def trim_outlying_samples(self, acc: NDArray[np.float64], a: int, z: int, j0: int, j1: int) -> tuple[int, int]:
        """Trim single samples off the ends of a rest while they lie outside its noise.

        A block edge falls anywhere: the first or last block of a rest may hold a few samples of the jump or
        move next to it (a logger that stores only holds, a block that straddles the start of a move).  A sample
        whose χ²₃ distance from the rest's mean, in its per-sample noise (the median block variance), is beyond
        the ``1 - false_alarm`` quantile is not of the rest; trimming stops at the first one within.
        """
        b = self.b
        w = b.n[j0:j1, None]
        mean = (b.mean[j0:j1] * w).sum(axis=0) / w.sum()
        var = np.maximum(np.median(b.var[j0:j1], axis=0), np.finfo(float).tiny)
        limit = rm.chi2_limit(self.s.false_alarm, 3) * self.s.threshold

        def outside(i: int) -> bool:
            d = acc[i] - mean
            return float(np.sum(d * d / var)) > limit

        edge = max(1, int(b.n[j0]))  # at most one block's worth from each end
        start, stop = a, z
        while start < min(a + edge, stop - 2) and outside(start):
            start += 1
        while stop > max(z - edge, start + 2) and outside(stop - 1):
            stop -= 1
        return start, stop

    def drop_odd_noise(self, kept: list[tuple[int, int, int, int]]
                       ) -> tuple[list[tuple[int, int, int, int]], int, int]:
        """Drop the still stretches whose noise is far above the recording's rests' (a move's settling oscillation).

        A rest's noise differs from rest to rest, but not beyond what the recording's own blocks show: a
        stretch whose block variance (median over its blocks, summed over the axes) exceeds the duration-weighted
        median of the rests' by more than twice the variance-step test's critical value (in log variance: the
        largest change between two blocks of one rest, once for the rest and once for the other) oscillates
        inside its blocks, which block means cannot see.
        """
        b = self.b
        if len(kept) < 3:
            return kept, 0, 0
        level = np.array([np.log(max(float(np.median(b.var[j0:j1].sum(axis=1))), np.finfo(float).tiny))
                          for _, _, j0, j1 in kept])
        weight = np.array([float(z - a) for a, z, _, _ in kept])
        order = np.argsort(level)
        cumulative = np.cumsum(weight[order])
        typical = float(level[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])
        odd = level > typical + 2.0 * self.var_limit
        dropped = [k for k, flag in zip(kept, odd) if flag]
        return [k for k, flag in zip(kept, odd) if not flag], len(dropped), sum(z - a for a, z, _, _ in dropped)

    def creeps(self, k0: int, k1: int) -> bool:
        """Whether the run's accelerometer mean moves (a slow turn).

        Either its batch means trend significantly (Student's t of their slope) by more than the samples' own
        spread about the stretch's mean (:data:`SAME_POSE_SAMPLE_SIGMAS` σ; a creep hidden in it, a flicker
        noise's or a warming sensor's, moves no pose) or than a pose tolerates (a steady creep through Δ shrinks the mean's
        norm by Δ²/24: ``√(24 WOBBLE_SHRINK)`` g); or its batch means range over more than both, which no
        noise does whatever its colour (a batch mean scatters less than the samples) and a turn along a
        curved path does without a straight trend.
        """
        b = self.b
        tstat, dof, change, spread = rm.trend_statistic(b.t_mid[k0:k1], b.mean[k0:k1])
        if dof <= 0:  # too few blocks for batches: the blocks' own means are the batch means
            spread = float(np.linalg.norm(b.mean[k0:k1].max(axis=0) - b.mean[k0:k1].min(axis=0)))
        noise = SAME_POSE_SAMPLE_SIGMAS * self.spread(k0, k1)
        pose = np.sqrt(24.0 * WOBBLE_SHRINK) * self.one_g
        k = self.s.drift_threshold
        trending = dof > 0 and tstat > rm.trend_limit(self.s.false_alarm, dof) * k and change > min(noise, pose) * k
        return bool(trending or spread > max(noise, pose) * k)

    def turns(self, k0: int, k1: int) -> bool:
        """Whether the run's mean rate is off the bias -- significantly, or by more than a MEMS gyro's bias moves
        (:data:`MAX_BIAS_WANDER_RAD_S`) -- through more than a pose's wobble tolerance.

        The noise of the run's mean rate is the scatter of its :data:`~optcal.data.rest_model.TREND_BATCHES`
        batch means (a hand's tremor and flicker included; Student's t with their dof) when the run has as many
        blocks, else the blocks' own noise of the mean times the gyro's noise colour (normal); the bias' wander
        between rests is added.  A significant offset that turns the sensor through less than
        ``√(2 WOBBLE_SHRINK)`` over the run, or over :data:`WOBBLE_DWELLS` dwells if the run is longer (a hand
        sagging by a fraction of a degree, a bias wandering over minutes), moves no pose.
        """
        b = self.b
        if b.gmean is None or self.bias is None:
            return False
        k = k1 - k0
        w = b.n[k0:k1, None]
        off = (b.gmean[k0:k1] * w).sum(axis=0) / w.sum() - self.bias
        if k >= rm.TREND_BATCHES:
            groups = np.array_split(np.arange(k0, k1), rm.TREND_BATCHES)
            xb = np.array([b.gmean[g].mean(axis=0) for g in groups])
            se2 = xb.var(axis=0, ddof=1) / rm.TREND_BATCHES + self.wander2
            limit = rm.trend_limit(self.s.false_alarm, rm.TREND_BATCHES - 1)
        else:
            assert self.gvar_ref is not None
            se2 = self.gkappa2 * np.median(self.gvar_ref[k0:k1], axis=0) / w.sum() + self.wander2
            limit = rm.normal_limit(self.s.false_alarm / 6.0)
        z = np.abs(off) / np.sqrt(np.maximum(se2, np.finfo(float).tiny))
        significant = bool(np.max(z) > limit * self.s.gyro_threshold)
        if self.gyro_scale is None:
            return significant
        # off the bias by more than any MEMS gyro's bias moves within a session: a rotation, whatever the
        # statistics of a stretch that shakes say of its noise
        beyond_bias = float(np.linalg.norm(off)) * self.gyro_scale > MAX_BIAS_WANDER_RAD_S * self.s.gyro_threshold
        if not (significant or beyond_bias):
            return False
        # over a wobble window at most: a bias that wanders by a little, integrated over minutes, is no turn
        duration = min(float(b.t_mid[k1 - 1] - b.t_mid[k0]) + float(b.n[k0]) / self.rate,
                       WOBBLE_DWELLS * self.s.min_dwell_s)
        turned = float(np.linalg.norm(off)) * self.gyro_scale * duration
        return turned > np.sqrt(2.0 * WOBBLE_SHRINK) * self.s.gyro_threshold

    def noise(self) -> dict[str, float]:
        out = {f"acc_colour_{a}": float(v) for a, v in zip("xyz", self.kappa2)}
        if self.bias is not None:
            out.update({f"gyro_colour_{a}": float(v) for a, v in zip("xyz", self.gkappa2)})
            out.update({f"gyro_wander_{a}": float(np.sqrt(v)) for a, v in zip("xyz", self.wander2)})
        return out

    def limits(self) -> dict[str, float]:
        out = {"step": float(np.median(self.step_limit)) if self.step_limit.size else float("nan"),
               "trend": rm.trend_limit(self.s.false_alarm, rm.TREND_BATCHES - 2) * self.s.drift_threshold}
        if self.bias is not None:
            out["gyro"] = float(np.median(self.gyro_limit))
        return out

    def trace(self, m: int) -> dict[str, NDArray[np.float64]]:
        """The step and gyro statistics over their critical values, per sample (the larger of a block's two pairs)."""
        b = self.b
        ratio = np.where(self.valid, self.step / self.step_limit, 0.0)
        per_block = np.zeros(b.count)
        per_block[1:] = ratio
        per_block[:-1] = np.maximum(per_block[:-1], ratio)
        lengths = (b.stop - b.start).astype(int)
        out = {"step": np.repeat(per_block, lengths)}
        if self.bias is not None:
            out["gyro"] = np.repeat(self.gstat / self.gyro_limit, lengths)
        return out


#: Largest change of a MEMS gyro's bias between the rests of one session, rad/s (1 °/s): in-run bias stability is
#: 0.001-0.1 °/s and the thermal drift at most about 0.1 °/s per °C over the few °C of a session; rests whose mean
#: rates scatter more are not all rests.
MAX_BIAS_WANDER_RAD_S: float = float(np.radians(1.0))

#: Quantile of the block-to-block rates at which the gyro's readings are set against the accelerometer's turn rate:
#: the fast moves, where a gyro's bias is small beside the rate.
UNIT_RATE_QUANTILE: float = 0.9


def _gyro_rad_per_unit(rec: Recording, gyro: NDArray[np.float64] | None, bias: NDArray[np.float64] | None,
                       blocks: rm.Blocks) -> float | None:
    """Radians per second per gyro unit, for a gyro whose unit the file does not state.

    The moves say it: gravity's direction in the sensor turns no faster than the sensor, so between
    consecutive blocks the accelerometer's turn rate |Δĝ|/Δt is at most the gyro's rate; at the fast moves
    (the :data:`UNIT_RATE_QUANTILE` quantile of both) the gyro reads 1-3 times the accelerometer's turn rate
    in rad/s and 57 times more in °/s.  A ratio above √57.3 (half-way on the log scale) says °/s.  A recording
    that never turns (its accelerometer's fast quantile within its noise) keeps the convention of the
    accelerometer's units: rad/s beside m/s² (ROS's ``sensor_msgs/Imu``), °/s beside g (datasheets).
    ``None`` for counts (their scale is the sensor's).
    """
    if gyro is None:
        return None
    if rec.gyro_units in RAD_PER_UNIT:
        return RAD_PER_UNIT[rec.gyro_units]
    if rec.gyro_units is not None or bias is None or blocks.gmean is None or rec.units == "counts":
        return None  # counts, or beside an accelerometer in counts: the scale is the sensor's
    u = blocks.mean / np.linalg.norm(blocks.mean, axis=1, keepdims=True)
    dt = np.diff(blocks.t_mid)
    ok = blocks.joined[1:] & (dt > 0)
    if ok.sum() >= 2:
        turn = np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0))[ok] / dt[ok]
        # the accelerometer's turn rate that its noise alone gives: two block means' noise over the block step
        noise = np.sqrt(2.0 * np.median(blocks.var.sum(axis=1) / blocks.n)) / np.median(np.linalg.norm(blocks.mean, axis=1))
        acc_fast = float(np.quantile(turn, UNIT_RATE_QUANTILE))
        if acc_fast > 3.0 * noise / float(np.median(dt)):
            gyro_fast = float(np.quantile(np.linalg.norm(blocks.gmean - bias, axis=1), UNIT_RATE_QUANTILE))
            ratio = gyro_fast / acc_fast
            return RAD_PER_UNIT["deg/s"] if ratio > np.sqrt(1.0 / RAD_PER_UNIT["deg/s"]) else RAD_PER_UNIT["rad/s"]
    return RAD_PER_UNIT["rad/s"] if rec.units == "m/s^2" else RAD_PER_UNIT["deg/s"]


def _wobble(gyro: NDArray[np.float64], t: NDArray[np.float64], rad_per_unit: float, window: int) -> float:
    """RMS angle (rad, norm over the axes) by which the orientation moves about its mean within windows of ``window`` samples.

    In each window (:data:`WOBBLE_DWELLS` dwells) the rates less their mean (the bias, and a
    steady turn, which :meth:`_RestModel.turns` tests) are integrated by the trapezoid rule over the true time
    steps; over a window the gyro's own angle random walk and bias wander stay far below the tolerance, a
    hand's tremor or a vibration do not.
    """
    m = gyro.shape[0]
    if m < 3:
        return 0.0
    total, count = 0.0, 0
    for a in range(0, m, window):
        w = gyro[a:a + window] * rad_per_unit
        if w.shape[0] < 3:
            continue
        w = w - w.mean(axis=0)
        dt = np.diff(t[a:a + window])[:, None]
        angle = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (w[1:] + w[:-1]) * dt, axis=0)])
        angle -= angle.mean(axis=0)
        total += float(np.sum(angle * angle))
        count += w.shape[0]
    return float(np.sqrt(total / max(count, 1)))


def _no_net_turn(gyro: NDArray[np.float64], t: NDArray[np.float64], end: int, start: int, model: _RestModel,
                 block: int, gyro_scale: float | None) -> bool:
    """Whether the gyro shows no net turn between samples ``end`` and ``start`` (a twitch that came back).

    The rates less the bias integrated over the interruption, against the noise of that integral (the
    per-sample noise of the next rest's blocks times the noise colour, as a random walk, and the bias'
    wander over the interruption): χ²₃ at the false-alarm probability; a significant net turn smaller than
    a pose's wobble tolerance (gyro in known units) is no turn either.
    """
    if model.bias is None or model.gvar_ref is None:
        return False
    if start <= end:
        return True
    dt = np.diff(t[end - 1:start + 1])
    rates = gyro[end:start] - model.bias
    net = (rates * dt[: rates.shape[0], None]).sum(axis=0)
    span = float(dt.sum())
    var = model.gkappa2 * model.gvar_ref[block] * float(np.sum(dt * dt)) + model.wander2 * span * span
    stat = float(np.sum(net * net / np.maximum(var, np.finfo(float).tiny)))
    if stat <= rm.chi2_limit(model.s.false_alarm, 3) * model.s.gyro_threshold:
        return True
    return gyro_scale is not None and float(np.linalg.norm(net)) * gyro_scale < np.sqrt(2.0 * WOBBLE_SHRINK) * model.s.gyro_threshold


def _join_twitches(kept: list[tuple[int, int, int, int]], t: NDArray[np.float64], model: _RestModel,
                   dwell_s: float, gyro: NDArray[np.float64] | None,
                   gyro_scale: float | None, max_gap: float) -> list[list[tuple[int, int]]]:
    """Group consecutive rests that are one pose interrupted (a twitch, a test's false alarm).

    Two consecutive rests are one pose when their means do not differ -- by less than the noise of the
    difference (each mean's variance from the scatter of its block means, at least ``κ² v / n``), or by
    less than :data:`SAME_POSE_SAMPLE_SIGMAS` per-sample σ (a flicker noise's wander between two pieces
    of one rest) -- and the sensor did not turn between them: by the gyro, no net turn
    (:func:`_no_net_turn`; a turn that comes back to the same orientation, a full turn of a table, is a
    move), or when the interruption is shorter than the dwell (the dwell as a prior: no pose is left and
    regained in less time than one is held).  Never across a time gap.
    """
    b = model.b
    block_s = model.block / model.rate  # both pieces' ends fall on block edges: the interruption is known to two blocks
    groups: list[list[tuple[int, int]]] = []
    last: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None
    for a, z, j0, j1 in kept:
        w = b.n[j0:j1, None]
        mean = (b.mean[j0:j1] * w).sum(axis=0) / w.sum()
        white = model.kappa2 * np.median(b.var[j0:j1], axis=0) / w.sum()
        scatter = b.mean[j0:j1].var(axis=0, ddof=1) / (j1 - j0) if j1 - j0 >= 2 else white
        se2 = np.maximum(white, scatter)
        sd = model.spread(j0, j1)  # the samples' spread about the piece's mean, its wander included
        if groups and last is not None:
            end = groups[-1][-1][1]
            gap = bool(np.max(np.diff(t[end - 1:a + 1])) > max_gap)
            if gap:
                still_between = False  # nothing is known of what the sensor did in a gap of the recording
            else:
                still_between = t[a] - t[end - 1] < dwell_s + 2.0 * block_s or (
                    gyro is not None and _no_net_turn(gyro, t, end, a, model, j0, gyro_scale))
            d = mean - last[0]
            stat = float(np.sum(d * d / np.maximum(se2 + last[1], np.finfo(float).tiny)))
            same = stat <= float(rm.step_limit(model.s.false_alarm, 1e6)) * model.s.threshold \
                or float(np.linalg.norm(d)) < SAME_POSE_SAMPLE_SIGMAS * min(sd, last[2])
            if still_between and same:
                groups[-1].append((a, z))
                continue
        groups.append([(a, z)])
        last = (mean, se2, sd)
    return groups


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

