"""A gyroscope's log without an accelerometer (``optcal allan FILE --sensor gyro``).

A gyro's Allan recording is often written with the gyro alone (``t, gx, gy, gz``; a ROS
``rostopic echo -p /imu`` export keeping only ``angular_velocity``).  The readers refuse it as
an accelerometer's recording (:class:`~optcal.data.readers.GyroOnlyColumns`, naming
``--sensor gyro``); :func:`gyro_recording` reads the source they made the one way every
recording is read (its time base, rate, pauses and exclusions decided and said), with a
stand-in accelerometer that holds still (:data:`STAND_IN`, with a white noise far below any accelerometer's).  The rest model then judges the
log's stillness by the gyro alone: the stand-in passes every accelerometer test, so a rest
ends only where the gyro's mean leaves its bias or its scatter grows.
"""

from __future__ import annotations

import numpy as np

from optcal.data.columns import ACC, GYRO
from optcal.data.decisions import DataInputError, Decision, decide
from optcal.data.evidence import gather_evidence
from optcal.data.options import ReadOptions
from optcal.data.readers import Source
from optcal.data.recording import Recording, recording_from_source
from optcal.errors import InputError

#: The stand-in accelerometer of a gyro-only log, in g: 1 g along (1, 1, 1)/√3 (the units check reads it as the
#: g it is stated in; not an integer on any axis, so the integer converters' rails cannot flag it as saturated).
STAND_IN: float = float(1.0 / np.sqrt(3.0))
#: The stand-in's white noise, g rms per axis: the rest model measures each rest's noise and the independent
#: samples it holds (a noise-free axis holds none, and no rest would pass), so the stand-in carries a white noise
#: (seeded: the same on every run) 1 µg, far below any MEMS accelerometer's (tens of µg/√Hz at tens of Hz),
#: so that it never ends a rest the gyro keeps.
STAND_IN_NOISE: float = 1e-6
#: The seed of the stand-in's noise (the same samples on every run).
STAND_IN_SEED: int = 0
#: The units decision's value on a gyro-only log (no accelerometer, no accelerometer units).
NO_ACCELEROMETER = "none"


def gyro_recording(src: Source, options: ReadOptions | None = None, *,
                   required_by: str = "reading a gyroscope's log") -> Recording:
    """Read a gyroscope's log with no accelerometer columns (the source a reader refused).

    Parameters
    ----------
    src : Source
        :attr:`optcal.data.readers.GyroOnlyColumns.source`: the time (or none) and the gyro columns.
    options : ReadOptions, optional
        ``rate``, ``time_unit`` and ``timing`` apply as for any recording; ``units`` (the accelerometer's)
        does not: the gyro's units are ``gyro_units`` (or the column names').
    required_by : str
        What needs the raw recording (the kind decision's reason).

    Returns
    -------
    Recording
        ``gyro`` holds the samples; ``acc`` the stand-in (:data:`STAND_IN`), which no result may read;
        ``units`` is the stand-in's g; the units decision is :data:`NO_ACCELEROMETER`, saying the log was read as a
        gyroscope's.

    Raises
    ------
    InputError
        ``units`` given (there is no accelerometer), or the reading's refusals (no time and no rate, ...).
    """
    options = options if options is not None else ReadOptions()
    if not src.has(*GYRO):
        raise InputError(f"{src.path}: no gyro columns (gx, gy, gz); map them with --columns gx=...,gy=...,gz=...")
    if options.units is not None:
        raise InputError(f"{src.path}: --units {options.units} names the accelerometer's units, and the file has no "
                         "accelerometer; the gyro's units are --gyro-units")
    if options.gyro_units is not None:
        src.gyro_units = options.gyro_units
    rng = np.random.default_rng(STAND_IN_SEED)
    for name in ACC:
        src.data[name] = STAND_IN + STAND_IN_NOISE * rng.standard_normal(src.n_rows)
    reason = ("no accelerometer columns: a gyroscope's log, read alone (its gyro analysed, as --sensor gyro; its "
              "stillness judged by the gyro, the rest model's accelerometer tests seeing a sensor held still)")
    flag = "--columns ax=NAME,ay=NAME,az=NAME"
    try:
        decisions = decide(src, gather_evidence(src), kind="raw", units="g", rate=options.rate,
                           time_unit=options.time_unit, timing=options.timing, required_by=required_by)
    except DataInputError as exc:  # the decisions printed with the refusal say no accelerometer, not the stand-in's g
        exc.decisions = [f"units: {NO_ACCELEROMETER} ({reason}; {flag})" if line.startswith("units:") else line
                         for line in exc.decisions]
        raise
    # converted in the stand-in's g (a window re-converts it too)
    rec = recording_from_source(src, decisions, keep_gyro_rail=options.keep_gyro_rail,  # the stand-in is no
                                gyro_range_dps=options.gyro_range_dps, keep_held=True)  # sensor: no hold sought
    decisions.units = Decision(NO_ACCELEROMETER, reason, flag)  # said: no accelerometer (rec.decisions is this)
    rec.units_reason = reason
    return rec
