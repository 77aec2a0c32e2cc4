"""optcal's noise identification, equivalent degrees of freedom and χ² intervals against allantools, the peer.

:mod:`optcal.families.noise.stability` is written from the papers (Riley & Greenhall 2004, Greenhall & Riley 2003,
NIST SP 1065); allantools (installed with the test extra) implements the same algorithms in ``allantools/ci.py``
(``autocorr_noise_id``, ``edf_greenhall``, ``confidence_interval``).  On generated white, flicker and random-walk
noise of several lengths the noise ids must be equal, the EDFs and the intervals equal to 10⁻⁹; the χ² quantiles
of :func:`optcal.core.quantiles.chi2_ppf` equal scipy's to 10⁻¹⁰ up to 10⁸ degrees of freedom; the exact
non-negative least squares equals scipy's; and the Allan command's modules import neither allantools nor scipy.
"""

from __future__ import annotations

import math
import subprocess
import sys

import allantools
import allantools.ci as peer
import numpy as np
import pytest
from scipy.optimize import nnls as scipy_nnls
from scipy.stats import chi2

from optcal.core.quantiles import chi2_ppf
from optcal.families.noise.allan import allan_deviation, nnls, phase_from_rate, simulate_noise
from optcal.families.noise.stability import ONE_SIGMA, chi2_interval, greenhall_edf, lag1_noise_id

RATE = 100.0


