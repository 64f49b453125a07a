"""Strip footing on a layer of soil (plane strain, y vertical, upwards).

Domain: x in [-L, L], y in [-D, 0] (L = ``extent`` B, D = ``depth`` B), the footing of width B on the
surface, centred at x = 0. Sides: u_x = 0; base: u_x = u_y = 0. The rigid footing is pushed down in
displacement control (u_y = -settlement * t on the soil nodes under it); ``rough=True`` also fixes
their u_x (no slip), ``rough=False`` leaves it free (smooth footing).

Self weight: body force (0, -gamma) and the geostatic in-situ stress sigma_yy = -(gamma |y| + q_s),
sigma_xx = sigma_zz = K0 sigma_yy (tension +), with the surcharge q_s applied as a pressure on the
surface beside the footing (and in the in-situ stress under it). Material axes (CPA): the deposition axis
e2 is at ``alpha_deg`` from the vertical y in the x-y plane (:func:`material.factory.plane_strain_axes`).

History columns: ``settlement_m``, ``pressure_kPa`` (mean footing pressure = vertical platen force / B,
compression +). ``bearing_capacity_kPa``: the largest mean pressure reached (the limit load when the
curve has flattened; check ``history`` for the plateau). For a weightless von Mises soil this is
Prandtl's (2 + pi) c_u with c_u = sigma_y / sqrt(3) (plane strain). A sand as soft as the thesis's
(E = 6000 kPa) shows no plateau within small-strain settlements, so the result also carries
``pressure_at_10pct_kPa``, the pressure at a settlement of 0.1 B (the usual settlement criterion for
the bearing capacity of footings on sand when the curve has no peak), and ``plateau_ratio``, the
slope of the last tenth of the curve over the initial slope (about 0 at a true limit load, 1 for a
linear response).
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

from femgran.cases.base import Drainage, Output, Problem, case, param, run
from femgran.cases.common import check_positive, check_steps, solver_options
from femgran.solver import Dirichlet

__all__ = ["Footing", "footing", "footing_mesh", "prandtl_pressure"]


def prandtl_pressure(c_u_kPa: float) -> float:
    """Prandtl's limit pressure of a strip footing on a weightless Tresca soil, (2 + pi) c_u [kPa]."""
    return (2.0 + np.pi) * float(c_u_kPa)


def footing_mesh(width_m: float = 1.0, *, extent: float = 4.0, depth: float = 3.0, resolution: int = 4,
                 growth: float = 1.2, kind: str = "quad"):
    """Graded rectangle for the strip footing (y up, surface at y = 0, footing edges on nodes).

    ``resolution``: elements across the footing half-width; the cells grow by ``growth`` away from it.
    """
    from femgran.mesh import graded, rectangle

    B = check_positive("width_m", width_m)
    n = int(resolution)
    if n < 1:
        raise ValueError(f"resolution = {resolution!r}: must be >= 1")
    h = 0.5 * B / n
    inner = np.linspace(-B, B, 4 * n + 1)  # footing edges at +-B/2 are nodes
    L, D = extent * B, depth * B

    def n_out(length):  # number of growing cells so that the first is ~h
        if growth == 1.0:
            return max(1, int(round(length / h)))
        return max(1, int(np.ceil(np.log(1 + length * (growth - 1) / h) / np.log(growth))))

    right = graded(L - B, n_out(L - B), growth, start=B)[1:]
    x = np.concatenate([-right[::-1], inner, right])
    y = -graded(D, n_out(D), growth)[::-1]
    return rectangle(x, y, kind=kind)


COLUMNS = {"settlement_m": "mean settlement of the footing [m], downwards +",
           "pressure_kPa": "mean footing pressure: vertical platen force / B [kPa], compression +"}


