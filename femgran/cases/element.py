"""One finite element under homogeneous boundary conditions: the bridge between material.driver and the solver.

A unit cube, one trilinear hexahedron (8 Gauss points), z the loading axis:

* bottom face u_z = 0, top face u_z = -eps_a * t (axial compression), both free in x and y (zero shear
  traction), so eps_xz and eps_yz may develop for an inclined deposition axis;
* the four lateral faces carry the cell pressure p0 (total lateral stress -p0, zero shear traction);
* rigid-body motion: the corner (0,0,0) has u_x = u_y = 0, the corner (1,0,0) has u_y = 0.

The homogeneous deformation u = H x (H_zx = H_zy = H_yx = 0) satisfies all these conditions, so the FE
solution is homogeneous and reproduces ``material.driver.triaxial`` (lateral and shear stresses
prescribed, axial strain driven) point by point.
"""

from __future__ import annotations

import numpy as np

from femgran.cases.common import check_positive, nodes_near, solver_options
from femgran.solver import Dirichlet, NewtonSolver
from material.factory import make_material

__all__ = ["element"]

_PATHS = ("triaxial",)


def element(material=None, path: str = "triaxial", *, p0_kPa: float = 100.0, alpha_deg: float = 0.0,
            axial_strain: float = 0.01, steps: int = 50, tol: float | None = None, solver=None):
    """Drained triaxial compression of one hexahedral element.

    Parameters
    ----------
    material : material object, CPAParameters, preset name or None (default CPA ``ottawa_c109``
        with axes for ``alpha_deg``).
    path : "triaxial" (the only homogeneous path implemented through the FE solver).
    p0_kPa : cell pressure [kPa], > 0; alpha_deg : deposition angle from z [deg];
    axial_strain : final axial strain (compression +) [-]; steps : equal strain steps (no regrowth).
    solver : :class:`femgran.solver.SolverOptions` or a mapping of its fields (None: its defaults);
        ``tol`` replaces its tolerance when given.

    Returns
    -------
    femgran.solver.Solution with history columns ``eps_a``, ``eps_v`` (compression +), ``q_kPa``
    (axial minus mean lateral stress, compression +), ``p_kPa`` and the shear strains ``gamma_xz``,
    ``gamma_yz`` (engineering, tension-positive convention).
    """
    from femgran.mesh import box
    from femgran.assembly import Discretisation

    if path not in _PATHS:
        raise ValueError(f"path = {path!r}: allowed {_PATHS}")
    p0 = check_positive("p0_kPa", p0_kPa)
    ea = check_positive("axial_strain", axial_strain)
    mat = make_material(material, alpha_deg=alpha_deg, plane_strain=False)
    mesh = box(1.0, 1.0, 1.0, 1, 1, 1)
    d = Discretisation(mesh, 1)
    b = mesh.boundaries
    bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
    bcs = [Dirichlet(d.vector_dofs(bot, [2]), 0.0, name="bottom"),
           Dirichlet(d.vector_dofs(top, [2]), -ea, name="top"),
           Dirichlet(d.vector_dofs(nodes_near(d, (0, 0, 0)), [0, 1]), 0.0),
           Dirichlet(d.vector_dofs(nodes_near(d, (1, 0, 0)), [1]), 0.0)]
    lateral = np.concatenate([b[k] for k in ("left", "right", "front", "back")])
    f_cell = d.pressure_force(lateral, p0)
    newton = NewtonSolver(d, mat, bcs, f_fixed=f_cell, initial_stress=-p0 * np.eye(3),
                          options=solver_options(solver, tol=tol))

    def observe(s):
        sig = np.average(s.points.stress, axis=0, weights=d.dx.ravel())
        eps = np.average(np.asarray(s.points.state["strain"]), axis=0, weights=d.dx.ravel())
        return {"eps_a": -eps[2, 2], "eps_v": -np.trace(eps), "q_kPa": 0.5 * (sig[0, 0] + sig[1, 1]) - sig[2, 2],
                "p_kPa": -np.trace(sig) / 3.0, "gamma_xz": 2 * eps[0, 2], "gamma_yz": 2 * eps[1, 2]}

    sol = newton.run(steps, observers=[observe], fixed_steps=True)
    return sol
