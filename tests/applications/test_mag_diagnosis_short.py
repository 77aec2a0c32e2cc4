"""A short magnetometer log's diagnosis measures the noise the samples have.

sebkm/sensor_fusion's ``experiments/mag/sphere.csv`` (534 samples of a Pmod NAV turned over a sphere, gauss) was
diagnosed with the misfit's degree-4 polynomial in the direction (35 terms) fitted to its 21 block means: the fit was
underdetermined and subtracted a "misfit" of 61 % rms of the field, so the white noise read 0.193 (against 0.018 in
the residuals themselves), the band ±0.127 and the noise colour 1 (35): the search was blind.  The degree is now the
highest the blocks determine (more than two blocks a term, as the dip's misfit already required), said in a note.
On a generated log of that length and noise."""

from __future__ import annotations

import json

import numpy as np

from helpers.cli_run import run

NOISE = 0.01  # white noise per axis, a share of the field: a consumer magnetometer's (about 0.5 µT of 48 µT)


def test_a_short_logs_white_noise_is_the_samples(tmp_path, capsys):
    rng = np.random.default_rng(7)
    n = 534
    # the sensor turned over the sphere by hand and read at 9 Hz (sebkm's median 111 ms): its direction a random walk
    # of about a radian between samples
    u = np.cumsum(rng.normal(0.0, 1.5, (n, 3)), axis=0) + rng.normal(size=3)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    m = u * 0.38 * np.array([1.03, 0.98, 1.0]) + np.array([0.025, 0.227, -0.082])
    m += rng.normal(0.0, NOISE * 0.38, m.shape)
    path = tmp_path / "sphere.csv"
    path.write_text("mx,my,mz\n" + "\n".join(f"{a:.5f},{b:.5f},{c:.5f}" for a, b, c in m) + "\n")
    code, out, err = run(["diagnose", str(path), "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    report = json.loads(out)
    band = report["band"]
    # the norm residual's white σ: the per-axis noise projected on the field's direction, NOISE of the field
    assert 0.7 * NOISE < band["sigma_sample"] < 1.5 * NOISE, band  # before: 1.7 times NOISE
    assert any("degree 2, not 4" in note for note in report["notes"])
