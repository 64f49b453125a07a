"""``femgran figures``: every figure of the package from its own simulations, in one folder with an index.

Five groups, each a set of runs on the sweep engine (:mod:`material.sweep`: a local Dask cluster, or
``--scheduler``; the runs go to ``OUT/runs/<key>`` and the same command again runs only those not yet
complete) and a drawing step that reads the run folders:

* ``model`` -- the thesis's chapter-2 model figures from element tests (:mod:`material.figures`:
  Figs. 14, 20, 21, 45-47 and the strength envelope);
* ``dem`` -- the chapter-3 DEM figures (Figs. 23-28, 38-44, and 29-34 when their tests run) from Table 4
  experiments (:mod:`dem.sweep`, :mod:`dem.figures`);
* ``bearing`` -- bearing capacity of a strip footing against the deposition angle, the load-settlement
  curves and the failure mechanisms;
* ``uniformity`` -- the non-uniformity of a triaxial specimen with rough platens against the deposition
  angle, and its strength against the homogeneous element test;
* ``shear-band`` -- the plane-strain biaxial test with softening on three meshes: curves, band angle and
  thickness against the element size (:mod:`femgran.band`), the bands, and the band angle against the
  deposition angle (0, 30, 60, 90: on the middle mesh in the reduced set, the crack band; on the
  coarsest in the full set, the implicit gradient with l = 6 mm to 8 % axial strain on meshes of
  h <= l / 3, specimen H = 3W).

Every PNG has a CSV of the same stem with what it draws; ``OUT/README.md`` lists each figure with a
sentence on what it shows. The default is a reduced size (coarse meshes, few steps, DEM samples at a
tenth of the thesis's particle numbers, three Table 4 tests: minutes on two cores); ``--full`` runs the
thesis's sizes (hours).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from material.commandline import add_out, add_progress, write_run_record
from material.sweep import Run, key_of

__all__ = ["GROUPS", "make_all", "register", "rice_onset_angles"]

_MATERIAL = {"preset": "ottawa_c109", "stabilisation": 0.1}  # the footing runs to its end (docs/cpa_law.md, 4)


@dataclass(frozen=True)
class Group:
    """A figure group: its runs (reduced or ``full``) and the drawing of its figures from the run folders.

    ``draw(runs_dir, records, out, full)`` writes PNG + CSV into ``out`` and returns ``{stem: sentence}``."""

    name: str
    runs: Callable[[bool], list[Run]]
    draw: Callable[[Path, dict, Path, bool], dict]


# ------------------------------------------------------------------------------------------ model
def _model_runs(full: bool, names=None) -> list[Run]:
    from material.figures import FIGURES

    return [Run(f"model-{n}", "material.figures:figure_run", {"name": n, "full": full}, {}) for n in (names or FIGURES)]


def _model_draw(runs_dir: Path, records: dict, out: Path, full: bool) -> dict:
    from material.figures import DESCRIPTIONS

    drawn = {}
    for key, rec in records.items():
        if not key.startswith("model-") or rec["status"] != "completed":
            continue
        for f in sorted((runs_dir / key).glob("*.png")) + sorted((runs_dir / key).glob("*.csv")):
            shutil.copy2(f, out / f.name)
            if f.suffix == ".png":
                drawn[f.stem] = DESCRIPTIONS.get(f.stem, "")
    return drawn


# ------------------------------------------------------------------------------------------ DEM
def _dem_tests(full: bool) -> list[str]:
    from dem.sweep import TABLE4

    return list(TABLE4) if full else ["T06", "T05", "T07"]


def _dem_runs(full: bool) -> list[Run]:
    return [Run(t, "dem.sweep:table4_run", {"test": t, "scale": 1.0 if full else 0.1, "seed": 1}, {})
            for t in _dem_tests(full)]


def _dem_draw(runs_dir: Path, records: dict, out: Path, full: bool) -> dict:
    from dem.figures import DESCRIPTIONS, sweep_figures

    done = [t for t in _dem_tests(full) if records.get(t, {}).get("status") == "completed"]
    if not done:
        return {}
    written = sweep_figures(runs_dir, done, figdir=out)
    return {p.stem: DESCRIPTIONS.get(p.stem[:5], "") + f" (Table 4 tests {', '.join(done)})"
            for p in written if p.suffix == ".png"}


# ------------------------------------------------------------------------------------------ boundary values
def _case_runs(case: str, sweep_key: str, values, fixed: dict, material=None, prefix=None) -> list[Run]:
    return [Run(f"{prefix or case}_{key_of({sweep_key: v})}", "femgran.sweep:case_target",
                {"case": case, "fields": {**fixed, sweep_key: v}, "material": material}, {sweep_key: v})
            for v in values]


def _bearing_runs(full: bool) -> list[Run]:
    alphas = np.arange(0.0, 91.0, 15.0) if full else [0.0, 30.0, 60.0, 90.0]
    fixed = {"resolution": 3, "steps": 40} if full else {"resolution": 2, "steps": 20}
    return _case_runs("footing", "alpha_deg", [float(a) for a in alphas], fixed, _MATERIAL)


def _uniformity_runs(full: bool) -> list[Run]:
    alphas = np.arange(0.0, 91.0, 15.0) if full else [0.0, 45.0, 90.0]
    fixed = {"platens": "rough", **({"resolution": 4, "steps": 60} if full else {"resolution": 2, "steps": 30})}
    return _case_runs("triaxial", "alpha_deg", [float(a) for a in alphas], fixed)


_BAND_MATERIAL = {"preset": "ottawa_c109", "stabilisation": 0.1,
                  "set": {"E": 60000.0, "zeta": 1.05, "softening_slip": 0.03, "residual_ratio": 0.65}}
#: The band's length scale of the full set: the implicit gradient with l = 6 mm (docs/regularisation.md).
_BAND_LENGTH_M = 0.006


def _band_setup(full: bool) -> tuple[list[int], int, dict, dict]:
    """Meshes, the mesh of the deposition-angle runs, case fields and material of the shear-band study: the
    reduced set on coarse meshes with the crack band (minutes), specimen H = 2W; the full set with the
    implicit gradient to 8 % on meshes of h = 0.35, 0.23 and 0.17 l (24, 36 and 48 elements across,
    multiples of 6, so the weak zone is the same region), the deposition-angle runs on the coarsest, on a
    specimen H = 3W. On H = 2W between rough platens a band from the weak zone reaches the free face below
    the top platen only if tan theta < H/W - 1/3 (theta < 59 deg), and the finer meshes formed an X at
    34-40 deg bounding the blocks the platens hold; on H = 3W (theta < 69.4 deg) one band runs at
    66.4-66.9 deg on 24, 30 and 36 elements, between Roscoe and Coulomb (docs/regularisation.md,
    section 4). The weak zone stays at W/6 above the bottom (``weak_zone_height`` 1/18 of H). A mesh of
    h = 0.46 l (18 elements) does not resolve the CPA gradient: its band took another angle and its curve
    left the finer meshes' by 3 % (ibid.)."""
    fixed = {"platens": "rough", "weak_zone": 0.1, "weak_zone_size": 1.0 / 3.0, "imperfection": 0.0}
    if full:
        return [24, 36, 48], 24, {**fixed, "height_ratio": 3.0, "weak_zone_height": 1.0 / 18.0,
                                  "axial_strain": 0.08, "steps": 320}, \
            {**_BAND_MATERIAL, "nonlocal_length": _BAND_LENGTH_M}
    return [4, 6, 8], 6, {**fixed, "weak_zone_height": 1.0 / 12.0, "axial_strain": 0.05, "steps": 60}, _BAND_MATERIAL


