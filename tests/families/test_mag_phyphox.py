"""phyphox's magnetometer export (``"Time (s)","Magnetic field x (µT)",…,"Absolute field (µT)"``: heinrichsemj/
PS_magfield's ``Arduino/Magnetometer.csv``, the app's own layout) was refused with "no magnetometer columns ... map them
with --columns": the column names were normalised with the micro sign dropped (``magnetic_field_x_t``), and the ``t``
left is no unit word, so no alias matched.  The micro sign (U+00B5) and the Greek mu (U+03BC), which phyphox and
other apps write for it, are now read as ``u``: the columns are found and their unit is stated by the names."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli_run import run

FIELD_UT = 49.0  # the Earth's field in central Europe (phyphox's home), µT
HARD_IRON_UT = (-6.0, 3.5, 11.0)  # a phone's residual hard iron, µT


def _write_phyphox(path, micro: str, n: int = 1500, seed: int = 5) -> None:
    """A phone turned through every direction, 100 Hz, 0.4 µT noise, in phyphox's five columns."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    m = (np.asarray(HARD_IRON_UT) + FIELD_UT * u / np.linalg.norm(u, axis=1, keepdims=True)
         + rng.normal(scale=0.4, size=(n, 3)))
    unit = f"{micro}T"
    head = ",".join(f'"{h}"' for h in ("Time (s)", f"Magnetic field x ({unit})", f"Magnetic field y ({unit})",
                                        f"Magnetic field z ({unit})", f"Absolute field ({unit})"))
    rows = [f"{0.0185 + 0.01 * i:.9E},{x:.9E},{y:.9E},{z:.9E},{np.sqrt(x * x + y * y + z * z):.9E}"
            for i, (x, y, z) in enumerate(m)]
    path.write_text(head + "\n" + "\n".join(rows) + "\n", encoding="utf-8")


@pytest.mark.parametrize("micro", ["\u00b5", "\u03bc"], ids=["micro-sign", "greek-mu"])
def test_phyphox_magnetometer_export_is_read_in_ut(tmp_path, capsys, micro):
    """Read without a flag: the three axes found (not the absolute field), µT as stated, field and hard iron."""
    path = tmp_path / "Magnetometer.csv"
    _write_phyphox(path, micro)
    code, out, err = run(["calibrate", str(path), "--sensor", "mag", "--json"], capsys)
    assert code == 0, err
    cal = json.loads(out)
    assert cal["units"]["input"] == "uT"
    assert "stated" in err and "Absolute field" not in err.split("magnetometer columns:")[1].splitlines()[0]
    assert abs(cal["field_strength"] - FIELD_UT) < 0.01 * FIELD_UT
    assert np.allclose(cal["o"], HARD_IRON_UT, atol=0.01 * FIELD_UT)
