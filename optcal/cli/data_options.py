"""The DATA reading options shared by every command that takes DATA.

Usage in a command module::

    @click.command()
    @click.argument("data", type=DATA_PATH)
    @data_options
    def calibrate(data: str, ..., **data_opts: Any) -> None:
        poses = load_data(data, **data_opts)
        click.echo(data_line(data, poses), err=...)

:func:`data_options` adds ``--columns``, ``--units``, ``--topic``, ``--rate``, ``--time-unit``,
``--timing``, ``--gyro-file`` (:func:`read_options`, the reading options alone), ``--format``
(pose table or raw recording) and the static-detection settings ``--static-window``,
``--static-threshold``, ``--gyro-threshold``, ``--drift-threshold``, ``--min-dwell``, ``--min-independent``,
``--trim``.
:func:`load_data` passes them to :func:`optcal.data.load`; when DATA is refused after some
decisions about it were made, :func:`decisions_on_error` prints them on standard output, as
:func:`data_line` prints them on success, before the one-line error on standard error (not
with ``--json``, whose standard output stays empty on an error).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import click

from optcal.core.poses import PoseTable

#: Type of the DATA argument: a file, or a directory (a ROS 2 bag); existence is checked by
#: the readers, with one clear error line.
DATA_PATH = click.Path(dir_okay=True, file_okay=True)

#: Keyword names that :func:`data_options` adds to a command.
DATA_OPTION_NAMES: tuple[str, ...] = (
    "columns", "units", "topic", "rate", "data_format", "time_unit", "timing", "gyro_file",
    "static_window", "static_threshold", "gyro_threshold", "drift_threshold", "min_dwell", "trim", "no_gyro_gate",
    "min_independent", "gyro_units", "keep_touches", "keep_spins", "keep_gyro_rail", "gyro_range",
    "keep_unhealthy", "keep_clipped", "keep_held",
)

_POSITIVE = click.FloatRange(min=0, min_open=True)
_NON_NEGATIVE = click.FloatRange(min=0)

_READ_OPTIONS: tuple[Callable[[Callable[..., Any]], Callable[..., Any]], ...] = (
    click.option("--columns", metavar="NAME=COLUMN,...", default=None,
                 help="Map the file's columns by name or 1-based position: e.g. ax=acc_x_counts,ay=acc_y_counts,az=acc_z_counts,t=t_s "
                      "or t=1,ax=2,ay=3,az=4 (names: t ax ay az gx gy gz temp sigma n_samples index); NAME=none ignores the "
                      "column optcal would take as NAME (e.g. index=none, t=none). "
                      "Common names, and the common layouts of files without a header, are recognised without it."),
    click.option("--units", type=click.Choice(["g", "m/s^2", "counts"]), default=None,
                 help="Units of the accelerometer data (default: from the column names or file format, else from the norm)."),
    click.option("--topic", default=None,
                 help="ROS bag: the sensor_msgs/Imu topic; ULog: sensor_accel[:INSTANCE] or sensor_combined (default "
                      "sensor_accel:0, sensor_combined where that is not logged or logged under 4 Hz; said); ArduPilot DataFlash: "
                      "IMU[:N] (default IMU:0) or ACC[:N]; "
                      "MAT/netCDF/HDF5: the accelerometer's variable NAME[:rows|:columns] (one sample per row or column)."),
    click.option("--rate", type=_POSITIVE, default=None, metavar="HZ",
                 help="Sampling rate of a recording without a time column (time = row / rate)."),
    click.option("--time-unit", type=click.Choice(["s", "ms", "us", "ns"]), default=None,
                 help="Unit of a time column whose name does not say it [s, as documented]."),
    click.option("--timing", type=click.Choice(["auto", "stamps", "uniform"]), default="auto", show_default=True,
                 help="Keep the time stamps, or spread the samples evenly over the stamped span "
                      "(auto does so for bursty or coarse stamps, and says so)."),
    click.option("--gyro-file", type=click.Path(dir_okay=False), default=None, metavar="PATH",
                 help="A second text file 't gx gy gz' merged on time (imu_tk writes acc and gyro in two files)."),
    click.option("--keep-gyro-rail", is_flag=True, default=None,
                 help="Keep the gyro's samples at a saturation rail (by default they are counted, enter no rest, and "
                      "the moves holding them are left out of the gyro's fit and diagnosis: a clipped rate misses "
                      "part of the turn)."),
    click.option("--keep-unhealthy", is_flag=True, default=None,
                 help="Keep the samples an ArduPilot log flags unhealthy (by default, as ArduPilot left them out of "
                      "its own use, counted and left out: an AH=0 row whole, a GH=0 row's gyro sample, its "
                      "accelerometer sample kept)."),
    click.option("--keep-clipped", is_flag=True, default=None,
                 help="Keep the samples a log's own clip flags mark (ArduPilot's VIBE.Clip rises, PX4's clip "
                      "counters; by default they are counted as saturated and enter no rest); rails in the values "
                      "are still sought."),
    click.option("--keep-held", is_flag=True, default=None,
                 help="Keep every row where the accelerometer's value is held over several rows (a logger writing "
                      "faster than its accelerometer updates; by default found from the runs of identical triples, "
                      "the first row of each update kept and the repeats counted, so no value weighs several "
                      "samples)."),
    click.option("--gyro-range", type=_POSITIVE, default=None, metavar="DPS",
                 help="The gyro's full scale, ±°/s (e.g. 2000): where its unit is not known (counts), a saturation "
                      "rail is sought beyond 75/DPS of its largest reading, the most a rest reads (by default beyond "
                      "75 °/s in counts of the finest 16-bit gyro, ±125 °/s)."),
)
_OPTIONS: tuple[Callable[[Callable[..., Any]], Callable[..., Any]], ...] = (
    *_READ_OPTIONS,
    click.option("--format", "data_format", type=click.Choice(["auto", "poses", "raw"]), default="auto", show_default=True,
                 help="Read DATA as a pose table (one row per static pose) or a raw recording (a time series); auto decides and says why."),
    click.option("--gyro-units", type=click.Choice(["counts", "rad/s", "deg/s"]), default=None,
                 help="Units of the gyro columns (default: from the column names or file, else measured on the moves: "
                      "the rate integral across each move against the accelerometer's turn; the decision is printed)."),
    click.option("--static-window", type=_POSITIVE, default=None, metavar="S",
                 help="Rest detection: block length, seconds [0.25]."),
    click.option("--static-threshold", type=_POSITIVE, default=None, metavar="K",
                 help="Rest detection: accept steps between block means up to K times the step test's critical value "
                      "(false alarm 1e-3) [1]."),
    click.option("--gyro-threshold", type=_POSITIVE, default=None, metavar="K",
                 help="Rest detection: accept gyro rates off the bias, and orientation wobble, up to K times their critical values [1]."),
    click.option("--drift-threshold", type=_POSITIVE, default=None, metavar="K",
                 help="Rest detection: accept a creep of a stretch's mean up to K times the trend test's critical value [1]."),
    click.option("--no-gyro-gate", is_flag=True, default=False,
                 help="Rest detection: ignore the gyro columns as evidence of motion (a warning says so)."),
    click.option("--min-dwell", type=_NON_NEGATIVE, default=None, metavar="S",
                 help="Rest detection: shortest rest kept, and longest interruption joined inside one pose, seconds [0.5]."),
    click.option("--min-independent", type=_NON_NEGATIVE, default=None, metavar="N",
                 help="Rest detection: fewest independent samples (samples over the noise colour) a rest holds, of the "
                      "accelerometer and the gyro alike [2 and 4] (a warning says what a lower value assumes)."),
    click.option("--keep-touches", is_flag=True, default=None,
                 help="Rest detection: keep a pose's end piece past a twitch next to a move although it is shifted from "
                      "the rest (left out by default as a hand's touch or settling, and counted)."),
    click.option("--keep-spins", is_flag=True, default=None,
                 help="Rest detection: take a still stretch as a rest whatever its |a| and gyro rate (by default |a| must "
                      "be gravity's and the rate within a MEMS gyro's bias, 75 °/s: a steady spin is no rest)."),
    click.option("--trim", type=_NON_NEGATIVE, default=None, metavar="S",
                 help="Static detection: cut this much from both ends of every interval, seconds [0]."),
)


def data_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding the DATA reading options (see the module docstring)."""
    for option in reversed(_OPTIONS):
        func = option(func)
    return func


