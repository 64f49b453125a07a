"""Triaxial specimen with rigid platens (3D): the prism of the thesis, 50 x 50 x 100 mm.

Geometry and axes: x, y in [0, 0.05] m, z in [0, 0.1] m; z is the loading (vertical) axis and the
deposition axis e2 lies at ``alpha_deg`` from z in the x-z plane (:func:`material.anisotropy.axes_from_alpha`).

Loading: the isotropic cell pressure p0 acts on the four lateral faces and is the in-situ stress
(-p0 I); the bottom platen is fixed, the top platen moves down by ``axial_strain * 0.1 m``. Platen
interface:

* ``"rough"``: no slip, the soil nodes on both platens have u_x = u_y = 0 (the platens do not rotate);
* ``"smooth"``: free slip, only u_z is prescribed on the platens (plus the two point constraints that
  remove the rigid-body motion in the x-y plane), so for alpha = 0 the specimen deforms homogeneously
  and reproduces the element test;
* ``"frictional"`` (friction coefficient ``friction``): a thin-layer interface. A layer of thickness
  ``interface_thickness_m`` (default 1 mm) at each platen is made of a cohesionless Drucker-Prager
  material with friction angle atan(friction), no dilation, the soil's elastic constants; its outer
  face is bonded to the platen (as ``"rough"``), so the soil slides on the platen when the mobilised
  shear/normal stress ratio of the layer reaches about the friction coefficient (Coulomb friction,
  regularised by the layer's elasticity). Built-in mesh only.

History columns: ``eps_a`` (compression +), ``q_kPa`` = -F_z / A0 - p0 (axial platen force over the
initial area, minus the cell pressure), ``eps_v`` (volume change of the specimen from the mean point strain,
compression +), ``top_shift_mm`` (mean x displacement of the top face minus that of the bottom face: the distortion),
``cv_q`` (uniformity measure: volume-weighted coefficient of variation of the Mises stress sqrt(3 J2)
over the specimen; 0 for a uniform field), ``cv_sigma_zz`` (same for the axial stress).
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

from femgran.cases.base import Drainage, Output, Problem, case, param, run
from femgran.cases.common import check_positive, check_steps, nodes_near, solver_options
from femgran.solver import Dirichlet

__all__ = ["Triaxial", "triaxial", "PLATENS"]

PLATENS = ("rough", "smooth", "frictional")
WIDTH, HEIGHT = 0.05, 0.1


def _weighted_cv(values, weights):
    m = np.average(values, weights=weights)
    s = np.sqrt(np.average((values - m) ** 2, weights=weights))
    return float(s / abs(m)) if abs(m) > 0 else 0.0


COLUMNS = {"eps_a": "axial strain [-], compression +",
           "q_kPa": "axial platen force / initial area - p0 [kPa], compression +",
           "eps_v": "volumetric strain from the mean point strain [-], compression +",
           "top_shift_mm": "mean x displacement of the top face minus that of the bottom face [mm]",
           "cv_q": "volume-weighted coefficient of variation of sqrt(3 J2) over the specimen [-]",
           "cv_sigma_zz": "volume-weighted coefficient of variation of sigma_zz [-]"}


@case
class Triaxial(Drainage):
    """Drained triaxial compression of the 50 x 50 x 100 mm specimen between rigid platens (module docstring)."""

    name: ClassVar[str] = "triaxial"
    plane_strain: ClassVar[bool] = False
    extend: ClassVar[str] = "axial_strain"  # may change on a resume: the loading goes on to the new end
    headline: ClassVar[str] = "peak_q_kPa"
    compare: ClassVar[tuple] = (("eps_a", "q_kPa"), ("eps_a", "cv_q"))

    p0_kPa: float = param(100.0, "cell pressure [kPa], > 0", flags=("--p0",))
    alpha_deg: float = param(0.0, "deposition angle between z and e2 [deg]", flags=("--alpha",))
    platens: str = param("rough", "'rough', 'smooth' or 'frictional' (a thin frictional layer)")
    axial_strain: float = param(0.15, "final axial strain [-], compression +")
    steps: int = param(60, "nominal number of load steps")
    mesh: str | None = param(None, "mesh file filling [0, 0.05]^2 x [0, 0.1] m; default resolution^2 x 2 resolution hexahedra")
    resolution: int = param(4, "elements across the width (built-in mesh)")
    order: int = param(1, "element order, 1 or 2")
    volumetric: str = param("standard", "'standard' or 'bbar' (hexahedra)")
    friction: float = param(0.3, "platen friction coefficient (platens 'frictional')", flags=("--platen-friction",))
    interface_thickness_m: float = param(0.001, "thickness of the frictional layer [m]")
    consolidation_from_kPa: float | None = param(None, "a first stage consolidates the specimen isotropically from "
                                                       "this cell pressure to p0 [kPa] (default: it starts at p0)")

    def __post_init__(self):
        if self.platens not in PLATENS:
            raise ValueError(f"platens = {self.platens!r}: allowed {PLATENS}")
        check_positive("p0_kPa", self.p0_kPa)
        check_positive("axial_strain", self.axial_strain)
        check_steps(self.steps)
        if self.consolidation_from_kPa is not None:
            check_positive("consolidation_from_kPa", self.consolidation_from_kPa)
        n = int(self.resolution)
        if self.mesh is None and n < 1:
            raise ValueError(f"resolution = {self.resolution!r}: must be >= 1")
        if self.platens == "frictional":
            check_positive("friction", self.friction)
            ti = check_positive("interface_thickness_m", self.interface_thickness_m)
            if self.mesh is not None:
                raise ValueError("platens = 'frictional': only with the built-in mesh (mesh=None)")
            if not ti < HEIGHT / (4 * max(n, 1)):
                raise ValueError(f"interface_thickness_m = {ti}: must be < a quarter of the element height "
                                 f"{HEIGHT / (2 * max(n, 1))} m")

    def build(self, mat) -> Problem:
        from femgran.gradient import discretisation_for
        from femgran.mesh import box, load_mesh

        p0, ea, n = float(self.p0_kPa), float(self.axial_strain), int(self.resolution)
        ti = float(self.interface_thickness_m)
        if self.mesh is None and self.platens == "frictional":
            import skfem

            from femgran.mesh import name_box_boundaries

            z = np.concatenate([[0.0], np.linspace(ti, HEIGHT - ti, 2 * n + 1), [HEIGHT]])
            xs = np.linspace(0.0, WIDTH, n + 1)
            m = name_box_boundaries(skfem.MeshHex.init_tensor(xs, xs, z))
        elif self.mesh is None:
            m = box(WIDTH, WIDTH, HEIGHT, n, n, 2 * n)
        else:
            m = load_mesh(self.mesh)
            lo, hi = m.p.min(axis=1), m.p.max(axis=1)
            if m.dim() != 3 or not (np.allclose(lo, 0, atol=1e-6) and np.allclose(hi, [WIDTH, WIDTH, HEIGHT], atol=1e-6)):
                raise ValueError(f"mesh {self.mesh!r}: must be 3D and fill [0, {WIDTH}] x [0, {WIDTH}] x [0, {HEIGHT}] m; "
                                 f"got bounds {lo} .. {hi}")
        d = discretisation_for(mat, m, self.order, self.volumetric if type(m).__name__ == "MeshHex1" else "standard")
        soil = mat
        if self.platens == "frictional":
            mat = _with_interface_layers(mat, d, float(self.friction), ti)
        b = m.boundaries
        bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
        bcs = [Dirichlet(d.vector_dofs(bot, [2]), 0.0, name="bottom"),
               Dirichlet(d.vector_dofs(top, [2]), -ea * HEIGHT, name="top")]
        if self.platens in ("rough", "frictional"):
            bcs += [Dirichlet(d.vector_dofs(bot, [0, 1]), 0.0), Dirichlet(d.vector_dofs(top, [0, 1]), 0.0)]
        else:
            bcs += [Dirichlet(d.vector_dofs(nodes_near(d, (0, 0, 0)), [0, 1]), 0.0),
                    Dirichlet(d.vector_dofs(nodes_near(d, (WIDTH, 0, 0)), [1]), 0.0)]
        lateral = np.concatenate([b[k] for k in ("left", "right", "front", "back")])
        f_cell = d.pressure_force(lateral, p0)
        p_start, stages = p0, None
        if self.consolidation_from_kPa is not None:  # the cell pressure acts on the top too; the platen follows it
            from femgran.cases.base import Stage

            p_start = float(self.consolidation_from_kPa)
            cell = np.concatenate([lateral, b["top"]])
            stages = [Stage("consolidation", [bcs[0]] + bcs[2:], d.pressure_force(cell, p_start),
                            d.pressure_force(cell, p0 - p_start), 10),
                      Stage("shearing", bcs, f_cell, None, int(self.steps))]
        area = WIDTH * WIDTH
        top_x, bot_x = d.vector_dofs(top, [0]), d.vector_dofs(bot, [0])
        w = d.dx.ravel()

        def observe(s):
            fz = float(np.sum(s.reaction[bcs[1].dofs]))
            sig = s.points.stress
            eps = np.asarray(s.points.state["strain"])
            pm = -np.trace(sig, axis1=1, axis2=2) / 3
            dev = sig + pm[:, None, None] * np.eye(3)
            qm = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
            top_z = bcs[1].dofs  # the axial strain of the (shearing) stage, from its start
            return {"eps_a": -float(np.mean(s.u[top_z] - s.u_start[top_z])) / HEIGHT, "q_kPa": -fz / area - p0,
                    "eps_v": -float(np.average(np.trace(eps, axis1=1, axis2=2), weights=w)),
                    "top_shift_mm": 1e3 * float(np.mean(s.u[top_x]) - np.mean(s.u[bot_x])),
                    "cv_q": _weighted_cv(qm, w), "cv_sigma_zz": _weighted_cv(sig[:, 2, 2], w)}

        return Problem(d, mat, bcs, f_fixed=f_cell, initial_stress=-p_start * np.eye(3), observe=observe,
                       columns=COLUMNS, stages=stages,
                       record={"mesh": str(self.mesh) if self.mesh else f"box {n}x{n}x{2 * n} hex"},
                       data={"soil": soil})

    def summarise(self, sol, problem) -> dict:
        """Peak q, the non-uniformity, and the homogeneous element test of the same soil, alpha and p0
        (``material.driver.triaxial``) at the specimen's last axial strain: the platens' effect."""
        from material import driver

        h = sol.history
        out = {"peak_q_kPa": float(np.nanmax(h["q_kPa"])), "max_cv_q": float(np.nanmax(h["cv_q"])),
               "final_cv_q": float(h["cv_q"][-1]), "final_eps_a": float(h["eps_a"][-1])}
        if out["final_eps_a"] > 0:
            ref = driver.triaxial(problem.data["soil"], float(self.p0_kPa), float(self.alpha_deg),
                                  axial_strain=out["final_eps_a"], steps=max(len(h) - 1, 1), on_failure="return",
                                  drained=self.drainage == "drained")
            problem.data["element_test"] = ref
            q_el = float(np.interp(out["final_eps_a"], ref["eps_a"], ref["q_kPa"]))
            out.update(element_peak_q_kPa=float(np.nanmax(ref["q_kPa"])), element_final_q_kPa=q_el,
                       final_q_over_element=float(h["q_kPa"][-1] / q_el) if q_el else float("nan"))
        return out

    def plots(self, sol, problem, out_dir: Path) -> None:
        _plots(sol, out_dir, problem.data.get("element_test"))


def triaxial(material=None, p0_kPa: float = 100.0, alpha_deg: float = 0.0, platens: str = "rough", *,
             axial_strain: float = 0.15, steps: int = 60, mesh=None, resolution: int = 4, order: int = 1,
             out=None, progress: bool = False, linear_solver: str | None = None, write_every: int = 1,
             plots: bool = True, volumetric: str = "standard", friction: float = 0.3,
             interface_thickness_m: float = 0.001, tol: float | None = None, solver=None, checkpoint_every: int = 0,
             resume: bool = False, **case_fields):
    """Drained triaxial compression of the 50 x 50 x 100 mm specimen between rigid platens.

    ``run(Triaxial(...), material, solver=..., output=Output(out, progress, write_every, plots))`` with
    the arguments as in :class:`Triaxial`; material: material object, CPAParameters, preset name,
    parameter file or None (CPA ``ottawa_c109``, :func:`material.factory.make_material`).
    solver : :class:`femgran.solver.SolverOptions` or a mapping of its fields (None: its defaults);
    ``tol`` and ``linear_solver`` (:data:`femgran.solver.LINEAR_SOLVERS`) replace those fields when given.
    ``checkpoint_every`` (a checkpoint every N converged steps) and ``resume`` (continue the run in ``out``
    from its last checkpoint) are those of :func:`femgran.cases.base.run`; ``case_fields``: the case's other
    fields (e.g. ``drainage="undrained"``).

    Returns
    -------
    femgran.solver.Solution (``history``, ``out_dir``, ``u``, ``stress``, ``state``, ``peak_q_kPa``).
    """
    case = Triaxial(p0_kPa, float(alpha_deg), platens, axial_strain, steps, None if mesh is None else str(mesh),
                    resolution, order, volumetric, friction, interface_thickness_m,
                    **case_fields)
    return run(case, material, solver=solver_options(solver, linear_solver=linear_solver, tol=tol),
               output=Output(out, progress, write_every, plots, checkpoint_every), resume=resume)


def _with_interface_layers(mat, d, mu, ti):
    """Composite material: a frictional Drucker-Prager layer in the elements touching the platens."""
    from material import DruckerPrager
    from material.composite import Composite

    E = getattr(mat, "E", None) or getattr(getattr(mat, "params", None), "E", None)
    nu = getattr(mat, "nu", None) or getattr(getattr(mat, "params", None), "nu", None)
    if E is None or nu is None:
        raise ValueError("platens = 'frictional': the soil material must expose E and nu (or params.E, params.nu)")
    layer = DruckerPrager(E, nu, 0.0, float(np.degrees(np.arctan(mu))), 0.0, match="plane_strain")
    zc = np.asarray(d.quadrature_points())[:, 2].reshape(d.nelems, d.nqp).mean(axis=1)
    in_layer = (zc < ti) | (zc > HEIGHT - ti)
    assignment = np.repeat(in_layer.astype(np.int64), d.nqp)
    return Composite([mat, layer], assignment)


def _plots(sol, out_dir: Path, element_test=None) -> None:
    from femgran.output import plot_field, plot_history, read_pvd

    ref = None if element_test is None else ("element test (homogeneous)", element_test["eps_a"], element_test["q_kPa"])
    plot_history(sol.history, "eps_a", "q_kPa", out_dir / "q_vs_eps_a.png",
                 xlabel="axial strain [-] (compression +)", ylabel="q [kPa]", title="triaxial specimen", reference=ref)
    plot_history(sol.history, "eps_a", "cv_q", out_dir / "uniformity.png", xlabel="axial strain [-]",
                 ylabel="coefficient of variation of sqrt(3 J2) [-]", title="stress non-uniformity")
    entries = read_pvd(out_dir / "triaxial.pvd")
    if entries:
        plot_field(entries[-1][1], "q_kPa", out_dir / "field_q.png")