@case
class Footing(Drainage):
    """Plane-strain rigid strip footing: load-settlement curve and bearing capacity (module docstring)."""

    name: ClassVar[str] = "footing"
    plane_strain: ClassVar[bool] = True
    extend: ClassVar[str] = "settlement_m"  # may change on a resume: the loading goes on to the new end
    headline: ClassVar[str] = "bearing_capacity_kPa"
    compare: ClassVar[tuple] = (("settlement_m", "pressure_kPa"),)

    width_m: float = param(1.0, "footing width B [m]", flags=("--width",))
    unit_weight: float = param(18.0, "unit weight gamma [kN/m3] (0: weightless)")
    surcharge_kPa: float = param(0.0, "surcharge q_s beside the footing [kPa]", flags=("--surcharge",))
    rough: bool = param(True, "rough footing (no slip); --smooth: free slip", negative="--smooth")
    alpha_deg: float = param(0.0, "bedding angle: deposition axis e2 from the vertical y [deg]", flags=("--alpha",))
    settlement_m: float | None = param(None, "final settlement [m] (default 0.1 B)", flags=("--settlement",))
    steps: int = param(40, "nominal number of load steps")
    K0: float = param(0.5, "earth pressure coefficient at rest of the in-situ stress")
    mesh: str | None = param(None, "2D mesh file (surface y = 0, footing centred at x = 0); default footing_mesh")
    resolution: int = param(3, "elements across the footing half-width (built-in mesh)")
    order: int = param(2, "element order, 1 or 2 (2: recommended for the nearly incompressible plastic flow)")
    extent: float = param(4.0, "half-width of the soil domain / B (built-in mesh)")
    depth: float = param(3.0, "depth of the soil domain / B (built-in mesh)")
    volumetric: str = param("bbar", "'bbar' (projected volumetric strain, no locking) or 'standard'")
    staged: bool = param(False, "stages: geostatic (K0 stress, gravity), the surcharge on the whole surface, "
                                "then the footing (default: one stage, the surcharge in the in-situ stress)")
    geostatic: str = param("k0", "staged: 'k0' (the in-situ stress K0 gamma |y| from the start) or 'gravity' "
                                 "(gravity switched on in an elastic stage, K0 = nu / (1 - nu), then the law)")

    def __post_init__(self):
        check_positive("width_m", self.width_m)
        check_positive("unit_weight", self.unit_weight, allow_zero=True)
        check_positive("surcharge_kPa", self.surcharge_kPa, allow_zero=True)
        check_positive("K0", self.K0)
        if self.settlement_m is not None:
            check_positive("settlement_m", self.settlement_m)
        check_steps(self.steps)
        if self.order not in (1, 2):
            raise ValueError(f"order = {self.order!r}: allowed 1 or 2")
        if self.volumetric not in ("bbar", "standard"):
            raise ValueError(f"volumetric = {self.volumetric!r}: allowed 'bbar' or 'standard'")
        if self.geostatic not in ("k0", "gravity"):
            raise ValueError(f"geostatic = {self.geostatic!r}: allowed 'k0' or 'gravity'")
        if self.geostatic == "gravity" and not self.staged:
            raise ValueError("geostatic = 'gravity' switches gravity on in a stage of its own: needs staged = true")
        if self.mesh is None and int(self.resolution) < 1:
            raise ValueError(f"resolution = {self.resolution!r}: must be >= 1")

    def build(self, mat) -> Problem:
        from femgran.gradient import discretisation_for
        from femgran.mesh import load_mesh

        B, gamma, qs, K0 = float(self.width_m), float(self.unit_weight), float(self.surcharge_kPa), float(self.K0)
        settle = 0.1 * B if self.settlement_m is None else float(self.settlement_m)
        m = (footing_mesh(B, extent=self.extent, depth=self.depth, resolution=self.resolution) if self.mesh is None
             else load_mesh(self.mesh))
        if m.dim() != 2:
            raise ValueError(f"mesh {self.mesh!r}: the footing is plane strain; a 2D mesh is required")
        if abs(m.p[1].max()) > 1e-9 * B or m.p[0].min() >= -B / 2 or m.p[0].max() <= B / 2:
            raise ValueError(f"mesh {self.mesh!r}: the surface must be y = 0 and the domain must contain |x| <= B/2")
        d = discretisation_for(mat, m, self.order, self.volumetric if type(m).__name__ == "MeshQuad1" else "standard")
        b = m.boundaries
        top_facets = b["top"]
        fx = m.p[0, m.facets[:, top_facets]].mean(axis=0)
        under = top_facets[np.abs(fx) < B / 2 - 1e-9 * B]
        beside = top_facets[np.abs(fx) > B / 2 - 1e-9 * B]
        foot = d.facet_scalar_dofs(under)
        if foot.size == 0:
            raise ValueError("footing: no mesh facet under the footing; refine the mesh")
        bcs = [Dirichlet(d.vector_dofs(d.facet_scalar_dofs(b["bottom"])), 0.0, name="base"),
               Dirichlet(d.vector_dofs(d.facet_scalar_dofs(np.concatenate([b["left"], b["right"]])), [0]), 0.0),
               Dirichlet(d.vector_dofs(foot, [1]), -settle, name="footing")]
        if self.rough:
            bcs.append(Dirichlet(d.vector_dofs(foot, [0]), 0.0))
        f_fixed = np.zeros(d.ndofs)
        if gamma > 0:
            f_fixed += d.body_force(np.array([0.0, -gamma]))
        if qs > 0 and beside.size:
            f_fixed += d.pressure_force(beside, qs)
        sigma0 = None
        in_situ_q = 0.0 if self.staged else qs  # staged: the surcharge is a load of its own stage
        if (gamma > 0 or in_situ_q > 0) and self.geostatic == "k0":
            sv = -(gamma * np.abs(d.quadrature_points()[:, 1]) + in_situ_q)
            sigma0 = np.zeros((d.n_points, 3, 3))
            sigma0[:, 1, 1] = sv
            sigma0[:, 0, 0] = sigma0[:, 2, 2] = K0 * sv
        fy_dofs = bcs[2].dofs
        stages = None
        if self.staged:
            from femgran.cases.base import Stage

            gravity = d.body_force(np.array([0.0, -gamma])) if gamma > 0 else np.zeros(d.ndofs)
            stages = [Stage("geostatic", bcs[:2], gravity, None, 1) if self.geostatic == "k0" else
                      Stage("gravity", bcs[:2], None, gravity, 1, elastic=True)]
            if qs > 0:
                stages.append(Stage("surcharge", bcs[:2], gravity, d.pressure_force(top_facets, qs), 5))
            stages.append(Stage("footing", bcs, f_fixed, None, int(self.steps)))

        def observe(s):  # the settlement of the footing from the start of the (footing) stage
            return {"settlement_m": -float(np.mean(s.u[fy_dofs] - s.u_start[fy_dofs])),
                    "pressure_kPa": -float(np.sum(s.reaction[fy_dofs])) / B}

        mesh_name = str(self.mesh) if self.mesh else \
            f"footing_mesh(resolution={self.resolution}, extent={self.extent}, depth={self.depth})"
        return Problem(d, mat, bcs, f_fixed=f_fixed, initial_stress=sigma0, observe=observe, columns=COLUMNS,
                       stages=stages,
                       record={"settlement_m": settle, "mesh": mesh_name, "volumetric": d.volumetric,
                               "vertical_axis": "y (up)"})

    def curve(self, sol, problem) -> dict:
        """The load-settlement curve of the footing (of its stage, from its start, in a staged run)."""
        h = sol.history
        if "stage" not in h:
            return {"settlement_m": h["settlement_m"], "pressure_kPa": h["pressure_kPa"]}
        last = h["stage"] == len(problem.stages) - 1
        first = max(int(np.argmax(last)) - 1, 0)  # the end of the stage before is the curve's origin
        keep = np.zeros(len(h), bool)
        keep[first:] = True
        origin = keep & ~last  # no settlement yet, and the footing carries the surcharge it replaces
        return {"settlement_m": np.where(origin, 0.0, h["settlement_m"])[keep],
                "pressure_kPa": np.where(origin, float(self.surcharge_kPa), h["pressure_kPa"])[keep]}

    def summarise(self, sol, problem) -> dict:
        return _capacity(self.curve(sol, problem), float(self.width_m))

    def plots(self, sol, problem, out_dir: Path) -> None:
        _plots(sol, out_dir, self.curve(sol, problem))


