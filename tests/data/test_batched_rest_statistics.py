"""The rest model's batched statistics equal the same statistic computed one stretch, window or group at a time.

The rest model computes several statistics for all stretches at once (the half-sample modes of the gyro's spans, the
rests' median block variances, the orientation wobble of every candidate rest): faster, and meant to decide exactly as
one call per stretch.  Each is checked here against a plain reference written out in the test, on random data with
ties, a large bias and uneven lengths.
"""

from __future__ import annotations

import numpy as np
import pytest

from optcal.data.quantiles import column_medians, grouped_column_medians
from optcal.data.rest_model import WOBBLE_SHRINK, column_half_sample_modes, windowed_half_sample_modes
from optcal.data.static_stretches import RESOLVED_WOBBLE_SHARE, wobble, wobbles


def reference_wobble(gyro, t, rad_per_unit, window, tolerance=None):
    """The wobble of one stretch as :func:`optcal.data.static_stretches.wobble` documents it, window by window."""
    m = gyro.shape[0]
    if m < 3:
        return 0.0
    if tolerance is not None:
        bound = (t[min(window, m) - 1] - t[0]) * np.sqrt(np.sum(np.var(gyro, axis=0))) * rad_per_unit
        if bound <= tolerance:
            return bound
    full = (m // window) * window
    windows = [(i, i + window) for i in range(0, full, window)]
    if m - full >= 3:
        windows.append((full, m))
    total = noise = count = 0.0
    for a, z in windows:
        w = gyro[a:z] * rad_per_unit
        tt = t[a:z]
        white = np.sum(np.var(np.diff(w, axis=0), axis=0)) / 2.0
        w = w - w.mean(axis=0)
        angle = np.vstack([np.zeros(3), np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(tt)[:, None], axis=0)])
        angle -= angle.mean(axis=0)
        total += np.sum(angle * angle)
        span = tt[-1] - tt[0]
        noise += (z - a) * white * np.mean(np.diff(tt)) * span / 12.0
        count += z - a
    if noise > RESOLVED_WOBBLE_SHARE**2 * 2.0 * WOBBLE_SHRINK * count:
        return 0.0
    return float(np.sqrt(max(total - noise, 0.0) / count))


@pytest.mark.parametrize("seed", range(6))
def test_wobbles_of_many_stretches_equal_the_reference_one_by_one(seed):
    rng = np.random.default_rng(seed)
    n = 4000
    t = np.cumsum(rng.uniform(0.004, 0.012, n))  # uneven host stamps
    gyro = rng.normal(size=(n, 3)) * 0.5 + np.array([3000.0, -2000.0, 150.0])  # counts with a large bias
    gyro[1000:1800] += 40.0 * np.sin(2 * np.pi * 4.0 * t[1000:1800])[:, None]  # a tremor in one stretch
    if seed % 2:
        gyro = np.round(gyro)  # quantised
    cuts = np.sort(rng.choice(np.arange(1, n), size=11, replace=False))
    edges = np.r_[0, cuts, n]
    spans = [(int(edges[i]), int(edges[i + 1])) for i in range(0, edges.size - 1, 2)]
    spans.append((n - 2, n))  # too short to wobble
    for tolerance in (None, 0.02, 1e-6):
        got = wobbles(gyro, t, 1e-4, 300, sorted(set(spans)), tolerance)
        for (a, z), value in zip(sorted(set(spans)), got):
            expected = reference_wobble(gyro[a:z], t[a:z], 1e-4, 300, tolerance)
            assert value == pytest.approx(expected, rel=1e-8, abs=1e-15)
            assert (value == 0.0) == (expected == 0.0)
    assert wobble(gyro[1000:1800], t[1000:1800], 1e-4, 300) > 0.0


@pytest.mark.parametrize("seed", range(4))
def test_windowed_half_sample_modes_equal_one_call_per_window(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(700, 3))
    if seed % 2:
        x = np.round(x * 4) / 4  # ties
    lo = rng.integers(0, 700, size=40)
    hi = np.minimum(lo + rng.integers(1, 300, size=40), 700)
    lo[:6], hi[:6] = [0, 699, 700, 350, 10, 20], [0, 700, 700, 350, 13, 24]  # empty (NaN), at the end, 3 and 4 values
    got = windowed_half_sample_modes(x, lo, hi)
    for i in range(lo.size):
        assert np.array_equal(got[i], column_half_sample_modes(x[lo[i]:hi[i]]), equal_nan=True)
    # a zero's sign included, as the windows were halved by index arrays (the padded lanes' sort picks which zero)
    assert got.tobytes() == indexed_windowed_half_sample_modes(x, lo, hi).tobytes()
    few = windowed_half_sample_modes(x, np.array([10, 20, 30]), np.array([13, 24, 31]))  # at most 4 values
    assert few.tobytes() == indexed_windowed_half_sample_modes(x, np.array([10, 20, 30]), np.array([13, 24, 31])).tobytes()


