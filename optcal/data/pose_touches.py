"""A joined pose's end pieces that are a hand's touch next to a move, left out of it (:func:`touches`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.data import rest_model as rm
from optcal.data.pose_joins import _piece_mean
from optcal.data.quantiles import column_medians

if TYPE_CHECKING:
    from optcal.data.rest_tests import RestModel


#: Fewest batches of the end piece's length in the rest of its pose for the piece's shift to be told from the
#: rest's own wander (:func:`touches`): the scatter of fewer means is no measure of it.
MIN_TOUCH_BATCHES: int = 3


def touches(groups: list[list[tuple[int, int]]], kept: list[tuple[int, int, int, int]], model: RestModel
            ) -> tuple[list[list[tuple[int, int]]], list[tuple[int, int]]]:
    """The groups less the end pieces that are a hand's touch next to a move, and those pieces.

    A pose joined from pieces (:func:`join_twitches`) whose last piece, after a twitch, leads into a move (or whose
    first, before a twitch, follows one) may be the sensor held as it is about to be moved, or still settling from
    the move: shifted from the rest by a fraction of a milli-g, well within the samples' spread (so joined), yet
    by many of the pose mean's standard errors.  Such a piece is left out when both

    * its mean is off the rest's by more than means of its length wander within the rest (the scatter of the rest's
      consecutive batches of as many blocks, at least :data:`MIN_TOUCH_BATCHES` of them: a flicker noise's wander
      is measured, not assumed; the χ²₃ of the difference over that scatter at the detector's false-alarm rate), and
    * keeping it would make the pose's mean worse: its pull on the joined mean, ``(n_e / N)² |d|²``, more than what
      it saves of the rest's variance, ``(n_e / N) σ²_rest`` (the larger of the rest's batch scatter over its
      batches and its blocks' noise).

    A piece inside a pose, or at the recording's ends, is not next to a move; nor one as long as the rest.
    """
    b = model.b
    blocks = {(a, z): (j0, j1) for a, z, j0, j1 in kept}
    out: list[list[tuple[int, int]]] = []
    dropped: list[tuple[int, int]] = []
    tiny = np.finfo(float).tiny
    for i, group in enumerate(groups):
        group = list(group)
        for end, moved in ((-1, i + 1 < len(groups)), (0, i > 0)):
            if len(group) < 2 or not moved:
                continue
            j0, j1 = blocks[group[end]]
            rest = np.concatenate([np.arange(*blocks[p]) for p in (group[:-1] if end == -1 else group[1:])])
            length = j1 - j0
            batches = rest.size // length
            if batches < MIN_TOUCH_BATCHES:
                continue
            piece, _, n_piece = _piece_mean(model, j0, j1)
            w = b.n[rest, None]
            n_rest = float(w.sum())
            rest_mean = (b.mean[rest] * w).sum(axis=0) / n_rest
            used = rest[: batches * length]
            sums = np.add.reduceat(b.mean[used] * b.n[used, None], np.arange(0, used.size, length), axis=0)
            counts = np.add.reduceat(b.n[used], np.arange(0, used.size, length))
            wander = (sums / counts[:, None]).var(axis=0, ddof=1)  # of a mean of the piece's length
            d = piece - rest_mean
            shifted = float(np.sum(d * d / np.maximum(wander * (1.0 + 1.0 / batches), tiny))) \
                > rm.chi2_limit(model.s.false_alarm, 3) * model.s.threshold
            white = model.kappa2 * (column_medians(b.var[rest]) / n_rest + model.floor)
            rest_var = np.maximum(wander / batches, white)
            share = n_piece / (n_piece + n_rest)
            if shifted and share * float(np.sum(d * d)) > float(np.sum(rest_var)):
                dropped.append(group.pop(end))
        out.append(group)
    return out, dropped
