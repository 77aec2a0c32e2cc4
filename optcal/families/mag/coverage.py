"""Which directions of the sphere a magnetometer's calibrated samples reach, what that leaves undetermined, and the
test of a turn in one plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Coverage directions (the cube's 6 faces, 12 edges and 8 corners) and the angular radius within
#: which a calibrated sample covers one: 30° leaves no point of the sphere farther than 30° from
#: a covered direction when all are covered (the largest gap between the 26 directions is 35°).
COVERAGE_CAP_DEG: float = 30.0
#: Coverage is judged on at most this many samples, evenly spaced in time: a turn through a
#: 30° cap at any hand speed leaves hundreds of samples in it at 10⁵ of a session.
COVERAGE_SAMPLES: int = 100_000


def _directions() -> tuple[NDArray[np.float64], list[str]]:
    dirs, names = [], []
    for v in np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij")).reshape(3, -1).T:
        if not v.any():
            continue
        dirs.append(v / np.linalg.norm(v))
        names.append("".join(f"{'+' if c > 0 else '-'}{a}" for c, a in zip(v, "xyz") if c))
    return np.array(dirs), names


COVERAGE_DIRECTIONS, COVERAGE_NAMES = _directions()


@dataclass(frozen=True)
class Coverage:
    """Which directions of the sphere the calibrated samples reach.

    Attributes
    ----------
    covered, missing : tuple of str
        Direction names (``+z``, ``-x+y``, ...) with a sample within :data:`COVERAGE_CAP_DEG`, and without.
    spread : ndarray, shape (3,)
        Eigenvalues of the covariance of the unit directions, ascending (0 along the axis of a planar turn).
    thinnest_axis : ndarray, shape (3,)
        The eigenvector of the smallest eigenvalue.
    nearest_cos : ndarray, shape (26,)
        Per coverage direction, the cosine of the angle to its nearest sample.
    """

    covered: tuple[str, ...]
    missing: tuple[str, ...]
    spread: NDArray[np.float64]
    thinnest_axis: NDArray[np.float64]
    nearest_cos: NDArray[np.float64]

    @property
    def share(self) -> float:
        """Share of the 26 directions covered."""
        return len(self.covered) / len(COVERAGE_NAMES)


def coverage(unit: NDArray[np.float64]) -> Coverage:
    """The :class:`Coverage` of calibrated samples ``unit`` (n, 3), any norm (they are normalised)."""
    stride = max(1, len(unit) // COVERAGE_SAMPLES)
    u = unit[::stride] / np.linalg.norm(unit[::stride], axis=1, keepdims=True)
    cos_cap = np.cos(np.radians(COVERAGE_CAP_DEG))
    best = np.max(u @ COVERAGE_DIRECTIONS.T, axis=0)
    hit = best >= cos_cap
    values, vectors = np.linalg.eigh(np.cov(u.T))
    return Coverage(tuple(n for n, h in zip(COVERAGE_NAMES, hit) if h), tuple(n for n, h in zip(COVERAGE_NAMES, hit) if not h),
                    values, vectors[:, 0], best)


#: A planar turn leaves the direction covariance this small along its axis (a full sphere gives
#: 1/3 on every axis, a turn about one axis with the field at 30° from it 0 along the axis, 0.125
#: and 0.125 across): below 0.01 (a tilt of 8° rms about the plane) the axis is not seen; the raw
#: samples' tilt share (:func:`planar_tilt`) is held to the same.
PLANAR_SPREAD: float = 0.01


def coverage_notes(cov: Coverage) -> list[str]:
    """What the coverage leaves undetermined and the orientations that would fix it."""
    notes = []
    if cov.spread[0] < PLANAR_SPREAD:
        axis = ", ".join(f"{c:+.2f}" for c in cov.thinnest_axis)
        notes.append(f"the samples turn in one plane (direction spread {cov.spread[0]:.2g} along [{axis}]): the "
                     f"ellipsoid's extent along that axis, the field strength and the hard iron along it are not determined; add orientations that tilt that axis "
                     f"towards and away from the field (e.g. roll the sensor 90° and turn it again)")
    if cov.missing:
        notes.append(f"coverage {len(cov.covered)}/{len(COVERAGE_NAMES)} directions; missing: {', '.join(cov.missing)} "
                     f"(point those sensor directions along the field to fill them)")
    return notes


def planar_tilt(m: NDArray[np.float64], misfit: float = np.inf) -> tuple[float, NDArray[np.float64]]:
    """The share of the samples' spread that tilts out of their plane, and that plane's axis (the thinnest).

    A field turned about one axis traces a circle; along the axis the samples hold the field's component and the hard
    iron, which no turn about it tells apart (the sphere fit finds them only from the noise and the misfit).  The
    raw samples' covariance's smallest eigenvalue, less the sensor's noise along that axis, over the whole spread, is
    the tilt's share: a full sphere gives 1/3, a turn tilted by θ rms about the plane θ²/2.  The noise is the smaller
    of two bounds: half the variance of consecutive samples' differences along the axis (by their MAD: a turn about
    the axis moves the samples in the plane), and ``misfit``, a fit's rms distance from its surface (sensor units).
    """
    eig, axes = np.linalg.eigh(np.cov(m.T))
    d = np.diff(m, axis=0) @ axes[:, 0]
    noise2 = (1.4826 * float(np.median(np.abs(d - np.median(d))))) ** 2 / 2.0 if d.size else 0.0
    return max(float(eig[0]) - min(noise2, misfit**2), 0.0) / max(float(np.sum(eig)), 1e-300), axes[:, 0]
