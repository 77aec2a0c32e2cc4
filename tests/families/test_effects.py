"""The extended forward model, its inversion, the CasADi fit and the measured-like recordings."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.applications.diagnosis.effects import EFFECTS, FITTED, parse_effects
from optcal.applications.diagnosis.effects import MAX_ORDER as FIT_MAX_ORDER
from optcal.applications.diagnosis.problem import ExtendedProblem, PoseData, active_mask, to_model
from optcal.applications.diagnosis.regressors import Regressors
from optcal.core.extended_model import MAX_ORDER, PARAMETRIC, ExtendedModel
from optcal.families.simulate.effects import demo_sensor, recording_with_effect, simulate_extended, warmup_cooldown
from optcal.errors import InputError
from optcal.families.accel.base import Normaliser
from optcal.core.model import lu2017_reference_model, theta_from
from optcal.core.poses import PoseTable
from optcal.families.simulate.poses import uniform_directions


def every_effect(base, temp_ref=30.0, t_ref=100.0) -> ExtendedModel:
    return ExtendedModel(
        base,
        {
            "temperature_bias": [[1e-3, 2e-5, 0], [-5e-4, 0, 0], [0, 0, 0]],
            "temperature_scale": [[0, 0], [0, 0], [3e-4, -1e-5]],
            "bias_drift": [[0, 0, 0], [2e-5, 0, 0], [-1e-5, 0, 0]],
            "scale_nonlinearity": [[0.004], [0.0], [-0.006]],
        },
        temp_ref,
        t_ref,
    )


def test_zero_coefficients_are_the_paper_model() -> None:
    base = lu2017_reference_model()
    d = uniform_directions(30, 1)
    np.testing.assert_allclose(ExtendedModel(base).measure(d), base.measure(d), atol=1e-15)


def test_inversion_recovers_the_linear_output_and_direction() -> None:
    base = demo_sensor()
    model = every_effect(base)
    rng = np.random.default_rng(2)
    d = uniform_directions(50, rng)
    temp, t = rng.uniform(10, 50, 50), rng.uniform(0, 200, 50)
    raw = model.measure(d, temp, t)
    np.testing.assert_allclose(model.linear_output(raw, temp, t), d @ base.C.T, rtol=1e-12, atol=1e-8)
    np.testing.assert_allclose(model.correct(raw, temp, t), d, atol=1e-12)


def test_units_are_per_g_whatever_the_raw_units() -> None:
    """1 mg/°C on y moves the y output of a counts sensor by 10 mg × S_y counts over 10 °C."""
    base = demo_sensor()
    S = np.linalg.norm(base.C, axis=1)
    model = ExtendedModel.with_effect(base, "temperature_bias", "y", 1e-3, temp_ref=20.0)
    d = np.array([[0.0, 0.0, 1.0]])
    shift = model.measure(d, [30.0]) - model.measure(d, [20.0])
    np.testing.assert_allclose(shift[0], [0, 10e-3 * S[1], 0], atol=1e-9)
    # 400 ppm/°C on x scales the x output by 1.004 over 10 °C; 6 mg/g² adds 6 mg at 1 g on z
    scale = ExtendedModel.with_effect(base, "temperature_scale", "x", 4e-4, temp_ref=20.0)
    up_x = np.array([[1.0, 0.0, 0.0]])
    y = up_x @ base.C.T
    np.testing.assert_allclose(scale.measure(up_x, [30.0]) - base.o, y * np.array([1.004, 1, 1]), rtol=1e-12)
    nl = ExtendedModel.with_effect(base, "scale_nonlinearity", "z", 6e-3)
    up_z = np.array([[0.0, 0.0, 1.0]])
    lin = up_z @ base.C.T
    f_z = lin[0, 2] / S[2]
    np.testing.assert_allclose(nl.measure(up_z)[0, 2] - base.o[2], S[2] * (f_z + 6e-3 * f_z**2), rtol=1e-12)


def test_nonlinearity_does_not_depend_on_the_unidentifiable_rotation() -> None:
    """C → C Q with ā → Qᵀ ā gives the same measurements (the force along each sensing axis)."""
    base = lu2017_reference_model()
    Q, _ = np.linalg.qr(np.random.default_rng(3).standard_normal((3, 3)))
    rotated = type(base)(base.C @ Q, base.o)
    d = uniform_directions(20, 4)
    a = ExtendedModel.with_effect(base, "scale_nonlinearity", "x", 5e-3).measure(d)
    b = ExtendedModel.with_effect(rotated, "scale_nonlinearity", "x", 5e-3).measure(d @ Q)
    np.testing.assert_allclose(a, b, atol=1e-14)


def test_casadi_fit_recovers_every_coefficient_from_noise_free_data() -> None:
    """Known truth: all four parametric effects (some of order 2) at once, exact data."""
    base = lu2017_reference_model()
    model = every_effect(base, temp_ref=30.0, t_ref=150.0)
    rng = np.random.default_rng(5)
    n = 120
    d = uniform_directions(n, rng)
    t = np.linspace(0, 300, n)
    temp = 30 + 20 * np.sin(2 * np.pi * t / 300 + 0.3)
    temp[:2] = 10.0, 50.0  # range 10..50 → T_ref = 30 (the fit's reference is the mid-range), t_ref = 150
    poses = simulate_extended(model, d, 0.0, temp=temp, t=t, record_sigma=False)
    reg = Regressors.of(poses)
    assert reg.temp_ref == pytest.approx(30, abs=0.1) and reg.t_ref == pytest.approx(150)
    norm = Normaliser.of(poses.acc)
    data = PoseData(norm.forward(poses.acc), reg.tau, reg.s)
    terms = {("temperature_bias", 0): 2, ("temperature_bias", 1): 1, ("temperature_scale", 2): 2,
             ("bias_drift", 1): 1, ("bias_drift", 2): 1, ("scale_nonlinearity", 0): 1, ("scale_nonlinearity", 2): 1}
    x0 = np.zeros(9 + len(active_mask({})))
    x0[:9] = norm.theta_to_normalised(theta_from(base.T_canonical, base.o))
    x, stats = ExtendedProblem.get(n).solve(x0, data.parameters(np.ones(n) * 1e6), active_mask(terms))
    fitted = to_model(x, norm.centre, norm.scale, reg)
    # every pose calibrates to exactly 1 g under the fitted model (T is the canonical rotation of the true one)
    np.testing.assert_allclose(np.linalg.norm(fitted.correct(poses.acc, temp, t), axis=1), 1.0, atol=1e-9)
    for effect in PARAMETRIC:
        np.testing.assert_allclose(fitted.coefficients[effect], model.coefficients[effect], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(fitted.base.A, base.A, rtol=1e-8)
    np.testing.assert_allclose(fitted.base.o, base.o, atol=1e-9)
    assert stats["success"]


def test_regressors_say_why_a_column_cannot_be_used() -> None:
    acc = uniform_directions(20, 1)
    reg = Regressors.of(PoseTable(acc=acc))
    assert not reg.has_temp and not reg.has_time
    assert any("no temperature column" in s for s in reg.notes)
    reg = Regressors.of(PoseTable(acc=acc, temp=np.full(20, 25.0), t=np.arange(20.0)))
    assert not reg.has_temp and reg.has_time
    assert "constant" in reg.reason_unsupported("temperature_bias")
    assert reg.supports("bias_drift") and reg.supports("scale_nonlinearity") and reg.supports("outliers")


def test_parse_effects() -> None:
    assert parse_effects(None) is None and parse_effects("all") is None
    assert parse_effects("outliers, temperature_bias") == ("temperature_bias", "outliers")
    with pytest.raises(InputError, match="unknown effect"):
        parse_effects("temperature")


def test_layout_covers_every_parametric_order() -> None:
    assert set(PARAMETRIC) | {"outliers"} == set(EFFECTS)
    # the fit's layout: every order of the model's terms, then one offset per session after the first
    assert active_mask({(e, a): FIT_MAX_ORDER[e] for e in FITTED for a in range(3)}).all()


def test_warmup_cooldown_is_not_monotone() -> None:
    t = np.linspace(0, 600, 200)
    temp = warmup_cooldown(t, 22, 38, 27)
    peak = int(np.argmax(temp))
    assert temp[0] == pytest.approx(22) and temp.max() == pytest.approx(38, abs=0.1) and 0.4 < t[peak] / 600 < 0.7
    assert temp[-1] < 30 and abs(np.corrcoef(t, temp)[0, 1]) < 0.6


@pytest.mark.parametrize("effect", ["temperature_bias", "outliers"])
def test_recording_with_effect_has_the_truth(effect: str) -> None:
    frame, truth = recording_with_effect(effect, n_poses=12, dwell_s=2.0, transition_s=1.0, seed=3)
    assert list(frame.columns)[:4] == ["t", "ax", "ay", "az"] and "temp" in frame
    assert np.all(frame["ax"] == np.round(frame["ax"]))  # integer counts
    assert truth.effect == effect
    if effect == "outliers":
        assert len(truth.corrupt_times) == 4 and len(truth.corrupt_radial_g) == 4
    else:
        assert truth.axis in "xyz" and truth.value == pytest.approx(0.8e-3)


def test_model_terms_need_their_columns() -> None:
    model = ExtendedModel.with_effect(lu2017_reference_model(), "bias_drift", "x", 1e-5)
    with pytest.raises(InputError, match="time"):
        model.measure(uniform_directions(3, 0))
    with pytest.raises(InputError, match="unknown effect"):
        ExtendedModel(lu2017_reference_model(), {"temperature": [[1], [0], [0]]})


def test_analytic_jacobian_matches_the_complex_step() -> None:
    """The chain-rule Jacobian of the extended residual against the complex step of the forward formula."""
    from optcal.applications.diagnosis.problem import COMPLEX_STEP, N_X, extended_residuals, residuals_and_jacobian

    rng = np.random.default_rng(8)
    n = 40
    u = uniform_directions(n, rng) * 1.02 + 0.01
    data = PoseData(u, rng.uniform(-1, 1, n), rng.uniform(-1, 1, n))
    x = np.concatenate([[1.01, 0.02, 0.98, -0.01, 0.03, 1.03, 0.01, -0.02, 0.005], rng.normal(0, 2e-3, N_X - 9)])
    r, J = residuals_and_jacobian(x, data)
    X = np.tile(x.astype(complex), (N_X, 1)) + 1j * COMPLEX_STEP * np.eye(N_X)
    reference = np.imag(extended_residuals(X, data.u, data.tau, data.s)).T / COMPLEX_STEP
    np.testing.assert_allclose(r, extended_residuals(x, data.u, data.tau, data.s), rtol=0, atol=1e-15)
    np.testing.assert_allclose(J, reference, rtol=1e-9, atol=1e-12)
