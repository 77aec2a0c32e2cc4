"""The text report and JSON summary of a Ferraris calibration (``optcal calibrate DATA --method ferraris``).

What was taken for what (the nine sections), the accelerometer as every accelerometer fit is
reported (:func:`optcal.report.calibration_text.calibration_report`: fit statistics, parameters
with standard errors, scale factors, angles and biases), then imucal's matrices, the held-out rests,
the turns as the calibrated gyroscope reads them and the gyroscope's parameters with standard errors.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optcal.core.jsonio import jsonable
from optcal.core.stats import rms
from optcal.data.recording import Recording
from optcal.families.ferraris.method import GYRO_PARAM_NAMES, FerrarisFit
from optcal.report.calibration_text import calibration_report

__all__ = ["ferraris_report", "ferraris_summary"]


def ferraris_summary(fit: FerrarisFit, rec: Recording) -> dict[str, Any]:
    """JSON-safe summary: the accelerometer's summary, imucal's matrices, sections, turns, held-out rests, gyro."""
    out = fit.accelerometer.summary()
    out["ferraris"] = jsonable({
        "matrices": fit.matrices.to_dict(),
        "matrices_units": {"K_a": f"{rec.units} per g", "b_a": rec.units, "K_g": f"{fit.gyro_units} per deg/s",
                           "b_g": fit.gyro_units, "K_ga": f"{fit.gyro_units} per g", "R_a": "1", "R_g": "1"},
        "sections": {name: {"rows": [int(rec.row[s.samples].min()), int(rec.row[s.samples].max())],
                            "n_samples": int(s.samples.size), "how": s.how}
                     for name, s in fit.regions.sections.items()},
        "sections_source": fit.regions.source,
        "face_rms_norm_residual_mg": fit.face_rms_mg,
        "held_out": fit.held_out,
        "held_out_rms_norm_residual_mg": fit.held_out_rms_mg,
        "turns": [{"name": t.name, "expected_deg": t.expected_deg, "about_axis_deg": t.about_axis_deg,
                   "net_rotation_deg": t.net_rotation_deg} for t in fit.turns],
        "bias_check_offdiagonal": fit.bias_check,
        "gyro": {"Tg_rad_s_per_unit": fit.gyro.T, "bg": fit.gyro.bias, "Gg": fit.gyro.g_sensitivity,
                 "units": fit.gyro_units, "units_reason": fit.gyro_units_reason,
                 "params": dict(zip(GYRO_PARAM_NAMES, fit.gyro_params)), "stderr": fit.gyro_stderr},
        "notes": fit.notes,
    })
    return out


def ferraris_report(fit: FerrarisFit, rec: Recording) -> str:
    """Readable report of a Ferraris calibration (module docstring)."""
    lines = [f"[[Ferraris sections: {fit.regions.source}]]"]
    lines += [f"    {line}" for line in fit.regions.describe(rec)]
    lines.append(calibration_report(fit.accelerometer))
    m = fit.matrices
    lines.append(f"[[imucal's matrices (output g; K_a in {rec.units} per g, K_g in {fit.gyro_units} per deg/s)]]")
    for name in ("K_a", "R_a", "b_a", "K_g", "R_g", "b_g", "K_ga"):
        value = np.atleast_2d(getattr(m, name))
        rows = [" ".join(f"{v: .7g}" for v in (np.diag(value) if name.startswith("K_") and name != "K_ga" else r))
                for r in (value[:1] if name.startswith("K_") and name != "K_ga" else value)]
        lines.append(f"    {name:<4s} = " + " | ".join(rows) + ("  (diagonal)" if name in ("K_a", "K_g") else ""))
    off = fit.bias_check[~np.eye(3, dtype=bool)]
    lines.append(f"    each pair's estimate of the other axes' biases differs from b_a by up to {np.max(np.abs(off)):.3g} "
                 f"{rec.units} (rms {rms(off):.3g}): the tilt and misalignment the pairs do not share")
    lines.append("[[Accelerometer on the rests not used (held out)]]")
    if fit.held_out:
        for h in fit.held_out:
            lines.append(f"    rest {h['interval']:>3d} (rows {h['rows'][0]}-{h['rows'][1]}, {h['n_samples']} samples): "
                         f"|a|-1 = {1e3 * h['norm_residual_g']:+.3f} mg")
        worst = max(abs(h["norm_residual_g"]) for h in fit.held_out)
        lines.append(f"    rms {fit.held_out_rms_mg:.3f} mg, max {1e3 * worst:.3f} mg over {len(fit.held_out)} rests "
                     f"(on the six faces: rms {fit.face_rms_mg:.3f} mg)")
    else:
        lines.append("    none (no rest outside the six faces)")
    lines.append(f"[[Turns read by the calibrated gyroscope (gyro units {fit.gyro_units}: {fit.gyro_units_reason})]]")
    for t in fit.turns:
        lines.append(f"    {t.name}: {t.about_axis_deg:+.3f}° about its axis (taken as {t.expected_deg:+.0f}°: exact on the "
                     f"stretch it was fitted on, eq. 15), attitude integrated over it closes within {t.net_rotation_deg:.3f}°")
    lines.append("[[Gyroscope: omega = T_g (g - b_g - G_g a), rad/s]]")
    se = fit.gyro_stderr
    for name, value in zip(GYRO_PARAM_NAMES, fit.gyro_params):
        e = se[name]
        rel = f"({abs(e / value) * 100:.2g} %)" if value != 0 and np.isfinite(e) else ""
        lines.append(f"    {name:<8s} = {value: .8g} +/- {e:.3g} {rel}")
    phys = fit.gyro.physical()
    lines.append("    scale factors " + ", ".join(f"{s * np.pi / 180:.6g}" for s in phys.scale)
                 + f" {fit.gyro_units} per deg/s; sensing axes off the accelerometer frame's by "
                 + ", ".join(f"{a:.3f}°" for a in phys.misalignment_deg))
    if fit.notes:
        lines.append("[[Ferraris notes]]")
        lines += [f"    - {n}" for n in fit.notes]
    return "\n".join(lines)
