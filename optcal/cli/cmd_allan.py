"""``optcal allan DATA``: Allan deviation and noise parameters of a static log (Yin 2014, section 2.2)."""

from __future__ import annotations

from dataclasses import dataclass
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import click
import numpy as np
from numpy.typing import NDArray

from optcal.cli.data_options import DATA_PATH, read_options, reading_kwargs
from optcal.cli.outputs import echo_json, plot_file, plot_option
from optcal.cli.quiet import quiet_option

#: File name of the figure when ``--plot`` names a folder.
FIGURE_NAME = "allan.png"
#: File name of the gyroscope's figure when ``--plot`` names a folder.
GYRO_FIGURE_NAME = "allan_gyro.png"

#: Missing samples tolerated in a log (a few dropped samples barely change the Allan deviation),
#: as a fraction of its samples; the log is treated as uniformly sampled and the count reported.
MAX_MISSING_FRACTION: float = 1e-3
#: Longest tolerated run of missing samples.
MAX_MISSING_RUN: int = 5
#: Share of a still log's samples that static detection must find at rest.
MIN_STILL_FRACTION: float = 0.9
UNSETTLED = "samples not at rest at the log's start or end (a start-up transient, a touch), cut: --keep-moves keeps them"
DROPPED = "samples missing from the log (gaps of a few samples, treated as uniformly sampled)"


@dataclass
class StillLog:
    """A still log read for the Allan deviation.

    Attributes
    ----------
    samples : ndarray, shape (n, 3)
        The analysed sensor's samples (the accelerometer's unless ``sensor="gyro"``).
    rate_hz : float
    units, units_reason : str
    exclusions : dict of str to int
    decisions : DataDecisions
    gyro : ndarray, shape (n, 3) or None
        The gyro samples of the same rows (when the log has gyro columns).
    gyro_units : str or None
        The gyro units the file states.
    """

    samples: np.ndarray
    rate_hz: float
    units: str
    units_reason: str
    exclusions: dict[str, int]
    decisions: Any
    gyro: np.ndarray | None = None
    gyro_units: str | None = None
    #: The stillness check still running beside the analysis (``read_still_log(..., concurrent=True)``): it
    #: raises the refusal when the log is not still; :meth:`confirm_still` waits for it.
    still: Future[Any] | None = None
    #: The rest model's segmentation of the log (:func:`optcal.data.static.detect_static`, rests counted only),
    #: once :meth:`confirm_still` has waited for it.
    segmentation: Any = None
    #: The samples kept by :meth:`trim_unsettled` (``None``: all).
    cut: tuple[int, int] | None = None
    #: The sensor analysed: ``"acc"``, ``"gyro"`` (asked for, or a file with gyro columns only) or ``"both"``.
    sensor: str = "acc"

    def confirm_still(self) -> Any:
        """Wait for the stillness check :func:`read_still_log` started; raise its refusal; return the segmentation."""
        from optcal.core.progress import stage

        if self.still is not None:
            still, self.still = self.still, None
            with stage("finding the samples at rest"):  # a few seconds on a 12-hour log: a bar says so
                self.segmentation = still.result()
        return self.segmentation

    def trim_unsettled(self) -> int:
        """Cut the samples not at rest at the log's start and end (a start-up transient, a hand leaving or
        reaching for the sensor): the series stays uninterrupted, so they need not enter it.  They are counted
        in :attr:`exclusions`; returns how many (0: nothing cut).  A log with no sample at rest is left alone."""
        rest = self.at_rest()
        kept = np.flatnonzero(rest)
        if kept.size == 0 or (kept[0] == 0 and kept[-1] == rest.size - 1):
            return 0
        first, last = int(kept[0]), int(kept[-1]) + 1
        cut = rest.size - (last - first)
        same = self.gyro is self.samples
        self.samples = self.samples[first:last]
        if self.gyro is not None:
            self.gyro = self.samples if same else self.gyro[first:last]
        self.cut = (first, last)
        self.exclusions[UNSETTLED] = cut
        return cut

    def at_rest(self) -> NDArray[np.bool_]:
        """Which of :attr:`samples` the rest model finds at rest (after :meth:`confirm_still`)."""
        seg = self.confirm_still()
        # the rest model's trace has a value per usable sample (detect_static drops the unusable rows itself), the
        # rows :attr:`samples` holds: indexing it by the usable rows again failed on a log with unusable rows
        static = np.asarray(seg.trace["static"], dtype=bool)
        return static if self.cut is None else static[self.cut[0]:self.cut[1]]


