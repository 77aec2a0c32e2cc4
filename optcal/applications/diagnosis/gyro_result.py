"""What the gyroscope's diagnosis found and how it is said: each named effect with its evidence
(:class:`GyroFinding`) and the whole diagnosis (:class:`GyroDiagnosis`: its JSON object and report lines), from
:func:`~optcal.applications.diagnosis.gyro_diagnosis.diagnose_gyro`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.gyro_problem import GyroParams
from optcal.core.model import EARTH_RATE, STANDARD_GRAVITY


@dataclass(frozen=True)
class GyroFinding:
    """An effect named in the gyroscope, with its evidence.

    Attributes
    ----------
    effect : str
        One of :data:`GYRO_EFFECTS`.
    axes : list of str
    estimate : dict
        Axis → value in SI (rad/s per m/s² for the g-sensitivity's diagonal term, (rad/s)⁻¹ for the scale
        nonlinearity, rad/s per °C, rad/s per s), or ``{"dt_s": ...}`` for the time offset.
    evidence : dict
        The likelihood ratio (or t), p, ΔBIC and the held-out ratio of the step that named it; the held-out moves'
        paired gain (``heldout_gain_deg``: the mean improvement of a held-out move's gravity-prediction angle, or of
        its rms inside-move misfit for the time offset, degrees), its standard error (``heldout_se_deg``), its t
        (``heldout_moves_t``) and the t it had to exceed (``heldout_moves_critical_t``).
    extra : dict
        The g-sensitivity's whole rows (rad/s per m/s²); the time offset's standard error and what it measures
        (:data:`TIME_OFFSET_MEASURES`).
    """

    effect: str
    axes: list[str]
    estimate: dict[str, Any]
    evidence: dict[str, float]
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"sensor": "gyroscope", "effect": self.effect, "axes": list(self.axes), "estimate": dict(self.estimate),
                "evidence": dict(self.evidence), **self.extra}

    def describe(self) -> str:
        if self.effect == "time_offset":
            dt = float(self.estimate["dt_s"])
            se = self.extra.get("stderr", {}).get("dt_s")
            return (f"time_offset: the gyro's samples are {abs(dt) * 1e3:.2f}"
                    + (f" ± {float(se) * 1e3:.2f}" if se is not None else "")
                    + f" ms {'late' if dt > 0 else 'early'} against the accelerometer's as the file holds them, its own "
                    f"offset included (t = {self.evidence['t']:.1f}, held-out {self.evidence['heldout_ratio']:.3f}×"
                    f"{_heldout_words(self.evidence, 'rms inside-move misfit')})")
        unit = {"g_sensitivity": "rad/s per m/s²", "gyro_scale_nonlinearity": "(rad/s)⁻¹",
                "gyro_temperature_bias": "rad/s per °C", "gyro_bias_drift": "rad/s per s"}[self.effect]
        values = ", ".join(f"{a} {float(v):.3g}" for a, v in self.estimate.items())
        rows = self.extra.get("row_rad_s_per_m_s2")
        if rows:  # the whole row: an axis' rate error may follow another axis' specific force (off-diagonal)
            values = "; ".join(f"{a} row (per x, y, z) " + ", ".join(f"{float(v):.3g}" for v in row)
                               for a, row in rows.items())
        return (f"{self.effect}({','.join(self.axes)}): {values} {unit} (likelihood ratio {self.evidence['lr']:.1f}, "
                f"p {self.evidence['p']:.2g}, ΔBIC {self.evidence['delta_bic']:.1f}, held-out {self.evidence['heldout_ratio']:.2f}×"
                f"{_heldout_words(self.evidence, 'angle')})")


def _heldout_words(evidence: dict[str, Any], what: str) -> str:
    """The held-out moves' paired gain in words (``""`` when ``evidence`` has none): the mean improvement per
    held-out move of its ``what``, its standard error and t against the t it had to exceed; and their response to
    the term (:func:`moves_response`)."""
    if "heldout_gain_deg" not in evidence:
        return ""
    words = (f"; held-out moves' {what} {float(evidence['heldout_gain_deg']):+.2g} ± "
             f"{float(evidence['heldout_se_deg']):.2g}° better per move, t {float(evidence['heldout_moves_t']):.2f} "
             f"against {float(evidence['heldout_moves_critical_t']):.2f}")
    response = evidence.get("moves_response_t")
    if isinstance(response, float) and math.isfinite(response):
        words += (f"; their response to it {float(evidence['moves_response']):.2f} ± "
                  f"{float(evidence['moves_response_se']):.2f} (1: they carried what it removes, 0: none of it), "
                  f"t {response:.2f}")
    return words


@dataclass
class GyroDiagnosis:
    """What the gyroscope's diagnosis found (:func:`diagnose_gyro`)."""

    findings: list[GyroFinding]
    steps: list[dict[str, Any]]
    angles_deg: NDArray[np.float64]
    band_deg: NDArray[np.float64]
    final_angles_deg: NDArray[np.float64]
    heldout_baseline_deg: float
    heldout_final_deg: float
    time_offset: dict[str, Any]
    tested: list[str]
    skipped: dict[str, str]
    final: GyroParams
    notes: list[str]
    solver: dict[str, Any]
    #: How the band was found: the runs simulated (0: linearised only) and the linearised band beside it.
    band_runs: int = 0
    linearised_band_deg: NDArray[np.float64] | None = None
    #: The moves left out before the diagnosis, by reason (:attr:`optcal.families.gyro.moves.MoveSet.exclusions`).
    moves_excluded: dict[str, int] = field(default_factory=dict)
    #: The accelerometer frame check (:class:`~optcal.applications.diagnosis.gyro_frame_check.FrameCheck`), None
    #: when skipped.
    accelerometer_frame: Any = None

    @property
    def gain(self) -> float:
        """Held-out rms gravity-prediction angle of the paper's model over the final model's."""
        return self.heldout_baseline_deg / self.heldout_final_deg if self.heldout_final_deg > 0 else 1.0

    @property
    def outside(self) -> NDArray[np.bool_]:
        return np.asarray(self.angles_deg > self.band_deg)

    def to_dict(self) -> dict[str, Any]:
        return {
            "findings": [f.to_dict() for f in self.findings],
            "gain": self.gain,
            "heldout_rms_deg": {"baseline": self.heldout_baseline_deg, "final": self.heldout_final_deg},
            "moves": [{"angle_deg": float(a), "band_deg": float(b), "outside": bool(a > b), "final_angle_deg": float(f)}
                      for a, b, f in zip(self.angles_deg, self.band_deg, self.final_angles_deg)],
            "moves_outside_band": int(np.sum(self.outside)),
            "moves_excluded": dict(self.moves_excluded),
            "band": {"runs": self.band_runs, "method": ("simulated: the fitted model integrated along each recorded move with the measured noise"
                                if self.band_runs else "linearised noise budget"),
                     "linearised_deg": None if self.linearised_band_deg is None else self.linearised_band_deg.tolist()},
            "rms_deg": {"baseline": float(np.sqrt(np.mean(self.angles_deg**2))),
                        "final": float(np.sqrt(np.mean(self.final_angles_deg**2)))},
            "steps": self.steps,
            "time_offset": self.time_offset,
            "tested": self.tested,
            "skipped": self.skipped,
            "final_model": {"T": self.final.T.tolist(), "bias": self.final.b.tolist(),
                            "terms": {t.label: v.tolist() for t, v in zip(self.final.terms, self.final.values)}},
            "solver": self.solver,
            "notes": self.notes,
            "accelerometer_frame": None if self.accelerometer_frame is None else self.accelerometer_frame.to_dict(),
        }

    def report_lines(self) -> list[str]:
        out = ["GYROSCOPE",
               f"  gravity prediction across {self.angles_deg.size} moves: {np.sqrt(np.mean(self.angles_deg**2)):.3f}° rms "
               f"under the paper's model; {int(np.sum(self.outside))} move(s) outside the "
               + (f"band of {self.band_runs} simulations of the fitted model along the recorded moves with the measured "
                  "noise" if self.band_runs else "noise band") + " (family-wise over the moves)"]
        out.extend(f"  {k}: {v}" for k, v in self.moves_excluded.items())
        for i in np.flatnonzero(self.outside)[:10]:
            out.append(f"    move {i + 1}: {self.angles_deg[i]:.3f}° (band {self.band_deg[i]:.3f}°)")
        if self.findings:
            out.append("  named:")
            for f in self.findings:
                out.append(f"    {f.describe()}")
                if f.effect == "g_sensitivity":
                    # the Earth's rate's vertical component (Ω sin φ along gravity) turns with the pose as a specific
                    # force along the axis would: a diagonal g-sensitivity of Ω sin φ / g at latitude φ
                    out.append(f"      (its diagonal terms include the Earth's rate along gravity, up to "
                               f"{EARTH_RATE / STANDARD_GRAVITY:.2g} rad/s per m/s² at the poles, which no recording "
                               "tells from the sensor's)")
        elif np.any(self.outside):
            # the band's excess left unexplained: said, not "nothing" (the effect is outside the five candidates, or
            # the noise model understates the moves' noise)
            effects = list(dict.fromkeys(label.split("(")[0] for label in self.tested))
            frame = bool(getattr(self.accelerometer_frame, "relevant", False))
            out.append(f"  none named: the {int(np.sum(self.outside))} move(s) beyond the band are explained by none of "
                       f"the candidates tested ({', '.join(effects)}); "
                       + ("the accelerometer's frame explains them (below)" if frame else
                          "the cause is outside them (motion during the rests, a time base that is not the samples', "
                          "a filter, the accelerometer's frame) or the noise model understates the moves' noise"))
            tried = [s for s in self.steps if not s.get("removed")][:1]
            for step in tried:
                moves_t = step.get("heldout_moves_t")
                out.append(f"    best candidate: {step['term']} (likelihood ratio {step['lr']:.1f}, p {step['p']:.2g} against "
                           f"{step['level']:.2g}, ΔBIC {step['delta_bic']:.1f}"
                           + (f", held-out moves' t {moves_t:.2f} against "
                              f"{step.get('heldout_moves_critical_t', step['heldout_critical_t']):.2f}"
                              + (f" (their angle {step['heldout_gain_deg']:+.2g} ± {step['heldout_se_deg']:.2g}° better "
                                 "per move)" if "heldout_gain_deg" in step else "")
                              if isinstance(moves_t, float) and math.isfinite(moves_t) else "")
                           + (f", their response {step['moves_response']:.2f} ± {step['moves_response_se']:.2f}"
                              if isinstance(step.get("moves_response_t"), float)
                              and math.isfinite(step["moves_response_t"]) else "") + ")")
        else:
            out.append("  none named (an effect below the tests' power is not ruled out)")
        if "dt_s" in self.time_offset and not self.time_offset.get("significant"):
            # measured whether named or not: a user who shifted a stream reads the total here (TIME_OFFSET_MEASURES)
            o = self.time_offset
            out.append(f"  time offset between the streams: {o['dt_s'] * 1e3:+.2f} ± {o['se_s'] * 1e3:.2f} ms (gyro "
                       f"late when positive; t {o['t']:.1f} against {o['critical_t']:.1f}, held-out "
                       f"{o['heldout_ratio']:.3f}×{_heldout_words(o, 'rms inside-move misfit')}): not named")
        if self.accelerometer_frame is not None and self.accelerometer_frame.run:
            out.append(self.accelerometer_frame.line())
        out.append(f"  held-out gravity prediction: {self.heldout_baseline_deg:.3f}° → {self.heldout_final_deg:.3f}° rms "
                   f"(gain {self.gain:.2f})")
        for name, why in self.skipped.items():
            out.append(f"  not tested: {name}: {why}")
        out += [f"  note: {n}" for n in self.notes]
        return out
