"""The rest model applied to one recording: its blocks, the noise measured on them, and the tests of each still stretch.

:mod:`optcal.data.rest_model` states the statistics and their distributions; :class:`RestModel` measures the
noise colour, the gyro's bias and wander on a recording (two passes: the second inside the rests the first
found), and judges each still stretch (:meth:`RestModel.peel`, :meth:`~RestModel.creeps`,
:meth:`~RestModel.turns`, ...).  :func:`optcal.data.static.detect_static` turns its verdicts into poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.core.stats import column_ptp, row_max_abs, row_norms
from optcal.core.units import RAD_PER_UNIT
from optcal.data import bias_model as bm
from optcal.data import rest_model as rm
from optcal.data.quantiles import column_mad_sigmas, column_medians, grouped_column_medians, median, np_column_medians, np_median, quantiles
from optcal.data.recording import Recording
from optcal.data.rest_model import MAX_BIAS_DRIFT_RAD_S2, MAX_BIAS_WANDER_RAD_S, NOISE_FLOOR_G, SAME_POSE_SAMPLE_SIGMAS, WOBBLE_DWELLS, WOBBLE_SHRINK
from optcal.data.rest_bounds import RestBounds, rest_bounds
from optcal.data.rest_model import MAX_GYRO_BIAS_RAD_S
from optcal.data.static_stretches import ScaleEvidence, decide_gyro_scale, gyro_rad_per_unit, scale_from_moves, true_runs
from optcal.data.units import nominal_conversion
from optcal.data.quantisation import quantum

if TYPE_CHECKING:
    from optcal.data.static import StaticSettings


def unit_rows(f: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each row of ``f`` (k, 3) (or ``f`` itself, (3,)) over its norm: a specific force's direction."""
    if f.ndim != 2:
        return np.asarray(f / np.maximum(np.linalg.norm(f, axis=-1, keepdims=True), np.finfo(float).tiny))
    norm = np.maximum(row_norms(f), np.finfo(float).tiny)
    out = np.empty(f.shape)
    for j in range(f.shape[1]):  # column by column (core.stats.row_norms): the same values
        np.divide(f[:, j], norm, out=out[:, j])
    return out


#: Standard errors (rms over the axes) within which the accelerometer's rate of change over a stretch agrees with
#: the turn its gyro predicts (:meth:`RestModel._turns_by_both`): a turn's prediction is off by the gyro's bias
#: error too, so agreement is looser than the test of the accelerometer's own motion.
TURN_AGREEMENT_SE: float = 3.0
#: The most radians per second one count of a gyro can be worth: a 16-bit converter over the largest full scale a
#: MEMS gyro has, ±4000 °/s (the common parts stop at ±2000 °/s).  Bounds the turn a significant offset off the bias
#: can be where the unit is unknown and the samples are counts (:meth:`RestModel._relevant_at_most`).
MAX_RAD_S_PER_COUNT: float = float(np.radians(4000.0) / 32768.0)
#: Rest noise (per-sample standard deviation of the median block, on the quietest axis) in converter steps at and
#: above which whole-number gyro samples are counts: a gyro printed in whole °/s or rad/s rests within a unit of its
#: bias (a MEMS gyro's noise is 0.05 °/s/√Hz at most: under 1 °/s rms below 800 Hz), its blocks spread under a step.
COUNTS_MIN_REST_STEPS: float = 1.0


@dataclass(frozen=True)
class Verdicts:
    """The tests of still stretches (:meth:`RestModel.judge`), one entry per stretch.

    Attributes
    ----------
    per_sample : ndarray
        Per-sample standard deviation about the stretch's mean (norm over the axes).
    creeps, turns : ndarray of bool
        The accelerometer's mean moves; the gyro's mean rate is off the bias (a slow turn).
    cannot_rest : ndarray of bool
        Its mean is no rest's (:class:`~optcal.data.rest_bounds.RestBounds`: its |a| is not gravity's).
    independent, independent_gyro : ndarray
        Independent samples of the accelerometer and of the gyro (infinite where it is no evidence).
    """

    per_sample: NDArray[np.float64]
    creeps: NDArray[np.bool_]
    turns: NDArray[np.bool_]
    independent: NDArray[np.float64]
    independent_gyro: NDArray[np.float64]
    cannot_rest: NDArray[np.bool_]


