"""Regressions of the diagnosis on the shared recordings since the last release (issue 39), one test each.

IMU-TK's Xsens log: the last release named ``bias_drift(z)`` with a held-out gain of 1.18; since the rest
model replaced the detector (c43cfa6 and its branch, merged at 0b9c92e) it names nothing (gain 1.0).  Bisected over
the last 90 commits: every revision on the old detector names it, every one on the rest model does not.  The
cause is the poses, not the diagnosis: the rest model keeps more samples at most rests' ends (typically 4-10 %, up to 35 %) (the rest at
282.6 s: 388 -> 525 samples, the σ of its mean 0.18 -> 0.33 counts, its x mean moved 0.46 counts), samples of the
moves' settling, and the baseline's reduced χ² rises from 4.19 to 6.19: the drift is then below what that scatter
lets a test name.  With 0.25 s trimmed from each rest's ends the current code names it again (gain 1.19).
The rest model is branch ``rest``'s to fix; the diagnosis is not made to work around it.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from optcal.applications.diagnosis import diagnose


def xsens(shared_data: Path) -> Path:
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    return path


def test_the_xsens_bias_drift_on_z_is_named_from_rests_without_their_settling_ends(shared_data: Path) -> None:
    """The diagnosis itself still finds the drift the last release found, once the rests hold no settling samples."""
    from optcal.data import load

    diag = diagnose(load(xsens(shared_data), trim_s=0.25), simulations=0)
    assert [(f.effect, f.axes) for f in diag.findings] == [("bias_drift", ["z"])]
    assert diag.to_dict()["final"]["gain"] >= 1.1


def test_the_xsens_bias_drift_on_z_is_named_as_in_the_last_release(shared_data: Path) -> None:
    """As the last release: bias_drift(z), held-out gain 1.18 (1.15 now).  Lost while a hand's touch before a move
    (a twitch, then the sensor held 0.4 mg off for 0.5 s) was joined into its rest; the rest model now leaves such a
    piece out (``touches``), and with ``--keep-touches`` the drift is hidden again."""
    from optcal.data import load

    assert diagnose(load(xsens(shared_data), keep_touches=True), simulations=0).findings == []
    diag = diagnose(load(xsens(shared_data)), simulations=0)
    assert [(f.effect, f.axes) for f in diag.findings] == [("bias_drift", ["z"])]
    assert diag.to_dict()["final"]["gain"] >= 1.1
