"""Load a raw accelerometer recording, calibrate it and save the calibration.

Shows the main job in Python: :func:`optcal.load` reads the file and prints every decision it
made (kind, columns, units, rate, the rests found), :func:`optcal.calibrate` fits the lumped
model ``ā = T (a − o)`` (Lu 2017, eq. 4) by maximum likelihood from the convex fit, and
``save`` writes the same JSON as ``optcal calibrate DATA -o FILE``.

Run::

    python examples/calibrate_raw_log.py ../shared/data/imutk-xsens/xsens_imutk.csv
    python examples/calibrate_raw_log.py            # no file: a simulated recording

Without an argument a recording is simulated (Lu 2017's sensor, 40 poses, 100 Hz, with gyro
columns), so the example runs anywhere.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import optcal


def simulated_recording(folder: Path) -> Path:
    """A raw recording of Lu 2017's sensor set down in 40 directions, written as CSV."""
    from optcal.families.simulate.poses import uniform_directions
    from optcal.families.simulate.recording import synthesize_recording

    sim = synthesize_recording(optcal.lu2017_reference_model(), uniform_directions(40, 1), rng=2)
    path = folder / "simulated_recording.csv"
    sim.frame.to_csv(path, index=False, float_format="%.7g")
    return path


def main(argv: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(argv[0]) if argv else simulated_recording(Path(tmp))
        reading = optcal.load(path)
        print("\n".join(reading.lines()))  # every decision with its reason and the flag that overrides it
        result = optcal.calibrate(reading)
        out = Path(tmp) / "calibration.json"
        result.save(out)
        again = optcal.load_calibration(out)
        T, o = np.asarray(again.T), np.asarray(again.o)
        print(f"poses: {reading.poses.n}")
        print("T =", np.array2string(T, precision=5))
        print("o =", np.array2string(o, precision=5))
        print(f"saved and read back: {out.name} ({out.stat().st_size} bytes)")


if __name__ == "__main__":
    main(sys.argv[1:])
