"""Plane-strain biaxial compression with a small imperfection: localisation in a shear band.

Geometry and axes: x in [0, W], y in [0, H] (H = ``height_ratio`` W, 2 by default), y vertical (loading axis), plane strain in z.
The deposition axis e2 is at ``alpha_deg`` from y in the x-y plane. Rigid platens, smooth by default:
bottom u_y = 0 (and u_x = 0 at the corner (0, 0)), top u_y = -eps_a H t, free to slide; rough
(``platens="rough"``): u_x = 0 on both end faces as well. The confining pressure p0 acts on the two
vertical faces and is the in-situ stress (-p0 I). The mesh is structured, ``resolution`` elements across;
``element_aspect`` sets their height over their width, so their diagonals, along which a band in a
structured mesh of linear elements forms most easily, lie at atan(element_aspect) from the x axis (45 deg
for the default squares): run a second aspect to tell the band's own angle from the mesh's.

Imperfection: the left face is pushed inwards by ``imperfection * W`` in a smooth bump at mid-height
(a geometric imperfection: every point carries the same material, so any material object works), and
optionally (``weak_zone`` > 0, CPA materials) a material imperfection: the quadrature points in the
square of side ``weak_zone_size`` W centred on the left face at (0, ``weak_zone_height`` H) have eta0
lowered by that fraction. Placed off mid-height (default H/4) it selects one band out of the symmetric
pair a mid-height imperfection triggers (the usual trigger of a band that crosses the specimen). The
zone is a fixed region of the specimen, sampled at the quadrature points, so it converges with the mesh,
and it is the same region on every mesh whose element edges run along its sides (the shear-band study's
zone, W/6 by W/3 at the bottom-left corner, on 6, 12, 18, 24 ... elements across).

The band: measured in the increment of the deviatoric strain between the peak and the last converged
step (:func:`femgran.band.measure_band`, the bump's own neighbourhood left out): ``band_angle_deg``,
``band_thickness_m`` (full width at half maximum of the profile across it), ``band_centre_m``,
``band_contrast``, ``localised`` and ``band_angle_method`` (whether the angle is the fitted centre
line's) in the summary, the same of the conjugate arm (the best band of the
other family of orientations, :func:`femgran.band.measure_arms`) as ``conjugate_band_angle_deg`` ...
``conjugate_localised``, and ``band.png`` (the field with the band and its conjugate's centre line drawn,
the profile with its fit). ``band_angle_deg`` is the angle between the band and the
minor principal (lateral, x) stress direction, to compare with Coulomb 45 + phi/2, Roscoe 45 + psi/2 and Arthur
45 + (phi + psi)/4 (``reference_angles_deg``), phi and psi the peak mobilised friction and dilatancy
angles from the global response: sin phi = (s1 - s3) / (s1 + s3), sin psi = -(d eps_v) / (d eps_1 - d eps_3)
(compression +).

After the peak. With the thesis's law (zeta = 1) eta(kappa) rises monotonically to eta_f: the specimen
hardens to a plateau and no band forms. The material offers post-peak softening (``zeta > 1``,
``softening_slip`` > 0, ``residual_ratio``; :class:`material.CPAParameters`) regularised by the band
thickness t with the crack-band method: the solver passes each point's element size h and the slip
scale of the softening becomes ``softening_slip t / h``, so the energy dissipated per unit band area
does not depend on h (``CPAModel(..., regularise=False)`` gives the mesh-dependent reference).
``examples/fe_04_biaxial_meshes.py``
runs three meshes with and without the regularisation. ``params["regularisation"]`` records the
regularisation used.
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

from femgran.band import Band, deviatoric_intensity, measure_arms, measure_band, mobilised_angles
from femgran.cases.base import Drainage, Output, Problem, case, param, run
from femgran.cases.common import check_positive, check_steps, nodes_near, solver_options
from femgran.solver import Dirichlet, PathControl

__all__ = ["Biaxial", "biaxial", "band_angle"]


def band_angle(points: np.ndarray, weights: np.ndarray, width: float | None = None,
               exclude: tuple[float, float, float] | None = None,
               search: tuple[float, float] = (15.0, 80.0)) -> tuple[float, bool]:
    """Inclination of the dominant band of a field from the x axis [deg, 0..90] and whether it is one:
    :func:`femgran.band.measure_band` with ``width`` as the field's resolution (default: 1/20 of the
    cloud's extent)."""
    x = np.asarray(points, float)
    h = float(np.max(np.ptp(x, axis=0))) / 20.0 if width is None else float(width)
    band = measure_band(x, weights, element_size=h, exclude=exclude, search=search)
    return band.angle_deg, band.localised


