"""The calibration type family: round trips, the registry (optcal.families.calibration_files), version checks,
correct(), validity range."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import optcal.families.calibration_files as calibration_files
from optcal.families.caltypes import (
    Calibration,
    ExtendedCalibration,
    ExtendedTerm,
    FitPoses,
    LumpedCalibration,
    SixPositionCalibration,
    ValidityRange,
    ValidityRangeWarning,
)
from optcal.core.extended_model import ExtendedModel
from optcal.families.simulate.effects import demo_sensor
from optcal.errors import InputError
from optcal.core.model import lu2017_reference_model
from optcal.families.simulate.poses import uniform_directions

RNG_DIRECTIONS = 11


def sensor_counts() -> ExtendedModel:
    """The demo sensor (counts) with every kind of term, orders above one included."""
    return ExtendedModel(
        demo_sensor(),
        {
            "temperature_bias": [[0.4e-3, 0.0], [0.0, 0.0], [-0.9e-3, 2e-5]],
            "temperature_scale": [[0.0], [300e-6], [0.0]],
            "bias_drift": [[0.0], [0.0], [2e-6]],
            "scale_nonlinearity": [[5e-3], [0.0], [0.0]],
        },
        temp_ref=30.0,
        t_ref=100.0,
    )


def samples(n: int = 40) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit directions, temperatures (22-38 °C) and times (0-200 s) and their noise-free measurements."""
    d = uniform_directions(n, rng=RNG_DIRECTIONS)
    temp = np.linspace(22.0, 38.0, n)
    t = np.linspace(0.0, 200.0, n)
    return d, temp, t, sensor_counts().measure(d, temp, t)


def every_type() -> list[Calibration]:
    d, temp, t, acc = samples()
    fitted = FitPoses(acc, temp, t)
    W = np.linalg.inv(lu2017_reference_model().C)  # a full W with the mounting rotation
    return [
        LumpedCalibration.from_model(lu2017_reference_model(), "g"),
        LumpedCalibration.from_model(demo_sensor(), "counts", fitted),
        SixPositionCalibration(W, [0.01, -0.02, 0.03], "m/s^2", FitPoses(acc[:6] / 1e3)),
        ExtendedCalibration.from_model(sensor_counts(), "counts", fitted_on=fitted),
    ]


@pytest.mark.parametrize("index", range(4))
def test_every_type_survives_save_and_load(index, tmp_path):
    cal = every_type()[index]
    path = tmp_path / "cal.json"
    cal.save(path)
    back = calibration_files.load(path)
    assert type(back) is type(cal)
    assert back == cal
    assert calibration_files.load(json.loads(path.read_text())) == cal
    d, temp, t, acc = samples()
    raw = acc if cal.units == "counts" else acc / 16400.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityRangeWarning)
        np.testing.assert_allclose(back.correct(raw, temp, t), cal.correct(raw, temp, t), rtol=0, atol=1e-12)
    # the file says what it is, in which units
    data = json.loads(path.read_text())
    assert data["cal_type"] == cal.cal_type and data["format_version"] == "2.0"
    assert data["units"]["input"] == cal.units and data["units"]["output"] == "g"


def test_value_equality_sees_every_number():
    cal = every_type()[3]
    other = calibration_files.load(cal.to_dict())
    assert other == cal
    other.terms = other.terms[:-1]
    assert other != cal
    moved = calibration_files.load(cal.to_dict())
    moved.o = moved.o + 1e-9
    assert moved != cal
    assert LumpedCalibration(np.eye(3), np.zeros(3)) != SixPositionCalibration(np.eye(3), np.zeros(3))


def test_unknown_type_and_newer_major_version_are_refused(tmp_path):
    d = every_type()[0].to_dict()
    with pytest.raises(InputError, match="unknown cal_type 'barometer'.*extended, imu, lumped, magnetometer, peer, sixpos_full"):
        calibration_files.load({**d, "cal_type": "barometer"})
    path = tmp_path / "new.json"
    path.write_text(json.dumps({**d, "format_version": "3.0"}))
    with pytest.raises(InputError, match=r"new.json: .*format version 3.0, newer than this optcal reads \(2.x"):
        calibration_files.load(path)
    # a newer minor version only adds optional fields: read
    assert calibration_files.load({**d, "format_version": "2.7", "new_optional_field": 1}) == every_type()[0]
    with pytest.raises(InputError, match="no such calibration file"):
        calibration_files.load(tmp_path / "missing.json")
    with pytest.raises(InputError, match="not an optcal calibration file"):
        calibration_files.load({"T": [1]})