def _band_regularisation(full: bool) -> str:
    return f"implicit gradient, l = {1e3 * _BAND_LENGTH_M:g} mm" if full else "crack band"


def _band_runs(full: bool) -> list[Run]:
    meshes, alpha_mesh, fixed, law = _band_setup(full)
    return (_case_runs("biaxial", "resolution", meshes, fixed, law)
            + _case_runs("biaxial", "alpha_deg", [30.0, 60.0, 90.0], {**fixed, "resolution": alpha_mesh}, law,
                         prefix="band_alpha"))


def _completed(records: dict, prefix: str) -> list[tuple[str, dict]]:
    return [(k, r) for k, r in records.items() if k.startswith(prefix) and r["status"] == "completed"]


def _history(folder: Path):
    from femgran.solver import History

    return History.read_csv(folder / "history.csv")


def _curves(ax, runs_dir: Path, runs, labels, x: str, y: str, **labelling) -> None:
    """One curve y(x) of each run's history, labelled; ``labelling`` sets the axis labels and title."""
    for (key, _), label in zip(runs, labels):
        h = _history(runs_dir / key)
        ax.plot(h[x], h[y], label=label)
    ax.set(**labelling)


def _tidy(*axes) -> None:
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)


def _field_panel(ax, folder: Path, stem: str, title: str):
    """The norm of the plastic strain at the last step of a plane run, cell by cell, with the nodal values as
    points (those are the CSV's data)."""
    import meshio
    from matplotlib.collections import PolyCollection

    from femgran.output import read_pvd

    entries = read_pvd(folder / f"{stem}.pvd")
    mesh = meshio.read(entries[-1][1])
    xy = mesh.points[:, :2]
    values = np.linalg.norm(np.asarray(mesh.point_data["plastic_strain"]).reshape(len(xy), -1), axis=1)
    polys, colours = [], []
    for block in mesh.cells:
        for cell in block.data:
            corners = cell[:4] if block.type.startswith("quad") else cell[:3]
            polys.append(xy[corners])
            colours.append(values[corners].mean())
    pc = PolyCollection(polys, array=np.asarray(colours), cmap="viridis", edgecolors="face", linewidths=0.2)
    ax.add_collection(pc)
    ax.scatter(xy[:, 0], xy[:, 1], c=values, s=1, cmap="viridis", label="nodes")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set(title=title, xlabel="x [m]", ylabel="y [m]")
    return pc


