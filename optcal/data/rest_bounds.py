"""What a rest's readings can be, whatever the noise: the bounds a steady spin breaks (docs/rest-model.md, fifth sweep).

:class:`RestBounds` says which blocks or stretches a rest can give; :class:`optcal.data.rest_tests.RestModel` keeps
the others out of the gyro's bias and :func:`optcal.data.static.detect_static` rejects the stretches that break them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.stats import row_max_abs, row_norms
from optcal.data.quantiles import np_column_medians
from optcal.data.rails import gyro_bias_bound
from optcal.data.recording import Recording
from optcal.data.rest_model import MAX_GYRO_BIAS_RAD_S
from optcal.data.units import PLAUSIBLE_NORM


@dataclass(frozen=True)
class RestBounds:
    """What a rest's readings can be, whatever the noise: the bounds a steady spin breaks.

    At rest the specific force is gravity alone, so |a| is 1 g within the accelerometer's scale and offset errors
    (the range :data:`~optcal.data.units.PLAUSIBLE_NORM` admits for data at rest in g or m/s²; in counts no 1 g is
    stated, and |a| is not bounded), and the gyro reads its bias, at most
    :data:`~optcal.data.rest_model.MAX_GYRO_BIAS_RAD_S` on any axis, taken in the gyro's units as stated, else as
    the most units it can be (:data:`~optcal.data.rest_model.MIN_RAD_S_PER_UNIT`), about its zero (mid-scale for
    unsigned 16-bit counts around it).  A steady spin keeps both sensors still in the sensor's frame; its
    centripetal acceleration and its rate break these bounds, so it can neither pass as a rest nor set the
    gyro's bias that the rests are judged against.  A still stretch is judged by its |a| (a gyro beyond its bound
    everywhere is a unit's or a zero's error, which the bias absorbs); the gyro's bound keeps spinning blocks out of
    the bias.

    Attributes
    ----------
    norm_range : tuple of float or None
        The |a| a rest can read, raw units (None: counts, not bounded).
    gyro_zero : ndarray (3,) or None
        The gyro's zero, its units (None: no gyro, or the gyro not evidence).
    gyro_limit : float
        The largest bias on an axis, the gyro's units (infinite without a gyro).
    gyro_unit : str
        How the gyro's units were taken for the bound.
    """

    norm_range: tuple[float, float] | None
    gyro_zero: NDArray[np.float64] | None
    gyro_limit: float
    gyro_unit: str

    def admits(self, acc: NDArray[np.float64], gyro: NDArray[np.float64] | None) -> NDArray[np.bool_]:
        """Whether each row of ``acc`` (k, 3; less the nominal zero) and ``gyro`` (k, 3) a rest can read."""
        ok = np.ones(acc.shape[0], dtype=bool)
        if self.norm_range is not None:
            norm = row_norms(acc)
            ok &= (norm >= self.norm_range[0]) & (norm <= self.norm_range[1])
        if gyro is not None and self.gyro_zero is not None:
            ok &= row_max_abs(gyro, self.gyro_zero) <= self.gyro_limit
        return ok

    def describe(self, units: str) -> str:
        """The bounds in words."""
        parts = []
        if self.norm_range is not None:
            parts.append(f"|a| outside {self.norm_range[0]:g}-{self.norm_range[1]:g} {units} (at rest |a| = 1 g)")
        if self.gyro_zero is not None:
            parts.append(f"a gyro mean over {self.gyro_limit:.4g} from its zero on an axis (a MEMS gyro's largest "
                         f"bias, {np.degrees(MAX_GYRO_BIAS_RAD_S):g} °/s, units {self.gyro_unit})")
        return " or ".join(parts)


def rest_bounds(rec: Recording, gyro: NDArray[np.float64] | None, gyro_means: NDArray[np.float64] | None,
                keep: bool) -> RestBounds:
    """:class:`RestBounds` of a recording (``keep``: ``--keep-spins``, no bounds)."""
    if keep:
        return RestBounds(None, None, np.inf, "")
    norm_range = PLAUSIBLE_NORM[rec.units] if rec.units in ("g", "m/s^2") else None
    if gyro is None or gyro_means is None or not gyro.size:
        return RestBounds(norm_range, None, np.inf, "")
    zero, limit, unit = gyro_bias_bound(rec.gyro_units, gyro, np_column_medians(gyro_means))
    return RestBounds(norm_range, zero, limit, unit)
