"""The thesis's model figures regenerated from the package's own element simulations.

Each figure is written as a PNG with the data behind it as a CSV of the same stem (``femgran figures`` writes them all):

* ``fig14_friction_distribution``: eta_f(alpha) of the ``ottawa_c109`` preset (eq. 2.20) against the
  slopes of the direct-shear envelopes (Fig. 8 data shipped with the package);
* ``fig20_triaxial_p50`` and ``fig21_triaxial_p100``: drained triaxial compression, alpha = 0 and 90;
* ``fig45_rotation_beta``: principal stress rotation, delta_psi = 0 and 90, beta = 0.1, 5, 10;
* ``fig46_rotation_psi`` and ``fig47_rotation_strains``: delta_psi = 0, 45, 90 at beta = 0.1;
* ``strength_envelope``: the continuous critical-plane strength q_f(alpha) at p0 = 50 and 100 kPa,
  with the peaks of the element tests at alpha = 0 and 90.
"""

from __future__ import annotations

import csv
from importlib.resources import files
from pathlib import Path
from typing import Callable

import numpy as np

from material import driver
from material.anisotropy import series
from material.failure import strength_envelope
from material.parameters import load_preset
from material.table import Table

__all__ = ["FIGURES", "DESCRIPTIONS", "make_figures", "figure_run", "direct_shear_envelopes"]


def direct_shear_envelopes() -> dict[str, np.ndarray]:
    """The Fig. 8 Coulomb envelopes shipped with the package: alpha_deg, slope, intercept_kPa."""
    text = files("material").joinpath("data/ottawa_c109_direct_shear_envelopes.csv").read_text()
    rows = [r for r in csv.reader(line for line in text.splitlines() if line and not line.startswith("#"))]
    header, data = rows[0], np.array(rows[1:], dtype=float)
    return {name: data[:, i] for i, name in enumerate(header)}


def _write_csv(path: Path, columns: dict[str, np.ndarray], comment: str) -> None:
    """The data behind a figure as a :class:`material.table.Table` (shorter columns padded with NaN)."""
    n = max(len(np.atleast_1d(v)) for v in columns.values())
    padded = {k: np.concatenate([np.atleast_1d(np.asarray(v, float)), np.full(n - len(np.atleast_1d(v)), np.nan)])
              for k, v in columns.items()}
    Table(padded, title=comment).write_csv(path)


def _fig14(out: Path, full: bool) -> list[Path]:
    import matplotlib.pyplot as plt

    p = load_preset("ottawa_c109")
    env = direct_shear_envelopes()
    alpha = np.linspace(0.0, 90.0, 91)
    x = p.omega1 * (1.0 - 3.0 * np.cos(np.deg2rad(alpha)) ** 2)  # (2.19)
    first = p.eta0 * (1.0 + x)  # order 1
    fourth = p.eta0 * series(x, p.a)  # order 4 (2.20, 2.21)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(env["alpha_deg"], env["slope"], "ko", label="direct shear, Fig. 8 slopes")
    ax.plot(alpha, first, "--", label="eq. 2.20, order 1")
    ax.plot(alpha, fourth, "-", label="eq. 2.20, order 4 (Table 3)")
    ax.set_xlabel("deposition angle alpha [deg]")
    ax.set_ylabel("friction coefficient eta_f [-]")
    ax.legend()
    ax.grid(alpha=0.3)
    png, csv_ = out / "fig14_friction_distribution.png", out / "fig14_friction_distribution.csv"
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
    _write_csv(csv_, {"alpha_deg": alpha, "eta_f_order1": first, "eta_f_order4": fourth,
                      "lab_alpha_deg": env["alpha_deg"], "lab_slope": env["slope"]},
               "eta_f(alpha) of preset ottawa_c109 (eq. 2.20) and the Fig. 8 direct-shear slopes")
    return [png, csv_]


def _triaxial_figure(out: Path, full: bool, p0: float, stem: str) -> list[Path]:
    import matplotlib.pyplot as plt

    p = load_preset("ottawa_c109")
    steps = 600 if full else 150
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    cols: dict[str, np.ndarray] = {}
    for alpha in (0.0, 90.0):
        res = driver.triaxial(p, p0_kPa=p0, alpha_deg=alpha, axial_strain=0.15, steps=steps)
        a1.plot(100 * res["eps_a"], res["q_kPa"], label=f"alpha = {alpha:g}")
        a2.plot(100 * res["eps_a"], 100 * res["eps_v"], label=f"alpha = {alpha:g}")
        cols[f"eps_a_alpha{alpha:g}"] = res["eps_a"]
        cols[f"q_kPa_alpha{alpha:g}"] = res["q_kPa"]
        cols[f"eps_v_alpha{alpha:g}"] = res["eps_v"]
    a1.set_xlabel("axial strain [%] (compression +)")
    a1.set_ylabel("q = sigma1 - sigma3 [kPa]")
    a2.set_xlabel("axial strain [%] (compression +)")
    a2.set_ylabel("volumetric strain [%] (compression +)")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend()
    fig.suptitle(f"Drained triaxial compression, p0 = {p0:g} kPa, preset ottawa_c109")
    fig.tight_layout()
    png, csv_ = out / f"{stem}.png", out / f"{stem}.csv"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    _write_csv(csv_, cols, f"drained triaxial compression at p0 = {p0:g} kPa; eps_a, eps_v compression +")
    return [png, csv_]