def _bearing_draw(runs_dir: Path, records: dict, out: Path, full: bool) -> dict:
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    runs = sorted(_completed(records, "footing_"), key=lambda kr: kr[1]["values"]["alpha_deg"])
    if not runs:
        return {}
    alphas = [r["values"]["alpha_deg"] for _, r in runs]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    a1.plot(alphas, [r["summary"]["bearing_capacity_kPa"] for _, r in runs], "o-", label="bearing capacity")
    a1.set(xlabel="deposition angle alpha [deg]", ylabel="bearing capacity [kPa]",
           title=f"strip footing, CPA ottawa_c109, step stabilisation {_MATERIAL['stabilisation']}")
    _curves(a2, runs_dir, runs, [f"alpha = {a:g}" for a in alphas], "settlement_m", "pressure_kPa",
            xlabel="settlement [m]", ylabel="mean footing pressure [kPa]", title="load-settlement")
    _tidy(a1, a2)
    fig.tight_layout()
    save_figure(fig, out / "bearing_capacity_vs_alpha.png")
    cols = min(2, len(runs))
    rows = -(-len(runs) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.5 * cols, 2.4 * rows + 0.6), squeeze=False, layout="constrained")
    for ax, (key, _), a in zip(axes.ravel(), runs, alphas):
        pc = _field_panel(ax, runs_dir / key, "footing", f"alpha = {a:g}")
    for ax in axes.ravel()[len(runs):]:
        ax.set_axis_off()
    fig.colorbar(pc, ax=axes.ravel().tolist(), label="|plastic strain|", shrink=0.8)
    save_figure(fig, out / "bearing_mechanisms.png")
    return {"bearing_capacity_vs_alpha": "Bearing capacity of a rough strip footing on the anisotropic sand against "
                                         "the deposition angle, and the load-settlement curves behind it, with the "
                                         f"step stabilisation {_MATERIAL['stabilisation']}: its overstress puts the "
                                         "pressure at s = 0.1 B 2.7-5 % above the stabilisation 0.01 at 15-90 deg "
                                         "and delays a second mechanism at 0 deg (docs/cpa_law.md, section 4).",
            "bearing_mechanisms": "The failure mechanisms: plastic strain at the end of each footing run, one "
                                  "panel per deposition angle."}


