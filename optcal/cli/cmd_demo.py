"""``optcal demo``: calibrate, diagnose, extend and measure the gain, told in plain words.

Without ``--data`` the demo needs no files: it builds a measured-like raw recording with one
hidden effect from the package's own simulator (:func:`optcal.families.simulate.effects.recording_with_effect`),
reads it like any recording, and tells the story; what was hidden is revealed only at the end,
as a check.  ``optcal demo --data FILE`` tells the same story for any recording or pose table.
"""

from __future__ import annotations

import tempfile
import textwrap
from pathlib import Path
from typing import Any

import click

from optcal.cli.cmd_diagnose import diagnosis_options, progress_printer, settings_from
from optcal.cli.data_options import DATA_PATH, data_options
from optcal.families.simulate.effects import HIDDEN_EFFECTS


def say(text: str = "", indent: int = 0) -> None:
    """Print a paragraph wrapped to 96 columns."""
    if not text:
        click.echo()
        return
    pad = " " * indent
    click.echo(textwrap.fill(text, width=96, initial_indent=pad, subsequent_indent=pad))


def _mg(x: float) -> str:
    return f"{x * 1e3:.2g} mg" if x < 0.01 else f"{x * 1e3:.3g} mg"


@click.command()
@click.option("--data", "data", type=DATA_PATH, default=None,
              help="Tell the story for this recording or pose table instead of a simulated one.")
@click.option("--hidden", type=click.Choice(["random", *HIDDEN_EFFECTS]), default="random", show_default=True,
              help="The effect hidden in the simulated recording (random: drawn with --seed).")
@data_options
@diagnosis_options
def demo(data: str | None, hidden: str, effects: str | None, folds: int, simulations: int, alpha: float,
         seed: int, method: str, plot_dir: str | None, quiet: bool, **data_opts: Any) -> None:
    """Calibrate, find what the paper's model gets wrong, extend it, and show the gain (needs no files)."""
    import numpy as np

    from optcal.cli.data_options import data_line, load_data
    from optcal.applications.diagnosis import Diagnoser
    from optcal.report.diagnosis_figures import save_figures
    from optcal.families.simulate.effects import recording_with_effect

    truth = None
    say("optcal demo: calibrate an accelerometer, find what the calibrated model gets wrong, name the "
        "cause, extend the model, and measure the gain on poses it has not seen.")
    say()
    with tempfile.TemporaryDirectory() as tmp:
        if data is None:
            rng = np.random.default_rng(seed)
            effect = str(rng.choice(HIDDEN_EFFECTS)) if hidden == "random" else hidden
            frame, truth = recording_with_effect(effect, seed=seed)
            path = str(Path(tmp) / "simulated_recording.csv")
            frame.to_csv(path, index=False, float_format="%.6f")
            temp = frame["temp"].to_numpy()
            say(f"1. The recording. I simulated what a bench recording looks like: a 16-bit MEMS accelerometer "
                f"sampled at 100 Hz in raw counts, set down by hand in 48 orientations and left to rest 4 s in each "
                f"({len(frame):,} samples, {frame['t'].iloc[-1]:.0f} s), while it warmed up from "
                f"{temp[0]:.0f} °C to {temp.max():.0f} °C and cooled down to {temp[-1]:.0f} °C. The simulation "
                "put one effect into the data that the paper's model does not have. Which one, and on which axis, "
                "stays hidden until the end; the analysis below sees only the recording.")
            loaded = load_data(path, **data_opts)
        else:
            say("1. The recording.")
            loaded = load_data(data, **data_opts)
            path = data
        poses = loaded
        say(data_line(path if data else "the simulated recording", poses), indent=3)
        say()
        settings = settings_from(effects, folds, simulations, alpha, seed, method)
        diag = Diagnoser(settings, progress_printer()).run(poses)

    noise = float(np.median(poses.sigma)) if poses.sigma is not None else None
    line = (f"2. Calibrate with the paper's model (Lu 2017: a scale-and-skew matrix T, a bias o and white noise), "
            f"over {poses.n} static poses ({diag.baseline_source}, refined by maximum likelihood). After calibration the magnitude of each pose "
            f"should be exactly 1 g; it is off by {_mg(diag.baseline_rms())} rms")
    if noise is not None and poses.units == "g":
        line += f", while the noise of a pose mean is only about {_mg(noise)}"
    elif noise is not None:
        line += f", while the noise of each pose mean predicts about {_mg(diag.simulation.statistics['rms_g'].simulated_median)}"
    say(line + f". On poses left out of the fit ({diag.settings.folds}-fold) it is off by "
        f"{_mg(diag.baseline_heldout_rms())}.")
    say()
    sim = diag.simulation
    say(f"3. Simulate the calibrated model. If the model were right, data simulated from it would look like the "
        f"measurements. I simulated it {sim.simulations} times on the same poses and compared the residuals:")
    if not sim.outside_band:
        say("every statistic of the measured residuals lies inside the simulated band: the simulation reproduces "
            "the measurements.", indent=3)
    for name in sim.outside_band:
        st = sim.statistics[name]
        lo, hi = st.band
        say(f"- {st.meaning}: measured {st.measured:.3g}, but the simulations give {lo:.3g} to {hi:.3g}.", indent=3)
    say()
    say("4. Name the cause. Each candidate effect (temperature bias and scale, bias drift in time, scale "
        "nonlinearity, outlier poses) is added to the model per axis, fitted jointly with T and o, and kept "
        "only if a likelihood-ratio test, the BIC and the error on held-out poses all say it helps.")
    if not diag.findings:
        say("Nothing passes: the paper's model explains these data.", indent=3)
    from optcal.core.extended_model import format_value

    for f in diag.findings:
        if f.rows is not None:
            say(f"- outliers: poses {', '.join(map(str, f.rows))} do not fit: {f.cause}.", indent=3)
        else:
            values = "; ".join(f"axis {a}: {format_value(f.effect, f.estimate[a], f.stderr[a])}" for a in f.axes)
            say(f"- {f.effect} ({values}): {f.cause}.", indent=3)
    for decision in diag.decisions:
        say(decision.text, indent=3)
    say()
    say(f"5. Extend the model and refit: {diag.final.describe()}. The error on held-out poses goes from "
        f"{_mg(diag.baseline_heldout_rms())} to {_mg(diag.final_heldout_rms())}: a gain of {diag.gain():.2f}×.")
    if diag.simulation_after is not None:
        outside = diag.simulation_after.outside_band
        stats = diag.simulation_after.statistics
        say("Simulated again, the extended model now reproduces the measurements"
            + ("." if not outside else
               " except for " + "; ".join(stats[n].meaning for n in outside)
               + f" (with {len(stats)} statistics checked at {diag.simulation_after.band * 100:g} %, one may fall "
               "outside by chance)."), indent=3)
    if plot_dir:
        from optcal.cli.outputs import plot_folder

        for p in save_figures(diag, plot_folder(plot_dir)):
            say(f"figure: {p}", indent=3)
    if truth is not None:
        say()
        say(f"6. The reveal. Hidden in the recording was {truth.describe()}.")
        say(_verdict(diag, truth), indent=3)


