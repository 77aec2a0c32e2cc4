"""The text report of a diagnosis, in plain words (``optcal diagnose`` without ``--json``).

:func:`diagnosis_report` is a function of the :class:`~optcal.applications.diagnosis.result.Diagnosis`:
the presentation lives here, above the diagnosis, which holds the numbers.
"""

from __future__ import annotations

import numpy as np

from optcal.applications.diagnosis.noise_model import NoiseModelCheck
from optcal.applications.diagnosis.result import Diagnosis
from optcal.applications.diagnosis.acceptance import BIC_TIE
from optcal.applications.diagnosis.sessions import SessionOffsets
from optcal.applications.diagnosis.simulation import SimulationCheck
from optcal.core.extended_model import format_value

MG = 1e3


def simulation_text(sim: SimulationCheck, indent: str = "", after: bool = False) -> str:
    """Plain-words summary of a simulation check."""
    of = " of the final model" if after else ""
    if not sim.simulations:
        return f"Simulation check{of}: not run (0 simulations requested)"
    lines = [
        f"Simulation check{of}: the fitted model simulated {sim.simulations} times on the same poses "
        f"({sim.noise}); {sim.band * 100:g} % bands"
    ]
    if not sim.outside_band:
        lines.append(f"{indent}every residual statistic is inside its simulated band: the simulation reproduces the measurements")
    else:
        lines.append(f"{indent}where the measurement leaves the simulated band (what the simulation gets wrong):")
        for name in sim.outside_band:
            st = sim.statistics[name]
            lo, hi = st.band
            lines.append(
                f"{indent}  {st.meaning}: measured {st.measured:.3g}, simulated {lo:.3g} .. {hi:.3g} (p = {st.p_value:.2g})"
            )
    if sim.multiplicity_note:
        lines.append(f"{indent}{sim.multiplicity_note}")
    return "\n".join(lines)


def measured_noise_lines(check: NoiseModelCheck) -> list[str]:
    """The measured route of the noise model: the noise of each pose mean from the recording's still parts."""
    if check.measured_route is None:
        return []
    if check.measured_understated_by is None:
        return [f"      measured route: not available ({check.measured_route})"]
    line = (f"      measured route: {check.measured_route}: σ/√n understated the pose noise "
            f"{check.measured_understated_by:.3g}× (median; residual-estimated {check.understated_by:.3g}×); "
            f"reduced χ² with the measured σ {check.reduced_chi2_measured:.3g}")
    if check.coverage_measured is not None:
        line += (f"; its {check.nominal_coverage * 100:g} % intervals cover {check.coverage_measured * 100:.0f} % "
                 "in the bootstrap")
    return [line]


def correlation_lines(check: NoiseModelCheck) -> list[str]:
    """The pose noise correlated in time, when the tests use it or estimated it again (a named noise explanation, never
    an effect)."""
    if check.correlation is None or not (check.correlation.used or check.correlation.baseline is not None):
        return []
    return [f"      {check.correlation.text()}"]


def random_walk_lines(check: NoiseModelCheck) -> list[str]:
    """The bias wandering as a random walk, when tested (a noise explanation, never an effect)."""
    if check.random_walk is None or not check.random_walk.tested:
        return []
    return [f"      {check.random_walk.text()}"]


def _sigma_line(check: NoiseModelCheck) -> str:
    """What the reduced χ² of the given σ says when the noise model is not named: below 1 the pose means scatter
    less than σ/√n predicts (said with the lower tail's p, ``1 − p_value``), which no "describes" may hide."""
    if check.reduced_chi2 < 1.0:
        return (f"   the noise model: the per-pose σ does not understate the scatter; it overstates it (reduced χ² "
                f"{check.reduced_chi2:.3g}: the residuals are {np.sqrt(check.reduced_chi2):.3g}× what it predicts, "
                f"lower-tail p = {1.0 - check.p_value:.2g}); the selection's tests estimate the noise scale from the "
                f"residuals and keep the σ's ratios as weights")
    return f"   the noise model: the per-pose σ describes the scatter (reduced χ² {check.reduced_chi2:.3g})"


