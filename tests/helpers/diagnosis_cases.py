"""Hidden-effect data sets for the diagnosis tests and the null-rate study (the truth stays here).

Issue 4's acceptance ranges: every effect of the vocabulary, a random axis, magnitudes down to
0.5 mg/°C, 300 ppm/°C, 3 mg of drift over the recording, 4 mg/g² and 8 % outlier poses; 40-120
poses; 0.2-0.8 mg of noise per pose.  The temperature follows a warm-up then a cool-down
(:func:`optcal.families.simulate.effects.warmup_cooldown`) spanning 15-30 °C over a 20-minute session.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from optcal.core.extended_model import ExtendedModel
from optcal.families.simulate.effects import simulate_extended, warmup_cooldown
from optcal.core.model import AXES, lu2017_reference_model
from optcal.core.poses import PoseTable
from optcal.families.simulate.poses import uniform_directions

#: Smallest magnitude of each effect (first-order coefficient; drift: g over the recording;
#: outliers: fraction of poses).
MIN_MAGNITUDE = {
    "temperature_bias": 0.5e-3,
    "temperature_scale": 300e-6,
    "bias_drift": 3e-3,
    "scale_nonlinearity": 4e-3,
    "outliers": 0.08,
}
DURATION_S = 1200.0
#: Temperature span of the warm-up (°C): a sensor warming in its enclosure, or a thermal chamber run.
SPAN_C = (15.0, 30.0)


@dataclass
class Case:
    poses: PoseTable
    effect: str | None
    axis: str | None
    value: float | None
    outlier_rows: list[int]
    sigma: float
    #: For outliers: each pose's shift (raw units, 3-vectors in the rows' order).
    outlier_shifts: list[NDArray[np.float64]] = field(default_factory=list)


def make_case(effect: str | None, seed: int, scale: tuple[float, float] = (1.0, 2.0),
              n_range: tuple[int, int] = (40, 120), sigma_range: tuple[float, float] = (0.2e-3, 0.8e-3)) -> Case:
    """A pose table with ``effect`` hidden (``None``: clean), drawn from the acceptance ranges."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(n_range[0], n_range[1] + 1))
    sigma = float(rng.uniform(*sigma_range))
    axis = int(rng.integers(3))
    factor = float(rng.uniform(*scale))
    directions = uniform_directions(n, rng)
    t = np.sort(rng.uniform(0, DURATION_S, n))
    span = float(rng.uniform(*SPAN_C))
    temp = warmup_cooldown(t, 22.0, 22.0 + span, 22.0 + 0.4 * span) + 0.05 * rng.standard_normal(n)
    base = lu2017_reference_model()
    value = None
    if effect in (None, "outliers"):
        model = ExtendedModel(base)
    else:
        value = MIN_MAGNITUDE[effect] * factor / (DURATION_S if effect == "bias_drift" else 1.0)
        value *= rng.choice([-1.0, 1.0])
        model = ExtendedModel.with_effect(base, effect, axis, value, temp_ref=30.0, t_ref=600.0)
    poses = simulate_extended(model, directions, sigma, temp=temp, t=t, rng=rng)
    rows: list[int] = []
    shifts: list[NDArray[np.float64]] = []
    if effect == "outliers":
        k = int(round(MIN_MAGNITUDE["outliers"] * factor * n))
        bad = np.sort(rng.choice(n, size=k, replace=False))
        acc = poses.acc.copy()
        for b in bad:  # a pose that was not static: 10-40 σ off, mostly along its own direction
            radial = acc[b] / np.linalg.norm(acc[b])
            side = np.cross(radial, rng.standard_normal(3))
            side /= np.linalg.norm(side)
            angle = rng.uniform(0, np.pi / 4)
            size = rng.uniform(10, 40) * sigma
            shifts.append(size * (rng.choice([-1.0, 1.0]) * np.cos(angle) * radial + np.sin(angle) * side))
            acc[b] += shifts[-1]
        poses = poses.with_acc(acc)
        rows = [int(r) for r in bad]
        axis = None
    return Case(poses, effect, None if axis is None else AXES[axis], value, rows, sigma, shifts)


def write_pose_table(poses: PoseTable, path):
    """``poses`` as a CSV pose table (``ax, ay, az, sigma, t, temp``) for the command-line tests."""
    import pandas as pd

    frame = pd.DataFrame({"ax": poses.acc[:, 0], "ay": poses.acc[:, 1], "az": poses.acc[:, 2],
                          "sigma": poses.sigma, "t": poses.t, "temp": poses.temp})
    frame.to_csv(path, index=False, float_format="%.10g")
    return path


def write_table(case, path: Path, temp: bool = True) -> Path:
    p = case.poses
    frame = pd.DataFrame({"ax": p.acc[:, 0], "ay": p.acc[:, 1], "az": p.acc[:, 2], "sigma": p.sigma, "t": p.t})
    if temp:
        frame["temp"] = p.temp
    frame.to_csv(path, index=False, float_format="%.10g")
    return path
