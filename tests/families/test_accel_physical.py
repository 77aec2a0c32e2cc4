"""The accelerometer's maximum likelihood kept only inside its physical set (optcal.families.accel.physical).

On poses covering part of the sphere with noise, the likelihood of Lu 2017 eq. 14 keeps falling as the ellipsoid
grows along the poorly covered axis: the refinement ran away (scale factors 2.4-11, z offsets of -6 to -10 g) and was
handed back.  With ``keep_physical`` (what ``optcal calibrate`` sets for the default and mle methods) the convex start
is kept where the refinement leaves the set, with a note and ``physical_set`` in the JSON; elsewhere nothing changes.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from optcal.core.constraints import physical_of_theta
from optcal.core.poses import PoseTable
from optcal.families.accel.calibration import calibrate
from optcal.families.accel.physical import OFFSET_MOVE_G, SCALE_FACTOR, physical_departure
from tests.helpers.cli_run import run_args

#: The generated sensor (mag8's accgen.py): raw = K g + b, in g.
K = np.array([[1.02, 0.003, -0.002], [0.0, 0.98, 0.004], [0.0, 0.0, 1.01]])
B = np.array([0.02, -0.015, 0.03])


def cap_poses(cap_deg: float, n: int, noise: float, seed: int) -> np.ndarray:
    """n poses with gravity within ``cap_deg`` of +z, raw = K g + b + noise (g)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(400 * n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u = u[u[:, 2] >= np.cos(np.radians(cap_deg))][:n]
    return u @ K.T + B + rng.normal(scale=noise, size=u.shape)


def _fit(acc: np.ndarray, units: str = "g", **settings) -> object:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the unguarded runaway stops at IPOPT's iteration limit
        return calibrate(PoseTable(acc=acc, units=units), method="mle", allow_degenerate=True, **settings)


def _scales(result) -> np.ndarray:
    return np.asarray(physical_of_theta(np.asarray(result.params[:9], float))[:3])


@pytest.mark.parametrize("cap, seed", [(45, 0), (60, 0)])
def test_runaway_on_a_cap_keeps_the_convex_start(cap, seed):
    acc = cap_poses(cap, 24, 0.005, seed)
    loose = _fit(acc)
    convex = calibrate(PoseTable(acc=acc, units="g"), method="convex", allow_degenerate=True)
    # the unguarded refinement runs away (the fault): a scale factor beyond the set's factor against its start
    assert np.max(_scales(loose) / _scales(convex)) > SCALE_FACTOR
    kept = _fit(acc, keep_physical=True)
    assert kept.method == "convex" and "physical_set" in kept.extra
    np.testing.assert_allclose(kept.params[:9], convex.params[:9], rtol=1e-6, atol=1e-9)
    ratio = _scales(kept) / _scales(convex)
    assert np.all((1 / SCALE_FACTOR <= ratio) & (ratio <= SCALE_FACTOR))
    assert any("MAXIMUM LIKELIHOOD NOT KEPT" in note and "--method convex" in note for note in kept.notes)
    assert kept.solver.success  # no convergence warning for a result that is not IPOPT's
    summary = kept.summary()
    assert summary["physical_set"]["kept"] == "convex" and summary["physical_set"]["scale_factor_limit"] == SCALE_FACTOR


def test_covered_sphere_unchanged():
    acc = cap_poses(180, 24, 0.005, 0)
    loose, kept = _fit(acc), _fit(acc, keep_physical=True)
    np.testing.assert_array_equal(kept.params, loose.params)
    assert kept.method == "mle" and "physical_set" not in kept.extra and "physical_set" not in kept.summary()


def test_user_bounds_turn_the_guard_off():
    acc = cap_poses(45, 24, 0.005, 0)
    bounded = _fit(acc, keep_physical=True, bounds={"o_z": (-20.0, 20.0)})
    assert bounded.method == "mle" and "physical_set" not in bounded.extra


def test_departure_in_any_units():
    """The set is relative to the start: the same decision in g and in counts (16384 LSB/g, MPU-6050 at ±2 g)."""
    acc = cap_poses(45, 24, 0.005, 1)
    g, counts = _fit(acc, keep_physical=True), _fit(acc * 16384.0, units="counts", keep_physical=True)
    assert g.method == counts.method == "convex"
    np.testing.assert_allclose(g.extra["physical_set"]["scale_ratio"], counts.extra["physical_set"]["scale_ratio"], rtol=1e-3)
    theta0 = np.array([1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    inside = theta0 + np.r_[np.zeros(6), 0.9 * OFFSET_MOVE_G, 0.0, 0.0]
    outside = theta0 + np.r_[np.zeros(6), 0.0, 0.0, 1.1 * OFFSET_MOVE_G]
    assert physical_departure(inside, theta0) is None
    why = physical_departure(outside, theta0)
    assert why is not None and "offset z" in why.reason and why.offset_move_g[2] == pytest.approx(1.1 * OFFSET_MOVE_G)


def test_cli_cap_says_so_in_text_and_json(tmp_path, capsys):
    path = tmp_path / "cap45.csv"
    np.savetxt(path, cap_poses(45, 24, 0.005, 0), delimiter=",", header="ax,ay,az", comments="", fmt="%.6f")
    code, out, err = run_args(capsys, "calibrate", str(path), "--format", "poses", "--units", "g", "--allow-degenerate", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["method"] == "convex" and data["physical_set"]["offset_move_g"][2] < -OFFSET_MOVE_G
    assert "did not converge" not in err
    code, out, _ = run_args(capsys, "calibrate", str(path), "--format", "poses", "--units", "g", "--allow-degenerate")
    assert code == 0 and "MAXIMUM LIKELIHOOD NOT KEPT" in out and "--method convex" in out


def test_planted_in_a_real_pose_table(shared_data):
    """Innalabs M3's 24 poses (hassan-innalabs-m3, in g): the half sphere x > 0 (11 poses) with 20 mg of white noise
    planted: the unguarded refinement runs away; the guarded one keeps its convex start.  The other half (z > 0, 14
    poses) with the same noise refines inside the set: unchanged."""
    from optcal.cli.data_options import load_data

    poses = load_data(str(shared_data / "hassan-innalabs-m3" / "CalibrationOfLowCostTriaxialInertialSensors.mat"))
    full = calibrate(poses, method="mle")
    u = full.correct(poses.acc)
    for axis, runaway in ((0, True), (2, False)):
        keep = u[:, axis] >= 0
        acc = poses.acc[keep] + np.random.default_rng(0).normal(scale=0.020 * np.mean(_scales(full)), size=(keep.sum(), 3))
        loose, kept = _fit(acc, units=poses.units), _fit(acc, units=poses.units, keep_physical=True)
        if runaway:
            convex = calibrate(PoseTable(acc=acc, units=poses.units), method="convex", allow_degenerate=True)
            assert np.max(_scales(loose) / _scales(convex)) > SCALE_FACTOR
            assert kept.method == "convex"
            np.testing.assert_allclose(kept.params[:9], convex.params[:9], rtol=1e-6, atol=1e-9)
        else:
            assert kept.method == "mle"
            np.testing.assert_array_equal(kept.params, loose.params)


def test_the_python_front_door_keeps_the_start_as_the_command_does():
    """``optcal.calibrate`` (default method) guards the refinement as ``optcal calibrate`` does: the same start kept."""
    import optcal

    acc = cap_poses(45, 24, 0.005, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        api = optcal.calibrate(PoseTable(acc=acc, units="g"), allow_degenerate=True)
        plain = optcal.calibrate(PoseTable(acc=acc, units="g"), allow_degenerate=True, keep_physical=False)
    convex = calibrate(PoseTable(acc=acc, units="g"), method="convex", allow_degenerate=True)
    assert "physical_set" in api.extra and "physical_set" not in plain.extra
    np.testing.assert_allclose(api.params[:9], convex.params[:9], rtol=1e-6, atol=1e-9)
