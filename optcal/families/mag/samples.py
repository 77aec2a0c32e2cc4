"""Reading a magnetometer's samples from any file optcal reads: text, MAT/netCDF/HDF5, ULog, ROS bags.

A magnetometer needs no rests (the field is constant in the world frame), so its samples are
read as they are: :func:`read_mag` returns a :class:`MagSamples` with the magnetometer's
columns (``mx, my, mz`` and the aliases of :data:`optcal.data.columns.MAG_ALIASES`), and where
the file has them the accelerometer (for the dip), time, temperature and a current or
throttle column (for the interference of a motor).  Every row with a non-finite
magnetometer value is counted in :attr:`MagSamples.exclusions`, never silently dropped.
"""

from __future__ import annotations

from pathlib import Path

from optcal.data.columns import parse_columns_option
from optcal.errors import InputError
# the reading's concepts, one module each (and importable from here, as before): the samples and their building,
# the rail, the columns by name and by a headerless file's layout, the readers per format, the held samples
from optcal.families.mag.columns import (CURRENT_ALIASES, GAUSS_SYMBOLS, NORMAL_ZERO, SUFFIX_MIN_CHARS,
                                         THROTTLE_ALIASES, TWO_AXES, _strip_mag_unit)
from optcal.families.mag.headerless import ACC_NORM_SPREAD, QUATERNION_NORM_TOL
from optcal.families.mag.held import HELD_ROWS, TORN_ROWS, drop_held
from optcal.families.mag.rail import MAG_NEAR_RAIL_SHARE, MAG_RAIL_MIN_UT, MAG_RAIL_ROWS, mag_rail, rail_line
from optcal.families.mag.read_container import _read_container
from optcal.families.mag.read_dataflash import _read_dataflash
from optcal.families.mag.read_rosbag import ROS_IMU_TYPE, ROS_JOIN_SHARE, ROS_MAG_TYPE, _read_rosbag
from optcal.families.mag.read_text import _read_text
from optcal.families.mag.read_ulog import PX4_CALIBRATED_MAG, _read_ulog
from optcal.families.mag.sample_set import ZERO_ROWS, MagSamples


def read_mag(path: str | Path, *, columns: str | dict[str, str] | None = None, topic: str | None = None,
             mag_units: str | None = None, keep_rail: bool = False, keep_repeats: bool = False,
             keep_spikes: bool = False) -> MagSamples:
    """Read a magnetometer's samples (module docstring).

    Parameters
    ----------
    path : str or Path
        A delimited text file, MAT-file, netCDF-4/HDF5 file, PX4 ULog or ROS 1/2 bag (``sensor_msgs/MagneticField``).
    columns : str or dict, optional
        ``--columns mx=NAME,my=NAME,mz=NAME`` (names or 1-based positions; ``ax=...`` for the accelerometer).
    topic : str, optional
        The magnetometer's variable of a container, the ULog topic (``sensor_mag:1``) or the bag's MagneticField topic.
    mag_units : str, optional
        The units (``--mag-units``), instead of the file's word or the decision from the magnitude.
    keep_rail : bool
        Keep the samples with an axis at the converter's rail (:func:`mag_rail`; left out and counted by default).
    keep_repeats : bool
        Keep every row where the logger repeats each magnetometer value until its next update (:func:`drop_held`;
        by default one row per update, the repeats counted).
    keep_spikes : bool
        Keep the samples that leave both neighbours by more than a turning field moves
        (:func:`optcal.families.mag.spikes.drop_spikes`; left out and counted by default).

    Raises
    ------
    InputError
        No magnetometer found, or a file optcal cannot read.
    """
    from optcal.families.mag.spikes import drop_spikes

    held = drop_held(_read_any_mag(str(path), columns, topic, mag_units, keep_rail), keep_repeats)
    return drop_spikes(held, keep_spikes)


def _read_any_mag(p: str, columns: str | dict[str, str] | None, topic: str | None, mag_units: str | None,
                  keep_rail: bool) -> MagSamples:
    from optcal.data.containers import container_type
    from optcal.data.readers import detect_file_type

    if not Path(p).exists():
        raise InputError(f"{p}: no such file")
    kind = detect_file_type(p)
    if kind == "csv" and (container := container_type(p)) is not None:
        return _read_container(p, container, topic, mag_units, keep_rail)
    if kind == "csv":
        return _read_text(p, parse_columns_option(columns) if isinstance(columns, str) or columns else {}, mag_units,
                          keep_rail)
    if kind == "ulog":
        return _read_ulog(p, topic, mag_units, keep_rail)
    if kind in ("ros1 bag", "ros2 bag"):
        return _read_rosbag(p, kind, topic, mag_units, keep_rail)
    if kind == "dataflash":
        return _read_dataflash(p, topic, mag_units, keep_rail)
    raise InputError(f"{p}: the magnetometer is read from text, MAT/netCDF/HDF5 and ULog files, not a {kind} yet; "
                     f"export its mx, my, mz columns to CSV")