def indexed_windowed_half_sample_modes(x, lo, hi):
    """:func:`windowed_half_sample_modes` as it was written with index arrays (``take_along_axis``, clipped)."""
    w, m = lo.size, x.shape[1]
    counts = np.maximum(hi - lo, 0)
    width = int(counts.max())
    at = np.arange(width)
    inside = at[None, :] < counts[:, None]
    y = x[np.minimum(lo[:, None] + at[None, :], x.shape[0] - 1)]
    y = np.sort(np.where(inside[:, :, None], y, np.inf), axis=1)
    y = np.ascontiguousarray(y.transpose(0, 2, 1)).reshape(w * m, width)
    n = np.repeat(counts, m)
    while bool((n > 3).any()):
        halve = n > 3
        h = np.where(halve, (n + 1) // 2, n)
        span = int((n - h + 1)[halve].max())
        j = np.arange(span)
        upper = np.take_along_axis(y, np.minimum(j[None, :] + h[:, None] - 1, y.shape[1] - 1), axis=1)
        with np.errstate(invalid="ignore"):
            widths = np.where(j[None, :] <= (n - h)[:, None], upper - y[:, :span], np.inf)
        start = np.where(halve, np.argmin(widths, axis=1), 0)
        k = np.arange(int(h.max()))
        y = np.take_along_axis(y, np.minimum(start[:, None] + k[None, :], y.shape[1] - 1), axis=1)
        y = np.where(k[None, :] < h[:, None], y, np.inf)
        n = h
    out = np.full(n.size, np.nan)
    one, two, three = n == 1, n == 2, n == 3
    out[one] = y[one, 0]
    out[two] = 0.5 * (y[two, 0] + y[two, 1])
    y3 = y[three, :3]
    lower, upper3 = y3[:, 1] - y3[:, 0], y3[:, 2] - y3[:, 1]
    out[three] = np.where(lower < upper3, 0.5 * (y3[:, 0] + y3[:, 1]),
                          np.where(lower > upper3, 0.5 * (y3[:, 1] + y3[:, 2]), y3[:, 1]))
    return out.reshape(w, m)


@pytest.mark.parametrize("seed", range(6))
def test_grouped_medians_equal_one_call_per_group(seed):
    rng = np.random.default_rng(seed)
    sizes = rng.integers(1, 40, size=60)
    if seed in (2, 3):
        sizes[3] = 2000  # one long group: the sort per column, not the stacked one
    if seed >= 4:
        sizes = rng.integers(1, 3000, size=9)  # few long groups (a long log's rests): a partition per group
    x = rng.gamma(2.0, size=(int(sizes.sum()), 3))
    if seed % 2:
        x = np.round(x, 1)
    got = grouped_column_medians(x, sizes)
    edges = np.r_[0, np.cumsum(sizes)]
    for i in range(sizes.size):
        assert np.array_equal(got[i], column_medians(x[edges[i]:edges[i + 1]]))
        assert np.array_equal(got[i], np.median(x[edges[i]:edges[i + 1]], axis=0))


def test_rests_counted_without_pose_statistics_are_the_same_rests(shared_data):
    """The Allan command's still fraction: ``detect_static(..., pose_statistics=False)`` finds the same rests (places
    and samples) as the full segmentation, and its segmentation refuses to make a pose table."""
    from optcal.data import load_recording
    from optcal.data.static import detect_static

    import dataclasses

    rec = load_recording(str(shared_data / "imutk-xsens" / "xsens_imutk.csv"))
    full, counted = detect_static(rec), detect_static(rec, pose_statistics=False)

    def places(seg):  # where each pose is, in samples, rows and time, and its samples
        return [(iv.start, iv.stop, iv.first_row, iv.last_row, iv.t_start, iv.t_end, iv.n_samples)
                for iv in seg.intervals]

    assert places(counted) == places(full)
    assert counted.n_used == full.n_used and len(full.intervals) == 38 and full.joined == 4  # poses of joined rests
    with pytest.raises(ValueError, match="counted its rests only"):
        counted.pose_table()
    # unusable samples inside the rests (every 97th): positions among the usable samples mapped to the recording's
    usable = rec.usable.copy()
    usable[::97] = False
    holed = dataclasses.replace(rec, usable=usable)
    full, counted = detect_static(holed), detect_static(holed, pose_statistics=False)
    assert places(counted) == places(full) and full.joined > 0 and len(full.intervals) > 30


def expression_wobbles(gyro, t, rad_per_unit, window, spans):
    """:func:`wobbles` without its tolerance, written as plain whole-array expressions (windows, samples, axes):
    the form it had before its scratch arrays were laid out samples first and reused in place."""
    from optcal.data.static_stretches import _ranks

    a = np.array([s[0] for s in spans], dtype=np.intp)
    z = np.array([s[1] for s in spans], dtype=np.intp)
    m = z - a
    rows = np.flatnonzero(m >= 3)
    whole = m[rows] // window
    rest = m[rows] - whole * window
    owner = np.concatenate([np.repeat(rows, whole), rows[rest >= 3]])
    first = np.concatenate([np.repeat(a[rows], whole) + _ranks(whole) * window, (a[rows] + whole * window)[rest >= 3]])
    n = np.concatenate([np.full(int(whole.sum()), window), rest[rest >= 3]]).astype(np.intp)
    j = np.arange(int(n.max()))
    idx = np.minimum(first[:, None] + j[None, :], gyro.shape[0] - 1)
    inside = j[None, :] < n[:, None]
    pair = inside[:, 1:] & inside[:, :-1]
    w = np.where(inside[..., None], gyro[idx], 0.0)
    tt = t[idx]
    dt = np.where(pair, np.diff(tt, axis=1), 0.0)
    d = np.where(pair[..., None], np.diff(w, axis=1), 0.0)
    k = (n - 1.0)[:, None]
    white = np.sum(np.sum(d * d, axis=1) / k - (np.sum(d, axis=1) / k) ** 2, axis=1) / 2.0
    mean = w.sum(axis=1) / n[:, None]
    angle = np.cumsum((0.5 * (w[:, 1:] + w[:, :-1]) - mean[:, None, :]) * dt[..., None], axis=1)
    angle = np.where(pair[..., None], angle, 0.0)
    spread2 = np.sum(np.sum(angle * angle, axis=1) - np.sum(angle, axis=1) ** 2 / n[:, None], axis=1)
    span = tt[np.arange(n.size), n - 1] - tt[:, 0]
    total = np.bincount(owner, weights=spread2, minlength=a.size)[rows] * rad_per_unit**2
    noise = np.bincount(owner, weights=n * white * (span / (n - 1.0)) * span / 12.0, minlength=a.size)[rows] * rad_per_unit**2
    n_all = np.maximum(np.bincount(owner, weights=n, minlength=a.size)[rows], 1.0)
    out = np.zeros(a.size)
    resolved = noise <= RESOLVED_WOBBLE_SHARE**2 * 2.0 * WOBBLE_SHRINK * n_all
    out[rows] = np.where(resolved, np.sqrt(np.maximum(total - noise, 0.0) / n_all), 0.0)
    return out


@pytest.mark.parametrize("seed", range(4))
def test_wobbles_bit_for_bit_as_the_plain_expressions(seed, monkeypatch):
    """The windows' sums add the samples in the same order as the plain expressions (so the same numbers to the last
    bit, which decide the same rests): one window or many, windows cut short, C or Fortran order, several chunks."""
    import optcal.data.wobble as ss  # the module whose wobbles reads the chunk size

    rng = np.random.default_rng(100 + seed)
    if seed % 2:
        monkeypatch.setattr(ss, "WOBBLE_CHUNK_VALUES", 5000)  # several chunks of windows
    for trial in range(40):
        n = int(rng.integers(30, 3000))
        gyro = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-3, 3) + rng.normal(size=3) * 10 ** rng.uniform(-2, 4)
        if trial % 2:
            gyro = np.asfortranarray(np.round(gyro))
        t = np.cumsum(rng.uniform(0.005, 0.015, size=n))
        cuts = np.sort(rng.choice(n, size=2 * int(rng.integers(1, 6)), replace=False))
        spans = [(int(x), int(y)) for x, y in zip(cuts[0::2], cuts[1::2])]
        window = int(rng.integers(3, 400))
        if all(z - a < 3 for a, z in spans):
            continue
        assert np.array_equal(wobbles(gyro, t, 1e-3, window, spans), expression_wobbles(gyro, t, 1e-3, window, spans))


