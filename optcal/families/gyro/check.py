"""A saved IMU calibration on other data: the gravity-prediction residual of its moves, before and after."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.families.gyro.moves import moves_from_segmentation
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows
from optcal.core.stats import rms
from optcal.core.units import RAD_PER_UNIT

if TYPE_CHECKING:
    from optcal.data.static import Segmentation
    from optcal.families.gyro.result import ImuCalibration


@dataclass(frozen=True)
class GravityCheck:
    """Angle between the gravity direction carried across each move and the one measured next, degrees."""

    angles_before_deg: NDArray[np.float64]
    angles_after_deg: NDArray[np.float64]
    before: str
    exclusions: dict[str, int] = field(default_factory=dict)

    @property
    def rms_before_deg(self) -> float:
        return rms(self.angles_before_deg)

    @property
    def rms_after_deg(self) -> float:
        return rms(self.angles_after_deg)


def gravity_prediction_check(cal: "ImuCalibration", seg: "Segmentation") -> GravityCheck:
    """Evaluate ``cal`` on the moves of a segmented recording (the gravity directions from ``cal``'s accelerometer).

    "Before" removes the bias measured in DATA's own still intervals and applies the nominal
    scale of the gyro units (for counts, the mean scale of ``cal``), no misalignment.
    """
    moves = moves_from_segmentation(seg)
    u = unit_rows(cal.correct(moves.acc_means))
    u0, u1 = u[moves.move_from], u[moves.move_to]
    predictor = GravityPredictor(moves.first_step, moves.last_step)
    after = angles_deg(predictor(cal.correct_gyro(moves.gyro_mid(), moves.acc_mid), moves.dt, u0), u1)
    nominal = RAD_PER_UNIT.get(cal.gyro_units)
    scale = nominal if nominal is not None else float(np.mean(1.0 / cal.gyro.physical().scale))
    w = moves.gyro_mid() - np.average(moves.gyro_means, axis=0, weights=moves.n_static)
    before = angles_deg(predictor(w * scale, moves.dt, u0), u1)
    what = (f"bias of DATA's still intervals removed, nominal {cal.gyro_units} scale" if nominal is not None
            else f"bias of DATA's still intervals removed, one scale {scale:.6g} rad/s per count")
    return GravityCheck(before, after, what, dict(moves.exclusions))
