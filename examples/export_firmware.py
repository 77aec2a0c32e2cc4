"""Export a calibration to PX4 and ArduPilot parameters, with what the firmware's model loses.

Shows :func:`optcal.applications.export.export`: the firmwares hold an offset and a diagonal
scale per axis only (``CAL_ACC0_XOFF``/``XSCALE``, ``INS_ACCOFFS_X``/``INS_ACCSCAL_X``), so the
exporter fits that reduced model to the calibration's poses, measures the rms error of ``|a|``
it adds, and refuses when it exceeds ``max_loss_g`` (as ``optcal export CAL --format px4``).

Run::

    python examples/export_firmware.py ../shared/data/imutk-xsens/xsens_imutk.csv
    python examples/export_firmware.py            # no file: a simulated recording

A recording in raw counts needs the driver's sensitivity as the second argument, counts per g
(the driver's or the datasheet's): the firmware's parameters are in m/s² of the driver's output.
"""

import sys
import tempfile
from pathlib import Path

import optcal
from optcal.applications.export import export
from optcal.applications.export.base import ExportOptions


def simulated_recording(folder: Path) -> Path:
    """A raw recording (g) of a sensor with small cross-axis terms, as a firmware can almost hold."""
    from optcal.families.simulate.poses import uniform_directions
    from optcal.families.simulate.recording import synthesize_recording

    sensor = optcal.LumpedModel.from_physical(scale=[1.02, 0.98, 1.01], rho=0.001, phi=-0.002, lam=0.001,
                                              bias=[0.03, -0.02, 0.05])  # angles in radians
    sim = synthesize_recording(sensor, uniform_directions(30, 5), sigma=0.001, gyro=False, rng=6)
    path = folder / "simulated_recording.csv"
    sim.frame.to_csv(path, index=False, float_format="%.7g")
    return path


def main(argv: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(argv[0]) if argv else simulated_recording(Path(tmp))
        counts_per_g = float(argv[1]) if len(argv) > 1 else None
        calibration = optcal.calibrate(optcal.load(path)).calibration
        options = ExportOptions(counts_per_g=counts_per_g, source=str(path.name))
        for fmt in ("px4", "ardupilot"):
            try:
                result = export(calibration, fmt, options)
            except optcal.InputError as exc:  # e.g. counts without counts_per_g: one line, as the command says it
                sys.exit(f"error: {exc}")
            print(f"--- {fmt}: the firmware's model adds {result.loss.describe() if result.loss else 'nothing'}")
            print(result.text.strip())
            for note in result.notes:
                print(f"note: {note}")


if __name__ == "__main__":
    main(sys.argv[1:])