def _rms_below_band(diag: Diagnosis) -> bool:
    """The measured rms of the norm residuals lies below its simulated band (the given σ overstates the noise)."""
    band = diag.simulation.statistics.get("rms_g")
    return band is not None and band.measured < band.band[0]


def pose_noise_lines(diag: Diagnosis) -> list[str]:
    """The pose-to-pose noise tested beside the per-pose σ (:mod:`optcal.applications.diagnosis.pose_noise`)."""
    floor = diag.pose_noise
    if floor is None or not floor.tested:
        return []
    lines = [f"   the poses' weights: {floor.reason}"]
    if floor.effects:
        lines.append("   the findings again with each pose's σ widened by the pose-to-pose noise estimated without "
                     "each (as --pose-noise auto weighs the poses):")
    for e in floor.effects:
        verdict = "it stands" if e.stands else "it rests on the σ's ratios"
        it = "it" if e.outliers_again is None else "them"
        taus = f"τ {e.tau_without_g * 1e3:.3g} mg without {it}, {e.tau_with_g * 1e3:.2g} mg with {it}"
        if e.outliers_again is None:
            lines.append(f"     {e.term}: p {e.p_value:.2g} against the {e.threshold:.2g} it entered at ({e.p_given:.2g} "
                         f"with σ as logged; {taus}): {verdict}")
        else:
            verdict = "they stand" if e.stands else "they rest on the σ's ratios"
            lines.append(f"     {e.term}: {e.outliers_again} of them set aside again at {e.threshold:.2g} ({taus}): "
                         f"{verdict}")
    return lines


def noise_model_lines(diag: Diagnosis) -> list[str]:
    """The noise-model explanation (never a finding), when the given σ understates the scatter."""
    check = diag.noise_model
    if check is None:
        return []
    extra = correlation_lines(check) + random_walk_lines(check)
    if not check.tested:
        return ["   the noise model:", *extra] if extra else []
    if not check.named:
        if check.measured_route is None and not extra:
            return []
        return [_sigma_line(check), *correlation_lines(check), *measured_noise_lines(check), *random_walk_lines(check)]
    unit = diag.poses.units
    lines = [
        f"   the noise model: the residuals are {np.sqrt(check.reduced_chi2):.3g}× what the per-pose σ predicts "
        f"(reduced χ² {check.reduced_chi2:.3g}, p = {check.p_value:.2g})",
        f"      named cause: {check.cause}",
        f"      extension: an extra pose-to-pose noise of {check.extra_noise:.3g} {unit} ({check.extra_noise_g * MG:.3g} mg) "
        f"per pose; σ/√n understated the pose noise {check.understated_by:.3g}× (median); reduced χ² "
        f"{check.reduced_chi2:.3g} → {check.reduced_chi2_after:.3g}",
    ]
    if check.coverage_extended is not None and check.coverage_given_sigma is not None:
        lines.append(
            f"      calibrated standard errors: {check.nominal_coverage * 100:g} % intervals cover "
            f"{check.coverage_given_sigma * 100:.0f} % with the given σ, {check.coverage_extended * 100:.0f} % with the "
            f"extended noise model ({check.simulations} simulations)"
        )
    return lines + correlation_lines(check) + measured_noise_lines(check) + random_walk_lines(check)


def session_lines(sessions: SessionOffsets) -> list[str]:
    """Per axis: the turn-on repeatability and every session's bias offset from their mean."""
    lines = []
    for ax in sessions.axes:
        offsets = ", ".join(f"{name} {v * MG:+.3g} ± {se * MG:.2g}"
                            for name, v, se in zip(sessions.names, sessions.offsets_g[ax], sessions.stderr_g[ax]))
        lines.append(f"      axis {ax}: turn-on repeatability {sessions.repeatability_g[ax] * MG:.3g} mg "
                     f"(sessions' biases from their mean, mg: {offsets})")
    lines.append(f"      {sessions.applied}")
    return lines


