"""Integration rules on the unit sphere: normalisation, symmetry and the claimed degree of exactness."""

import itertools

import numpy as np
import pytest

from material.planes import (
    available_rules,
    integration_rule,
    monomial_sphere_average,
    rotate_normals,
    rule_info,
    sphere_average,
)

RULES = sorted(available_rules())
EXPECTED = {  # name: (planes, degree)
    "lebedev-26": (13, 7),
    "bazant-oh-21": (21, 9),
    "lebedev-50": (25, 11),
    "bazant-oh-33": (33, 11),
    "lebedev-86": (43, 15),
    "lebedev-110": (55, 17),
    "equator-78": (78, 13),
}
OCTAHEDRAL = [r for r in RULES if r != "equator-78"]
# Bazant-Oh tables are printed with 10 digits: their moments are exact to ~3e-11
TOL = {"bazant-oh-33": 1e-9}


def _monomial_errors(normals, weights, degree):
    """Largest |rule - exact| over all monomials x^a y^b z^c with a + b + c == degree."""
    err = 0.0
    for a in range(degree + 1):
        for b in range(degree + 1 - a):
            c = degree - a - b
            approx = np.sum(weights * normals[:, 0] ** a * normals[:, 1] ** b * normals[:, 2] ** c)
            err = max(err, abs(approx - monomial_sphere_average(a, b, c)))
    return err


def test_catalogue():
    assert {k: EXPECTED[k][1] for k in EXPECTED} == available_rules()
    for name, (m, deg) in EXPECTED.items():
        info = rule_info(name)
        assert info["n_planes"] == m and info["degree"] == deg and info["even_degree"] == deg - 1


@pytest.mark.parametrize("name", RULES)
def test_normalised_unit_hemisphere(name):
    n, w = integration_rule(name)
    assert n.shape == (EXPECTED[name][0], 3) and w.shape == (EXPECTED[name][0],)
    assert abs(w.sum() - 1.0) < 1e-14
    assert np.all(w > 0)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-14)
    # +/- folding: no normal appears together with its opposite, and no duplicates
    both = np.vstack([n, -n])
    d = np.linalg.norm(both[:, None, :] - both[None, :, :], axis=2)
    assert np.sum(d < 1e-8) == 2 * len(n)


@pytest.mark.parametrize("name", OCTAHEDRAL)
def test_octahedral_invariance(name):
    """The 48 signed permutations map the set of +/- normals (with weights) onto itself."""
    n, w = integration_rule(name)
    full_n, full_w = np.vstack([n, -n]), np.concatenate([w, w])
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            m = n[:, perm] * np.array(signs)
            d = np.linalg.norm(m[:, None, :] - full_n[None, :, :], axis=2)
            j = d.argmin(axis=1)
            assert d[np.arange(len(m)), j].max() < 1e-8
            assert np.allclose(full_w[j], w, rtol=1e-8)


@pytest.mark.parametrize("name", RULES)
def test_exact_up_to_claimed_degree_and_not_beyond(name):
    n, w = integration_rule(name)
    degree = available_rules()[name]
    tol = TOL.get(name, 1e-13)
    for d in range(0, degree, 2):  # even monomials up to degree - 1
        assert _monomial_errors(n, w, d) < tol, (name, d)
    # one degree higher than claimed (even): not exact
    assert _monomial_errors(n, w, degree + 1) > 1e-7  # lebedev-110: 5.0e-7


def test_bazant_oh_33_table_precision():
    """The 10-digit table: even moments up to degree 10 agree to a few 1e-11, degree 12 is off by ~1e-4."""
    n, w = integration_rule("bazant-oh-33")
    err10 = max(_monomial_errors(n, w, d) for d in (2, 4, 6, 8, 10))
    err12 = _monomial_errors(n, w, 12)
    print(f"bazant-oh-33: max error degree<=10: {err10:.2e}, degree 12: {err12:.2e}")
    assert 1e-13 < err10 < 1e-10
    assert 5e-5 < err12 < 5e-4


def test_second_and_fourth_order_fabric_identities():
    """<n n> = I/3 and <n n n n> = (d d + 2 sym)/15 for every rule (what the plastic strain average relies on)."""
    d = np.eye(3)
    iso4 = (np.einsum("ij,kl->ijkl", d, d) + np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d)) / 15
    for name in RULES:
        n, w = integration_rule(name)
        tol = TOL.get(name, 1e-13)
        assert np.allclose(sphere_average(np.einsum("ai,aj->aij", n, n), w), d / 3, atol=tol)
        assert np.allclose(sphere_average(np.einsum("ai,aj,ak,al->aijkl", n, n, n, n), w), iso4, atol=tol)


def test_rotated_rule_still_exact():
    """Rotating the planes with a material frame keeps the rule exact (a rotated polynomial has the same degree)."""
    from material.anisotropy import axes_from_alpha

    n, w = integration_rule("bazant-oh-33")
    nr = rotate_normals(n, axes_from_alpha(37.0))
    assert np.allclose(np.linalg.norm(nr, axis=1), 1.0)
    for deg in (2, 6, 10):
        assert _monomial_errors(nr, w, deg) < 1e-9


def test_monomial_sphere_average_closed_form():
    assert monomial_sphere_average(0, 0, 0) == pytest.approx(1.0)
    assert monomial_sphere_average(2, 0, 0) == pytest.approx(1 / 3)
    assert monomial_sphere_average(4, 0, 0) == pytest.approx(1 / 5)
    assert monomial_sphere_average(2, 2, 0) == pytest.approx(1 / 15)
    assert monomial_sphere_average(2, 2, 2) == pytest.approx(1 / 105)
    assert monomial_sphere_average(1, 2, 0) == 0.0
    # Monte Carlo cross-check of a degree-6 moment
    rng = np.random.default_rng(0)
    v = rng.normal(size=(400_000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    assert np.mean(v[:, 0] ** 4 * v[:, 2] ** 2) == pytest.approx(monomial_sphere_average(4, 0, 2), rel=2e-2)


def test_unknown_rule_lists_available():
    with pytest.raises(KeyError, match="bazant-oh-33"):
        integration_rule("gauss-7")


def test_returns_copies():
    n, w = integration_rule("bazant-oh-21")
    n[:] = 0.0
    w[:] = 0.0
    n2, w2 = integration_rule("bazant-oh-21")
    assert abs(w2.sum() - 1) < 1e-14 and np.allclose(np.linalg.norm(n2, axis=1), 1)


def test_sphere_average_shape_check():
    _, w = integration_rule("lebedev-26")
    with pytest.raises(ValueError, match="weights"):
        sphere_average(np.ones(5), w)