def static_log(
    data: str,
    columns: str | None = None,
    units: str | None = None,
    topic: str | None = None,
    rate: float | None = None,
) -> tuple[np.ndarray, float, str, str, dict[str, int]]:
    """Samples, rate, units, how the units were decided and exclusions of a still log (:func:`read_still_log`)."""
    log = read_still_log(data, columns=columns, units=units, topic=topic, rate=rate)
    return log.samples, log.rate_hz, log.units, log.units_reason, log.exclusions


def parse_window(window: str | None) -> tuple[float, float] | None:
    """``START:END`` (seconds; either side may be empty) as ``(start, end)``, or None."""
    from optcal.errors import InputError

    if window is None:
        return None
    parts = window.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start = float(parts[0]) if parts[0].strip() else -np.inf
        end = float(parts[1]) if parts[1].strip() else np.inf
    except ValueError:
        raise InputError(f"--window {window!r}: give START:END in seconds (e.g. 0:50, or :50 for the first 50 s)") from None
    if not start < end:
        raise InputError(f"--window {window!r}: START must be before END")
    return start, end


def missing_samples(t: NDArray[np.float64]) -> tuple[int, int, int, float, float] | None:
    """Samples missing between the stamps ``t``: their number, the longest run, where the longest step
    starts, that step and the median step (the sampling step); ``None`` for fewer than two stamps.

    A step of ``k`` sampling steps (rounded) misses ``k − 1`` samples.  Computed in one array of the
    steps, in place, freed on return (a 12-hour log's steps are 35 MB; four temporaries of that
    size held beside the samples were a sixth of a copy of its numbers).

    Parameters
    ----------
    t : ndarray
        Time stamps, s.

    Returns
    -------
    tuple or None
    """
    from optcal.data.quantiles import median

    steps = np.diff(t)
    if not steps.size:
        return None
    step = median(steps)  # np.median's figure, without its import of numpy.ma (30 ms)
    at = int(np.argmax(steps))
    gap = float(steps[at])
    if not step > 0:
        return 0, 0, at, gap, step
    np.divide(steps, step, out=steps)
    np.rint(steps, out=steps)
    steps -= 1.0
    longest = int(steps.max())
    np.maximum(steps, 0.0, out=steps)
    return int(steps.sum()), longest, at, gap, step