def _uniformity_draw(runs_dir: Path, records: dict, out: Path, full: bool) -> dict:
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    runs = sorted(_completed(records, "triaxial_"), key=lambda kr: kr[1]["values"]["alpha_deg"])
    if not runs:
        return {}
    alphas = [r["values"]["alpha_deg"] for _, r in runs]
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(14, 4))
    a1.plot(alphas, [r["summary"]["final_cv_q"] for _, r in runs], "o-", label="at the end")
    a1.plot(alphas, [r["summary"]["max_cv_q"] for _, r in runs], "s--", label="largest")
    a1.set(xlabel="deposition angle alpha [deg]", ylabel="coefficient of variation of q [-]",
           title="non-uniformity of the specimen")
    a2.plot(alphas, [r["summary"].get("final_q_over_element", np.nan) for _, r in runs], "o-",
            label="specimen / element test")
    a2.axhline(1.0, color="k", lw=0.8)
    a2.set(xlabel="deposition angle alpha [deg]", ylabel="final q of the specimen / element test [-]",
           title="the platens' effect on strength")
    _curves(a3, runs_dir, runs, [f"alpha = {a:g}" for a in alphas], "eps_a", "q_kPa",
            xlabel="axial strain (compression +)", ylabel="q = s1 - s3 [kPa]", title="specimens, rough platens")
    _tidy(a1, a2, a3)
    fig.tight_layout()
    save_figure(fig, out / "triaxial_nonuniformity_vs_alpha.png")
    return {"triaxial_nonuniformity_vs_alpha": "A triaxial specimen with rough platens: the coefficient of "
                                               "variation of the deviator over the specimen, its strength against "
                                               "the homogeneous element test, and its curves, against the "
                                               "deposition angle."}


def _band_draw(runs_dir: Path, records: dict, out: Path, full: bool) -> dict:
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    runs = sorted(_completed(records, "biaxial_"), key=lambda kr: kr[1]["values"]["resolution"])
    if not runs:
        return {}
    drawn = _band_alpha_draw(runs_dir, records, out, full)
    sizes = [1e3 * 0.05 / r["values"]["resolution"] for _, r in runs]
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(14, 4))
    _curves(a1, runs_dir, runs, [f"h = {h_mm:.2f} mm" for h_mm in sizes], "eps_a", "q_kPa",
            xlabel="axial strain (compression +)", ylabel="q = s1 - s3 [kPa]", title="biaxial with softening")
    a2.plot(sizes, [r["summary"]["band_angle_deg"] for _, r in runs], "o-", label="band angle (FE)")
    for ref, style in (("coulomb", ":"), ("roscoe", "--"), ("arthur", "-.")):
        a2.plot(sizes, [r["summary"].get(f"reference_angles_deg_{ref}", np.nan) for _, r in runs], style, label=ref)
    a2.set(xlabel="element size h [mm]", ylabel="angle from the minor stress direction [deg]", title="band angle")
    a3.plot(sizes, [1e3 * r["summary"].get("band_thickness_m", np.nan) for _, r in runs], "o-",
            label="band thickness (FE)")
    if full:
        a3.axhline(1e3 * _BAND_LENGTH_M, color="k", ls=":", label="l, the gradient's length")
    else:
        a3.plot(sizes, [3 * h for h in sizes], "k:", label="3 elements")
    a3.set(xlabel="element size h [mm]", ylabel="band thickness [mm]",
           title=f"band thickness ({_band_regularisation(full)})")
    _tidy(a1, a2, a3)
    fig.tight_layout()
    save_figure(fig, out / "shear_band_meshes.png")
    tall = float(runs[0][1]["kwargs"]["fields"].get("height_ratio", 2.0))  # H / W of the specimen
    fig, axes = plt.subplots(1, len(runs), figsize=(2.6 * len(runs), 1.6 + 1.3 * tall), squeeze=False)
    for ax, (key, _), h_mm in zip(axes[0], runs, sizes):
        pc = _field_panel(ax, runs_dir / key, "biaxial", f"h = {h_mm:.2f} mm")
    for ax in axes[0][1:]:  # one y axis for the row: the panels' labels would run into their neighbours
        ax.set_ylabel("")
        ax.tick_params(labelleft=False)
    fig.colorbar(pc, ax=axes[0].tolist(), label="|plastic strain|", shrink=0.8)
    save_figure(fig, out / "shear_band_fields.png")
    return {**drawn,
            "shear_band_meshes": f"The plane-strain biaxial test with softening on three meshes "
                                 f"({_band_regularisation(full)}): curves, the band angle against the element "
                                 f"size with the Coulomb, Roscoe and Arthur angles, and the band's measured "
                                 f"thickness.",
            "shear_band_fields": "The shear bands: plastic strain at the end of each run, one panel per mesh."}


