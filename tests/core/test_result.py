"""The fit-result base (optcal.core.fit_result): statistics written once, χ² and n as typed fields; pose tables."""

import numpy as np
import pytest

from optcal.core.fit_result import FitRecord, FitResult, SolverInfo, chi_square, standard_errors
from optcal.core.identifiability import IdentifiabilityReport, RankReport

#: A straight line ``y = a + b x`` fitted by weighted least squares, and what lmfit 1.3.4 reports
#: for it (``lmfit.minimize`` of ``(y - a - b x) / sigma``, default ``leastsq``): χ², the number
#: of data, of varied parameters, reduced χ², AIC and BIC.  lmfit's convention (minimizer.py,
#: ``_calculate_statistics``): ``-2 ln L = n ln(χ²/n)``, ``AIC = -2 ln L + 2p``,
#: ``BIC = -2 ln L + p ln n``.
LINE_X = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
LINE_Y = np.array([1.0, 3.1, 4.9, 7.2, 8.8, 11.3, 12.9])
LINE_SIGMA = np.array([0.1, 0.1, 0.2, 0.2, 0.1, 0.3, 0.2])
LMFIT_LINE = {"chisqr": 6.0182880365760525, "ndata": 7, "nvarys": 2, "redchi": 1.2036576073152105,
              "aic": 2.9422488336095514, "bic": 2.8340691317201774,
              "a": 1.0495554991059934, "b": 1.9689357378727672,
              "a_stderr": 0.08396502596032437, "b_stderr": 0.02915353168338259}


def line_fit() -> FitResult:
    """The weighted straight-line fit as a :class:`FitResult`, covariance scaled by the reduced χ² (as lmfit's)."""
    w = 1.0 / LINE_SIGMA**2
    X = np.column_stack([np.ones_like(LINE_X), LINE_X])
    sw = np.sqrt(w)
    params, *_ = np.linalg.lstsq(X * sw[:, None], LINE_Y * sw, rcond=None)
    residuals = LINE_Y - X @ params
    chisqr = chi_square(residuals, w)
    covariance = np.linalg.inv(X.T @ (X * w[:, None])) * chisqr / (len(LINE_X) - 2)
    return FitResult(params=params, param_names=["a", "b"], covariance=covariance, residuals=residuals, weights=w,
                     chisqr=chisqr, n_observations=len(LINE_X), solver=SolverInfo("numpy.linalg.lstsq", "solved", True, 0, 0.0))


def test_statistics_follow_lmfits_convention_on_a_reference_problem():
    fit = line_fit()
    ref = LMFIT_LINE
    np.testing.assert_allclose(fit.params, [ref["a"], ref["b"]], rtol=1e-7)
    assert fit.chisqr == pytest.approx(ref["chisqr"], rel=1e-10)
    assert fit.n_observations == ref["ndata"] and fit.n_params == ref["nvarys"] and fit.dof == 5
    assert fit.redchi == pytest.approx(ref["redchi"], rel=1e-10)
    assert fit.aic == pytest.approx(ref["aic"], rel=1e-9)
    assert fit.bic == pytest.approx(ref["bic"], rel=1e-9)
    assert fit.stderr == pytest.approx({"a": ref["a_stderr"], "b": ref["b_stderr"]}, rel=1e-6)


def test_chi_square_is_the_typed_field_not_recomputed():
    """A method whose cost is not Σ w r² of the kept residuals (six-position: vector residuals) gives its own χ² and n."""
    fit = line_fit()
    fit.chisqr, fit.n_observations = 42.0, 21
    assert fit.chisqr == 42.0 and fit.chisqr != chi_square(fit.residuals, fit.weights)
    assert fit.dof == 19 and fit.redchi == pytest.approx(42.0 / 19)
    assert fit.aic == pytest.approx(21 * np.log(42.0 / 21) + 2 * 2)
    assert fit.bic == pytest.approx(21 * np.log(42.0 / 21) + np.log(21) * 2)


def test_no_degrees_of_freedom_and_no_covariance():
    fit = line_fit()
    fit.n_observations = 2
    assert fit.dof == 0 and np.isnan(fit.redchi)
    fit.covariance = None
    assert all(np.isnan(v) for v in fit.stderr.values())
    assert standard_errors(np.diag([4.0, -1e-30]), ["p", "q"]) == {"p": 2.0, "q": 0.0}


def test_fit_record_holds_a_typed_identifiability_report():
    record = FitRecord(params=np.zeros(2), param_names=["a", "b"], covariance=np.eye(2),
                       solver=SolverInfo("none", "ok", True, 0, 0.0), identifiability=RankReport(2, 2, 3.0))
    assert record.identifiability.to_dict() == {"rank": 2, "n_params": 2, "condition_number": 3.0}
    assert record.exclusions == {} and record.notes == []
    rich = IdentifiabilityReport(rank=8, n_params=9, condition_number=float("inf"),
                                 unidentified=[{"entry": "A_xy", "combination": {"A_xy": 1.0}, "text": "A_xy"}])
    back = IdentifiabilityReport.from_dict(rich.to_dict() | {"condition_number": None})  # JSON writes inf as null
    assert back == rich and not back.identifiable and "A_xy" in back.describe()


def test_solver_record_round_trip():
    solver = SolverInfo("IPOPT", "Solve_Succeeded", True, 12, 0.25, "note")
    assert SolverInfo.from_dict(solver.to_dict()) == solver


def test_pose_table_copies_extra_columns():
    from optcal.core.poses import PoseTable

    col = np.arange(9.0)
    table = PoseTable(acc=np.eye(3)[np.arange(9) % 3], extra={"roll_deg": col})
    table.extra["roll_deg"][0] = 99.0
    assert col[0] == 0.0


def test_pose_tables_compare_values():
    from optcal.core.poses import PoseTable

    acc = np.eye(3)[np.arange(9) % 3] + 0.01 * np.arange(27).reshape(9, 3)
    a = PoseTable(acc=acc, temp=np.arange(9.0), extra={"roll_deg": np.arange(9.0)})
    b = PoseTable(acc=acc.copy(), temp=np.arange(9.0), extra={"roll_deg": np.arange(9.0)}, meta={"path": "x"})
    assert a == b
    assert a != b.subset(np.arange(8))
    assert a != PoseTable(acc=acc, extra={"roll_deg": np.arange(9.0)})
    b.extra["roll_deg"][0] = 5.0
    assert a != b
