"""Still stretches of a recording: runs, the gyro's unit and wobble, and the pieces of one pose joined.

The rest model (:mod:`optcal.data.rest_tests`) finds runs of still blocks (:func:`true_runs`); these helpers
read the gyro in radians (:func:`gyro_rad_per_unit`, :mod:`optcal.data.gyro_unit`; its scale from the moves,
:mod:`optcal.data.move_scale`), measure how a stretch's orientation wobbles (:func:`wobble`,
:mod:`optcal.data.wobble`; its bound, :mod:`optcal.data.wobble_bound`), join the rests that are one pose
interrupted (:func:`join_twitches`, :func:`no_net_turn`, :mod:`optcal.data.pose_joins`) and leave out a hand's
touch at a pose's ends (:func:`touches`, :mod:`optcal.data.pose_touches`), and give a pose's sample positions
(:func:`group_positions`).  Every name these modules define is importable from here, as before the split.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

# the stretches' concepts, one module each (and importable from here, as before): the gyro's unit, its scale
# from the moves, the wobble and its bound, the pieces of one pose joined, and a hand's touch at a pose's ends
from optcal.data.gyro_unit import UNIT_MATCH_FACTOR, decide_gyro_scale, gyro_rad_per_unit
from optcal.data.move_scale import (ALIAS_CANDIDATES, GRID_STEP_LOG, MAX_MOVE_S, MAX_SCALE_MOVES,
                                    MAX_UNEXPLAINED_TURN, MIN_MOVE_TURN_RAD, MIN_SCALE_MOVES, MOVE_STEP_S,
                                    REFINE_POINTS, SCALE_GRID, ScaleEvidence, _move_increments, _pair_products,
                                    _predicted_cosines, _refine_logs, _turn_about_axis, _turned, scale_from_moves)
from optcal.data.pose_joins import (_piece_mean, _piece_means, _still_between, _window_integrals, join_twitches,
                                    no_net_turn, stays_in_pose)
from optcal.data.pose_touches import MIN_TOUCH_BATCHES, touches
from optcal.data.wobble import RESOLVED_WOBBLE_SHARE, WOBBLE_CHUNK_VALUES, _ranks, wobble, wobbles
from optcal.data.wobble_bound import SPREAD_ROUNDING_ULPS, _block_span_sums, _span_sums, _spread_margin


def true_runs(mask: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return edges[::2], edges[1::2]


def group_positions(group: list[tuple[int, int]]) -> slice | NDArray[np.int64]:
    """The sample positions of a group of stretches ``[a, b)``: a slice for one stretch (no index array)."""
    if len(group) == 1:
        return slice(int(group[0][0]), int(group[0][1]))
    return np.concatenate([np.arange(a, b) for a, b in group])