COLUMNS = {"eps_a": "axial strain [-], compression +",
           "eps_lateral": "lateral strain from the mean face displacements [-], compression +",
           "eps_v": "volumetric strain eps_a + eps_lateral [-], compression +",
           "q_kPa": "s1 - s3: axial platen force / W - p0 [kPa], compression +"}


@case
class Biaxial(Drainage):
    """Plane-strain biaxial test of a specimen W x 2W with an imperfection: the shear band (module docstring)."""

    name: ClassVar[str] = "biaxial"
    plane_strain: ClassVar[bool] = True
    extend: ClassVar[str] = "axial_strain"  # may change on a resume: the loading goes on to the new end
    headline: ClassVar[str] = "band_angle_deg"
    compare: ClassVar[tuple] = (("eps_a", "q_kPa"),)

    p0_kPa: float = param(100.0, "confining pressure [kPa]", flags=("--p0",))
    alpha_deg: float = param(0.0, "deposition angle from the vertical y [deg]", flags=("--alpha",))
    width_m: float = param(0.05, "specimen width W [m] (height height_ratio W)", flags=("--width",))
    axial_strain: float = param(0.08, "final axial strain [-], compression +")
    steps: int = param(40, "nominal number of load steps")
    resolution: int = param(8, "elements across the width (height_ratio x as many over the height with element_aspect 1)")
    order: int = param(1, "element order, 1 or 2")
    imperfection: float = param(0.02, "inward bump of the left face at mid-height / W (0: perfect specimen)")
    volumetric: str = param("bbar", "'bbar' or 'standard'")
    weak_zone: float = param(0.0, "relative drop of eta0 near (0, weak_zone_height H) (CPA; 0: none)")
    weak_zone_height: float = param(0.25, "height of the weak zone's centre / H, in (0, 1)")
    platens: str = param("smooth", "'smooth' (end faces slide freely) or 'rough'")
    control_strain: float = param(0.0, "path following: 0 = the platen displacement drives the test; > 0 = the "
                                       "lateral expansion of the specimen (mean face displacements / W, extension +) "
                                       "drives it to this value and the platen follows, past a snap-back")
    weak_zone_size: float = param(0.2, "side of the weak zone's square / W, in (0, 1]")
    element_aspect: float = param(1.0, "height / width of the elements (1: squares, whose diagonals lie at 45 deg); "
                                       "the rows over the height are round(height_ratio resolution / element_aspect)")
    height_ratio: float = param(2.0, "specimen height H / width W, in [1, 6]")

    def __post_init__(self):
        check_positive("p0_kPa", self.p0_kPa)
        check_positive("width_m", self.width_m)
        check_positive("axial_strain", self.axial_strain)
        check_steps(self.steps)
        if not 0 <= check_positive("imperfection", self.imperfection, allow_zero=True) < 0.2:
            raise ValueError(f"imperfection = {self.imperfection!r}: allowed 0 <= imperfection < 0.2")
        if self.platens not in ("smooth", "rough"):
            raise ValueError(f"platens = {self.platens!r}: allowed 'smooth' or 'rough'")
        if int(self.resolution) < 2:
            raise ValueError(f"resolution = {self.resolution!r}: must be >= 2")
        if not 1.0 <= check_positive("height_ratio", self.height_ratio) <= 6.0:
            raise ValueError(f"height_ratio = {self.height_ratio!r}: allowed 1 <= height_ratio <= 6")
        if not 0.25 <= check_positive("element_aspect", self.element_aspect) <= 4.0:
            raise ValueError(f"element_aspect = {self.element_aspect!r}: allowed 0.25 <= element_aspect <= 4")
        if not 0 <= check_positive("weak_zone", self.weak_zone, allow_zero=True) < 0.5:
            raise ValueError(f"weak_zone = {self.weak_zone!r}: allowed 0 <= weak_zone < 0.5")
        check_positive("control_strain", self.control_strain, allow_zero=True)
        if self.weak_zone > 0 and not 0.0 < float(self.weak_zone_height) < 1.0:
            raise ValueError(f"weak_zone_height = {self.weak_zone_height!r}: allowed 0 < weak_zone_height < 1")
        if self.weak_zone > 0 and not 0.0 < float(self.weak_zone_size) <= 1.0:
            raise ValueError(f"weak_zone_size = {self.weak_zone_size!r}: allowed 0 < weak_zone_size <= 1")

    def build(self, mat) -> Problem:
        from femgran.gradient import discretisation_for
        from femgran.mesh import name_box_boundaries, rectangle

        p0, W, ea, imp, n = float(self.p0_kPa), float(self.width_m), float(self.axial_strain), \
            float(self.imperfection), int(self.resolution)
        H = float(self.height_ratio) * W
        rows = max(2, round(float(self.height_ratio) * n / float(self.element_aspect)))
        m = rectangle(np.linspace(0, W, n + 1), np.linspace(0, H, rows + 1))
        p = m.p.copy()
        p[0] += imp * W * (1 - p[0] / W) * np.exp(-(((p[1] - 0.5 * H) / (0.1 * H)) ** 2))
        m = name_box_boundaries(type(m)(p, m.t))
        # the bump moved the left face: name it by the original x = 0 nodes
        left_nodes = np.flatnonzero(np.abs(m.p[0] - imp * W * np.exp(-(((m.p[1] - 0.5 * H) / (0.1 * H)) ** 2)))
                                    < 1e-12 * W)
        left_facets = np.flatnonzero(np.all(np.isin(m.facets, left_nodes), axis=0))
        d = discretisation_for(mat, m, self.order, self.volumetric)
        if self.weak_zone > 0:
            mat = _with_weak_zone(mat, float(self.weak_zone), d, float(self.weak_zone_size), W,
                                  float(self.weak_zone_height) * H)
        b = m.boundaries
        bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
        right = d.facet_scalar_dofs(b["right"])
        left = d.facet_scalar_dofs(left_facets)
        if self.platens == "smooth":  # u_y only, and u_x = 0 at the corner (0, 0) against rigid-body drift
            bcs = [Dirichlet(d.vector_dofs(bot, [1]), 0.0, name="bottom"),
                   Dirichlet(d.vector_dofs(top, [1]), -ea * H, name="top"),
                   Dirichlet(d.vector_dofs(nodes_near(d, m.p[:, np.argmin(m.p[0] + m.p[1])]), [0]), 0.0)]
        else:  # rough: the platens hold the end faces' lateral displacement too
            bcs = [Dirichlet(d.vector_dofs(bot, [0, 1]), 0.0, name="bottom"),
                   Dirichlet(d.vector_dofs(top, [1]), -ea * H, name="top"),
                   Dirichlet(d.vector_dofs(top, [0]), 0.0)]
        f_cell = d.pressure_force(np.concatenate([left_facets, b["right"]]), p0)
        rx, lx = d.vector_dofs(right, [0]), d.vector_dofs(left, [0])
        peak = _PeakStrains(d.n_points)

        def observe(s):
            q = -float(np.sum(s.reaction[bcs[1].dofs])) / W - p0
            e_a = -float(np.mean(s.u[bcs[1].dofs])) / H
            e_l = -(float(np.mean(s.u[rx])) - float(np.mean(s.u[lx]))) / W
            peak.add(q, s.points.state["strain"])
            return {"eps_a": e_a, "eps_lateral": e_l, "eps_v": e_a + e_l, "q_kPa": q}

        control = None
        if self.control_strain > 0:  # the lateral expansion: mean u_x of the right face minus that of the left
            control = PathControl(np.concatenate([rx, lx]), np.concatenate([np.full(rx.size, 1.0 / rx.size),
                                                                            np.full(lx.size, -1.0 / lx.size)]),
                                  name="lateral_expansion_m")
        columns = COLUMNS if control is None else \
            {**COLUMNS, "lateral_expansion_m": "the controlled lateral expansion, mean u_x right - left face [m]"}
        return Problem(d, mat, bcs, f_fixed=f_cell, initial_stress=-p0 * np.eye(3), observe=observe, columns=columns,
                       record={"height_m": H, "vertical_axis": "y", "regularisation": _regularisation(mat),
                               "control": "lateral expansion" if control is not None else "platen displacement"},
                       data=peak.data, persist=_PeakStrains.KEYS, control=control,
                       control_end=float(self.control_strain) * W if control is not None else None)

    def summarise(self, sol, problem) -> dict:
        if len(sol.history) > 1:
            return _peak_and_band(sol, problem.data, problem.disc, float(self.p0_kPa), float(self.width_m),
                                  float(self.height_ratio) * float(self.width_m), float(self.imperfection))
        nan = float("nan")  # no converged step: nothing to measure
        return dict(**Band.none().summary(), **Band.none().summary("conjugate_"), peak_friction_deg=nan,
                    peak_dilatancy_deg=nan,
                    peak_q_kPa=nan, reference_angles_deg={"coulomb": nan, "roscoe": nan, "arthur": nan})

    def plots(self, sol, problem, out_dir: Path) -> None:
        _plots(sol, out_dir)
        if "band" in problem.data:
            band, points, intensity, conjugate = problem.data["band"]
            _band_plot(band, points, intensity, out_dir / "band.png", conjugate)