def _verdict(diag: Any, truth: Any) -> str:
    """Did the diagnosis find what was hidden?"""
    found = {f.effect: f for f in diag.findings}
    if truth.effect == "outliers":
        rows = truth.corrupt_rows(diag.poses)
        got = set(found["outliers"].rows or []) if "outliers" in found else set()
        sideways = [f"pose {r} ({abs(g) * 1e3:.1f} mg)" for r, g in zip(rows, truth.corrupt_radial_g) if r not in got]
        text = (f"The diagnosis flagged poses {sorted(got) if got else 'none'}; the corrupted poses were poses {rows}: "
                f"{len(got & set(rows))} of {len(rows)} found, {len(got - set(rows))} flagged wrongly.")
        if sideways:
            text += (" Missed: " + ", ".join(sideways) + " — the part of the shift along the pose's own direction, the "
                     "only part that changes the measured magnitude; a sideways shift only tilts the pose, which no "
                     "static calibration can see and which does the calibration no harm.")
        return text
    f = found.get(truth.effect)
    if f is None or truth.axis not in f.axes:
        named = ", ".join(f"{g.effect} ({', '.join(g.axes)})" for g in diag.findings) or "nothing"
        return f"The diagnosis named {named}: it missed the hidden effect."
    est = f.estimate[truth.axis]
    err = abs(est - truth.value) / abs(truth.value)
    others = [g.effect for g in diag.findings if g is not f]
    extra = f" It also named {', '.join(others)}, which was not hidden." if others else ""
    return (f"The diagnosis named the right effect on the right axis and estimated {est:.4g} "
            f"against the true {truth.value:.4g} ({100 * err:.1f} % off).{extra}")
