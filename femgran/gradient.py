"""Implicit-gradient regularisation: the displacement and a nodal nonlocal field, solved as one Newton system.

A softening law without a length localises into one row of elements, so its post-peak response follows the
mesh. The implicit-gradient enhancement (Peerlings, de Borst, Brekelmans & de Vree 1996; for plasticity
Engelen, Geers & Baaijens 2003) adds a scalar field ebar, continuous over the mesh, that solves

    ebar - l^2 lap(ebar) = e      in the body,      grad(ebar) . n = 0   on its boundary,

with e the law's local measure of softening at the points (e.g. the equivalent plastic strain) and l the
material's length; the law softens with ebar (see :class:`material.GradientVonMises`), so the softening
spreads over a width set by l instead of by the element size.

:class:`GradientDiscretisation` is a :class:`femgran.assembly.Discretisation` whose unknown vector is
[u (the displacement DOFs, numbered as before); ebar (linear Lagrange nodal values)]. The ebar rows are the
weak form of the equation above scaled by s = E / l [kPa/m], the law's Young's modulus over the length, so
that they are forces as the displacement rows are (kN/m in plane strain, kN in 3D; the weak form itself is
kPa m^2 in plane strain): the solver's one tolerance and its line search's merit then weigh both fields alike
whatever the size of the problem, and a body twice as large with twice the length is the same problem at twice
the scale, its Newton iterates included (``tests/femgran/test_gradient.py``). With s = E the ebar rows carried
one more power of length: for the same error of strain and of ebar a node's ebar row was h / (1 m) times its
displacement row (now h / l), 1/500 on the shear-band study's elements (h = 2 mm), and the same run twice as
large took other line-search steps and cut-backs and another path after the peak (peak q 504.0 against
502.2 kPa on 6 elements across). The equation:

    r_ebar = s [ (M + l^2 D) ebar - int phi e ],      M = int phi phi,   D = int grad(phi) . grad(phi),

and the Newton matrix of the coupled problem is, with S = d sigma / d ebar, E = d e / d eps, c = d e / d ebar
from the material's :class:`material.base.CoupledTangent`,

    [ K_uu                    int B^T S phi     ]
    [ -s int phi E B          s (M + l^2 D - int phi c phi) ]

the exact derivative of the coupled residual (Newton keeps its quadratic convergence; tested against
finite differences). The ebar field has no Dirichlet condition. The solver (:mod:`femgran.solver`) is the
same as for the displacement alone: it passes :meth:`point_inputs` (the increment of ebar at the points)
to the material and the material's tangent back to :meth:`internal_force` and :meth:`stiffness`.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import scipy.sparse as sp

import skfem
from skfem.helpers import dot, grad

from femgran.assembly import Discretisation
from material.base import BackStressTangent, CoupledTangent
from material.tensors import from_mandel, to_mandel

__all__ = ["ALL_COMPONENTS", "PLANE_COMPONENTS", "PLANE_TOLERANCE", "BackStressDiscretisation",
           "GradientDiscretisation", "NONLOCAL_ELEMENTS", "OneDimensionalBand", "discretisation_for",
           "one_dimensional_band"]

#: The linear Lagrange element of ebar on each mesh type.
NONLOCAL_ELEMENTS = {"MeshHex1": "ElementHex1", "MeshTet1": "ElementTetP1", "MeshQuad1": "ElementQuad1",
                     "MeshTri1": "ElementTriP1"}


class OneDimensionalBand(NamedTuple):
    """The plastic zone of the over-nonlocal implicit gradient in one dimension (:func:`one_dimensional_band`)."""

    zone_width_m: float  #: full width of the zone where the plastic strain grows [m]
    fwhm_m: float        #: full width at half maximum of its growth profile [m]
    profile: Callable[[np.ndarray], np.ndarray]  #: the growth rate across the zone, 1 at its centre, 0 outside


def one_dimensional_band(length_m: float, over_nonlocal: float = 2.0) -> OneDimensionalBand:
    """The width of the localised plastic zone of the over-nonlocal implicit gradient, in closed form.

    A bar of uniform stress softens with kappa_hat = m ebar + (1 - m) kappa, ebar - l^2 ebar'' = kappa. In
    the zone where it loads, sigma_y(kappa_hat) is the bar's stress, so the rate of kappa_hat is the same at
    every point of the zone, whatever the softening law: d kappa_hat = C. Eliminating d kappa,

        d ebar + (m - 1) l^2 d ebar'' = C        inside:  d ebar = C + B cos(x / lam),  lam = l sqrt(m - 1),
        d ebar - l^2 d ebar'' = 0                outside: exponentials decaying over l,

    and at the zone's edges x = +-w/2 the plastic rate d kappa = (m d ebar - C) / (m - 1) vanishes and
    d ebar is smooth. These conditions give tan(w / (2 lam)) = -1 / sqrt(m - 1), so with
    theta = pi - arctan(1 / sqrt(m - 1)) in (pi/2, pi)

        w = 2 theta lam,      d kappa(x) / d kappa(0) = (cos theta - cos(x / lam)) / (cos theta - 1),

    and the profile's full width at half maximum is 2 lam arccos((1 + cos theta) / 2). For the default
    m = 2: w = 1.5 pi l = 4.71 l and the FWHM is 2.85 l; with m -> 1 both go to zero (the nonlocal variable
    alone lets the zone shrink, Jirasek & Rolshoven 2003), and for large m the zone approaches 2 pi lam.
    The width does not depend on the softening modulus, only on l and m: it is the band thickness the
    regularisation sets, against which the plane-strain bands of ``docs/regularisation.md`` are measured
    (the bar of ``tests/femgran/test_gradient.py`` checks it on the finite-element solution).
    """
    ell = float(length_m)
    m = float(over_nonlocal)
    if not (np.isfinite(ell) and ell > 0.0):
        raise ValueError(f"length_m = {length_m!r}: must be a finite length > 0 [m]")
    if not (np.isfinite(m) and m > 1.0):
        raise ValueError(f"over_nonlocal = {over_nonlocal!r}: must be > 1 (with 1 the zone has no width)")
    lam = ell * np.sqrt(m - 1.0)
    theta = np.pi - np.arctan(1.0 / np.sqrt(m - 1.0))
    c = np.cos(theta)

    def profile(x):
        x = np.abs(np.asarray(x, dtype=float))
        return np.where(x < theta * lam, (c - np.cos(np.minimum(x, theta * lam) / lam)) / (c - 1.0), 0.0)

    return OneDimensionalBand(2.0 * theta * lam, 2.0 * lam * float(np.arccos(0.5 * (1.0 + c))), profile)


def _add_nonlocal_fields(disc, length: float, scale: float, k: int):
    """Give ``disc`` (a displacement discretisation) k linear nodal fields on its mesh and quadrature: the
    validated ``length`` and ``scale``, ``nonlocal_basis``, ``nbe``, ``n_nonlocal_dofs``, ``ndofs``, ``phi``
    (nel, nq, nbe) and the Helmholtz rows s (M + l^2 D) of each field, numbered after the displacement
    field by field (``_helmholtz``); returns the scalar basis."""
    for name, v in (("length", length), ("scale", scale)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r}: must be > 0 (finite)")
    disc.length, disc.scale = float(length), float(scale)
    element = getattr(skfem, NONLOCAL_ELEMENTS[type(disc.mesh).__name__])()
    disc.nonlocal_basis = nb = skfem.Basis(disc.mesh, element, intorder=disc.intorder)
    if not np.array_equal(nb.X, disc.basis.X):
        raise RuntimeError("the nonlocal basis does not share the displacement's quadrature points")
    disc.nbe = nb.Nbfun
    disc.n_nonlocal_dofs = k * nb.N
    disc.ndofs = disc.n_displacement_dofs + k * nb.N
    disc.phi = np.ascontiguousarray(np.transpose(np.stack([np.asarray(nb.basis[a][0]) for a in range(disc.nbe)]),
                                                 (1, 2, 0)))  # (nel, nq, nbe)

    @skfem.BilinearForm
    def helmholtz(e, v, w):
        return e * v + disc.length**2 * dot(grad(e), grad(v))

    L = sp.kron(sp.identity(k), helmholtz.assemble(nb)).tocoo()
    n0 = disc.n_displacement_dofs
    disc._helmholtz = sp.csr_matrix((disc.scale * L.data, (L.row + n0, L.col + n0)), shape=(disc.ndofs,) * 2)
    disc._coupling = None
    return nb


class GradientDiscretisation(Discretisation):
    """Displacement (order 1 or 2) and a linear nodal nonlocal field ebar on the same mesh and quadrature.

    Parameters
    ----------
    mesh, order, volumetric : as :class:`femgran.assembly.Discretisation`
    length : float
        The internal length l [m], > 0 (the material's ``nonlocal_length``).
    scale : float
        The factor s [kPa/m] > 0 the ebar equation is multiplied by: the material's Young's modulus over the
        length, E / l, makes its rows forces (module docstring; :func:`discretisation_for`).

    Attributes
    ----------
    n_displacement_dofs : int
        The displacement DOFs come first, ``ndofs = n_displacement_dofs + n_nonlocal_dofs``.
    nonlocal_basis : skfem.CellBasis
        The scalar basis of ebar (its DOFs are the mesh vertices).
    """

    def __init__(self, mesh, order: int = 2, volumetric: str = "standard", *, length: float, scale: float):
        super().__init__(mesh, order, volumetric)
        nb = _add_nonlocal_fields(self, length, scale, 1)
        self.nonlocal_edofs = np.ascontiguousarray(nb.element_dofs.T + self.n_displacement_dofs)  # (nel, nbe)
        self._pattern = None

    # ------------------------------------------------------------------ the nonlocal field
    def nonlocal_values(self, u: np.ndarray) -> np.ndarray:
        """ebar (or its increment) at the points, (N,), from the full unknown vector ``u``."""
        ue = np.asarray(u)[self.nonlocal_edofs]  # (nel, nbe)
        return np.einsum("ea,eqa->eq", ue, self.phi).ravel()

    def nonlocal_field(self, u: np.ndarray) -> np.ndarray:
        """The nodal values of ebar at the mesh vertices, (n_vertices,)."""
        return np.asarray(u)[self.n_displacement_dofs:][: self.mesh.p.shape[1]]

    def point_inputs(self, du: np.ndarray) -> dict:
        """The material's extra input for the increment ``du``: ``{"d_nonlocal": (N,)}``."""
        return {"d_nonlocal": self.nonlocal_values(du)}

    # ------------------------------------------------------------------ residual and Newton matrix
    def _weighted_force(self, tensor):
        """f_(e,q,a,i) contributions sum_j T_ij dN_a,j + c tr(T) g_a,i (the transposed strain operator),
        (nel, nq, nbf, dim), of a point tensor field T (N, 3, 3) (no quadrature weight)."""
        d = self.dim
        T = np.asarray(tensor)[:, :d, :d].reshape(self.nelems, self.nqp, d, d)
        f = np.einsum("eqij,eqaj->eqai", T, self.dN, optimize=True)
        if self.g is not None:
            f = f + self.c * np.trace(T, axis1=2, axis2=3)[:, :, None, None] * self.g
        return f

    def internal_force(self, stress, tangent=None, u=None) -> np.ndarray:
        """The coupled residual without the external load: the displacement rows f_int(sigma) and the ebar
        rows s[(M + l^2 D) ebar - int phi e] from the full unknown ``u`` and the local measure in
        ``tangent`` (a :class:`material.base.CoupledTangent`). Without them (the reactions, which only the
        displacement rows carry) the ebar rows are zero."""
        f = super().internal_force(stress)
        if tangent is None or u is None:
            return f
        if not isinstance(tangent, CoupledTangent):
            raise TypeError("a GradientDiscretisation needs a gradient-enhanced material (update(..., d_nonlocal=) "
                            f"returning a CoupledTangent); got a tangent of type {type(tangent).__name__}")
        local = np.asarray(tangent.local).reshape(self.nelems, self.nqp)
        fe = np.einsum("eq,eqa,eq->ea", local, self.phi, self.dx, optimize=True)
        f -= self.scale * np.bincount(self.nonlocal_edofs.ravel(), weights=fe.ravel(), minlength=self.ndofs)
        return f + self._helmholtz @ np.asarray(u)

    def stiffness(self, tangent) -> sp.csr_matrix:
        """The Newton matrix of the coupled residual (module docstring) from the material's
        :class:`material.base.CoupledTangent`."""
        if not isinstance(tangent, CoupledTangent):
            raise TypeError("a GradientDiscretisation needs a gradient-enhanced material (update(..., d_nonlocal=) "
                            f"returning a CoupledTangent); got a tangent of type {type(tangent).__name__}")
        K = super().stiffness(tangent.dstress_dstrain)
        dx, phi = self.dx, self.phi
        k_ue = np.einsum("eqai,eqb,eq->eaib", self._weighted_force(tangent.dstress_dnonlocal), phi, dx, optimize=True)
        k_eu = -self.scale * np.einsum("eqb,eqai,eq->ebai", phi, self._weighted_force(tangent.dlocal_dstrain), dx,
                                       optimize=True)
        c = np.asarray(tangent.dlocal_dnonlocal).reshape(self.nelems, self.nqp)
        k_ee = -self.scale * np.einsum("eqa,eq,eqb,eq->eab", phi, c, phi, dx, optimize=True)
        nel = self.nelems
        rows, cols = self._coupling_pattern()
        data = np.concatenate([k_ue.reshape(nel, -1).ravel(), k_eu.reshape(nel, -1).ravel(), k_ee.ravel()])
        coupling = sp.csr_matrix((data, (rows, cols)), shape=(self.ndofs, self.ndofs))
        return (K + coupling + self._helmholtz).tocsr()

    def _coupling_pattern(self):
        """(rows, cols) of the element blocks u-ebar, ebar-u and ebar-ebar, in the order :meth:`stiffness`
        lays out their values (made once)."""
        if self._coupling is None:
            nu_e, ne = self.edofs.shape[1], self.nbe
            rows = np.concatenate([np.repeat(self.edofs, ne, axis=1).ravel(),
                                   np.repeat(self.nonlocal_edofs, nu_e, axis=1).ravel(),
                                   np.repeat(self.nonlocal_edofs, ne, axis=1).ravel()])
            cols = np.concatenate([np.tile(self.nonlocal_edofs, (1, nu_e)).ravel(),
                                   np.tile(self.edofs, (1, ne)).ravel(),
                                   np.tile(self.nonlocal_edofs, (1, ne)).ravel()])
            self._coupling = (rows, cols)
        return self._coupling


#: The Mandel basis (6, 3, 3): a symmetric tensor is sum_c v_c E_c, v its Mandel vector (material.tensors).
_MANDEL_BASIS = np.stack([from_mandel(row) for row in np.eye(6)])
#: The Mandel components of ebar_p a :class:`BackStressDiscretisation` carries: all six (xx, yy, zz, yz, xz,
#: xy), or in plane strain the four a law symmetric under z -> -z leaves non-zero.
ALL_COMPONENTS = (0, 1, 2, 3, 4, 5)
PLANE_COMPONENTS = (0, 1, 2, 5)
#: The out-of-plane shears of the plastic strain a plane-strain back stress accepts, relative to its largest
#: component: round-off (measured 1e-17 relative on the shear-band study's runs at alpha = 30 and 60 deg).
PLANE_TOLERANCE = 1e-10


class BackStressDiscretisation(Discretisation):
    """Displacement (order 1 or 2) and the nonlocal plastic strain tensor ebar_p of a law with a gradient
    back stress (:class:`material.CPAModel` with a ``back_stress_modulus``): linear nodal fields, the
    Mandel components of ebar_p, each solving

        ebar_p - l_b^2 lap(ebar_p) = eps_p      in the body,      grad(ebar_p) . n = 0   on its boundary.

    The unknown vector is [u; ebar_p's first component (nodal values); ...; its last]. The rows of component c
    are s [(M + l_b^2 D) ebar_c - int phi eps_p,c], as for the scalar field of
    :class:`GradientDiscretisation`, and the Newton matrix is the same block matrix with the material's
    :class:`material.base.BackStressTangent` contracted with the Mandel basis E_c: d sigma / d ebar_c =
    (d sigma / d ebar_p) : E_c, d eps_p,c / d eps = E_c : (d eps_p / d eps), and the coupling
    E_c : (d eps_p / d ebar_p) : E_d of the components at each point.

    **Components.** In 3D all six. In plane strain four, xx, yy, zz and xy (:data:`PLANE_COMPONENTS`): the
    out-of-plane shears of eps_p vanish where the law is symmetric under the reflection z -> -z, which
    the plane-strain cases make it (the material's e3 out of the plane, ``material.factory.plane_strain_axes``,
    and a rule of planes closed under that reflection). Measured with all six fields on the shear-band
    study's back-stress runs at alpha = 30 and 60 deg (to 8 %): |eps_p,xz|, |eps_p,yz| <= 1.2e-18 and
    |ebar_p,xz|, |ebar_p,yz| <= 1.9e-19, against |eps_p| = 0.22. Every residual checks that the law's
    plastic strain keeps them within :data:`PLANE_TOLERANCE` of its largest component and raises a
    ``ValueError`` saying what to do where it does not; ``components=ALL_COMPONENTS`` carries all six.
    The two fewer fields take a quarter of the unknowns and their couplings out of the linear system:
    ``python benchmarks/gradient.py --law cpa`` (idle machine) measured 1.79 times the crack band's time
    with four fields, 3.57 with six, with the rows scaled by E; scaled by E / l_b (:func:`discretisation_for`)
    1.61 and 2.29 in two runs on a busy machine, where the rows scaled by E gave 1.59 beside them; since
    the direct solver prefers the diagonal as pivot (``femgran.solver.DIAG_PIVOT_THRESHOLD``) 1.14, 1.64 and
    1.60 in three runs on a busy machine.
    """

    nonlocal_name = "nonlocal_plastic_strain"

    def __init__(self, mesh, order: int = 2, volumetric: str = "standard", *, length: float, scale: float,
                 components: tuple[int, ...] | None = None):
        super().__init__(mesh, order, volumetric)
        if components is None:
            components = PLANE_COMPONENTS if self.dim == 2 else ALL_COMPONENTS
        components = tuple(int(c) for c in components)
        if self.dim == 3 and components != ALL_COMPONENTS or not set(PLANE_COMPONENTS) <= set(components) \
                or not set(components) <= set(ALL_COMPONENTS) or len(set(components)) != len(components):
            raise ValueError(f"components = {components!r}: allowed {PLANE_COMPONENTS} (plane strain) or "
                             f"{ALL_COMPONENTS} (the Mandel indices of xx, yy, zz, yz, xz, xy)")
        self.components = components
        self.n_components = len(components)
        self._dropped = tuple(c for c in ALL_COMPONENTS if c not in components)
        self._basis = _MANDEL_BASIS[list(components)]
        nb = _add_nonlocal_fields(self, length, scale, self.n_components)
        # (nel, k, nbe): the DOFs of component c at the element's vertices
        component = np.arange(self.n_components)[None, :, None]
        self.nonlocal_edofs = np.ascontiguousarray(self.n_displacement_dofs + component * nb.N
                                                   + nb.element_dofs.T[:, None, :])

    # ------------------------------------------------------------------ the nonlocal field
    def _tensors(self, mandel: np.ndarray) -> np.ndarray:
        """(n, 3, 3) tensors from (n, k) values of the carried components (the others zero)."""
        full = np.zeros((mandel.shape[0], 6))
        full[:, list(self.components)] = mandel
        return from_mandel(full)

    def nonlocal_values(self, u: np.ndarray) -> np.ndarray:
        """ebar_p (or its increment) at the points, (N, 3, 3), from the full unknown vector ``u``."""
        ue = np.asarray(u)[self.nonlocal_edofs]  # (nel, k, nbe)
        return self._tensors(np.einsum("eca,eqa->eqc", ue, self.phi).reshape(-1, self.n_components))

    def nonlocal_field(self, u: np.ndarray) -> np.ndarray:
        """The nodal ebar_p at the mesh vertices, (n_vertices, 9) (the tensor's components, row by row)."""
        nb = self.nonlocal_basis.N
        mandel = np.asarray(u)[self.n_displacement_dofs:].reshape(self.n_components, nb).T
        return self._tensors(mandel[: self.mesh.p.shape[1]]).reshape(-1, 9)

    def point_inputs(self, du: np.ndarray) -> dict:
        """The material's extra input for the increment ``du``: ``{"d_nonlocal_plastic_strain": (N, 3, 3)}``."""
        return {"d_nonlocal_plastic_strain": self.nonlocal_values(du)}

    def adapt_unknowns(self, u: np.ndarray, what: str = "u") -> np.ndarray:
        """``u`` for this discretisation from an unknown vector of the same mesh that carried all six
        components (a checkpoint written before plane strain carried four): the dropped components'
        fields, which must be zero to :data:`PLANE_TOLERANCE`, are left out. A vector of this
        discretisation's length is returned as it is; another length raises ``ValueError``."""
        u = np.asarray(u)
        nb, n0 = self.nonlocal_basis.N, self.n_displacement_dofs
        if u.shape == (self.ndofs,):
            return u
        if u.shape != (n0 + 6 * nb,):
            raise ValueError(f"{what}: {u.shape[0]} unknowns, where this mesh and back stress have {self.ndofs} "
                             f"({n0} displacements and {self.n_components} fields of {nb}) or {n0 + 6 * nb} "
                             "(all six fields): the checkpoint belongs to another run")
        fields = u[n0:].reshape(6, nb)
        dropped, scale = self._dropped_size(fields.T)
        if dropped.max(initial=0.0) > PLANE_TOLERANCE * scale:
            raise ValueError(f"{what}: the components {self._dropped} of ebar_p, which this discretisation does "
                             f"not carry, reach {dropped.max():.3g} (of {scale:.3g}): resume with "
                             "components=ALL_COMPONENTS")
        return np.concatenate([u[:n0], fields[list(self.components)].ravel()])

    def _dropped_size(self, mandel: np.ndarray) -> tuple[np.ndarray, float]:
        """(the largest dropped component of each row of ``mandel`` (n, 6), the largest component of all): the
        check against :data:`PLANE_TOLERANCE` that the components this discretisation leaves out are zero."""
        scale = max(float(np.abs(mandel).max(initial=0.0)), 1e-300)
        if not self._dropped:
            return np.zeros(len(mandel)), scale
        return np.abs(mandel[:, list(self._dropped)]).max(axis=1), scale

    def _carried(self, plastic_strain) -> np.ndarray:
        """The Mandel components of the law's plastic strain (N, 3, 3) this discretisation carries, (N, k),
        after checking that the others stay zero (class docstring)."""
        full = to_mandel(np.asarray(plastic_strain))
        dropped, scale = self._dropped_size(full)
        if dropped.max(initial=0.0) > PLANE_TOLERANCE * scale:
            raise ValueError(
                f"the law's plastic strain has out-of-plane shears (Mandel components {self._dropped}: "
                f"{dropped.max():.3g} at point {int(np.argmax(dropped))}, against {scale:.3g}), which the "
                "plane-strain back stress does not carry: give the material its e3 out of the plane (material."
                "factory.plane_strain_axes) and a rule closed under the reflection z -> -z, or build the "
                "discretisation with components=ALL_COMPONENTS")
        return full[:, list(self.components)]

    # ------------------------------------------------------------------ residual and Newton matrix
    def _check(self, tangent):
        if not isinstance(tangent, BackStressTangent):
            raise TypeError("a BackStressDiscretisation needs a law with a gradient back stress (update(..., "
                            "d_nonlocal_plastic_strain=) returning a BackStressTangent); got a tangent of type "
                            f"{type(tangent).__name__}")

    def _weighted_forces(self, tensors):
        """:meth:`GradientDiscretisation._weighted_force` of k tensor fields (N, k, 3, 3): (nel, nq, k, nbf, dim)."""
        d = self.dim
        T = np.asarray(tensors)[:, :, :d, :d].reshape(self.nelems, self.nqp, self.n_components, d, d)
        f = np.einsum("eqcij,eqaj->eqcai", T, self.dN, optimize=True)
        if self.g is not None:
            f = f + self.c * np.trace(T, axis1=3, axis2=4)[:, :, :, None, None] * self.g[:, :, None]
        return f

    def internal_force(self, stress, tangent=None, u=None) -> np.ndarray:
        """The coupled residual without the external load: the displacement rows f_int(sigma) and the rows of
        each component of ebar_p (class docstring) from the full unknown ``u`` and the plastic strain in
        ``tangent``; without them (the reactions) those rows are zero."""
        f = super().internal_force(stress)
        if tangent is None or u is None:
            return f
        self._check(tangent)
        local = self._carried(tangent.local).reshape(self.nelems, self.nqp, self.n_components)
        fe = np.einsum("eqc,eqa,eq->eca", local, self.phi, self.dx, optimize=True)
        f -= self.scale * np.bincount(self.nonlocal_edofs.ravel(), weights=fe.ravel(), minlength=self.ndofs)
        return f + self._helmholtz @ np.asarray(u)

    def stiffness(self, tangent) -> sp.csr_matrix:
        """The Newton matrix of the coupled residual (class docstring) from the material's
        :class:`material.base.BackStressTangent`."""
        self._check(tangent)
        K = super().stiffness(tangent.dstress_dstrain)
        E = self._basis
        dx, phi, nel = self.dx, self.phi, self.nelems
        s_c = np.einsum("nijkl,ckl->ncij", tangent.dstress_dnonlocal, E, optimize=True)
        e_c = np.einsum("ckl,nklij->ncij", E, tangent.dlocal_dstrain, optimize=True)
        c_cd = np.einsum("ckl,nklij,dij->ncd", E, tangent.dlocal_dnonlocal, E, optimize=True)
        k_ue = np.einsum("eqcai,eqb,eq->eaicb", self._weighted_forces(s_c), phi, dx, optimize=True)
        k_eu = -self.scale * np.einsum("eqb,eqcai,eq->ecbai", phi, self._weighted_forces(e_c), dx, optimize=True)
        c = c_cd.reshape(nel, self.nqp, self.n_components, self.n_components)
        k_ee = -self.scale * np.einsum("eqa,eqcd,eqb,eq->ecadb", phi, c, phi, dx, optimize=True)
        rows, cols = self._coupling_pattern()
        data = np.concatenate([k_ue.reshape(nel, -1).ravel(), k_eu.reshape(nel, -1).ravel(),
                               k_ee.reshape(nel, -1).ravel()])
        coupling = sp.csr_matrix((data, (rows, cols)), shape=(self.ndofs, self.ndofs))
        return (K + coupling + self._helmholtz).tocsr()

    def _coupling_pattern(self):
        """(rows, cols) of the element blocks u-ebar_p, ebar_p-u and ebar_p-ebar_p in :meth:`stiffness`'s order."""
        if self._coupling is None:
            ne = self.nonlocal_edofs.reshape(self.nelems, -1)  # (nel, k nbe), component-major
            nu_e, nn_e = self.edofs.shape[1], ne.shape[1]
            rows = np.concatenate([np.repeat(self.edofs, nn_e, axis=1).ravel(), np.repeat(ne, nu_e, axis=1).ravel(),
                                   np.repeat(ne, nn_e, axis=1).ravel()])
            cols = np.concatenate([np.tile(ne, (1, nu_e)).ravel(), np.tile(self.edofs, (1, nn_e)).ravel(),
                                   np.tile(ne, (1, nn_e)).ravel()])
            self._coupling = (rows, cols)
        return self._coupling


def discretisation_for(material, mesh, order: int = 1, volumetric: str = "standard") -> Discretisation:
    """The discretisation ``material`` needs on ``mesh``: the displacement alone, or, for a gradient-enhanced
    law (one with a ``nonlocal_length``, :mod:`material.base`), the displacement and the nodal nonlocal field
    (:class:`GradientDiscretisation`, its equation scaled by the law's Young's modulus over the length, E / l,
    so that its rows are forces: module docstring), or for a law with a gradient back stress (a
    ``back_stress_length``) the displacement and the nonlocal plastic strain tensor
    (:class:`BackStressDiscretisation`, scaled the same way with its length l_b)."""
    back = getattr(material, "back_stress_length", None)
    if back is not None:
        return BackStressDiscretisation(mesh, order, volumetric, length=back, scale=float(material.E) / float(back))
    length = getattr(material, "nonlocal_length", None)
    if length is None:
        return Discretisation(mesh, order, volumetric)
    return GradientDiscretisation(mesh, order, volumetric, length=length, scale=float(material.E) / float(length))