def biaxial(material=None, p0_kPa: float = 100.0, alpha_deg: float = 0.0, *, width_m: float = 0.05,
            axial_strain: float = 0.08, steps: int = 40, resolution: int = 8, order: int = 1,
            imperfection: float = 0.02, volumetric: str = "bbar", out=None, progress: bool = False,
            linear_solver: str | None = None, write_every: int = 1, plots: bool = True, tol: float | None = None,
            weak_zone: float = 0.0, weak_zone_height: float = 0.25,
            platens: str = "smooth", solver=None, checkpoint_every: int = 0, resume: bool = False, **case_fields):
    """Plane-strain biaxial test of a specimen W x 2W with a geometric imperfection.

    ``run(Biaxial(...), material, solver=..., output=Output(out, progress, write_every, plots))`` with
    the arguments as in :class:`Biaxial`; material: material object, CPAParameters, preset name,
    parameter file or None (CPA ``ottawa_c109``, :func:`material.factory.make_material`).
    solver : :class:`femgran.solver.SolverOptions` or a mapping of its fields (None: its defaults);
    ``tol`` (relative residual tolerance) and ``linear_solver`` replace those fields when given.
    ``checkpoint_every`` (a checkpoint every N converged steps) and ``resume`` (continue the run in ``out``
    from its last checkpoint) are those of :func:`femgran.cases.base.run`; ``case_fields``: the case's other
    fields (e.g. ``drainage="undrained"``).

    Returns
    -------
    femgran.solver.Solution with ``peak_q_kPa`` (the largest q) and ``peak_friction_deg`` (from it),
    ``peak_dilatancy_deg`` (at the first step within 1 % of the peak q), ``band_angle_deg`` (of the
    strain increment from that step to the end), ``reference_angles_deg`` (Coulomb, Roscoe, Arthur),
    ``localised``; history columns ``eps_a``, ``eps_v``, ``q_kPa`` (s1 - s3, compression +).
    """
    case = Biaxial(p0_kPa, float(alpha_deg), width_m, axial_strain, steps, resolution, order, imperfection,
                   volumetric, weak_zone, weak_zone_height, platens, **case_fields)
    return run(case, material, solver=solver_options(solver, linear_solver=linear_solver, tol=tol),
               output=Output(out, progress, write_every, plots, checkpoint_every), resume=resume)


