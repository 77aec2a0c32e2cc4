"""Allan deviation of the gyro channels of a still log: angle random walk, bias instability, rate random walk.

The gyro's Allan deviation has the same slopes as the accelerometer's (Yin 2014, section
2.2; IEEE Std 952): the −1/2 line at τ = 1 s is the angle random walk ``N`` (rad/√s =
rad/s/√Hz, Kalibr's ``gyroscope_noise_density``), the flat part / 0.664 the bias
instability ``B`` (rad/s), the +1/2 line at τ = 3 s the rate random walk ``K`` (rad/s/√s =
rad/s²/√Hz, Kalibr's ``gyroscope_random_walk``).  The curve and the fit are
:mod:`optcal.families.noise.allan`'s, applied to the gyro samples and scaled to rad/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from optcal.errors import InputError
from optcal.core.units import RAD_PER_UNIT, normalise_gyro_units
from optcal.core.model import AXES
from optcal.families.noise.allan import AllanCurve, NoiseParameters, allan_deviation, fit_noise_parameters

#: SI units of the three gyro noise parameters.
GYRO_SI_UNITS: dict[str, str] = {"angle_random_walk": "rad/s/√Hz", "bias_instability": "rad/s",
                                 "rate_random_walk": "rad/s²/√Hz"}
#: Conventional display: (unit, factor from SI).
GYRO_DISPLAY: dict[str, tuple[str, float]] = {"angle_random_walk": ("°/√h", float(np.degrees(1.0) * 60.0)),
                                              "bias_instability": ("°/h", float(np.degrees(1.0) * 3600.0)),
                                              "rate_random_walk": ("°/h/√h", float(np.degrees(1.0) * 3600.0 * 60.0))}


@dataclass(frozen=True)
class GyroAxisNoise:
    """Noise of one gyro axis, SI units (:data:`GYRO_SI_UNITS`)."""

    angle_random_walk: float
    bias_instability: float
    rate_random_walk: float | None
    bias_instability_is_upper_bound: bool
    notes: tuple[str, ...]


@dataclass
class GyroAllanAnalysis:
    """Allan analysis of the three gyro axes of a still log.

    Attributes
    ----------
    curves : dict of str to AllanCurve
        Per axis, in the input units.
    axes : dict of str to GyroAxisNoise
        Per axis, in rad/s units.
    units : str
        Gyro input units; :attr:`rad_per_unit` converts them.
    rate_hz : float
    n_samples : int
    """

    curves: dict[str, AllanCurve]
    axes: dict[str, GyroAxisNoise]
    units: str
    rad_per_unit: float
    rate_hz: float
    n_samples: int

    def kalibr(self) -> dict[str, float]:
        """Kalibr's ``gyroscope_noise_density`` and ``gyroscope_random_walk`` (the largest axis's)."""
        rrw = [a.rate_random_walk for a in self.axes.values() if a.rate_random_walk is not None]
        return {"gyroscope_noise_density": max(a.angle_random_walk for a in self.axes.values()),
                "gyroscope_random_walk": max(rrw) if rrw else float("nan")}

    def summary(self) -> dict[str, Any]:
        """JSON-safe summary (``optcal allan --sensor gyro --json``)."""
        out: dict[str, Any] = {
            "sensor": "gyro",
            "units": {**GYRO_SI_UNITS, "input": self.units, "rad_s_per_input_unit": self.rad_per_unit},
            "log": {"rate_hz": self.rate_hz, "n_samples": self.n_samples, "duration_s": self.n_samples / self.rate_hz},
            "kalibr": {k: (None if not np.isfinite(v) else v) for k, v in self.kalibr().items()},
        }
        for axis, a in self.axes.items():
            out[axis] = {"angle_random_walk": a.angle_random_walk, "bias_instability": a.bias_instability,
                         "rate_random_walk": a.rate_random_walk,
                         "bias_instability_is_upper_bound": a.bias_instability_is_upper_bound, "notes": list(a.notes)}
        return out

    def report(self) -> str:
        """Readable table in SI and conventional units."""
        lines = [f"Allan deviation of the gyro: {self.n_samples / self.rate_hz:.1f} s still log ({self.n_samples} "
                 f"samples at {self.rate_hz:g} Hz, input in {self.units})"]
        for axis, a in self.axes.items():
            lines.append(f"[{axis}]")
            for name in GYRO_SI_UNITS:
                value = getattr(a, name)
                label = name.replace("_", " ")
                if value is None:
                    lines.append(f"    {label:<20s} not present")
                    continue
                unit, factor = GYRO_DISPLAY[name]
                bound = " (upper bound)" if name == "bias_instability" and a.bias_instability_is_upper_bound else ""
                lines.append(f"    {label:<20s} {value:.4g} {GYRO_SI_UNITS[name]} = {value * factor:.4g} {unit}{bound}")
            lines.extend(f"    note: {n}" for n in a.notes)
        k = self.kalibr()
        lines.append(f"Kalibr: gyroscope_noise_density {k['gyroscope_noise_density']:.4g}, "
                     f"gyroscope_random_walk {k['gyroscope_random_walk']:.4g}")
        return "\n".join(lines)


def _axis(p: NoiseParameters, factor: float) -> GyroAxisNoise:
    s = p.scaled(factor)
    return GyroAxisNoise(s.velocity_random_walk, s.bias_instability, s.rate_random_walk, s.bias_instability_bound,
                         tuple(s.notes))


def analyse_gyro_log(
    samples: ArrayLike, rate_hz: float, units: str, counts_per_rad_s: float | None = None, max_tau_s: float | None = None
) -> GyroAllanAnalysis:
    """Allan deviation and noise parameters of the gyro samples (n, 3) of a still log.

    Parameters
    ----------
    samples : array_like, shape (n, 3)
    rate_hz : float
    units : {"counts", "rad/s", "deg/s"}
    counts_per_rad_s : float, optional
        Scale of counts (required for counts; an IMU calibration's ``K_g``).
    max_tau_s : float, optional
    """
    data = np.asarray(samples, dtype=float)
    if data.ndim != 2 or data.shape[1] != 3:
        raise InputError(f"the gyro log needs three columns (gx, gy, gz), got shape {data.shape}")
    units = normalise_gyro_units(units)
    if units == "counts":
        if counts_per_rad_s is None or not counts_per_rad_s > 0:
            raise InputError("gyro counts need a positive counts-per-rad/s scale to report noise in rad/s "
                             "(counts_per_rad_s; the scale K_g of an IMU calibration)")
        factor = 1.0 / float(counts_per_rad_s)
    else:
        factor = RAD_PER_UNIT[units]
    curves = {axis: allan_deviation(data[:, i], rate_hz, max_tau_s) for i, axis in enumerate(AXES)}
    axes = {axis: _axis(fit_noise_parameters(c), factor) for axis, c in curves.items()}
    return GyroAllanAnalysis(curves, axes, units, factor, float(rate_hz), int(data.shape[0]))
