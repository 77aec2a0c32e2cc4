"""The magnetometer's maximum-likelihood refinement never ends outside the physical set nor worse than its start."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cli_run import run_args
from optcal.core.poses import PoseTable
from optcal.families.accel.calibration import calibrate
from optcal.families.mag.fit import MagSettings, fit_form
from optcal.families.mag.refine import FIELD_FACTOR, refinement_departure
from optcal.families.mag.samples import MagSamples
from optcal.families.mag.units import decide_mag_units

FIELD = 50.0  # µT
SOFT = np.array([[1.1, 0.05, 0.02], [0.05, 0.95, -0.03], [0.02, -0.03, 1.0]])  # m = SOFT b + o
HARD = np.array([12.0, -8.0, 20.0])


def _cap(cap_deg: float, noise: float, n: int = 1500, seed: int = 0) -> np.ndarray:
    """Samples whose true field direction lies within ``cap_deg`` of +z (90: half the sphere), white noise a share of the field."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(8 * n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = v[v[:, 2] >= np.cos(np.radians(cap_deg))][:n]
    return np.asarray((FIELD * v) @ SOFT.T + HARD + rng.normal(scale=noise * FIELD, size=v.shape))


def _samples(m: np.ndarray) -> MagSamples:
    return MagSamples(m=m, units=decide_mag_units(m, "uT", "the test"))


def _rms(T: np.ndarray, o: np.ndarray, m: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.linalg.norm((m - o) @ T.T, axis=1) - 1.0) ** 2)))


def test_half_a_sphere_ends_in_the_physical_set_not_a_degenerate_ellipsoid():
    """Half the sphere, 3 % noise, a soft iron: the unguarded ML grows the field many times (the residual is a share
    of the fitted field); the full form is refined with the noise in the sensor's units instead, says so, and its
    rms is at or below the convex start's, its field within 5 % of the truth (measured: 2.6 %)."""
    m = _cap(90.0, 0.03)
    poses = PoseTable(acc=m, units="counts", source="raw recording")
    start = calibrate(poses, method="convex", allow_degenerate=True)
    F0 = float(np.linalg.det(start.T) ** (-1 / 3))
    ml = calibrate(poses, method="default", allow_degenerate=True)  # the planted failure, as the old code kept it
    assert float(np.linalg.det(ml.T) ** (-1 / 3)) > FIELD_FACTOR * F0
    assert refinement_departure(ml.T, np.asarray(ml.o), start.T, np.asarray(start.o), m, "squared") is not None
    fit = fit_form(_samples(m), "full", MagSettings())
    assert fit.note is not None and "not kept" in fit.note and "--method convex" in fit.note
    assert "noise in the sensor's units" in fit.method
    assert fit.rms <= _rms(start.T, np.asarray(start.o), m)
    assert abs(fit.field_strength / FIELD - 1) < 0.05  # not the runaway's
    assert np.linalg.norm(fit.o - HARD) < 0.1 * FIELD


def test_a_60_degree_cap_keeps_the_convex_start():
    """A 60° cap with 3 % noise: both refinements run away (the share's and the sensor units' alike: the cap does not
    determine the full form), so the convex start is kept, with the note, at its own rms."""
    m = _cap(60.0, 0.03)
    start = calibrate(PoseTable(acc=m, units="counts", source="raw recording"), method="convex", allow_degenerate=True)
    fit = fit_form(_samples(m), "full", MagSettings())
    assert fit.method == "convex"
    assert fit.note is not None and "nor with the noise in the sensor's units" in fit.note and "convex start is kept" in fit.note
    assert abs(fit.rms - _rms(start.T, np.asarray(start.o), m)) < 1e-9


def test_standard_errors_do_not_depend_on_the_units():
    """The same samples in counts (×1000): every standard error scales with the data (T's by 1/1000, o's by 1000),
    not truncated by JᵀJ's condition number (before: o's came out ~1e-14 counts on ybabs)."""
    m = _cap(180.0, 0.01, n=600)
    a = fit_form(_samples(m), "full", MagSettings())
    b = fit_form(_samples(1000.0 * m), "full", MagSettings())
    for name, se in a.stderr.items():
        factor = 1000.0 if name.startswith("o_") else 1e-3
        assert b.stderr[name] == pytest.approx(factor * se, rel=1e-3), name
    assert b.worst_share == pytest.approx(a.worst_share, rel=1e-3)


def test_a_covered_sphere_keeps_the_refinement():
    """The whole sphere: the ML refinement is kept (no note) and its rms is at or below the convex start's."""
    m = _cap(180.0, 0.03)
    poses = PoseTable(acc=m, units="counts", source="raw recording")
    start = calibrate(poses, method="convex", allow_degenerate=True)
    fit = fit_form(_samples(m), "full", MagSettings())
    assert fit.note is None
    assert fit.rms <= _rms(start.T, np.asarray(start.o), m)
    assert abs(fit.field_strength / FIELD - 1) < 0.02


def test_the_departures_named():
    """Each reason the refinement is not kept: the field moved, an axis stretched, the objective above the start's."""
    m = _cap(180.0, 0.01, n=300)
    T0, o0 = np.linalg.inv(SOFT) / FIELD, HARD
    assert refinement_departure(T0, o0, T0, o0, m, "squared") is None
    assert "times the convex start's" in str(refinement_departure(T0 / 2, o0, T0, o0, m, "squared"))
    stretched = T0 @ np.diag([3.0, 3.0, 1 / 9.0 / 1.0])  # det unchanged, one axis 9 times longer against the field
    assert "stretches an axis" in str(refinement_departure(stretched, o0, T0, o0, m, "squared"))
    assert "above the convex start" in str(refinement_departure(T0, o0 + 0.1 * FIELD, T0, o0, m, "squared"))
    assert refinement_departure(T0, o0 + 0.1 * FIELD, T0, o0, m, "huber") is None  # a robust loss's objective differs


def test_the_note_is_printed(tmp_path, capsys):
    """On the command line the note is printed and the calibration written (exit 0, no failure), without the
    warning of the refinement that was not kept."""
    m = _cap(90.0, 0.03)
    path = tmp_path / "cap.csv"
    np.savetxt(path, m, delimiter=",", header="mx,my,mz", comments="")
    code, out, err = run_args(capsys, "calibrate", str(path), "--sensor", "mag", "--mag-form", "full", "--mag-units", "uT",
                            "--output", str(tmp_path / "cap.json"))
    assert code == 0
    assert "maximum-likelihood refinement of the full form is not kept" in out
    assert "did not converge" not in err  # the solver's warning is not printed for a result that is not kept


def test_the_held_out_comparison_says_it_fits_by_plain_maximum_likelihood():
    """With --loss huber (or a method other than ML) the decision says the forms were compared under the squared
    loss, which the user's settings do not change; with the defaults it says nothing of it."""
    from optcal.families.mag.fit import choose_form

    s = _samples(_cap(180.0, 0.01, n=600))
    plain = choose_form(s, MagSettings())
    assert plain.heldout is not None and "plain maximum likelihood" not in plain.form_reason
    assert plain.heldout.summary()["fit"] == "maximum likelihood, squared loss"
    huber = choose_form(s, MagSettings(estimator={"loss": "huber"}))
    assert "compared under plain maximum likelihood (squared loss), not --loss huber" in huber.form_reason
    convex = choose_form(s, MagSettings(method="convex"))
    assert "not --method convex" in convex.form_reason