class _PeakStrains:
    """The strain at the history rows whose q is within 1 % of the largest q so far (float32), kept in
    ``data`` under :data:`KEYS` so that the checkpoints carry it (a resumed run measures the band from the
    same peak): the band is measured from the first row within 1 % of the final peak, which every later
    running maximum keeps among these rows. Memory: a few rows after a sharp peak, more on a plateau.

    The strains live in a buffer of doubling capacity, and ``data["peak_strains"]`` is a view of its filled
    rows, replaced (never changed in place) at every step as :attr:`Problem.persist` requires: a row added
    on a plateau is written past the end of the previous view, so a long plateau costs amortised O(1) per
    step instead of a copy of every kept row."""

    KEYS = ("peak_rows", "peak_q", "peak_strains", "peak_count")

    def __init__(self, n_points: int):
        self.data = {"peak_rows": np.zeros(0, np.int64), "peak_q": np.zeros(0),
                     "peak_strains": np.zeros((0, n_points, 3, 3), np.float32), "peak_count": np.zeros(1, np.int64)}
        self._buffer = self.data["peak_strains"]

    def add(self, q: float, strain) -> None:
        d = self.data
        row = int(d["peak_count"][0])
        d["peak_count"] = np.array([row + 1])
        q_max = max(q, float(d["peak_q"].max()) if d["peak_q"].size else q)
        keep = d["peak_q"] >= 0.99 * q_max
        strains = d["peak_strains"]
        if strains.base is not self._buffer and strains is not self._buffer:  # restored from a checkpoint
            self._buffer = strains
        if not keep.all():  # a new maximum drops rows: compact into a new buffer
            self._buffer = np.ascontiguousarray(strains[keep])
            strains = self._buffer
        rows, qs, n = d["peak_rows"][keep], d["peak_q"][keep], int(keep.sum())
        if q >= 0.99 * q_max:
            if n == self._buffer.shape[0]:  # full: double the capacity (the old views stay as they are)
                grown = np.empty((max(2 * n, 4),) + self._buffer.shape[1:], np.float32)
                grown[:n] = strains[:n]
                self._buffer = grown
            self._buffer[n] = np.asarray(strain, np.float32)
            rows, qs, n = np.append(rows, row), np.append(qs, q), n + 1
        d["peak_rows"], d["peak_q"], d["peak_strains"] = rows, qs, self._buffer[:n]

    @staticmethod
    def strain_at(data: dict, row: int) -> np.ndarray:
        """The kept strain of history row ``row`` (N, 3, 3)."""
        where = np.flatnonzero(data["peak_rows"] == row)
        if not where.size:
            raise ValueError(f"the strain of history row {row} was not kept (rows kept: "
                             f"{data['peak_rows'].tolist()})")
        return data["peak_strains"][int(where[0])].astype(float)


