"""Hidden effects in real recordings, and the same recording in other units (issue 13's families, in CI).

The hidden-effects study (`studies/diagnose_hidden_effects.py`) runs these families over 120-400 seeds; these tests
run one or two cases each, so that a change that breaks a family fails here first.  The truth stays in
the test: `diagnose` sees only the recording.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from optcal.applications.diagnosis import diagnose
from optcal.core.model import LumpedModel

XSENS_COLUMNS = {"t_s": "t", "acc_x_counts": "ax", "acc_y_counts": "ay", "acc_z_counts": "az"}


@functools.lru_cache(maxsize=None)
def _xsens_and_its_calibration(path: Path) -> tuple[pd.DataFrame, LumpedModel]:
    """The Xsens log with its synthetic temperature channel, and its own lumped calibration (``mle``): the same for
    every planting, so read and fitted once per test process (speed only: 14 call sites)."""
    from optcal.data import load
    from optcal.families.accel.calibration import calibrate
    from optcal.families.simulate.effects import warmup_cooldown

    raw = pd.read_csv(path).rename(columns=XSENS_COLUMNS)[["t", "ax", "ay", "az"]]
    raw["temp"] = warmup_cooldown(raw["t"].to_numpy(), 22.0, 38.0, 27.0)
    return raw, calibrate(load(path), "mle").model


@functools.lru_cache(maxsize=None)
def _distorted_csv(path: Path, effect: str | None, axis: int, value: float) -> str:
    """The planted log's CSV text (writing it is most of a planting's cost; the unplanted one is asked for 7 times)."""
    from optcal.core.extended_model import ExtendedModel
    from optcal.families.simulate.effects import distort_recording

    raw, base = _xsens_and_its_calibration(path)
    model = (ExtendedModel(base, temp_ref=30.0, t_ref=256.0) if effect is None else
             ExtendedModel.with_effect(base, effect, axis, value, temp_ref=30.0, t_ref=256.0))
    return str(distort_recording(raw.copy(), model).rename(columns={v: k for k, v in XSENS_COLUMNS.items()}).to_csv(
        index=False, float_format="%.8g"))


def planted_xsens(tmp_path: Path, path: Path, effect: str | None, axis: int, value: float, name: str):
    """The Xsens log with ``effect`` planted on ``axis`` through its own lumped calibration, and a synthetic
    warm-up/cool-down temperature channel (the log has none), read back as ``optcal diagnose`` reads it (a new
    table each call, from a file written into ``tmp_path``)."""
    from optcal.data import load

    out = tmp_path / f"{name}.csv"
    out.write_text(_distorted_csv(path, effect, axis, value), encoding="utf-8")
    return load(out)


@pytest.mark.parametrize(("effect", "axis", "value"), [("temperature_bias", 0, 0.4e-3),
                                                       ("scale_nonlinearity", 1, -4e-3)])
def test_an_effect_planted_in_the_real_xsens_log_is_named_on_its_axis(
        shared_data: Path, tmp_path: Path, effect: str, axis: int, value: float) -> None:
    """Planted in the real log (its own noise and its own rise-and-fall z bias stay in): named on its axis within
    30 %, and nothing named that the same log without the planting does not already show."""
    path = shared_data / "imutk-xsens" / "xsens_imutk.csv"
    if not path.exists():
        pytest.skip("imutk-xsens recording absent")
    own = diagnose(planted_xsens(tmp_path, path, None, 0, 0.0, "unplanted"), simulations=0)
    diag = diagnose(planted_xsens(tmp_path, path, effect, axis, value, "planted"), simulations=0)
    found = diag.finding(effect)
    letter = "xyz"[axis]
    assert found is not None and letter in found.axes
    assert found.estimate[letter] == pytest.approx(value, rel=0.3)
    named = {(f.effect, a) for f in diag.findings for a in f.axes}
    assert named - {(f.effect, a) for f in own.findings for a in f.axes} == {(effect, letter)}


def test_the_same_recording_in_counts_and_in_m_per_s2_gives_the_same_diagnosis(tmp_path: Path) -> None:
    """A raw 100 Hz recording with a hidden temperature coefficient, written once in counts and once in m/s²:
    the same finding, axis and estimate (the coefficients are per g whatever the input units)."""
    from optcal.data import load
    from optcal.families.simulate.effects import recording_with_effect

    frame, truth = recording_with_effect("temperature_bias", seed=3)
    frame.to_csv(tmp_path / "counts.csv", index=False, float_format="%.8g")
    si = frame.copy()
    for c in ("ax", "ay", "az"):  # the demo sensor's nominal 16,384 counts per g, written as m/s²
        si[c] = si[c] * 9.80665 / 16384.0
    si.rename(columns={"ax": "acc_x_mps2", "ay": "acc_y_mps2", "az": "acc_z_mps2"}).to_csv(
        tmp_path / "si.csv", index=False, float_format="%.10g")
    in_counts, in_si = (diagnose(load(tmp_path / name), simulations=0) for name in ("counts.csv", "si.csv"))
    assert in_counts.poses.units == "counts" and in_si.poses.units == "m/s^2"
    for diag in (in_counts, in_si):
        assert [(f.effect, f.axes) for f in diag.findings] == [("temperature_bias", [truth.axis])]
    a = truth.axis
    assert in_counts.findings[0].estimate[a] == pytest.approx(truth.value, rel=0.3)
    assert in_si.findings[0].estimate[a] == pytest.approx(in_counts.findings[0].estimate[a], rel=1e-3)
    assert np.isclose(in_si.final_heldout_rms(), in_counts.final_heldout_rms(), rtol=1e-3)
