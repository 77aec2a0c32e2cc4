"""Human descriptions of orientations: "x up, tilted 35° toward −y".

The direction ``d`` is the specific force in the sensor frame (the reading of a perfect
accelerometer at rest, +1 g along the axis that points up).  The description names the axis
closest to vertical ("x up", "z down" for ``−z`` up), the tilt angle from it and the axis the
tilt leans toward: "x up, tilted 35° toward −y" means start with x pointing up and turn the
device so that −y rises by 35° (``d = cos35°·x̂ − sin35°·ŷ``).  A tilt toward a diagonal names
both axes with the angle from the first ("toward +y, 20° toward +z").
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from optcal.model import AXES

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
    tilt = float(np.rad2deg(np.arccos(np.clip(abs(d[main]), -1.0, 1.0))))
    if tilt < NEGLIGIBLE_DEG:
        return head
    others = [i for i in range(3) if i != main]
    lean = d[others]
    first = int(np.argmax(np.abs(lean)))
    second = 1 - first
    toward = _signed(others[first], lean[first])
    azimuth = float(np.rad2deg(np.arctan2(abs(lean[second]), abs(lean[first]))))
    text = f"{head}, tilted {tilt:.0f}° toward {toward}"
    if azimuth >= NEGLIGIBLE_DEG:
        text += f", {azimuth:.0f}° toward {_signed(others[second], lean[second])}"
    return text


def describe_directions(directions: ArrayLike) -> list[str]:
    """:func:`describe_direction` of each row."""
    return [describe_direction(d) for d in np.asarray(directions, float).reshape(-1, 3)]


__all__ = ["describe_direction", "describe_directions"]
