"""Allan analysis of a three-axis static log of either sensor: every axis's curve and noise parameters, summary, report, figure.

The curve and the fit are :mod:`optcal.families.noise.allan`'s (Yin 2014, section 2.2; IEEE Std
952); the sensor (:mod:`optcal.families.noise.sensors`) names the coefficients and converts the
input units to SI.  ``optcal allan --json`` prints :meth:`AllanAnalysis.summary`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from optcal.errors import InputError
from optcal.core.model import AXES
from optcal.families.noise.allan import (
    FLICKER_FACTOR,
    NOISE_DENSITY_TAU_S,
    PARAMETERS,
    AllanCurve,
    NoiseParameters,
    allan_deviation,
    fit_noise_parameters,
    rate_random_walk_bound,
    rate_random_walk_confidence_bound,
)
from optcal.families.noise.sensors import ACCELEROMETER, NoiseSensor

if TYPE_CHECKING:
    from matplotlib.figure import Figure


# --------------------------------------------------------------------------- whole-log analysis
@dataclass
class AllanAnalysis:
    """Allan analysis of a three-axis static log of one sensor.

    Attributes
    ----------
    curves, parameters : dict
        Per axis (``x``, ``y``, ``z``): :class:`AllanCurve` and :class:`NoiseParameters`,
        both in the input units.
    units : str
        Input units (accelerometer: ``g``, ``m/s^2`` or ``counts``; gyroscope: ``rad/s``,
        ``deg/s`` or ``counts``).
    si_per_unit : float
        SI units (m/s² or rad/s) per input unit.
    rate_hz : float
    n_samples : int
    sensor : NoiseSensor
        Names and units of the coefficients (:data:`ACCELEROMETER` or :data:`GYROSCOPE`).
    """

    curves: dict[str, AllanCurve]
    parameters: dict[str, NoiseParameters]
    units: str
    si_per_unit: float
    rate_hz: float
    n_samples: int
    sensor: NoiseSensor = ACCELEROMETER

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.rate_hz

    def si_parameters(self) -> dict[str, NoiseParameters]:
        """The parameters converted to SI (the units of :attr:`NoiseSensor.si_units`)."""
        return {axis: p.scaled(self.si_per_unit) for axis, p in self.parameters.items()}

    def kalibr(self) -> dict[str, float]:
        """Kalibr's noise density and random walk (:attr:`NoiseSensor.kalibr_keys`), SI.

        The largest axis's N, and the largest rate random walk the log shows (NaN when no axis
        shows one); empty for a sensor without Kalibr keys in its summary.
        """
        if self.sensor.kalibr_keys is None:
            return {}
        si = self.si_parameters().values()
        walks = [p.rate_random_walk for p in si if p.rate_random_walk is not None]
        density_key, walk_key = self.sensor.kalibr_keys
        return {density_key: max(p.noise_density for p in si), walk_key: max(walks) if walks else float("nan")}

    def summary(self) -> dict[str, Any]:
        """JSON-safe summary in SI units (what ``optcal allan --json`` prints).

        One object ``{"units": {...}, "log": {...}, "x": {...}, "y": {...}, "z": {...}}`` (the
        gyroscope's also ``"sensor": "gyro"`` and ``"kalibr"``, :meth:`kalibr`); each axis has the
        noise density (:attr:`NoiseSensor.noise_density_name`), ``bias_instability``,
        ``rate_random_walk`` (or None), ``ci`` and ``notes``; ``log`` gives the rate, sample count
        and duration.  Two figures bound the rate random walk whether or not the log shows it
        (every term of σ²(τ) is non-negative, so K²τ/3 ≤ σ²(τ) at every τ):
        ``rate_random_walk_largest_consistent`` (with ``..._tau_s``) is ``min_τ σ̂(τ)·√(3/τ)``, the
        largest K the *measured* curve allows (a point value, not a confidence bound), and
        ``rate_random_walk_bound`` the one-sided 95 % confidence bound from the upper confidence
        limit of σ(τ) at the longest τ (:func:`~optcal.families.noise.allan.rate_random_walk_confidence_bound`).
        """
        sensor = self.sensor
        out: dict[str, Any] = {} if sensor.summary_tag is None else {"sensor": sensor.summary_tag}
        out["units"] = {**sensor.si_units, "input": self.units, sensor.summary_scale_key: self.si_per_unit}
        out["log"] = {"rate_hz": self.rate_hz, "n_samples": self.n_samples, "duration_s": self.duration_s}
        if sensor.kalibr_keys is not None:
            out["kalibr"] = {k: (v if np.isfinite(v) else None) for k, v in self.kalibr().items()}
        for axis, p in self.si_parameters().items():
            curve = self.curves[axis]
            k_largest, at_tau = rate_random_walk_bound(curve.taus, curve.adev)  # K²τ/3 ≤ σ²(τ) (Yin 2014, Table 1)
            entry: dict[str, Any] = {
                sensor.noise_density_name: p.noise_density,
                "bias_instability": p.bias_instability,
                "rate_random_walk": p.rate_random_walk,
                "rate_random_walk_largest_consistent": k_largest * self.si_per_unit,
                "rate_random_walk_largest_consistent_tau_s": at_tau,
                "rate_random_walk_bound": rate_random_walk_confidence_bound(curve).to_dict(self.si_per_unit),
            }
            if sensor.bound_flag_beside_values:
                entry["bias_instability_is_upper_bound"] = p.bias_instability_bound
            entry["ci"] = {sensor.summary_name(k): v for k, v in p.ci.items()}
            entry["ci"]["bias_instability_is_upper_bound"] = p.bias_instability_bound
            entry["notes"] = p.notes
            out[axis] = entry
        return out

    def report(self) -> str:
        """Readable table of the parameters in SI and conventional units."""
        sensor = self.sensor
        lines = [
            f"Allan deviation of a {self.duration_s:.1f} s static log ({self.n_samples} samples at "
            f"{self.rate_hz:g} Hz, input in {self.units})",
        ]
        for axis, p in self.si_parameters().items():
            lines.append(f"[{axis}]")
            for parameter in PARAMETERS:
                value, name = getattr(p, parameter), sensor.summary_name(parameter)
                label = name.replace("_", " ")
                if value is None:
                    k_bound = rate_random_walk_confidence_bound(self.curves[axis])
                    k_up = k_bound.value * self.si_per_unit
                    lines.append(f"    {label:<22s} not present; K <= {k_up:.4g} {sensor.si_units[name]} at "
                                 f"{k_bound.confidence:.0%} confidence (sigma's upper limit at tau = {k_bound.tau_s:.4g} s)")
                    continue
                shown = ", ".join(f"{value * f:.4g} {u}" for u, f in sensor.display_units[name])
                bound = " (upper bound)" if parameter == "bias_instability" and p.bias_instability_bound else ""
                lines.append(f"    {label:<22s} {value:.4g} {sensor.si_units[name]} = {shown}{bound}")
            lines.extend(f"    note: {n}" for n in p.notes)
        if sensor.kalibr_keys is not None:
            lines.append("Kalibr: " + ", ".join(f"{k} {v:.4g}" if np.isfinite(v) else f"{k} not present"
                                             for k, v in self.kalibr().items()))
        return "\n".join(lines)


def analyse_static_log(
    samples: ArrayLike,
    rate_hz: float,
    units: str,
    counts_per_unit: float | None = None,
    max_tau_s: float | None = None,
    sensor: NoiseSensor = ACCELEROMETER,
) -> AllanAnalysis:
    """Allan deviation and noise parameters of every axis of a static log of one sensor.

    Parameters
    ----------
    samples : array_like, shape (n, 3)
        Static samples, one column per axis, in ``units``.
    rate_hz : float
        Sample rate.
    units : str
        Input units (:meth:`NoiseSensor.si_per_unit`).
    counts_per_unit : float, optional
        Scale of ``counts`` (required for counts): counts per g for the accelerometer, per rad/s
        for the gyroscope (:attr:`NoiseSensor.counts_scale_unit`).
    max_tau_s : float, optional
        Largest τ analysed (must leave at least 9 clusters).
    sensor : NoiseSensor
        :data:`ACCELEROMETER` (default) or :data:`GYROSCOPE`.
    """
    data = np.asarray(samples, dtype=float)
    if data.ndim != 2 or data.shape[1] != 3:
        raise InputError(f"a static log needs three columns (x, y, z), got shape {data.shape}")
    factor = sensor.si_per_unit(units, counts_per_unit)
    from optcal.core.progress import progress

    axes = progress(enumerate(AXES), total=len(AXES), desc=f"Allan deviation ({sensor.name})")
    curves = {axis: allan_deviation(data[:, i], rate_hz, max_tau_s) for i, axis in axes}
    return AllanAnalysis(
        curves=curves,
        parameters={axis: fit_noise_parameters(c, sensor) for axis, c in curves.items()},
        units=sensor.canonical_units(units),
        si_per_unit=factor,
        rate_hz=float(rate_hz),
        n_samples=int(data.shape[0]),
        sensor=sensor,
    )


# --------------------------------------------------------------------------- plot
def allan_figure(analysis: AllanAnalysis, title: str | None = None) -> "Figure":
    """Log-log Allan deviation of each axis with confidence intervals and the fitted lines (either sensor).

    Values are drawn in the input units; the legend gives the parameters in conventional units
    (:attr:`~optcal.families.noise.sensors.NoiseSensor.legend_units`).
    Drawn on a :class:`matplotlib.figure.Figure` of its own (no pyplot state, the backend untouched).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 4.8))
    axes = fig.subplots(1, 3)
    sensor = analysis.sensor

    def legend(parameter: str, si_value: float, bound: bool = False) -> str:
        """``VRW 0.12 m/s/√h (3.4 µg/√Hz)``: the coefficient in the conventional units of the legend."""
        name = sensor.summary_name(parameter)
        shown = [f"{si_value * factor:.3g} {unit}" for unit, factor in sensor.display_units[name]
                 if unit in sensor.legend_units[name]]
        rest = f" ({', '.join(shown[1:])})" if len(shown) > 1 else ""
        return f"{sensor.abbreviation(parameter)} {'≤ ' if bound else ''}{shown[0]}{rest}"

    for ax, (axis, curve) in zip(axes, analysis.curves.items()):
        p = analysis.parameters[axis]
        si = p.scaled(analysis.si_per_unit)
        err = np.vstack([curve.adev - curve.ci_low, curve.ci_high - curve.adev])
        ax.errorbar(curve.taus, curve.adev, yerr=err, fmt="o", ms=4, capsize=2, color="k", label="overlapping ADEV")
        dense = np.geomspace(curve.taus[0], curve.taus[-1], 200)
        ax.loglog(dense, p.model_adev(dense), "-", color="0.5", lw=2, alpha=0.6, label="fitted sum")
        ax.loglog(dense, p.noise_density / np.sqrt(dense), "--", color="tab:blue",
                  label=legend("noise_density", si.noise_density))
        ax.plot([NOISE_DENSITY_TAU_S], [p.noise_density], "s", color="tab:blue", ms=7, mfc="none")
        flat_label = legend("bias_instability", si.bias_instability, p.bias_instability_bound) + " (flat = 0.664 B)"
        ax.axhline(FLICKER_FACTOR * p.bias_instability, ls=":", color="tab:green", label=flat_label)
        if p.rate_random_walk is not None and si.rate_random_walk is not None:
            ax.loglog(dense, p.rate_random_walk * np.sqrt(dense / 3.0), "-.", color="tab:red",
                      label=legend("rate_random_walk", si.rate_random_walk))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("τ (s)")
        ax.set_title(f"{axis} axis")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
        ax.set_ylim(bottom=min(curve.ci_low.min(), FLICKER_FACTOR * p.bias_instability) * 0.5)
    axes[0].set_ylabel(f"Allan deviation σ(τ) ({analysis.units})")
    fig.suptitle(title or f"Allan deviation, {analysis.duration_s / 3600:.3g} h at {analysis.rate_hz:g} Hz")
    fig.tight_layout()
    return fig


def plot_allan(analysis: AllanAnalysis, path: str | Path, title: str | None = None) -> Path:
    """Save :func:`allan_figure` to ``path`` (parent folders created); returns the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    from optcal.core.atomic import atomic_path

    with atomic_path(out) as tmp:  # whole or not at all
        allan_figure(analysis, title).savefig(tmp, dpi=120)
    return out