def footing(material=None, width_m: float = 1.0, unit_weight: float = 18.0, surcharge_kPa: float = 0.0,
            rough: bool = True, alpha_deg: float = 0.0, *, settlement_m: float | None = None, steps: int = 40,
            K0: float = 0.5, mesh=None, resolution: int = 3, order: int = 2, extent: float = 4.0,
            depth: float = 3.0, volumetric: str = "bbar", out=None, progress: bool = False,
            linear_solver: str | None = None, write_every: int = 1, plots: bool = True, tol: float | None = None,
            solver=None, checkpoint_every: int = 0, resume: bool = False, **case_fields):
    """Load-settlement response and bearing capacity of a rigid strip footing (plane strain).

    ``run(Footing(...), material, solver=..., output=Output(out, progress, write_every, plots))`` with
    the arguments as in :class:`Footing`; material: material object, CPAParameters, preset name,
    parameter file or None (CPA ``ottawa_c109``, :func:`material.factory.make_material`).
    solver : :class:`femgran.solver.SolverOptions` or a mapping of its fields (None: its defaults);
    ``tol`` (relative residual tolerance, out-of-balance force / reaction) and ``linear_solver`` replace
    the corresponding fields when given.
    ``checkpoint_every`` (a checkpoint every N converged steps) and ``resume`` (continue the run in ``out``
    from its last checkpoint) are those of :func:`femgran.cases.base.run`; ``case_fields``: the case's other
    fields (e.g. ``drainage="undrained"``).

    Returns
    -------
    femgran.solver.Solution with ``bearing_capacity_kPa``, ``pressure_at_10pct_kPa``, ``plateau_ratio``
    and history columns ``settlement_m``, ``pressure_kPa``.
    """
    case = Footing(width_m, unit_weight, surcharge_kPa, bool(rough), float(alpha_deg), settlement_m, steps, K0,
                   None if mesh is None else str(mesh), resolution, order, extent, depth, volumetric, **case_fields)
    return run(case, material, solver=solver_options(solver, linear_solver=linear_solver, tol=tol),
               output=Output(out, progress, write_every, plots, checkpoint_every), resume=resume)