def _band_alpha_draw(runs_dir: Path, records: dict, out: Path, full: bool) -> dict:
    """Band angle against the deposition angle (the study's run at alpha 0 on the alpha runs' mesh, and those)."""
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    alpha_mesh = _band_setup(full)[1]
    runs = [kr for kr in _completed(records, "biaxial_") if kr[1]["values"]["resolution"] == alpha_mesh]
    runs += _completed(records, "band_alpha_")
    if len(runs) < 2:
        return {}
    alphas = [r["kwargs"]["fields"].get("alpha_deg", 0.0) for _, r in runs]
    order = np.argsort(alphas)
    alphas = np.asarray(alphas)[order]
    runs = [runs[i] for i in order]
    fig, ax = plt.subplots(figsize=(6, 4))
    angle = np.array([r["summary"]["band_angle_deg"] for _, r in runs])
    band = np.array([bool(r["summary"].get("localised")) for _, r in runs])
    ax.plot(alphas, angle, "-", color="C0", lw=0.8)
    ax.scatter(alphas[band], angle[band], color="C0", label="band angle (FE): a band")
    ax.scatter(alphas[~band], angle[~band], facecolors="none", edgecolors="C0", label="no band: the most band-like")
    for ref, style in (("coulomb", ":"), ("roscoe", "--"), ("arthur", "-.")):
        ax.plot(alphas, [r["summary"].get(f"reference_angles_deg_{ref}", np.nan) for _, r in runs], style, label=ref)
    fields = runs[0][1]["kwargs"]["fields"]
    grid, onset = rice_onset_angles(_band_setup(full)[3], float(fields.get("p0_kPa", 100.0)))
    ax.plot(grid, onset["falling"], "k-", lw=1.2, label="Rice's onset, falling bands (element, rate-independent)")
    ax.plot(grid, onset["rising"], "k--", lw=1.2, label="Rice's onset, rising bands (element, rate-independent)")
    ax.set(xlabel="deposition angle alpha [deg]", ylabel="band angle from the minor stress direction [deg]",
           title=f"biaxial with softening, {alpha_mesh} elements across\n{_band_regularisation(full)}")
    _tidy(ax)
    fig.tight_layout()
    save_figure(fig, out / "shear_band_vs_alpha.png")
    return {"shear_band_vs_alpha": "The band angle of the softening biaxial test against the deposition angle, "
                                   "with the Coulomb, Roscoe and Arthur angles from each run's own peak and the "
                                   "bands in which the law's own tangent first admits a band, rising and falling "
                                   "(Rice's condition on the plane-strain element test of the same sand without "
                                   "the step stabilisation)."}


def rice_onset_angles(material_spec: dict, p0_kPa: float, alphas=tuple(range(0, 91, 15))):
    """The band angle at the onset of localisation of the study's sand on the plane-strain element path
    (:func:`material.driver.plane_strain`, Rice's condition): the rate-independent local law (no step
    stabilisation, no gradient, no back stress: the first keeps the algorithmic tangent elliptic, the others
    add a length the element does not have), 400 steps to 5 % (the same to 0.25 deg with 1600;
    docs/regularisation.md, section 4).
    Returns (alphas, {"rising": angles [deg], "falling": angles [deg]}): each family's band nearest to
    forming at the last elliptic row (the driver tilts the bedding toward +x, as the biaxial case does), NaN
    where the path stays elliptic."""
    from material import driver
    from material.factory import LENGTH_KEYS, make_material

    spec = {k: v for k, v in material_spec.items() if k not in LENGTH_KEYS}
    spec["stabilisation"] = 0.0
    angles = {"rising": [], "falling": []}
    for a in alphas:
        res = driver.plane_strain(make_material(spec, alpha_deg=float(a)), p0_kPa=p0_kPa, alpha_deg=float(a),
                                  axial_strain=0.05, steps=400)
        onset = res.metadata["bifurcation"]
        for family, values in angles.items():
            values.append(np.nan if onset is None else onset[f"{family}_deg"])
    return np.asarray(alphas, dtype=float), {family: np.asarray(v) for family, v in angles.items()}