#: Keyword names that :func:`read_options` adds (reading a recording, no kind, no static detection).
READ_OPTION_NAMES: tuple[str, ...] = ("columns", "units", "topic", "rate", "time_unit", "timing", "gyro_file",
                                      "keep_gyro_rail", "gyro_range", "keep_unhealthy", "keep_clipped",
                                      "keep_held")


def read_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding the options that read a recording (``--columns`` ... ``--gyro-file``)."""
    for option in reversed(_READ_OPTIONS):
        func = option(func)
    return func


def reading_kwargs(opts: dict[str, Any]) -> dict[str, Any]:
    """Keywords of :func:`optcal.data.load_recording` from the options of :func:`read_options`."""
    unknown = set(opts) - set(READ_OPTION_NAMES) - {"gyro_units"}
    if unknown:
        raise TypeError(f"not reading options: {', '.join(sorted(unknown))}")
    return {"options": build_read_options(opts)}


#: The :class:`~optcal.data.options.ReadOptions` field (or static-detection setting) of each flag
#: whose keyword differs from it.
_FLAG_FIELDS: dict[str, str] = {
    "data_format": "kind", "static_window": "window_s", "static_threshold": "threshold", "min_dwell": "min_dwell_s",
    "trim": "trim_s", "gyro_range": "gyro_range_dps",
}


def build_read_options(opts: dict[str, Any]) -> Any:
    """The :class:`~optcal.data.options.ReadOptions` of a command's DATA flags: the one place they are mapped.

    Parameters
    ----------
    opts : dict
        The keywords :func:`data_options` or :func:`read_options` added (and ``gyro_units``
        where a command has it); those left at ``None`` let the evidence decide.

    Returns
    -------
    ReadOptions

    Raises
    ------
    TypeError
        A keyword that is not a DATA flag (a programming error in a command).
    InputError
        A value out of its range (naming the field and its flag).
    """
    from optcal.data.options import ReadOptions

    unknown = set(opts) - set(DATA_OPTION_NAMES) - {"gyro_units"}
    if unknown:
        raise TypeError(f"not DATA options: {', '.join(sorted(unknown))}")
    fields = {_FLAG_FIELDS.get(k, k): v for k, v in opts.items() if k != "no_gyro_gate"}
    if opts.get("no_gyro_gate"):
        fields["use_gyro"] = False
    return ReadOptions.build(None, **fields)


@contextmanager
def decisions_on_error(path: str) -> Iterator[None]:
    """Print the decisions made about DATA before it was refused, then let the error go on.

    On standard output, where :func:`data_line` prints them on success (and the commands print them
    before a refused fit), unless the command's ``--json`` keeps its standard output for one
    JSON object; the one-line error follows on standard error (:func:`optcal.cli.main.main`).
    """
    from optcal.data.decisions import DataInputError

    try:
        yield
    except DataInputError as exc:
        context = click.get_current_context(silent=True)
        as_json = context is not None and bool(context.params.get("as_json"))
        if exc.decisions and not as_json:
            click.echo("\n".join([f"DATA: {path} refused; the decisions made before:",
                                   *("  " + line for line in exc.decisions)]))
        raise


def load_data(path: str, **opts: Any) -> PoseTable:
    """Load DATA with the options collected by :func:`data_options` (the poses of :func:`load_data_detailed`)."""
    return load_data_detailed(path, **opts).poses


def load_data_detailed(path: str, **opts: Any) -> Any:
    """Read DATA with the options collected by :func:`data_options`: the :class:`optcal.data.Reading`.

    The decisions made before DATA is refused are printed with the error (:func:`decisions_on_error`).
    """
    from optcal.data.options import read

    with decisions_on_error(path):
        return read(path, build_read_options(opts))


def data_line(path: str, poses: PoseTable) -> str:
    """What DATA was read as, and every decision with its reason (every command prints it)."""
    if poses.source == "raw recording":
        seg = poses.meta.get("segmentation", {})
        n_rows, n_usable = seg.get("n_samples", "?"), poses.meta.get("n_usable", seg.get("n_samples", "?"))
        samples = f"{n_usable} samples" + ("" if n_usable == n_rows else f" of {n_rows} rows")
        what = (
            f"a raw recording ({samples}, {poses.meta.get('duration_s', 0):.1f} s at "
            f"{poses.meta.get('rate_hz', float('nan')):.4g} Hz) → {poses.n} static poses"
        )
    else:
        what = f"a pose table ({poses.n} poses)"
    head = f"DATA: {path} read as {what}, units {poses.units}"
    if poses.decisions is None:
        return head
    return "\n".join([head, *("  " + line for line in poses.decisions.lines())])


def data_summary(path: str, poses: PoseTable) -> dict[str, Any]:
    """JSON-safe description of what DATA was read as (for ``--json`` output)."""
    out: dict[str, Any] = {
        "path": path,
        "kind": poses.source,
        "kind_reason": poses.meta.get("kind_reason"),
        "units": poses.units,
        "units_reason": poses.meta.get("units_reason"),
        "n_poses": poses.n,
        "exclusions": dict(poses.exclusions),
        "decisions": None if poses.decisions is None else poses.decisions.to_dict(),
    }
    if poses.source == "raw recording":
        seg = poses.meta.get("segmentation", {})
        out.update(
            {
                "n_samples": seg.get("n_samples"),
                "n_usable": poses.meta.get("n_usable"),
                "rate_hz": poses.meta.get("rate_hz"),
                "duration_s": poses.meta.get("duration_s"),
                "time": poses.meta.get("time"),
                "thresholds": seg.get("thresholds"),
            }
        )
    return out