def peer_lines(diag: Diagnosis) -> list[str]:
    """A peer's calibration (``--baseline`` from imucal or imu_tk) next to optcal's own: what each misses."""
    peer = diag.peer
    first, *rest = peer.lines()
    lines = ["The given calibration next to optcal's: " + first] + ["  " + line for line in rest]
    if diag.findings:
        named = ", ".join(dict.fromkeys(f.effect for f in diag.findings))
        lines.append(f"   neither {peer.peer} nor the paper's model holds what the diagnosis named ({named}); "
                     f"the final model does: held-out {diag.final_heldout_rms() * MG:.3g} mg")
    else:
        lines.append(f"   the diagnosis named no effect beyond the paper's model that {peer.peer} would also miss")
    return lines


def diagnosis_report(diag: Diagnosis) -> str:
    """Readable report: what the simulation gets wrong, the causes, the extended model, the gain."""
    settings = diag.settings
    lines = [
        f"Diagnosis of {diag.n} poses ({diag.poses.source}, units {diag.poses.units})",
        "",
        f"1. Baseline: the paper's model (T, o, white noise), maximum likelihood started from {diag.baseline_source}",
        f"   rms norm residual {diag.baseline_rms() * MG:.3g} mg; held-out ({settings.folds}-fold over poses) "
        f"{diag.baseline_heldout_rms() * MG:.3g} mg",
    ]
    if diag.given_rms_g is not None:
        lines.append(f"   the given calibration as it is: rms norm residual {diag.given_rms_g * MG:.3g} mg on these poses")
    lines += ["", "2. " + simulation_text(diag.simulation, indent="   ")]
    lines += ["", f"3. Candidate effects tested: {', '.join(diag.effects_tested) or 'none'}"]
    for effect, why in diag.skipped.items():
        lines.append(f"   not tested: {effect} ({why})")
    lines.append(
        f"   forward selection: F/likelihood-ratio test at family-wise level {settings.alpha:g} (Bonferroni over the "
        "candidates of each step), lower BIC, and a paired held-out gain beyond "
        f"{settings.to_dict()['heldout_se']:g} of its standard errors, all three required"
    )
    lines += pose_noise_lines(diag)
    for k, step in enumerate(diag.steps, 1):
        best = sorted(step.candidates, key=lambda c: c.delta_bic)[:3]
        tried = "; ".join(f"{c.term} ΔBIC {c.delta_bic:+.1f}, p {c.p_value:.2g}" for c in best)
        verdict = f"added {step.accepted.term}" if step.accepted else "nothing passes: stop"
        lines.append(f"   step {k}: {verdict}  [best candidates: {tried or 'none'}]")
        for c in step.candidates:  # every candidate the held-out check judged: its paired gain and SE
            if c.heldout_t is not None and c.heldout_gain_g2 is not None and c.heldout_se_g2 is not None:
                judged = "entered" if c is step.accepted else "not entered"
                lines.append(f"      {c.term}: held-out gain {c.heldout_gain_g2 * MG**2:+.3g} ± {c.heldout_se_g2 * MG**2:.2g} "
                             f"mg² per pose, t {c.heldout_t:.2f} against {c.heldout_critical_t:g} "
                             f"({c.heldout_units} units): {judged}")
        for d in step.dropped:  # a term accepted earlier that this step's term made unneeded (backward check)
            lines.append(f"      dropped {d.term}: {d.reason}")
    for decision in diag.decisions:
        lines.append("   " + decision.text)
    lines += ["", "4. Findings"]
    noise_named = diag.noise_model is not None and diag.noise_model.named
    if not diag.findings:
        if noise_named:
            lines.append("   none named: no candidate effect passes the tests and the excess scatter is explained by the "
                         "noise model (see 3); an effect below the detection limits (below) is not ruled out")
        elif "rms_g" in diag.simulation.outside_band and _rms_below_band(diag):
            # the scatter is smaller than σ/√n says: the given σ overstates the pose noise (a logger's σ taken over a
            # ringing or vibrating rest); no effect is missing, and the selection's tests estimate the scale anyway
            lines.append(
                "   none: the paper's model explains these data (no candidate passes the tests); the residuals are "
                "smaller than the given per-pose noise predicts (see 2): σ/√n overstates the scatter of the pose means"
            )
        elif "rms_g" in diag.simulation.outside_band:
            lines.append(
                "   none: no candidate effect passes the tests, although the residuals are larger than the given "
                "per-pose noise predicts (see 2): the excess is not one of the tested effects"
            )
        else:
            lines.append("   none: the paper's model explains these data (no candidate passes the tests)")
    for f in diag.findings:
        lines.append(f"   {f.effect}: {f.cause}")
        if f.rows is not None:
            named = "poses" if diag.poses.source == "raw recording" else "poses in file rows"
            where = [str(r) if f.row_sessions is None else f"{r} of {f.row_sessions[i]}" for i, r in enumerate(f.rows)]
            lines.append(f"      {named} {', '.join(where)} given zero weight")
        if f.sessions is not None:
            lines += session_lines(f.sessions)
        for step in [] if f.step is None else f.step.get("steps", [f.step]):
            when = (f" (t = {step['previous_t_s']:.1f} s → {step['t_s']:.1f} s)" if "t_s" in step else "")
            size = ("" if "estimate" not in step else
                    " by " + ", ".join(f"{v * MG:+.3g} mg on {a}" for a, v in step["estimate"].items()))
            lines.append(f"      the bias stepped between the rests in rows {step['previous_row']} and {step['row']}"
                         f"{when}, after {step['poses_before']} poses{size}, and stayed")
        for ax in f.axes if f.sessions is None else ():
            order = f.order[ax]
            change = f.change_over_data[ax]
            size = f"{change * 1e6:.3g} ppm" if f.effect == "temperature_scale" else f"{change * MG:.3g} mg"
            value = (f"{f.estimate[ax] * MG:+.3g} ± {f.stderr[ax] * MG:.2g} mg (after minus before)"
                     if f.effect == "bias_step" else format_value(f.effect, f.estimate[ax], f.stderr[ax]))
            lines.append(
                f"      axis {ax}: {value}"
                + (f" (polynomial order {order} supported by the data; slope at the reference shown)" if order > 1 else "")
                + f"; changes by {size} over the data"
            )
        lines.append(
            f"      evidence: ΔBIC {f.evidence.delta_bic:+.1f}, p = {f.evidence.p_value:.2g}; held-out rms "
            f"{f.heldout_rms_g_before * MG:.3g} → {f.heldout_rms_g_after * MG:.3g} mg"
        )
        if f.alternatives:  # findings.alternatives: within BIC_TIE of the named term in the step that named it
            lines.append(f"      not told apart by these data from (ΔBIC within {BIC_TIE:g} of the named term's, as tried): "
                         + ", ".join(f"{a['term']} ({a['delta_bic']:+.1f})" for a in f.alternatives))
    lines += noise_model_lines(diag)
    if diag.detection_limits:
        level = diag.detection_limits[0].level
        lines.append(f"   detection limits (smallest effect a test at level {level:.2g} would name, about half the time):")
        lines += [f"      {lim.text()}" for lim in diag.detection_limits]
    if diag.outlier_limit is not None:
        lim = diag.outlier_limit
        lines.append(f"   smallest outlier pose the outlier test (level {lim.level:.2g} over the poses) would name, about half "
                     f"the time: {lim.text()}")
    lines += [
        "",
        "5. Final model: " + diag.final.describe(),
        f"   rms {diag.final_rms() * MG:.3g} mg; held-out {diag.final_heldout_rms() * MG:.3g} mg; "
        f"gain {diag.gain():.3g}× (baseline held-out / final held-out)",
    ]
    if diag.final.outliers:
        kept = diag.kept
        on_kept = diag.baseline_heldout_rms(kept)
        lines.append(
            f"   (held-out rms over the {int(kept.sum())} kept poses; on those same poses the baseline's is "
            f"{on_kept * MG:.3g} mg, a gain of {on_kept / diag.final_heldout_rms():.3g}×)"
        )
    if diag.simulation_after is not None:
        lines += ["", "6. " + simulation_text(diag.simulation_after, indent="   ", after=True)]
    if diag.peer is not None:
        lines += ["", *peer_lines(diag)]
    lines += [f"note: {note}" for note in diag.notes]
    return "\n".join(lines)
