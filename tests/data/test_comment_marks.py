"""Comment lines above the data marked ``//`` (C-style firmware prints) or ``;`` (INI-style notes), as ``#`` and ``%``
already were: skipped, and the one just above the data read as the column names.  Before, such lines were taken
for the header or for rows, and the file's names were lost."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.data import load
from optcal.data.text import sniff_layout
from optcal.families.simulate.poses import uniform_directions
from optcal.families.simulate.recording import synthesize_recording
from optcal.core.model import lu2017_reference_model


@pytest.mark.parametrize("mark", ["#", "//", ";"])
def test_comment_lines_above_the_data_marked_slashes_or_semicolon(tmp_path, mark):
    rec = synthesize_recording(lu2017_reference_model(), uniform_directions(12, rng=1), dwell_s=2.0,
                               transition_s=1.0, sigma=0.002, rng=2)
    frame = rec.frame[["t", "ax", "ay", "az"]]
    body = "\n".join(",".join(f"{v:.6f}" for v in row) for row in frame.to_numpy())
    path = tmp_path / "fw.csv"
    path.write_text(f"{mark} MPU-6050 print, 100 Hz, g\n{mark} board 3\n{mark} t_s,ax,ay,az\n{body}\n")
    layout = sniff_layout(path)
    assert list(layout.comment_names or ()) == ["t_s", "ax", "ay", "az"] and layout.first_data_line == 3
    loaded = load(path)
    assert loaded.decisions is not None and "t_s" in " ".join(loaded.decisions.lines())
    assert loaded.n == len(rec.dwells)
    means = [frame[["ax", "ay", "az"]].to_numpy()[a:b].mean(axis=0) for a, b in rec.dwells]
    assert np.allclose(loaded.acc, means, atol=0.003)
