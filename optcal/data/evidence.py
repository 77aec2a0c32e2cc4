"""Evidence (the second step of the data layer): one pass of statistics over what was read.

:func:`gather_evidence` computes, once and in this one place, every statistic of the samples
that the decisions (:mod:`optcal.data.decisions`) and the conversion
(:mod:`optcal.data.recording`) use: the usable rows and what was excluded, the median norm and
the median step between rows, the time column's steps, and for counts the statistics of the
nominal conversion (whether they sit around an unsigned converter's mid-scale, and their norm
about it).  When the column names do not settle which triple is the accelerometer
(:class:`~optcal.data.columns.ColumnRoles`), it also measures how each candidate triple reads
at rest (:class:`RoleEvidence`), and the statistics above for each reading of the roles.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from optcal.data.columns import ACC, GYRO
from optcal.data.quantiles import column_medians, median, quantiles
from optcal.data.readers import Source
from optcal.data.units import MAX_REST_NOISE_G, MS2_NORM_RANGE, UNSIGNED_16_MAX, UNSIGNED_16_MIDSCALE, sphere_through

#: An axis beyond this many g (by the median norm as 1 g) is beyond any accelerometer's full scale.
ABSURD_G: float = 64.0
#: Rows per piece of the evidence's element-wise passes: their temporaries (512 KiB of numbers, 64 KiB of
#: flags) stay in the processor's cache and are reused, instead of a new array of the file's length per
#: operation (two to six times faster on a 12-hour log, the same numbers).
EVIDENCE_PIECE: int = 2**16
#: Rows from which the evidence's element-wise passes run on two threads, each over half the rows (numpy's
#: element-wise operations release the interpreter, so two cores share them; the same numbers, element by
#: element): on the 12-hour still log the passes are 0.3 CPU s on the reading's serial path, where a thread's
#: start (about 0.1 ms) is nothing; below 8 pieces (a few seconds of a log) it is not worth one.
PARALLEL_ROWS: int = 8 * 2**16
#: Stamps are bursty when 1/median(Δt) exceeds (N−1)/duration by this factor.
BURST_RATIO: float = 2.0
#: Stamps are coarse when more than this fraction of the steps repeat the previous stamp.
COARSE_REPEATED_FRACTION: float = 0.05

# exclusion counters (also the keys of ``PoseTable.exclusions``)
NON_FINITE = "non-finite samples (empty, non-numeric or truncated cells)"
ZERO_ROWS = "all-zero rows (an unfilled buffer)"
ABSURD = f"samples beyond any full scale (an axis above {ABSURD_G:g} g)"

# ------------------------------------------------------------------ how a candidate triple reads at rest
#: Rows per block of the rest statistics: enough for a block's standard deviation to measure the
#: noise (15 degrees of freedom per axis), few enough that a rest of a fraction of a second holds
#: whole blocks at the usual 50 Hz to 1 kHz.
ROLE_BLOCK_SAMPLES: int = 16
#: The noise floor of a triple: this quantile of its blocks' per-sample standard deviations (the
#: quietest tenth of a recording is at rest).
NOISE_FLOOR_QUANTILE: float = 0.1
#: A block is quiet when its standard deviation is within this factor of the noise floor (the static
#: detection's default gate, ``--static-threshold 3``); the rest statistics use the blocks where
#: every candidate triple is quiet.
QUIET_FACTOR: float = 3.0
#: Fewer quiet blocks than this (≈ 1.3 s at 100 Hz) say nothing about the rests.
MIN_QUIET_BLOCKS: int = 8
#: A rest reading this many per-sample noise standard deviations from the triple's median rest reading
#: has moved: a turn of 60° or more moves an accelerometer's reading by 1 g or more, at least
#: 1 / :data:`~optcal.data.units.MAX_REST_NOISE_G` = 20 times its noise (a resting accelerometer's noise
#: is at most 0.05 g); a gyroscope's rest reading stays at its bias, within its noise.
MOVED_NOISE_RATIO: float = 1.0 / MAX_REST_NOISE_G
#: A triple whose rest readings are away from their median for this fraction of the rest time or more
#: was turned between rests (a calibration spreads its rests over six or more orientations); a
#: gyroscope at rest reads its bias in every orientation, away from it only on the rare quiet
#: stretch of a steady turn.
TURNED_FRACTION: float = 0.2
#: An accelerometer's rest readings lie on one sphere around its zero (radius 1 g) up to its
#: scale-factor and cross-axis errors, a few percent: 90 % of them within this fraction of the
#: fitted radius is a sphere.  A gyroscope's rest readings are one point (its bias), or, on a
#: rate table, rates of different sizes.
SPHERE_MISFIT: float = 0.1


@dataclass(frozen=True)
class TimeEvidence:
    """Statistics of a time column over the usable rows (in the column's own unit).

    Attributes
    ----------
    n : int
    duration : float
    median_step, min_positive_step : float
    repeated : int
        Steps of exactly zero (a repeated stamp).
    backwards : int
        Negative steps.
    first_backwards : int or None
        Index (into the usable rows) of the first sample after a negative step.
    regular_fraction : float
        Fraction of the steps within ±50 % of the median step (0 when the median step is not positive).
    start : float
        The first stamp (NaN when unknown): a date since 1970 in one unit is evidence of that unit.
    """

    n: int
    duration: float
    median_step: float
    min_positive_step: float
    repeated: int
    backwards: int
    first_backwards: int | None
    regular_fraction: float = 0.0
    start: float = float("nan")

    @property
    def mean_step(self) -> float:
        return self.duration / (self.n - 1) if self.n > 1 else float("nan")

    @property
    def repeated_fraction(self) -> float:
        return self.repeated / max(1, self.n - 1)

    @property
    def bursty(self) -> bool:
        """Host stamps in bursts: the typical step is far shorter than the mean step."""
        return self.n > 10 and self.median_step > 0 and self.median_step * BURST_RATIO < self.mean_step

    @property
    def coarse(self) -> bool:
        """Stamps coarser than the sampling: many samples share a stamp."""
        return self.n > 10 and self.repeated_fraction > COARSE_REPEATED_FRACTION

    @property
    def regular(self) -> bool:
        """Steps within ±50 % of their median for 90 % of the samples (a sampled time series)."""
        return self.median_step > 0 and self.regular_fraction >= 0.9

    @property
    def series_like(self) -> bool:
        """Stamps of a time series: forwards only, and regular, bursty or coarse."""
        return self.backwards == 0 and (self.bursty or self.coarse or self.regular)


@dataclass(frozen=True)
class TripleRest:
    """How one candidate triple reads at rest (over the blocks where every candidate triple is quiet).

    Attributes
    ----------
    names : tuple of str
        The file's names of the three columns.
    noise : float
        Per-sample standard deviation at rest (median over the quiet blocks, pooled over the axes), raw units.
    moved_fraction : float
        Fraction of the quiet blocks whose mean lies more than :data:`MOVED_NOISE_RATIO` noise from
        the median rest reading.
    radius, misfit : float
        Radius of the sphere through the quiet blocks' means (NaN when they do not determine one),
        and the 90th percentile of their distances' departure from it, as a fraction of it.
    """

    names: tuple[str, str, str]
    noise: float
    moved_fraction: float
    radius: float
    misfit: float

    @property
    def turned(self) -> bool:
        """Its rest readings move between rests (:data:`TURNED_FRACTION`)."""
        return self.moved_fraction >= TURNED_FRACTION

    @property
    def on_sphere(self) -> bool:
        """Its rest readings lie on a sphere far larger than the noise (:data:`SPHERE_MISFIT`)."""
        return bool(np.isfinite(self.radius) and self.radius >= MOVED_NOISE_RATIO * self.noise
                    and self.misfit <= SPHERE_MISFIT)

    @property
    def acceleration_like(self) -> bool:
        """Read as an accelerometer turned between rests reads: moved, and on one sphere."""
        return self.turned and self.on_sphere

    def describe(self) -> str:
        """How it reads at rest, in words: ``its rest readings move more than 20 noise σ (3.09) from ...``."""
        if not self.turned:
            return (f"its rest readings stay within {MOVED_NOISE_RATIO:g} noise σ ({self.noise:.3g}) of their median "
                    f"in {100 * (1 - self.moved_fraction):.0f} % of the rest time")
        moved = (f"its rest readings move more than {MOVED_NOISE_RATIO:g} noise σ ({self.noise:.3g}) from their median "
                 f"in {100 * self.moved_fraction:.0f} % of the rest time")
        if self.on_sphere:
            return f"{moved}, on one sphere (radius {self.radius:.4g}, 90 % within {100 * self.misfit:.2g} % of it)"
        return f"{moved}, but not on one sphere"


@dataclass(frozen=True)
class RoleEvidence:
    """How each candidate triple reads at rest, and the evidence of each reading of the roles.

    Attributes
    ----------
    quiet_blocks, blocks : int
        Blocks of :data:`ROLE_BLOCK_SAMPLES` rows where every candidate triple is quiet, of all.
    triples : tuple of TripleRest
        In the order of :attr:`optcal.data.columns.ColumnRoles.triples` (empty when fewer than
        :data:`MIN_QUIET_BLOCKS` blocks are quiet).
    readings : tuple of Evidence
        The file's evidence with candidate triple ``k`` read as the accelerometer.
    """

    quiet_blocks: int
    blocks: int
    triples: tuple[TripleRest, ...]
    readings: tuple[Evidence, ...]


@dataclass(frozen=True)
class Evidence:
    """One pass of statistics over a :class:`~optcal.data.readers.Source`.

    Attributes
    ----------
    n_rows : int
    size_bytes : int
    usable : ndarray of bool
        Rows with finite accelerometer (and time, gyro, temperature) values, not all-zero,
        not absurd.
    non_finite, zero_rows, absurd : int
        Rows excluded for each reason.
    median_norm : float
        Median ‖a‖ over the usable rows, raw units.
    median_step : float
        Median ‖a_k+1 − a_k‖ over consecutive usable rows, raw units.
    time : TimeEvidence or None
    extremes : tuple of float or None
        The smallest and the largest accelerometer sample over the usable rows; measured, with the
        two below, when the median norm allows counts (the statistics of their nominal conversion,
        :func:`optcal.data.units.nominal_conversion`).
    medians : tuple of float or None
        Each accelerometer axis's median over the usable rows, when the samples are all in 0..65535.
    midscale_norm : float
        Median ‖a − 32768‖ over the usable rows, when the samples are all in 0..65535 (else NaN).
    roles : RoleEvidence or None
        When the names leave the roles of the columns open.
    """

    n_rows: int
    size_bytes: int
    usable: NDArray[np.bool_]
    non_finite: int
    zero_rows: int
    absurd: int
    median_norm: float
    median_step: float
    time: TimeEvidence | None
    extremes: tuple[float, float] | None = None
    medians: tuple[float, float, float] | None = None
    midscale_norm: float = float("nan")
    roles: RoleEvidence | None = None

    def exclusions(self) -> dict[str, int]:
        return {k: v for k, v in ((NON_FINITE, self.non_finite), (ZERO_ROWS, self.zero_rows), (ABSURD, self.absurd)) if v}


def gather_evidence(src: Source) -> Evidence:
    """The statistics every decision is made from, in one pass over the columns.

    Column by column, with no copy of the samples when every row is usable (the common
    case); the median norm over the usable rows is the one over the finite, non-zero rows
    when no row is absurd (one median, not two).  When ``src.roles`` leaves the roles of the
    columns open, also the rest statistics of each candidate triple and the evidence of each
    reading of the roles (:class:`RoleEvidence`).
    """
    ev = _reading_evidence(src)
    if src.roles is None:
        return ev
    roles = src.roles
    readings = tuple(ev if k == roles.acc else _reading_evidence(src.with_accelerometer(k))
                     for k in range(len(roles.triples)))
    by_name = {src.column_map[c]: src.data[c] for c in (*ACC, *GYRO) if c in src.data}
    triples = [tuple(by_name[name] for name in names) for names in roles.triples]
    quiet, blocks, rests = _rest_readings(roles.triples, triples)
    return replace(ev, roles=RoleEvidence(quiet, blocks, rests, readings))


def _pieces(n: int, first: int = 0) -> Iterator[tuple[int, int]]:
    """Consecutive ``(start, end)`` row ranges of :data:`EVIDENCE_PIECE` rows covering rows ``first`` to ``n``."""
    for start in range(first, n, EVIDENCE_PIECE):
        yield start, min(n, start + EVIDENCE_PIECE)


def _over_rows(n: int, work: Callable[[int, int], None]) -> None:
    """``work(lo, hi)`` over rows 0 to ``n``: in two halves on two threads from :data:`PARALLEL_ROWS` rows.

    ``work`` writes only its rows of its outputs, with temporaries of its own: element-wise passes, whose
    numbers do not depend on how the rows are shared.
    """
    if n < PARALLEL_ROWS:
        work(0, n)
        return
    import threading

    mid = n // 2
    failed: list[BaseException] = []

    def later() -> None:
        try:
            work(mid, n)
        except BaseException as exc:  # raised by the caller's thread below
            failed.append(exc)

    helper = threading.Thread(target=later, name="optcal-evidence", daemon=True)
    helper.start()
    try:
        work(0, mid)
    finally:
        helper.join()
    if failed:
        raise failed[0]


def _reading_evidence(src: Source) -> Evidence:
    """The statistics of ``src`` as its columns are mapped (see :func:`gather_evidence`).

    The masks, the norm and the steps are computed :data:`EVIDENCE_PIECE` rows at a time into
    small reused temporaries (element by element: the same numbers as whole-column operations), on
    two threads from :data:`PARALLEL_ROWS` rows (:func:`_over_rows`).
    """
    n = src.n_rows
    acc = [src.column(c) for c in ACC]  # column by column: no copy of the file's data
    finite = np.ones(n, dtype=bool)
    zero = np.empty(n, dtype=bool)
    present = [src.column(name) for name in (*ACC, "t", *GYRO, "temp") if src.has(name)]
    zero_cols = [src.column(name) for name in (*ACC, *(GYRO if src.has(*GYRO) else ()))]
    dtype = np.result_type(*acc)  # the samples' type for the temporaries, as whole-column operations

    def masks(lo: int, hi: int) -> None:
        flags = np.empty(min(hi - lo, EVIDENCE_PIECE), dtype=bool)
        for a0, z0 in _pieces(hi, lo):
            f, z, w = finite[a0:z0], zero[a0:z0], flags[: z0 - a0]
            for col in present:
                np.isfinite(col[a0:z0], out=w)
                f &= w
            z[:] = f
            for col in zero_cols:
                np.equal(col[a0:z0], 0.0, out=w)
                z &= w

    _over_rows(n, masks)
    ok = finite & ~zero
    every_ok = bool(ok.all())
    with np.errstate(over="ignore", invalid="ignore"):
        # the median norm ignores a few absurd cells; then an axis beyond ABSURD_G of it is absurd
        norm = np.empty(n, dtype=np.result_type(acc[0], acc[0]))

        def norms(lo: int, hi: int) -> None:
            values = np.empty(min(hi - lo, EVIDENCE_PIECE), dtype=dtype)
            for a0, z0 in _pieces(hi, lo):
                part, w = norm[a0:z0], values[: z0 - a0]
                np.multiply(acc[0][a0:z0], acc[0][a0:z0], out=part)
                for a in acc[1:]:
                    np.multiply(a[a0:z0], a[a0:z0], out=w)
                    part += w
                np.sqrt(part, out=part)

        _over_rows(n, norms)
        med = median(norm if every_ok else norm[ok]) if ok.any() else float("nan")
        absurd = np.zeros(n, dtype=bool)
        if np.isfinite(med) and med > 0:
            limit = ABSURD_G * med

            def absurds(lo: int, hi: int) -> None:
                values = np.empty(min(hi - lo, EVIDENCE_PIECE), dtype=dtype)
                flags = np.empty(min(hi - lo, EVIDENCE_PIECE), dtype=bool)
                for a0, z0 in _pieces(hi, lo):
                    w, hit = values[: z0 - a0], flags[: z0 - a0]
                    for a in acc:
                        np.abs(a[a0:z0], out=w)
                        np.greater(w, limit, out=hit)
                        hit &= ok[a0:z0]
                        absurd[a0:z0] |= hit

            _over_rows(n, absurds)
    n_absurd = int(np.count_nonzero(absurd))
    usable = ok & ~absurd if n_absurd else ok
    every = every_ok and not n_absurd
    extremes: tuple[float, float] | None = None
    medians: tuple[float, float, float] | None = None
    midscale_norm = float("nan")
    if usable.any():
        median_norm = med if not n_absurd else median(norm[usable])
        del norm
        with np.errstate(over="ignore", invalid="ignore"):  # values near the float limit
            step = np.zeros(max(0, int(np.count_nonzero(usable)) - 1))
            for a in acc:  # one axis at a time: a log with unusable rows holds one compressed copy at once
                x = a if every else a[usable]

                def steps(lo: int, hi: int, x: NDArray[np.float64] = x) -> None:
                    values = np.empty(min(hi - lo, EVIDENCE_PIECE), dtype=dtype)
                    for a0, z0 in _pieces(hi, lo):
                        w = values[: z0 - a0]
                        np.subtract(x[a0 + 1:z0 + 1], x[a0:z0], out=w)  # np.diff's x[i+1] - x[i]
                        np.multiply(w, w, out=w)
                        step[a0:z0] += w

                _over_rows(step.size, steps)
                del x
            np.sqrt(step, out=step)
        median_step = median(step, overwrite_input=True) if step.size else 0.0
        del step
        if median_norm >= MS2_NORM_RANGE[1]:  # counts are possible: the statistics of their nominal conversion
            extremes, medians, midscale_norm = _counts_statistics(acc if every else [a[usable] for a in acc])
    else:
        median_norm = median_step = float("nan")
    if src.has("t") and np.count_nonzero(usable) > 1:
        t = src.column("t")
        time = time_evidence(t if every else t[usable])
    else:
        time = None
    return Evidence(
        n_rows=n,
        size_bytes=src.size_bytes,
        usable=usable,
        non_finite=n - int(np.count_nonzero(finite)),
        zero_rows=int(np.count_nonzero(zero)),
        absurd=n_absurd,
        median_norm=median_norm,
        median_step=median_step,
        time=time,
        extremes=extremes,
        medians=medians,
        midscale_norm=midscale_norm,
    )


def _counts_statistics(
    acc: list[NDArray[np.float64]],
) -> tuple[tuple[float, float], tuple[float, float, float] | None, float]:
    """The extremes of the usable samples; when they are all in 0..65535 (an unsigned 16-bit converter's
    range), each axis's median and the median norm about mid-scale (else ``None`` and NaN).

    The statistics :func:`optcal.data.units.nominal_conversion` takes from the samples, computed as
    it computes them, to the bit.
    """
    extremes = (min(float(a.min()) for a in acc), max(float(a.max()) for a in acc))
    if not (extremes[0] >= 0 and extremes[1] <= UNSIGNED_16_MAX):
        return extremes, None, float("nan")
    medians = (median(acc[0]), median(acc[1]), median(acc[2]))
    norm = (acc[0] - UNSIGNED_16_MIDSCALE) ** 2
    for a in acc[1:]:
        norm += (a - UNSIGNED_16_MIDSCALE) ** 2
    np.sqrt(norm, out=norm)
    return extremes, medians, median(norm, overwrite_input=True)


def time_evidence(t: NDArray[np.float64]) -> TimeEvidence:
    """Steps, repeats and reversals of a time column (one difference of the column, one median).

    The order-dependent statistics (the first step backwards) are taken before the median
    partitions the steps in place; the rest are counts and a minimum, which do not depend on
    the order, the regular fraction counted piece by piece (:data:`EVIDENCE_PIECE`).
    """
    d = np.diff(t)
    back = np.flatnonzero(d < 0)
    positive = d > 0
    any_positive = bool(positive.any())
    min_positive = float(d.min(where=positive, initial=np.inf)) if any_positive else 0.0
    del positive
    repeated = int(np.count_nonzero(d == 0))
    med = median(d, overwrite_input=True) if d.size else 0.0  # d is a permutation of the steps from here on
    regular = 0.0
    if med > 0:
        near = 0
        flags = np.empty(min(d.size, EVIDENCE_PIECE), dtype=bool)
        values = np.empty(min(d.size, EVIDENCE_PIECE), dtype=d.dtype)
        for a0, z0 in _pieces(d.size):
            w, hit = values[: z0 - a0], flags[: z0 - a0]
            np.subtract(d[a0:z0], med, out=w)
            np.abs(w, out=w)
            np.less_equal(w, 0.5 * med, out=hit)
            near += int(np.count_nonzero(hit))
        regular = near / d.size  # the mean of the flags: a count over the steps
    return TimeEvidence(
        n=int(t.size),
        duration=float(t[-1] - t[0]),
        median_step=med,
        min_positive_step=min_positive,
        repeated=repeated,
        backwards=int(back.size),
        first_backwards=int(back[0] + 1) if back.size else None,
        regular_fraction=regular,
        start=float(t[0]) if t.size else float("nan"),
    )


def _rest_readings(
    names: tuple[tuple[str, str, str], ...], triples: list[tuple[NDArray[np.float64], ...]]
) -> tuple[int, int, tuple[TripleRest, ...]]:
    """Quiet blocks (every triple quiet), all blocks, and how each triple reads over the quiet ones."""
    n = int(triples[0][0].size)
    nb = n // ROLE_BLOCK_SAMPLES
    if nb < MIN_QUIET_BLOCKS:
        return 0, nb, ()
    stats = [_block_statistics(cols, nb) for cols in triples]
    quiet = quiet_blocks(stats, nb)
    if quiet is None:
        return 0, nb, ()
    n_quiet = int(np.count_nonzero(quiet))
    if n_quiet < MIN_QUIET_BLOCKS:
        return n_quiet, nb, ()
    rests = []
    for triple_names, cols, (means, std) in zip(names, triples, stats):
        m = means[quiet]
        noise = max(median(std[quiet]), _resolution(cols) / 2)
        away = np.linalg.norm(m - column_medians(m), axis=1) > MOVED_NOISE_RATIO * noise
        centre, radius = sphere_through(m)
        misfit = float("nan")
        if np.isfinite(radius) and radius > 0:
            misfit = quantiles(np.abs(np.linalg.norm(m - centre, axis=1) - radius) / radius, [0.9])[0]
        rests.append(TripleRest(triple_names, noise, float(np.mean(away)), radius, misfit))
    return n_quiet, nb, tuple(rests)


def quiet_blocks(stats: list[tuple[NDArray[np.float64], NDArray[np.float64]]], nb: int) -> NDArray[np.bool_] | None:
    """The blocks quiet on every triple (``stats``: each triple's :func:`_block_statistics`): finite, with a
    per-sample noise within :data:`QUIET_FACTOR` of its floor (the :data:`NOISE_FLOOR_QUANTILE` of the finite
    blocks'); ``None`` when a triple has no finite block."""
    quiet = np.ones(nb, dtype=bool)
    for means, std in stats:
        finite = np.isfinite(std) & np.all(np.isfinite(means), axis=1)
        quiet &= finite
        if not finite.any():
            return None
        floor = quantiles(std[finite], [NOISE_FLOOR_QUANTILE])[0]
        quiet &= std <= QUIET_FACTOR * floor
    return quiet


def _block_statistics(cols: tuple[NDArray[np.float64], ...], nb: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Means (nb, 3) and per-sample standard deviations pooled over the axes (nb,) of consecutive blocks."""
    w = ROLE_BLOCK_SAMPLES
    means = np.empty((nb, 3))
    var = np.zeros(nb)
    for j, col in enumerate(cols):
        x = col[: nb * w].reshape(nb, w)
        means[:, j] = x.mean(axis=1)
        var += x.var(axis=1)
    return means, np.sqrt(var / 3.0)


def _resolution(cols: tuple[NDArray[np.float64], ...]) -> float:
    """1 for integer-valued samples (counts: a noise below one count reads as a step of one), else 0."""
    head = np.concatenate([c[: 64 * ROLE_BLOCK_SAMPLES] for c in cols])
    head = head[np.isfinite(head)]
    return 1.0 if head.size and bool(np.all(head == np.round(head))) else 0.0
