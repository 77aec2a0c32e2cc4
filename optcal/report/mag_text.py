"""The magnetometer calibration's text report."""

from __future__ import annotations

from typing import Any

import numpy as np


def _row(v: Any) -> str:
    return "[" + ", ".join(f"{x: .6g}" for x in np.asarray(v, dtype=float)) + "]"


def mag_report(result: Any) -> str:
    """The report of a :class:`optcal.families.mag.calibration.MagCalibrationResult`."""
    cal, fit = result.calibration, result.fit
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
