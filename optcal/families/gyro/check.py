"""A saved IMU calibration on other data: the gravity-prediction residual of its moves, before and after.

The residual "after" is tested against the noise model of DATA's own moves
(:mod:`optcal.families.gyro.consistency`, test 1, with ``2m`` degrees of freedom: nothing was
fitted to DATA), and once more with the bias of DATA's own rests in place of the
calibration's, which tells a bias that changed (another unit, a turn-on change) from a scale
or misalignment that does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.stats import rms
from optcal.core.units import RAD_PER_UNIT
from optcal.families.gyro.consistency import ResidualTest, residual_test
from optcal.families.gyro.moves import moves_from_segmentation
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows

if TYPE_CHECKING:
    from optcal.data.static import Segmentation
    from optcal.families.gyro.result import ImuCalibration


@dataclass(frozen=True)
class GravityCheck:
    """Angle between the gravity direction carried across each move and the one measured next, degrees.

    Attributes
    ----------
    angles_before_deg, angles_after_deg : ndarray, shape (m,)
    before : str
        What "before" means.
    exclusions : dict
        Moves dropped, by reason.
    residual : ResidualTest, optional
        "After" against DATA's noise model.
    residual_own_bias : ResidualTest, optional
        The calibration with the bias of DATA's rests, against the same model.
    """

    angles_before_deg: NDArray[np.float64]
    angles_after_deg: NDArray[np.float64]
    before: str
    exclusions: dict[str, int] = field(default_factory=dict)
    residual: ResidualTest | None = None
    residual_own_bias: ResidualTest | None = None

    @property
    def rms_before_deg(self) -> float:
        return rms(self.angles_before_deg)

    @property
    def rms_after_deg(self) -> float:
        return rms(self.angles_after_deg)

    @property
    def flagged(self) -> bool:
        """"After" beyond the bound of DATA's noise model."""
        return self.residual is not None and self.residual.flagged

    def verdict(self) -> str | None:
        """One line on "after" against DATA's noise model (``None`` without the test).

        Beyond the bound it is flagged; far beyond it (where a fit would be refused) the line says
        the calibration does not fit DATA's gyro and whether DATA's own bias explains the difference.
        """
        if self.residual is None:
            return None
        if not self.residual.flagged:
            return f"gyro: {self.residual.describe()}"
        if not self.residual.far_beyond:
            return f"gyro: flag: after calibration, {self.residual.describe()}"
        line = f"gyro: FLAG: after calibration, {self.residual.describe()}: this calibration does not fit DATA's gyro"
        own = self.residual_own_bias
        if own is not None:
            line += (f"; with the bias of DATA's own rests {own.rms_deg:.3f}° ({own.ratio:.2f}× the bound"
                     + (": scale or misalignment differ too" if own.far_beyond
                        else ": the bias differs, another unit or a bias that changed") + ")")
        return line

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` entries of the test (empty without it)."""
        if self.residual is None:
            return {}
        out: dict[str, Any] = {"test": self.residual.to_dict()}
        if self.residual_own_bias is not None:
            out["test_with_own_bias"] = self.residual_own_bias.to_dict()
        return out


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
    # DATA's own bias: the rests' mean reading, less the calibration's g-sensitivity at each rest
    rest_bias = moves.gyro_means
    G = cal.gyro.g_sensitivity
    if G is not None:
        rest_bias = rest_bias - cal.correct(moves.acc_means) @ G.T
    own_bias = np.average(rest_bias, axis=0, weights=moves.n_static)
    test = residual_test(moves, cal.accelerometer, cal.gyro, after, 0, bias=own_bias)
    own_model = replace(cal.gyro, bias=own_bias)
    f_mid = cal.correct(moves.acc_mid) if G is not None else None
    own_after = angles_deg(predictor(own_model.correct(moves.gyro_mid(), f_mid), moves.dt, u0), u1)
    own_test = residual_test(moves, cal.accelerometer, own_model, own_after, 0, bias=own_bias)
    return GravityCheck(before, after, what, dict(moves.exclusions), test, own_test)