def _rotation_runs(betas, psis, full: bool):
    steps = 300 if full else 80
    runs = {}
    for beta in betas:
        params = load_preset("ottawa_c109_induced").replace(beta=beta)
        for psi in psis:
            runs[(beta, psi)] = driver.rotation(params, p0_kPa=14.0, delta_psi_deg=psi, steps=steps,
                                                preshear_steps=steps, unload_steps=max(steps // 4, 10))
    return runs


def _fig45(out: Path, full: bool) -> list[Path]:
    import matplotlib.pyplot as plt

    runs = _rotation_runs((0.1, 5.0, 10.0), (0.0, 90.0), full)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    cols = {}
    for (beta, psi), res in runs.items():
        m = np.isfinite(res["eps_1r"])
        ls = "-" if psi == 0 else "--"
        a1.plot(100 * res["eps_1r"][m], res["q_kPa"][m], ls, label=f"beta = {beta:g}, dpsi = {psi:g}")
        a2.plot(100 * res["eps_1r"][m], 100 * res["eps_v"][m], ls, label=f"beta = {beta:g}, dpsi = {psi:g}")
        cols[f"eps_1r_b{beta:g}_psi{psi:g}"] = res["eps_1r"][m]
        cols[f"q_kPa_b{beta:g}_psi{psi:g}"] = res["q_kPa"][m]
        cols[f"eps_v_b{beta:g}_psi{psi:g}"] = res["eps_v"][m]
    a1.set_xlabel("major strain on reshear [%]")
    a1.set_ylabel("q = sqrt(3 J2) [kPa]")
    a2.set_xlabel("major strain on reshear [%]")
    a2.set_ylabel("volumetric strain [%] (compression +)")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle("Principal stress rotation after pre-shear (plane strain, 14 kPa), induced anisotropy")
    fig.tight_layout()
    png, csv_ = out / "fig45_rotation_beta.png", out / "fig45_rotation_beta.csv"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    _write_csv(csv_, cols, "reshear after a principal stress rotation dpsi; preset ottawa_c109_induced with beta")
    return [png, csv_]


def _fig46_47(out: Path, full: bool) -> list[Path]:
    import matplotlib.pyplot as plt

    runs = _rotation_runs((0.1,), (0.0, 45.0, 90.0), full)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    cols = {}
    for (beta, psi), res in runs.items():
        m = np.isfinite(res["eps_1r"])
        a1.plot(100 * res["eps_1r"][m], res["q_kPa"][m], label=f"dpsi = {psi:g}")
        a2.plot(100 * res["eps_1r"][m], 100 * res["eps_v"][m], label=f"dpsi = {psi:g}")
        cols[f"eps_1r_psi{psi:g}"] = res["eps_1r"][m]
        cols[f"q_kPa_psi{psi:g}"] = res["q_kPa"][m]
        cols[f"eps_v_psi{psi:g}"] = res["eps_v"][m]
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend()
        a.set_xlabel("major strain on reshear [%]")
    a1.set_ylabel("q = sqrt(3 J2) [kPa]")
    a2.set_ylabel("volumetric strain [%] (compression +)")
    fig.suptitle("Principal stress rotation, beta = 0.1 (Fig. 46)")
    fig.tight_layout()
    png46, csv46 = out / "fig46_rotation_psi.png", out / "fig46_rotation_psi.csv"
    fig.savefig(png46, dpi=120)
    plt.close(fig)
    _write_csv(csv46, cols, "reshear after dpsi = 0, 45, 90; ottawa_c109_induced, beta = 0.1")

    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    cols47 = {}
    for ax, ((beta, psi), res) in zip(axes, runs.items()):
        step = np.arange(len(res))
        for comp in ("xx", "yy", "xy"):
            ax.plot(step, 100 * res[f"eps_{comp}"], label=f"eps_{comp}")
            cols47[f"eps_{comp}_psi{psi:g}"] = res[f"eps_{comp}"]
        ax.set_title(f"dpsi = {psi:g}")
        ax.set_xlabel("load step (pre-shear, unload, reshear)")
        ax.grid(alpha=0.3)
        ax.legend()
    axes[0].set_ylabel("strain component [%] (tension +)")
    fig.suptitle("Strain components through the rotation test, beta = 0.1 (Fig. 47)")
    fig.tight_layout()
    png47, csv47 = out / "fig47_rotation_strains.png", out / "fig47_rotation_strains.csv"
    fig.savefig(png47, dpi=120)
    plt.close(fig)
    _write_csv(csv47, cols47, "strain components (tension +) per load step; ottawa_c109_induced, beta = 0.1")
    return [png46, csv46, png47, csv47]


def _envelope(out: Path, full: bool) -> list[Path]:
    import matplotlib.pyplot as plt

    p = load_preset("ottawa_c109")
    alphas = np.linspace(0.0, 90.0, 19 if full else 10)
    fig, ax = plt.subplots(figsize=(6, 4))
    cols = {"alpha_deg": alphas}
    for p0 in (50.0, 100.0):
        q = strength_envelope(p, p0, alphas)
        ax.plot(alphas, q, "-", label=f"critical plane, p0 = {p0:g} kPa")
        cols[f"q_f_kPa_p{p0:g}"] = q
        peaks = []
        for a in (0.0, 90.0):
            res = driver.triaxial(p, p0_kPa=p0, alpha_deg=a, axial_strain=0.3, steps=200 if full else 100)
            peaks.append(res["q_kPa"].max())
        ax.plot([0.0, 90.0], peaks, "o", label=f"element test peak (30 % strain), p0 = {p0:g}")
        cols[f"element_peak_kPa_p{p0:g}_alpha0_90"] = np.array(peaks)
    ax.set_xlabel("deposition angle alpha [deg]")
    ax.set_ylabel("failure deviator q_f [kPa]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    png, csv_ = out / "strength_envelope.png", out / "strength_envelope.csv"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    _write_csv(csv_, cols, "continuous critical-plane strength q_f(alpha), drained triaxial compression")
    return [png, csv_]


FIGURES: dict[str, Callable[[Path, bool], list[Path]]] = {
    "fig14": _fig14,
    "fig20": lambda out, full: _triaxial_figure(out, full, 50.0, "fig20_triaxial_p50"),
    "fig21": lambda out, full: _triaxial_figure(out, full, 100.0, "fig21_triaxial_p100"),
    "fig45": _fig45,
    "fig46-47": _fig46_47,
    "envelope": _envelope,
}


#: One sentence per figure file (stem): what it shows (the index of ``femgran figures``).
DESCRIPTIONS = {
    "fig14_friction_distribution": "Friction coefficient eta_f against the deposition angle: the series of eq. 2.20 "
                                   "(order 1 and order 4, Table 3) against the slopes of the direct-shear envelopes.",
    "fig20_triaxial_p50": "Drained triaxial compression at p0 = 50 kPa, bedding horizontal (alpha 0) and vertical "
                          "(alpha 90): deviator and volumetric strain against axial strain.",
    "fig21_triaxial_p100": "Drained triaxial compression at p0 = 100 kPa, alpha 0 and 90: deviator and volumetric "
                           "strain against axial strain.",
    "fig45_rotation_beta": "Reshear after a rotation of the principal stress by 0 and 90 deg for three rates beta of "
                           "induced anisotropy: deviator and volumetric strain against the reshear strain.",
    "fig46_rotation_psi": "Reshear after rotations of the principal stress of 0, 45 and 90 deg (beta = 0.1).",
    "fig47_rotation_strains": "Strain components through pre-shear, unloading and reshear for the three rotations.",
    "strength_envelope": "Drained triaxial strength q_f against the deposition angle from the critical-plane "
                         "criterion, with the peaks of the element tests at alpha 0 and 90.",
}


def figure_run(out, name: str, full: bool = False) -> dict:
    """Sweep target (:mod:`material.sweep`): the figure ``name`` of :data:`FIGURES` into the folder ``out``."""
    if name not in FIGURES:
        raise ValueError(f"figure = {name!r}: allowed {list(FIGURES)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = FIGURES[name](out, bool(full))
    return {"files": len(written)}


def make_figures(out_dir, names=None, full: bool = False, progress: bool = True) -> list[Path]:
    """Write the named figures (default: all of ``FIGURES``) into ``out_dir``; returns the paths."""
    names = list(FIGURES) if names is None else list(names)
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise KeyError(f"unknown figure(s) {unknown}; available: {list(FIGURES)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from tqdm import tqdm

    written: list[Path] = []
    for name in tqdm(names, desc="figures", disable=not progress):
        written += FIGURES[name](out, full)
    return written
