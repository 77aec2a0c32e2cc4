"""Synthetic fleets with known truth, and planted trouble, for tests, benchmarks and studies.

A unit's sensor is the lumped model of Lu 2017 (eq. 1, 5) with unit-to-unit scatter about a
nominal sensor: scale factors ``1 + N(0, SCALE_SD)``, the three non-orthogonality angles
``N(0, ANGLE_SD_DEG)``, biases ``N(0, BIAS_SD)`` (in g).  Each unit records ``n_poses``
directions uniform on the sphere with per-pose noise ``sigma`` (g), written as a pose table
CSV (``ax, ay, az, sigma``).  Planted trouble: units with a scale error on x, units that
recorded only the six faces of a cube (repeated, so the table has enough rows but does not
identify the off-diagonal of A), and unreadable files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import simulate_poses, six_position, uniform_directions

SCALE_SD: float = 0.01
ANGLE_SD_DEG: float = 0.2
BIAS_SD: float = 0.02
#: Repetitions of each face for a six-face unit (24 poses, enough rows for the fit to run).
SIX_FACE_REPEATS: int = 4


def unit_model(rng: np.random.Generator, scale_error: float = 0.0) -> LumpedModel:
    """One unit's sensor drawn from the population (``scale_error``: relative, added on x)."""
    scale = 1.0 + SCALE_SD * rng.standard_normal(3)
    scale[0] *= 1.0 + scale_error
    rho, phi, lam = np.deg2rad(ANGLE_SD_DEG * rng.standard_normal(3))
    return LumpedModel.from_physical(scale, rho, phi, lam, bias=BIAS_SD * rng.standard_normal(3))


@dataclass
class SyntheticFleet:
    """What :func:`write_fleet` wrote.

    Attributes
    ----------
    folder : Path
    truth : dict of str to ndarray
        True θ of every readable unit.
    kinds : dict of str to str
        ``normal``, ``scale_error``, ``six_faces`` or ``unreadable`` per unit.
    """

    folder: Path
    truth: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    kinds: dict[str, str] = field(default_factory=dict)

    def units(self, kind: str) -> list[str]:
        """The units of one kind."""
        return [u for u, k in self.kinds.items() if k == kind]


def write_fleet(
    folder: str | Path,
    n_units: int,
    seed: int = 0,
    *,
    n_poses: int = 120,
    sigma: float = 0.002,
    scale_error_units: int = 1,
    scale_error: float = 0.08,
    six_face_units: int = 1,
    unreadable_units: int = 2,
) -> SyntheticFleet:
    """Write ``n_units`` pose tables into ``folder`` (``unit00000.csv`` ...), with planted trouble.

    The last units are the planted ones: ``scale_error_units`` with an x scale error of
    ``scale_error``, ``six_face_units`` with only the six faces, ``unreadable_units`` files
    that no reader accepts (random bytes, a header without rows).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fleet = SyntheticFleet(folder)
    n_normal = n_units - scale_error_units - six_face_units - unreadable_units
    if n_normal < 0:
        raise ValueError("more planted units than units")
    kinds = ["normal"] * n_normal + ["scale_error"] * scale_error_units + ["six_faces"] * six_face_units
    kinds += ["unreadable"] * unreadable_units
    for k, kind in enumerate(kinds):
        name = f"unit{k:05d}"
        path = folder / f"{name}.csv"
        fleet.kinds[name] = kind
        rng = np.random.default_rng([seed, k])
        if kind == "unreadable":
            path.write_bytes(rng.bytes(200) if k % 2 else b"ax,ay,az\n")
            continue
        model = unit_model(rng, scale_error if kind == "scale_error" else 0.0)
        directions = np.repeat(six_position(), SIX_FACE_REPEATS, axis=0) if kind == "six_faces" else uniform_directions(n_poses, rng)
        poses = simulate_poses(model, directions, sigma, rng=rng)
        table = np.column_stack([poses.acc, np.full(poses.n, sigma)])
        np.savetxt(path, table, fmt="%.10g", delimiter=",", header="ax,ay,az,sigma", comments="")
        fleet.truth[name] = model.theta
    return fleet
