"""A parameter no pose excites is undetermined on its own, in the single and the batched rank test.

Scaling the Fisher information to correlation form blows a column with no information (its
diagonal at rounding level, ~1e-17 of the largest) up to unit size: the column of rounding noise
then either passes as an independent direction (a rank one too high, a degenerate pose set
accepted) or is paired with the genuine null combinations ("o_z together with +0.45·A_xz").
"""

from __future__ import annotations

import numpy as np
import pytest

from optcal.errors import IdentifiabilityError
from optcal.families.accel.batched import BatchedMaximumLikelihood
from optcal.families.accel.mle import MaximumLikelihood
from optcal.core.identifiability import (
    A_INDEX,
    analyse,
    dA_dtheta,
    fisher_information,
    numerical_rank,
    parameter_full_scale,
    scaled_information,
)
from optcal.core.model import PARAM_NAMES, lu2017_reference_model
from optcal.core.poses import PoseTable
from optcal.families.simulate.poses import uniform_directions

MODEL = lu2017_reference_model()
T = MODEL.T_canonical


def _raw_plane(n: int, wobble: float, rng: np.random.Generator) -> np.ndarray:
    """Noise-free poses whose raw ``a − o`` lies in the raw x-y plane (``wobble``: its z, relative)."""
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False) + 0.3
    u = np.c_[np.cos(angle), np.sin(angle), wobble * rng.standard_normal(n)]
    return u / np.linalg.norm(u @ T.T, axis=1)[:, None] + MODEL.o


def _calibrated_plane(n: int) -> np.ndarray:
    """Noise-free poses whose calibrated direction ``T (a − o)`` lies in the x-y plane."""
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False) + 0.1
    return np.linalg.solve(T, np.c_[np.cos(angle), np.sin(angle), 0 * angle].T).T + MODEL.o


def _theta_change(item: dict, T: np.ndarray) -> np.ndarray:
    """The change of θ that a described combination of entries of (A, o) (or of θ) stands for."""
    names = [f"A_{'xyz'[i]}{'xyz'[j]}" for i, j in A_INDEX] + ["o_x", "o_y", "o_z"]
    combo = item["combination"]
    if set(combo) <= set(PARAM_NAMES):
        return np.array([combo.get(n, 0.0) for n in PARAM_NAMES])
    change = np.array([combo.get(n, 0.0) for n in names])
    return np.concatenate([np.linalg.solve(dA_dtheta(T), change[:6]), change[6:]])


@pytest.mark.parametrize("wobble", [0.0, 1e-9])
def test_unexcited_parameter_named_alone_and_the_combinations_are_null(wobble):
    """Raw poses in one plane: T_zz unexcited, plus three genuine null combinations (rank 5)."""
    acc = _raw_plane(12, wobble, np.random.default_rng(3))
    report = analyse(T, MODEL.o, acc)
    assert report.rank == 5
    assert len(report.unidentified) == 4
    # T_zz alone, in the entries of A the report speaks of (A_zz, tied to A_xz and A_yz by T)
    assert report.unidentified[0]["entry"] == "A_zz"
    assert report.unidentified[0]["text"].endswith(": no pose carries information on it")
    assert np.count_nonzero(np.abs(_theta_change(report.unidentified[0], T)) > 1e-9) == 1  # a change of T_zz only
    F = fisher_information(T, MODEL.o, acc)
    scale = np.sqrt(np.diag(F).max())
    for item in report.unidentified:
        v = _theta_change(item, T)
        # every named change is a null direction of the information, to rounding
        assert np.linalg.norm(F @ v) <= 1e-8 * scale**2 * np.linalg.norm(v), item["text"]
        assert all(abs(c) < 1e3 for c in item["combination"].values()), item["text"]
    # the combinations are among the excited parameters: none of them moves T_zz's entry again
    for item in report.unidentified[1:]:
        assert "A_zz" not in item["combination"]
    entries = sorted(item["entry"] for item in report.unidentified[1:])
    assert entries == ["A_xz", "A_yz", "o_z"]


def test_single_and_batched_refuse_a_pose_set_that_leaves_one_parameter_unexcited():
    """Two planes of poses (raw and calibrated x-y): everything but T_zz is determined (rank 8)."""
    acc = np.vstack([_raw_plane(8, 1e-9, np.random.default_rng(4)), _calibrated_plane(8)])
    report = analyse(T, MODEL.o, acc)
    assert report.rank == 8
    assert len(report.unidentified) == 1 and report.unidentified[0]["entry"] == "A_zz"
    assert report.unidentified[0]["text"].endswith(": no pose carries information on it")
    table = PoseTable(acc=acc)
    with pytest.raises(IdentifiabilityError, match="8 of 9"):
        MaximumLikelihood().fit(table)
    good = PoseTable(acc=MODEL.measure(uniform_directions(24, 1)))
    fit = BatchedMaximumLikelihood().fit_many([good, table], validate=False)
    assert fit.identifiable.tolist() == [True, False]


def test_counts_units_do_not_make_the_offsets_look_unexcited():
    """In counts the offsets' information is ~1e-16 of the scale factors' in raw units: full-scale units judge them alike."""
    counts_per_g = 16384.0
    acc = MODEL.measure(uniform_directions(24, 1)) * counts_per_g
    T_counts, o_counts = T / counts_per_g, MODEL.o * counts_per_g
    F = fisher_information(T_counts, o_counts, acc)
    assert np.diag(F)[6:].max() < 1e-13 * np.diag(F)[:6].max()  # raw units would call the offsets unexcited
    report = analyse(T_counts, o_counts, acc)
    assert report.rank == 9 and report.unidentified == []


def test_stacked_rank_test_equals_the_single_one():
    """The batched fit's rank test (a stack of informations, one unexcited set per unit) is the single one."""
    rng = np.random.default_rng(5)
    designs = [MODEL.measure(uniform_directions(24, 1)),
               np.vstack([_raw_plane(8, 1e-9, rng), _calibrated_plane(8)]),
               _raw_plane(16, 0.0, rng)]
    stack = np.stack([fisher_information(T, MODEL.o, acc) for acc in designs])
    theta = np.array([T[0, 0], T[1, 0], T[1, 1], T[2, 0], T[2, 1], T[2, 2], *MODEL.o])
    full_scale = np.broadcast_to(parameter_full_scale(theta), (len(designs), 9))
    ranks = numerical_rank(np.linalg.eigvalsh(scaled_information(stack, full_scale)[0]))
    assert ranks.tolist() == [analyse(T, MODEL.o, acc).rank for acc in designs] == [9, 8, 5]
