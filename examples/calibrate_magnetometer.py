"""Calibrate a magnetometer: hard iron (an offset) and soft iron (a matrix) from samples turned through space.

Shows :func:`optcal.families.mag.calibration.calibrate_mag` on what
:func:`optcal.families.mag.samples.read_mag` read: the samples of a constant field lie on an
ellipsoid, ``|T (m − o)| = 1`` with the field's strength stated beside it; the fit chooses the
smallest form the samples support (offsets, diagonal or full), as
``optcal calibrate DATA --sensor mag``.

Run::

    python examples/calibrate_magnetometer.py ../shared/data/ckexplorer-holds/acc_mag_log.csv
    python examples/calibrate_magnetometer.py            # no file: simulated samples

Without an argument 3,000 samples of a 0.35-gauss field are simulated through a planted soft iron
(a symmetric matrix) and hard iron (0.12, −0.30, 0.07 gauss), and the fitted offset is compared
with the planted one.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

from optcal.families.mag.calibration import calibrate_mag
from optcal.families.mag.samples import read_mag

HARD_IRON = np.array([0.12, -0.30, 0.07])  # gauss
SOFT_IRON = np.array([[0.35, 0.02, -0.01], [0.02, 0.31, 0.015], [-0.01, 0.015, 0.38]])  # gauss per unit direction


def simulated_samples(folder: Path) -> Path:
    """Samples m = S u + o + noise for directions u uniform on the sphere, as CSV (mx, my, mz in gauss)."""
    rng = np.random.default_rng(3)
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    m = u @ SOFT_IRON.T + HARD_IRON + rng.normal(scale=0.002, size=u.shape)
    path = folder / "simulated_mag.csv"
    np.savetxt(path, m, delimiter=",", header="mx,my,mz", comments="", fmt="%.6f")
    return path


def main(argv: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(argv[0]) if argv else simulated_samples(Path(tmp))
        samples = read_mag(path)
        result = calibrate_mag(samples)
        cal = result.calibration
        print(f"form: {result.fit.fit.form}; units: {cal.units}; field strength {cal.field_strength:.4g} {cal.units}")
        print("hard iron o =", np.array2string(cal.o, precision=4))
        print("soft iron T =", np.array2string(cal.T, precision=4))
        if not argv:
            print(f"offset error against the planted one: {np.linalg.norm(cal.o - HARD_IRON) * 1e3:.2f} mgauss")
        cal.save(Path(tmp) / "mag.json")  # the JSON of `optcal calibrate DATA --sensor mag -o mag.json`


if __name__ == "__main__":
    main(sys.argv[1:])