def read_still_log(data: str, sensor: str | None = "acc", window: tuple[float, float] | None = None,
                   concurrent: bool = False, **read_options: Any) -> StillLog:
    """Read a still log for the Allan deviation.

    Unusable samples (non-finite, duplicated, saturated) are dropped and counted; a few
    dropped samples (at most :data:`MAX_MISSING_FRACTION` of the log, runs of at most
    :data:`MAX_MISSING_RUN`) are counted and the log treated as uniformly sampled; a longer
    gap is refused, because the Allan deviation needs uniform sampling.  A log that static
    detection does not find at rest (at least :data:`MIN_STILL_FRACTION` of it) is refused:
    the Allan deviation of a moving sensor measures the motion.  ``sensor="gyro"`` takes the
    gyro samples (``units`` then says the gyro units as the file states them, or ``None``);
    ``sensor="both"`` the accelerometer's with the gyro's beside them (``gyro``); ``sensor=None`` the
    accelerometer's, or the gyro's of a file with gyro columns only (:mod:`optcal.data.gyro_log`).  ``window``
    keeps only the samples with ``start ≤ t ≤ end`` (the still part of a longer recording; the
    rows outside it are counted).  ``concurrent=True`` returns as soon as the log is read and runs the
    stillness check in a thread beside the caller's analysis (its numpy work releases the interpreter,
    so two cores share the two): the caller must call :meth:`StillLog.confirm_still` before it uses a
    result, and the same refusal is raised there.
    """
    from dataclasses import replace

    from optcal.cli.data_options import decisions_on_error
    from optcal.data import load_recording
    from optcal.data.static import detect_static
    from optcal.errors import InputError

    from optcal.data.gyro_log import gyro_recording
    from optcal.data.options import ReadOptions
    from optcal.data.readers import GyroOnlyColumns

    with decisions_on_error(data):  # the decisions made before a refusal are printed with it
        try:
            rec = load_recording(data, required_by="the allan command", **read_options)
        except GyroOnlyColumns as exc:  # a gyroscope's log: its noise, unless the accelerometer's was asked for
            if sensor not in (None, "gyro"):
                raise
            sensor = "gyro"
            options = ReadOptions.build(read_options.pop("options", None), **read_options)
            rec = gyro_recording(exc.source, options, required_by="the allan command")
    sensor = sensor or "acc"
    exclusions = dict(rec.exclusions)
    if window is not None:
        keep = (rec.t >= window[0]) & (rec.t <= window[1])
        if np.count_nonzero(keep & rec.usable) < 2:
            raise InputError(f"{data}: no samples with {window[0]:g} <= t <= {window[1]:g} s (the log spans "
                             f"{rec.t[0]:.6g} to {rec.t[-1]:.6g} s)")
        outside = int(np.count_nonzero(~keep))
        rec = replace(rec, t=rec.t[keep], acc=rec.acc[keep], gyro=None if rec.gyro is None else rec.gyro[keep],
                      temp=None if rec.temp is None else rec.temp[keep], row=rec.row[keep], usable=rec.usable[keep],
                      gyro_unhealthy=None if rec.gyro_unhealthy is None else rec.gyro_unhealthy[keep],
                      nominal=None)
        if outside:
            exclusions[f"samples outside --window {window[0]:g}:{window[1]:g} s"] = outside
    # the gyro's noise leaves out the samples the log marks unhealthy (Recording.gyro_usable), the accelerometer's
    # alone keeps them; a log with every sample usable (the common case) is used as read: indexing would copy it
    usable = rec.gyro_usable if sensor in ("gyro", "both") else rec.usable
    every = bool(np.all(usable))
    t = rec.t if every else rec.t[usable]
    samples = rec.acc if every else rec.acc[usable]
    gyro = None if rec.gyro is None else rec.gyro if every else rec.gyro[usable]
    if sensor in ("gyro", "both") and gyro is None:
        raise InputError(f"{data}: no gyro columns (gx, gy, gz); map them with --columns gx=...,gy=...,gz=...")
    if sensor == "gyro" and gyro is not None:
        samples = gyro
    n_rows = samples.shape[0]
    def still_check() -> Any:
        seg = detect_static(rec, pose_statistics=False)  # the still fraction only: no pose statistics
        still = seg.n_used / max(1, n_rows)
        if still < MIN_STILL_FRACTION:
            raise InputError(
                f"{data}: the log is not still: static detection finds only {100 * still:.0f} % of its samples at "
                f"rest ({len(seg.intervals)} static interval(s)); the Allan deviation needs a log of a sensor that "
                "does not move"
                + ("" if window is not None else " (--window START:END analyses the still part of a longer recording)")
            )
        return seg

    # started before the gaps are counted: the check is the longest of the work beside the analysis, so every
    # step of the reader's thread before it starts lengthens the command (a refusal for a gap still comes first)
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="optcal-still")
    still = pool.submit(still_check)
    pool.shutdown(wait=False)
    gaps = missing_samples(t)
    if gaps is not None:
        total, longest, at, gap, step = gaps
        if total and (longest > MAX_MISSING_RUN or total > MAX_MISSING_FRACTION * t.size):
            raise InputError(
                f"{data}: the log has a gap of {gap:.4g} s at t = {t[at]:.6g} s ({total} samples missing in all; "
                f"sampling step {step:.4g} s); the Allan deviation needs an uninterrupted, uniformly sampled still log: "
                "cut the log at the gap"
            )
        if total:
            exclusions[DROPPED] = total
    if sensor == "gyro":
        log = StillLog(samples, rec.rate_hz, rec.gyro_units or "", "stated by the file" if rec.gyro_units else "",
                       exclusions, rec.decisions, gyro, rec.gyro_units, still=still)
    else:
        log = StillLog(samples, rec.rate_hz, rec.units, rec.units_reason, exclusions, rec.decisions, gyro,
                       rec.gyro_units, still=still)
    log.sensor = sensor
    if not concurrent:
        log.confirm_still()
    return log


