"""Displacement discretisation on scikit-fem: strains, internal forces and the tangent B^T D B.

A :class:`Discretisation` holds a scikit-fem mesh, a scalar Lagrange element and its quadrature. It
takes the scalar shape-function gradients ``dN`` and weights ``dx`` from scikit-fem's ``CellBasis``
and numbers the vector DOFs as scikit-fem's ``ElementVector`` does (``dof = dim * scalar_dof +
component``), so the boundary tools of scikit-fem apply unchanged. The material is evaluated outside
(once per Newton iteration); this module only maps

* displacement ``u`` (ndofs,) -> strain increment at the points (N, 3, 3) (plane strain: eps_zz = 0),
* point stress (N, 3, 3) -> internal force f_int_(a,i) = sum_q dx sigma_ij dN_a,j,
* point tangent (N, 3, 3, 3, 3) -> K_(a,i)(b,k) = sum_q dx dN_a,j D_ijkl dN_b,l (no major symmetry needed).

The tangent is assembled by a numba kernel over elements (:func:`_element_stiffness`) and scattered
into a CSR pattern computed once; :func:`element_stiffness_reference` is the plain numpy version the
tests compare against (and both against scikit-fem's own ``asm`` of the same form).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit, prange

import skfem

__all__ = ["Discretisation", "element_for", "element_stiffness_reference"]

# element and quadrature order per (mesh type, polynomial order): full Gauss for Q1/Q2/H1/H2,
# exact stiffness on straight simplices
_ELEMENTS = {
    ("MeshHex1", 1): ("ElementHex1", 3),
    ("MeshHex1", 2): ("ElementHex2", 5),
    ("MeshTet1", 1): ("ElementTetP1", 1),
    ("MeshTet1", 2): ("ElementTetP2", 2),
    ("MeshQuad1", 1): ("ElementQuad1", 3),
    ("MeshQuad1", 2): ("ElementQuad2", 5),
    ("MeshTri1", 1): ("ElementTriP1", 1),
    ("MeshTri1", 2): ("ElementTriP2", 2),
}


def element_for(mesh, order: int = 1):
    """The scalar Lagrange element and quadrature order for ``mesh`` (hex/tet/quad/tri) and ``order`` (1, 2)."""
    key = (type(mesh).__name__, int(order) if order in (1, 2) else order)
    if order not in (1, 2):
        raise ValueError(f"order = {order!r}: allowed 1 (linear) or 2 (quadratic)")
    if key not in _ELEMENTS:
        allowed = sorted({k[0] for k in _ELEMENTS})
        raise ValueError(f"mesh type {key[0]}: not supported; allowed {allowed}")
    name, intorder = _ELEMENTS[key]
    return getattr(skfem, name)(), intorder


@njit(cache=True, parallel=True)
def _element_stiffness(dN, dx, D, out):
    """K_e[(a,i),(b,k)] = sum_q dx dN[a,j] D[i,j,k,l] dN[b,l] for every element.

    dN (nel, nq, nbf, dim), dx (nel, nq), D (nel, nq, dim, dim, dim, dim), out (nel, nbf*dim, nbf*dim).
    """
    nel, nq, nbf, dim = dN.shape
    for e in prange(nel):
        G = np.empty((nbf, dim, dim, dim))
        for r in range(nbf * dim):
            for c in range(nbf * dim):
                out[e, r, c] = 0.0
        for q in range(nq):
            w = dx[e, q]
            for a in range(nbf):
                for i in range(dim):
                    for k in range(dim):
                        for l in range(dim):
                            s = 0.0
                            for j in range(dim):
                                s += dN[e, q, a, j] * D[e, q, i, j, k, l]
                            G[a, i, k, l] = w * s
            for a in range(nbf):
                for i in range(dim):
                    r = a * dim + i
                    for b in range(nbf):
                        for k in range(dim):
                            s = 0.0
                            for l in range(dim):
                                s += G[a, i, k, l] * dN[e, q, b, l]
                            out[e, r, b * dim + k] += s
    return out


@njit(cache=True, parallel=True)
def _element_stiffness_bbar(dN, g, c, dx, D, out):
    """B-bar version: K_e = sum_q dx Bbar[a,i,j,m] D[j,m,k,l] Bbar[b,n,k,l] with
    Bbar[a,i,j,k] = (delta_ij dN[a,k] + delta_ik dN[a,j]) / 2 + c delta_jk g[a,i]."""
    nel, nq, nbf, dim = dN.shape
    for e in prange(nel):
        Bq = np.empty((nbf, dim, dim, dim))
        G = np.empty((nbf, dim, dim, dim))
        for r in range(nbf * dim):
            for cc in range(nbf * dim):
                out[e, r, cc] = 0.0
        for q in range(nq):
            w = dx[e, q]
            for a in range(nbf):
                for i in range(dim):
                    for j in range(dim):
                        for k in range(dim):
                            v = 0.0
                            if i == j:
                                v += 0.5 * dN[e, q, a, k]
                            if i == k:
                                v += 0.5 * dN[e, q, a, j]
                            if j == k:
                                v += c * g[e, q, a, i]
                            Bq[a, i, j, k] = v
            for a in range(nbf):
                for i in range(dim):
                    for k in range(dim):
                        for l in range(dim):
                            s = 0.0
                            for j in range(dim):
                                for m in range(dim):
                                    s += Bq[a, i, j, m] * D[e, q, j, m, k, l]
                            G[a, i, k, l] = w * s
            for a in range(nbf):
                for i in range(dim):
                    r = a * dim + i
                    for b in range(nbf):
                        for n in range(dim):
                            s = 0.0
                            for k in range(dim):
                                for l in range(dim):
                                    s += G[a, i, k, l] * Bq[b, n, k, l]
                            out[e, r, b * dim + n] += s
    return out


def bbar_operator_reference(dN, g, c):
    """Bbar[e,q,a,i,j,k] (numpy, for tests) of the B-bar strain operator."""
    dim = dN.shape[-1]
    I = np.eye(dim)
    sym = 0.5 * (np.einsum("ij,eqak->eqaijk", I, dN) + np.einsum("ik,eqaj->eqaijk", I, dN))
    return sym + c * np.einsum("jk,eqai->eqaijk", I, g)


def element_stiffness_reference(dN, dx, D):
    """Plain numpy version of :func:`_element_stiffness` (for tests)."""
    K = np.einsum("eqaj,eqijkl,eqbl,eq->eaibk", dN, D, dN, dx)
    nel, nbf, dim = K.shape[0], K.shape[1], K.shape[2]
    return K.reshape(nel, nbf * dim, nbf * dim)


class Discretisation:
    """Vector displacement field on a scikit-fem mesh (3D: hex/tet; plane strain: quad/tri).

    Parameters
    ----------
    mesh : skfem.Mesh
        MeshHex1, MeshTet1 (3D) or MeshQuad1, MeshTri1 (plane strain, in the x-y plane).
    order : int
        1 (linear) or 2 (quadratic) Lagrange elements.
    volumetric : str
        "standard" (strain = sym grad u) or "bbar": the in-plane (2D) or full (3D) volumetric strain
        is replaced by its element-wise L2 projection onto constants (linear elements: mean dilatation,
        Q1/P0) or onto linear polynomials (quadratic elements: Q2/P1), which removes the volumetric
        locking of nearly incompressible plastic flow: eps_bar = eps + (theta_bar - theta) I_dim / dim
        (plane strain: eps_zz stays 0).

    Attributes
    ----------
    dim : int
        2 (plane strain) or 3.
    basis : skfem.CellBasis
        Scalar basis (shape functions, quadrature, scalar DOFs).
    dN : (nelems, nqp, nbf, dim) shape-function gradients [1/m]; dx : (nelems, nqp) weights [m^3 or m^2].
    edofs : (nelems, nbf * dim) vector DOFs of each element, local order (a, i) -> a * dim + i.
    n_points : int
        Number of quadrature points, nelems * nqp (element-major, see :mod:`femgran.state`).
    """

    def __init__(self, mesh, order: int = 1, volumetric: str = "standard"):
        from femgran.mesh import check_mesh

        if volumetric not in ("standard", "bbar"):
            raise ValueError(f"volumetric = {volumetric!r}: allowed 'standard' or 'bbar'")
        self.volumetric = volumetric

        element, intorder = element_for(mesh, order)
        self.mesh = mesh
        self.order = int(order)
        self.dim = mesh.p.shape[0]
        self.element = element
        self.intorder = intorder
        self.basis = skfem.Basis(mesh, element, intorder=intorder)
        check_mesh(mesh, self.basis)
        b = self.basis
        self.nelems = mesh.t.shape[1]
        self.nqp = b.X.shape[1]
        self.nbf = b.Nbfun
        dN = np.stack([b.basis[a][0].grad for a in range(self.nbf)])  # (nbf, dim, nel, nq)
        self.dN = np.ascontiguousarray(np.transpose(dN, (2, 3, 0, 1)))
        self.dx = np.ascontiguousarray(b.dx)
        self.n_points = self.nelems * self.nqp
        self.ndofs = self.dim * b.N
        self.n_displacement_dofs = self.ndofs  # a coupled discretisation appends its own fields' DOFs
        sd = b.element_dofs.T  # (nel, nbf) scalar dofs
        self.edofs = np.ascontiguousarray((self.dim * sd[:, :, None] + np.arange(self.dim)).reshape(self.nelems, -1))
        self._pattern = None
        self.g = self._bbar_correction() if volumetric == "bbar" else None
        self.c = 1.0 / self.dim

    def _bbar_correction(self) -> np.ndarray:
        """g[e,q,a,i] = (Pi dN_a,i)(q) - dN_a,i(q), Pi the element L2 projection onto P0 (order 1) or P1."""
        x = np.asarray(self.basis.global_coordinates())  # (dim, nel, nq)
        w = self.dx
        if self.order == 1:
            phi = np.ones((1,) + w.shape)
        else:
            xc = ((x * w).sum(axis=2) / w.sum(axis=1))[:, :, None]
            h = w.sum(axis=1) ** (1.0 / self.dim)  # element size, for conditioning
            phi = np.concatenate([np.ones((1,) + w.shape), (x - xc) / h[None, :, None]])
        M = np.einsum("men,pen,en->emp", phi, phi, w)
        Minv = np.linalg.inv(M)
        P = np.einsum("meq,emp,per,er->eqr", phi, Minv, phi, w)  # (nel, nq, nq)
        return np.einsum("eqr,erai->eqai", P, self.dN) - self.dN

    # ------------------------------------------------------------------ DOF helpers
    def vector_dofs(self, scalar_dofs, components=None) -> np.ndarray:
        """Vector DOFs of the given scalar DOFs, for ``components`` (default all), sorted."""
        comps = range(self.dim) if components is None else np.atleast_1d(components)
        s = np.asarray(scalar_dofs, dtype=np.int64).ravel()
        return np.sort(np.concatenate([self.dim * s + int(c) for c in comps])).astype(np.int64)

    def facet_scalar_dofs(self, facets) -> np.ndarray:
        """Scalar DOFs (vertex and higher-order) on the given facets."""
        return np.asarray(self.basis.get_dofs(np.asarray(facets)).flatten(), dtype=np.int64)

    def dof_coordinates(self) -> np.ndarray:
        """(ndofs_scalar, dim) coordinates of the scalar DOFs [m]."""
        return self.basis.doflocs.T

    def element_size(self) -> np.ndarray:
        """Size h of the element of each quadrature point, (element area or volume)^(1/dim) [m], (N,).

        The length the crack-band regularisation of a softening law divides by (linear elements; a
        quadratic element can hold a band narrower than itself, so its h is an upper bound)."""
        return np.repeat(self.dx.sum(axis=1) ** (1.0 / self.dim), self.nqp)

    def quadrature_points(self) -> np.ndarray:
        """(N, dim) global coordinates of the quadrature points [m], element-major."""
        x = np.asarray(self.basis.global_coordinates())  # (dim, nel, nq)
        return np.ascontiguousarray(x.reshape(self.dim, -1).T)

    # ------------------------------------------------------------------ kinematics and forces
    def gradient(self, u: np.ndarray) -> np.ndarray:
        """Displacement gradient at the points, (N, 3, 3) (zeros out of plane in 2D)."""
        ue = np.asarray(u)[self.edofs].reshape(self.nelems, self.nbf, self.dim)
        g = np.einsum("eai,eqaj->eqij", ue, self.dN, optimize=True).reshape(-1, self.dim, self.dim)
        if self.dim == 3:
            return g
        out = np.zeros((g.shape[0], 3, 3))
        out[:, :2, :2] = g
        return out

    def strain(self, u: np.ndarray) -> np.ndarray:
        """Small strain sym(grad u) (or its B-bar form) at the points, (N, 3, 3), tension positive
        (plane strain: eps_zz = 0)."""
        g = self.gradient(u)
        eps = 0.5 * (g + np.swapaxes(g, 1, 2))
        if self.g is not None:
            ue = np.asarray(u)[self.edofs].reshape(self.nelems, self.nbf, self.dim)
            dtheta = np.einsum("eai,eqai->eq", ue, self.g).ravel()
            idx = np.arange(self.dim)
            eps[:, idx, idx] += self.c * dtheta[:, None]
        return eps

    def point_inputs(self, du: np.ndarray) -> dict:
        """Extra inputs of the material's ``update`` for the increment ``du`` (none here; a coupled
        discretisation, :class:`femgran.gradient.GradientDiscretisation`, passes its field's increment)."""
        return {}

    def internal_force(self, stress: np.ndarray, tangent=None, u=None) -> np.ndarray:
        """f_int_(a,i) = sum_q dx sigma_ij dN_a,j, (ndofs,) [kN]; ``stress`` (N, 3, 3) kPa.

        ``tangent`` and ``u`` (the material's tangent and the full unknown vector) are what a coupled
        discretisation needs for the rows of its other fields; the displacement rows use neither."""
        d = self.dim
        s = np.asarray(stress)[:, :d, :d].reshape(self.nelems, self.nqp, d, d)
        fe = np.einsum("eqij,eqaj,eq->eai", s, self.dN, self.dx, optimize=True)
        if self.g is not None:
            tr = np.trace(s, axis1=2, axis2=3)
            fe = fe + self.c * np.einsum("eq,eqai,eq->eai", tr, self.g, self.dx, optimize=True)
        fe = fe.reshape(self.nelems, -1)
        return np.bincount(self.edofs.ravel(), weights=fe.ravel(), minlength=self.ndofs)

    def _ensure_pattern(self):
        if self._pattern is None:
            n = self.ndofs
            m = self.edofs.shape[1]
            rows = np.repeat(self.edofs, m, axis=1).ravel()
            cols = np.tile(self.edofs, (1, m)).ravel()
            keys = rows * n + cols
            uniq, inverse = np.unique(keys, return_inverse=True)
            r = uniq // n
            indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=n))])
            self._pattern = (indptr.astype(np.int64), (uniq % n).astype(np.int64), inverse.astype(np.int64))
        return self._pattern

    def element_matrices(self, tangent: np.ndarray) -> np.ndarray:
        """Element tangent matrices (nelems, nbf*dim, nbf*dim) from the point tangent (N, 3, 3, 3, 3)."""
        d = self.dim
        D = np.asarray(tangent, dtype=float)
        if D.shape != (self.n_points, 3, 3, 3, 3):
            raise ValueError(f"tangent: expected shape ({self.n_points}, 3, 3, 3, 3), got {D.shape}")
        if d == 2:
            D = D[:, :2, :2, :2, :2]
        D = np.ascontiguousarray(D).reshape(self.nelems, self.nqp, d, d, d, d)
        m = self.nbf * d
        out = np.empty((self.nelems, m, m))
        if self.g is not None:
            return _element_stiffness_bbar(self.dN, self.g, self.c, self.dx, D, out)
        return _element_stiffness(self.dN, self.dx, D, out)

    def stiffness(self, tangent: np.ndarray) -> sp.csr_matrix:
        """Global tangent K (ndofs, ndofs) CSR [kN/m] from the point tangent (N, 3, 3, 3, 3) kPa."""
        ke = self.element_matrices(tangent)
        indptr, indices, inverse = self._ensure_pattern()
        data = np.bincount(inverse, weights=ke.ravel(), minlength=indices.size)
        return sp.csr_matrix((data, indices, indptr), shape=(self.ndofs, self.ndofs))

    # ------------------------------------------------------------------ loads
    def traction_force(self, facets, traction) -> np.ndarray:
        """Consistent nodal forces of a traction on ``facets``, (ndofs,) [kN].

        ``traction``: a vector (dim,) [kPa] or a callable ``f(x) -> (dim, nfacets, nqp)`` of the facet
        quadrature coordinates ``x`` (dim, nfacets, nqp). Pressures: :meth:`pressure_force`.
        """
        fb = skfem.FacetBasis(self.mesh, self.element, facets=np.asarray(facets), intorder=self.intorder)
        x = np.asarray(fb.global_coordinates())
        t = traction(x) if callable(traction) else np.broadcast_to(np.asarray(traction, float)[:, None, None],
                                                                    (self.dim,) + x.shape[1:])
        return self._facet_load(fb, lambda w, c: t[c])

    def pressure_force(self, facets, pressure) -> np.ndarray:
        """Nodal forces of a pressure p [kPa] (compression positive, acting against the outward normal)."""
        fb = skfem.FacetBasis(self.mesh, self.element, facets=np.asarray(facets), intorder=self.intorder)
        x = np.asarray(fb.global_coordinates())
        p = pressure(x) if callable(pressure) else float(pressure)
        return self._facet_load(fb, lambda w, c: -p * w.n[c])

    def body_force(self, b) -> np.ndarray:
        """Nodal forces of a body force b (dim,) [kN/m^3] (e.g. (0, -gamma) in 2D with y up)."""
        b = np.asarray(b, dtype=float)
        if b.shape != (self.dim,):
            raise ValueError(f"body force: expected {self.dim} components, got shape {b.shape}")
        return self._cell_load(lambda c: b[c])

    def _facet_load(self, fb, density):
        out = np.zeros(self.ndofs)
        for c in range(self.dim):
            @skfem.LinearForm
            def form(v, w, c=c):
                return density(w, c) * v

            out[: self.n_displacement_dofs][c::self.dim] += form.assemble(fb)
        return out

    def _cell_load(self, density):
        out = np.zeros(self.ndofs)
        for c in range(self.dim):
            @skfem.LinearForm
            def form(v, w, c=c):
                return density(c) * v

            out[: self.n_displacement_dofs][c::self.dim] += form.assemble(self.basis)
        return out