def _capacity(history, B: float) -> dict:
    """Largest pressure, pressure at s = 0.1 B (NaN if not reached) and the plateau ratio of a curve."""
    s = np.asarray(history["settlement_m"], float)
    q = np.asarray(history["pressure_kPa"], float)
    at10 = float(np.interp(0.1 * B, s, q)) if s.size and s.max() >= 0.1 * B * (1 - 1e-9) else float("nan")
    ratio = float("nan")
    if s.size >= 3 and s[-1] > 0:
        k0 = max(1, int(np.searchsorted(s, 0.05 * s[-1])))  # initial slope over the first 5 %
        k1 = int(np.searchsorted(s, 0.9 * s[-1]))
        first = (q[k0] - q[0]) / max(s[k0] - s[0], 1e-300)
        last = (q[-1] - q[k1]) / max(s[-1] - s[k1], 1e-300) if k1 < s.size - 1 else float("nan")
        ratio = float(last / first) if first > 0 else float("nan")
    return {"bearing_capacity_kPa": float(np.nanmax(q)) if q.size else float("nan"),
            "pressure_at_10pct_kPa": at10, "plateau_ratio": ratio}


def _plots(sol, out_dir: Path, curve: dict) -> None:
    from femgran.output import plot_field, plot_history, read_pvd

    plot_history(curve, "settlement_m", "pressure_kPa", out_dir / "load_settlement.png",
                 xlabel="settlement [m]", ylabel="mean footing pressure [kPa]", title="strip footing")
    entries = read_pvd(out_dir / "footing.pvd")
    if entries:
        field = "eq_plastic_strain" if "eq_plastic_strain" in sol.state else "q_kPa"
        if "plastic_strain" in sol.state:
            plot_field(entries[-1][1], "plastic_strain", out_dir / "mechanism_plastic_strain.png", component="norm")
        else:
            plot_field(entries[-1][1], field, out_dir / "mechanism.png")
