"""An iOS CoreMotion dump's shape (fffire-oss/imu_processing's ``circle.txt``): one record over four lines, a
date-time line, then ``Acceleration:``, ``Rotation Rate:`` and ``Magnetic Field:`` lines (the seventh strangers'
sweep, docs/rest-model.md)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def ios_dump_lines(t: NDArray[np.float64], acc: NDArray[np.float64], gyro: NDArray[np.float64]) -> list[str]:
    """The lines of one record per row of ``t`` (s from 15:24:00), ``acc`` (n, 3) and ``gyro`` (n, 3)."""
    lines = []
    for s, a, w in zip(t, acc, gyro):
        whole, frac = divmod(float(s), 1.0)
        minute, second = divmod(int(whole), 60)
        lines += [f"    2023-04-17 15:{24 + minute:02d}:{second:02d}.{round(frac * 1e4):04d}",
                  "    Acceleration: " + ", ".join(repr(float(v)) for v in a),
                  "    Rotation Rate: " + ", ".join(repr(float(v)) for v in w),
                  "    Magnetic Field: 456.39, -227.53, -400.04"]
    return lines
