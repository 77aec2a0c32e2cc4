"""optcal's overlapping Allan deviation against allantools, the reference it replaces on the hot path.

optcal computes σ(τ) from the cumulative sum of the samples (Riley, NIST SP 1065, eq. 11;
:func:`optcal.families.noise.allan.overlapping_adev`); allantools' ``oadev`` is the peer
implementation (BSD-3 licence, allantools/allantools.py ``calc_adev_phase``).  On short series of
white, random-walk and quantised noise, with a large mean (1 g on a vertical axis, where the
sum loses digits unless the mean is removed first), every octave τ agrees to 1e-12 relative,
and so do the numbers of terms.
"""

from __future__ import annotations

import allantools
import numpy as np
import pytest

from optcal.families.noise.allan import allan_deviation, octave_taus, overlapping_adev, phase_from_rate


def _series(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    white = rng.normal(0.0, 2e-3, n)
    if kind == "white":
        return 1.0 + white
    if kind == "random walk":
        return -0.98 + white + np.cumsum(rng.normal(0.0, 5e-5, n))
    return np.round((0.5 + white) * 16384) / 16384  # quantised to an MPU6050's 1/16384 g


@pytest.mark.parametrize("kind", ["white", "random walk", "quantised"])
@pytest.mark.parametrize("rate_hz", [100.0, 33.3])
def test_overlapping_adev_equals_allantools_oadev(kind: str, rate_hz: float) -> None:
    y = _series(kind, 20_000, np.random.default_rng(7))
    taus = octave_taus(y.size, rate_hz)
    ms = np.rint(taus * rate_hz).astype(int)
    adev, n_terms = overlapping_adev(phase_from_rate(y, rate_hz), rate_hz, ms)
    ref_taus, ref_adev, _, ref_n = allantools.oadev(y, rate=rate_hz, data_type="freq", taus=taus)
    np.testing.assert_allclose(ms / rate_hz, ref_taus, rtol=1e-15)
    np.testing.assert_allclose(adev, ref_adev, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(n_terms, ref_n)
    np.testing.assert_allclose(phase_from_rate(y, rate_hz), allantools.frequency2phase(y, rate_hz), rtol=1e-12, atol=1e-18)


def test_allan_deviation_reports_the_reference_curve() -> None:
    y = _series("random walk", 12_000, np.random.default_rng(11))
    curve = allan_deviation(y, 50.0)
    ref_taus, ref_adev, _, ref_n = allantools.oadev(y, rate=50.0, data_type="freq", taus=curve.taus)
    np.testing.assert_allclose(curve.taus, ref_taus, rtol=1e-15)
    np.testing.assert_allclose(curve.adev, ref_adev, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(curve.n_terms, ref_n)


def test_a_cluster_longer_than_half_the_phase_is_refused() -> None:
    from optcal.errors import InputError

    with pytest.raises(InputError, match="phase points"):
        overlapping_adev(np.zeros(10), 1.0, [5])


def test_the_pieces_formed_together_sum_as_one_piece_at_a_time() -> None:
    """σ(τ) is, to the last bit, the in-order sum of each :data:`ADEV_PIECE`-point piece's ``np.dot`` (the sum the
    pieces had when formed one at a time), on a series that spans several passes of :data:`ADEV_ROWS` pieces and
    ends in a partial piece."""
    from optcal.families.noise.allan import ADEV_PIECE, ADEV_ROWS

    y = _series("random walk", 2 * ADEV_PIECE * ADEV_ROWS + 3 * ADEV_PIECE + 1234, np.random.default_rng(5))
    phase = phase_from_rate(y, 100.0)
    ms = np.rint(octave_taus(y.size, 100.0) * 100.0).astype(int)
    adev, _ = overlapping_adev(phase, 100.0, ms)
    for k, m in enumerate(ms):
        n = phase.size - 2 * m
        second = (phase[m : m + n] * -2.0 + phase[2 * m :]) + phase[:n]  # Riley, NIST SP 1065, eq. 11, optcal's order
        total = 0.0
        for a in range(0, n, ADEV_PIECE):
            total += float(np.dot(second[a : a + ADEV_PIECE], second[a : a + ADEV_PIECE]))
        assert adev[k] == np.sqrt(total / (2.0 * n)) / m * 100.0, f"m = {m}"
