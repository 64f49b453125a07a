"""Figures of the thesis's chapter 3 from a sweep folder (PNG, matplotlib; glyphs with pyvista).

Numbering follows the thesis: 23-28 (one test: biaxial response and strain rotation), 29-30 (sample
size N1-N3), 31-34 (contact parameters T01-T07), 38 (fabric distribution with Kanatani fits of order
1-3), 39-41 (delta during biaxial and rotation), 42 (superquadric glyphs of n^Omega over n^e), 43 (MIL
against areal porosity), 44 (alpha_deps, alpha_sigma, alpha_Omega during rotation).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from material.table import Table, read_table


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _load(out: Path, test: str):
    f = out / test
    d = {"biaxial": read_table(f / "biaxial" / "history.csv"), "rotation": read_table(f / "rotation" / "history.csv")}
    for stage in ("biaxial", "rotation"):
        for m in ("mil", "areal_porosity"):
            p = f / stage / f"fabric_{m}.csv"
            if p.is_file():
                d[f"{stage}_{m}"] = read_table(p)
    return d


def _unwrap(a):
    """Unwrap angles defined modulo 180 deg; NaN entries (undefined directions) stay NaN."""
    a = np.asarray(a, float)
    out = np.full_like(a, np.nan)
    ok = np.isfinite(a)
    if ok.any():
        out[ok] = np.degrees(np.unwrap(np.radians(2 * a[ok]))) / 2
    return out


#: One sentence per figure (by its number): what it shows (the index of ``femgran figures``).
DESCRIPTIONS = {
    "fig23": "Deviatoric stress ratio q/p against the deviatoric strain in the DEM biaxial test.",
    "fig24": "Volumetric strain against the deviatoric strain in the DEM biaxial test.",
    "fig25": "Deviatoric strain components while the principal strain axes rotate at constant strain magnitude.",
    "fig26": "Their increments: a rotation of the axes at constant magnitude (eq. 3.10).",
    "fig27": "Stress components during the rotation of the strain axes.",
    "fig28": "Direction of the principal stress against the direction of the principal strain increment "
             "during the rotation (the dashed line: coaxial).",
    "fig29": "Stress ratio of samples of different size (N1-N3).",
    "fig30": "Volumetric strain of samples of different size (N1-N3).",
    "fig31": "Stress ratio for three contact friction angles (T01-T03).",
    "fig32": "Volumetric strain for three contact friction angles (T01-T03).",
    "fig33": "Stress ratio for different contact stiffnesses (T04-T07).",
    "fig34": "Volumetric strain for different contact stiffnesses (T04-T07).",
    "fig38": "Directional fabric (areal porosity and mean intercept length) at the end of the biaxial stage, with "
             "Kanatani fits of order 1-3.",
    "fig39": "Angle delta between the fabric tensor and the strain deviator during the biaxial stage.",
    "fig40": "Angle delta between the fabric tensor and the strain deviator during the rotation of the strain axes.",
    "fig41": "Delta during the rotation for pairs of contact parameters.",
    "fig42": "Glyphs of the fabric tensor over the strain deviator at six stages of the rotation.",
    "fig43": "Delta measured with the mean intercept length and with the areal porosity.",
    "fig44": "Directions of the strain, strain increment, stress and fabric during the rotation.",
}


def sweep_figures(out, tests, figdir=None) -> list[Path]:
    """The chapter-3 figures of the Table 4 runs ``out/<test>`` into ``figdir`` (default ``out/figures``):
    each PNG with the CSV of what it draws (:func:`material.plotting.save_figure`)."""
    from material.plotting import save_figure

    plt = _plt()
    out = Path(out)
    figdir = out / "figures" if figdir is None else Path(figdir)
    figdir.mkdir(parents=True, exist_ok=True)
    data = {t: _load(out, t) for t in tests}
    main = "T06" if "T06" in data else tests[0]
    written = []

    def save(fig, name):
        fig.tight_layout()
        written.extend(save_figure(fig, figdir / name))

    b, r = data[main]["biaxial"], data[main]["rotation"]
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(100 * b["eps_q"], b["q_kPa"] / b["p_kPa"])
    ax.set(xlabel="eps_q [%]", ylabel="q / p [-]", title=f"Fig. 23 ({main}): deviatoric stress ratio")
    save(fig, "fig23_stress_ratio.png")
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(100 * b["eps_q"], 100 * b["eps_v"])
    ax.set(xlabel="eps_q [%]", ylabel="eps_v [%] (compression +)", title=f"Fig. 24 ({main}): volumetric strain")
    save(fig, "fig24_volumetric.png")
    a = _unwrap(r["alpha_target_deg"])
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(a, 0.5 * (r["eps_xx"] - r["eps_yy"]), label="(eps_xx - eps_yy)/2")
    ax.plot(a, r["eps_xy"], label="eps_xy")
    ax.set(xlabel="alpha_eps [deg]", ylabel="deviatoric strain (tension +)", title="Fig. 25: strain components")
    ax.legend()
    save(fig, "fig25_strain_components.png")
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(a[1:], np.diff(0.5 * (r["eps_xx"] - r["eps_yy"])), label="d(eps_xx - eps_yy)/2")
    ax.plot(a[1:], np.diff(r["eps_xy"]), label="d eps_xy")
    ax.set(xlabel="alpha_eps [deg]", ylabel="strain increment", title="Fig. 26: strain increments")
    ax.legend()
    save(fig, "fig26_strain_increments.png")
    fig, ax = plt.subplots(figsize=(5, 4))
    for c in ("sigma_xx_kPa", "sigma_yy_kPa", "sigma_xy_kPa"):
        ax.plot(a, -r[c], label=c.replace("_kPa", "") + " (comp. +)")
    ax.set(xlabel="alpha_eps [deg]", ylabel="stress [kPa]", title="Fig. 27: stress components")
    ax.legend()
    save(fig, "fig27_stress_components.png")
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(_unwrap(r["alpha_deps_deg"][1:]), _unwrap(r["alpha_sigma_deg"][1:]), ".")
    lim = [np.nanmin(_unwrap(r["alpha_deps_deg"][1:])), np.nanmax(_unwrap(r["alpha_deps_deg"][1:]))]
    ax.plot(lim, lim, "k--", lw=0.8, label="coaxial")
    ax.set(xlabel="alpha_deps [deg]", ylabel="alpha_sigma [deg]", title="Fig. 28: stress vs strain-increment direction")
    ax.legend()
    save(fig, "fig28_alpha_sigma_vs_alpha_deps.png")

    for number, group, ylabel, column in ((29, ("N1", "N2", "N3"), "q / p", None), (30, ("N1", "N2", "N3"), "eps_v [%]", "eps_v"),
                                          (31, ("T01", "T02", "T03"), "q / p", None), (32, ("T01", "T02", "T03"), "eps_v [%]", "eps_v"),
                                          (33, ("T04", "T05", "T06", "T07"), "q / p", None), (34, ("T04", "T05", "T06", "T07"), "eps_v [%]", "eps_v")):
        present = [t for t in group if t in data]
        if not present:
            continue
        fig, ax = plt.subplots(figsize=(5, 4))
        for t in present:
            h = data[t]["biaxial"]
            y = h["q_kPa"] / h["p_kPa"] if column is None else 100 * h[column]
            ax.plot(100 * h["eps_q"], y, label=t)
        ax.set(xlabel="eps_q [%]", ylabel=ylabel, title=f"Fig. {number}")
        ax.legend()
        save(fig, f"fig{number}_{'_'.join(present)}.png")

    # Fig. 38: distribution of n (and MIL) at the end of the biaxial stage with fits of order 1-3
    from .experiments import load_run
    from .stereology import fabric

    run = load_run(out / main / "biaxial")
    fig, axes = plt.subplots(1, 2, figsize=(9, 4), subplot_kw={"projection": "polar"})
    for ax, measure in zip(axes, ("areal_porosity", "mil")):
        fab = fabric(run.final, measure=measure, grid_spacing_m=1e-5)
        th = np.radians(np.concatenate([fab.directions_deg, fab.directions_deg + 180]))
        ax.plot(th, np.concatenate([fab.values, fab.values]), "o", ms=3, label="measured")
        fine = np.linspace(0, 360, 361)
        for order in (1, 2, 3):
            ax.plot(np.radians(fine), fab.fit(order)(fine), label=f"order {order}")
        ax.set_title(f"Fig. 38 ({main}): {measure}", fontsize=9)
        ax.set_rlim(0.97 * fab.values.min(), 1.02 * fab.values.max())
    axes[1].legend(fontsize=7, loc="lower right")
    save(fig, "fig38_fabric_distribution.png")

    for number, stage, x in ((39, "biaxial", "eps_q"), (40, "rotation", "alpha_eps_deg")):
        fig, ax = plt.subplots(figsize=(5, 4))
        for t in data:
            f = data[t].get(f"{stage}_mil")
            if f is not None:
                xx = 100 * f[x] if x == "eps_q" else _unwrap(f[x])
                ax.plot(xx, f["delta_deg"], label=f"{t} ({np.nanmean(f['delta_deg']):.1f}+-{np.nanstd(f['delta_deg']):.1f})")
        ax.set(xlabel="eps_q [%]" if x == "eps_q" else "alpha_eps [deg]", ylabel="delta [deg] (MIL)",
               title=f"Fig. {number}: delta during {stage}")
        ax.legend(fontsize=7)
        save(fig, f"fig{number}_delta_{stage}.png")

    pairs = [p for p in (("T05", "T06"), ("T03", "T06"), ("T05", "T07")) if p[0] in data and p[1] in data]
    if pairs:
        fig, axes = plt.subplots(len(pairs), 1, figsize=(5, 3 * len(pairs)), squeeze=False)
        for ax, pair in zip(axes[:, 0], pairs):
            for t in pair:
                f = data[t]["rotation_mil"]
                ax.plot(_unwrap(f["alpha_eps_deg"]), f["delta_deg"], label=t)
            ax.set(xlabel="alpha_eps [deg]", ylabel="delta [deg]")
            ax.legend()
        axes[0, 0].set_title("Fig. 41: influence of the contact parameters")
        save(fig, "fig41_parameters.png")

    fig, axes = plt.subplots(2, 1, figsize=(5, 6))
    for ax, stage, x in ((axes[0], "biaxial", "eps_q"), (axes[1], "rotation", "alpha_eps_deg")):
        for m in ("mil", "areal_porosity"):
            f = data[main].get(f"{stage}_{m}")
            if f is not None:
                ax.plot(100 * f[x] if x == "eps_q" else _unwrap(f[x]), f["delta_deg"], label=m)
        ax.set(xlabel="eps_q [%]" if x == "eps_q" else "alpha_eps [deg]", ylabel="delta [deg]")
        ax.legend()
    axes[0].set_title(f"Fig. 43 ({main}): MIL vs areal porosity")
    save(fig, "fig43_mil_vs_n.png")

    f = data[main]["rotation_mil"]
    rows = f["row"].astype(int)
    fig, ax = plt.subplots(figsize=(5, 4))
    ae = _unwrap(r["alpha_eps_deg"])
    ax.plot(ae, _unwrap(r["alpha_deps_deg"]), label="alpha_deps")
    ax.plot(ae, _unwrap(r["alpha_sigma_deg"]), label="alpha_sigma")
    ax.plot(ae[rows], _unwrap(f["alpha_eps_deg"] + f["delta_deg"]), "o-", label="alpha_Omega (MIL)")
    ax.plot(ae, ae, "k--", lw=0.8, label="alpha_eps")
    ax.set(xlabel="alpha_eps [deg]", ylabel="angle [deg]", title=f"Fig. 44 ({main})")
    ax.legend(fontsize=8)
    save(fig, "fig44_angles.png")
    try:
        written.append(glyph_figure(f, figdir / "fig42_glyphs.png"))
        keep = ("alpha_eps_deg", "delta_deg", "omega_xx", "omega_xy")
        written.append(Table({k: f[k] for k in keep},
                             {"omega_xx": "fabric tensor Omega, xx component (Omega_yy = -Omega_xx)",
                              "omega_xy": "fabric tensor Omega, xy component"},
                             title="Fig. 42: the fabric tensor drawn as glyphs (MIL) during the rotation")
                       .write_csv(figdir / "fig42_glyphs.csv"))
    except Exception as exc:  # pyvista needs an off-screen renderer; the rest of the set is still useful
        (figdir / "fig42_glyphs.txt").write_text(f"glyph figure not rendered: {exc}\n")
    return written


def superquadric_glyph(tensor, centre, scale: float, n: int = 120, gamma: float = 3.0):
    """Outline (n, 2) of a 2D superquadric glyph (Schultz & Kindlmann 2010) of a symmetric 2x2
    tensor with eigenvalues of either sign: radius |lambda_i|-scaled, concave (four-pointed) shape."""
    w, v = np.linalg.eigh(np.asarray(tensor))
    t = np.linspace(0, 2 * np.pi, n)
    sx = np.sign(np.cos(t)) * np.abs(np.cos(t)) ** gamma
    sy = np.sign(np.sin(t)) * np.abs(np.sin(t)) ** gamma
    local = np.column_stack([abs(w[1]) * sx, abs(w[0]) * sy]) * scale
    frame = np.column_stack([v[:, 1], v[:, 0]])
    return np.asarray(centre) + local @ frame.T


def _offscreen_pyvista():
    """pyvista for off-screen rendering. Linux without DISPLAY (or with PYVISTA_OFF_SCREEN=true): name
    VTK's EGL window, else VTK probes X first and prints "bad X server connection" before falling back
    to EGL/OSMesa itself (it still falls back if EGL fails). A local copy of the set-up in
    femgran.output._offscreen_pyvista, because dem must not import femgran."""
    import os
    import sys

    if sys.platform.startswith("linux") and (
            not os.environ.get("DISPLAY") or os.environ.get("PYVISTA_OFF_SCREEN", "").lower() == "true"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    return pv


def glyph_figure(fabric_rows: dict, path, angles=(0, 15, 30, 45, 60, 90)) -> Path:
    """Fig. 42: glyphs of n^Omega (grey, scaled to 1) over n^e (black, scaled to 1/2) at several alpha_eps.

    Both tensors are traceless, so their superquadric glyphs are four-pointed stars with equal arms;
    the axis of the positive eigenvalue is drawn as a line (red: n^Omega, blue: n^e)."""
    pv = _offscreen_pyvista()
    ae = _unwrap(fabric_rows["alpha_eps_deg"])
    plotter = pv.Plotter(off_screen=True, window_size=(1500, 330))
    plotter.set_background("white")
    for k, a in enumerate(angles):
        i = int(np.argmin(np.abs(ae - a)))
        om = np.array([[fabric_rows["omega_xx"][i], fabric_rows["omega_xy"][i]],
                       [fabric_rows["omega_xy"][i], -fabric_rows["omega_xx"][i]]])
        ar = np.radians(ae[i])
        ne = np.array([[np.cos(2 * ar), np.sin(2 * ar)], [np.sin(2 * ar), -np.cos(2 * ar)]]) / np.sqrt(2)
        for tensor, scale, colour, z in ((om / np.linalg.norm(om), 1.0, "lightgray", 0.0), (ne, 0.5, "black", 0.01)):
            xy = superquadric_glyph(tensor, (2.5 * k, 0.0), scale / np.abs(np.linalg.eigvalsh(tensor)).max())
            pts = np.column_stack([xy, np.full(len(xy), z)])
            poly = pv.PolyData(pts, faces=np.concatenate([[len(pts)], np.arange(len(pts))]))
            plotter.add_mesh(poly, color=colour)
            w, v = np.linalg.eigh(tensor)  # mark the positive-eigenvalue axis (sign shown by colour)
            axis = v[:, 1] * scale * 1.1
            plotter.add_mesh(pv.Line((2.5 * k - axis[0], -axis[1], 0.02), (2.5 * k + axis[0], axis[1], 0.02)),
                             color="tab:red" if colour == "lightgray" else "tab:blue", line_width=4)
        plotter.add_point_labels([[2.5 * k - 0.8, -1.4, 0]], [f"({'abcdef'[k]}) {a} deg"], font_size=14, shape=None,
                                 show_points=False, text_color="black")
    plotter.view_xy()
    plotter.reset_camera()
    plotter.camera.zoom(2.6)
    plotter.screenshot(str(path))
    plotter.close()
    return Path(path)