def _peak_and_band(sol, data: dict, d, p0: float, W: float, H: float, imp: float) -> dict:
    """Peak friction and dilatancy from the global response, and the band of the strain increment after the peak."""
    h = sol.history
    xq = d.quadrature_points()
    q, e_a, e_l = h["q_kPa"], h["eps_a"], h["eps_lateral"]
    # peak friction from the largest deviator; the dilatancy and the start of the band's strain
    # increment at the first step within 1 % of it (on a plateau, where the dilatancy is still the peak's)
    q_max = float(np.nanmax(q))
    k = int(np.flatnonzero(q >= 0.99 * q_max)[0])
    k0, k1 = max(k - 1, 0), min(k + 1, len(q) - 1)
    phi, psi = mobilised_angles(q_max + p0, p0, e_a[k1] - e_a[k0], e_l[k1] - e_l[k0])
    dstrain = np.asarray(sol.state["strain"]) - _PeakStrains.strain_at(data, k)
    gamma = deviatoric_intensity(dstrain)
    h_el = float(d.element_size().max())
    exclude = (0.0, 0.5 * H, 0.15 * W + h_el) if imp > 0 else None  # the bump's own crush
    band, conjugate = measure_arms(xq, gamma, element_size=h_el, exclude=exclude)
    data["band"] = (band, xq, gamma, conjugate)  # for the band plot
    return dict(**band.summary(), **conjugate.summary("conjugate_"), peak_friction_deg=phi, peak_dilatancy_deg=psi,
                peak_q_kPa=q_max, reference_angles_deg={"coulomb": 45 + phi / 2, "roscoe": 45 + psi / 2, "arthur": 45 + (phi + psi) / 4})


def _with_weak_zone(mat, weak: float, d, size: float, W: float, y0: float):
    """A Composite: ``mat`` everywhere but at the quadrature points in the square of side ``size`` W centred at
    (0, y0), where eta0 is (1 - weak) x."""
    from material import CPAModel
    from material.composite import Composite

    if not isinstance(mat, CPAModel):
        raise ValueError(f"weak_zone = {weak!r}: needs a CPA material (CPAModel, parameters or a preset), "
                         f"got {type(mat).__name__}")
    x = d.quadrature_points()
    half = 0.5 * size * W
    inside = (x[:, 0] < half) & (np.abs(x[:, 1] - y0) < half)
    if not inside.any():
        raise ValueError(f"weak_zone_size = {size!r}: the weak zone ({2 * half:.3g} m across) holds no quadrature "
                         f"point of this mesh (element size {float(d.element_size().max()):.3g} m); allowed: a "
                         f"zone about one element across or more (a larger weak_zone_size or a finer resolution)")
    weak_mat = mat.replace(params=mat.params.replace(eta0=mat.params.eta0 * (1 - weak)))
    return Composite([mat, weak_mat], inside.astype(np.int64))


