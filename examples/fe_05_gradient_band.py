"""Example fe_05: a shear band whose thickness is set by the material's length, not by the mesh.

Plane-strain biaxial compression (``femgran.cases.Biaxial``: W = 50 mm, H = 100 mm, p0 = 50 kPa, smooth
platens, a 2 % bump of the left face as the trigger) of a softening von Mises solid (E = 20 MPa,
nu = 0.3, sigma_y = 150 kPa, H = -1 MPa), on meshes of 10, 20 and 30 elements across (h = 5, 2.5 and
1.67 mm):

* regularised by the implicit gradient (:class:`material.GradientVonMises`, :mod:`femgran.gradient`) with
  l = 10 mm and l = 5 mm: the post-peak q and the band's thickness (measured by
  :func:`femgran.band.measure_band`) should not depend on h once h <= l / 2, and the thickness should
  scale with l;
* local (no length): the band is as thin as the mesh allows and q drops with h until the runs stop.

Writes ``bands.csv`` (one row per run: l, h, peak q, q at 2, 3 and 4 % axial strain, band thickness,
angle and contrast) and ``gradient_band.png`` (the curves, and the thickness against h), and prints the
spread of q over the meshes of each l. The runs are a study on the sweep engine (:mod:`material.sweep`):
``--jobs 2`` runs two at a time; the same command again runs only the runs not yet complete.

    python examples/fe_05_gradient_band.py [--jobs 2] [--resolutions 10 20 30] [--lengths 0.01 0.005]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from femgran.solver import History
from material.sweep import Run, sweep
from material.table import Table

STRAINS = (0.02, 0.03, 0.04)  # axial strains at which q is compared over the meshes
MATERIAL = {"law": "von_mises", "E_kPa": 20000.0, "nu": 0.3, "yield_stress_kPa": 150.0, "hardening_kPa": -1000.0}
CASE = {"p0_kPa": 50.0, "axial_strain": 0.04, "steps": 80}


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/fe_05_gradient_band")
    ap.add_argument("--resolutions", type=int, nargs="+", default=[10, 20, 30], help="elements across the width")
    ap.add_argument("--lengths", type=float, nargs="+", default=[0.01, 0.005], help="internal lengths l [m]")
    ap.add_argument("--no-local", action="store_true", help="leave out the local (unregularised) runs")
    ap.add_argument("--jobs", type=int, default=1, help="runs at a time (local Dask cluster)")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs must be at least 1, got {args.jobs}")
    if any(not (np.isfinite(x) and x > 0) for x in args.lengths):
        ap.error(f"--lengths must be > 0, got {args.lengths}")
    out = Path(args.out)
    lengths = list(args.lengths) + ([] if args.no_local else [None])
    runs = [Run(_tag(n, ell), "femgran.sweep:case_target",
                {"case": "biaxial", "fields": {**CASE, "resolution": n},
                 "material": MATERIAL if ell is None else {**MATERIAL, "length_m": ell}},
                {"resolution": n, "length_m": "local" if ell is None else ell})
            for ell in lengths for n in sorted(args.resolutions, reverse=True)]
    sweep(runs, out, workers=args.jobs, progress=False, title="fe_05 gradient band")
    rows = collect(out)
    _plot(rows, out / "gradient_band.png")
    return rows


def _tag(n: int, ell) -> str:
    return f"{'local' if ell is None else f'l_{1e3 * ell:g}mm'}_resolution_{n}"


def collect(out: Path) -> list[dict]:
    """One row per completed or stopped run under ``out``; writes bands.csv and prints the spreads."""
    rows = []
    for folder in sorted(out.glob("*_resolution_*")):
        if not (folder / "summary.json").is_file():
            continue
        h = History.read_csv(folder / "history.csv")
        summary = json.loads((folder / "summary.json").read_text())
        params = json.loads((folder / "parameters.json").read_text())
        status = json.loads((folder / "status.json").read_text()) if (folder / "status.json").is_file() else {}
        tag = folder.name.split("_resolution_")[0]
        e, q = np.asarray(h["eps_a"]), np.asarray(h["q_kPa"])
        rows.append({"length": tag, "resolution": int(params["resolution"]),
                     "element_size_mm": 1e3 * params["width_m"] / int(params["resolution"]),
                     "peak_q_kPa": float(q.max()), "completed": bool(status.get("completed", False)),
                     "q": [float(np.interp(x, e, q)) if x <= e[-1] + 1e-12 else float("nan") for x in STRAINS],
                     "band_thickness_mm": 1e3 * summary["band_thickness_m"], "band_angle_deg": summary["band_angle_deg"],
                     "band_contrast": summary["band_contrast"], "history": h})
    table = Table(title="fe_05: biaxial shear band, implicit gradient against local, several meshes")
    for r in rows:
        length_mm = float("nan") if r["length"] == "local" else float(r["length"][2:-2])
        table.append({"length_mm (NaN: local)": length_mm, "resolution": r["resolution"], "element_size_mm": r["element_size_mm"],
                      "peak_q_kPa": r["peak_q_kPa"], **{f"q_at_{x:g}_kPa": v for x, v in zip(STRAINS, r["q"])},
                      "band_thickness_mm": r["band_thickness_mm"], "band_angle_deg": r["band_angle_deg"],
                      "band_contrast": r["band_contrast"], "completed": int(r["completed"])})
    table.write_csv(out / "bands.csv")
    for tag in sorted({r["length"] for r in rows}):
        sel = sorted((r for r in rows if r["length"] == tag), key=lambda r: r["resolution"])
        spread = [np.ptp([r["q"][j] for r in sel]) / max(r["peak_q_kPa"] for r in sel) for j in range(len(STRAINS))]
        print(f"{tag}: q at {STRAINS} spreads by " + ", ".join(f"{100 * s:.1f} %" for s in spread)
              + " of the peak over meshes " + str([r["resolution"] for r in sel]) + "; band thickness "
              + " / ".join(f"{r['band_thickness_mm']:.1f}" for r in sel) + " mm"
              + ("" if all(r["completed"] for r in sel) else " (some runs stopped early: NaN)"))
    return rows


def _plot(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tags = sorted({r["length"] for r in rows})
    fig, axes = plt.subplots(1, len(tags) + 1, figsize=(4 * (len(tags) + 1), 3.6))
    for ax, tag in zip(axes, tags):
        for r in sorted((r for r in rows if r["length"] == tag), key=lambda r: r["resolution"]):
            ax.plot(r["history"]["eps_a"], r["history"]["q_kPa"], label=f"h = {r['element_size_mm']:.2f} mm")
        ax.set_title(tag.replace("_", " = ").replace("mm", " mm") if tag != "local" else "local (no length)",
                     fontsize=9)
        ax.set_xlabel("axial strain (compression +)")
        ax.set_ylabel("q = s1 - s3 [kPa]")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    ax = axes[-1]
    for tag in tags:
        sel = sorted((r for r in rows if r["length"] == tag), key=lambda r: r["element_size_mm"])
        ax.plot([r["element_size_mm"] for r in sel], [r["band_thickness_mm"] for r in sel], "o-", label=tag)
    ax.set_xlabel("element size h [mm]")
    ax.set_ylabel("band thickness (FWHM) [mm]")
    ax.set_title("band thickness against the mesh", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
