"""Diagnose a calibration: what the paper's model gets wrong, its cause, and the gain of fixing it.

Shows :func:`optcal.applications.diagnosis.diagnose` on the static poses :func:`optcal.load`
found: the lumped model (Lu 2017) is fitted, simulated from (a parametric bootstrap: do the
measured residuals look like the simulated ones?), and each candidate effect (temperature bias
and scale, a bias drift in time, scale nonlinearity, outlier poses) is added per axis and kept
only when a likelihood-ratio test, the BIC and the error on held-out poses agree, as
``optcal diagnose DATA`` does.

Run::

    python examples/diagnose.py ../shared/data/imutk-xsens/xsens_imutk.csv
    python examples/diagnose.py            # no file: a recording with a hidden temperature bias

Without an argument the demo's recording is simulated (16-bit counts, 48 rests while the sensor
warms up and cools down) with a temperature-dependent bias on its z axis, which the diagnosis
should name.
"""

import sys
import tempfile
from pathlib import Path

import optcal
from optcal.applications.diagnosis import diagnose
from optcal.report.diagnosis_text import diagnosis_report


def simulated_recording(folder: Path) -> Path:
    """The demo's recording with a temperature-dependent bias on z (``optcal demo --hidden temperature_bias``)."""
    from optcal.families.simulate.effects import recording_with_effect

    frame, hidden = recording_with_effect("temperature_bias", "z", seed=1)
    path = folder / "recording_with_a_hidden_effect.csv"
    frame.to_csv(path, index=False, float_format="%.6f")
    print(f"hidden: {hidden.effect}({hidden.axis}) = {hidden.value:g} g per °C")
    return path


def main(argv: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(argv[0]) if argv else simulated_recording(Path(tmp))
        poses = optcal.load(path).poses
        diag = diagnose(poses, simulations=100, seed=0)
        print(diagnosis_report(diag))
        names = ", ".join(f"{f.effect}({','.join(map(str, f.axes))})" for f in diag.findings if f.rows is None)
        print(f"named: {names or 'nothing'}; held-out error {diag.baseline_heldout_rms() * 1e3:.3f} -> "
              f"{diag.final_heldout_rms() * 1e3:.3f} mg (gain {diag.gain():.2f})")


if __name__ == "__main__":
    main(sys.argv[1:])
