"""The HTML report of a magnetometer's calibration (``optcal calibrate DATA --sensor mag --report``): its verdict, the
coverage of the sphere before and after, the norm residual, the text report."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.quality.verdict import Reason, Verdict
from optcal.report.document import ReportDocument, Section, Table, now_utc, versions
from optcal.report.figures import embed
from optcal.report.mag_text import mag_report

#: The norm residual's rms (share of the field) up to which a magnetometer calibration is "good": a heading error of
#: about that many radians (0.57° per 1 %) where the field is horizontal, within a consumer compass's stated 1-2°.
GOOD_RMS_SHARE: float = 0.02
#: Beyond this share the samples do not lie on an ellipsoid well enough for a compass (a heading error of 3°).
USABLE_RMS_SHARE: float = 0.05


def coverage_figure(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64], units: str) -> Any:
    """The samples' directions before the calibration (the raw field less its mean) and after (``T (m − o)``), as
    azimuth against elevation: the sphere's coverage, and the ellipsoid made a sphere (the norm, coloured)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 3.4), layout="constrained")
    raw = m - m.mean(axis=0)
    cal = (m - o) @ T.T
    step = max(1, m.shape[0] // 4000)
    for k, (v, title, norm) in enumerate(((raw, f"before: m − mean ({units})", np.linalg.norm(raw, axis=1)),
                                          (cal, "after: T (m − o), |·| = 1 for the field", np.linalg.norm(cal, axis=1)))):
        a = fig.add_subplot(1, 2, k + 1)
        u = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)
        az = np.degrees(np.arctan2(u[:, 1], u[:, 0]))
        el = np.degrees(np.arcsin(np.clip(u[:, 2], -1.0, 1.0)))
        sc = a.scatter(az[::step], el[::step], c=norm[::step], s=3, cmap="viridis")
        fig.colorbar(sc, ax=a, label="|·|")
        a.set_xlim(-180, 180)
        a.set_ylim(-90, 90)
        a.set_xlabel("azimuth (°)")
        a.set_ylabel("elevation (°)")
        a.set_title(title, fontsize=9)
    return fig


