"""Candidate gravity directions and the constraints users have on them.

A :class:`CandidateSet` is the feasible set of a plan: a grid of directions on the sphere (free
orientations, optionally within a cap about an axis), the directions a turntable reaches with
its gimbals on fixed steps (Sun 2011's three-axis table), or a fixed list from a file.  The
relaxation chooses weights over the grid; when the set is ``continuous`` the chosen poses are
then refined off the grid (within the cap, if any).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.rotations import turntable_attitude
from optcal.errors import InputError
from optcal.families.simulate.poses import user_directions

#: Candidate grid size for free orientations (spacing about 4.5°).
DEFAULT_GRID: int = 2000
_AXIS_NAMES = {f"{s}{a}": (1.0 if s == "+" else -1.0) * np.eye(3)[i] for i, a in enumerate("xyz") for s in "+-"}


def fibonacci_sphere(n: int) -> NDArray[np.float64]:
    """``n`` nearly uniform unit vectors (the Fibonacci lattice), shape (n, 3)."""
    if n < 1:
        raise InputError(f"the candidate grid needs at least one direction, not {n}")
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def parse_axis(axis: str | ArrayLike) -> NDArray[np.float64]:
    """A unit axis from ``"+z"``, ``"-x"``, ... or a 3-vector."""
    if isinstance(axis, str):
        key = axis.strip().lower().replace("−", "-")
        key = key if key[:1] in "+-" else "+" + key
        if key not in _AXIS_NAMES:
            raise InputError(f"axis must be one of +x, -x, +y, -y, +z, -z or a 3-vector, not {axis!r}")
        return _AXIS_NAMES[key].copy()
    return user_directions(np.asarray(axis, float).reshape(1, 3))[0]


@dataclass(frozen=True, init=False)
class Cap:
    """Directions within ``half_angle_deg`` of ``axis`` (a device that cannot be turned over).

    Built from an axis name (``"+z"``, ``"-x"``, ...) or a 3-vector (:func:`parse_axis`); ``axis``
    is then the unit vector.
    """

    axis: NDArray[np.float64]
    half_angle_deg: float

    def __init__(self, axis: str | ArrayLike, half_angle_deg: float) -> None:
        if not 0.0 < half_angle_deg <= 180.0:
            raise InputError(
                f"the cap half-angle must be in (0°, 180°], not {half_angle_deg:g}°: "
                "a cap of 0° allows a single orientation, which determines no calibration"
            )
        object.__setattr__(self, "axis", parse_axis(axis))
        object.__setattr__(self, "half_angle_deg", half_angle_deg)

    @property
    def cos_half_angle(self) -> float:
        return float(np.cos(np.deg2rad(self.half_angle_deg)))

    def contains(self, directions: NDArray, slack: float = 1e-9) -> NDArray[np.bool_]:
        """Which unit directions lie in the cap."""
        return directions @ self.axis >= self.cos_half_angle - slack

    def boundary(self, n: int) -> NDArray[np.float64]:
        """``n`` directions evenly spaced on the cap's edge, shape (n, 3)."""
        e1 = np.linalg.svd(self.axis[None, :])[2][1]  # a unit vector orthogonal to the axis
        e2 = np.cross(self.axis, e1)
        t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)[:, None]
        alpha = np.deg2rad(self.half_angle_deg)
        return np.cos(alpha) * self.axis + np.sin(alpha) * (np.cos(t) * e1 + np.sin(t) * e2)

    def describe(self) -> str:
        name = next((k for k, v in _AXIS_NAMES.items() if np.allclose(v, self.axis)), np.array2string(self.axis, precision=3))
        return f"within {self.half_angle_deg:g}° of {name} up"


@dataclass(frozen=True)
class CandidateSet:
    """The feasible directions of a plan.

    Attributes
    ----------
    directions : ndarray, shape (n, 3)
        Unit gravity directions in the sensor frame.
    continuous : bool
        Whether planned poses may leave the grid (free orientations or a cap); False for a
        turntable or a list from a file.
    cap : Cap or None
        The cap the directions (and refined poses) must stay in.
    labels : list of str
        How to reach each direction when it is not obvious (turntable angles), else empty.
    description : str
        For the report.
    excluded : int
        Directions of the source outside the cap (counted, never silently dropped).
    """

    directions: NDArray[np.float64]
    continuous: bool
    cap: Cap | None = None
    labels: list[str] = field(default_factory=list)
    description: str = ""
    excluded: int = 0

    def __post_init__(self) -> None:
        if len(self.directions) == 0:
            where = f" {self.cap.describe()}" if self.cap else ""
            raise InputError(f"no candidate direction is feasible{where} ({self.description}); widen the constraint")


