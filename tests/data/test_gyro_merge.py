"""A gyro file that shares a coarse time column with the accelerometer's (``--gyro-file``): its rows are paired as
they are, not collapsed onto each repeated stamp's last sample (cggos/imu_tk's RealSense T265 files: 200 Hz stamped
to 10 ms)."""

from __future__ import annotations

import numpy as np

from optcal.core.model import LumpedModel
from optcal.data import load_with_segmentation
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording


def test_a_gyro_file_sharing_a_coarse_time_column_keeps_every_sample(tmp_path):
    model = LumpedModel.from_physical([1.0, 1.0, 1.0], 0.0, 0.0, 0.0, [0.0, 0.0, 0.0])
    syn = synthesize_recording(model, uniform_directions(8, rng=3), rate_hz=200.0, dwell_s=2.0,
                               transition_s=1.0, sigma=0.002, rng=4)
    f = syn.frame
    t = np.round(f["t"].to_numpy(), 2)  # a 200 Hz stream stamped to 10 ms: every other row repeats its stamp
    assert np.mean(np.diff(t) == 0) > 0.4
    np.savetxt(tmp_path / "acc.txt", np.column_stack([t, f[["ax", "ay", "az"]].to_numpy()]), fmt="%.9g")
    written = f[["gx", "gy", "gz"]].to_numpy()
    np.savetxt(tmp_path / "gyro.txt", np.column_stack([t, written]), fmt="%.9g")
    loaded = load_with_segmentation(tmp_path / "acc.txt", gyro_file=tmp_path / "gyro.txt")
    rec = loaded.segmentation.recording
    assert rec.gyro is not None and rec.gyro.shape == written.shape
    scale = np.median(np.abs(rec.gyro[written != 0] / written[written != 0]))  # the file's unit to the reader's
    np.testing.assert_allclose(rec.gyro, scale * written, rtol=1e-6, atol=1e-9 * scale)
    assert any("row for row" in n for n in rec.meta["notes"])
