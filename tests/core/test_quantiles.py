"""The distributions' quantiles the rest model's critical values come from, against scipy.stats (a reference
implementation; optcal computes them itself so that a command does not import scipy.stats to start)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special, stats

from optcal.core import quantiles

TAILS = (0.75, 0.5, 0.25, 1e-3, 1.667e-4, 1e-6, 3e-8, 1e-12)
DOF = (1.0, 2.0, 3.0, 5.0, 7.0, 19.0, 48.0, 199.0, 1e4, 1e6)


@pytest.mark.parametrize("p", TAILS)
@pytest.mark.parametrize("d1", [1.0, 3.0])
def test_f_upper_quantile(p: float, d1: float) -> None:
    for d2 in DOF:
        # scipy.stats.f.isf goes through 1 − p, which loses the tail's digits below 1e-8: its beta inverse does not
        y = special.betaincinv(d2 / 2.0, d1 / 2.0, p)
        reference = d2 * (1.0 - y) / (d1 * y)
        assert quantiles.f_isf(p, d1, d2) == pytest.approx(reference, rel=1e-8)
        if p >= 1e-8:
            assert quantiles.f_isf(p, d1, d2) == pytest.approx(stats.f.isf(p, d1, d2), rel=1e-8)
    assert quantiles.f_ppf(0.25, 1.0, 48.0) == pytest.approx(stats.f.ppf(0.25, 1.0, 48.0), rel=1e-9)


@pytest.mark.parametrize("p", TAILS)
def test_chi2_t_and_normal_upper_quantiles(p: float) -> None:
    for dof in (1, 2, 3, 6, 7, 10, 100, 1000, 10000):
        assert quantiles.chi2_isf(p, dof) == pytest.approx(stats.chi2.isf(p, dof), rel=1e-12)
        assert quantiles.t_isf(p, dof) == pytest.approx(stats.t.isf(p, dof), rel=1e-9)  # through F(1, dof)
    assert quantiles.norm_isf(p) == pytest.approx(stats.norm.isf(p), rel=1e-14)


def test_incomplete_functions_at_their_ends_and_bad_tails() -> None:
    assert quantiles.beta_lower(2.0, 3.0, 0.0) == 0.0 and quantiles.beta_lower(2.0, 3.0, 1.0) == 1.0
    assert quantiles.beta_lower(2.0, 3.0, 0.3) == pytest.approx(special.betainc(2.0, 3.0, 0.3), rel=1e-13)
    assert quantiles.gamma_upper(1.5, 0.0) == 1.0
    for x in (0.1, 2.0, 2.6, 40.0):
        assert quantiles.gamma_upper(1.5, x) == pytest.approx(special.gammaincc(1.5, x), rel=1e-12)
    for bad in (0.0, 1.0, -0.1, np.nan):
        with pytest.raises(ValueError, match="tail probability"):
            quantiles.f_isf(bad, 3.0, 10.0)


def test_normal_quantile_is_statistics_normal_dist_bit_for_bit_without_importing_statistics(monkeypatch) -> None:
    """norm_isf takes CPython's C form of NormalDist.inv_cdf (no import of statistics at a command's start): the same
    values to the last bit, and NormalDist itself where the C form is absent."""
    import subprocess
    import sys
    from statistics import NormalDist

    rng = np.random.default_rng(3)
    for p in [*rng.uniform(size=2000), *(10.0 ** -np.arange(1, 300, 7)), 0.5, 1 - 1e-16, 1e-300]:
        assert quantiles.norm_isf(float(p)) == -NormalDist().inv_cdf(float(p))
    monkeypatch.setattr(quantiles, "_normal_dist_inv_cdf", None)
    assert quantiles.norm_isf(0.01) == -NormalDist().inv_cdf(0.01)
    probe = "import sys; from optcal.core import quantiles; quantiles.chi2_isf(0.01, 3); print('statistics' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
