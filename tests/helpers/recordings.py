"""A simulated recording the reading tests turn into a stranger's layout: poses of one accelerometer model with
the simulator's gyro (rad/s), 100 Hz, 2 mg of noise."""

from __future__ import annotations

from optcal.core.model import LumpedModel
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording

#: The accelerometer every reading test's recording is made with: scales 1.01, 0.99, 1.0, small
#: non-orthogonalities and offsets of 10-20 mg.
MODEL = LumpedModel.from_physical([1.01, 0.99, 1.0], 0.004, -0.003, 0.005, [0.01, -0.02, 0.015])


def turned_recording(n_poses: int, rng_poses: int, rng_noise: int, dwell_s: float = 3.0):
    """``n_poses`` evenly spread poses of :data:`MODEL`, ``dwell_s`` each, with 1.5-s turns between them."""
    return synthesize_recording(MODEL, uniform_directions(n_poses, rng=rng_poses), dwell_s=dwell_s, transition_s=1.5,
                                sigma=0.002, rng=rng_noise)
