"""Calibrate an IMU: the accelerometer from its rests, then the gyroscope from the moves between them.

Shows :func:`optcal.families.gyro.estimator.calibrate_imu_loaded` on what :func:`optcal.load`
read: the accelerometer's lumped model (Lu 2017) from the static poses, then the gyroscope's
scale-misalignment matrix and bias by integrating each move and comparing the turned gravity
with the next rest's (IMU-TK's method, as ``optcal calibrate DATA --imu``).  It prints how far
the integrated gravity lands from the measured one before and after the gyroscope's calibration.

Run::

    python examples/calibrate_imu.py ../shared/data/imutk-xsens/xsens_imutk.csv
    python examples/calibrate_imu.py            # no file: a simulated IMU recording

Without an argument a recording with gyro columns (deg/s, a 0.5/-0.3/0.2 deg/s bias) is simulated.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import optcal
from optcal.families.gyro.estimator import calibrate_imu_loaded


def simulated_imu_recording(folder: Path) -> Path:
    """A raw recording with gyro columns: 30 rests joined by turns, written as CSV."""
    from optcal.families.simulate.poses import uniform_directions
    from optcal.families.simulate.recording import synthesize_recording

    sim = synthesize_recording(optcal.lu2017_reference_model(), uniform_directions(30, 3), gyro=True, rng=4)
    path = folder / "simulated_imu.csv"
    sim.frame.to_csv(path, index=False, float_format="%.7g")
    return path


def main(argv: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(argv[0]) if argv else simulated_imu_recording(Path(tmp))
        reading = optcal.load(path)
        cal = calibrate_imu_loaded(reading)
        print(f"poses: {reading.poses.n}; gyro units: {cal.gyro_units} ({cal.gyro_units_reason})")
        print(f"gyro bias ({cal.gyro_units}):", np.array2string(np.asarray(cal.gyro.bias), precision=4))
        print(f"gravity after each move, rms error: {cal.rms_angle_before_deg:.3f} deg with {cal.before}, "
              f"{cal.rms_angle_after_deg:.3f} deg calibrated")
        cal.save(Path(tmp) / "imu.json")  # the JSON of `optcal calibrate DATA --imu -o imu.json`


if __name__ == "__main__":
    main(sys.argv[1:])
