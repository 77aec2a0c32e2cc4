"""Six-position least squares with known orientations (Yin 2014, eqs. 2-4)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from optcal.families.accel.calibration import calibrate
from optcal.cli.main import main
from optcal.errors import InputError
from optcal.families.accel.sixpos import PARAM_NAMES, SixPositionLeastSquares, reference_from_angles
from optcal.core.model import STANDARD_GRAVITY, lumped_matrix
from optcal.core.poses import PoseTable
from optcal.families.accel.result import CalibrationResult

#: Table 2 of the paper (reconstructed): the six faces of a levelled cube, roll/pitch in degrees.
SIX = np.array([(0, 0), (180, 0), (90, 0), (-90, 0), (0, 90), (0, -90)], dtype=float)
C_TRUE = lumped_matrix((1.02, 0.97, 1.03), *np.radians((0.5, 0.3, 0.4)))
O_TRUE = np.array([0.03, -0.02, 0.05])
W_TRUE = np.linalg.inv(C_TRUE)
V_TRUE = -W_TRUE @ O_TRUE


def six_poses(sigma: float, rng: np.random.Generator | None, angles: np.ndarray = SIX, units_scale: float = 1.0) -> PoseTable:
    """Pose means a = C f + o + e (e ~ N(0, σ² I)) with the orientation in ``extra``."""
    f = reference_from_angles(angles[:, 0], angles[:, 1])
    acc = f @ C_TRUE.T + O_TRUE
    if rng is not None:
        acc = acc + rng.standard_normal(acc.shape) * sigma
    return PoseTable(
        acc=acc * units_scale,
        sigma=np.full(len(angles), sigma * units_scale),
        units="g" if units_scale == 1.0 else "counts",
        extra={"roll_deg": angles[:, 0].copy(), "pitch_deg": angles[:, 1].copy()},
    )


def test_reference_follows_the_tilt_convention() -> None:
    f = reference_from_angles(SIX[:, 0], SIX[:, 1])
    expected = [[0, 0, 1], [0, 0, -1], [0, 1, 0], [0, -1, 0], [-1, 0, 0], [1, 0, 0]]
    np.testing.assert_allclose(f, expected, atol=1e-15)


def test_noise_free_poses_give_w_and_v_exactly() -> None:
    r = SixPositionLeastSquares().fit(six_poses(1e-4, None))
    np.testing.assert_allclose(r.W, W_TRUE, atol=1e-12)
    np.testing.assert_allclose(r.V, V_TRUE, atol=1e-12)
    np.testing.assert_allclose(r.T, W_TRUE, atol=1e-12)
    np.testing.assert_allclose(r.o, O_TRUE, atol=1e-12)
    np.testing.assert_allclose(r.residuals, 0, atol=1e-12)
    assert r.param_names == list(PARAM_NAMES) and r.method == "sixpos"
    assert any("not optcal's canonical lower-triangular" in n for n in r.notes)


def test_w_and_v_within_three_standard_errors_of_truth() -> None:
    r = calibrate(six_poses(5e-5, np.random.default_rng(2014)), method="sixpos")
    truth = np.concatenate([W_TRUE.ravel(), V_TRUE])
    se = np.sqrt(np.diag(r.covariance))
    assert r.sigma_known
    assert np.all(np.abs(r.params - truth) < 3 * se)


def test_standard_errors_match_the_monte_carlo_scatter() -> None:
    rng = np.random.default_rng(1)
    truth = np.concatenate([W_TRUE.ravel(), V_TRUE])
    z = []
    for _ in range(400):
        r = SixPositionLeastSquares().fit(six_poses(1e-3, rng))
        z.append((r.params - truth) / np.sqrt(np.diag(r.covariance)))
    z = np.array(z)
    # each standardised error has unit variance: 400 runs give its sd to about ±3.5 % (1 SE)
    assert np.all(np.abs(z.std(axis=0) - 1) < 0.12)
    assert np.all(np.abs(z.mean(axis=0)) < 3 / np.sqrt(400))


def test_without_sigma_the_covariance_comes_from_the_residuals() -> None:
    poses = six_poses(1e-3, np.random.default_rng(4))
    poses.sigma = None
    r = SixPositionLeastSquares().fit(poses)
    assert not r.sigma_known
    assert np.all(np.isfinite(r.covariance)) and np.all(np.diag(r.covariance) > 0)
    assert any("degree(s) of freedom" in n for n in r.notes)
    with pytest.raises(InputError, match="sigma"):
        SixPositionLeastSquares(scale_covariance=False).fit(poses)


def test_reference_columns_equal_the_angles_and_accept_m_per_s2() -> None:
    poses = six_poses(1e-4, np.random.default_rng(5))
    by_angles = SixPositionLeastSquares().fit(poses)
    f = reference_from_angles(SIX[:, 0], SIX[:, 1]) * STANDARD_GRAVITY
    ref = PoseTable(acc=poses.acc, sigma=poses.sigma, extra={"gx_ref": f[:, 0], "gy_ref": f[:, 1], "gz_ref": f[:, 2]})
    by_reference = SixPositionLeastSquares().fit(ref)
    np.testing.assert_allclose(by_reference.params, by_angles.params, atol=1e-12)
    assert any("m/s^2" in n for n in by_reference.notes)


def test_counts_give_w_in_g_per_count_and_a_working_correction() -> None:
    r = SixPositionLeastSquares().fit(six_poses(2e-4, np.random.default_rng(6), units_scale=16384.0))
    np.testing.assert_allclose(r.W * 16384.0, W_TRUE, atol=2e-3)
    raw = (C_TRUE @ [0.0, 0.6, 0.8] + O_TRUE) * 16384.0
    np.testing.assert_allclose(r.correct(raw), [0.0, 0.6, 0.8], atol=1e-3)


def test_result_survives_a_json_round_trip(tmp_path) -> None:
    r = SixPositionLeastSquares().fit(six_poses(1e-4, np.random.default_rng(8)))
    r.save(tmp_path / "cal.json")
    back = CalibrationResult.load(tmp_path / "cal.json")
    np.testing.assert_allclose(back.T, r.T)
    np.testing.assert_allclose(back.params, r.params)
    np.testing.assert_allclose(back.W, r.W)
    np.testing.assert_allclose(back.V, r.V)
    assert back.chisqr == r.chisqr and back.n_observations == 3 * r.n_poses and back.extra.keys() == r.extra.keys()
    # the file keeps format 2.0's layout: W, V, n and chi-square under extra as well
    saved = json.loads((tmp_path / "cal.json").read_text())["extra"]
    assert list(saved)[:2] == ["W", "V"] and list(saved)[-2:] == ["n_observations", "chisqr"]
    assert back == r


def test_result_holds_a_sixpos_full_calibration() -> None:
    from optcal.families.caltypes import SixPositionCalibration

    r = SixPositionLeastSquares().fit(six_poses(1e-4, np.random.default_rng(8)))
    cal = r.calibration
    assert isinstance(cal, SixPositionCalibration)
    np.testing.assert_array_equal(cal.W, r.W)
    raw = C_TRUE @ [0.0, 0.6, 0.8] + O_TRUE
    np.testing.assert_allclose(cal.correct(raw), r.correct(raw[None]), atol=1e-15)
    # its lumped form has the same norms (A = WᵀW) and optcal's canonical T
    lumped = cal.lumped()
    np.testing.assert_allclose(lumped.T.T @ lumped.T, cal.W.T @ cal.W, atol=1e-12)
    np.testing.assert_allclose(lumped.o, r.o, atol=1e-12)


def test_mle_started_from_a_sixpos_result_starts_at_its_calibration() -> None:
    """MaximumLikelihood(init=<sixpos result>) starts from θ of W, V (not from W's first nine numbers)."""
    from optcal.families.accel.base import Normaliser
    from optcal.families.accel.mle import MaximumLikelihood
    from optcal.core.model import theta_from

    rng = np.random.default_rng(3)
    dirs = rng.standard_normal((30, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    angles = np.degrees(np.column_stack([np.arctan2(dirs[:, 1], dirs[:, 2]), -np.arcsin(dirs[:, 0])]))
    poses = six_poses(1e-4, rng, angles=angles)
    r = SixPositionLeastSquares().fit(poses)
    mle = MaximumLikelihood(init=r)
    norm = Normaliser.of(poses.acc)
    theta_n, source = mle.initial_normalised(poses, norm, norm.forward(poses.acc))
    lumped = r.calibration.lumped()
    np.testing.assert_allclose(norm.theta_to_raw(theta_n), theta_from(lumped.T, lumped.o), atol=1e-12)
    assert source == "sixpos"
    fitted = mle.fit(poses)
    default = MaximumLikelihood().fit(poses)
    np.testing.assert_allclose(fitted.params, default.params, atol=1e-8)


def test_missing_orientation_is_refused() -> None:
    poses = six_poses(1e-4, None)
    poses.extra = {}
    with pytest.raises(InputError, match="roll_deg and pitch_deg"):
        SixPositionLeastSquares().fit(poses)
    partial = six_poses(1e-4, None)
    partial.extra["roll_deg"][2] = np.nan
    with pytest.raises(InputError, match="not finite for 1 pose"):
        SixPositionLeastSquares().fit(partial)


def _write(path, poses: PoseTable, with_angles: bool = True) -> None:
    head = "ax,ay,az,sigma" + (",roll_deg,pitch_deg" if with_angles else "")
    rows = []
    for k in range(poses.n):
        row = [*poses.acc[k], poses.sigma[k]] + ([*SIX[k]] if with_angles else [])
        rows.append(",".join(f"{v:.10g}" for v in row))
    path.write_text(head + "\n" + "\n".join(rows) + "\n")


def test_cli_calibrate_method_sixpos(tmp_path, capsys) -> None:
    poses = six_poses(1e-4, np.random.default_rng(9))
    f = tmp_path / "six.csv"
    _write(f, poses)
    assert main(["calibrate", str(f), "--method", "sixpos", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "sixpos"
    assert set(out["params"]) == set(PARAM_NAMES) and set(out["stderr"]) == set(PARAM_NAMES)
    np.testing.assert_allclose(out["T"], W_TRUE, atol=2e-3)


def test_cli_without_orientation_exits_2(tmp_path, capsys) -> None:
    f = tmp_path / "six.csv"
    _write(f, six_poses(1e-4, None), with_angles=False)
    assert main(["calibrate", str(f), "--method", "sixpos"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "roll_deg" in err and "gx_ref" in err