def _regularisation(mat) -> str:
    back = getattr(mat, "back_stress_length", None)
    if back is not None:
        modulus = getattr(mat, "back_stress_modulus", None)
        if modulus is None and hasattr(mat, "laws"):
            modulus = getattr(mat.laws[0], "back_stress_modulus", None)
        return f"gradient back stress: modulus H = {modulus:g} kPa, length l = {back:g} m"
    length = getattr(mat, "nonlocal_length", None)
    if length is not None:
        return f"implicit gradient: length l = {length:g} m"
    p = getattr(mat, "params", None)
    if p is None and hasattr(mat, "laws"):
        p = getattr(mat.laws[0], "params", None)
    if p is not None and getattr(p, "softening_slip", 0.0) > 0:
        return f"crack band: softening slip scale {p.softening_slip:g} m x t / h (t = {p.t:g} m)"
    return "none (no softening in the material)"


def _band_plot(band: Band, points, intensity, path: Path, conjugate: Band | None = None) -> None:
    """The strain increment after the peak with the measured band (centre line, +- half its thickness) and
    the centre line of its conjugate arm, and the profile across the band with its fit; PNG and CSV
    (:func:`material.plotting.save_figure`)."""
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    fig, (ax, pr) = plt.subplots(1, 2, figsize=(9, 5), gridspec_kw={"width_ratios": [1, 1.3]})
    sc = ax.scatter(points[:, 0], points[:, 1], c=intensity, s=6, cmap="viridis", label="Gauss points")
    fig.colorbar(sc, ax=ax, label="deviatoric strain increment after the peak")
    if np.isfinite(band.angle_deg):
        t, c = np.asarray(band.direction), np.asarray(band.centre)
        n, L = np.array([-t[1], t[0]]), float(np.ptp(points, axis=0).max())
        style = "-" if band.localised else ":"
        half = band.thickness_m if band.localised else 0.0
        for k, (off, label) in enumerate(((0.0, "band centre line"), (0.5, "half thickness"), (-0.5, None))):
            a, b = c + off * half * n - L * t, c + off * half * n + L * t
            ax.plot([a[0], b[0]], [a[1], b[1]], style, color="k" if k == 0 else "r", lw=1.2, label=label)
        if conjugate is not None and np.isfinite(conjugate.angle_deg):
            t2, c2 = np.asarray(conjugate.direction), np.asarray(conjugate.centre)
            a, b = c2 - L * t2, c2 + L * t2
            ax.plot([a[0], b[0]], [a[1], b[1]], "--" if conjugate.localised else ":", color="w", lw=1.2,
                    label=f"conjugate arm, {conjugate.angle_deg:.1f} deg"
                          + (" (line integral)" if conjugate.from_line_integral else "")
                          + (f", {1e3 * conjugate.thickness_m:.2f} mm" if conjugate.localised else ""))
        ax.set_xlim(points[:, 0].min(), points[:, 0].max())
        ax.set_ylim(points[:, 1].min(), points[:, 1].max())
        dist, mean, fit = band.profile
        pr.plot(1e3 * dist, mean, "o", ms=3, label="mean in strips")
        pr.plot(1e3 * dist, fit, "-", label=f"fit: thickness {1e3 * band.thickness_m:.2f} mm" if band.localised
                else f"fit: no band ({band.verdict})")
    zone = (f"no band: a zone {1e3 * band.peak_width_m:.1f} mm wide, of a section of {1e3 * band.section_m:.1f} mm"
            if band.verdict == "zone" else "no localised band")
    ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]",
           title=(f"band at {band.angle_deg:.1f} deg" if band.localised else zone)
           + ("" if band.angle_method in ("centre line", "none") else "\n" + band.angle_method))
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12))  # below: the field stays clear
    pr.set(xlabel="distance across the band [mm]", ylabel="deviatoric strain increment",
           title=f"contrast {band.contrast:.2f}")
    pr.legend(fontsize=8)
    pr.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)


def _plots(sol, out_dir: Path) -> None:
    from femgran.output import plot_field, plot_history, read_pvd

    plot_history(sol.history, "eps_a", "q_kPa", out_dir / "q_vs_eps_a.png", xlabel="axial strain [-] (compression +)",
                 ylabel="q = s1 - s3 [kPa]", title="plane-strain biaxial")
    plot_history(sol.history, "eps_a", "eps_v", out_dir / "eps_v.png", xlabel="axial strain [-] (compression +)",
                 ylabel="volumetric strain [-] (compression +)")
    entries = read_pvd(out_dir / "biaxial.pvd")
    if entries:
        plot_field(entries[-1][1], "q_kPa", out_dir / "field_q.png")
