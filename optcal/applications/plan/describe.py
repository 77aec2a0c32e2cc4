"""Human descriptions of orientations: "x up, tilted 35° toward −y".

The direction ``d`` is the specific force in the sensor frame (the reading of a perfect
accelerometer at rest, +1 g along the axis that points up).  The description names the axis
closest to vertical ("x up", "z down" for ``−z`` up), the tilt angle from it and the axis the
tilt leans toward: "x up, tilted 35° toward −y" means start with x pointing up and turn the
device so that −y rises by 35° (``d = cos35°·x̂ − sin35°·ŷ``).  A tilt out of a coordinate plane
is given as two tilts in the two vertical planes through the main axis ("z up, tilted 35° toward
+x and 35° toward +y": ``d ∝ (tan35°, tan35°, 1)``), the larger first.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from optcal.core.model import AXES

#: Tilts (and tilt azimuths) below this many degrees are not mentioned.
NEGLIGIBLE_DEG: float = 0.5


def _signed(axis: int, sign: float) -> str:
    return ("+" if sign > 0 else "−") + AXES[axis]


def describe_direction(direction: ArrayLike) -> str:
    """Description of one unit gravity direction in the sensor frame (module docstring)."""
    d = np.asarray(direction, float).reshape(3)
    d = d / np.linalg.norm(d)
    main = int(np.argmax(np.abs(d)))
    head = f"{AXES[main]} {'up' if d[main] > 0 else 'down'}"
    parts = []
    for other in sorted((i for i in range(3) if i != main), key=lambda i: -abs(d[i])):
        # tilt in the vertical plane of the main axis and this axis
        angle = float(np.rad2deg(np.arctan2(abs(d[other]), abs(d[main]))))
        if angle >= NEGLIGIBLE_DEG:
            parts.append(f"{angle:.0f}° toward {_signed(other, d[other])}")
    return head if not parts else f"{head}, tilted " + " and ".join(parts)


def describe_directions(directions: ArrayLike) -> list[str]:
    """:func:`describe_direction` of each row."""
    return [describe_direction(d) for d in np.asarray(directions, float).reshape(-1, 3)]


__all__ = ["describe_direction", "describe_directions"]
