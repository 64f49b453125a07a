"""Expansion of a cylindrical cavity in a thick-walled cylinder (plane strain): the case a newcomer reads first.

Geometry: the quarter annulus a <= r <= b, 0 <= theta <= 90 deg (x-y plane, z out of plane), with
symmetry on x = 0 and y = 0. The cavity wall moves outwards by ``expansion * a * t`` (t the load
factor), the outer surface keeps the pressure p0, which is also the in-situ stress (-p0 I).

History columns: ``expansion`` (u_a / a) and ``pressure_kPa`` (cavity pressure, the radial reaction
on the wall over its length a pi / 2). Closed forms to compare with (:func:`elastic_pressure`,
:func:`limit_pressure`): Lame's elastic cylinder, and the collapse pressure of a von Mises
(Tresca in plane strain) wall, p0 + 2 c_u ln(b / a) with c_u = sigma_y / sqrt(3) (Hill 1950, ch. V).

This module is the whole case: a dataclass of geometry and loads with ``build`` and ``summarise``;
:func:`femgran.cases.base.run` does the rest.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from femgran.cases.base import Drainage, Output, Problem, case, param, run
from femgran.cases.common import check_positive, check_steps, solver_options
from femgran.solver import Dirichlet

__all__ = ["Cavity", "cavity", "elastic_pressure", "limit_pressure"]


def elastic_pressure(u_a: float, a: float, b: float, E: float, nu: float) -> float:
    """Lame: the cavity pressure increment [kPa] of a linear elastic plane-strain cylinder a..b whose
    wall moves out by u_a [m], the outer pressure held."""
    lam, G = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    # u = A r + B / r with sigma_r(b) = 2 (lam + G) A - 2 G B / b^2 = 0 and u(a) = u_a
    A = u_a / (a + (lam + G) * b**2 / (G * a))
    B = (lam + G) * A * b**2 / G
    return -(2 * (lam + G) * A - 2 * G * B / a**2)


def limit_pressure(p0: float, a: float, b: float, yield_stress: float) -> float:
    """Collapse pressure [kPa] of a von Mises cylinder a..b in plane strain: p0 + 2 (sigma_y / sqrt 3) ln(b / a)."""
    return p0 + 2.0 * yield_stress / np.sqrt(3.0) * np.log(b / a)


@case
class Cavity(Drainage):
    """Cylindrical cavity expansion in a thick-walled cylinder, plane strain (module docstring)."""

    name: ClassVar[str] = "cavity"
    plane_strain: ClassVar[bool] = True
    extend: ClassVar[str] = "expansion"  # may change on a resume: the loading goes on to the new end
    headline: ClassVar[str] = "final_pressure_kPa"
    compare: ClassVar[tuple] = (("expansion", "pressure_kPa"),)

    inner_radius_m: float = param(0.1, "cavity radius a [m]")
    outer_radius_m: float = param(0.2, "outer radius b [m], > a")
    p0_kPa: float = param(100.0, "in-situ stress and outer pressure [kPa]", flags=("--p0",))
    expansion: float = param(0.05, "final wall displacement / a [-]")
    steps: int = param(20, "nominal number of load steps")
    alpha_deg: float = param(0.0, "deposition angle from y [deg] (CPA)", flags=("--alpha",))
    radial_elements: int = param(8, "elements across the wall (2 x as many around the quarter)")
    order: int = param(2, "element order, 1 or 2")

    def __post_init__(self):
        a = check_positive("inner_radius_m", self.inner_radius_m)
        if not check_positive("outer_radius_m", self.outer_radius_m) > a:
            raise ValueError(f"outer_radius_m = {self.outer_radius_m!r}: must be > inner_radius_m = {a!r}")
        check_positive("p0_kPa", self.p0_kPa, allow_zero=True)
        check_positive("expansion", self.expansion)
        check_steps(self.steps)
        check_steps(self.radial_elements, "radial_elements")
        if self.order not in (1, 2):
            raise ValueError(f"order = {self.order!r}: allowed 1 or 2")

    def build(self, mat) -> Problem:
        from femgran.gradient import discretisation_for
        from femgran.mesh import graded, rectangle

        a, b, p0 = float(self.inner_radius_m), float(self.outer_radius_m), float(self.p0_kPa)
        n = int(self.radial_elements)
        r = a + graded(b - a, n, 1.1)  # finer at the wall
        theta = np.linspace(0.0, 0.5 * np.pi, 2 * n + 1)
        polar = rectangle(r, theta)
        xy = np.vstack([polar.p[0] * np.cos(polar.p[1]), polar.p[0] * np.sin(polar.p[1])])
        named = polar.boundaries  # the (r, theta) rectangle's sides: the same facets after the mapping
        m = type(polar)(xy, polar.t).with_boundaries({"cavity": named["left"], "outer": named["right"],
                                                      "bottom": named["bottom"], "left": named["top"]})
        d = discretisation_for(mat, m, self.order, "bbar" if self.order == 2 else "standard")
        wall = d.facet_scalar_dofs(m.boundaries["cavity"])
        xw = d.dof_coordinates()[wall]
        angle = np.arctan2(xw[:, 1], xw[:, 0])
        cos, sin = np.cos(angle), np.sin(angle)  # the wall moves radially
        u_a = float(self.expansion) * a
        bcs = [Dirichlet(d.vector_dofs(wall, [0]), u_a * cos, name="cavity_x"),
               Dirichlet(d.vector_dofs(wall, [1]), u_a * sin),
               Dirichlet(d.vector_dofs(np.setdiff1d(d.facet_scalar_dofs(m.boundaries["bottom"]), wall), [1]), 0.0),
               Dirichlet(d.vector_dofs(np.setdiff1d(d.facet_scalar_dofs(m.boundaries["left"]), wall), [0]), 0.0)]
        f_out = d.pressure_force(m.boundaries["outer"], p0) if p0 > 0 else None
        wx, wy = bcs[0].dofs, bcs[1].dofs

        def observe(s):
            radial = float(np.sum(s.reaction[wx] * cos + s.reaction[wy] * sin))
            return {"expansion": float(np.mean(s.u[wx] * cos + s.u[wy] * sin)) / a,
                    "pressure_kPa": radial / (0.5 * np.pi * a)}

        return Problem(d, mat, bcs, f_fixed=f_out, initial_stress=-p0 * np.eye(3) if p0 > 0 else None,
                       observe=observe, columns={"expansion": "radial displacement of the wall / a [-], outwards +",
                                                 "pressure_kPa": "cavity pressure [kPa], compression +"},
                       record={"mesh": f"quarter annulus, {n} x {2 * n} elements"})

    def summarise(self, sol, problem) -> dict:
        return {"final_pressure_kPa": float(sol.history["pressure_kPa"][-1])}

    def plots(self, sol, problem, out_dir) -> None:
        from femgran.output import plot_history

        plot_history(sol.history, "expansion", "pressure_kPa", out_dir / "pressure_expansion.png",
                     xlabel="cavity expansion u_a / a [-]", ylabel="cavity pressure [kPa]", title="cylindrical cavity")


def cavity(material=None, *, out=None, solver=None, progress: bool = False, plots: bool = True,
           checkpoint_every: int = 0, resume: bool = False, **fields):
    """``run(Cavity(**fields), material, ...)``: the pressure-expansion curve of a cylindrical cavity."""
    return run(Cavity(**fields), material, solver=solver_options(solver),
               output=Output(out, progress, 1, plots, checkpoint_every), resume=resume)
