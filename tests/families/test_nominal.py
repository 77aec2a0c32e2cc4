"""Known orientations as nominal (optcal.families.accel.nominal): the tilts estimated, not absorbed into the bias."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.core.poses import PoseTable
from optcal.errors import InputError
from optcal.families.accel.calibration import calibrate
from optcal.report.calibration_text import calibration_report

#: Pose-mean noise, g (a few hundred samples of a 1 mg-noise accelerometer).
SIGMA_G = 2e-5
#: Placement scatter of hand-placed faces simulated, degrees.
TILT_DEG = 0.3


def _faces(seed: int, directions: np.ndarray | None = None) -> tuple[PoseTable, np.ndarray, np.ndarray]:
    """Faces (or other nominal directions) of a sensor u = C f + o, each pose tilted by N(0, TILT_DEG²) per axis."""
    rng = np.random.default_rng(seed)
    C = np.diag([1.01, 0.99, 1.02]) + 0.004 * rng.standard_normal((3, 3))
    o = np.array([0.02, -0.03, 0.015])
    n = np.vstack([np.eye(3), -np.eye(3)]) if directions is None else directions
    t = np.radians(TILT_DEG) * rng.standard_normal(n.shape)
    f = n + t - (t * n).sum(axis=1, keepdims=True) * n
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    u = f @ C.T + o + SIGMA_G * rng.standard_normal(n.shape)
    extra = {"gx_ref": n[:, 0], "gy_ref": n[:, 1], "gz_ref": n[:, 2]}
    return PoseTable(acc=u, sigma=np.full(len(u), SIGMA_G), extra=extra), n, o


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tilts_do_not_reach_the_bias(seed: int) -> None:
    """Six tilted faces: Yin 2014's least squares puts the tilts into the bias (mg), the tilt-estimating fit does not."""
    poses, _, o = _faces(seed)
    six = calibrate(poses, method="sixpos")
    nominal = calibrate(poses, method="nominal")
    err_six, err_nominal = np.linalg.norm(six.o - o), np.linalg.norm(nominal.o - o)
    assert err_six > 5e-4  # tilts of 0.3° move the least-squares bias by mg
    assert err_nominal < 0.2 * err_six and err_nominal < 2e-4
    se = nominal.stderr
    assert all(np.isfinite(v) and v > 0 for v in se.values())
    assert nominal.extra["determined_without_nominal"] == 6  # six norms: the rest rests on the placement
    assert "+/- nan" not in calibration_report(nominal)


def test_nearest_axis_is_the_nominal_direction() -> None:
    """Without orientation columns the faces' nominal directions are the nearest axes: the same fit."""
    poses, _, _ = _faces(3)
    bare = PoseTable(acc=poses.acc, sigma=poses.sigma)
    a, b = calibrate(poses, method="nominal"), calibrate(bare, method="nominal")
    np.testing.assert_allclose(a.params, b.params, rtol=1e-6, atol=1e-9)


def test_many_directions_are_determined_without_the_placement() -> None:
    """Twelve directions spread over the sphere: the poses alone determine 9 of 12 (all but the frame's rotation)."""
    rng = np.random.default_rng(5)
    d = rng.standard_normal((12, 3))
    poses, _, o = _faces(6, d / np.linalg.norm(d, axis=1, keepdims=True))
    fit = calibrate(poses, method="nominal")
    assert fit.extra["determined_without_nominal"] == 9
    assert np.linalg.norm(fit.o - o) < 2e-4


def test_a_pose_far_from_every_axis_is_not_a_face() -> None:
    poses, _, _ = _faces(7)
    acc = poses.acc.copy()
    acc[0] = [0.7, 0.7, 0.1]
    with pytest.raises(InputError, match="not one of the six faces"):
        calibrate(PoseTable(acc=acc, sigma=poses.sigma), method="nominal")


def test_sixpos_report_has_standard_errors() -> None:
    """The six-position fit's engineering parameters carry standard errors (its covariance is of W and V)."""
    poses, _, _ = _faces(8)
    text = calibration_report(calibrate(poses, method="sixpos"))
    assert "+/- nan" not in text and "S_x" in text
