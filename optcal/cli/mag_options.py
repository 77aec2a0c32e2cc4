"""``--accept-mag-fit``: one definition for every command that reads a magnetometer.

``calibrate --sensor mag``, ``diagnose --sensor mag``, ``plan --sensor mag --next DATA``, and ``check`` and
``apply`` with a magnetometer calibration read DATA's magnetometer through
:func:`optcal.families.mag.samples.read_mag`, which leaves out the samples at the converter's rail and says so in a
line that names this flag; each of them takes it (as :mod:`optcal.cli.data_options` adds the DATA flags), and a
command that reads no magnetometer refuses it in one line (:func:`refuse_accept_mag_fit`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

__all__ = ["accept_mag_fit_option", "refuse_accept_mag_fit"]

_ACCEPT_MAG_FIT = click.option(
    "--accept-mag-fit", is_flag=True, default=False,
    help="Reading a magnetometer (--sensor mag, or a magnetometer calibration): keep its samples at the converter's "
         "rail (left out and counted by default: the field beyond the full scale is unknown); where a fit is made, "
         "also keep samples that do not lie on an ellipsoid and a fit that cannot be right, with a warning.")


def accept_mag_fit_option(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding ``--accept-mag-fit`` (keyword ``accept_mag_fit``; see the module docstring)."""
    return _ACCEPT_MAG_FIT(func)


def refuse_accept_mag_fit(accept_mag_fit: bool, what: str) -> None:
    """Refuse ``--accept-mag-fit`` where the command reads no magnetometer (``what`` says when it applies).

    Raises
    ------
    InputError
        ``accept_mag_fit`` given.
    """
    if accept_mag_fit:
        from optcal.errors import InputError

        raise InputError(f"--accept-mag-fit applies {what}")
