"""The options for reading another tool's calibration file, shared by every command that takes one.

``check``, ``apply``, ``export`` (CAL), ``diagnose`` (``--baseline``) and ``plan`` (``--prior``)
read imucal's calibration JSON and imu_tk's ``.calib`` pair as well as optcal's own files
(:func:`optcal.families.calibration_files.load`, by content).  Two things such a file does not
record are options:

* ``--peer-gravity M/S2``: the g the tool scaled its accelerometer output to (imucal's
  ``grav``, imu_tk's ``g_mag``; both default to 9.81 m/s²).  The |a| − 1 figures depend on it.
* ``--gyro-calib FILE``: imu_tk's gyroscope ``.calib`` when it is not next to the accelerometer's
  under the same name with ``acc`` replaced by ``gyro`` (``test_imu_acc.calib`` →
  ``test_imu_gyro.calib``, as imu_tk's ``test_imu_calib`` saves them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click


def peer_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Click decorator adding ``--peer-gravity`` and ``--gyro-calib``."""
    func = click.option("--gyro-calib", "gyro_calib", type=click.Path(dir_okay=False), default=None, metavar="FILE",
                        help="imu_tk: the gyroscope's .calib (default: the calibration's name with 'acc' replaced by "
                             "'gyro', next to it).")(func)
    return click.option("--peer-gravity", "peer_gravity", type=click.FloatRange(min=0, min_open=True), default=None,
                        metavar="M/S2",
                        help="imucal/imu_tk file: the g its accelerometer output was scaled to (imucal's grav, "
                             "imu_tk's g_mag; default 9.81, their default).")(func)


def load_calibration(path: str, peer_gravity: float | None = None, gyro_calib: str | None = None) -> Any:
    """Read a calibration file of any kind (optcal's, imucal's, imu_tk's) with the peer options."""
    import optcal.families.calibration_files as calibration_files

    return calibration_files.load(path, gyro=gyro_calib, gravity=peer_gravity)