def _longest_rest(seg: Any) -> str:
    """``--window START:END`` of the longest run of samples the rest model finds at rest."""
    from optcal.data.static_stretches import true_runs

    a, b = true_runs(np.asarray(seg.trace["static"], dtype=bool))
    if not a.size:
        return "--window START:END analyses a still part"
    k = int(np.argmax(b - a))
    t = seg.recording.t
    return f"--window {t[a[k]]:.6g}:{t[b[k] - 1]:.6g} analyses its longest still stretch"


#: Pieces of the running sums (:class:`~optcal.families.noise.disturbance.PhaseCarries`, 2¹⁵ samples each, about
#: 0.3 ms) worked out between two looks at the stillness check: its end, the longer branch's, waits at most this long.
CARRY_STEP: int = 4


def carry_ahead(log: StillLog, analyses: dict[str, Any]) -> dict[str, list[Any]]:
    """The running sums of the disturbance check (:func:`check_disturbances`), worked out on the caller's thread
    while the stillness check still runs beside it (its core otherwise waits), until that check ends.

    Only for columns that are contiguous (summed where they lie, no copy of the log's length held); after the check,
    a log cut by :meth:`StillLog.trim_unsettled` no longer matches them and they go unused.  The disturbance check's
    numbers are the same with or without them (:func:`~optcal.families.noise.disturbance.phase_prefix_at`).
    """
    from optcal.families.noise.disturbance import PhaseCarries

    still = log.still
    if still is None or still.done():
        return {}
    out: dict[str, list[Any]] = {}
    for name, analysis in analyses.items():
        x = log.gyro if name == "gyro" and log.gyro is not None else log.samples
        if x.ndim != 2 or x.shape[1] != len(analysis.curves):
            continue
        out[name] = [PhaseCarries(x[:, j], log.rate_hz) if x[:, j].flags.c_contiguous else None
                     for j in range(x.shape[1])]
    todo = [c for columns in out.values() for c in columns if c is not None]
    while todo and not still.done():
        todo = [c for c in todo if not c.advance(CARRY_STEP)]
    return out


