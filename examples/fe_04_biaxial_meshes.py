"""Example fe_04: plane-strain biaxial test on three meshes: localisation, band angle, regularisation.

CPA ``ottawa_c109`` with the post-peak softening switched on (zeta = 1.05: a plane reaches eta_f at
kappa* = A / (zeta - 1); beyond it eta decays to 0.65 eta_f with the slip scale ``softening_slip``),
p0 = 100 kPa, a weak zone (eta0 10 % lower, W/6 wide and W/3 high at the bottom-left corner: the same
region on every mesh with a multiple of 6 elements across) as the trigger, no geometric imperfection,
Q1 B-bar elements (``--order 2``: quadratic) with 12, 18 and 24 elements across the 50 mm width
(h, h/1.5, h/2). Each mesh runs twice: regularised (the softening slip scale of a point is
softening_slip t / h, the band thickness t = 6 mm smeared over the element size h: crack band) and
unregularised (every element softens as if it were one band thickness wide). The variants ``gradient``
(the implicit gradient of length ``--length``) and ``back_stress`` (the gradient back stress
X = H (eps_p - ebar_p) of ``--back-stress H L``, docs/regularisation.md, section 5) regularise with a
length instead, and ``--alphas`` runs every mesh and
variant at several deposition angles (``band_vs_alpha.png``: the band angle against alpha as the band
forms, in the first 0.5 % of axial strain after the peak, and in the last 0.5 %).

Stiffness. The study uses E = 60 MPa (a dense sand; ``--youngs-modulus``), not the thesis's 6 MPa: a
band that softens over a slip s releases the elastic energy of the whole specimen, and the post-peak
path can be followed under displacement control only while the band's softening stiffness, about
(1 - r) q_peak / s, stays below the specimen's elastic stiffness E' / H (no snap-back). With
E = 6 MPa that needs s of 0.15 m or more, i.e. hardly any softening; with 60 MPa, s = 0.03 m follows.
The element itself must not snap back either (crack band: h below a limit that grows with s).

Prints, per run, the peak q, friction and dilatancy angles, the band angle (or that no band formed)
with the Coulomb / Roscoe / Arthur angles, q at three post-peak strains (3.5, 4.5, 6 %); writes
``meshes.csv`` and a plot of all curves. For each setting run on two meshes or more it measures the two
mesh criteria of the study (:mod:`femgran.convergence`) and prints them in a line: the spread of q over the
meshes at every strain from the peak to the end, as a fraction of the peak, and the band's thickness in
each 0.5 % window after the peak against the finest mesh's, in that mesh's elements
(``mesh_convergence_q.csv``, ``mesh_convergence_band.csv``). The runs are a study on the sweep engine
(:mod:`material.sweep`):
``--jobs 2`` runs them two at a time on a local Dask cluster (one numba thread per worker),
``--scheduler ADDRESS`` on an existing cluster; the same command again runs only the runs not yet
complete, and a run stopped part-way (a worker killed: it cannot catch Ctrl-C) goes on from its last
checkpoint, written every ``--checkpoint-every`` steps. The same command with a larger
``--axial-strain`` and ``--steps`` in proportion takes a finished study on to the new end: each run goes
on from its last checkpoint, with the step it had, to what the run aimed there from the start would give. ``meshes.csv`` and the plot collect every run folder
found under ``--out``.

    python examples/fe_04_biaxial_meshes.py [--quick] [--jobs 2] [--resolutions 12 18 24] [--variants ...]
        [--back-stress H L] [--alphas 0 30 60 90] [--height-ratio 3] [--width W] [--order 2] [--rule R]
        [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from femgran.band import is_zone
from femgran.solver import History
from femgran.sweep import STUDY_CHECKPOINT_EVERY
from material.commandline import parse_set, with_changes
from material.parameters import load_preset
from material.planes import DEFAULT_RULE, available_rules, rule_info
from material.sweep import Run, sweep
from material.table import Table

VARIANTS = ("regularised", "unregularised", "gradient", "back_stress")
STYLES = {"crack band": "-", "unregularised": "--"}  # line style of each variant in the plot (gradients: ":")
POST_PEAK_STRAINS = (0.035, 0.045, 0.06)
#: The weak zone: the square of side W/3 centred on the left face at H/12 = W/6, i.e. x < W/6, y < W/3.
WEAK_ZONE_SIZE, WEAK_ZONE_HEIGHT = 1.0 / 3.0, 1.0 / 12.0  # axial strains at which the post-peak q of the meshes is compared


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="mesh 4, regularised only, to the peak (3 %% strain), 10 steps, no stabilisation")
    ap.add_argument("--out", default="out/fe_04_biaxial")
    ap.add_argument("--resolutions", type=int, nargs="+", default=[12, 18, 24],
                    help="elements across the width (multiples of 6: the weak zone is the same region on each)")
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=["regularised", "unregularised"],
                    help="regularised: the crack band; gradient: the implicit gradient of length --length; "
                         "back_stress: the gradient back stress of --back-stress H L")
    ap.add_argument("--length", type=float, default=0.006,
                    help="the gradient's length l [m] (variant gradient; it needs h <= l/3: 24 elements or more "
                         "across for l = 6 mm, docs/regularisation.md section 4)")
    ap.add_argument("--back-stress", type=float, nargs=2, default=[1000.0, 0.006], metavar=("H", "L"),
                    help="variant back_stress: its modulus H [kPa] and length l_b [m] (docs/regularisation.md, "
                         "section 5: 1 MPa and 6 mm keep q within 1.2 %% on 12 elements across and more)")
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.0],
                    help="deposition angles [deg] from the vertical: every mesh and variant runs at each; with "
                         "more than one, band_vs_alpha.png draws the band angle against alpha")
    ap.add_argument("--softening-slip", type=float, default=0.03, help="slip scale of the softening [m]")
    ap.add_argument("--youngs-modulus", type=float, default=60000.0, help="E [kPa]")
    ap.add_argument("--platens", choices=("smooth", "rough"), default="rough")
    ap.add_argument("--element-aspect", type=float, default=1.0,
                    help="height / width of the elements: 1 squares (diagonals at 45 deg), tan(theta) puts "
                         "their diagonals at theta from the horizontal (the mesh's own preferred band angle)")
    ap.add_argument("--height-ratio", type=float, default=2.0,
                    help="specimen height / width (the weak zone stays x < W/6, y < W/3). With rough platens a "
                         "band from the weak zone reaches the free face below the top platen only if tan(theta) < "
                         "H/W - 1/3: 2 bounds it below 59 deg (the finer meshes then form an X at 34-39 deg), 3 "
                         "leaves room for the Coulomb angle (docs/regularisation.md, section 4)")
    ap.add_argument("--weak-zone-at", type=float, default=WEAK_ZONE_HEIGHT * 2.0, metavar="Y",
                    help="height of the weak zone's centre above the bottom platen / W (default 1/6: the zone "
                         "x < W/6, y < W/3); it must lie below the top, Y < --height-ratio. Moving it tests "
                         "whether the trigger sets the band (docs/regularisation.md, section 4); give each "
                         "position its own --out")
    ap.add_argument("--axial-strain", type=float, default=0.06)
    ap.add_argument("--steps", type=int, default=240, help="nominal load steps")
    ap.add_argument("--stabilisation", type=float, default=0.1,
                    help="step stabilisation of the CPA law (0: the thesis's law, which stops past the peak)")
    ap.add_argument("--width", type=float, default=0.05, help="specimen width W [m] (height: --height-ratio W)")
    ap.add_argument("--order", type=int, choices=(1, 2), default=1,
                    help="element order: 1 (Q1 B-bar, the study's) or 2 (quadratic displacement, the gradient's "
                         "field linear; docs/regularisation.md, section 4: the gradient band converges much faster)")
    ap.add_argument("--rule", choices=sorted(available_rules()), default=DEFAULT_RULE,
                    help="integration planes of the CPA law (material.planes; default %(default)s). equator-78 puts "
                         "a plane every 5 deg about the out-of-plane axis; with the default's few planes there the "
                         "arms of a band that ends on a free face turn below the Coulomb angle after the peak "
                         "(docs/regularisation.md, section 4). A rule other than the default names the run folders")
    ap.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                    help="change a CPA parameter on top of the study's (repeatable), e.g. eta_c_ratio=0 for "
                         "associated flow; the run folders' names do not show it, so give each setting its own "
                         "--out")
    ap.add_argument("--easy-steps", type=int, default=None, metavar="N",
                    help="the solver's step grows only after N consecutive easy steps without a cut-back "
                         "(femgran.solver.SolverOptions.easy_steps; 2 saves 40 %% of the evaluations into the "
                         "peak; default: after every easy step, which a study run before the option resumes with)")
    ap.add_argument("--checkpoint-every", type=int, default=STUDY_CHECKPOINT_EVERY, metavar="N",
                    help="a checkpoint every N converged steps of each run (0: only at its end). A run on a Dask "
                         "worker cannot catch Ctrl-C or a kill: the same command again goes on from its last "
                         "checkpoint (default %(default)s)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="runs at a time (worker processes of a local Dask cluster, one numba thread each)")
    ap.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler to run on")
    args = ap.parse_args(argv)
    if args.quick:
        # to the peak only, where the thesis's law needs no stabilisation (10 steps of 0.3 % would give
        # it an overstress of 25 % in q)
        args.resolutions, args.variants, args.axial_strain, args.steps = [4], ["regularised"], 0.03, 10
        args.stabilisation = 0.0
    if args.jobs < 1:
        ap.error(f"--jobs must be at least 1, got {args.jobs}")
    if args.checkpoint_every < 0:
        ap.error(f"--checkpoint-every must be 0 (only at the end) or more, got {args.checkpoint_every}")
    out = Path(args.out)
    try:
        runs = study(args)
    except (KeyError, ValueError) as err:  # a bad length, width or --set: the usage and the message, exit code 2
        ap.error(str(err))
    result = sweep(runs, out, workers=args.jobs, scheduler=args.scheduler, progress=False,
                   title="fe_04 meshes", on_record=_say)
    rows = collect(out)
    _plot(rows, out / "q_vs_eps_a_meshes.png")
    if len({r["alpha_deg"] for r in rows}) > 1:
        _plot_alpha(rows, out / "band_vs_alpha.png", runs[0].kwargs["material"], runs[0].kwargs["fields"]["p0_kPa"])
    if args.alphas == [0.0]:
        return {(int(r["values"]["resolution"]), r["values"]["variant"]): r["summary"] for r in result.records}
    return {(int(r["values"]["resolution"]), r["values"]["variant"], r["values"]["alpha_deg"]): r["summary"]
            for r in result.records}


def study(args) -> list[Run]:
    """The runs: each mesh and variant a biaxial case (:func:`femgran.sweep.case_target`), finest mesh first."""
    changes = {"E": args.youngs_modulus, "zeta": 1.05, "softening_slip": args.softening_slip,
               "residual_ratio": 0.65, **parse_set(args.set)}
    with_changes(load_preset("ottawa_c109"), changes)  # an unknown key or a value out of range: its message here
    material = {"preset": "ottawa_c109", "stabilisation": args.stabilisation, "set": changes}
    if args.rule != DEFAULT_RULE:  # only then, so that a study run before the option resumes as it was
        material["rule"] = args.rule
    fields = {"p0_kPa": 100.0, "alpha_deg": 0.0, "axial_strain": args.axial_strain, "steps": args.steps,
              "imperfection": 0.0, "weak_zone": 0.1, "weak_zone_height": args.weak_zone_at / args.height_ratio,
              "weak_zone_size": WEAK_ZONE_SIZE,
              "platens": args.platens, "element_aspect": args.element_aspect,
              "height_ratio": args.height_ratio}
    if args.width != 0.05:  # only then, so that a study run before the option resumes as it was
        fields["width_m"] = args.width
    if args.order != 1:  # likewise
        fields["order"] = args.order
    back_stress = args.back_stress
    if not 0.0 < args.weak_zone_at < args.height_ratio:
        raise ValueError(f"--weak-zone-at = {args.weak_zone_at!r}: allowed 0 < Y < --height-ratio "
                         f"({args.height_ratio:g}), the weak zone's centre inside the specimen's left face")
    for name, value in (("--length", args.length), ("--back-stress H", back_stress[0]),
                        ("--back-stress L", back_stress[1]), ("--width", args.width)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} = {value!r}: must be > 0 (finite)")
    laws = {"regularised": {**material, "regularise": True}, "unregularised": {**material, "regularise": False},
            "gradient": {**material, "nonlocal_length": args.length},
            "back_stress": {**material, "back_stress_modulus": back_stress[0], "back_stress_length": back_stress[1]}}
    runs = []
    for alpha in args.alphas:
        for n in sorted(args.resolutions, reverse=True):
            for variant in args.variants:
                tag = _tag(n, variant, args.length, args.element_aspect, args.height_ratio, back_stress, alpha,
                           args.order, args.weak_zone_at, args.rule)
                target = {"case": "biaxial", "fields": {**fields, "resolution": n, "alpha_deg": alpha},
                          "material": laws[variant], "checkpoint_every": args.checkpoint_every}
                if args.easy_steps is not None:  # only then, so that a study run before the option resumes as it was
                    target["solver"] = {"easy_steps": args.easy_steps}
                runs.append(Run(tag, "femgran.sweep:case_target", target,
                                {"resolution": n, "variant": variant, "alpha_deg": alpha}))
    return runs


def _tag(n: int, variant: str, length: float, aspect: float = 1.0, height_ratio: float = 2.0,
         back_stress=(1000.0, 0.006), alpha: float = 0.0, order: int = 1,
         weak_zone_at: float = WEAK_ZONE_HEIGHT * 2.0, rule: str = DEFAULT_RULE) -> str:
    suffix = {"regularised": "", "unregularised": "_unregularised", "gradient": f"_gradient_{1e3 * length:g}mm",
              "back_stress": f"_back_stress_{back_stress[0]:g}kPa_{1e3 * back_stress[1]:g}mm"}
    shape = (("" if order == 1 else f"_order_{order}") + ("" if aspect == 1.0 else f"_aspect_{aspect:g}")
             + ("" if height_ratio == 2.0 else f"_height_{height_ratio:g}W")
             + ("" if weak_zone_at == WEAK_ZONE_HEIGHT * 2.0 else f"_weak_zone_at_{weak_zone_at:g}W")
             + ("" if rule == DEFAULT_RULE else f"_rule_{rule}"))
    return f"resolution_{n}" + shape + suffix[variant] + ("" if alpha == 0.0 else f"_alpha_{alpha:g}")


def _variant(folder: Path) -> str:
    """The variant (for the gradients with their length, and the back stress's modulus) a run folder
    holds, from its name."""
    name = folder.name.split("_alpha_")[0]
    if "_gradient_" in name:
        return "gradient " + name.split("_gradient_")[1]
    if "_back_stress_" in name:
        return "back stress " + " ".join(name.split("_back_stress_")[1].split("_"))
    return "unregularised" if name.endswith("_unregularised") else "crack band"


def _rule(folder: Path) -> str:
    """The integration rule of a run folder, from its name (the default's runs do not name it)."""
    name = folder.name.split("_alpha_")[0]
    if "_rule_" not in name:
        return DEFAULT_RULE
    rule = name.split("_rule_")[1]
    return next(r for r in sorted(available_rules(), key=len, reverse=True) if rule.startswith(r))


def _say(rec) -> None:
    """One line per run as it finishes."""
    s = rec["summary"]
    if rec["status"] == "failed":
        print(f"{rec['key']}: failed: {rec['message']}", flush=True)
        return
    ref = {k: s.get(f"reference_angles_deg_{k}", float("nan")) for k in ("coulomb", "roscoe", "arthur")}
    band = f"band at {s['band_angle_deg']:.1f} deg" if s.get("localised") else "no localised band"
    width, section = s.get("band_peak_width_m", float("nan")), s.get("band_section_m", float("nan"))
    if not s.get("localised") and is_zone(s.get("band_contrast", 0.0), width, section):
        band = f"no band: a zone {1e3 * width:.1f} mm wide of a section of {1e3 * section:.1f} mm"
    if s.get("localised") and s.get("band_angle_method", "centre line") != "centre line":
        band += f" ({s['band_angle_method']})"
    print(f"{rec['key']}: peak q {s.get('peak_q_kPa', float('nan')):.1f} kPa; peak phi "
          f"{s.get('peak_friction_deg', float('nan')):.1f}, psi {s.get('peak_dilatancy_deg', float('nan')):.1f} deg; "
          f"{band}; Coulomb {ref['coulomb']:.1f}, Roscoe {ref['roscoe']:.1f}, Arthur {ref['arthur']:.1f} "
          f"[{s.get('stop_reason', rec['message'])}]", flush=True)


def _post_peak_q(history) -> list[float]:
    """q [kPa] at the strains POST_PEAK_STRAINS (NaN beyond the end of the run)."""
    e, q = np.asarray(history["eps_a"]), np.asarray(history["q_kPa"])
    return [float(np.interp(x, e, q)) if x <= e[-1] else float("nan") for x in POST_PEAK_STRAINS]


def collect(out: Path) -> list[dict]:
    """One row per run folder under ``out`` (this process's runs and any other's); writes meshes.csv and
    prints the spread of the post-peak q over the meshes of each variant."""

    rows = []
    for folder in sorted(out.glob("resolution_*")):
        if not (folder / "summary.json").is_file():
            continue  # a run still going, or one that stopped before writing its summary
        h = History.read_csv(folder / "history.csv")
        params = json.loads((folder / "parameters.json").read_text())
        summary = json.loads((folder / "summary.json").read_text())
        status = json.loads((folder / "status.json").read_text()) if (folder / "status.json").is_file() else {}
        n, order = int(params["resolution"]), int(params.get("order", 1))
        variant, rule = _variant(folder), _rule(folder)
        series = (variant + ("" if order == 1 else ", quadratic elements")
                  + ("" if rule == DEFAULT_RULE else f", {rule}"))
        rows.append({"resolution": n, "variant": variant, "order": order, "rule": rule, "series": series,
                     "alpha_deg": float(params.get("alpha_deg", 0.0)),
                     "folder": folder,
                     "element_size_mm": 1e3 * params["width_m"] / n, "history": h,
                     "post_peak_q": _post_peak_q(h), "completed": bool(status.get("completed", False)),
                     **summary,
                     "peak_q_kPa": float(np.nanmax(h["q_kPa"]))})  # the largest q (older summaries: q near it)
    table = Table(title="shear-band study: biaxial runs on several meshes")
    for r in rows:
        ref = r["reference_angles_deg"]
        row = {"resolution": r["resolution"], **_series_columns(r),
               "element_size_mm": r["element_size_mm"], "peak_q_kPa": r["peak_q_kPa"]}
        row.update({f"q_at_{e:g}_kPa": q for e, q in zip(POST_PEAK_STRAINS, r["post_peak_q"])})
        row.update({f"drop_at_{e:g}_kPa": r["peak_q_kPa"] - q for e, q in zip(POST_PEAK_STRAINS, r["post_peak_q"])})
        row.update(final_eps_a=r["history"]["eps_a"][-1], peak_phi_deg=r["peak_friction_deg"],
                   peak_psi_deg=r["peak_dilatancy_deg"], localised=int(r["localised"]), band_angle_deg=r["band_angle_deg"],
                   band_thickness_mm=1e3 * r["band_thickness_m"],
                   coulomb_deg=ref["coulomb"], roscoe_deg=ref["roscoe"], arthur_deg=ref["arthur"],
                   completed=int(r["completed"]))
        table.append(row)
    table.write_csv(out / "meshes.csv")
    for series, alpha in sorted({(r["series"], r["alpha_deg"]) for r in rows}):
        sel = [r for r in rows if r["series"] == series and r["alpha_deg"] == alpha]
        parts = []
        for j, e in enumerate(POST_PEAK_STRAINS):  # only the runs that reached the strain count
            got = [r for r in sel if np.isfinite(r["post_peak_q"][j])]
            if len(got) > 1:
                q = np.array([r["post_peak_q"][j] for r in got])
                drop = np.array([r["peak_q_kPa"] for r in got]) - q
                parts.append(f"at {e:g}: {np.ptp(q):.1f} kPa (of the drop from each mesh's peak: "
                             f"{np.ptp(drop):.1f} kPa) over meshes {[r['resolution'] for r in got]}")
        if parts:
            print(f"{series}" + (f", alpha {alpha:g} deg" if alpha else "") + ": spread of q " + "; ".join(parts))
    _mesh_convergence(rows, out)
    return rows


def _series_columns(row) -> dict:
    """The numeric columns that name a run's series (variant, element order, deposition angle, the number
    of planes of its rule) in the study's tables."""
    variant = row["variant"]
    length = float(variant.split()[1][:-2]) if variant.startswith("gradient") else float("nan")
    back = variant.split()[2:] if variant.startswith("back stress") else ["nan", "nan"]
    return {"order": row["order"], "alpha_deg": row["alpha_deg"], "planes": rule_info(row["rule"])["n_planes"],
            "crack_band": int(variant == "crack band"),
            "gradient_length_mm (NaN: none)": length,
            "back_stress_modulus_kPa (NaN: none)": float(back[0].removesuffix("kPa")),
            "back_stress_length_mm (NaN: none)": float(back[1].removesuffix("mm"))}


def _mesh_convergence(rows, out: Path) -> None:
    """The issue's two mesh criteria for each series run on two meshes or more (:mod:`femgran.convergence`):
    the spread of q at every strain after the peak, and the band's thickness in each 0.5 % window after
    the peak against the finest mesh's. Writes ``mesh_convergence_q.csv`` and ``mesh_convergence_band.csv``
    (one block of rows per series, named by the columns of meshes.csv) and prints a line per series."""
    from femgran.convergence import band_spread, describe, q_spread

    q_all = Table(title="shear-band study: spread of q over the meshes of each series after the peak")
    band_all = Table(title="shear-band study: band thickness per 0.5 % window after the peak against the finest mesh")
    for series, alpha in sorted({(r["series"], r["alpha_deg"]) for r in rows}):
        sel = sorted((r for r in rows if r["series"] == series and r["alpha_deg"] == alpha),
                     key=lambda r: r["resolution"])
        if len(sel) < 2:
            continue
        name = _series_columns(sel[0])
        q = q_spread([r["history"] for r in sel])
        for row in q.rows():
            q_all.append({**name, **row})
        try:
            band = band_spread([r["folder"] for r in sel], [1e-3 * r["element_size_mm"] for r in sel])
        except (FileNotFoundError, ValueError) as err:  # no VTK series, or nothing written after the peak
            band, note = None, f"; the band not compared ({err})"
        else:
            note = ""
            for row in band.rows():
                band_all.append({**name, **row})
        print(f"{series}" + (f", alpha {alpha:g} deg" if alpha else "") + f", meshes "
              f"{[r['resolution'] for r in sel]}: " + describe(q, band) + note, flush=True)
    q_all.write_csv(out / "mesh_convergence_q.csv")
    band_all.write_csv(out / "mesh_convergence_band.csv")


def _plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax_drop) = plt.subplots(1, 2, figsize=(10, 4))
    keys = sorted({(r["series"], r["resolution"], r["alpha_deg"]) for r in rows})
    colours = {k: f"C{i % 10}" for i, k in enumerate(keys)}
    for r in sorted(rows, key=lambda r: (r["series"], r["resolution"], r["alpha_deg"])):
        style = dict(color=colours[(r["series"], r["resolution"], r["alpha_deg"])], ls=STYLES.get(r["variant"], ":"),
                     label=f"h = {r['element_size_mm']:.2f} mm, {r['series']}"
                           + (f", alpha {r['alpha_deg']:g}" if r["alpha_deg"] else ""))
        e, q = r["history"]["eps_a"], r["history"]["q_kPa"]
        ax.plot(e, q, **style)
        ax_drop.plot(e, q - r["peak_q_kPa"], **style)
    ax.set_ylabel("q = s1 - s3 [kPa]")
    ax.set_title("biaxial, CPA with softening: solid = crack band, dashed = none, dotted = gradients", fontsize=9)
    start = 0.8 * min(r["history"]["eps_a"][int(np.nanargmax(r["history"]["q_kPa"]))] for r in rows)
    low = min(np.nanmin(np.where(r["history"]["eps_a"] >= start, r["history"]["q_kPa"] - r["peak_q_kPa"], 0.0))
              for r in rows)
    ax_drop.set_xlim(start, None)
    ax_drop.set_ylim(1.1 * low - 1.0, 5.0)  # the post-peak part
    ax_drop.set_ylabel("q - peak q of the mesh [kPa]")
    ax_drop.set_title("softening from each mesh's own peak", fontsize=9)
    for a in (ax, ax_drop):
        a.set_xlabel("axial strain (compression +)")
        a.legend(fontsize=7)
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _forming_and_final(row, window: float = 0.005) -> dict:
    """The band of ``row``'s run in the first and the last window of ``window`` axial strain after the peak
    (:func:`femgran.band.band_history`): the band as it forms, which the Coulomb, Roscoe and Arthur angles
    speak to, and where the run ends. Of the last window's two arms, the band (the stronger one if both
    are); a window without one gives its stronger arm, with ``localised`` 0 and its fitted width."""
    from femgran.band import band_history

    keys = ("angle_deg", "thickness_m", "localised", "rising", "peak_width_m", "section_m", "contrast", "friction_deg",
            "interior_shear")
    windows = band_history(row["folder"], window)
    if not len(windows):  # the run ended at its peak: no window after it
        return {name: {**dict.fromkeys(keys, float("nan")), "localised": 0.0, "eps": (float("nan"),) * 2}
                for name in ("forming", "final")}
    out = {}
    for name, i in (("forming", 0), ("final", len(windows) - 1)):
        prefix = "" if windows["localised"][i] or not windows["conjugate_localised"][i] else "conjugate_"
        out[name] = {key: float(windows[prefix + key][i]) for key in keys}
        out[name]["eps"] = (float(windows["eps_from"][i]), float(windows["eps_to"][i]))
    return out


def _law_angles(row, bands: dict) -> np.ndarray:
    """The band the law forms at the friction inside the arm of the forming and the final window of
    :func:`_forming_and_final` (:func:`femgran.band.law_band_angles`, the run's material from its case.toml),
    in each arm's sense, on the element sheared as the inside of the arm is and on the one sheared the other
    way (they differ only on a mirror-symmetric bedding); NaN for a window without a friction. Prints them;
    returns (2 shears, 2 windows)."""
    from femgran.band import law_band_angles, run_material

    material, alpha, p0 = run_material(row["folder"])
    names = ("forming", "final")
    inside = np.array([bands[n]["interior_shear"] for n in names])
    friction = [bands[n]["friction_deg"] for n in names]
    rising = [bool(bands[n]["rising"] > 0.5) for n in names]
    # one element path: each window read as sheared as the arm's inside, then the other way
    angles, indicator = law_band_angles(material, alpha, p0, friction * 2, rising * 2,
                                        interior_shear=np.concatenate([inside, -inside]))
    out = np.full((2, 2), np.nan)
    for k, how in enumerate(("as the inside of the arm", "the other way")):
        part = slice(2 * k, 2 * k + 2)
        print(f"  alpha {alpha:g}: the law's band at the friction inside the arm (element sheared {how}), "
              + "; ".join(f"{n} {bands[n]['friction_deg']:.1f} deg -> {v:.2f} deg, indicator {x:+.3f} (the arm "
                          f"{bands[n]['angle_deg']:.1f})" for n, v, x in zip(names, angles[part], indicator[part])),
              flush=True)
        # not drawn where the acoustic tensor is strongly indefinite: there its least det points nowhere in
        # particular (measured on these paths: -0.03 to +0.005 where bands form, -0.87 to -1.0 in those states,
        # nothing between)
        out[k] = np.where(indicator[part] > -0.5, angles[part], np.nan)
    return out


def _describe(name: str, b: dict) -> str:
    """One window of :func:`_forming_and_final` in words."""
    if np.isnan(b["eps"][0]):
        return f"{name}: no window after the peak"
    head = f"{name} ({100 * b['eps'][0]:.2f}-{100 * b['eps'][1]:.2f} %): "
    if b["localised"]:
        return head + (f"band at {b['angle_deg']:.1f} deg, {'rising' if b['rising'] else 'falling'}, "
                       f"{1e3 * b['thickness_m']:.1f} mm")
    return head + (f"no band (widest peak {1e3 * b['peak_width_m']:.1f} mm of a section of "
                   f"{1e3 * b['section_m']:.1f} mm, contrast {b['contrast']:.2g})")


def _plot_alpha(rows, path, material_spec: dict | None = None, p0_kPa: float = 100.0):
    """The band angle against the deposition angle, one line per variant and mesh, in the first window of
    0.5 % axial strain after the peak (circles: the band as it forms) and in the last (squares), with the
    Coulomb, Roscoe and Arthur angles from each run's own peak (an open marker: no band in that window, a
    zone or a diffuse field: :attr:`femgran.band.Band.verdict`), the other arm of the X over the whole post-peak
    increment (triangles, where there is one), the band the law itself forms at the friction inside the arm
    in each of the two windows (crosses: on the element sheared as the inside of the arm; plus signs: sheared
    the other way, where that differs, on a mirror-symmetric bedding; :func:`_law_angles`), and, for ``material_spec`` (the study's sand) at its lateral
    stress ``p0_kPa``, Rice's onset on the plane-strain element path for the rising and the falling bands
    (:func:`femgran.figures.rice_onset_angles`: rate-independent, so with ``equator-78``, whose
    rate-independent element path stops at the peak below alpha = 90, none);
    and beside it, for the finest mesh of the first variant, the deviatoric strain increment from the peak to
    the end of each run. Prints each run's two windows and Rice's angles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    groups = sorted({(r["series"], r["resolution"]) for r in rows})
    finest = max((g for g in groups if g[0] == groups[0][0]), key=lambda g: g[1])
    panels = sorted((r for r in rows if (r["series"], r["resolution"]) == finest), key=lambda r: r["alpha_deg"])
    series = [(i, g, sorted((r for r in rows if (r["series"], r["resolution"]) == g), key=lambda r: r["alpha_deg"]))
              for i, g in enumerate(groups)]
    series = [(i, g, sel) for i, g, sel in series if len(sel) > 1]  # a line needs two angles
    fig = plt.figure(figsize=(6 + 2.2 * len(panels), 4.6 + 0.16 * (len(series) + 3)))  # room for the legend
    grid = fig.add_gridspec(1, 1 + len(panels), width_ratios=[2.6] + [1] * len(panels))
    ax = fig.add_subplot(grid[0, 0])
    reference, legend = None, []
    for i, (variant, n), sel in series:
        a = np.array([r["alpha_deg"] for r in sel])
        bands = [_forming_and_final(r) for r in sel]
        for r, b in zip(sel, bands):
            print(f"{variant}, {n} elements, alpha {r['alpha_deg']:g}: "
                  + "; ".join(_describe(name, b[name]) for name in ("forming", "final")), flush=True)
        # the law's own band at the friction inside the arm in each window (femgran.band.law_band_angles): where
        # the arm follows it, the law sets the angle, not the mesh or the platens
        law = np.array([_law_angles(r, b) for r, b in zip(sel, bands)])  # (runs, shears, windows)
        ax.scatter(np.repeat(a, 2), law[:, 0].ravel(), color=f"C{i}", marker="x", s=22, lw=0.9,
                   label=f"{variant}, {n} elements across, the law's band at the friction inside")
        other_way = law[:, 1] != law[:, 0]  # the element path sheared the other way (mirror-symmetric beddings)
        ax.scatter(np.repeat(a, 2)[other_way.ravel()], law[:, 1][other_way], color=f"C{i}", marker="+", s=30,
                   lw=0.9, label=f"{variant}, {n} elements across, the same, element sheared the other way")
        for name, marker, ls in (("forming", "o", "-"), ("final", "s", "--")):
            angle = np.array([b[name]["angle_deg"] for b in bands])
            band = np.array([bool(b[name]["localised"]) for b in bands])
            label = f"{variant}, {n} elements across, {'as it forms' if name == 'forming' else 'last window'}"
            (line,) = ax.plot(a, angle, ls, color=f"C{i}", lw=0.8, label=label)
            if name == "forming":  # one legend entry per series: the title says which marker is which window
                legend.append((line, f"{variant}, {n} elements across"))
            ax.scatter(a[band], angle[band], color=f"C{i}", marker=marker)
            ax.scatter(a[~band], angle[~band], facecolors="none", edgecolors=f"C{i}", marker=marker)
        # the other arm of the X over the whole post-peak increment (the summary's conjugate band): with
        # inclined bedding the two arms are not symmetric, and either may be the one the law's tangent selects
        other = np.array([float(r.get("conjugate_band_angle_deg", np.nan)) for r in sel])
        if np.isfinite(other).any():  # filled where the summary calls that arm a band, open where not
            ax.plot(a, other, ":", color=f"C{i}", lw=0.8, label=f"{variant}, {n} elements across, the other arm, peak to end")
            other_band = np.array([bool(r.get("conjugate_localised", False)) for r in sel])
            ax.scatter(a[other_band], other[other_band], color=f"C{i}", marker="v")
            ax.scatter(a[~other_band], other[~other_band], facecolors="none", edgecolors=f"C{i}", marker="v")
        if reference is None:
            reference = (a, sel)
    if reference is not None:  # the first series' own Coulomb, Roscoe and Arthur angles
        a, sel = reference
        for ref, style in (("coulomb", ":"), ("roscoe", "--"), ("arthur", "-.")):
            (line,) = ax.plot(a, [r["reference_angles_deg"][ref] for r in sel], style, color="k", lw=0.8, label=ref)
            legend.append((line, ref))
        legend.append((ax.scatter([], [], color="k", marker="x", s=22, lw=0.9),
                       "x: the law's band inside the arm (Rice, element sheared as its inside; band --law)"))
        legend.append((ax.scatter([], [], color="k", marker="+", s=30, lw=0.9),
                       "+: the same, element sheared the other way (alpha = 0, 90)"))
        if material_spec is not None:  # the law's own bands, each family (the X's arms need not be mirror images)
            from femgran.figures import rice_onset_angles

            angles, onset = rice_onset_angles(material_spec, float(p0_kPa), alphas=tuple(a))
            for family, style in (("falling", "-"), ("rising", "--")):
                print(f"Rice's onset on the element path, {family} bands: "
                      + ", ".join(f"alpha {g:g}: {v:.2f} deg" for g, v in zip(angles, onset[family])), flush=True)
                (line,) = ax.plot(angles, onset[family], style, color="0.55", lw=2.2, zorder=0,
                                  label=f"Rice, {family} bands")
                legend.append((line, f"Rice's onset (element, rate-independent), {family} bands"))
    ax.set(xlabel="deposition angle alpha [deg]", ylabel="band angle from the minor stress direction [deg]",
           title="the band against the bedding, first (o) and last (s) 0.5 % window\n"
                 "after the peak; open: no band in that window (a zone or diffuse);\n"
                 "v: the other arm, from the peak to the end")
    ax.title.set_fontsize(9)
    ax.legend(*zip(*legend), fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1,
              frameon=False)  # below the axes
    ax.grid(alpha=0.3)
    for k, r in enumerate(panels):
        axf = fig.add_subplot(grid[0, 1 + k])
        _post_peak_field(axf, r)
        axf.set_title(f"alpha = {r['alpha_deg']:g} deg", fontsize=9)
        axf.set_axis_off()
    fig.tight_layout()
    if panels:
        fig.text(0.5 + 0.5 * 2.6 / (2.6 + len(panels)), 0.02, f"deviatoric strain increment from the peak to the end, "
                 f"{finest[0]}, {finest[1]} elements across (each panel on its own scale)", ha="center", fontsize=8)
    save_figure(fig, path)  # and the angles it draws as a CSV of the same stem


def _post_peak_field(ax, row):
    """The deviatoric strain increment (element averages of the VTK cell field ``strain``) from the first
    written step within 1 % of the peak q to the last one (where :func:`femgran.band.band_history` starts and
    ends), drawn on the mesh of ``row``'s run."""
    from matplotlib.collections import PolyCollection

    from femgran.band import deviatoric_intensity, read_cells, written_steps

    _, _, paths, start = written_steps(row["folder"])
    _, e0 = read_cells(paths[start])
    corners, e1 = read_cells(paths[-1])
    pc = PolyCollection(corners, array=deviatoric_intensity(e1 - e0), cmap="magma", edgecolors="face",
                        linewidths=0.1)
    ax.add_collection(pc)
    ax.set_aspect("equal")
    ax.autoscale_view()


if __name__ == "__main__":
    main()
