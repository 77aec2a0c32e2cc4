"""Diagnosis: hidden effects are named with the right axis and size; clean data give no finding.

The data sets come from :mod:`diagnosis_cases` (the acceptance ranges of issue 4); the test
holds the truth and :class:`optcal.applications.diagnosis.Diagnoser` never sees it.  The false-finding rate
over many seeds is measured in ``studies/diagnose_acceptance.py``; here a few seeds guard it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers.diagnosis_cases import make_case

from optcal.families.accel.calibration import calibrate
from optcal.data import load
from optcal.applications.diagnosis import Diagnoser, DiagnosisSettings, diagnose
from optcal.applications.diagnosis.effects import EFFECTS
from optcal.applications.diagnosis.fitting import Fitter
from optcal.applications.diagnosis.regressors import Regressors
from optcal.core.extended_model import ExtendedModel
from optcal.families.simulate.effects import recording_with_effect, simulate_extended, warmup_cooldown
from optcal.errors import InputError
from optcal.core.model import lu2017_reference_model
from optcal.core.poses import PoseTable
from optcal.core.jsonio import jsonable
from optcal.families.simulate.poses import uniform_directions
from optcal.report.diagnosis_text import diagnosis_report

SIMULATIONS = 30


def oracle_p_value(case) -> float:
    """p value of the hidden term for an oracle that knows which term to test (no selection)."""
    start = calibrate(case.poses, "mle")
    fitter = Fitter(case.poses, Regressors.of(case.poses), start.T, start.o, folds=10)
    base = fitter.fit({})
    return fitter.f_test(base, fitter.fit({(case.effect, "xyz".index(case.axis)): 1}))


def check_named(diag, case) -> dict | None:
    """The hidden effect is the only finding, on the right axis, within 30 % (or the right rows).

    A draw at the smallest magnitudes can carry too little evidence for any method: if nothing
    is named, an oracle that knows the hidden term must not find it significant at the
    selection's per-candidate level either (the rate of such draws is measured in
    ``studies/diagnose_acceptance.py``).
    """
    named = [(f.effect, f.axes) for f in diag.findings]
    if not diag.findings and case.effect != "outliers":
        level = diag.settings.alpha / 2 / 12
        assert oracle_p_value(case) > level, "the data held the evidence, but diagnose named nothing"
        return None
    assert [f.effect for f in diag.findings] == [case.effect], f"named {named}"
    finding = diag.findings[0]
    if case.effect == "outliers":
        rows = set(finding.rows or [])
        assert set(case.outlier_rows) <= rows, f"missed rows {set(case.outlier_rows) - rows}"
        assert len(rows - set(case.outlier_rows)) <= 0.3 * len(case.outlier_rows)
    else:
        assert finding.axes == [case.axis]
        estimate = finding.estimate[case.axis]
        assert abs(estimate - case.value) < 0.3 * abs(case.value), (estimate, case.value)
        # the standard error is honest: the truth is within 4 of them
        assert abs(estimate - case.value) < 4 * finding.stderr[case.axis]
    # the held-out rms falls for the finding, and the gain is reported
    assert finding.heldout_rms_g_after < finding.heldout_rms_g_before
    out = diag.to_dict()
    assert out["final"]["gain"] == pytest.approx(out["baseline"]["heldout_rms_g"] / out["final"]["heldout_rms_g"])
    assert out["final"]["gain"] > 1
    return finding


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("effect", EFFECTS)
def test_hidden_effect_is_named_with_axis_and_size(effect: str, seed: int) -> None:
    case = make_case(effect, seed)
    diag = diagnose(case.poses, simulations=SIMULATIONS if seed == 1 else 0, seed=seed)
    found = check_named(diag, case)
    if found and seed == 1 and effect != "outliers":
        # the simulation check sees it: the effect's own regressor leaves the simulated band
        stat = f"corr_{effect}_{case.axis}"
        assert stat in diag.simulation.outside_band, diag.simulation.outside_band


def test_smallest_magnitudes_with_the_most_poses_are_found() -> None:
    """All five effects at exactly the smallest acceptance magnitude (120 poses, 0.5 mg)."""
    for k, effect in enumerate(EFFECTS):
        case = make_case(effect, 100 + k, scale=(1.0, 1.0), n_range=(120, 120), sigma_range=(0.5e-3, 0.5e-3))
        check_named(diagnose(case.poses, simulations=0), case)


@pytest.mark.parametrize("seed", range(8))
def test_clean_data_give_no_finding(seed: int) -> None:
    case = make_case(None, 1000 + seed)
    diag = diagnose(case.poses, simulations=SIMULATIONS if seed == 0 else 0)
    assert diag.findings == []
    out = diag.to_dict()
    assert out["final"]["gain"] == 1.0 and out["final"]["model"].startswith("T, o")
    if seed == 0:
        # the noise claim is right, so the simulated rms band holds the measured rms
        assert "rms_g" not in diag.simulation.outside_band


@pytest.mark.parametrize("hidden", ["temperature_bias", "bias_drift"])
def test_warmup_then_cooldown_separates_temperature_from_time(hidden: str) -> None:
    """A sensor that warms up and cools down: temperature and time are told apart."""
    rng = np.random.default_rng(7)
    n = 60
    t = np.sort(rng.uniform(0, 1200, n))
    temp = warmup_cooldown(t, 22, 40, 28)
    value = 0.6e-3 if hidden == "temperature_bias" else 4e-3 / 1200
    model = ExtendedModel.with_effect(lu2017_reference_model(), hidden, "z", value, temp_ref=30, t_ref=600)
    poses = simulate_extended(model, uniform_directions(n, rng), 0.4e-3, temp=temp, t=t, rng=rng)
    diag = diagnose(poses, simulations=0)
    assert [f.effect for f in diag.findings] == [hidden]
    other = "bias_drift" if hidden == "temperature_bias" else "temperature_bias"
    decisions = [c for c in diag.decisions if c.other == other]
    if decisions:  # when both explained it on their own, the report says why one was chosen
        assert decisions[0].chosen == hidden and decisions[0].p_other_given_chosen > 0.01
        assert hidden in decisions[0].text and "better" in decisions[0].text


@pytest.mark.parametrize("effect", ["temperature_scale", "outliers"])
def test_raw_100hz_recording(effect: str, tmp_path: Path) -> None:
    """A raw recording in counts (static detection → poses) with a hidden effect."""
    frame, truth = recording_with_effect(effect, seed=11)
    path = tmp_path / "rec.csv"
    frame.to_csv(path, index=False, float_format="%.6f")
    poses = load(path)
    assert poses.source == "raw recording" and poses.n == 48 and poses.temp is not None
    diag = diagnose(poses, simulations=0)
    assert [f.effect for f in diag.findings] == [effect]
    f = diag.findings[0]
    if effect == "outliers":
        visible = [r for r, g in zip(truth.corrupt_rows(poses), truth.corrupt_radial_g) if abs(g) > 2e-3]
        assert set(visible) <= set(f.rows or []) <= set(truth.corrupt_rows(poses))
    else:
        assert f.axes == [truth.axis]
        assert f.estimate[truth.axis] == pytest.approx(truth.value, rel=0.3)
    assert diag.gain() > 1.5


def test_json_shape_is_the_issue_s(tmp_path: Path) -> None:
    case = make_case("temperature_bias", 5)
    out = jsonable(diagnose(case.poses, simulations=10).to_dict())
    text = json.dumps(out, allow_nan=False)
    out = json.loads(text)
    assert isinstance(out["n_poses"], int)
    assert set(out["outlier_limit"]) == {"median_g", "smallest_g", "largest_g", "level", "poses"}
    assert set(out["baseline"]) == {"model", "calibration", "rms_g", "heldout_rms_g", "given_rms_g"}
    assert {"model", "rms_g", "heldout_rms_g", "gain"} <= set(out["final"])
    assert "statistics" in out["simulation_check"] and "outside_band" in out["simulation_check"]
    for f in out["findings"]:
        assert f["effect"] in EFFECTS
        assert set(f["axes"]) <= {"x", "y", "z"} and set(f["estimate"]) == set(f["axes"]) == set(f["stderr"])
        assert set(f["evidence"]) == {"delta_bic", "p_value"}
        assert isinstance(f["heldout_rms_g_before"], float) and isinstance(f["heldout_rms_g_after"], float)


# ----------------------------------------------------------------------------- bad input
def clean_table(n: int = 40, temp: np.ndarray | None = None, t: bool = True) -> PoseTable:
    rng = np.random.default_rng(0)
    model = ExtendedModel(lu2017_reference_model())
    return simulate_extended(model, uniform_directions(n, rng), 0.5e-3, temp=temp,
                             t=np.arange(n) * 10.0 if t else None, rng=rng)


def test_temperature_model_without_temperature_column() -> None:
    with pytest.raises(InputError, match="temperature_bias: no temperature column"):
        diagnose(clean_table(), effects="temperature_bias")


def test_constant_temperature() -> None:
    with pytest.raises(InputError, match="temperature is constant"):
        diagnose(clean_table(temp=np.full(40, 25.0)), effects=["temperature_scale"])
    # not asked for: the temperature effects are skipped, and the report says why
    diag = diagnose(clean_table(temp=np.full(40, 25.0)), simulations=0)
    assert "temperature_bias" in diag.skipped and "constant" in diag.skipped["temperature_bias"]
    assert diag.findings == []


def test_drift_without_time() -> None:
    with pytest.raises(InputError, match="bias_drift: no time column"):
        diagnose(clean_table(t=False), effects="bias_drift")


def test_small_sessions_test_one_candidate_at_a_time_and_state_detection_limits() -> None:
    """25 poses: every candidate is tested (one at a time), and the limits of what was not found are stated."""
    temp = np.linspace(20, 40, 25)
    diag = diagnose(clean_table(25, temp=temp), simulations=0)
    assert diag.findings == []
    assert {(lim.effect, lim.axis) for lim in diag.detection_limits} == {
        (e, a) for e in ("temperature_bias", "temperature_scale", "bias_drift", "scale_nonlinearity", "bias_step")
        for a in "xyz"}  # a bias step not named has its own limit (limits.step_limit)
    lim = next(x for x in diag.detection_limits if x.effect == "temperature_bias" and x.axis == "z")
    assert 0 < lim.limit < 1e-3 and "detection limits" in diagnosis_report(diag)
    # and the smallest outlier pose it could name: the t quantile of a Bonferroni test over 25 poses
    # at 15 degrees of freedom (≈ 5) times the pose noise and its leverage factor
    pose = diag.outlier_limit
    assert pose is not None and pose.poses == 25 and pose.smallest_g <= pose.median_g <= pose.largest_g
    assert 4.5 * np.sqrt(diag.final.rss / 16) < pose.smallest_g and pose.largest_g < 30 * np.sqrt(diag.final.rss / 16)
    assert "smallest outlier pose the outlier test" in diagnosis_report(diag)
    # 11 poses are below the baseline's own minimum (9 parameters + 3 degrees of freedom)
    with pytest.raises(InputError, match=r"11 poses are too few for a diagnosis: at least 12"):
        diagnose(clean_table(11), simulations=0)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_22_pose_session_names_an_effect_above_its_detection_limit(seed: int) -> None:
    """A hand-held session of 22 poses (mikoff-mpu9150 size) with a temperature bias at 3× the smallest acceptance size."""
    case = make_case("temperature_bias", 300 + seed, scale=(3.0, 3.0), n_range=(22, 22), sigma_range=(0.3e-3, 0.3e-3))
    diag = diagnose(case.poses, simulations=0)
    check_named(diag, case)


def test_unknown_effect() -> None:
    with pytest.raises(InputError, match="unknown effect"):
        diagnose(clean_table(), effects="humidity")


def test_monotone_warmup_decides_on_the_evidence_and_says_why() -> None:
    """Temperature and time correlate (r ≈ 0.9): both explain the bias alone; the report says which and why."""
    rng = np.random.default_rng(0)
    n = 60
    t = np.sort(rng.uniform(0, 1200, n))
    temp = 22 + 16 * (1 - np.exp(-t / 300))
    model = ExtendedModel.with_effect(lu2017_reference_model(), "temperature_bias", "x", 0.6e-3, temp_ref=30, t_ref=600)
    poses = simulate_extended(model, uniform_directions(n, rng), 0.4e-3, temp=temp, t=t, rng=rng)
    diag = diagnose(poses, simulations=0)
    assert [f.effect for f in diag.findings] == ["temperature_bias"]
    (decision,) = [c for c in diag.decisions if c.other == "bias_drift"]
    assert decision.temperature_time_correlation > 0.85
    assert decision.delta_bic_chosen < decision.delta_bic_other < 0
    assert decision.p_other_given_chosen > 0.05
    assert "explains it better" in decision.text and "adds nothing significant" in decision.text
    assert decision.text in diagnosis_report(diag)


def test_higher_polynomial_order_where_the_data_support_it() -> None:
    """A quadratic temperature bias (0.04 mg/°C² over 25 °C) is fitted with order 2, and said so."""
    rng = np.random.default_rng(5)
    n = 80
    t = np.sort(rng.uniform(0, 1200, n))
    temp = warmup_cooldown(t, 20, 45, 30)
    coefficients = {"temperature_bias": [[0, 0, 0], [0, 0, 0], [0.5e-3, 0.04e-3, 0]]}
    model = ExtendedModel(lu2017_reference_model(), coefficients, temp_ref=float(0.5 * (temp.min() + temp.max())), t_ref=600)
    poses = simulate_extended(model, uniform_directions(n, rng), 0.4e-3, temp=temp, t=t, rng=rng)
    diag = diagnose(poses, simulations=0)
    (finding,) = diag.findings
    assert finding.effect == "temperature_bias" and finding.order == {"z": 2}
    c1, c2 = finding.coefficients["z"]
    assert c1 == pytest.approx(0.5e-3, rel=0.1) and c2 == pytest.approx(0.04e-3, rel=0.3)
    assert "polynomial order 2" in diagnosis_report(diag)


def test_typed_result_round_trips_through_json_and_figures_leave_the_backend_alone(tmp_path: Path) -> None:
    """to_dict() is plain JSON (dataclasses all the way down); figures are Figure objects, the backend untouched."""

    import matplotlib

    from optcal.applications.diagnosis import Finding, SimulationCheck, Step
    from optcal.report.diagnosis_figures import residual_figure, save_figures

    backend = matplotlib.get_backend()
    case = make_case("bias_drift", 6)
    diag = Diagnoser(DiagnosisSettings(simulations=5)).run(case.poses)
    assert isinstance(diag.simulation, SimulationCheck) and all(isinstance(s, Step) for s in diag.steps)
    assert all(isinstance(f, Finding) for f in diag.findings)
    out = diag.to_dict()
    assert json.loads(json.dumps(jsonable(out), allow_nan=False)) == jsonable(out)
    assert out["findings"][0]["estimate"] == diag.findings[0].estimate
    assert out["selection"][0]["accepted"] == diag.steps[0].accepted.term
    fig = residual_figure(diag)
    assert len(fig.legends) == 1 and "time from the start (s)" in [a.get_xlabel() for a in fig.axes]
    assert not any("corr_" in t.get_text() for a in fig.axes for t in a.get_yticklabels())
    paths = save_figures(diag, tmp_path)
    assert len(paths) == 2 and matplotlib.get_backend() == backend


@pytest.mark.parametrize("seed", [41, 42])
def test_two_effects_at_once_are_both_named_with_axes_and_estimates(seed: int) -> None:
    """A temperature bias on one axis and a drift on another (truth hidden): both named, each within 30 %."""
    rng = np.random.default_rng(seed)
    n = 90
    t = np.sort(rng.uniform(0, 1200, n))
    temp = warmup_cooldown(t, 22, 40, 28)
    axes = rng.permutation(3)[:2]
    coefficients = {"temperature_bias": np.zeros((3, 1)), "bias_drift": np.zeros((3, 1))}
    coefficients["temperature_bias"][axes[0], 0] = 0.8e-3
    coefficients["bias_drift"][axes[1], 0] = -6e-3 / 1200
    model = ExtendedModel(lu2017_reference_model(), coefficients, temp_ref=30, t_ref=600)
    poses = simulate_extended(model, uniform_directions(n, rng), 0.4e-3, temp=temp, t=t, rng=rng)
    diag = diagnose(poses, simulations=0)
    named = {f.effect: f for f in diag.findings}
    assert set(named) == {"temperature_bias", "bias_drift"}, [(f.effect, f.axes) for f in diag.findings]
    for effect, axis in (("temperature_bias", axes[0]), ("bias_drift", axes[1])):
        f = named[effect]
        assert f.axes == ["xyz"[axis]]
        assert f.estimate["xyz"[axis]] == pytest.approx(coefficients[effect][axis, 0], rel=0.3)