def check_disturbances(log: StillLog, analyses: dict[str, Any], data: str, keep_moves: bool,
                       carries: dict[str, list[Any]] | None = None) -> list[str]:
    """Refuse a still log whose moves are relevant to its Allan deviation; the lines that say what was found.

    Two things a still log's rests can hide: a turn between two rests (gravity's direction in the sensor differs by
    more than :data:`~optcal.data.static_stretches.MIN_MOVE_TURN_RAD`, the rest model's least move: the log holds two
    orientations, and its Allan deviation the step between them), and the samples between or inside the rests that
    are not at rest (a knock, a turn and back), which enter the series and are bounded by
    :func:`optcal.families.noise.disturbance.disturbance_change` against each curve's own uncertainty.  ``keep_moves``
    (``--keep-moves``) analyses the log anyway, said so.  ``carries``: :func:`carry_ahead`'s running sums, per
    sensor.
    """
    from optcal.core.progress import stage
    from optcal.data.static_stretches import MIN_MOVE_TURN_RAD
    from optcal.errors import InputError
    from optcal.families.noise.disturbance import PLACEBOS, RELEVANT_SHARE, disturbance_change

    seg = log.confirm_still()
    lines: list[str] = []
    override = " (--keep-moves analyses it anyway)"
    rec, static = seg.recording, np.asarray(seg.trace["static"], dtype=bool)
    if len(seg.intervals) > 1:
        means = np.array([rec.acc[iv.start:iv.stop][static[iv.start:iv.stop]].mean(axis=0) for iv in seg.intervals])
        u = means / np.linalg.norm(means, axis=1, keepdims=True)
        ref = max(range(len(seg.intervals)), key=lambda k: seg.intervals[k].n_samples)
        angles = np.degrees(np.arccos(np.clip(u @ u[ref], -1.0, 1.0)))
        k = int(np.argmax(angles))
        turned = (f"gravity's direction differs by {angles[k]:.3g}° between the rests at t = "
                  f"{seg.intervals[ref].t_start:.6g}-{seg.intervals[ref].t_end:.6g} s and "
                  f"{seg.intervals[k].t_start:.6g}-{seg.intervals[k].t_end:.6g} s")
        if angles[k] > np.degrees(MIN_MOVE_TURN_RAD):
            if not keep_moves:
                raise InputError(f"{data}: the log holds more than one orientation: {turned} (a turn: more than "
                                 f"{np.degrees(MIN_MOVE_TURN_RAD):g}°), so its Allan deviation would measure the step "
                                 f"between them; {_longest_rest(seg)}{override}")
            lines.append(f"kept with --keep-moves: {turned}")
        elif angles[k] > 0:
            lines.append(f"rests: {len(seg.intervals)}; {turned} (a tilt or a bias step, below a "
                         f"{np.degrees(MIN_MOVE_TURN_RAD):g}° turn): in the series")
    at_rest = log.at_rest()
    moving = int(np.count_nonzero(~at_rest))
    if not moving:
        return lines
    worst: tuple[bool, float, str] = (False, -1.0, "")
    for name, analysis in analyses.items():
        x = log.gyro if name == "gyro" and log.gyro is not None else log.samples
        axes = list(analysis.curves)
        with stage(f"replacing the {moving} samples not at rest ({name}, {PLACEBOS} placebos)"):  # seconds on a long log
            b = disturbance_change(x, at_rest, log.rate_hz, [analysis.curves[a] for a in axes],
                                   (carries or {}).get(name, ()))
        if (b.relevant, b.ratio) > worst[:2]:
            what = "gyro" if name == "gyro" else "acc"
            worst = (b.relevant, b.ratio, f"{what} {axes[b.axis]} at τ = {b.tau:.3g} s by {b.change:.3g} "
                     f"{analysis.units}, {b.ratio:.2g} of its uncertainty (σ {b.adev:.3g}, half-interval "
                     f"{b.half_width:.3g})")
    relevant, ratio = worst[0], worst[1]
    found = (f"{moving} sample(s) not at rest ({100 * moving / at_rest.size:.2g} % of the log) move the Allan "
             f"deviation of {worst[2]}")
    if relevant:
        if not keep_moves:
            raise InputError(f"{data}: the log moves: {found}, above {RELEVANT_SHARE:g} of it and above what "
                             f"replacing as many samples at rest does at {PLACEBOS} random places; "
                             f"{_longest_rest(seg)}{override}")
        lines.append(f"kept with --keep-moves: {found}")
    elif ratio > RELEVANT_SHARE:
        lines.append(f"not at rest: {found}, no more than replacing as many samples at rest by others does "
                     f"({PLACEBOS} random places): the noise's own, kept")
    else:
        lines.append(f"not at rest: {found}: within {RELEVANT_SHARE:g} of it, kept")
    return lines


@click.command()
@click.argument("data", type=DATA_PATH)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (SI units) instead of the table.")
@plot_option(f"the log-log Allan deviation with the fitted lines ({FIGURE_NAME}; {GYRO_FIGURE_NAME} for the gyroscope)")
@click.option("--counts-per-g", type=click.FloatRange(min=0, min_open=True), default=None, metavar="N",
              help="Scale of raw counts, needed for counts (16384 for an MPU-6050 at ±2 g).")
