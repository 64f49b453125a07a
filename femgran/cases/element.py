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

from typing import ClassVar

import numpy as np

from femgran.cases.base import Drainage, Output, Problem, case, param, run
from femgran.cases.common import check_positive, check_steps, nodes_near, solver_options
from femgran.solver import Dirichlet

__all__ = ["Element", "element"]

_PATHS = ("triaxial",)


COLUMNS = {"eps_a": "axial strain -eps_zz [-], compression +", "eps_v": "volumetric strain -tr(eps) [-], compression +",
           "q_kPa": "mean lateral minus axial stress [kPa], compression +", "p_kPa": "mean stress -tr(sigma)/3 [kPa]",
           "gamma_xz": "engineering shear strain 2 eps_xz [-], tension +",
           "gamma_yz": "engineering shear strain 2 eps_yz [-], tension +"}


@case
class Element(Drainage):
    """Drained triaxial compression of one hexahedral element: the FE check of the element drivers (module docstring)."""

    name: ClassVar[str] = "element"
    plane_strain: ClassVar[bool] = False
    extend: ClassVar[str] = "axial_strain"  # may change on a resume: the loading goes on to the new end
    headline: ClassVar[str] = "peak_q_kPa"
    compare: ClassVar[tuple] = (("eps_a", "q_kPa"),)

    path: str = param("triaxial", "'triaxial' (the homogeneous path implemented through the FE solver)")
    p0_kPa: float = param(100.0, "cell pressure [kPa], > 0", flags=("--p0",))
    alpha_deg: float = param(0.0, "deposition angle from z [deg]", flags=("--alpha",))
    axial_strain: float = param(0.01, "final axial strain [-], compression +")
    steps: int = param(50, "equal strain steps (no regrowth)")

    def __post_init__(self):
        if self.path not in _PATHS:
            raise ValueError(f"path = {self.path!r}: allowed {_PATHS}")
        check_positive("p0_kPa", self.p0_kPa)
        check_positive("axial_strain", self.axial_strain)
        check_steps(self.steps)

    def build(self, mat) -> Problem:
        from femgran.gradient import discretisation_for
        from femgran.mesh import box

        p0, ea = float(self.p0_kPa), float(self.axial_strain)
        mesh = box(1.0, 1.0, 1.0, 1, 1, 1)
        d = discretisation_for(mat, mesh, 1)
        b = mesh.boundaries
        bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
        bcs = [Dirichlet(d.vector_dofs(bot, [2]), 0.0, name="bottom"),
               Dirichlet(d.vector_dofs(top, [2]), -ea, name="top"),
               Dirichlet(d.vector_dofs(nodes_near(d, (0, 0, 0)), [0, 1]), 0.0),
               Dirichlet(d.vector_dofs(nodes_near(d, (1, 0, 0)), [1]), 0.0)]
        lateral = np.concatenate([b[k] for k in ("left", "right", "front", "back")])
        w = d.dx.ravel()

        def observe(s):
            sig = np.average(s.points.stress, axis=0, weights=w)
            eps = np.average(np.asarray(s.points.state["strain"]), axis=0, weights=w)
            return {"eps_a": -eps[2, 2], "eps_v": -np.trace(eps), "q_kPa": 0.5 * (sig[0, 0] + sig[1, 1]) - sig[2, 2],
                    "p_kPa": -np.trace(sig) / 3.0, "gamma_xz": 2 * eps[0, 2], "gamma_yz": 2 * eps[1, 2]}

        return Problem(d, mat, bcs, f_fixed=d.pressure_force(lateral, p0), initial_stress=-p0 * np.eye(3),
                       observe=observe, columns=COLUMNS, fixed_steps=True, record={"mesh": "unit cube, one trilinear hexahedron"})

    def summarise(self, sol, problem) -> dict:
        return {"peak_q_kPa": float(np.nanmax(sol.history["q_kPa"]))}

    def plots(self, sol, problem, out_dir) -> None:
        from femgran.output import plot_history

        plot_history(sol.history, "eps_a", "q_kPa", out_dir / "q_vs_eps_a.png",
                     xlabel="axial strain [-] (compression +)", ylabel="q [kPa]", title="one element, triaxial")
        plot_history(sol.history, "eps_a", "eps_v", out_dir / "eps_v.png", xlabel="axial strain [-] (compression +)",
                     ylabel="volumetric strain [-] (compression +)", title="one element, triaxial")


def element(material=None, path: str = "triaxial", *, p0_kPa: float = 100.0, alpha_deg: float = 0.0,
            axial_strain: float = 0.01, steps: int = 50, tol: float | None = None, solver=None, out=None,
            progress: bool = False, write_every: int = 1, plots: bool = True, checkpoint_every: int = 0,
            resume: bool = False, **case_fields):
    """Drained triaxial compression of one hexahedral element.

    ``run(Element(...), material, solver=..., output=Output(out, progress, write_every, plots))`` with
    the arguments as in :class:`Element`; material: material object, CPAParameters, preset name,
    parameter file or None (CPA ``ottawa_c109`` with axes for ``alpha_deg``).
    solver : :class:`femgran.solver.SolverOptions` or a mapping of its fields (None: its defaults);
    ``tol`` replaces its tolerance when given.
    ``checkpoint_every`` (a checkpoint every N converged steps) and ``resume`` (continue the run in ``out``
    from its last checkpoint) are those of :func:`femgran.cases.base.run`; ``case_fields``: the case's other
    fields (e.g. ``drainage="undrained"``).

    Returns
    -------
    femgran.solver.Solution with history columns ``eps_a``, ``eps_v`` (compression +), ``q_kPa``
    (axial minus mean lateral stress, compression +), ``p_kPa`` and the shear strains ``gamma_xz``,
    ``gamma_yz`` (engineering, tension-positive convention).
    """
    case = Element(path, p0_kPa, float(alpha_deg), axial_strain, steps, **case_fields)
    return run(case, material, solver=solver_options(solver, tol=tol),
               output=Output(out, progress, write_every, plots, checkpoint_every), resume=resume)
