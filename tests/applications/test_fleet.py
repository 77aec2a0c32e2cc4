"""optcal fleet: Dask run with planted trouble, parity with optcal calibrate, population, prior."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pandas as pd
import pytest

from optcal.cli.main import main
from optcal.data import load
from optcal.families.accel.calibration import calibrate
from optcal.errors import InputError
from optcal.core.identifiability import parameter_full_scale
from optcal.applications.fleet.engine import ClusterSettings
from optcal.applications.fleet.inputs import expand_inputs, read_manifest
from optcal.applications.fleet.population import flag_units, population_stats
from optcal.applications.fleet.prior import PopulationPrior, estimate_prior, fit_with_prior
from optcal.applications.fleet.synthetic import write_fleet
from optcal.applications.fleet.unit import UnitInput, UnitOutcome, read_unit
from optcal.data.options import ReadOptions
from optcal.core.norm_residual import heldout_residuals
from optcal.core.model import PARAM_NAMES, LumpedModel
from optcal.families.simulate.poses import simulate_poses, six_position, uniform_directions

N_UNITS = 150


@pytest.fixture(scope="module")
def fleet_run(tmp_path_factory):
    """One CLI run on a real LocalCluster (2 worker processes) over a fleet with planted trouble."""
    folder = tmp_path_factory.mktemp("fleet")
    truth = write_fleet(folder / "units", N_UNITS, seed=11)
    out = folder / "results.parquet"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(["fleet", str(folder / "units"), "-o", str(out), "--workers", "2", "--json", "--no-progress"])
    return truth, code, json.loads(stdout.getvalue()), pd.read_parquet(out), out


def test_fleet_acceptance(fleet_run):
    truth, code, summary, table, _ = fleet_run
    assert code == 0
    # the table was streamed, the units in input order
    assert list(table["unit"]) == sorted(truth.kinds)
    assert summary["engine"] == "dask.distributed LocalCluster, 2 workers"
    assert summary["n_units"] == N_UNITS == len(table)
    # the unreadable files are listed with their reason, nothing else failed
    assert sorted(f["unit"] for f in summary["failed"]) == sorted(truth.units("unreadable"))
    assert all(f["error"] for f in summary["failed"])
    assert summary["calibrated"] == N_UNITS - len(truth.units("unreadable"))
    # the odd unit is flagged, for its x scale; at most 2 % of the normal units are
    flagged = {f["unit"]: f["reason"] for f in summary["flagged"]}
    odd = truth.units("scale_error")[0]
    assert odd in flagged and "T_xx" in flagged[odd]
    normal = truth.units("normal")
    assert sum(u in flagged for u in normal) <= 0.02 * len(normal)
    # the six-face unit is calibrated with the prior, within 0.01 of its true A
    six = truth.units("six_faces")[0]
    row = table.set_index("unit").loc[six]
    assert row["status"] == "calibrated_with_prior"
    theta = row[list(PARAM_NAMES)].to_numpy(float)
    A, A_true = LumpedModel.from_theta(theta).A, LumpedModel.from_theta(truth.truth[six]).A
    assert np.max(np.abs(A - A_true)) < 0.01
    # its standard errors say the off-diagonal comes from the prior, the diagonal from the data
    weights = row[[f"{p}_prior_weight" for p in PARAM_NAMES]].to_numpy(float)
    assert np.all(weights[[1, 3, 4]] > 0.9) and np.all(weights[[0, 2, 5]] < 0.1)


def test_unit_identical_to_calibrate(fleet_run, capsys):
    truth, _, _, table, _ = fleet_run
    rows = table.set_index("unit")
    for unit in (truth.units("normal")[0], truth.units("scale_error")[0]):
        path = str(truth.folder / f"{unit}.csv")
        assert main(["calibrate", path, "--json"]) == 0
        ref = json.loads(capsys.readouterr().out)
        # the fleet solves its units in batches: equal to the solver tolerance (fit_units below)
        theta = np.array([rows.loc[unit, p] for p in PARAM_NAMES])
        ref_theta = np.array([ref["params"][p] for p in PARAM_NAMES])
        assert np.max(np.abs(theta - ref_theta) / parameter_full_scale(ref_theta)) < PARITY_FULL_SCALE
        np.testing.assert_allclose([rows.loc[unit, f"{p}_stderr"] for p in PARAM_NAMES],
                                   [ref["stderr"][p] for p in PARAM_NAMES], rtol=1e-7, atol=0)


#: Largest difference between a unit's θ solved in a batch and alone, as a fraction of the
#: parameter's full scale (:func:`optcal.core.identifiability.parameter_full_scale`); measured 8.3e-10 on 300 units at ipopt.tol 1e-7, at most 1.1e-10 at 1e-10.
PARITY_FULL_SCALE = 5e-10


def test_fit_units_in_batches_equal_to_one_at_a_time(tmp_path, monkeypatch):
    """A few hundred units fitted together: every outcome as optcal calibrate's path gives it,
    the units the batch cannot take (unreadable, six faces) through the single-unit path."""
    import optcal.applications.fleet.unit as unit_module

    truth = write_fleet(tmp_path, 200, seed=23, scale_error_units=2, six_face_units=2, unreadable_units=2)
    units = expand_inputs([str(tmp_path)])
    data = [read_unit(u, ReadOptions()) for u in units]
    alone = [unit_module.fit_unit(u, d) for u, d in zip(units, data)]
    single_calls: list[str] = []
    original = unit_module.fit_unit

    def counted(u: UnitInput, d: object) -> UnitOutcome:
        single_calls.append(u.unit)
        return original(u, d)

    monkeypatch.setattr(unit_module, "fit_unit", counted)
    together = unit_module.fit_units(units, data)
    assert sorted(single_calls) == sorted(truth.units("unreadable") + truth.units("six_faces"))
    for b, s in zip(together, alone):
        assert (b.unit, b.status, b.reason, b.n_poses, b.sigma_known) == (s.unit, s.status, s.reason, s.n_poses, s.sigma_known)
        if s.theta is None:
            continue
        assert np.max(np.abs(b.theta - s.theta) / parameter_full_scale(s.theta)) < PARITY_FULL_SCALE
        assert np.max(np.abs(b.theta - s.theta) / s.stderr) < 1e-6  # the solver tolerance
        np.testing.assert_allclose(b.stderr, s.stderr, rtol=1e-7, atol=0)
        assert b.rms_g == pytest.approx(s.rms_g, rel=1e-7) and b.heldout_rms_g == pytest.approx(s.heldout_rms_g, rel=1e-7)


def test_prior_helps_weak_units_and_does_not_bias_the_others(fleet_run):
    truth, _, _, table, _ = fleet_run
    rows = table.set_index("unit")
    normal = [u for u in truth.units("normal") if rows.loc[u, "status"] == "calibrated"]
    own = np.array([rows.loc[u, list(PARAM_NAMES)].to_numpy(float) - truth.truth[u] for u in normal])
    with_prior = np.array([rows.loc[u, [f"{p}_with_prior" for p in PARAM_NAMES]].to_numpy(float) - truth.truth[u]
                           for u in normal])
    # no bias: the mean error over the units lies within 3 standard errors of zero
    mean, se = with_prior.mean(axis=0), with_prior.std(axis=0, ddof=1) / np.sqrt(len(normal))
    assert np.all(np.abs(mean) < 3 * se)
    # and the prior does not make well-determined units worse
    assert np.all(np.sqrt(np.mean(with_prior**2, axis=0)) <= 1.02 * np.sqrt(np.mean(own**2, axis=0)))
    # the weak unit: its own data alone (degenerate fit) are far off, the prior fixes that
    six = truth.units("six_faces")[0]
    alone = calibrate(load(str(truth.folder / f"{six}.csv")), allow_degenerate=True)
    A_true = LumpedModel.from_theta(truth.truth[six]).A
    theta = rows.loc[six, list(PARAM_NAMES)].to_numpy(float)
    assert np.max(np.abs(LumpedModel.from_theta(theta).A - A_true)) < 0.5 * np.max(np.abs(alone.A - A_true))


def test_prior_fit_noise_free_reference():
    """A six-face unit, noise-free, with a prior centred on the truth: the fit is the truth to 1e-8."""
    model = LumpedModel.from_physical([1.01, 0.99, 1.02], 0.003, -0.002, 0.001, [0.02, -0.01, 0.03])
    poses = simulate_poses(model, np.repeat(six_position(), 2, axis=0), 0.0)
    prior = PopulationPrior(model.theta, np.diag([1e-4, 1e-5, 1e-4, 1e-5, 1e-5, 1e-4, 4e-4, 4e-4, 4e-4]), 50, "g", 0.001)
    fit = fit_with_prior(poses, prior, start=model.theta + 0.01)
    assert np.allclose(fit.result.params[:9], model.theta, atol=1e-8, rtol=0)
    assert fit.result.method == "mle+prior" and fit.result.solver.success
    assert np.all(fit.prior_weight[[1, 3, 4]] > 0.99) and np.all(fit.prior_weight[[0, 2, 5, 6, 7, 8]] < 0.01)


def test_heldout_residuals_are_exact_leave_one_out_for_a_linear_fit():
    rng = np.random.default_rng(3)
    J = rng.standard_normal((30, 4))
    y = J @ rng.standard_normal(4) + 0.1 * rng.standard_normal(30)
    w = rng.uniform(0.5, 2.0, 30)
    sw = np.sqrt(w)
    beta = np.linalg.lstsq(J * sw[:, None], y * sw, rcond=None)[0]
    loo = []
    for k in range(30):
        keep = np.arange(30) != k
        b = np.linalg.lstsq(J[keep] * sw[keep, None], y[keep] * sw[keep], rcond=None)[0]
        loo.append(y[k] - J[k] @ b)
    # the residual of the norm-residual fit is r = measured − predicted: here y − Jβ, Jacobian −J
    assert np.allclose(heldout_residuals(y - J @ beta, -J, w), loo, atol=1e-12)


def _outcome(unit: str, theta: np.ndarray, rms: float) -> UnitOutcome:
    return UnitOutcome(unit, unit, "calibrated", theta=theta, covariance=np.diag(np.full(9, 1e-8)), rms_g=rms, units="g")


def test_flag_rule_false_flag_rate_and_planted_unit():
    rng = np.random.default_rng(5)
    sd = np.array([0.01, 0.0035, 0.01, 0.0035, 0.0035, 0.01, 0.02, 0.02, 0.02])
    base = LumpedModel.from_physical([1, 1, 1], 0, 0, 0, [0, 0, 0]).theta
    outcomes = [_outcome(f"u{k}", base + sd * rng.standard_normal(9), 0.002 + 1e-4 * rng.standard_normal()) for k in range(2000)]
    odd = _outcome("odd", base + np.array([0.08, 0, 0, 0, 0, 0, 0, 0, 0]), 0.002)
    stats = population_stats([*outcomes, odd])
    flagged = {o.unit for o in flag_units([*outcomes, odd], stats)}
    assert "odd" in flagged
    assert len(flagged - {"odd"}) <= 0.02 * len(outcomes)
    # the prior of these units: mean and covariance of the population (estimation noise removed)
    prior = estimate_prior([o for o in outcomes if not o.flag])
    assert np.allclose(np.sqrt(np.diag(prior.covariance)), sd, rtol=0.1)


def test_inputs_manifest_glob_and_errors(tmp_path):
    truth = write_fleet(tmp_path / "d", 6, seed=1, scale_error_units=0, six_face_units=0, unreadable_units=1)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("unit,path,line\nA,d/unit00000.csv,north\nB,d/unit00001.csv,south\n")
    units = expand_inputs([str(manifest), str(tmp_path / "d" / "unit0000[2-3].csv")])
    assert [u.unit for u in units] == ["A", "B", "unit00002", "unit00003"]
    assert units[0].metadata == {"line": "north"} and units[0].path == str(tmp_path / "d" / "unit00000.csv")
    assert len(expand_inputs([str(tmp_path / "d")])) == len(truth.kinds)
    logs = tmp_path / "logs"  # a logger's text dumps, as ../shared/data/mikoff-mpu9150 has them, beside its notes
    logs.mkdir()
    for name in ("imu0.log", "imu1.dat", "README.md", "SHA256SUMS"):
        (logs / name).write_text("0 0 1\n")
    assert [u.unit for u in expand_inputs([str(logs)])] == ["imu0", "imu1"]
    with pytest.raises(InputError, match="matches no file"):
        expand_inputs([str(tmp_path / "nothing_*.csv")])
    bad = tmp_path / "bad.csv"
    bad.write_text("unit,path\nA,\n")
    with pytest.raises(InputError, match="line 2"):
        read_manifest(bad)


def test_cli_usage_errors_are_one_line(tmp_path, capsys):
    write_fleet(tmp_path / "d", 3, seed=1, scale_error_units=0, six_face_units=0, unreadable_units=0)
    key = tmp_path / "k.pem"
    key.write_text("x")
    code = main(["fleet", str(tmp_path / "d"), "-o", str(tmp_path / "r.parquet"), "--tls-key", str(key)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "scheduler" in err and len(err.strip().splitlines()) == 1
    code = main(["fleet", str(tmp_path / "d"), "-o", str(tmp_path / "missing" / "r.parquet")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "folder does not exist" in err
    with pytest.raises(InputError, match="workers"):
        ClusterSettings(workers=2, scheduler="tcp://127.0.0.1:1")


def test_read_unit_from_an_fsspec_url(tmp_path):
    import fsspec

    write_fleet(tmp_path, 1, seed=2, scale_error_units=0, six_face_units=0, unreadable_units=0)
    with fsspec.open("memory://fleet/unit00000.csv", "wb") as fh:
        fh.write((tmp_path / "unit00000.csv").read_bytes())
    poses = read_unit(UnitInput("u", "memory://fleet/unit00000.csv"), ReadOptions())
    assert np.array_equal(poses.acc, load(str(tmp_path / "unit00000.csv")).acc)
    failure = read_unit(UnitInput("v", "memory://fleet/missing.csv"), ReadOptions())
    assert failure.error


def test_results_writer_streams_the_table_in_row_groups(tmp_path):
    """Rows written chunk by chunk: several row groups, the same table as the whole-table path."""
    import pyarrow.parquet as pq

    from optcal.applications.fleet.results import FleetResult, ResultsWriter

    rng = np.random.default_rng(1)
    outcomes = [UnitOutcome(f"u{k}", f"p{k}", "calibrated" if k % 3 else "failed", reason="" if k % 3 else "bad file",
                            theta=rng.standard_normal(9) if k % 3 else None, stderr=np.full(9, 1e-3) if k % 3 else None,
                            rms_g=0.002, n_poses=120, exclusions={"moving": k}, units="g",
                            metadata={"line": "north"} if k % 2 else {}) for k in range(10)]
    with ResultsWriter(tmp_path / "r.parquet", ["line"], row_group=4) as writer:
        for s in range(0, 10, 3):
            writer.write(outcomes[s:s + 3])
    assert pq.ParquetFile(tmp_path / "r.parquet").num_row_groups == 2
    streamed = pd.read_parquet(tmp_path / "r.parquet")
    whole = FleetResult(outcomes, None, None, "", "test", 0.0)
    whole.write_parquet(tmp_path / "whole.parquet")
    pd.testing.assert_frame_equal(streamed, pd.read_parquet(tmp_path / "whole.parquet"))
    assert streamed["meta_line"].isna().tolist() == [True, False] * 5
    assert streamed["T_xx"].isna().sum() == 4 and streamed["exclusions"][3] == '{"moving": 3}'


def test_fleet_exits_2_when_no_unit_was_calibrated(tmp_path, capsys):
    (tmp_path / "units").mkdir()
    for k in range(2):
        (tmp_path / "units" / f"u{k}.csv").write_text("ax,ay,az\n")  # an unfilled logger file: no pose
    code = main(["fleet", str(tmp_path / "units"), "-o", str(tmp_path / "r.parquet"), "--workers", "1", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "no unit of 2 was calibrated" in err