@click.option("--sensor", type=click.Choice(["acc", "gyro", "both"]), default=None,
              help="Channels analysed: the accelerometer (the default; the gyro for a file with gyro columns only), "
                   "the gyro (angle random walk, bias instability, rate random walk), or both (one JSON with 'accelerometer' and 'gyroscope': what optcal export --allan takes "
                   "for Kalibr, VINS, ORB-SLAM3, OKVIS).")
@click.option("--gyro-units", type=click.Choice(["counts", "rad/s", "deg/s"]), default=None,
              help="--sensor gyro/both: units of the gyro columns (default: from the column names or file, else from the data).")
@click.option("--counts-per-rad-s", type=click.FloatRange(min=0, min_open=True), default=None, metavar="N",
              help="--sensor gyro/both: scale of raw gyro counts (e.g. K_g of an IMU calibration).")
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False), default=None, metavar="CAL",
              help="Take the counts scales from a calibration instead of --counts-per-g / --counts-per-rad-s: each raw "
                   "axis's counts per g (per rad/s for an imu calibration's gyroscope), their mean used.")
@click.option("--window", default=None, metavar="START:END",
              help="Analyse only the samples with START <= t <= END (s): the still part of a longer recording "
                   "(e.g. :50 for the first 50 s).")
@click.option("--keep-moves", is_flag=True, default=False,
              help="Analyse a log whose moves are relevant to its Allan deviation (a turn between rests, samples not "
                   "at rest that move σ(τ) by more than its one-sigma uncertainty) instead of refusing it.")
@read_options
@click.option("--max-tau", type=click.FloatRange(min=0, min_open=True), default=None, metavar="S",
              help="Largest averaging time τ (default: the largest octave τ leaving 9 clusters).")
