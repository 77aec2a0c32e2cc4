"""The lumped error model (Lu 2017, eq. 2-6) and its identifiable form."""

import numpy as np
import pytest

from optcal.errors import InputError
from optcal.core.model import (
    LU2017_TABLE1_A_REF,
    LU2017_TABLE1_O_REF,
    LumpedModel,
    canonical_T,
    non_orthogonality_matrix,
    theta_from,
    unpack_theta,
)
from optcal.families.simulate.poses import uniform_directions


def test_table1_reference_from_physical_parameters(lu_model):
    # Lu 2017, section 3.1 parameters -> Table 1 reference A (printed to 4 decimals)
    assert np.max(np.abs(lu_model.A - LU2017_TABLE1_A_REF)) <= 5e-5 + 1e-12
    np.testing.assert_allclose(lu_model.o, LU2017_TABLE1_O_REF)


def test_non_orthogonality_rows_are_unit_vectors():
    cno = non_orthogonality_matrix(0.03, -0.02, 0.01)
    np.testing.assert_allclose(np.linalg.norm(cno, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(non_orthogonality_matrix(0, 0, 0), np.eye(3))


def test_canonical_T_is_lower_triangular_and_reproduces_A(lu_model):
    T = lu_model.T_canonical
    assert np.allclose(np.triu(T, 1), 0)
    assert np.all(np.diag(T) > 0)
    np.testing.assert_allclose(T.T @ T, lu_model.A, atol=1e-14)
    # any rotation of T gives the same canonical form
    q, _ = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))
    np.testing.assert_allclose(canonical_T((q @ lu_model.T).T @ (q @ lu_model.T)), T, atol=1e-12)


def test_canonical_T_rejects_indefinite():
    with pytest.raises(InputError, match="not an ellipsoid"):
        canonical_T(np.diag([1.0, -1.0, 1.0]))


def test_physical_round_trip_without_mounting():
    m = LumpedModel.from_physical([1.1, 0.9, 1.05], 0.02, -0.01, 0.015, [0.1, -0.2, 0.05])
    p = m.physical()
    np.testing.assert_allclose(p.scale, [1.1, 0.9, 1.05], atol=1e-12)
    np.testing.assert_allclose([p.rho, p.phi, p.lam], [0.02, -0.01, 0.015], atol=1e-12)
    np.testing.assert_allclose(p.lumped_matrix(), m.C, atol=1e-12)


def test_physical_decomposition_absorbs_mounting(lu_model):
    # the mounting misalignment is not identifiable: the decomposition gives the same A
    p = lu_model.physical()
    back = LumpedModel.from_physical(p.scale, p.rho, p.phi, p.lam, p.bias)
    np.testing.assert_allclose(back.A, lu_model.A, atol=1e-12)


def test_theta_pack_unpack(lu_model):
    th = lu_model.theta
    T, o = unpack_theta(th)
    np.testing.assert_allclose(theta_from(T, o), th)
    np.testing.assert_allclose(LumpedModel.from_theta(th).A, lu_model.A, atol=1e-12)


def test_correct_inverts_measure(lu_model):
    d = uniform_directions(50, 3)
    a = lu_model.measure(d)
    np.testing.assert_allclose(lu_model.correct(a), d, atol=1e-12)
    # the canonical T gives unit norms too (a rotation of the true directions)
    calibrated = (a - lu_model.o) @ lu_model.T_canonical.T
    np.testing.assert_allclose(np.linalg.norm(calibrated, axis=1), 1.0, atol=1e-12)