def _noise(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """White, flicker (1/f from the spectrum) or random-walk rate noise, or the three summed, of ``n`` samples."""
    parts = {"white": (1e-3, 0.0, 0.0), "flicker": (0.0, 1e-3, 0.0), "random walk": (0.0, 0.0, 1e-3),
             "mixed": (1e-3, 2e-4, 2e-5)}[kind]
    return simulate_noise(n, RATE, *parts, rng=rng)


@pytest.mark.parametrize("kind", ["white", "flicker", "random walk", "mixed"])
@pytest.mark.parametrize("n", [3_000, 40_000, 200_000])
def test_noise_id_equals_allantools_at_every_octave(kind: str, n: int) -> None:
    phase = phase_from_rate(_noise(kind, n, np.random.default_rng([n, len(kind)])), RATE)
    ids = []
    m = 1
    while (phase.size - 1) // m >= 30:
        head = phase[: 2048 * m + 1]  # as allan_deviation does
        alpha, alpha_float, d, rho = peer.autocorr_noise_id(head, m, data_type="phase", dmin=0, dmax=2)
        mine = lag1_noise_id(head, m)
        assert (mine.alpha, mine.differences) == (alpha, d)
        assert mine.alpha_estimate == pytest.approx(alpha_float, rel=1e-9, abs=1e-12)
        assert mine.delta == pytest.approx(rho, rel=1e-9, abs=1e-12)
        ids.append(alpha)
        m *= 2
    # the generated noise is identified as what it is where its term dominates (τ_0's octave, away from the ends)
    expected = {"white": 0, "flicker": -1, "random walk": -2}.get(kind)
    if expected is not None:
        assert ids[0] == expected


@pytest.mark.parametrize("n_phase", [101, 1_001, 20_001, 720_001, 4_320_001])
def test_greenhall_edf_equals_allantools(n_phase: int) -> None:
    """Every case of the algorithm: the exact sum (J ≤ 100, m' = m or ∞), the tables (r > d + 1) and the sum at
    J_max between; the Allan (d = 2), first-difference and Hadamard variances; both estimators."""
    compared = 0
    for d in (1, 2, 3):
        for alpha in range(-3, 3):
            if alpha + 2 * d <= 1:
                continue
            for m in (1, 2, 3, 8, 16, 25, 33, 34, 64, 100, 1024, 2**14, 2**18):
                for overlapping in (True, False):
                    if 1 + math.floor((m if overlapping else 1) * (n_phase - 1 - m * d) / m) < 1:
                        continue  # no term: allantools returns a negative edf, optcal refuses
                    try:
                        ref = peer.edf_greenhall(alpha=alpha, d=d, m=m, N=n_phase, overlapping=overlapping,
                                                 modified=False)
                    except NotImplementedError:  # white phase noise with ⌈r⌉ ≤ d: neither computes it
                        with pytest.raises(ValueError):
                            greenhall_edf(alpha, d, m, n_phase, overlapping)
                        continue
                    assert greenhall_edf(alpha, d, m, n_phase, overlapping) == pytest.approx(ref, rel=1e-9)
                    compared += 1
    assert compared > 150


@pytest.mark.parametrize("dof", [0.8, 1.0, 2.5, 17.0, 150.0, 1_999.0, 2_000.0, 2_001.0, 4.1e4, 3.3e6, 4.3e7, 1e8])
def test_chi2_ppf_equals_scipy(dof: float) -> None:
    for q in (1e-3, 0.025, 0.05, (1 - ONE_SIGMA) / 2, 0.5, (1 + ONE_SIGMA) / 2, 0.95, 0.975, 0.999):
        assert chi2_ppf(q, dof) == pytest.approx(float(chi2.ppf(q, dof)), rel=1e-10)


@pytest.mark.parametrize("edf", [1.0, 3.7, 48.0, 2.5e3, 6.1e5, 4.3e6])
@pytest.mark.parametrize("confidence", [ONE_SIGMA, 0.9, 0.95])
def test_chi2_interval_equals_allantools(edf: float, confidence: float) -> None:
    low, high = peer.confidence_interval(2.5e-3, edf, confidence)
    mine = chi2_interval(2.5e-3, edf, confidence)
    assert mine == pytest.approx((low, high), rel=1e-9)
    assert ONE_SIGMA == pytest.approx(float(peer.ONE_SIGMA_CI), rel=1e-15)


@pytest.mark.parametrize("kind", ["white", "flicker", "random walk", "mixed"])
@pytest.mark.parametrize("n", [5_000, 120_000])
def test_allan_curve_intervals_equal_the_peer_chain(kind: str, n: int) -> None:
    """The whole curve: allantools' noise id, EDF and interval at every τ of :func:`allan_deviation`."""
    y = _noise(kind, n, np.random.default_rng([n, 3, len(kind)]))
    curve = allan_deviation(y, RATE)
    phase = phase_from_rate(y, RATE)
    _, ref_adev, _, _ = allantools.oadev(y, rate=RATE, data_type="freq", taus=curve.taus)
    last = 0
    for i, m in enumerate(np.rint(curve.taus * RATE).astype(int)):
        if (phase.size - 1) // m >= 30:
            last = int(np.clip(peer.autocorr_noise_id(phase[: 2048 * m + 1], m, data_type="phase")[0], -2, 1))
        assert curve.alpha[i] == last
        edf = peer.edf_greenhall(alpha=last, d=2, m=int(m), N=phase.size, overlapping=True, modified=False)
        assert curve.edf[i] == pytest.approx(edf, rel=1e-9)
        low, high = peer.confidence_interval(ref_adev[i], edf, ONE_SIGMA)
        assert (curve.ci_low[i], curve.ci_high[i]) == pytest.approx((low, high), rel=1e-9)


def test_exact_nnls_equals_scipy() -> None:
    rng = np.random.default_rng(12)
    taus = 2.0 ** np.arange(12) / RATE
    for trial in range(200):
        columns = [1.0 / taus, np.ones_like(taus), taus / 3.0][: 1 + trial % 3]
        design = np.column_stack(columns) * rng.uniform(0.5, 2.0, (taus.size, 1))
        target = design @ rng.normal(0.0, 1.0, design.shape[1]) + rng.normal(0.0, 0.3, taus.size)
        np.testing.assert_allclose(nnls(design, target), scipy_nnls(design, target)[0], rtol=1e-9, atol=1e-12)


def test_the_allan_command_imports_neither_allantools_nor_scipy() -> None:
    code = ("import sys, optcal.cli.main, optcal.cli.cmd_allan, optcal.families.noise.analysis, "
            "optcal.applications.diagnosis.still_noise; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'allantools', 'scipy'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_head_of_one_quantised_value_keeps_the_previous_noise_id() -> None:
    """A quantised sensor whose first 2100 samples read its mean exactly: the phase does not vary there, so the lag-1
    autocorrelation is undefined (allantools' own identification fails on it: int(nan)); optcal skips that τ's
    identification (the exponent of the τ before, white frequency noise before any) instead of failing."""
    with pytest.raises(ValueError, match="does not vary"):
        lag1_noise_id(np.zeros(100), 1)
    rest = np.random.default_rng(4).permutation(np.repeat([0.25, -0.25], 19_000))  # mean exactly 0
    y = np.concatenate([np.zeros(2_100), rest])
    phase = phase_from_rate(y, RATE)
    assert not np.any(phase[:2_101])  # the head of the phase is exactly zero
    curve = allan_deviation(y, RATE)
    assert curve.alpha[0] == 0
    assert np.all(np.isfinite(curve.ci_low)) and np.all(np.isfinite(curve.ci_high))