def heading_figure(result: Any) -> Any:
    """A planar (heading) calibration's coverage: the samples per heading sector (the
    :data:`~optcal.families.mag.planar.HEADING_SECTORS` sectors the held-out comparison leaves out in turn, about the
    fitted centre; a sector not reached in red), and the samples in the plane after the calibration, ``T₂ (P m − c)``,
    on the unit circle (coloured by the norm)."""
    from matplotlib.figure import Figure

    from optcal.families.mag.planar import HEADING_SECTORS, heading_sectors

    pf = result.planar
    p = result.samples.m @ pf.basis.T
    counts = np.bincount(heading_sectors(p, pf.c), minlength=HEADING_SECTORS)
    width = 2 * np.pi / HEADING_SECTORS
    fig = Figure(figsize=(8.0, 3.6), layout="constrained")
    a = fig.add_subplot(1, 2, 1, projection="polar")
    shown = np.where(counts > 0, counts, 0.25 * max(counts.max(), 1))  # a sector not reached: a red stub
    a.bar(width * (np.arange(HEADING_SECTORS) + 0.5), shown, width=0.9 * width, color=["tab:blue" if k else "tab:red" for k in counts])
    a.set_yticklabels([])
    a.set_title(f"samples per {360 // HEADING_SECTORS}° heading: {int(np.count_nonzero(counts))} of {HEADING_SECTORS}\n"
                f"reached (max {int(counts.max())}; red: none)", fontsize=9)
    b = fig.add_subplot(1, 2, 2)
    v = (p - pf.c) @ pf.T2.T
    norm = np.linalg.norm(v, axis=1)
    step = max(1, len(v) // 4000)
    sc = b.scatter(v[::step, 0], v[::step, 1], c=norm[::step], s=3, cmap="viridis")
    t = np.linspace(0.0, 2 * np.pi, 181)
    b.plot(np.cos(t), np.sin(t), color="0.5", lw=0.8)
    b.set_aspect("equal")
    b.set_xlabel("T₂ (P m − c), first axis of the plane")
    b.set_ylabel("second axis")
    b.set_title("after: the field in the plane, |·| = 1", fontsize=9)
    fig.colorbar(sc, ax=b, label="|·|")
    return fig


def mag_verdict(rms: float, missing: list[str], what: str = "direction(s) of the sphere") -> Verdict:
    """Good, usable with care or not usable, by the norm residual's rms and the coverage: ``missing`` names the
    ``what`` not reached (the sphere's directions, or a planar calibration's heading sectors)."""
    reasons = []
    level = "good"
    if rms > USABLE_RMS_SHARE:
        level = "not usable"
        reasons.append(Reason("not usable", "norm residual", f"rms of |T(m − o)| − 1 is {rms:.2%} of the field "
                              f"(> {USABLE_RMS_SHARE:.0%}): the samples do not lie on an ellipsoid"))
    elif rms > GOOD_RMS_SHARE:
        level = "usable with care"
        reasons.append(Reason("usable with care", "norm residual", f"rms of |T(m − o)| − 1 is {rms:.2%} of the field"))
    else:
        reasons.append(Reason("good", "norm residual", f"rms of |T(m − o)| − 1 is {rms:.2%} of the field"))
    if missing:
        if level == "good":
            level = "usable with care"
        reasons.insert(0, Reason("usable with care", "coverage", f"{len(missing)} {what} not reached: "
                                 f"{', '.join(missing[:8])}"))
    return Verdict(level, reasons, None)  # type: ignore[arg-type]


def mag_document(result: Any, data_path: str, command: str) -> ReportDocument:
    """The report of a :class:`~optcal.families.mag.calibration.MagCalibrationResult`."""
    cal = result.calibration
    samples = result.samples
    info = cal.info
    rows = [["field strength", f"{cal.field_strength:.6g} {cal.units}"],
            ["hard iron o", ", ".join(f"{v:.6g}" for v in cal.o) + f" {cal.units}"],
            ["form", str(info.get("form"))],
            ["rms |T(m − o)| − 1", f"{info.get('rms_norm_residual', float('nan')):.4%}"],
            ["samples", str(samples.n)]]
    if info.get("dip_deg") is not None:
        rows.append(["dip", f"{info['dip_deg']:.2f} ± {info.get('dip_se_deg', float('nan')):.2f}° "
                            f"(spread {info.get('dip_std_deg', float('nan')):.2f}°)"])
    missing = list(info.get("coverage_missing", []))
    if getattr(result, "planar", None) is not None:  # a heading calibration: its coverage is the headings, not the sphere
        from optcal.families.mag.planar import HEADING_SECTORS

        width = 360 // HEADING_SECTORS
        missing = [f"heading {k * width}-{(k + 1) * width}°" for k in range(HEADING_SECTORS)
                   if k not in result.planar.sectors]
        figure = embed(heading_figure(result), "The samples' headings in the plane of the turn, and the field in the "
                                               "plane after the calibration (coloured by the norm)")
    else:
        figure = embed(coverage_figure(samples.m, cal.T, cal.o, cal.units),
                       "The samples' directions on the sphere before and after the calibration (coloured by the norm)")
    section = Section("Magnetometer calibration", [f"m̄ = T (m − o), |m̄| = 1 for the local field; {samples.n} samples."],
                      [Table(["quantity", "value"], rows, "The calibration")], [figure], mag_report(result))
    verdict = mag_verdict(float(info.get("rms_norm_residual", 0.0)), missing,
                          "direction(s) of the sphere" if getattr(result, "planar", None) is None else "heading sector(s)")
    return ReportDocument(f"Magnetometer calibration of {data_path}", data_path, verdict, [section], command,
                          versions(), now_utc())