@quiet_option
def allan(
    data: str,
    as_json: bool,
    plot_path: str | None,
    counts_per_g: float | None,
    sensor: str | None,
    gyro_units: str | None,
    counts_per_rad_s: float | None,
    calibration_path: str | None,
    window: str | None,
    max_tau: float | None,
    keep_moves: bool,
    **reading: Any,
) -> None:
    """Allan deviation of a static log: velocity random walk, bias instability, rate random walk.

    DATA is a raw recording of a still sensor (CSV with ax, ay, az, a time column or a rate;
    Parquet, ROS bag or ULog).  Overlapping Allan deviation on octave-spaced τ with
    confidence intervals (Greenhall's degrees of freedom); the noise parameters are read from the fitted
    −1/2, 0 and +1/2 slope lines as in Yin 2014.  Where no +1/2 slope shows, the rate random
    walk's one-sided 95 % confidence bound from the longest τ is reported instead.
    """
    from optcal.errors import InputError
    from optcal.families.noise.analysis import analyse_static_log, plot_allan
    from optcal.families.noise.scales import scale_for
    from optcal.families.noise.sensors import ACCELEROMETER, GYROSCOPE
    from optcal.data.units import decide_gyro_units

    scales: dict[str, Any] = {}
    scale_lines: list[str] = []
    if calibration_path is not None:
        if counts_per_g is not None or counts_per_rad_s is not None:
            raise InputError("--calibration gives the counts scales: drop --counts-per-g / --counts-per-rad-s, or --calibration")
        import optcal.families.calibration_files as calibration_files
        from optcal.families.noise.scales import calibration_scales

        scales = calibration_scales(calibration_files.load(calibration_path))
    span = parse_window(window)
    # the stillness check runs beside the analysis (two cores: about a second less on a 12-hour log) and is
    # waited for before anything is printed or drawn: a log that is not still is refused as before
    log = read_still_log(data, sensor=sensor, window=span, concurrent=True, **reading_kwargs(reading))
    sensor = log.sensor  # the gyro's for a file with gyro columns only
    reasons: dict[str, str] = {}

    def analyse() -> dict[str, Any]:
        nonlocal counts_per_g, counts_per_rad_s
        out: dict[str, Any] = {}
        scale_lines.clear()  # a second analysis (after a start-up transient is cut) says its scales once
        if sensor in ("acc", "both"):
            acc = log.samples
            if calibration_path is not None:
                counts_per_g = scale_for(scales, "acc", ACCELEROMETER.canonical_units(log.units), calibration_path)
                if counts_per_g is not None:
                    scale_lines.append(scales["acc"].describe(calibration_path))
            ACCELEROMETER.si_per_unit(log.units, counts_per_g)  # fail early on counts without a scale
            out["acc"] = analyse_static_log(acc, log.rate_hz, log.units, counts_per_g, max_tau)
            reasons["acc"] = log.units_reason
        if sensor in ("gyro", "both"):
            gyro = log.samples if sensor == "gyro" else log.gyro
            assert gyro is not None  # read_still_log refuses a log without gyro columns
            # a still log has no moves for the peak-rate rule: its noise density says the unit
            decision = decide_gyro_units(gyro, gyro.mean(axis=0), gyro_units, log.gyro_units or None, log.rate_hz)
            if calibration_path is not None:
                counts_per_rad_s = scale_for(scales, "gyro", decision.units, calibration_path)
                if counts_per_rad_s is not None:
                    scale_lines.append(scales["gyro"].describe(calibration_path))
            out["gyro"] = analyse_static_log(gyro, log.rate_hz, decision.units, counts_per_rad_s, max_tau, GYROSCOPE)
            reasons["gyro"] = decision.reason
        return out

    try:
        analyses = analyse()
    except Exception:  # the log's refusal comes first, as when the check ran before the analysis
        log.confirm_still()
        raise
    carries = carry_ahead(log, analyses)  # the disturbance check's running sums, while the stillness check runs on
    log.confirm_still()
    if not keep_moves and log.trim_unsettled():  # a start-up transient or a last touch: the series without it
        analyses = analyse()
    disturbances = check_disturbances(log, analyses, data, keep_moves, carries)
    figures = []
    if plot_path is not None:
        for name, analysis in analyses.items():
            figure = plot_file(plot_path, FIGURE_NAME if name == "acc" else GYRO_FIGURE_NAME)
            if name == "gyro" and "acc" in analyses and figure.name != GYRO_FIGURE_NAME:  # a file name given
                figure = figure.with_name(f"{figure.stem}_gyro{figure.suffix}")
            what = "accelerometer" if name == "acc" else "gyroscope"
            plot_allan(analysis, figure, title=f"Allan deviation of {data} ({what})")
            figures.append(figure)
    if as_json:
        summaries: dict[str, Any] = {}
        for name, analysis in analyses.items():
            out: dict[str, Any] = analysis.summary()
            out["log"].update({"path": data, "units_reason": reasons[name], "exclusions": log.exclusions,
                               **({"window_s": list(span or ())} if window else {}),
                               **({"scales": scale_lines} if scale_lines else {}),
                               **({"disturbances": disturbances} if disturbances else {}),
                               **({"decisions": log.decisions.to_dict()} if log.decisions is not None else {})})
            summaries[name] = out
        if sensor == "both":
            echo_json({"sensor": "both", "log": summaries["acc"]["log"], "accelerometer": summaries["acc"],
                       "gyroscope": summaries["gyro"]})
        else:
            echo_json(summaries[sensor])
        for figure in figures:
            click.echo(f"figure saved to {figure}", err=True)
        return
    units = "; ".join(f"{'gyro' if name == 'gyro' else 'acc'} units {a.units} ({reasons[name]})"
                      for name, a in analyses.items())
    click.echo(f"DATA: {data}, a still log of {log.samples.shape[0]} samples at {log.rate_hz:.6g} Hz, {units}")
    if log.decisions is not None:
        for line in log.decisions.lines():
            click.echo("  " + line)
    for line in scale_lines:
        click.echo(line)
    if log.exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in log.exclusions.items()))
    for line in disturbances:
        click.echo(line)
    for name, analysis in analyses.items():
        if len(analyses) > 1:
            click.echo("accelerometer:" if name == "acc" else "gyroscope:")
        click.echo(analysis.report())
    for figure in figures:
        click.echo(f"figure saved to {figure}")