def test_registry_is_open_to_a_new_type():
    calibration_files.register("lumped_copy", "optcal.families.caltypes.lumped:LumpedCalibration")
    try:
        assert calibration_files.calibration_class("lumped_copy") is LumpedCalibration
    finally:
        del calibration_files.CAL_TYPES["lumped_copy"]


def test_lumped_needs_the_canonical_T():
    model = lu2017_reference_model()
    with pytest.raises(InputError, match="lower-triangular"):
        LumpedCalibration(model.T, model.o)
    cal = LumpedCalibration.from_any_T(model.T, model.o)
    d = uniform_directions(20, rng=1)
    np.testing.assert_allclose(np.linalg.norm(cal.correct(model.measure(d)), axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(cal.theta, model.theta, atol=1e-14)


def test_extended_correct_inverts_the_forward_model():
    d, temp, t, acc = samples()
    cal = ExtendedCalibration.from_model(sensor_counts(), "counts")
    assert cal.needs == ("temp", "t")
    assert {(term.effect, term.axis, term.order) for term in cal.terms} == {
        ("temperature_bias", "x", 1), ("temperature_bias", "z", 2), ("temperature_scale", "y", 1),
        ("bias_drift", "z", 1), ("scale_nonlinearity", "x", 1),
    }
    # the lumped rotation is fixed by the canonical T, so the directions come back up to it
    Q = cal.T @ demo_sensor().C
    np.testing.assert_allclose(cal.correct(acc, temp, t), d @ Q.T, atol=1e-12)
    np.testing.assert_allclose(Q @ Q.T, np.eye(3), atol=1e-12)
    # dropping the terms leaves errors of the size of the terms
    assert np.max(np.abs(cal.lumped().norm_errors(acc))) > 1e-3


def test_extended_refuses_a_missing_column():
    d, temp, t, acc = samples(5)
    cal = ExtendedCalibration.from_model(sensor_counts(), "counts")
    with pytest.raises(InputError, match=r"temperature_bias on x, temperature_bias on z, temperature_scale on y: pass temp="):
        cal.correct(acc, None, t)
    with pytest.raises(InputError, match="bias_drift on z: pass t="):
        cal.correct(acc, temp)
    with pytest.raises(InputError, match="temp has 3 values for 5 samples"):
        cal.correct(acc, temp[:3], t)
    with pytest.raises(InputError, match="give the reference temp_ref"):
        ExtendedCalibration(cal.T, cal.o, (ExtendedTerm("temperature_bias", "z", (1e-3,)),))


def test_extended_warns_outside_its_validity_range_and_says_by_how_much():
    d, temp, t, acc = samples()
    cal = ExtendedCalibration.from_model(sensor_counts(), "counts", fitted_on=FitPoses(acc, temp, t))
    assert cal.validity.temp == (22.0, 38.0) and cal.validity.t == (0.0, 200.0)
    assert cal.validity.norm_g == pytest.approx((1.0, 1.0), abs=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cal.correct(acc, temp + 0.9, t)  # inside the 1 °C margin
    hot = temp.copy()
    hot[-3:] = 45.0
    with pytest.warns(ValidityRangeWarning, match=r"temperature 45 °C is 7 °C above the fitted range 22..38 °C \(3 of 40"):
        out = cal.correct(acc, hot, t)
    assert cal.out_of_range(out, hot, t).sum() == 3
    with pytest.warns(ValidityRangeWarning, match=r"\|a\| 2.0\d* g is 1.0\d* g above"):
        cal.correct(2 * acc[:1] - cal.o, temp[:1], t[:1])
    assert ValidityRange.from_dict(cal.validity.to_dict()) == cal.validity


def test_fit_poses_and_calibrations_compare_values_not_identity():
    a, b = every_type(), every_type()
    assert all(x == y for x, y in zip(a, b))
    assert a[1].fitted_on == b[1].fitted_on
