"""The accelerometer's physical set: where a maximum-likelihood refinement of the convex start may end.

The maximum likelihood (Lu 2017, eq. 13-14) minimises ``Σ (‖T(a − o)‖ − 1)²``, a residual that is a share of the
fitted g.  On poses that cover part of the sphere (a cap) that likelihood keeps falling as the ellipsoid grows along
the poorly covered axis: generated 24-pose caps of 45° and 60° with 5 mg noise end at scale factors of 2.4-11 and a
z offset of −5.9 to −10 g (IPOPT stops at its iteration limit), their rms residual 0.7-1.2 mg below the noise they
were drawn with.  That is not a sensor, so :func:`physical_departure` says why such a refinement is not kept.

The set is stated relative to the convex start (eq. 18-30), the algebraic fit of the same poses, so that it holds in
any units (g, m/s², counts): on poses that determine the calibration both fits differ by the noise's share (mg, a
fraction of a percent), and a real sensor's whole tolerance is smaller than the moves it refuses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.constraints import physical_of_theta

#: A refinement may scale an axis by at most this factor against the convex start's scale factor.  A MEMS
#: accelerometer's sensitivity is within a few percent of its nominal (MPU-6050: initial calibration tolerance ±3 %,
#: PS-MPU-6000A-00 rev. 3.4, section 6.2; ADXL345: 230-282 LSB/g about 256, ±10 %, Analog Devices data sheet,
#: table 1), so the start and a refinement of a real sensor differ by far less; the factor is five times the widest
#: tolerance (a start wrong by the whole tolerance still refines freely) and excludes the runaway above (2.4-11).
#: The magnetometer's refinement uses the same factor on its field strength (optcal.families.mag.refine.FIELD_FACTOR).
SCALE_FACTOR: float = 1.5
#: A refinement may move an offset by at most this many g (in the start's scale) from the convex start's.  A MEMS
#: accelerometer's zero-g offset is within ±50 mg (x, y) and ±80 mg (z) of zero for the MPU-6050 (same section) and
#: ±150 mg (x, y), ±250 mg (z) for the ADXL345 (table 1, 0 g bias level): the whole range of a part is below 0.5 g,
#: so a refinement that moves the offset further than that from its start has slid along the poorly covered axis
#: (the runaway above: 5.9-10 g), not refined a sensor.  Relative to the start, not to zero, so that a sensor whose
#: offset is beyond its datasheet (a damaged part, an unstated range setting) still refines.
OFFSET_MOVE_G: float = 0.5


@dataclass(frozen=True)
class PhysicalDeparture:
    """Why a maximum-likelihood refinement is outside the physical set.

    Attributes
    ----------
    reason : str
        One sentence: which scale factor or offset moved how far from the convex start's.
    scale_ratio : tuple of float
        The refinement's scale factors ``S_x, S_y, S_z`` over the convex start's.
    offset_move_g : tuple of float
        The refinement's offsets minus the start's, in g of the start's scale factors.
    """

    reason: str
    scale_ratio: tuple[float, float, float]
    offset_move_g: tuple[float, float, float]

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary (with the set's limits)."""
        return {"reason": self.reason, "scale_ratio": list(self.scale_ratio), "offset_move_g": list(self.offset_move_g),
                "scale_factor_limit": SCALE_FACTOR, "offset_move_limit_g": OFFSET_MOVE_G}


def physical_departure(theta: NDArray, start: NDArray) -> PhysicalDeparture | None:
    """Whether the refinement ``theta`` left the physical set around its convex ``start`` (both θ in raw units).

    Outside when a scale factor ``S_i`` (Lu 2017, eq. 1: the row norms of ``C = T⁻¹``) is more than
    :data:`SCALE_FACTOR` times or less than its reciprocal times the start's, or when an offset ``o_i`` moved from the
    start's by more than :data:`OFFSET_MOVE_G` in g of the start's scale factor.

    Parameters
    ----------
    theta, start : ndarray, shape (9,)
        θ of the refinement and of its convex start (T lower-triangular, o; raw units).

    Returns
    -------
    PhysicalDeparture or None
        None when inside the set.
    """
    theta, start = np.asarray(theta, dtype=float), np.asarray(start, dtype=float)
    S = np.asarray(physical_of_theta(theta)[:3], dtype=float)
    S0 = np.asarray(physical_of_theta(start)[:3], dtype=float)
    ratio = S / S0
    move = (theta[6:9] - start[6:9]) / S0  # Lu 2017, eq. 2: o in raw units, S raw units per g
    parts = []
    for axis, r in zip("xyz", ratio):
        if not 1.0 / SCALE_FACTOR <= r <= SCALE_FACTOR:
            parts.append(f"its scale factor {axis} is {r:.3g} times the convex start's (beyond a factor {SCALE_FACTOR:g})")
    for axis, d in zip("xyz", move):
        if not abs(d) <= OFFSET_MOVE_G:
            parts.append(f"its offset {axis} moved {d:+.3g} g from the convex start's (beyond {OFFSET_MOVE_G:g} g)")
    if not parts:
        return None
    return PhysicalDeparture("; ".join(parts), (float(ratio[0]), float(ratio[1]), float(ratio[2])),
                             (float(move[0]), float(move[1]), float(move[2])))
