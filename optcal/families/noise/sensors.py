"""The sensors of the Allan analysis: what the accelerometer's and the gyroscope's names, units and raw-count scales are.

The Allan deviation and its fit (:mod:`optcal.families.noise.allan`) are the same for both
sensors; IEEE Std 952 names the −1/2-slope coefficient N after what the white noise integrates
to: the velocity random walk of an accelerometer, the angle random walk of a gyroscope.  The
bias instability and the rate random walk keep their names.  :class:`NoiseSensor` holds the
names, the SI and conventional units of the three coefficients, the conversion of the input
units (raw counts included) to SI, and the layout of the ``optcal allan --json`` summary.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from optcal.errors import InputError
from optcal.core.model import STANDARD_GRAVITY
from optcal.core.units import RAD_PER_UNIT, normalise_units


@dataclass(frozen=True)
class NoiseSensor:
    """What differs between the Allan analyses of the accelerometer and of the gyroscope.

    The curve and the fit are the same for both sensors; this names the coefficients, gives
    their units and converts the input units (raw counts included) to SI.

    Attributes
    ----------
    name : str
        ``"acc"`` or ``"gyro"`` (the value of ``optcal allan --sensor``).
    noise_density_name : str
        Name of the −1/2-slope coefficient N in the summary and report: ``velocity_random_walk``
        (accelerometer) or ``angle_random_walk`` (gyroscope), IEEE Std 952's names.
    canonical_units : callable
        Maps a spelling of the input units to ``"counts"`` or a key of
        :attr:`si_per_physical_unit`; raises :class:`~optcal.errors.InputError` on an unknown one.
    si_per_physical_unit : dict of str to float
        SI units (m/s², rad/s) per physical input unit.
    counts_scale_unit : str
        The physical unit raw counts are scaled to (``counts_per_unit`` counts per g, per rad/s).
    counts_scale_missing : str
        The refusal when counts come without that scale (how to give it).
    si_units : dict of str to str
        SI units of N, bias instability and rate random walk, keyed by their summary names.
    display_units : dict of str to list of (str, float)
        Conventional report units of each coefficient and the factor from its SI unit.
    legend_units : dict of str to tuple of str
        Which of :attr:`display_units` a figure's legend shows (the legend has less room than the report).
    summary_scale_key : str
        Key of the SI-per-input-unit factor in the summary's ``units``.
    summary_tag : str or None
        Value of the summary's ``sensor`` key; None for the accelerometer, whose summary carries
        no tag (a result without one is the accelerometer's).
    kalibr_keys : tuple of (str, str) or None
        Kalibr's names of N and K, given in the summary's ``kalibr`` entry (the largest axis's);
        None for the accelerometer, whose Kalibr keys the export writes from the axes.
    bound_flag_beside_values : bool
        Whether each axis of the summary also gives ``bias_instability_is_upper_bound`` beside
        the values (the gyroscope's layout), not only in ``ci``.
    """

    name: str
    noise_density_name: str
    canonical_units: Callable[[str], str]
    si_per_physical_unit: dict[str, float]
    counts_scale_unit: str
    counts_scale_missing: str
    si_units: dict[str, str]
    display_units: dict[str, list[tuple[str, float]]]
    legend_units: dict[str, tuple[str, ...]]
    summary_scale_key: str
    summary_tag: str | None
    kalibr_keys: tuple[str, str] | None
    bound_flag_beside_values: bool

    def summary_name(self, parameter: str) -> str:
        """The summary's name of a coefficient of :data:`PARAMETERS` (N takes the sensor's name)."""
        return self.noise_density_name if parameter == "noise_density" else parameter

    def abbreviation(self, parameter: str) -> str:
        """Initials of a coefficient's summary name: VRW or ARW, BI, RRW."""
        return "".join(word[0] for word in self.summary_name(parameter).split("_")).upper()

    def si_per_unit(self, units: str, counts_per_unit: float | None = None) -> float:
        """SI units (m/s² or rad/s) per input unit.

        Parameters
        ----------
        units : str
            Input units (accelerometer: g, m/s^2, counts; gyroscope: rad/s, deg/s, counts).
        counts_per_unit : float, optional
            Required for ``counts``: counts per :attr:`counts_scale_unit` (e.g. 16384 per g for an
            MPU-6050 at ±2 g; the scale K_g of an IMU calibration per rad/s).

        Raises
        ------
        InputError
            On unknown units, or counts without a positive finite scale.
        """
        units = self.canonical_units(units)
        if units != "counts":
            return self.si_per_physical_unit[units]
        if counts_per_unit is None or not np.isfinite(counts_per_unit) or counts_per_unit <= 0:
            raise InputError(self.counts_scale_missing)
        return self.si_per_physical_unit[self.counts_scale_unit] / float(counts_per_unit)


_DEGREES_PER_RAD: float = float(np.degrees(1.0))

#: The accelerometer: velocity random walk (m/s/√s), bias instability (m/s²), rate random walk (m/s²/√s).
ACCELEROMETER = NoiseSensor(
    name="acc",
    noise_density_name="velocity_random_walk",
    canonical_units=partial(normalise_units, sensor="accelerometer"),
    si_per_physical_unit={"m/s^2": 1.0, "g": STANDARD_GRAVITY},
    counts_scale_unit="g",
    counts_scale_missing=("raw counts need a positive counts-per-g scale to report noise in physical units "
                          "(--counts-per-g; 16384 for an MPU-6050 at ±2 g)"),
    si_units={"velocity_random_walk": "m/s/√s", "bias_instability": "m/s^2", "rate_random_walk": "m/s^2/√s"},
    display_units={
        "velocity_random_walk": [("m/s/√h", 60.0), ("µg/√Hz", 1e6 / STANDARD_GRAVITY)],
        "bias_instability": [("µg", 1e6 / STANDARD_GRAVITY), ("mg", 1e3 / STANDARD_GRAVITY)],
        "rate_random_walk": [("m/s/h^1.5", 3600.0**1.5), ("µg/√s", 1e6 / STANDARD_GRAVITY)],
    },
    legend_units={"velocity_random_walk": ("m/s/√h", "µg/√Hz"), "bias_instability": ("µg",),
                  "rate_random_walk": ("µg/√s",)},
    summary_scale_key="si_per_input_unit",
    summary_tag=None,
    kalibr_keys=None,
    bound_flag_beside_values=False,
)
#: The gyroscope: angle random walk (rad/s/√Hz, Kalibr's ``gyroscope_noise_density``), bias
#: instability (rad/s), rate random walk (rad/s²/√Hz, Kalibr's ``gyroscope_random_walk``).
GYROSCOPE = NoiseSensor(
    name="gyro",
    noise_density_name="angle_random_walk",
    canonical_units=partial(normalise_units, sensor="gyro"),
    si_per_physical_unit=RAD_PER_UNIT,
    counts_scale_unit="rad/s",
    counts_scale_missing=("gyro counts need a positive counts-per-rad/s scale to report noise in rad/s "
                          "(counts_per_rad_s; the scale K_g of an IMU calibration)"),
    si_units={"angle_random_walk": "rad/s/√Hz", "bias_instability": "rad/s", "rate_random_walk": "rad/s²/√Hz"},
    display_units={
        "angle_random_walk": [("°/√h", _DEGREES_PER_RAD * 60.0)],
        "bias_instability": [("°/h", _DEGREES_PER_RAD * 3600.0)],
        "rate_random_walk": [("°/h/√h", _DEGREES_PER_RAD * 3600.0 * 60.0)],
    },
    legend_units={"angle_random_walk": ("°/√h",), "bias_instability": ("°/h",), "rate_random_walk": ("°/h/√h",)},
    summary_scale_key="rad_s_per_input_unit",
    summary_tag="gyro",
    kalibr_keys=("gyroscope_noise_density", "gyroscope_random_walk"),
    bound_flag_beside_values=True,
)
#: The sensors by :attr:`NoiseSensor.name`.
SENSORS: dict[str, NoiseSensor] = {s.name: s for s in (ACCELEROMETER, GYROSCOPE)}
