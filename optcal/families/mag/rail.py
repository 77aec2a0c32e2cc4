"""A magnetometer's saturation rail: the samples with an axis held at its converter's full scale, found as the
accelerometer's and the gyroscope's are, and the line that says them (:func:`~optcal.families.mag.samples.read_mag`
leaves them out)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.families.mag.units import EARTH_FIELD_UT, UT_PER_UNIT

#: The exclusion key of the samples at a rail.
MAG_RAIL_ROWS = "magnetometer samples with an axis at its converter's rail (the field beyond its full scale)"
#: A magnetometer's rail lies at least this far from its zero, µT: twice the Earth's strongest field (65 µT,
#: :data:`~optcal.families.mag.units.EARTH_FIELD_UT`), so that the extreme of a field seen through a hard-iron offset
#: as large as the field itself, read twice by a coarse converter, is never taken for one.  A converter whose full
#: scale is nearer (an HMC5883L at its ±0.88 G range) has its rail found only where it is an integer one.
MAG_RAIL_MIN_UT: float = 2 * EARTH_FIELD_UT[1]


def mag_rail(m: NDArray, usable: NDArray[np.bool_], units: str) -> tuple[NDArray[np.bool_], list[float]]:
    """Samples with an axis at a saturation rail (:func:`optcal.data.rails.rail_samples`, the accelerometer's model:
    an extreme reached exactly by several samples, the same magnitude on any axis), at least
    :data:`MAG_RAIL_MIN_UT` from the zero on the extreme's side; in counts only a 16-bit converter's full scale (the
    unit unknown, no distance can be stated).

    A turning magnetometer's field passes its extreme slowly (a 0.5-G component turning at 1 rad/s, read at 256 Hz
    in steps of 1/2048 G, stays within one step of its top for about 23 samples), so an extreme read by several
    equal samples is a rail only where it is held longer than a smooth peak of its flanks' curvature holds: the
    gyro's test (:data:`~optcal.data.rails.GYRO_RAIL_MIN_RUN`, ``rails._held_beyond_a_peak``)."""
    from optcal.data.rails import GYRO_RAIL_MIN_RUN, rail_samples

    per_ut = UT_PER_UNIT.get(units)
    distance = MAG_RAIL_MIN_UT / per_ut if per_ut else float("inf")
    levels: list[float] = []
    rail = rail_samples(np.asarray(m, dtype=float), usable, (0.0, 0.0, 0.0), distance, min_run=GYRO_RAIL_MIN_RUN,
                        levels=levels, outward=True)
    return rail, sorted(levels)


#: A magnetometer's range is chosen so that the field and the board's hard iron fit in it as the sensor turns:
#: samples left beside a rail whose largest axis reads beyond this share of the rail (median over the samples) sit
#: nearer the full scale than the zero, so their magnitude says nothing of the unit (the unit's note is left out)
#: and the rail's line says what such a reading is.
MAG_NEAR_RAIL_SHARE: float = 0.5


def rail_line(levels: list[float], units: str, n_rail: int, n: int) -> str:
    """The one line that says the rail: its level(s), the samples held there, and the flag that keeps them."""
    at = ", ".join(f"±{v:.7g}" for v in levels) or "a 16-bit converter's full scale"
    return (f"magnetometer rail: {n_rail} of {n} samples ({100 * n_rail / max(n, 1):.3g} %) hold an axis at {at} "
            f"{units}, the converter's full scale (the field beyond it unknown): left out; --accept-mag-fit "
            f"keeps them")