class RestModel:
    """The blocks of one recording and the tests of :mod:`optcal.data.rest_model` on them, measured in two passes."""

    def __init__(self, rec: Recording, s: StaticSettings, t: NDArray[np.float64], acc: NDArray[np.float64],
                 gyro: NDArray[np.float64] | None, block: int, breaks: NDArray[np.int64], rate: float) -> None:
        self.s = s
        self.rate = rate
        qa = quantum(acc) or 0.0
        qg = (quantum(gyro) or 0.0) if gyro is not None else 0.0
        self.block = block
        self.b = b = rm.make_blocks(t, acc, gyro, block, breaks, qa, qg)
        self.half_width = max(1, int(np.ceil(s.min_dwell_s * rate / (2.0 * block))))
        self.dwell_blocks = max(1, int(np.ceil(s.min_dwell_s * rate / block)))
        b.var_ref = rm.local_noise(b.var, self.half_width)
        self.valid = b.joined[1:]
        self.dof = b.n[1:] + b.n[:-1] - 2.0
        self.floor = rm.rounding_floor(b.var, qa)
        self.gfloor = rm.rounding_floor(b.gvar, qg) if b.gvar is not None else np.zeros(3)
        self.ratios = rm.pair_ratios(b.mean, b.var_ref, b.n, self.floor)
        self.dof0 = dof0 = float(np_median(self.dof)) if self.dof.size else 1.0
        # Noise colour, first from the pairs of the quietest quarter of the blocks (a motion adds to a block's
        # spread, so the quietest blocks are at rest, or the slowest moments of a recording that never rests)
        calm = rm.calm_pairs(b.var, self.valid)
        if calm.sum() >= rm.MIN_COLOUR_PAIRS:
            self.kappa2 = rm.noise_colour(self.ratios[calm], dof0, 0.5)
        else:
            self.kappa2 = rm.noise_colour(self.ratios[self.valid], dof0, rm.QUIET_PAIRS_QUANTILE)
        with np.errstate(over="ignore"):  # a huge --static-threshold: an infinite limit
            self.step_limit = rm.step_limit(s.false_alarm, self.dof) * s.threshold
        self.bias: NDArray[np.float64] | None = None  # the gyro's bias over the session (median of its track)
        self.track = np.zeros((b.count, 3))  # the gyro's bias at each block (rm.bias_track)
        self.gyro_scale: float | None = None  # rad/s per gyro unit, once the bias is known
        self.gyro_units = rec.gyro_units
        nominal = rec.nominal if rec.nominal is not None else nominal_conversion(rec.units, acc)
        self.one_g = float(nominal.sensitivity)
        self.acc_zero = np.asarray(nominal.offset, dtype=float)
        self.bounds: RestBounds = rest_bounds(rec, gyro, b.gmean, s.keep_spins)
        self.can_rest = ~self._over_a_dwell(~self.bounds.admits(b.mean - self.acc_zero, b.gmean))  # a rest's readings
        self.units = rec.units
        self.rest_base = self.can_rest.copy()  # the still blocks a rest's bias is measured on (_pass)
        self.rest_base_how = ""  # how the first pass's rest_base was narrowed (_refine_rest_base)
        self.bias_model: bm.BiasModel | None = None
        self.gkappa2 = np.ones(3)
        self.gvar_ref: NDArray[np.float64] | None = None
        self.wander2 = np.zeros(3)
        with np.errstate(over="ignore"):  # a huge --gyro-threshold: the limit is infinite, every rate is noise
            self.gyro_limit = rm.step_limit(s.false_alarm, b.n - 1.0) * s.gyro_threshold
        self.gyro_quantum = qg
        self.still = np.ones(b.count, dtype=bool)
        self._pooled: dict[tuple[bool, int, int], NDArray[np.float64]] = {}
        self._spans: rm.SpanEstimates | None = None
        self._pass(first=True)
        self.t, self.gyro = t, gyro
        self.scale_evidence = self._scale_from_moves()
        self.gyro_scale, self.gyro_unit_reason = decide_gyro_scale(rec, self.scale_evidence,
                                                                   gyro_rad_per_unit(rec, gyro, self.bias, self.b))
        refined = self._refine_rest_base(rec)
        if gyro is None:
            self.gyro_unit_reason = ""
        elif (self.gyro_scale is not None and rec.gyro_units not in RAD_PER_UNIT) or refined:
            # again, with the scale measured: the bias track's drift limit (and the rests' bias, where the decided
            # scale sets aside more of the still blocks as no rest's: RestBounds)
            self._pass(first=True, again=True)
        # Second pass: the noise colour and the gyro bias' wander measured inside the rests the first pass found
        inside = self._pairs_inside(self.runs())
        if inside.sum() >= 8:
            self.kappa2 = rm.noise_colour(self.ratios[inside], dof0, 0.5)
        self._pass(first=False)

    def _pass(self, first: bool, again: bool = False) -> None:
        """One pass of the tests over the blocks; ``again``: the first pass repeated once the gyro's scale is
        measured, which changes only the bias track (its drift limit) and what follows from it: the accelerometer's
        tests and the gyro's noise colour, which do not depend on the scale, are kept from the first."""
        b = self.b
        if not again:
            self.step = rm.step_statistic(self.ratios, self.kappa2)
            if first:
                self.var_steps = rm.log_variance_steps(b.var)
                self.var_limit = rm.variance_step_limit(self.var_steps[self.valid], self.s.false_alarm,
                                                       float(np_median(b.n))) * self.s.threshold
            self.quiet = self.valid & (self.step <= self.step_limit) & (self.var_steps <= self.var_limit)
        if b.gmean is None or b.gvar is None:
            return
        acc_still = self._acc_still()
        base = acc_still if acc_still.sum() >= 3 else np.ones(b.count, dtype=bool)
        if (base & self.rest_base).sum() >= 3:  # the bias of a rest, not of a steady spin (RestBounds)
            base = base & self.rest_base
        if first:
            if self._spans is None:  # the spans' estimates are the same whatever the drift limit: measured once
                self._spans = rm.span_estimates(b.t_mid[base], b.gmean[base], step=rm.BIAS_SPAN_S / 2.0)
            self.track = rm.follow_spans(self._spans, b.t_mid, self._max_drift())
            self.bias = np_column_medians(self.track)
            if not again:
                self.gvar_ref = rm.local_noise(b.gvar, self.half_width)
                gratios = rm.pair_ratios(b.gmean, self.gvar_ref, b.n, self.gfloor)
                pairs = self.quiet if self.quiet.sum() >= 8 else self.valid
                self.gkappa2 = rm.noise_colour(gratios[pairs], self.dof0, rm.QUIET_PAIRS_QUANTILE)
        else:
            self._measure_wander()
        assert self.bias is not None and self.gvar_ref is not None
        self.gstat = rm.gyro_statistic(b.gmean, self.gvar_ref, b.n, self.track, self.gkappa2, self.wander2, self.gfloor)
        self.still = self.gstat <= self.gyro_limit
        scale = self._scale()
        if scale is not None and not first:
            # significant, but turning the sensor through less than a pose tolerates over the time a rest is judged
            # on (WOBBLE_DWELLS dwells, as the stretches' own test): a real gyro's bias, not a move (not in the first
            # pass, whose rests measure the bias: a smooth move's slow ends are not rests of the bias)
            rate = row_norms(b.gmean - self.track) * scale
            # within a real gyro's reach of its bias (g-sensitivity's largest term at 1 g), only the turn across the
            # specific force moves a pose: about it, a(t) stays as it is (a yaw creep, or G f along f)
            across = row_norms(np.cross(b.gmean - self.track, unit_rows(b.mean - self.acc_zero))) * scale
            rate = np.where(rate <= bm.MAX_G_SENSITIVITY_RAD_S_PER_G, across, rate)
            self.still |= ~rm.turn_is_relevant(rate, WOBBLE_DWELLS * self.s.min_dwell_s, self.s.gyro_threshold)

    def _over_a_dwell(self, bad: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """The blocks of ``bad`` in runs of consecutive blocks lasting :data:`~optcal.data.rest_model.WOBBLE_DWELLS`
        dwells or more (the time a rest is judged on): a steady spin, which holds the accelerometer still as long as a
        rest and fills the spans the gyro's bias is the mode of; a shorter run (a hand's pan about gravity, which the
        accelerometer does not see) is a move the mode of the still blocks passes over, as before."""
        out = np.zeros_like(bad)
        for a, z in zip(*true_runs(bad)):
            if z - a >= max(WOBBLE_DWELLS * self.dwell_blocks, 2):
                out[a:z] = True
        return out

    def _refine_rest_base(self, rec: Recording) -> bool:
        """Once the gyro's scale is decided (measured on the moves, or the convention of the accelerometer's unit), the
        still blocks a rest's bias is measured on, narrowed to the bias bound in that scale where the first pass's
        was in the most units the gyro can be in (:class:`~optcal.data.rest_bounds.RestBounds`; 75 °/s is 75 units
        when the unit is unknown, 1.3 in rad/s).  Whether that set aside more blocks (the spans are then measured
        again); not where fewer than three blocks would be left (a scale that makes every rest a spin is the scale's
        error, not the rests')."""
        b = self.b
        if (self.bounds.gyro_zero is None or b.gmean is None or self.gyro_scale is None
                or rec.gyro_units in RAD_PER_UNIT):
            return False
        still = self._acc_still() & self.can_rest
        limit = MAX_GYRO_BIAS_RAD_S / self.gyro_scale
        base = still & ~self._over_a_dwell(still & (row_max_abs(b.gmean, self.bounds.gyro_zero) > limit))
        if base.sum() < 3 or not np.any(still & ~base):
            return False
        self.rest_base, self._spans = self.can_rest & (base | ~still), None
        self.rest_base_how = (f"over {limit:.4g} from its zero on an axis ({np.degrees(MAX_GYRO_BIAS_RAD_S):g} °/s in "
                              f"the gyro's scale as decided: {self.gyro_unit_reason.split(':')[0]})")
        return True

    def _scale_from_moves(self) -> ScaleEvidence | None:
        """The gyro's scale measured across the moves between the first pass's rests (:func:`scale_from_moves`)."""
        b = self.b
        if self.gyro is None or self.bias is None:
            return None
        runs = self.runs()
        pairs = [(end, start) for (_, end), (start, _) in zip(runs[:-1], runs[1:])
                 if bool(b.joined[end:start + 1].all())]  # else a time gap: nothing is known of the move
        if not pairs:
            return None
        ends, starts = np.array(pairs, dtype=np.intp).T
        spans = [(int(b.start[e - 1]), int(b.stop[s])) for e, s in pairs]
        # gravity's direction over the last two blocks before each move and the first two after it
        before = unit_rows(0.5 * (b.mean[np.maximum(ends - 2, 0)] + b.mean[ends - 1]) - self.acc_zero)
        after = unit_rows(0.5 * (b.mean[starts] + b.mean[np.minimum(starts + 1, b.count - 1)]) - self.acc_zero)
        return scale_from_moves(self.t, self.gyro, self.bias, spans, before, after)

    def _scale(self) -> float | None:
        """Radians per second per gyro unit: measured (:func:`gyro_rad_per_unit`), or stated; None while unknown."""
        return self.gyro_scale if self.gyro_scale is not None else RAD_PER_UNIT.get(self.gyro_units or "")

    def _max_drift(self) -> float | None:
        """The fastest a MEMS gyro's bias moves, in the gyro's units per second (None while its unit is unknown)."""
        scale = self._scale()
        return None if scale is None else MAX_BIAS_DRIFT_RAD_S2 / scale

    def directions(self, rows: NDArray[np.intp] | slice = slice(None)) -> NDArray[np.float64]:
        """The specific force's unit direction of blocks ``rows`` by the nominal conversion (k, 3)."""
        return unit_rows(self.b.mean[rows] - self.acc_zero)

    def _bias_rests(self) -> list[tuple[int, int]]:
        """The stretches the gyro's bias is measured on: runs of blocks the accelerometer calls still (a real gyro's
        bias differs from rest to rest, so the gyro cannot yet say which are rests) whose mean rate is within a MEMS
        gyro's bias range of the first bias (:data:`MAX_BIAS_WANDER_RAD_S`, where the gyro's unit is known: a turn
        about gravity, which the accelerometer does not see, is faster)."""
        b = self.b
        assert self.bias is not None and b.gmean is not None
        limit = MAX_BIAS_WANDER_RAD_S / self.gyro_scale if self.gyro_scale is not None else np.inf
        near = (row_norms(b.gmean - self.bias) <= limit) & self.can_rest
        starts, stops = true_runs(self.quiet & near[1:] & near[:-1])
        return [(int(a), int(z) + 1) for a, z in zip(starts, stops)]

    def _measure_wander(self) -> None:
        """The gyro's bias as a real gyro's (:func:`~optcal.data.rest_model.fit_bias_model`: a bias, its
        g-sensitivity and its steps after knocks, fitted to the rests' mean rates; a thermal drift followed by the
        track of what is left), and the wander between rests: the scatter of the rests' mean rates about it beyond
        their noise."""
        b = self.b
        assert self.bias is not None and b.gmean is not None and b.gvar is not None
        if self._scale() is None:
            # a gyro whose scale nothing states or measures: a real gyro's bias has no stated bounds in its units (its
            # g-sensitivity, its steps, its range), and a turn about gravity cannot be told from it
            return self._measure_wander_plain()
        # the pieces of one stretch the accelerometer calls still (parted by blocks off the bias: a turn about
        # gravity, a twitch) are one rest: a bias steps in a move, and the rests a step needs are distinct
        groups: list[list[tuple[int, int]]] = []
        previous = -1
        loud = np.r_[0, np.cumsum(~self.quiet)]  # non-quiet pairs before each pair: a range's count by a difference
        for k0, k1 in self._bias_rests():
            if groups and loud[max(k0, previous)] == loud[previous]:
                groups[-1].append((k0, k1))
            else:
                groups.append([(k0, k1)])
            previous = k1 - 1
        # each group's weighted means, by sums over its rows (the groups' rows in order, concatenated)
        pieces = [np.concatenate([np.arange(k0, k1) for k0, k1 in group]) for group in groups]
        sizes = np.array([p.size for p in pieces], dtype=np.intp)
        pieces = [p for p in pieces if p.size >= rm.TREND_MIN_BATCHES]  # shorter: a piece of a slow turn, unchecked
        if len(pieces) < bm.MIN_RESTS_G_SENSITIVITY:
            return self._measure_wander_plain()
        sizes = sizes[sizes >= rm.TREND_MIN_BATCHES]
        rows_all = np.concatenate(pieces)
        offsets = np.r_[0, np.cumsum(sizes)[:-1]]
        w = b.n[rows_all, None]
        n_all = np.add.reduceat(w, offsets, axis=0)
        group_rates = np.add.reduceat(b.gmean[rows_all] * w, offsets, axis=0) / n_all
        group_acc = np.add.reduceat(b.mean[rows_all] * w, offsets, axis=0) / n_all
        first, last = rows_all[offsets], rows_all[offsets + sizes - 1]
        keep = ~self._turns_by_both(pieces, group_rates, group_acc, first, last)
        if keep.sum() < bm.MIN_RESTS_G_SENSITIVITY:
            return self._measure_wander_plain()
        noise2 = self.gkappa2 * grouped_column_medians(b.gvar[rows_all], sizes)[keep] / n_all[keep]
        at = 0.5 * (b.t_mid[first] + b.t_mid[last])[keep]
        rest_means = group_rates[keep]
        direction = unit_rows(group_acc[keep] - self.acc_zero)
        scale = self._scale()
        assert scale is not None  # a gyro without a scale took the ideal gyro's bias above
        self.bias_model = model = bm.fit_bias_model(at, direction, rest_means, noise2,
                                                    bm.MAX_G_SENSITIVITY_RAD_S_PER_G / scale)
        modelled = model.at(at, direction)
        # what the model leaves (a thermal drift) followed over the session, each span's median
        # (on spans a whole span apart: a package warms over minutes)
        drift = rm.follow_spans(rm.span_estimates(at, rest_means - modelled, column_medians, rm.BIAS_SPAN_S),
                                b.t_mid, self._max_drift())
        self.track = model.at(b.t_mid, self.directions()) + drift
        self.bias = np_column_medians(rest_means)
        # about the model and its drift at each rest: the bias wanders about them (a random walk) by as much as the
        # rests' means scatter; a scatter beyond any MEMS gyro's bias change is of false rests
        dev = rest_means - modelled - np.column_stack([np.interp(at, b.t_mid, drift[:, j]) for j in range(3)])
        robust2 = column_mad_sigmas(dev) ** 2
        self.wander2 = np.minimum(np.maximum(robust2 - np_column_medians(noise2), 0.0), (MAX_BIAS_WANDER_RAD_S / scale) ** 2)

    def _acc_slope(self, rows: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The accelerometer's rate of change over the blocks ``rows``: the slope of their means on time (least
        squares, per axis) and its standard error from the blocks' noise times the noise colour (and the rounding
        floor); ``None`` when the blocks span no time."""
        b = self.b
        t = b.t_mid[rows] - b.t_mid[rows].mean()
        sxx = float(np.sum(t * t))
        if sxx <= 0:
            return None
        slope = (t[:, None] * (b.mean[rows] - b.mean[rows].mean(axis=0))).sum(axis=0) / sxx
        se = np.sqrt(self.kappa2 * (column_medians(b.var[rows]) / float(np_median(b.n[rows])) + self.floor) / sxx)
        return slope, se

    def _turns_by_both(self, pieces: list[NDArray[np.intp]], rates: NDArray[np.float64], acc: NDArray[np.float64],
                       first: NDArray[np.intp], last: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Whether each stretch the accelerometer calls still (blocks ``pieces[i]``, their weighted mean ``rates`` and
        specific force ``acc``, first and last blocks) turns by both sensors' evidence.

        A turn not about gravity moves the accelerometer: at ``ω`` (the gyro's rate less the bias) its specific
        force ``a`` changes at ``ȧ = −ω × a``.  The accelerometer's own rate of change over the stretch (the slope of
        its block means on time, least squares, with its standard error from the blocks' noise times the noise
        colour) is set against it: when it is off zero by more than :data:`TURN_AGREEMENT_SE` standard errors and
        within as many of the gyro's prediction, both sensors see the same turn, and the stretch says nothing of
        the bias.  A stretch whose accelerometer does not move while its gyro says it should is a rest whose bias
        differs (g-sensitivity, a step after a knock).  Without the gyro's unit: no; nor where the gyro's rate turns the sensor through less than a pose's tolerance over the stretch (its rest
        tells the bias), which needs no slope.
        """
        b = self.b
        scale = self._scale()
        out = np.zeros(len(pieces), dtype=bool)
        if scale is None or b.gmean is None or self.bias is None:
            return out
        omega = (rates - self.bias) * scale
        duration = b.t_mid[last] - b.t_mid[first] + b.n[last] / self.rate
        tiny = np.finfo(float).tiny
        relevant = rm.turn_is_relevant(np.linalg.norm(omega, axis=1), duration, 1.0)
        for i in np.flatnonzero(relevant):
            moved = self._acc_slope(pieces[i])
            if moved is None:
                continue
            slope, se = moved
            predicted = -np.cross(omega[i], acc[i] - self.acc_zero)
            moves = float(np.sum(slope * slope / np.maximum(se * se, tiny))) > rm.chi2_limit(self.s.false_alarm, 3)
            d = slope - predicted
            out[i] = moves and float(np.sum(d * d / np.maximum(se * se, tiny))) <= TURN_AGREEMENT_SE**2 * 3.0
        return out

    def _measure_wander_plain(self) -> None:
        """The bias and its wander where too few rests say how a real gyro's bias differs between them
        (:data:`~optcal.data.rest_model.MIN_RESTS_G_SENSITIVITY`): the first rests' mean rates, their median over
        each span, and their scatter about the session's median beyond their noise."""
        b = self.b
        assert self.bias is not None and b.gmean is not None and b.gvar is not None
        means, noise2, mids = [], [], []
        for k0, k1 in self.runs():
            n = b.n[k0:k1].sum()
            means.append((b.gmean[k0:k1] * b.n[k0:k1, None]).sum(axis=0) / n)
            noise2.append(self.gkappa2 * column_medians(b.gvar[k0:k1]) / n)
            mids.append(0.5 * (b.t_mid[k0] + b.t_mid[k1 - 1]))
        if means:
            # the bias re-estimated from the rests themselves (the half-sample mode of all still blocks is a start:
            # its own error, integrated over a long rest, would look like a turn), their median over each span
            at = np.asarray(mids)
            rest_means = np.asarray(means)
            self.track = rm.bias_track(at, rest_means, b.t_mid, self._max_drift(), estimate=column_medians)
            self.bias = np_column_medians(rest_means)
        if len(means) >= 3:
            # about the session's median, not the track: the track is a span's median, and the bias wanders about
            # it within a span (a random walk) by as much as the rests' means scatter over the session
            dev = rest_means - self.bias
            robust2 = (1.4826 * np_column_medians(np.abs(dev))) ** 2
            self.wander2 = np.maximum(robust2 - np_column_medians(noise2), 0.0)
            if self.gyro_scale is not None:  # a scatter beyond any MEMS gyro's bias change is of false rests
                self.wander2 = np.minimum(self.wander2, (MAX_BIAS_WANDER_RAD_S / self.gyro_scale) ** 2)

    def _acc_still(self) -> NDArray[np.bool_]:
        """Blocks the accelerometer calls still: a quiet pair on either side."""
        acc_still = np.zeros(self.b.count, dtype=bool)
        acc_still[1:] |= self.quiet
        acc_still[:-1] |= self.quiet
        return acc_still

    def turning_blocks(self) -> int:
        """Blocks the accelerometer calls still whose gyro mean is off the bias."""
        return int(np.sum(self._acc_still() & ~self.still))

    def runs(self) -> list[tuple[int, int]]:
        """Block ranges ``[k0, k1)`` of two or more still blocks joined by quiet pairs."""
        # a link needs both its blocks still, so every block of a run of links is; a lone block between two
        # steps is in no run: it moves
        starts, stops = true_runs(self.quiet & self.still[1:] & self.still[:-1])
        return [(int(a), int(z) + 1) for a, z in zip(starts, stops)]

    def _pairs_inside(self, runs: list[tuple[int, int]]) -> NDArray[np.bool_]:
        inside = np.zeros(self.valid.size, dtype=bool)
        for k0, k1 in runs:
            inside[k0:k1 - 1] = True
        return inside & self.valid

    def split_by_noise(self, runs: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Cut out of each run the blocks far noisier than the run's quieter quarter: a rest has one noise level.

        A smooth motion (all of a low-pass filtered recording's motion) changes the block means and the
        block variances gradually, so that no pair of consecutive blocks tells it from the noise; its
        blocks are still many times noisier than the rest around them.  The critical value is the
        variance-step test's (:func:`optcal.data.rest_model.variance_step_limit`).
        """
        b = self.b
        out: list[tuple[int, int]] = []
        total = np.maximum(b.var.sum(axis=1), np.finfo(float).tiny)
        for k0, k1 in runs:
            # the quieter blocks of the run and of a dwell on either side: a short stretch of a move's tail is
            # measured against the rest it settles into
            w = self.dwell_blocks
            level = quantiles(total[max(0, k0 - w):min(b.count, k1 + w)], [rm.QUIET_PAIRS_QUANTILE])[0]
            calm = np.log(total[k0:k1] / level) <= self.var_limit
            starts, stops = true_runs(calm)
            out.extend((k0 + int(a), k0 + int(z)) for a, z in zip(starts, stops))
        return out

    def peel(self, k0: int, k1: int) -> tuple[int, int]:
        """Drop the run's end blocks while their mean differs from the rest of the run's (a settling tail)."""
        b = self.b
        while k1 - k0 >= 3:
            changed = False
            for end in (k0, k1 - 1):
                # against the blocks next to it: a rest's mean may wander (flicker) over its length
                others = slice(k0 + 1, min(k1, k0 + 1 + self.half_width)) if end == k0 else slice(max(k0, k1 - 1 - self.half_width), k1 - 1)
                n_rest = float(b.n[others].sum())
                rest_mean = (b.mean[others] * b.n[others, None]).sum(axis=0) / n_rest
                stat = rm.mean_shift_statistic(b.mean[end], b.var_ref[end], float(b.n[end]), rest_mean, self.kappa2, n_rest,
                                               self.floor)
                if stat > rm.step_limit_one(self.s.false_alarm, b.n[end] - 1.0) * self.s.threshold:
                    if end == k0:
                        k0 += 1
                    else:
                        k1 -= 1
                    changed = True
                    break
            if not changed:
                break
        return k0, k1

    def spread(self, k0: int, k1: int) -> float:
        """Per-sample standard deviation of the stretch about its mean (norm over the axes; the spread of its
        block means included, so that a stretch that moves is as loud as its motion)."""
        return float(np.sqrt(self.pooled_variance(k0, k1).sum()))

    def _moments(self, gyro: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The block means and variances of the accelerometer, or of the gyro."""
        b = self.b
        if not gyro:
            return b.mean, b.var
        assert b.gmean is not None and b.gvar is not None
        return b.gmean, b.gvar

    def pooled_variance(self, k0: int, k1: int, gyro: bool = False) -> NDArray[np.float64]:
        """Per-axis variance of the samples of blocks ``[k0, k1)`` about their common mean (:meth:`_pooled_variances`);
        computed once per stretch (several tests ask)."""
        key = (gyro, k0, k1)
        if key not in self._pooled:
            self._pooled[key] = self._pooled_variances(rm.Ranges.of([k0], [k1]), gyro)[0]
        return self._pooled[key]

    def _pooled_variances(self, r: rm.Ranges, gyro: bool) -> NDArray[np.float64]:
        """Per range of blocks and axis, the variance of the samples about their common mean (the blocks' own
        variances and the spread of their means, pooled) (P, 3)."""
        means, var = self._moments(gyro)
        w = self.b.n[r.rows]
        n = r.sums(w)
        out = np.empty((r.count, means.shape[1]))
        for j in range(means.shape[1]):  # column by column: :func:`~optcal.data.rest_model.pair_ratios`
            m = means[r.rows, j]
            dev = m - (r.sums(m * w) / n)[r.owner]
            out[:, j] = (r.sums(var[r.rows, j] * (w - 1.0)) + r.sums(w * dev * dev)) / (n - 1.0)
        return out

    def _independent(self, r: rm.Ranges, gyro: bool, samples: NDArray[np.float64]) -> NDArray[np.float64]:
        """Samples over the noise colour: each stretch's per-sample variance over the variance of its mean.

        A stretch of :data:`~optcal.data.rest_model.TREND_BATCHES` blocks or more measures the variance of its
        mean itself, from its block means as a first-order autoregression (their variance over their number,
        times ``(1 + ρ) / (1 − ρ)`` for their lag-one correlation ρ): its own noise, whatever its colour, so
        neither a filter's smoothing, which the pairs of blocks overstate (a block smoother than the noise
        between blocks), nor a sway correlated over several blocks is misread.  A shorter one takes the
        recording's colour ``κ²`` (a block's ``κ²`` samples carry the information of one).  The median over
        the axes.  ``samples``: each stretch's samples; infinite for the gyro where it is no evidence of motion.
        """
        if gyro and (self.bias is None or self.b.gmean is None):
            return np.full(r.count, np.inf)
        kappa2 = self.gkappa2 if gyro else self.kappa2
        short = samples / max(float(np.sort(kappa2)[1]), 1.0)  # the median of the three axes
        k = r.length.astype(float)
        if not np.any(k >= rm.TREND_BATCHES):
            return short
        per_sample = self._pooled_variances(r, gyro)
        means = self._moments(gyro)[0][r.rows]
        d = means - (r.sums(means) / k[:, None])[r.owner]
        scatter = r.sums(d * d)
        lagged = np.zeros_like(d)
        lagged[1:] = d[1:] * d[:-1]
        lagged[r.offset] = 0.0  # a stretch's first block has no predecessor in it
        tiny = np.finfo(float).tiny
        with np.errstate(divide="ignore", invalid="ignore"):  # the short stretches, whose values are not used
            rho = np.clip(r.sums(lagged) / np.maximum(scatter, tiny), 0.0, (1.0 - 1.0 / k)[:, None])
            var_mean = scatter / (k - 1.0)[:, None] / k[:, None] * (1.0 + rho) / (1.0 - rho)
            ratio = np.sort(per_sample / np.maximum(var_mean, tiny), axis=1)[:, 1]  # the median of the three axes
        n = r.sums(self.b.n[r.rows])
        return np.where(k >= rm.TREND_BATCHES, np.minimum(ratio, n), short)

    def judge(self, pieces: list[tuple[int, int, int, int]]) -> Verdicts:
        """The tests of each still stretch ``(a, z, k0, k1)`` (samples ``[a, z)``, blocks ``[k0, k1)``), all at once."""
        r = rm.Ranges.of([p[2] for p in pieces], [p[3] for p in pieces])
        samples = np.array([p[1] - p[0] for p in pieces], dtype=float)
        pooled = self._pooled_variances(r, False)
        for (_, _, k0, k1), v in zip(pieces, pooled):
            self._pooled[(False, k0, k1)] = v
        per_sample = np.sqrt(pooled.sum(axis=1))
        n = r.sums(self.b.n[r.rows, None])
        acc = r.sums(self.b.mean[r.rows] * self.b.n[r.rows, None]) / n - self.acc_zero
        # |a| only: a gyro beyond the bound everywhere is a unit's or a zero's error, which the bias absorbs
        return Verdicts(per_sample, self._creeps(r, per_sample), self._turns(r),
                        self._independent(r, False, samples), self._independent(r, True, samples),
                        ~self.bounds.admits(acc, None))

    def set_aside(self) -> str:
        """The still blocks the bounds of a rest set aside from the gyro's bias
        (:class:`~optcal.data.rest_bounds.RestBounds`), in words (empty when none)."""
        still = self._acc_still()
        n = int(np.count_nonzero(still & ~self.can_rest))
        far = int(np.count_nonzero(still & self.can_rest & ~self.rest_base))
        if not n and not far:
            return ""
        out = f"of {int(np.count_nonzero(still))} blocks still for the accelerometer, set aside from the gyro's bias"
        if n:
            out += f": {n} no rest's over {WOBBLE_DWELLS:g} dwells by {self.bounds.describe(self.units)}"
        if far:
            out += f"; {far} whose gyro mean is {self.rest_base_how}"
        return out + " (a steady spin); --keep-spins keeps them"

    def trim_outlying_samples(self, acc: NDArray[np.float64], a: int, z: int, j0: int, j1: int) -> tuple[int, int]:
        """Trim single samples off the ends of a rest while they lie outside its noise.

        A block edge falls anywhere: the first or last block of a rest may hold a few samples of the jump or
        move next to it (a logger that stores only holds, a block that straddles the start of a move).  A sample
        whose χ²₃ distance from the rest's mean, in its per-sample noise (the median block variance), is beyond
        the ``1 - false_alarm`` quantile is not of the rest; trimming stops at the first one within.
        """
        b = self.b
        w = b.n[j0:j1, None]
        mean = (b.mean[j0:j1] * w).sum(axis=0) / w.sum()
        # at least the rounding of the data's own scale: a noise-free rest has no sample outside it
        floor = (64.0 * np.finfo(float).eps * float(np.max(np.abs(mean)))) ** 2
        var = np.maximum(column_medians(b.var[j0:j1]), max(floor, np.finfo(float).tiny))
        limit = rm.chi2_limit(self.s.false_alarm, 3) * self.s.threshold

        def leading_outside(rows: NDArray[np.float64]) -> int:
            """How many of ``rows``, from the first, lie outside the noise (up to the first within)."""
            d = rows - mean
            inside = (d * d / var).sum(axis=1) <= limit
            return int(np.argmax(inside)) if inside.any() else rows.shape[0]

        edge = max(1, int(b.n[j0]))  # at most one block's worth from each end
        start = a + leading_outside(acc[a:max(a, min(a + edge, z - 2))])
        stop = z - leading_outside(acc[max(z - edge, start + 2):z][::-1])
        return start, stop

    def drop_odd_noise(self, kept: list[tuple[int, int, int, int]]
                       ) -> tuple[list[tuple[int, int, int, int]], list[tuple[int, int, int, int]]]:
        """Drop the still stretches whose noise is far above the recording's rests' (a move's settling oscillation):
        the stretches kept, and those dropped.

        A rest's noise differs from rest to rest, but not beyond what the recording's own blocks show: a
        stretch whose block variance (median over its blocks, summed over the axes) exceeds the duration-weighted
        median of the rests' by more than twice the variance-step test's critical value (in log variance: the
        largest change between two blocks of one rest, once for the rest and once for the other) oscillates
        inside its blocks, which block means cannot see.
        """
        b = self.b
        if len(kept) < 3:
            return kept, []
        floor = (NOISE_FLOOR_G * self.one_g) ** 2  # noise levels below it are the same for any calibration
        level = np.array([np.log(max(float(median(b.var[j0:j1].sum(axis=1))), floor))
                          for _, _, j0, j1 in kept])
        weight = np.array([float(z - a) for a, z, _, _ in kept])
        order = np.argsort(level)
        cumulative = np.cumsum(weight[order])
        typical = float(level[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])
        odd = level > typical + 2.0 * self.var_limit
        return [k for k, flag in zip(kept, odd) if not flag], [k for k, flag in zip(kept, odd) if flag]

    def _creeps(self, r: rm.Ranges, per_sample: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether each stretch's accelerometer mean moves (a slow turn).

        Either its batch means trend significantly (Student's t of their slope) by more than the samples' own
        spread about the stretch's mean (:data:`SAME_POSE_SAMPLE_SIGMAS` σ; a creep hidden in it, a flicker
        noise's or a warming sensor's, moves no pose) or than a pose tolerates (a steady creep through Δ shrinks the mean's
        norm by Δ²/24: ``√(24 WOBBLE_SHRINK)`` g); or its batch means range over more than both, which no
        noise does whatever its colour (a batch mean scatters less than the samples) and a turn along a
        curved path does without a straight trend.
        """
        b = self.b
        tstat, dof, change, spread = rm.trend_statistics(b.t_mid, b.mean, r)
        means = b.mean[r.rows]  # too few blocks for batches: the blocks' own means are the batch means
        blocks_range = np.linalg.norm(np.maximum.reduceat(means, r.offset) - np.minimum.reduceat(means, r.offset), axis=1)
        spread = np.where(dof > 0, spread, blocks_range)
        noise = SAME_POSE_SAMPLE_SIGMAS * per_sample
        pose = np.sqrt(24.0 * WOBBLE_SHRINK) * self.one_g
        k = self.s.drift_threshold
        limit = np.array([rm.trend_limit(self.s.false_alarm, int(d)) if d > 0 else np.inf for d in dof])
        with np.errstate(over="ignore"):  # a huge --drift-threshold: infinite limits
            trending = (dof > 0) & (tstat > limit * k) & (change > np.minimum(noise, pose) * k)
            return np.asarray(trending | (spread > np.maximum(noise, pose) * k))

    def _turns(self, r: rm.Ranges) -> NDArray[np.bool_]:
        """Whether each stretch's mean rate is off the bias -- significantly, or by more than a MEMS gyro's bias
        moves (:data:`MAX_BIAS_WANDER_RAD_S`) -- through more than a pose's wobble tolerance.

        The noise of the stretch's mean rate is the scatter of its :data:`~optcal.data.rest_model.TREND_BATCHES`
        batch means (a hand's tremor and flicker included; Student's t with their dof) when it has as many
        blocks, else the blocks' own noise of the mean times the gyro's noise colour (normal); the bias' wander
        between rests is added.  A significant offset that turns the sensor through less than
        ``√(2 WOBBLE_SHRINK)`` over the stretch, or over :data:`WOBBLE_DWELLS` dwells if it is longer (a hand
        sagging by a fraction of a degree, a bias wandering over minutes), moves no pose.
        """
        b = self.b
        if b.gmean is None or self.bias is None or self.gvar_ref is None:
            return np.zeros(r.count, dtype=bool)
        w = b.n[r.rows, None]
        n = r.sums(b.n[r.rows])
        off = r.sums((b.gmean[r.rows] - self.track[r.rows]) * w) / n[:, None]
        k = r.length
        long = k >= rm.TREND_BATCHES
        se2 = np.empty((r.count, 3))
        if long.any():
            sub = rm.Ranges.of(r.start[long], r.stop[long])
            batches, owner = rm.batch_ranges(sub, rm.TREND_BATCHES, larger_first=True)
            xb = batches.sums(b.gmean[sub.rows]) / batches.length[:, None]
            first = np.arange(sub.count) * rm.TREND_BATCHES
            dev = xb - (np.add.reduceat(xb, first) / rm.TREND_BATCHES)[owner]
            se2[long] = np.add.reduceat(dev * dev, first) / (rm.TREND_BATCHES - 1.0) / rm.TREND_BATCHES + self.wander2
        for i in np.flatnonzero(~long):
            se2[i] = self.gkappa2 * (column_medians(self.gvar_ref[r.start[i]:r.stop[i]]) / n[i] + self.gfloor) + self.wander2
        limit = np.where(long, rm.trend_limit(self.s.false_alarm, rm.TREND_BATCHES - 1),
                         rm.normal_limit(self.s.false_alarm / 6.0))
        z = np.abs(off) / np.sqrt(np.maximum(se2, np.finfo(float).tiny))
        with np.errstate(over="ignore"):  # a huge --gyro-threshold: an infinite limit
            significant = np.max(z, axis=1) > limit * self.s.gyro_threshold
        if self.gyro_scale is None:
            bound = self._count_scale_bound() if significant.any() else None
            if bound is None:
                return np.asarray(significant)
            return np.asarray(significant & self._relevant_at_most(r, off, bound, significant))
        # off the bias by more than any MEMS gyro's bias moves within a session: a rotation, whatever the
        # statistics of a stretch that shakes say of its noise
        rate = np.linalg.norm(off, axis=1) * self.gyro_scale
        # beyond it by more than the noise of the stretch's mean rate (a noisy gyro's mean is off by its noise)
        rate_low = np.maximum(rate - limit * np.sqrt(se2.sum(axis=1)) * self.gyro_scale, 0.0)
        beyond_bias = rate_low > MAX_BIAS_WANDER_RAD_S * self.s.gyro_threshold
        # over a wobble window at most: a bias that wanders by a little, integrated over minutes, is no turn
        duration = np.minimum(b.t_mid[r.stop - 1] - b.t_mid[r.start] + b.n[r.start] / self.rate,
                              WOBBLE_DWELLS * self.s.min_dwell_s)
        # within a real gyro's reach of its bias (g-sensitivity's largest term at 1 g), only the turn across the
        # specific force moves the pose: about it, a(t) stays as it is (a yaw creep, or G f along f)
        acc = r.sums(b.mean[r.rows] * w) / n[:, None]
        across = np.linalg.norm(np.cross(off, unit_rows(acc - self.acc_zero)), axis=1) * self.gyro_scale
        rate = np.where(rate <= bm.MAX_G_SENSITIVITY_RAD_S_PER_G, across, rate)
        return np.asarray((significant | beyond_bias) & rm.turn_is_relevant(rate, duration, self.s.gyro_threshold))

    def _count_scale_bound(self) -> float | None:
        """:data:`MAX_RAD_S_PER_COUNT` where the gyro's samples are counts (whole numbers, a one-unit converter step,
        resting over :data:`COUNTS_MIN_REST_STEPS` steps or more), else None (the unit may be any: no bound)."""
        gvar = self.b.gvar
        if gvar is None or self.gyro_quantum != 1.0:
            return None
        rest_steps = float(np.min(np.sqrt(column_medians(gvar))))
        return MAX_RAD_S_PER_COUNT if rest_steps >= COUNTS_MIN_REST_STEPS else None

    def _relevant_at_most(self, r: rm.Ranges, off: NDArray[np.float64], bound: float,
                          which: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Whether each stretch's mean rate off the bias, ``off`` (gyro units), may turn the sensor beyond a pose's
        tolerance, at most ``bound`` rad/s per unit (the unit unknown), the accelerometer bounding the turn across
        the specific force (only the stretches ``which``; the others False).

        A turn across the specific force moves the accelerometer, ``ȧ = −ω × a``: its rate is at most the
        accelerometer's own rate of change over the stretch (the slope of its block means on time, least squares,
        plus the offset test's limit times its standard error from the blocks' noise times the noise colour) over
        ``|a|``, however fast the gyro's unknown unit would make it.  About the specific force only the gyro says:
        at most ``bound`` times the offset.  Judged over a wobble window at most, as where the unit is known.
        """
        b = self.b
        out = np.zeros(r.count, dtype=bool)
        z = rm.normal_limit(self.s.false_alarm / 6.0)
        for i in np.flatnonzero(which):
            rows = np.arange(r.start[i], r.stop[i])
            w = b.n[rows, None]
            acc = (b.mean[rows] * w).sum(axis=0) / w.sum() - self.acc_zero
            f = unit_rows(acc)
            along = abs(float(off[i] @ f)) * bound
            across = float(np.linalg.norm(np.cross(off[i], f))) * bound
            moved = self._acc_slope(rows)
            if moved is not None:  # the accelerometer's turn: its slope and standard error
                slope, se = moved
                seen = (float(np.linalg.norm(slope)) + z * float(np.linalg.norm(se))) / float(np.linalg.norm(acc))
                across = min(across, seen)
            duration = min(float(b.t_mid[rows[-1]] - b.t_mid[rows[0]]) + b.n[rows[0]] / self.rate,
                           WOBBLE_DWELLS * self.s.min_dwell_s)
            out[i] = bool(rm.turn_is_relevant(np.hypot(along, across), duration, self.s.gyro_threshold))
        return out

    def noise(self) -> dict[str, float]:
        """The noise measured: colours, the gyro bias' wander and its drift over the session (the range of its track),
        and the rounding floor of a block mean (its standard deviation, q/√12) on the axes whose signal is quieter
        than the converter's step."""
        out = {f"acc_colour_{a}": float(v) for a, v in zip("xyz", self.kappa2)}
        out.update({f"acc_rounding_{a}": float(np.sqrt(v)) for a, v in zip("xyz", self.floor) if v > 0})
        if self.bias is not None:
            out.update({f"gyro_colour_{a}": float(v) for a, v in zip("xyz", self.gkappa2)})
            out.update({f"gyro_wander_{a}": float(np.sqrt(v)) for a, v in zip("xyz", self.wander2)})
            out.update({f"gyro_rounding_{a}": float(np.sqrt(v)) for a, v in zip("xyz", self.gfloor) if v > 0})
            drift = column_ptp(self.track) if self.track.size else np.zeros(3)
            out.update({f"gyro_bias_drift_{a}": float(v) for a, v in zip("xyz", drift) if v > 0})
        return out

    def limits(self) -> dict[str, float]:
        out = {"step": float(np_median(self.step_limit)) if self.step_limit.size else float("nan"),
               "trend": rm.trend_limit(self.s.false_alarm, rm.TREND_BATCHES - 2) * self.s.drift_threshold}
        if self.bias is not None:
            out["gyro"] = float(np_median(self.gyro_limit))
        return out

    def trace(self, m: int) -> dict[str, NDArray[np.float64]]:
        """The step and gyro statistics over their critical values, per sample (the larger of a block's two pairs)."""
        b = self.b
        ratio = np.where(self.valid, self.step / self.step_limit, 0.0)
        per_block = np.zeros(b.count)
        per_block[1:] = ratio
        per_block[:-1] = np.maximum(per_block[:-1], ratio)
        lengths = (b.stop - b.start).astype(int)
        out = {"step": np.repeat(per_block, lengths)}
        if self.bias is not None:
            out["gyro"] = np.repeat(self.gstat / self.gyro_limit, lengths)
        return out
