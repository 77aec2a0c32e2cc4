"""The orientations a magnetometer session still needs: the field directions its samples have not reached.

A magnetometer's hard and soft iron are determined by the field seen from every side of the sensor: the calibrated
field's direction in the sensor frame must visit the whole sphere (:func:`optcal.families.mag.fit.coverage`, 26
directions with a cap of :data:`~optcal.families.mag.fit.COVERAGE_CAP_DEG` each).  The plan lists the missing ones,
the largest gap first (greedily: each next direction is the missing one farthest from every sample and every
direction already planned), each as "point the sensor's ``-x+y`` along the field": the local field points north and
dips below the horizontal by the inclination, so with the sensor's axis along it the field is seen from there.
Without a recording, the plan is the 26 directions themselves, faces first.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.families.mag.fit import COVERAGE_CAP_DEG, COVERAGE_DIRECTIONS, COVERAGE_NAMES, Coverage


@dataclass(frozen=True)
class PlannedDirection:
    """One orientation to add: a sensor direction to point along the field.

    Attributes
    ----------
    name : str
        The direction's name (``+z``, ``-x+y``, ``+x-y+z``).
    vector : ndarray (3,)
        Its unit vector in the sensor frame.
    gap_deg : float
        Its angle from the nearest sample (or planned direction) before it is added.
    """

    name: str
    vector: NDArray[np.float64]
    gap_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {"direction": self.name, "vector": self.vector.tolist(), "gap_deg": self.gap_deg}


def plan_coverage(cov: Coverage | None) -> list[PlannedDirection]:
    """The directions :func:`~optcal.families.mag.fit.coverage` found missing, the largest gap first.

    ``None`` (no recording): all 26 directions, faces, then edges, then corners, each with a gap of 180°.
    """
    order = np.argsort([np.count_nonzero(v) for v in np.round(COVERAGE_DIRECTIONS * np.sqrt(3.0), 6)], kind="stable")
    if cov is None:
        return [PlannedDirection(COVERAGE_NAMES[i], COVERAGE_DIRECTIONS[i], 180.0) for i in order]
    # the cosine of each direction's nearest sample, then of its nearest sample or planned direction
    nearest = np.array(cov.nearest_cos, dtype=float)
    cap = np.cos(np.radians(COVERAGE_CAP_DEG))
    out: list[PlannedDirection] = []
    while True:
        missing = np.flatnonzero(nearest < cap)
        if not missing.size:
            return out
        pick = int(missing[np.argmin(nearest[missing])])  # the largest gap
        gap = float(np.degrees(np.arccos(np.clip(nearest[pick], -1.0, 1.0))))
        out.append(PlannedDirection(COVERAGE_NAMES[pick], COVERAGE_DIRECTIONS[pick], gap))
        nearest = np.maximum(nearest, COVERAGE_DIRECTIONS @ COVERAGE_DIRECTIONS[pick])


def plan_lines(planned: list[PlannedDirection], cov: Coverage | None) -> list[str]:
    """The plan in words."""
    lines = []
    if cov is not None:
        lines.append(f"coverage: {len(cov.covered)}/{len(COVERAGE_NAMES)} directions within {COVERAGE_CAP_DEG:g}° "
                     f"of a sample")
    if not planned:
        lines.append("nothing to add: every direction of the sphere has a sample within "
                     f"{COVERAGE_CAP_DEG:g}° of it")
        return lines
    lines.append(f"{len(planned)} orientation(s) to add, the largest gap first: point the sensor axis named along the "
                 "local field (north, dipping below the horizontal by the inclination) and turn slowly about it")
    for i, p in enumerate(planned, 1):
        lines.append(f"{i:>3}. {p.name:<8} [{p.vector[0]:+.3f} {p.vector[1]:+.3f} {p.vector[2]:+.3f}]"
                     + (f"  (nearest sample {p.gap_deg:.0f}° away)" if p.gap_deg < 180.0 else ""))
    return lines
