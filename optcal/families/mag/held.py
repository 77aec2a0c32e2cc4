"""A magnetometer's held samples: the rows a logger repeated until the magnetometer's next update, left out and
counted (one row per update) unless kept."""

from __future__ import annotations

import numpy as np

from optcal.families.mag.sample_set import MagSamples

#: Exclusion reason of the rows a logger repeated until the magnetometer's next update (:mod:`optcal.data.held_samples`).
HELD_ROWS = "magnetometer rows repeating its last update (a slower magnetometer in a faster log)"
#: Exclusion reason of a held log's rows between two updates that hold axes of both (a torn copy).
TORN_ROWS = "magnetometer rows holding axes of two updates (a logger's torn copy between them)"


def drop_held(samples: MagSamples, keep: bool = False) -> MagSamples:
    """``samples`` with one row per magnetometer update where the logger repeated each value until the next
    (:func:`optcal.data.held_samples.held_runs`), the repeats counted and said; with ``keep`` every row, said."""
    from dataclasses import replace

    from optcal.data.held_samples import held_runs

    held = held_runs(samples.m)
    if held is None:
        return samples
    note = held.describe("magnetometer", "--keep-mag-repeats", kept=keep)
    if keep:
        return replace(samples, notes=[*samples.notes, note])
    rows = held.first
    torn = {TORN_ROWS: int(held.torn.size)} if held.torn.size else {}
    pick = (lambda a: None if a is None else a[rows])
    return replace(samples, m=np.ascontiguousarray(samples.m[rows]), acc=pick(samples.acc), gyro=pick(samples.gyro),
                   t=pick(samples.t), temp=pick(samples.temp), current=pick(samples.current),
                   throttle=pick(samples.throttle), exclusions={**samples.exclusions, HELD_ROWS: held.n_repeats, **torn},
                   notes=[*samples.notes, note])