GROUPS: dict[str, Group] = {
    "dem": Group("dem", _dem_runs, _dem_draw),  # first: the longest runs start first
    "model": Group("model", _model_runs, _model_draw),
    "bearing": Group("bearing", _bearing_runs, _bearing_draw),
    "uniformity": Group("uniformity", _uniformity_runs, _uniformity_draw),
    "shear-band": Group("shear-band", _band_runs, _band_draw),
}


# ------------------------------------------------------------------------------------------ the set
def _selection(only) -> tuple[list[str], list[str] | None]:
    """(groups, model figure names or None for all) of ``--only``."""
    from material.figures import FIGURES

    if not only:
        return list(GROUPS), None
    unknown = [n for n in only if n not in GROUPS and n not in FIGURES]
    if unknown:
        raise ValueError(f"figures --only {unknown}: allowed the groups {list(GROUPS)} or the model figures "
                         f"{list(FIGURES)}")
    groups = [g for g in GROUPS if g in only]
    names = [n for n in only if n in FIGURES]
    if names and "model" not in groups:
        groups.append("model")
    return groups, (names or None) if "model" not in only else None


def _index(out: Path, drawn: dict, records: dict, full: bool) -> Path:
    lines = ["# femgran figures", "",
             f"Made by `femgran figures{' --full' if full else ''}` from the package's own simulations "
             f"({'the thesis sizes' if full else 'reduced size: coarse meshes, few steps, small DEM samples'}). "
             "Each PNG has a CSV of the same name with the numbers it draws; the runs behind them are in `runs/` "
             "(`runs/summary.csv`).", ""]
    for stem in sorted(drawn):
        csv = f" ([data]({stem}.csv))" if (out / f"{stem}.csv").is_file() else ""
        lines.append(f"- [{stem}.png]({stem}.png){csv}: {drawn[stem]}")
    failed = [(k, r) for k, r in records.items() if r["status"] != "completed"]
    if failed:
        lines += ["", "## Runs that did not complete (their figures are missing or partial)", ""]
        lines += [f"- `runs/{k}`: {r['status']}: {r['message']}" for k, r in failed]
    path = out / "README.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def make_all(out, only=None, full: bool = False, progress: bool = True, workers: int | None = None,
             scheduler: str | None = None) -> dict:
    """Run every group's runs (one study, ``out/runs``), draw the figures into ``out`` and write the index.

    Returns ``{stem: sentence}`` of the figures drawn; a group whose runs failed is left out of it and the
    index names its runs and their messages."""
    from material.sweep import sweep

    groups, names = _selection(only)
    out = Path(out)
    runs = []
    for g in groups:
        runs += _model_runs(full, names) if g == "model" else GROUPS[g].runs(full)
    result = sweep(runs, out / "runs", scheduler=scheduler, workers=workers, progress=progress, title="figures")
    records = {r["key"]: r for r in result.records}
    drawn: dict[str, str] = {}
    for g in groups:
        drawn.update(GROUPS[g].draw(out / "runs", records, out, full))
    _index(out, drawn, records, full)
    return drawn


def register(subparsers) -> None:
    import argparse

    from material.figures import FIGURES

    p = subparsers.add_parser("figures", help="every figure from the package's own simulations, with an index",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_out(p, "out/figures")
    p.add_argument("--only", nargs="+", metavar="NAME",
                   help=f"only these groups ({', '.join(GROUPS)}) or model figures ({', '.join(FIGURES)})")
    p.add_argument("--full", action="store_true", help="the thesis's sizes (hours; default: reduced, minutes)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local Dask cluster (default: the machine's cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler; 'serial' runs in this process")
    add_progress(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    out = Path(args.out)
    drawn = make_all(out, only=args.only, full=args.full, progress=args.progress, workers=args.workers,
                     scheduler=args.scheduler)
    from material.sweep import read_summary

    status = read_summary(out / "runs").metadata.get("status", [])
    write_run_record(out, args, figures=sorted(drawn), runs=len(status),
                     incomplete=sum(s != "completed" for s in status))
    print(f"{len(drawn)} figure(s) in {out} (index: {out / 'README.md'})")
    return 0 if all(s == "completed" for s in status) else 1
