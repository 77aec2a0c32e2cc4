"""Simulated data with the extensions of :class:`~optcal.core.extended_model.ExtendedModel` hidden in them.

The companion of :mod:`optcal.families.simulate.poses` (the paper's model) for the extended model: pose tables
(:func:`simulate_extended`), a raw recording distorted sample by sample
(:func:`distort_recording`), a sensor warming up and cooling down (:func:`warmup_cooldown`),
and the measured-like raw recordings of ``optcal demo`` and the diagnosis tests with one hidden
effect whose truth is returned separately (:func:`recording_with_effect`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.extended_model import PARAMETRIC, ExtendedModel, axis_number, format_value
from optcal.core.model import AXES, LumpedModel
from optcal.core.poses import PoseTable
from optcal.families.simulate.kinematics import gauss_markov, white_noise

#: What :func:`recording_with_effect` can hide: every term of the extended model, or outlier poses.
HIDDEN_EFFECTS: tuple[str, ...] = (*PARAMETRIC, "outliers")

def simulate_extended(
    model: ExtendedModel,
    directions: ArrayLike,
    sigma: float | ArrayLike,
    *,
    temp: ArrayLike | None = None,
    t: ArrayLike | None = None,
    rng: np.random.Generator | int | None = None,
    units: str = "g",
    record_sigma: bool = True,
) -> PoseTable:
    """A pose table from the extended model with white noise per pose (raw units, per axis)."""
    rng = np.random.default_rng(rng)
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = len(d)
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (n,)).copy()
    acc = model.measure(d, temp, t) + rng.standard_normal((n, 3)) * sig[:, None]
    return PoseTable(
        acc=acc,
        sigma=sig if record_sigma and np.all(sig > 0) else None,
        t=None if t is None else np.asarray(t, float),
        temp=None if temp is None else np.asarray(temp, float),
        units=units,
        source="simulation",
        extra={"true_dx": d[:, 0], "true_dy": d[:, 1], "true_dz": d[:, 2]},
    )


def distort_recording(frame: Any, model: ExtendedModel) -> Any:
    """Apply the extensions of ``model`` to a raw recording made with ``model.base``.

    ``frame`` is a pandas DataFrame with ``ax, ay, az`` (and ``t``, ``temp`` as the model
    needs), e.g. :attr:`optcal.families.simulate.recording.SyntheticRecording.frame` made with the same
    base model; each sample's linear output ``a − o`` (noise included) passes through the
    extended model.  Returns a new frame.
    """
    out = frame.copy()
    acc = out[["ax", "ay", "az"]].to_numpy(dtype=float)
    temp = out["temp"].to_numpy(dtype=float) if "temp" in out else None
    t = out["t"].to_numpy(dtype=float) if "t" in out else None
    new = model.distort(acc - model.base.o, temp, t)
    out["ax"], out["ay"], out["az"] = new[:, 0], new[:, 1], new[:, 2]
    return out

#: Size of each effect in :func:`recording_with_effect` when none is given (first-order coefficient;
#: for ``bias_drift`` the drift over the whole recording in g; for ``outliers`` the number of poses).
DEMO_MAGNITUDE: dict[str, float] = {
    "temperature_bias": 0.8e-3,
    "temperature_scale": 400e-6,
    "bias_drift": 5e-3,
    "scale_nonlinearity": 6e-3,
    "outliers": 4,
}


def demo_sensor() -> LumpedModel:
    """A 16-bit MEMS accelerometer in counts (±2 g, about 16,400 counts per g; cf. the MPU-6050 data)."""
    return LumpedModel.from_physical(
        scale=[16300.0, 16450.0, 16700.0],
        rho=np.deg2rad(0.3),
        phi=np.deg2rad(-0.2),
        lam=np.deg2rad(0.4),
        bias=[700.0, -360.0, -1830.0],
    )


def warmup_cooldown(t: ArrayLike, start_c: float = 22.0, peak_c: float = 38.0, end_c: float = 27.0) -> NDArray[np.float64]:
    """A sensor warming up (first 55 % of the time) and cooling down again, °C at times ``t``."""
    t = np.asarray(t, dtype=float)
    u = (t - t.min()) / max(float(np.ptp(t)), 1e-12)
    knee = 0.55
    rise = start_c + (peak_c - start_c) * (1 - np.exp(-u / 0.15)) / (1 - np.exp(-knee / 0.15))
    at_knee = start_c + (peak_c - start_c)
    fall = end_c + (at_knee - end_c) * np.exp(-(u - knee) / 0.12)
    return np.where(u <= knee, rise, fall)


@dataclass
class HiddenEffect:
    """The truth of :func:`recording_with_effect` (for the check at the end, never for the fit).

    Attributes
    ----------
    effect : str
    axis : str or None
        ``None`` for outliers.
    value : float or None
        First-order coefficient (units of :class:`~optcal.core.extended_model.ExtendedModel`) (``None`` for outliers).
    corrupt_times : list of (float, float)
        For outliers: the time span of each corrupted dwell.
    corrupt_radial_g : list of float
        For outliers: the part of each shift along the pose's direction, g (the only part a
        static calibration can see: a sideways shift changes the direction, not the magnitude).
    model : ExtendedModel
        The true sensor.
    """

    effect: str
    axis: str | None
    value: float | None
    corrupt_times: list[tuple[float, float]]
    model: ExtendedModel
    corrupt_radial_g: list[float] = field(default_factory=list)

    def describe(self) -> str:
        if self.effect == "none":
            return "no effect"
        if self.effect == "outliers":
            return f"outliers: {len(self.corrupt_times)} poses shifted by 15-40 mg while the sensor rested"
        if self.value is None:  # impossible: recording_with_effect gives every parametric effect its value
            raise AssertionError(f"the hidden effect {self.effect!r} has no value")
        return f"{self.effect} on axis {self.axis}: {format_value(self.effect, float(self.value))}"

    def corrupt_rows(self, poses: PoseTable) -> list[int]:
        """Rows of the poses (static intervals) whose time falls in a corrupted dwell."""
        if poses.t is None:
            return []
        return [int(r) for r, t in zip(poses.rows, poses.t) if any(a <= t <= b for a, b in self.corrupt_times)]


def recording_with_effect(
    effect: str | None,
    axis: str | None = None,
    value: float | None = None,
    *,
    n_poses: int = 48,
    dwell_s: float = 4.0,
    transition_s: float = 2.0,
    rate_hz: float = 100.0,
    noise_g: float = 0.004,
    gauss_markov_g: float = 0.0,
    correlation_s: float = 4.0,
    seed: int | None = 0,
) -> tuple[Any, HiddenEffect]:
    """A measured-like raw recording (counts, 100 Hz, warm-up then cool-down) with one hidden effect.

    The sensor (:func:`demo_sensor`) is set down in ``n_poses`` random orientations
    (:func:`optcal.families.simulate.recording.synthesize_recording`: rest, smooth turns, a gyro), its
    temperature follows :func:`warmup_cooldown`, the effect is applied to every sample through
    :class:`ExtendedModel`, and the output is rounded to integer counts.

    Parameters
    ----------
    effect : str or None
        One of :data:`HIDDEN_EFFECTS`, or ``None`` for none (a clean recording).
    axis : {"x", "y", "z"}, optional
        Axis of the effect (drawn at random when omitted; ignored for outliers).
    value : float, optional
        First-order coefficient (units of :class:`~optcal.core.extended_model.ExtendedModel`); for ``bias_drift`` the default is
        :data:`DEMO_MAGNITUDE` spread over the recording; for ``outliers`` the number of poses.
    noise_g : float
        White noise per sample and axis, g.
    gauss_markov_g, correlation_s : float
        A first-order Gauss–Markov noise added to every axis
        (:func:`optcal.families.simulate.kinematics.gauss_markov`): its standard
        deviation (g) and correlation time (s).  At the time scale of a pose it does not average
        down like white noise, so the pose means scatter more than ``σ/√n`` says.
    seed : int, optional

    Returns
    -------
    frame : pandas.DataFrame
        ``t, ax, ay, az, gx, gy, gz, temp``.
    truth : HiddenEffect
    """
    from optcal.families.simulate.recording import synthesize_recording
    from optcal.families.simulate.poses import uniform_directions

    if effect is not None and effect not in HIDDEN_EFFECTS:
        raise InputError(f"unknown effect {effect!r}; choose from {', '.join(HIDDEN_EFFECTS)}")
    rng = np.random.default_rng(seed)
    base = demo_sensor()
    S = np.linalg.norm(base.C, axis=1)
    directions = uniform_directions(n_poses, rng)
    rec = synthesize_recording(
        base, directions, rate_hz=rate_hz, dwell_s=dwell_s, transition_s=transition_s,
        sigma=float(noise_g * S.mean()), units="counts", rng=rng,
    )
    frame = rec.frame.copy()
    t = frame["t"].to_numpy()
    frame["temp"] = warmup_cooldown(t) + white_noise(rng, 0.05, len(t))
    if gauss_markov_g > 0:
        coloured = gauss_markov((len(t), 3), 1.0 / rate_hz, gauss_markov_g, correlation_s, rng)
        for i, c in enumerate(("ax", "ay", "az")):
            frame[c] = frame[c].to_numpy() + S[i] * coloured[:, i]
    axis_name = AXES[int(rng.integers(3))] if axis is None else AXES[axis_number(axis)]
    corrupt: list[tuple[float, float]] = []
    if effect is None:
        truth = HiddenEffect("none", None, None, [], ExtendedModel(base, temp_ref=30.0, t_ref=float(t.mean())))
    elif effect == "outliers":
        count = int(value if value is not None else DEMO_MAGNITUDE["outliers"])
        model = ExtendedModel(base, temp_ref=30.0, t_ref=float(t.mean()))
        acc = frame[["ax", "ay", "az"]].to_numpy(dtype=float, copy=True)
        radial: list[float] = []
        for k in sorted(rng.choice(len(rec.dwells), size=min(count, len(rec.dwells)), replace=False)):
            a, b = rec.dwells[k]
            shift = rng.standard_normal(3)
            shift *= rng.uniform(0.015, 0.040) / np.linalg.norm(shift)  # g
            acc[a:b] += S * shift
            corrupt.append((float(t[a]), float(t[b - 1])))
            radial.append(float(shift @ rec.directions[k]))
        frame["ax"], frame["ay"], frame["az"] = acc[:, 0], acc[:, 1], acc[:, 2]
        truth = HiddenEffect(effect, None, None, corrupt, model, radial)
    else:
        if value is None:
            value = DEMO_MAGNITUDE[effect] / (np.ptp(t) if effect == "bias_drift" else 1.0)
        model = ExtendedModel.with_effect(base, effect, axis_name, float(value), temp_ref=30.0, t_ref=float(t.mean()))
        frame = distort_recording(frame, model)
        truth = HiddenEffect(effect, axis_name, float(value), [], model)
    for c in ("ax", "ay", "az"):
        frame[c] = np.round(frame[c].to_numpy())
    return frame, truth

