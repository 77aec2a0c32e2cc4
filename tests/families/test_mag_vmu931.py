"""The magnetometer's reader on Variense VMU931's exports (Alanzwang/vmu931): the sensor's word in every row names
the triple, headered (``Attribute,Time stamp,x,y,z`` with ``Magnetometer`` in every row) or not
(``magnetometer,411480,x,y,z``), as the accelerometer's reader already read it; before, the headered file asked for
``--columns mx=x,my=y,mz=z`` and the headerless one was refused ("5 unnamed columns fit no common layout"), though
the accelerometer's commands named ``optcal calibrate FILE --sensor mag`` for both."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run
from helpers.vmu931 import FIELD_UT, HARD_IRON_UT, write_vmu931


@pytest.mark.parametrize("header", [True, False])
def test_vmu931_magnetometer_read_by_its_word(tmp_path, capsys, header):
    """A turned magnetometer in either layout: read without a flag, the word said, the field and hard iron
    recovered (0.3 µT noise over 3000 samples: the fit's standard errors are about 0.01 µT)."""
    files = write_vmu931(tmp_path, 411480, header=header, mag_turned=True)
    code, out, err = run(["calibrate", files["magnetometer"], "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["n_samples"] == 3000
    assert abs(cal["field_strength"] - FIELD_UT) < 0.1
    assert np.allclose(cal["o"], HARD_IRON_UT, atol=0.1)
    decisions = " ".join(cal["decisions"])
    assert ("'Magnetometer': the magnetometer" if header else "'magnetometer': the magnetometer") in decisions
    assert ("t=Time stamp" if header else "mx=3, my=4, mz=5, t=2") in decisions


@pytest.mark.parametrize("header", [True, False])
def test_vmu931_other_sensors_refused_by_the_magnetometer_reader(tmp_path, capsys, header):
    """The control: the accelerometer's and the gyroscope's files given to ``--sensor mag`` are refused in one line
    naming the command that reads them, not read as a magnetometer."""
    files = write_vmu931(tmp_path, 411480, header=header)
    for word, reader in (("acceleration", "optcal calibrate FILE reads it"),
                         ("gyroscope", "optcal allan FILE --sensor gyro reads it")):
        code, out, err = run(["calibrate", files[word], "--sensor", "mag"], capsys)
        assert code == 2 and reader in err and err.count("\n") == 1


def test_a_split_stamp_is_the_magnetometer_samples_time(tmp_path):
    """The same headerless reader on ROS's ``secs,nsecs,mx,my,mz`` (SiyangMeng's mag.csv, the third sweep): the joined
    stamp was written into the columns after they were named, so the samples' time kept the whole seconds (steps of
    0 and 1 s at 100 Hz); now it is the stamp."""
    from optcal.families.mag.samples import read_mag

    n = 300
    ns = np.round(np.arange(n) * 0.01 * 1e9).astype(np.int64) + 1696324304 * 10**9
    u = np.random.default_rng(0).normal(size=(n, 3))
    m = 40.0 * u / np.linalg.norm(u, axis=1, keepdims=True)
    path = tmp_path / "mag.csv"
    path.write_text("".join(f"{a // 10**9},{a % 10**9:9d},{x:.4f},{y:.4f},{z:.4f}\n" for a, (x, y, z) in zip(ns, m)))
    samples = read_mag(path)
    assert samples.t is not None and np.allclose(np.diff(samples.t), 0.01, atol=1e-6)
