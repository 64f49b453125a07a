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

import numpy as np

from femgran.cases.common import (check_positive, keep_failed_points, material_record, newton_log,
                                  nodes_near, run_folder, solver_options)
from femgran.solver import Dirichlet, NewtonSolver
from material.factory import make_material

__all__ = ["triaxial", "PLATENS"]

PLATENS = ("rough", "smooth", "frictional")
WIDTH, HEIGHT = 0.05, 0.1


def _weighted_cv(values, weights):
    m = np.average(values, weights=weights)
    s = np.sqrt(np.average((values - m) ** 2, weights=weights))
    return float(s / abs(m)) if abs(m) > 0 else 0.0


def triaxial(material=None, p0_kPa: float = 100.0, alpha_deg: float = 0.0, platens: str = "rough", *,
             axial_strain: float = 0.05, steps: int = 25, mesh=None, resolution: int = 4, order: int = 1,
             out=None, progress: bool = False, linear_solver: str | None = None, write_every: int = 1,
             plots: bool = True, volumetric: str = "standard", friction: float = 0.3,
             interface_thickness_m: float = 0.001, tol: float | None = None, solver=None):
    """Drained triaxial compression of the 50 x 50 x 100 mm specimen between rigid platens.

    Parameters
    ----------
    material : material object, CPAParameters, preset name, or None (CPA ``ottawa_c109``).
    p0_kPa : cell pressure [kPa], > 0.
    alpha_deg : deposition angle between z and e2 [deg].
    platens : "rough", "smooth" or "frictional" (thin frictional layer, coefficient ``friction``).
    friction : platen friction coefficient mu (``platens="frictional"``), > 0.
    interface_thickness_m : thickness of the frictional layer [m].
    axial_strain : final axial strain, compression + [-]; steps : nominal number of load steps.
    mesh : None (structured hexahedra, ``resolution`` x ``resolution`` x 2 ``resolution``) or the path
        of a mesh file meshio reads (must fill the box [0, 0.05]^2 x [0, 0.1] m).
    order : 1 (linear) or 2 (quadratic) elements.
    volumetric : "standard" or "bbar" (hexahedra only; see :class:`femgran.assembly.Discretisation`).
    out : run folder (None: no files).
    solver : :class:`femgran.solver.SolverOptions` or a mapping of its fields (None: its defaults);
        ``tol`` and ``linear_solver`` (:data:`femgran.solver.LINEAR_SOLVERS`) replace those fields when given.

    Returns
    -------
    femgran.solver.Solution (``history``, ``out_dir``, ``u``, ``stress``, ``state``).
    """
    from femgran.assembly import Discretisation
    from femgran.mesh import box, load_mesh

    if platens not in PLATENS:
        raise ValueError(f"platens = {platens!r}: allowed {PLATENS}")
    p0 = check_positive("p0_kPa", p0_kPa)
    ea = check_positive("axial_strain", axial_strain)
    n = int(resolution)
    if platens == "frictional":
        mu = check_positive("friction", friction)
        ti = check_positive("interface_thickness_m", interface_thickness_m)
        if mesh is not None:
            raise ValueError("platens = 'frictional': only with the built-in mesh (mesh=None)")
        if not ti < HEIGHT / (4 * max(n, 1)):
            raise ValueError(f"interface_thickness_m = {ti}: must be < a quarter of the element height "
                             f"{HEIGHT / (2 * max(n, 1))} m")
    if mesh is None:
        if n < 1:
            raise ValueError(f"resolution = {resolution!r}: must be >= 1")
        if platens == "frictional":
            import skfem
            from femgran.mesh import name_box_boundaries

            z = np.concatenate([[0.0], np.linspace(ti, HEIGHT - ti, 2 * n + 1), [HEIGHT]])
            xs = np.linspace(0.0, WIDTH, n + 1)
            m = name_box_boundaries(skfem.MeshHex.init_tensor(xs, xs, z))
        else:
            m = box(WIDTH, WIDTH, HEIGHT, n, n, 2 * n)
    else:
        m = load_mesh(mesh)
        lo, hi = m.p.min(axis=1), m.p.max(axis=1)
        if m.dim() != 3 or not (np.allclose(lo, 0, atol=1e-6) and np.allclose(hi, [WIDTH, WIDTH, HEIGHT], atol=1e-6)):
            raise ValueError(f"mesh {mesh!r}: must be 3D and fill [0, {WIDTH}] x [0, {WIDTH}] x [0, {HEIGHT}] m; "
                             f"got bounds {lo} .. {hi}")
    mat = make_material(material, alpha_deg=alpha_deg, plane_strain=False)
    d = Discretisation(m, order, volumetric if type(m).__name__ == "MeshHex1" else "standard")
    if platens == "frictional":
        mat = _with_interface_layers(mat, d, mu, ti)
    b = m.boundaries
    bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
    bcs = [Dirichlet(d.vector_dofs(bot, [2]), 0.0, name="bottom"),
           Dirichlet(d.vector_dofs(top, [2]), -ea * HEIGHT, name="top")]
    if platens in ("rough", "frictional"):
        bcs += [Dirichlet(d.vector_dofs(bot, [0, 1]), 0.0), Dirichlet(d.vector_dofs(top, [0, 1]), 0.0)]
    else:
        bcs += [Dirichlet(d.vector_dofs(nodes_near(d, (0, 0, 0)), [0, 1]), 0.0),
                Dirichlet(d.vector_dofs(nodes_near(d, (WIDTH, 0, 0)), [1]), 0.0)]
    lateral = np.concatenate([b[k] for k in ("left", "right", "front", "back")])
    f_cell = d.pressure_force(lateral, p0)
    out_dir = run_folder(out)
    mat = keep_failed_points(mat, out_dir)
    newton = NewtonSolver(d, mat, bcs, f_fixed=f_cell, initial_stress=-p0 * np.eye(3),
                          options=solver_options(solver, linear_solver=linear_solver, tol=tol), log=newton_log(out_dir))
    area = WIDTH * WIDTH
    top_x, bot_x = d.vector_dofs(top, [0]), d.vector_dofs(bot, [0])
    w = d.dx.ravel()

    def observe(s):
        r = d.internal_force(s.points.stress) - s.external(s.t)
        fz = float(np.sum(r[bcs[1].dofs]))
        sig = s.points.stress
        eps = np.asarray(s.points.state["strain"])
        pm = -np.trace(sig, axis1=1, axis2=2) / 3
        dev = sig + pm[:, None, None] * np.eye(3)
        qm = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
        return {"eps_a": -float(np.mean(s.u[bcs[1].dofs])) / HEIGHT, "q_kPa": -fz / area - p0,
                "eps_v": -float(np.average(np.trace(eps, axis1=1, axis2=2), weights=w)),
                "top_shift_mm": 1e3 * float(np.mean(s.u[top_x]) - np.mean(s.u[bot_x])),
                "cv_q": _weighted_cv(qm, w), "cv_sigma_zz": _weighted_cv(sig[:, 2, 2], w)}

    writer = None
    params = {"case": "triaxial", "p0_kPa": p0, "alpha_deg": float(alpha_deg), "platens": platens,
              "axial_strain": ea, "steps": int(steps), "mesh": str(mesh) if mesh else f"box {n}x{n}x{2 * n} hex",
              "order": int(order), "solver": newton.options.to_dict(), "material": material_record(mat),
              "friction": float(friction) if platens == "frictional" else None,
              "interface_thickness_m": float(interface_thickness_m) if platens == "frictional" else None,
              "ndofs": d.ndofs}
    if out_dir is not None:
        from femgran.output import SeriesWriter, write_parameters

        write_parameters(out_dir / "parameters.json", params)
        writer = SeriesWriter(out_dir, d, name="triaxial", every=write_every)
    sol = newton.run(steps, writer=writer, progress=progress, observers=[observe])
    sol.extra.update(params=params, peak_q_kPa=float(np.nanmax(sol.history["q_kPa"])))
    if out_dir is not None and plots:
        _plots(sol, out_dir)
    return sol


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


def _plots(sol, out_dir: Path) -> None:
    from femgran.output import plot_field, plot_history, read_pvd

    plot_history(sol.history, "eps_a", "q_kPa", out_dir / "q_vs_eps_a.png", xlabel="axial strain (compression +)",
                 ylabel="q [kPa]", title="triaxial specimen")
    plot_history(sol.history, "eps_a", "cv_q", out_dir / "uniformity.png", xlabel="axial strain",
                 ylabel="CV of sqrt(3 J2)", title="stress non-uniformity")
    entries = read_pvd(out_dir / "triaxial.pvd")
    if entries:
        plot_field(entries[-1][1], "q_kPa", out_dir / "field_q.png")
