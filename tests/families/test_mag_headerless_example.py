"""The refusal of a headerless file of no common width named ``--columns mx=1,my=2,mz=3`` whatever the file held:
for AlexMinhao's 8- and 14-column logs (seconds of the minute and milliseconds, gyro, magnetometer; then a second
stamp and a unit quaternion) it named the time columns as a magnetometer.  The example now sets aside the stamps
and quaternions the evidence shows and names the last triple of the rest, or none."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.errors import InputError
from optcal.families.mag.samples import read_mag


def _log(path, quaternion: bool) -> None:
    """A 111-Hz log over two minutes' wrap: seconds of the minute, ms, gyro (rad/s), magnetometer (uT); with a second
    stamp and a unit quaternion after them when ``quaternion``."""
    rng = np.random.default_rng(7)
    n = 2000
    t = 55.0 + np.arange(n) * 0.009  # wraps from 59 to 0 s
    secs, ms = np.floor(t) % 60, np.floor((t % 1) * 1000)
    gyro = rng.normal(0, 1.0, (n, 3))
    mag = np.round(rng.normal(0, 20, (n, 3)) / 0.6) * 0.6
    cols = [secs, ms, *gyro.T, *mag.T]
    if quaternion:
        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        cols += [secs, ms, *np.round(q, 7).T]
    np.savetxt(path, np.column_stack(cols), delimiter=",", fmt="%.7g")


@pytest.mark.parametrize("quaternion", [False, True], ids=["8 columns", "14 columns"])
def test_the_example_names_the_magnetometer_the_evidence_points_to(tmp_path, quaternion):
    path = tmp_path / "log.csv"
    _log(path, quaternion)
    with pytest.raises(InputError, match=r"e\.g\. --columns mx=6,my=7,mz=8 \(columns 1-2 a split time stamp") as info:
        read_mag(path)
    assert ("columns 11-14 a unit quaternion" in str(info.value)) == quaternion
    assert read_mag(path, columns="mx=6,my=7,mz=8").n == 2000


def test_no_example_where_the_rest_is_no_set_of_triples(tmp_path):
    path = tmp_path / "seven.csv"
    np.savetxt(path, np.random.default_rng(8).normal(size=(200, 7)), delimiter=",")
    with pytest.raises(InputError, match=r"--columns mx=N,my=N,mz=N \(the 7 other columns are no set of triples\)"):
        read_mag(path)
