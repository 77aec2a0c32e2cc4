"""What the magnetometer's diagnosis found (:func:`optcal.applications.magnetic.diagnosis.diagnose_mag`): the named
effects and the diagnosis with its band, held-out gain, plain and extended models, as JSON and as the report's lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.magnetic.band import BLOCK
from optcal.applications.magnetic.dip_channel import DIP_BLOCK_SHARE, DipChannel

@dataclass(frozen=True)
class MagFinding:
    """An effect named in the magnetometer (``"sensor": "magnetometer"``)."""

    effect: str
    axes: list[str]
    estimate: dict[str, float]
    evidence: dict[str, float]
    stretch: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"sensor": "magnetometer", "effect": self.effect, "axes": list(self.axes),
                               "estimate": dict(self.estimate), "evidence": dict(self.evidence)}
        if self.stretch is not None:
            out.update(self.stretch)
        return out

    def describe(self, units: str) -> str:
        values = ", ".join(f"{a} {v:+.4g}" for a, v in self.estimate.items())
        if self.effect == "local_disturbance" and self.stretch is not None:
            s = self.stretch
            when = (f"{s['start_s']:.2f}-{s['stop_s']:.2f} s" if s.get("start_s") is not None
                    else f"samples {s['start_sample']}-{s['stop_sample']}")
            left = s["stop_sample"] - s["start_sample"]
            if s.get("channel") == "dip":
                return (f"local_disturbance {when}: the field bent by {s['dip_shift_deg']:+.2f}° of dip, its strength "
                        f"unchanged ({left} samples left out; χ² dip {self.evidence['statistic_dip']:.1f}, strength "
                        f"{self.evidence['statistic_strength']:.1f}; the dip moved {self.evidence['moved_dip_se']:.1f} SE)")
            shift = s.get("dip_shift_deg")
            dip = (f", dip {shift:+.2f}° (the dip moved {self.evidence['moved_dip_se']:.1f} SE, held-out gain "
                   f"{self.evidence['heldout_dip_gain_se']:.1f} SE)" if shift is not None and math.isfinite(shift) else "")
            return (f"local_disturbance {when}: a field of {values} {units} added{dip} ({left} "
                    f"samples left out; χ² {self.evidence['statistic']:.1f}; leaving it out turns the heading "
                    f"{self.evidence['heading_deg']:.3g}° ({self.evidence['moved_heading_se']:.1f} SE), the field "
                    f"{self.evidence['field']:+.3g} {units} ({self.evidence['moved_field_se']:.1f} SE), held-out "
                    f"gain {self.evidence['heldout_gain_se']:.1f} SE)")
        per = {"temperature_offset": f"{units} per °C", "current_interference": f"{units} per unit of the column"}
        return f"{self.effect}: {values} {per.get(self.effect, units)} (likelihood ratio {self.evidence['lr']:.1f}, held-out {self.evidence['heldout_ratio']:.3f}×)"


@dataclass
class MagDiagnosis:
    """What :func:`diagnose_mag` found."""

    findings: list[MagFinding]
    units: str
    n_samples: int
    block_means: NDArray[np.float64]
    band: float
    sigma_sample: float
    colour: float
    heldout_plain: float
    heldout_extended: float
    plain: dict[str, Any]
    extended: dict[str, Any]
    excluded: int
    notes: list[str] = field(default_factory=list)
    dip: DipChannel | None = None
    heldout_dip_plain: float | None = None
    heldout_dip_extended: float | None = None

    @property
    def gain(self) -> float:
        return self.heldout_plain / self.heldout_extended if self.heldout_extended > 0 else 1.0

    def to_dict(self) -> dict[str, Any]:
        outside = np.flatnonzero(np.abs(self.block_means) > self.band)
        return {
            "sensor": "magnetometer", "n_samples": self.n_samples, "findings": [f.to_dict() for f in self.findings],
            "gain": self.gain, "heldout_rms_norm_residual": {"plain": self.heldout_plain, "extended": self.heldout_extended},
            "band": {"block_samples": BLOCK, "half_width": self.band, "sigma_sample": self.sigma_sample,
                     "colour": self.colour, "blocks": int(self.block_means.size),
                     "blocks_outside": [[int(k) * BLOCK, (int(k) + 1) * BLOCK] for k in outside]},
            "plain": self.plain, "extended": self.extended, "excluded_samples": self.excluded, "notes": self.notes,
            "dip_channel": None if self.dip is None else {
                **self.dip.to_dict(), "heldout_rms_deg": {"plain": self.heldout_dip_plain,
                                                          "extended": self.heldout_dip_extended}},
        }

    def report_lines(self) -> list[str]:
        outside = int(np.sum(np.abs(self.block_means) > self.band))
        out = ["MAGNETOMETER",
               f"  norm residual: {self.n_samples} samples, white σ {self.sigma_sample:.3g}, blocks of {BLOCK} "
               f"(noise colour {self.colour:.2g}); {outside} of {self.block_means.size} blocks outside the band "
               f"±{self.band:.3g} (family-wise over the blocks)"]
        if self.dip is not None:
            d = self.dip
            out.append(f"  dip residual: {d.n_still} still samples, white σ {d.sigma_sample:.3g}°, a block's mean "
                       f"σ {d.sigma_block:.3g}° over {d.blocks_used} of {d.blocks} blocks at least "
                       f"{100 * DIP_BLOCK_SHARE:g} % still; held-out rms {self.heldout_dip_plain:.3g}° → "
                       f"{self.heldout_dip_extended:.3g}°")
            out.append(f"  near rest: {d.near_rest}")
        else:
            out.append("  dip residual: not searched (no accelerometer, or too few still blocks)")
        if self.findings:
            out.append("  named:")
            out += [f"    {f.describe(self.units)}" for f in self.findings]
        else:
            out.append("  none named (an effect below the tests' power is not ruled out)")
        out.append(f"  held-out rms |T(m − o)| − 1 (outside every named stretch): {self.heldout_plain:.4g} → "
                   f"{self.heldout_extended:.4g} (gain {self.gain:.3f})")
        out.append(f"  extended model: o {np.round(self.extended['o'], 6).tolist()} {self.units}, field "
                   f"{self.extended['field_strength']:.6g} {self.units}; {self.excluded} samples left out")
        out += [f"  note: {n}" for n in self.notes]
        return out