def _apply_cap(directions: NDArray, cap: Cap | None, labels: list[str]) -> tuple[NDArray, list[str], int]:
    if cap is None:
        return directions, labels, 0
    keep = cap.contains(directions)
    return directions[keep], [lab for lab, k in zip(labels, keep) if k], int(np.sum(~keep))


def sphere_candidates(n: int = DEFAULT_GRID, cap: Cap | None = None) -> CandidateSet:
    """Free orientations: a Fibonacci grid of ``n`` directions (inside the cap, if any).

    With a cap, the grid is laid over the cap alone (about ``n`` points in it).
    """
    if cap is None:
        return CandidateSet(fibonacci_sphere(n), True, None, [], f"free orientations (grid of {n})")
    area_fraction = (1.0 - cap.cos_half_angle) / 2.0
    d, _, _ = _apply_cap(fibonacci_sphere(int(np.ceil(n / max(area_fraction, 1e-6)))), cap, [])
    if cap.half_angle_deg < 180.0:
        # the boundary circle at the grid's spacing: optimal designs in a cap sit on its edge
        spacing = np.sqrt(4.0 * np.pi * area_fraction / max(len(d), 1))
        alpha = np.deg2rad(cap.half_angle_deg)
        d = np.vstack([d, cap.boundary(max(int(np.ceil(2.0 * np.pi * np.sin(alpha) / spacing)), 3))])
    return CandidateSet(d, True, cap, [], f"free orientations {cap.describe()} (grid of {len(d)})")


def turntable_candidates(step_deg: float = 45.0, cap: Cap | None = None) -> CandidateSet:
    """Directions a three-axis turntable reaches with pitch and roll on multiples of ``step_deg``.

    The gimbal convention is Sun 2011's (:func:`optcal.core.rotations.turntable_attitude`); the heading
    (outer, vertical axis) does not move gravity in the body frame.  Each direction keeps the
    first (pitch, roll) pair that reaches it as its label.
    """
    if not 0 < step_deg <= 180 or abs(360.0 / step_deg - round(360.0 / step_deg)) > 1e-9:
        raise InputError(f"the turntable step must divide 360°, not {step_deg:g}°")
    angles = np.deg2rad(np.arange(0.0, 360.0, step_deg))
    pitch, roll = (a.ravel() for a in np.meshgrid(angles, angles, indexing="ij"))
    # Sun 2011, eq. 1: f^b = C_n^b [0, 0, 1]ᵀ, the third row of C_b^n
    # rounded so that exact zeros stay zeros (cos 90° is 6e-17, which would fake information)
    f_b = np.round(turntable_attitude(pitch, roll, np.zeros_like(pitch))[:, 2, :], 12) + 0.0
    _, first = np.unique(f_b, axis=0, return_index=True)
    first = np.sort(first)
    labels = [f"pitch {np.rad2deg(pitch[k]):.0f}°, roll {np.rad2deg(roll[k]):.0f}°" for k in first]
    d, labels, excluded = _apply_cap(f_b[first], cap, labels)
    text = f"turntable, pitch and roll in steps of {step_deg:g}°" + (f", {cap.describe()}" if cap else "")
    return CandidateSet(d, False, cap, labels, text, excluded)


def given_candidates(directions: ArrayLike, cap: Cap | None = None, source: str = "given list") -> CandidateSet:
    """A fixed list of directions to choose from (no refinement off the list)."""
    d, labels, excluded = _apply_cap(user_directions(directions), cap, [])
    return CandidateSet(d, False, cap, labels, f"{source} ({len(d)} directions)", excluded)


def read_orientations(path: str) -> NDArray[np.float64]:
    """Directions from a CSV of orientations: columns dx,dy,dz or qw,qx,qy,qz or roll_deg,pitch_deg."""
    from optcal.data.tables import read_csv_frame

    frame = read_csv_frame(path)
    for kind, cols in (("directions", ["dx", "dy", "dz"]), ("quaternions", ["qw", "qx", "qy", "qz"]),
                       ("euler_deg", ["roll_deg", "pitch_deg"])):
        if all(c in frame.columns for c in cols):
            values = frame[cols].to_numpy(float)
            bad = ~np.all(np.isfinite(values), axis=1)
            if np.any(bad):
                raise InputError(f"{path}: rows {', '.join(str(i + 2) for i in np.flatnonzero(bad)[:5])} are not finite")
            return user_directions(values, kind)
    raise InputError(f"{path}: needs columns dx,dy,dz or qw,qx,qy,qz or roll_deg,pitch_deg")


__all__ = [
    "DEFAULT_GRID",
    "CandidateSet",
    "Cap",
    "fibonacci_sphere",
    "given_candidates",
    "parse_axis",
    "read_orientations",
    "sphere_candidates",
    "turntable_candidates",
]
