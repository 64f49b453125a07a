"""Voigt (Abaqus UMAT) and Mandel converters: round trips, invariance of contractions, isotropic stiffness."""

import numpy as np
import pytest

from material import tensors as T
from material.elastic import isotropic_compliance, isotropic_stiffness

rng = np.random.default_rng(42)


def _sym(a):
    return 0.5 * (a + np.swapaxes(a, -1, -2))


def _minor_sym_tangent(shape=()):
    c = rng.normal(size=shape + (3, 3, 3, 3))
    c = 0.5 * (c + np.swapaxes(c, -4, -3))
    return 0.5 * (c + np.swapaxes(c, -2, -1))  # minor symmetric, NOT major symmetric


def test_mandel_round_trip_and_order():
    a = _sym(rng.normal(size=(4, 5, 3, 3)))
    v = T.to_mandel(a)
    assert v.shape == (4, 5, 6)
    assert np.allclose(T.from_mandel(v), a, atol=1e-15)
    x = np.array([[1.0, 6.0, 5.0], [6.0, 2.0, 4.0], [5.0, 4.0, 3.0]])
    r = np.sqrt(2)
    assert np.allclose(T.to_mandel(x), [1, 2, 3, 4 * r, 5 * r, 6 * r])


def test_voigt_abaqus_order_and_engineering_shear():
    x = np.array([[1.0, 6.0, 5.0], [6.0, 2.0, 4.0], [5.0, 4.0, 3.0]])
    assert np.allclose(T.stress_to_voigt(x), [1, 2, 3, 6, 5, 4])
    assert np.allclose(T.strain_to_voigt(x), [1, 2, 3, 12, 10, 8])
    a = _sym(rng.normal(size=(7, 3, 3)))
    assert np.allclose(T.voigt_to_stress(T.stress_to_voigt(a)), a)
    assert np.allclose(T.voigt_to_strain(T.strain_to_voigt(a)), a)


def test_double_contraction_preserved():
    s = _sym(rng.normal(size=(10, 3, 3)))
    e = _sym(rng.normal(size=(10, 3, 3)))
    ref = np.einsum("nij,nij->n", s, e)
    assert np.allclose(np.einsum("ni,ni->n", T.to_mandel(s), T.to_mandel(e)), ref)
    assert np.allclose(np.einsum("ni,ni->n", T.stress_to_voigt(s), T.strain_to_voigt(e)), ref)


def test_tangent_round_trips_and_action():
    c = _minor_sym_tangent((3,))
    e = _sym(rng.normal(size=(3, 3, 3)))
    s = np.einsum("nijkl,nkl->nij", c, e)
    m = T.to_mandel_matrix(c)
    assert m.shape == (3, 6, 6)
    assert np.allclose(T.from_mandel_matrix(m), c)
    assert np.allclose(np.einsum("nIJ,nJ->nI", m, T.to_mandel(e)), T.to_mandel(s))
    d = T.to_voigt_tangent(c)
    assert np.allclose(T.from_voigt_tangent(d), c)
    assert np.allclose(np.einsum("nIJ,nJ->nI", d, T.strain_to_voigt(e)), T.stress_to_voigt(s))


def test_isotropic_stiffness_in_mandel_form():
    E, nu = 6000.0, 0.33
    K, G = E / (3 * (1 - 2 * nu)), E / (2 * (1 + nu))
    p_vol, p_dev = T.identity_projectors()
    C = isotropic_stiffness(E, nu)
    assert np.allclose(C, 3 * K * p_vol + 2 * G * p_dev)
    m = T.to_mandel_matrix(C)
    assert np.allclose(m, 3 * K * T.to_mandel_matrix(p_vol) + 2 * G * T.to_mandel_matrix(p_dev))
    # Mandel projectors are orthogonal projections: P P = P, Pvol Pdev = 0, sum = I6
    mv, md = T.to_mandel_matrix(p_vol), T.to_mandel_matrix(p_dev)
    assert np.allclose(mv @ mv, mv) and np.allclose(md @ md, md) and np.allclose(mv @ md, 0)
    assert np.allclose(mv + md, np.eye(6))
    # eigenvalues 3K (once) and 2G (five times); the Mandel inverse is the compliance
    assert np.allclose(np.sort(np.linalg.eigvalsh(m)), [2 * G] * 5 + [3 * K])
    assert np.allclose(np.linalg.inv(m), T.to_mandel_matrix(isotropic_compliance(E, nu)))
    # Abaqus DDSDDE: shear diagonal entries are G (engineering strain), normal block lambda + 2G / lambda
    d = T.to_voigt_tangent(C)
    lam = K - 2 * G / 3
    assert np.allclose(np.diag(d), [lam + 2 * G] * 3 + [G] * 3)
    assert np.allclose(d[0, 1], lam)


def test_bad_shapes():
    with pytest.raises(ValueError, match="Mandel vector"):
        T.from_mandel(np.zeros(5))
    with pytest.raises(ValueError, match="tangent"):
        T.to_mandel_matrix(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="strain"):
        T.strain_to_voigt(np.zeros((2, 3)))
