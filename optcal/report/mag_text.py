"""The magnetometer calibration's text report."""

from __future__ import annotations

from typing import Any

import numpy as np


def _row(v: Any) -> str:
    return "[" + ", ".join(f"{x: .6g}" for x in np.asarray(v, dtype=float)) + "]"


def mag_report(result: Any) -> str:
    """The report of a :class:`optcal.families.mag.calibration.MagCalibrationResult`."""
    cal, fit = result.calibration, result.fit
    if getattr(result, "planar", None) is not None:
        return planar_report(result)
    f = fit.fit
    u = cal.units
    se = f.stderr
    o_se = [se.get(f"o_{a}", float("nan")) for a in "xyz"]
    lines = [
        f"magnetometer calibration: m̄ = T (m − o), |m̄| = 1 ({f.method}; solver {f.solver})",
        f"form: {f.form}: {fit.form_reason}",
        f"field strength: {cal.field_strength:.6g} {u}",
        f"hard iron o ({u}): {_row(f.o)} ± {_row(o_se)}",
        "soft iron T (symmetric, per " + u + "):",
        *("  " + _row(row) for row in f.T),
        f"rms of |T(m − o)| − 1: {f.rms:.4g} ({100 * f.rms:.3g} % of the field) over {result.samples.n} samples",
        f"coverage: {len(fit.coverage.covered)}/26 directions within 30 deg",
    ]
    lines += ["note: " + n for n in fit.notes]
    if result.dip is not None:
        lines += result.dip.lines()
    elif result.samples.acc is not None:
        lines.append("dip: too few still samples (|a| near its median) to estimate it")
    return "\n".join(lines)


def planar_report(result: Any) -> str:
    """The report of a planar (heading) :class:`optcal.families.mag.calibration.MagCalibrationResult`."""
    cal, pf = result.calibration, result.planar
    u = cal.units
    p = cal.info["planar"]
    se = pf.stderr
    c_se = [se.get("c_0", float("nan")), se.get("c_1", float("nan"))]
    lines = [
        f"magnetometer calibration, planar (heading): m̄ = T₂ (P m − c), |m̄| = 1 in the plane ({pf.method}; solver {pf.solver})",
        f"form: planar ({pf.form}): {result.fit.form_reason}",
        f"plane normal n: {_row(pf.normal)}; plane basis P: {_row(pf.basis[0])}, {_row(pf.basis[1])}",
        f"field in the plane H: {pf.horizontal_field:.6g} {u}",
        f"hard iron in the plane c ({u}, in P's axes): {_row(pf.c)} ± {_row(c_se)}; along n: undetermined (0)",
        "soft iron T₂ (symmetric, per " + u + ", in P's axes):",
        *("  " + _row(row) for row in pf.T2),
        f"T (3×3) = Pᵀ T₂ P + n nᵀ / H: {p['normal_row']}",
        f"rms of |T₂(P m − c)| − 1: {pf.rms:.4g} ({100 * pf.rms:.3g} % of H) over {result.samples.n} samples",
        f"headings covered: {len(pf.sectors)} of {p['headings_covered']['of']} sectors of "
        f"{360 // p['headings_covered']['of']}°",
    ]
    lines += ["note: " + n for n in result.fit.notes]
    return "\n".join(lines)
