"""The tangent assembly, strains and internal forces against scikit-fem's own forms and numpy references."""

import numpy as np
import pytest
import skfem
from skfem.helpers import ddot, sym_grad

from femgran.assembly import Discretisation, element_stiffness_reference
from femgran.mesh import box, rectangle
from femgran.state import PointState

MESHES = [
    ("hex1", lambda: box(1.0, 1.0, 2.0, 2, 2, 3), 1),
    ("hex2", lambda: box(1.0, 1.0, 1.0, 1, 2, 2), 2),
    ("tet1", lambda: box(1.0, 1.0, 1.0, 2, 2, 2, kind="tet"), 1),
    ("tet2", lambda: box(1.0, 1.0, 1.0, 1, 1, 2, kind="tet"), 2),
    ("quad1", lambda: rectangle(np.linspace(0, 1, 4), np.linspace(0, 2, 3)), 1),
    ("quad2", lambda: rectangle(np.linspace(0, 1, 4), np.linspace(0, 2, 3)), 2),
    ("tri1", lambda: rectangle(np.linspace(0, 1, 4), np.linspace(0, 2, 3), kind="tri"), 1),
    ("tri2", lambda: rectangle(np.linspace(0, 1, 3), np.linspace(0, 2, 3), kind="tri"), 2),
]


def _distort(mesh, amount=0.08, seed=0):
    """Move interior vertices randomly (keeps the boundary straight)."""
    p = mesh.p.copy()
    lo, hi = p.min(axis=1, keepdims=True), p.max(axis=1, keepdims=True)
    interior = np.all((p > lo + 1e-9) & (p < hi - 1e-9), axis=0)
    rng = np.random.default_rng(seed)
    p[:, interior] += amount * rng.uniform(-1, 1, size=(p.shape[0], interior.sum()))
    return type(mesh)(p, mesh.t)


def _random_tangent(n, rng):
    """Random (N,3,3,3,3) with minor symmetries but no major symmetry (non-associated flow)."""
    D = rng.normal(size=(n, 3, 3, 3, 3))
    D = 0.5 * (D + D.transpose(0, 2, 1, 3, 4))
    return 0.5 * (D + D.transpose(0, 1, 2, 4, 3))


@pytest.mark.parametrize("name,make,order", MESHES, ids=[m[0] for m in MESHES])
def test_tangent_matches_scikit_fem_assembly(name, make, order, rng):
    mesh = _distort(make()) if name.startswith(("hex", "quad")) else make()
    d = Discretisation(mesh, order)
    vb = skfem.Basis(mesh, skfem.ElementVector(d.element), intorder=d.intorder)
    assert np.array_equal(vb.element_dofs.T, d.edofs)  # our DOF numbering is ElementVector's
    D = _random_tangent(d.n_points, rng)
    K = d.stiffness(D)
    # scikit-fem's layout: tensor indices first, (nelems, nqp) last; femgran's point = element * nqp + q
    Dq = np.moveaxis(D[:, : d.dim, : d.dim, : d.dim, : d.dim], 0, -1).reshape((d.dim,) * 4 + (d.nelems, d.nqp))

    @skfem.BilinearForm
    def tangent_form(u, v, w):
        return ddot(np.einsum("ijkl...,kl...->ij...", w.C, sym_grad(u)), sym_grad(v))

    K_ref = tangent_form.assemble(vb, C=Dq)
    assert abs(K - K_ref).max() <= 1e-13 * abs(K_ref).max()
    # numba kernel vs plain numpy
    Dd = np.ascontiguousarray(D[:, : d.dim, : d.dim, : d.dim, : d.dim]).reshape(d.nelems, d.nqp, *(d.dim,) * 4)
    np.testing.assert_allclose(d.element_matrices(D), element_stiffness_reference(d.dN, d.dx, Dd), rtol=1e-12, atol=1e-12)
    # internal force: d f_int / d u = K for a linear map sigma = D : eps
    u = rng.normal(size=d.ndofs)
    sig = np.einsum("nijkl,nkl->nij", D, d.strain(u))
    np.testing.assert_allclose(d.internal_force(sig), K @ u, rtol=1e-10, atol=1e-10 * np.abs(K @ u).max())


def test_point_state_commit_and_revert():
    import material

    ps = PointState(material.VonMises(1e4, 0.3, 10.0), 2)
    de = np.zeros((2, 3, 3))
    de[:, 0, 1] = de[:, 1, 0] = 0.01
    ps.evaluate(de)
    assert ps.trial_state["eq_plastic_strain"].max() > 0
    ps.revert()
    assert ps.state["eq_plastic_strain"].max() == 0 and ps.trial_state["eq_plastic_strain"].max() == 0
    ps.evaluate(de)
    ps.commit()
    assert ps.state["eq_plastic_strain"].min() > 0
    np.testing.assert_allclose(np.sqrt(1.5) * np.linalg.norm(ps.stress[0] - np.trace(ps.stress[0]) / 3 * np.eye(3)), 10.0)


@pytest.mark.parametrize("name,make,order", [m for m in MESHES if m[0] in ("hex1", "hex2", "quad1", "quad2")],
                         ids=["hex1", "hex2", "quad1", "quad2"])
def test_bbar_tangent_is_the_derivative_of_the_bbar_internal_force(name, make, order, rng):
    from femgran.assembly import bbar_operator_reference

    mesh = _distort(make())
    d = Discretisation(mesh, order, volumetric="bbar")
    D = _random_tangent(d.n_points, rng)
    K = d.stiffness(D)
    u = rng.normal(size=d.ndofs)
    sig = np.einsum("nijkl,nkl->nij", D, d.strain(u))
    np.testing.assert_allclose(d.internal_force(sig), K @ u, rtol=1e-10, atol=1e-10 * np.abs(K @ u).max())
    # numba kernel vs the plain numpy B-bar operator
    dim = d.dim
    Dd = np.ascontiguousarray(D[:, :dim, :dim, :dim, :dim]).reshape(d.nelems, d.nqp, *(dim,) * 4)
    Bb = bbar_operator_reference(d.dN, d.g, d.c)
    K_ref = np.einsum("eqaijm,eqjmkl,eqbnkl,eq->eaibn", Bb, Dd, Bb, d.dx).reshape(d.element_matrices(D).shape)
    np.testing.assert_allclose(d.element_matrices(D), K_ref, rtol=1e-11, atol=1e-11 * np.abs(K_ref).max())
    # the projected volumetric strain of a quadratic (order 2) / linear (order 1) field is its projection:
    # a linear displacement keeps its exact (constant) strain
    H = np.arange(1.0, 1.0 + dim * dim).reshape(dim, dim) * 1e-3
    ul = (d.dof_coordinates() @ H.T).ravel()
    eps = d.strain(ul)[:, :dim, :dim]
    np.testing.assert_allclose(eps, np.broadcast_to(0.5 * (H + H.T), eps.shape), atol=1e-14)
