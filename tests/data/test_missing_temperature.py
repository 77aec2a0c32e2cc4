"""A temperature with no number in it (a PX4 driver without a thermometer publishes NaN in ``sensor_accel``; a
logger writes an empty ``temp`` column): before, every accelerometer sample was counted non-finite and the file
refused ("no usable sample"); now the temperature is set aside, said in a note, and the samples are read."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.core.model import LumpedModel
from optcal.data import load
from optcal.data.writers import write_ulog
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording


@pytest.fixture(scope="module")
def recording():
    """6 poses of 2 s at 100 Hz in m/s² with a temperature column."""
    model = LumpedModel.from_physical([9.70, 9.90, 9.80], 0.01, -0.01, 0.02, [0.10, -0.20, 0.30])
    return synthesize_recording(model, uniform_directions(6, rng=3), dwell_s=2.0, transition_s=1.0, sigma=0.02,
                                gyro_units="rad/s", temperature=(30.0, 0.02), rng=4, units="m/s^2")


@pytest.mark.parametrize("kind", ["ulog", "csv"])
def test_a_temperature_with_no_number_leaves_the_samples_usable(recording, tmp_path, kind):
    frame = recording.frame.copy()
    frame["temp"] = np.nan
    path = tmp_path / f"rec.{'ulg' if kind == 'ulog' else 'csv'}"
    if kind == "ulog":
        write_ulog(frame, path)  # sensor_accel.temperature NaN in every message
    else:
        frame.to_csv(path, index=False, na_rep="")
    loaded = load(path)
    assert loaded.n == len(recording.dwells)
    assert np.allclose(loaded.acc, [np.mean(recording.frame[["ax", "ay", "az"]].to_numpy()[a:b], axis=0)
                                    for a, b in recording.dwells], atol=0.02)
    assert any("holds no number" in n and "set aside" in n for n in loaded.meta["notes"])


def test_a_temperature_missing_in_some_rows_keeps_those_rows_out(recording, tmp_path):
    """The control: a temperature logged in most rows stays read, the rows without it counted."""
    frame = recording.frame.copy()
    frame.loc[frame.index[::10], "temp"] = np.nan
    frame.to_csv(tmp_path / "part.csv", index=False, na_rep="")
    loaded = load(tmp_path / "part.csv")
    assert not any("holds no number" in n for n in loaded.meta["notes"])
    assert loaded.n == len(recording.dwells)