def test_the_wobble_bound_summed_by_blocks_clears_the_stretches_the_samples_clear(shared_data):
    """The rest model's wobble bound (:func:`~optcal.data.static_stretches.wobbles` with ``tolerance``) summed from its
    blocks' moments, as :func:`~optcal.data.static.detect_static` does, against the samples' own sums: on the xsens
    recording's candidate rests, and with a 1 Hz sway of growing size planted in every other one, the same verdict
    for every stretch; the blocks' spread² with its rounding margin never below the samples', and above them by at most
    the ``q²/12`` per axis its blocks' variances carry (this gyro counts in whole units, its planted sway does not);
    stretches decided by the bound, window by window, and wobbling, all present; spans given out of order (their
    blocks gathered) the same sums to the bit."""
    import dataclasses

    import optcal.data.static as st
    from optcal.data import load_recording
    from optcal.data.static_stretches import _block_span_sums, _span_sums, _spread_margin
    from optcal.data.quantiles import np_column_medians
    from optcal.data.quantisation import quantum

    rec = load_recording(str(shared_data / "imutk-xsens" / "xsens_imutk.csv"))
    calls = []

    def spy(*args):
        calls.append(args)
        return wobbles(*args)

    def candidates(recording):
        calls.clear()
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(st, "wobbles", spy)
            st.detect_static(recording, pose_statistics=False)
        return calls[0]

    still = candidates(rec)
    gyro, t, scale, window, spans, tolerance, blocks = still
    planted = rec.gyro.copy()
    for k, (a, z) in enumerate(spans[1::2]):  # a hand's 1 Hz sway, its rms angle from 1 % of the tolerance to 10 times
        rate = tolerance / scale * 10.0 ** (-1.0 + 3.0 * k / max(1, len(spans) // 2 - 1))
        planted[a:z] += rate * np.sin(2 * np.pi * t[a:z])[:, None] * np.array([1.0, -0.5, 0.3])
    decided = {"bound": 0, "windows": 0, "wobbling": 0}
    sway = candidates(dataclasses.replace(rec, gyro=planted))
    # the candidates of the recording, without and with the sway (the blocks of the swaying gyro: a stretch that sways
    # hard has blocks off the bias and is no candidate of its own), and the swaying recording's own candidates
    for gyro, spans, blocks in ((still[0], spans, blocks), (sway[0], spans, sway[6]), (sway[0], sway[4], sway[6])):
        by_blocks = wobbles(gyro, t, scale, window, spans, tolerance, blocks)
        by_samples = wobbles(gyro, t, scale, window, spans, tolerance)
        assert np.array_equal(by_blocks > tolerance, by_samples > tolerance)
        bound = by_samples != wobbles(gyro, t, scale, window, spans)  # the bound's value, not the windows' wobble
        decided["bound"] += int(np.count_nonzero(bound))
        decided["windows"] += int(np.count_nonzero(~bound & (by_samples <= tolerance)))
        decided["wobbling"] += int(np.count_nonzero(by_samples > tolerance))
        a = np.array([s[0] for s in spans])
        z = np.array([s[1] for s in spans])
        centre = np_column_medians(gyro[a])
        m = (z - a)[:, None]
        spreads = []
        for s1, s2 in (_span_sums(gyro, a, z, centre), _block_span_sums(gyro, blocks, a, z, centre)):
            spreads.append(np.maximum(s2 / m - (s1 / m) ** 2, 0.0).sum(axis=1))
        samples, summed = spreads
        margin = _spread_margin(_block_span_sums(gyro, blocks, a, z, centre)[1] / m, z - a)
        back = _block_span_sums(gyro, blocks, a[::-1], z[::-1], centre)  # spans out of order: their blocks gathered
        assert all(np.array_equal(x[::-1], y) for x, y in zip(back, _block_span_sums(gyro, blocks, a, z, centre)))
        q = quantum(gyro) or 0.0
        assert np.all(summed + margin >= samples)
        assert np.all(summed - samples <= 3.0 * q * q / 12.0 + 1e-12 * samples)
    assert min(decided.values()) > 0, decided
