"""``--accept-mag-fit``, ``--keep-mag-repeats`` and ``--keep-mag-spikes``: one definition for every command that
reads a magnetometer.

``calibrate --sensor mag``, ``diagnose --sensor mag``, ``plan --sensor mag --next DATA``, and ``check`` and
``apply`` with a magnetometer calibration read DATA's magnetometer through
:func:`optcal.families.mag.samples.read_mag`, which leaves out the samples at the converter's rail and the rows a
logger repeated until the magnetometer's next update and its spikes (samples that leave both neighbours by more than
a turning field moves), and says so in lines that name these flags; each of them
takes them (:func:`mag_read_options`, as :mod:`optcal.cli.data_options` adds the DATA flags), and a command that
reads no magnetometer refuses them in one line (:func:`refuse_mag_options`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

__all__ = ["mag_read_options", "refuse_mag_options"]

_ACCEPT_MAG_FIT = click.option(
    "--accept-mag-fit", is_flag=True, default=False,
    help="Reading a magnetometer (--sensor mag, or a magnetometer calibration): keep its samples at the converter's "
         "rail (left out and counted by default: the field beyond the full scale is unknown); where a fit is made, "
         "also keep samples that do not lie on an ellipsoid and a fit that cannot be right, with a warning.")
_KEEP_MAG_REPEATS = click.option(
    "--keep-mag-repeats", is_flag=True, default=False,
    help="Reading a magnetometer: keep every row where the logger repeats each magnetometer value until its next "
         "update (a slower magnetometer in a faster log; by default one row per update is kept and the repeats are "
         "counted: each would weigh its sample several times).")

_KEEP_MAG_SPIKES = click.option(
    "--keep-mag-spikes", is_flag=True, default=False,
    help="Reading a magnetometer: keep the samples (runs of 1-3 rows) that leave both neighbours by more than a field "
         "turning at 10 rad/s can move between them and whose second difference is an outlier over the log (a bus "
         "glitch, a torn register read, a motor's pulse; left out and counted by default).")


def mag_read_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding ``--accept-mag-fit``, ``--keep-mag-repeats`` and ``--keep-mag-spikes`` (keywords
    ``accept_mag_fit``, ``keep_mag_repeats``, ``keep_mag_spikes``; see the module docstring)."""
    return _ACCEPT_MAG_FIT(_KEEP_MAG_REPEATS(_KEEP_MAG_SPIKES(func)))


def refuse_mag_options(accept_mag_fit: bool, keep_mag_repeats: bool, keep_mag_spikes: bool, what: str) -> None:
    """Refuse the magnetometer's reading flags where the command reads no magnetometer (``what`` says when they
    apply).

    Raises
    ------
    InputError
        ``accept_mag_fit``, ``keep_mag_repeats`` or ``keep_mag_spikes`` given.
    """
    used = [flag for flag, value in (("--accept-mag-fit", accept_mag_fit), ("--keep-mag-repeats", keep_mag_repeats),
                                     ("--keep-mag-spikes", keep_mag_spikes)) if value]
    if used:
        from optcal.errors import InputError

        raise InputError(f"{' and '.join(used)} {'applies' if len(used) == 1 else 'apply'} {what}")
