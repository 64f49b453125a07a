"""``femgran element ...``: single-point element tests of the CPA law from the command line.

Examples::

    femgran element triaxial                        # ottawa_c109, p0 = 100 kPa, alpha = 0 and 90 -> out/element
    femgran element triaxial --p0 50 100 --alpha 0 90 --steps 300
    femgran element direct-shear --sigma-n 10 50 75 --alpha 0 45 90
    femgran element rotation --dpsi 0 45 90 --set beta=5
    femgran element path lab.csv --substeps 5      # replay lab data (see material.driver.LoadPath.from_csv)
    femgran element path path.toml                 # a path declared as data (LoadPath.from_toml)

Every run of the sweep (:mod:`material.sweep`: one after the other here, or ``--workers N`` / ``--scheduler
ADDRESS`` on Dask; the same command again skips the runs already complete) writes into its own folder
under ``--out`` (default ``out/element``): ``<test>_<tag>/<test>.csv`` (tag e.g. ``p0_100_alpha_90``, a
commented header). Next to them: one PNG overlaying the runs, ``summary.csv`` (peak stress, final volume
change per run), the parameter file used (``parameters.toml``) and ``run.json`` (command, options,
package version, seed = none: the tests are deterministic).
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

from material.commandline import add_out, add_parameters, add_progress, parameters_from_args, parse_set, write_run_record

__all__ = ["register"]

# test name -> (driver function, swept options as (cli dest, driver keyword, default list))
_SWEEPS = {
    "triaxial": [("p0", "p0_kPa", [100.0]), ("alpha", "alpha_deg", [0.0, 90.0])],
    "oedometer": [("p0", "p0_kPa", [10.0]), ("alpha", "alpha_deg", [0.0])],
    "plane-strain": [("p0", "p0_kPa", [100.0]), ("alpha", "alpha_deg", [0.0, 90.0])],
    "true-triaxial": [("p0", "p0_kPa", [100.0]), ("alpha", "alpha_deg", [0.0]), ("b", "b", [0.0, 0.5, 1.0])],
    "direct-shear": [("sigma_n", "sigma_n_kPa", [50.0]), ("alpha", "alpha_deg", [0.0, 90.0])],
    "simple-shear": [("sigma_n", "sigma_n_kPa", [50.0]), ("alpha", "alpha_deg", [0.0, 90.0])],
    "cyclic-simple-shear": [("sigma_n", "sigma_n_kPa", [50.0]), ("alpha", "alpha_deg", [0.0])],
    "rotation": [("p0", "p0_kPa", [14.0]), ("dpsi", "delta_psi_deg", [0.0, 90.0])],
    "path": [],
}
_SWEEP_FLAGS = {"p0": "--p0", "alpha": "--alpha", "sigma_n": "--sigma-n", "b": "--b", "dpsi": "--dpsi"}
_SWEEP_HELP = {
    "p0": "initial isotropic (cell) pressure(s) [kPa]",
    "alpha": "deposition angle(s) between the loading axis (shear-plane normal) and e2 [deg]",
    "sigma_n": "normal stress(es) on the shear plane [kPa]",
    "b": "intermediate principal stress ratio(s) b = (s2 - s3)/(s1 - s3)",
    "dpsi": "rotation(s) of the major principal stress between pre-shear and reshear [deg]",
}
_HELP = {
    "triaxial": "drained/undrained triaxial compression or extension (Figs. 20-21)",
    "oedometer": "K0 compression (all lateral and shear strains zero)",
    "plane-strain": "biaxial plane-strain compression, sigma3 held, eps_yy = 0",
    "true-triaxial": "true triaxial compression at constant b",
    "direct-shear": "direct shear as simple shear of a band of thickness t (Figs. 5-8, 16-19)",
    "simple-shear": "simple shear at constant normal stress or constant height",
    "cyclic-simple-shear": "strain-controlled cyclic simple shear",
    "rotation": "principal stress rotation in plane strain, directional shear cell (Figs. 45-47)",
    "path": "replay a mixed stress/strain path from a CSV of lab data",
}


def register(subparsers) -> None:
    """Add ``femgran element TEST ...`` to the top-level parser."""
    element = subparsers.add_parser(
        "element",
        help="single-point element tests of the material law (material.driver)",
        description="Single-point element tests; writes CSV + PNG + parameters + run.json into --out.",
    )
    tests = element.add_subparsers(dest="test", metavar="TEST")
    tests.required = True
    common = argparse.ArgumentParser(add_help=False)
    g = common.add_argument_group("material and output")
    add_parameters(g, preset_default=None)  # default ottawa_c109; ottawa_c109_induced for rotation
    g.add_argument("--rule", default="bazant-oh-33", help="plane integration rule (material.planes.available_rules())")
    g.add_argument("--stabilisation", type=float, default=0.0, metavar="MU",
                   help="the CPA step stabilisation (default 0: the thesis's law; the FE cases' --stabilisation, "
                        "docs/cpa_law.md section 4)")
    g.add_argument("--steps", type=int, default=None, help="load steps of the main stage (default: the driver's)")
    add_out(g, "out/element")
    add_progress(g)
    g.add_argument("--no-plot", action="store_true", help="skip the PNG")
    g.add_argument("--workers", type=int, default=1,
                   help="worker processes of a local Dask cluster for the runs (default 1: here, one by one; "
                        "element tests are quick)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler (tcp://host:8786) to run the tests on")

    for name, sweeps in _SWEEPS.items():
        p = tests.add_parser(name, parents=[common], help=_HELP[name], description=_HELP[name])
        for dest, _, default in sweeps:
            p.add_argument(_SWEEP_FLAGS[dest], dest=dest, type=float, nargs="+", default=default,
                           help=f"{_SWEEP_HELP[dest]} (default {' '.join(f'{v:g}' for v in default)})")
        _add_specific(p, name)
        p.set_defaults(func=_run)


def _add_specific(p, name: str) -> None:
    if name in ("triaxial", "oedometer", "plane-strain", "true-triaxial"):
        default = {"triaxial": 0.15, "oedometer": 0.02}.get(name, 0.1)
        p.add_argument("--axial-strain", type=float, default=default, help=f"axial strain applied (default {default})")
    if name == "triaxial":
        p.add_argument("--undrained", action="store_true", help="constant volume, report the excess pore pressure")
        p.add_argument("--extension", action="store_true", help="axial extension instead of compression")
    if name == "direct-shear":
        p.add_argument("--displacement", type=float, default=0.006, help="shear displacement [m] (default 0.006)")
    if name in ("simple-shear",):
        p.add_argument("--gamma", type=float, default=0.2, help="engineering shear strain (default 0.2)")
    if name in ("simple-shear", "cyclic-simple-shear"):
        p.add_argument("--constant-height", action="store_true", help="hold the normal strain instead of the normal stress")
    if name == "cyclic-simple-shear":
        p.add_argument("--amplitude", type=float, default=0.005, help="shear strain amplitude (default 0.005)")
        p.add_argument("--cycles", type=int, default=3, help="number of cycles (default 3)")
    if name == "rotation":
        p.add_argument("--preshear-strain", type=float, default=0.02, help="pre-shear strain along x (default 0.02)")
        p.add_argument("--axial-strain", type=float, default=0.05, help="reshear strain along the rotated axis (default 0.05)")
    if name == "path":
        p.add_argument("csv", metavar="FILE",
                       help="CSV with columns sig_<c>_kPa / eps_<c> per component (tension +), or a TOML path "
                            "declared as segments (material.driver.LoadPath.from_toml)")
        p.add_argument("--substeps", type=int, default=1, help="load steps per CSV row (default 1)")


def _parameters(args):
    return parameters_from_args(args, "ottawa_c109_induced" if args.test == "rotation" else "ottawa_c109")


def _specific_kwargs(args) -> dict:
    t = args.test
    kw: dict = {}
    if args.steps is not None:
        kw["steps" if t != "cyclic-simple-shear" else "steps_per_quarter"] = args.steps
    if t in ("triaxial", "oedometer", "plane-strain", "true-triaxial", "rotation"):
        kw["axial_strain"] = args.axial_strain
    if t == "triaxial":
        kw.update(drained=not args.undrained, extension=args.extension)
    if t == "direct-shear":
        kw["shear_displacement"] = args.displacement
    if t == "simple-shear":
        kw.update(shear_strain=args.gamma, constant_height=args.constant_height)
    if t == "cyclic-simple-shear":
        kw.update(gamma_amplitude=args.amplitude, cycles=args.cycles, constant_height=args.constant_height)
    if t == "rotation":
        kw["preshear_strain"] = args.preshear_strain
    return kw


def _material_spec(args) -> dict:
    """The ``[material]`` mapping of the flags (what :func:`material.sweep.element` and the factory take)."""
    spec = {"parameters": str(Path(args.params).resolve())} if args.params else \
        {"preset": args.preset or ("ottawa_c109_induced" if args.test == "rotation" else "ottawa_c109")}
    changes = parse_set(args.set)
    stabilised = {"stabilisation": args.stabilisation} if args.stabilisation else {}
    return {**spec, **({"set": changes} if changes else {}), "rule": args.rule, **stabilised}


def _runs(args) -> list:
    """One :class:`material.sweep.Run` per combination of the swept values (folder ``<test>_<tag>``)."""
    from material.sweep import Run

    stem = args.test.replace("-", "_")
    spec = _material_spec(args)
    if args.test == "path":
        tag = Path(args.csv).stem
        kw = {"path_file": str(Path(args.csv).resolve()), "substeps": args.substeps}
        return [Run(f"path_{tag}", "material.sweep:element", {"test": "path", "material": spec, **kw}, {})]
    from material.base import check_positive

    sweeps = _SWEEPS[args.test]
    for dest, key, _ in sweeps:  # bad values are named before anything runs
        if key in ("p0_kPa", "sigma_n_kPa"):
            for v in getattr(args, dest):
                check_positive(key, v)
    runs = []
    for combo in itertools.product(*(getattr(args, dest) for dest, _, _ in sweeps)):
        kw = {key: v for (_, key, _), v in zip(sweeps, combo)}
        tag = "_".join(f"{dest}_{v:g}" for (dest, _, _), v in zip(sweeps, combo))
        runs.append(Run(f"{stem}_{tag}", "material.sweep:element",
                        {"test": args.test, "material": spec, **kw, **_specific_kwargs(args)}, kw))
    return runs


def _run(args) -> int:
    from material.parameters import save_parameters
    from material.results import read_csv as read_result
    from material.sweep import sweep
    from material.version import __version__

    params = _parameters(args)  # checks the preset, file and --set before anything runs
    if args.stabilisation:
        from material.factory import make_material

        make_material(_material_spec(args))  # and the stabilisation
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = args.test.replace("-", "_")
    t0 = time.perf_counter()
    result = sweep(_runs(args), out, scheduler=args.scheduler, workers=args.workers,
                   progress=args.progress and args.workers != 1, title=f"element {args.test}")
    runs, files = [], []
    for rec in result.records:
        csv = out / rec["key"] / f"{stem}.csv"
        if rec["status"] == "failed" or not csv.is_file():
            print(f"femgran element {args.test}: {rec['key']}: failed: {rec['message']}", file=sys.stderr)
            continue
        res = read_result(csv)
        runs.append((rec["key"].removeprefix(stem + "_"), rec, res))
        files.append(str(csv.relative_to(out)))
        if rec["status"] != "completed":
            print(f"femgran element {args.test}: {rec['key']}: stopped early: {rec['message']}", file=sys.stderr)
    if not args.no_plot and runs:
        files.append(_plot(runs, out / f"{stem}.png", f"{args.test} ({params.name})").name)
    save_parameters(params, out / "parameters.toml", femgran_version=__version__)
    files += ["parameters.toml", "summary.csv"]
    write_run_record(out, args, test=args.test, seed=None, deterministic=True,
                     wall_time_s=round(time.perf_counter() - t0, 3),
                     runs=[{"tag": r["key"], "status": r["status"], "message": r["message"]} for r in result.records],
                     ran=result.ran, skipped=result.skipped, files=files)
    print(f"femgran element {args.test}: {len(result.records)} run(s) -> {out}/ ({result.ran} run now, "
          f"{result.skipped} already complete; {', '.join(files)})")
    for tag, _, res in runs:
        print("  " + _summary(tag, res))
    return 0 if result.completed else 1


def _summary(tag: str, res) -> str:
    bits = [tag]
    for col in ("tau_kPa", "t_kPa", "q_kPa"):
        if col in res:
            bits.append(f"max {col} = {res[col].max():.4g}")
            break
    for col in ("normal_displacement_m", "eps_v"):
        if col in res:
            bits.append(f"final {col} = {res[col][-1]:.4g}")
            break
    if "bifurcation" in res.metadata:
        onset = res.metadata["bifurcation"]
        bits.append("elliptic throughout (no band by Rice's condition)" if onset is None else
                    f"a band can form from eps_a = {onset['eps_a']:.4g} (q13 = {onset['q13_kPa']:.4g} kPa), "
                    f"inclined {onset['band_deg']:.1f} deg to the sigma3 axis" + _family(onset))
    sheared = res.metadata.get("shear_onset")
    if sheared is not None:
        bits.append(f"the symmetric path branches at eps_a = {sheared['eps_a']:.4g}: the point shears "
                    f"(eps_xz {'> 0' if sheared['sense'] > 0 else '< 0'} after it, a sense round-off decides)")
    if not res.completed:
        bits.append("STOPPED EARLY")
    return ", ".join(bits)


def _family(onset: dict) -> str:
    """Which family of bands the onset is in, and the other family's nearest band."""
    family = onset.get("family")
    if family is None:
        return ""
    if family == "both":
        return " (rising and falling alike)"
    other = "falling" if family == "rising" else "rising"
    return f" ({family}; the nearest {other} band {onset[other + '_deg']:.1f} deg)"


def _plot(runs, path: Path, title: str) -> Path:
    from matplotlib.figure import Figure

    pairs = runs[0][2].plot_pairs or [("eps_q", "q_kPa"), ("eps_q", "eps_v")]
    fig = Figure(figsize=(5.0 * len(pairs), 4.0), layout="constrained")
    axes = fig.subplots(1, len(pairs), squeeze=False)[0]
    for tag, _, res in runs:
        for ax, (x, y) in zip(axes, pairs):
            ax.plot(res[x], res[y], lw=1.5, label=tag + ("" if res.completed else " (stopped)"))
    for ax, (x, y) in zip(axes, pairs):
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    return path
