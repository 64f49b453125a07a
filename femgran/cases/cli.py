"""``femgran triaxial|footing|biaxial|run`` subcommands (boundary-value problems).

Examples::

    femgran triaxial --alpha 0 45 90 --platens rough            # -> out/triaxial/alpha_0 ... + comparison
    femgran footing --alpha 0 30 60 90 --surcharge 10           # bearing capacity vs bedding angle
    femgran footing --law von_mises --E 30000 --yield 173.2 --unit-weight 0   # Prandtl check
    femgran biaxial --resolution 8 16 32                        # three meshes on one plot
    femgran run case.toml                                       # a case file (femgran.cases.casefile)

A sweep (several values of --alpha or --resolution) writes one run folder per value under --out,
plus ``summary.csv`` and a comparison PNG.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from material.commandline import add_out, add_parameters, add_progress, parse_set, write_run_record

__all__ = ["register"]


def _material(args, alpha, plane_strain):
    from femgran.cases.casefile import build_material

    if args.law == "cpa":
        spec = {"law": "cpa", "set": parse_set(args.set), "stabilisation": args.stabilisation}
        spec.update({"parameters": args.params} if args.params else {"preset": args.preset})
    elif args.law == "von_mises":
        spec = {"law": "von_mises", "E_kPa": args.E, "nu": args.nu, "yield_stress_kPa": args.yield_stress}
    elif args.law == "drucker_prager":
        spec = {"law": "drucker_prager", "E_kPa": args.E, "nu": args.nu, "cohesion_kPa": args.cohesion,
                "friction_deg": args.friction}
    else:
        spec = {"law": "linear_elastic", "E_kPa": args.E, "nu": args.nu}
    return build_material(spec, alpha, plane_strain)


def _common(p, default_out):
    g = p.add_argument_group("material")
    g.add_argument("--law", choices=["cpa", "von_mises", "drucker_prager", "linear_elastic"], default="cpa")
    add_parameters(g)
    g.add_argument("--stabilisation", type=float, default=0.0, metavar="MU",
                   help="CPA step stabilisation (default 0: the thesis's law; 0.1 lets the non-associated sand "
                        "carry a footing to its end, docs/cpa_law.md section 4)")
    g.add_argument("--E", type=float, default=3e4, help="Young's modulus of the reference laws [kPa]")
    g.add_argument("--nu", type=float, default=0.3, help="Poisson's ratio of the reference laws")
    g.add_argument("--yield-stress", type=float, default=100.0 * np.sqrt(3), help="von Mises yield stress [kPa]")
    g.add_argument("--cohesion", type=float, default=1.0, help="Drucker-Prager cohesion [kPa]")
    g.add_argument("--friction", type=float, default=35.0, help="Drucker-Prager friction angle [deg]")
    p.add_argument("--alpha", type=float, nargs="+", default=[0.0], help="deposition angle(s) [deg]")
    p.add_argument("--steps", type=int, default=None, help="nominal number of load steps")
    p.add_argument("--order", type=int, choices=[1, 2], default=None, help="element order")
    _solver_flags(p)
    add_out(p, default_out)
    add_progress(p)


def _solver_flags(p):
    s = p.add_argument_group("solver (femgran.solver.SolverOptions; default: its values)")
    s.add_argument("--tol", type=float, default=None, help="relative residual tolerance of the Newton iterations")
    s.add_argument("--max-iter", type=int, default=None, help="Newton iterations per attempt of a step")
    s.add_argument("--max-cuts", type=int, default=None, help="successive step cut-backs before a clean stop")
    s.add_argument("--line-search", type=int, default=None, metavar="K",
                   help="shortest line-search step 2**-K of the Newton step (0: plain Newton)")
    s.add_argument("--predictor", choices=["extrapolate", "tangent", "none"], default=None,
                   help="first guess of each step's displacements")
    s.add_argument("--linear-solver", default=None, choices=["auto", "superlu", "amg-gmres", "ilu-gmres"],
                   help="auto: SuperLU for small and plane-strain problems, AMG-GMRES for large 3D ones")


_SOLVER_FLAGS = ("tol", "max_iter", "max_cuts", "line_search", "predictor", "linear_solver")


def _solver_given(args) -> dict:
    return {k: getattr(args, k) for k in _SOLVER_FLAGS if getattr(args, k) is not None}


def _kw(args, **extra):
    from femgran.cases.common import solver_options

    kw = {"solver": solver_options(_solver_given(args)), "progress": args.progress}
    if args.steps is not None:
        kw["steps"] = args.steps
    if args.order is not None:
        kw["order"] = args.order
    kw.update(extra)
    return kw


def _sweep(args, func, plane_strain, label, values, key, metric, fixed):
    out = Path(args.out)
    rows = []
    sols = []
    for v in values:
        alpha = v if key == "alpha_deg" else args.alpha[0]
        kw = dict(fixed)
        kw[key] = v
        if key != "alpha_deg":
            kw["alpha_deg"] = alpha
        run_dir = out / f"{label}_{v:g}" if len(values) > 1 else out
        sol = func(material=_material(args, alpha, plane_strain), out=run_dir, **kw)
        sols.append((v, sol))
        rows.append((v, metric(sol), sol.completed))
        print(f"{label} = {v:g}: {metric.__doc__} = {metric(sol):.4g}; {sol.stop_reason}; results in {run_dir}")
    write_run_record(out, args, runs=[{"value": v, "metric": m, "completed": c} for v, m, c in rows])
    if len(values) > 1:
        from material.table import Table

        columns = {label: [r[0] for r in rows], metric.__doc__: [r[1] for r in rows], "completed": [r[2] for r in rows]}
        Table(columns, {"completed": "1 if the run reached its end, 0 if it stopped"}, {"command": args.command},
              title=f"{args.command} sweep over {label}").write_csv(out / "summary.csv")
    return sols


def _overlay(sols, x, y, path, label, xlabel, ylabel):
    from femgran.output import plot_curves

    plot_curves([(f"{label} = {v:g}", s.history[x], s.history[y], "-") for v, s in sols], path, xlabel=xlabel,
                ylabel=ylabel)


def _triaxial(args):
    from femgran.cases.triaxial import triaxial

    def metric(s):
        """peak_q_kPa"""
        return s.peak_q_kPa

    fixed = _kw(args, p0_kPa=args.p0, platens=args.platens, axial_strain=args.axial_strain, resolution=args.resolution,
                friction=args.platen_friction)
    if args.mesh:
        fixed["mesh"] = args.mesh
    sols = _sweep(args, triaxial, False, "alpha", args.alpha, "alpha_deg", metric, fixed)
    if len(sols) > 1:
        _overlay(sols, "eps_a", "q_kPa", Path(args.out) / "q_vs_eps_a.png", "alpha", "axial strain [-]", "q [kPa]")
        _overlay(sols, "eps_a", "cv_q", Path(args.out) / "uniformity.png", "alpha", "axial strain [-]",
                 "coefficient of variation of sqrt(3 J2) [-]")
    return 0


def _footing(args):
    from femgran.cases.footing import footing

    def metric(s):
        """bearing_capacity_kPa"""
        return s.bearing_capacity_kPa

    fixed = _kw(args, width_m=args.width, unit_weight=args.unit_weight, surcharge_kPa=args.surcharge,
                rough=not args.smooth, resolution=args.resolution)
    if args.settlement is not None:
        fixed["settlement_m"] = args.settlement
    if args.mesh:
        fixed["mesh"] = args.mesh
    sols = _sweep(args, footing, True, "alpha", args.alpha, "alpha_deg", metric, fixed)
    if len(sols) > 1:
        _overlay(sols, "settlement_m", "pressure_kPa", Path(args.out) / "load_settlement.png", "alpha",
                 "settlement [m]", "mean footing pressure [kPa]")
    return 0


def _biaxial(args):
    from femgran.cases.biaxial import biaxial

    def metric(s):
        """band_angle_deg"""
        return s.band_angle_deg

    fixed = _kw(args, p0_kPa=args.p0, axial_strain=args.axial_strain, imperfection=args.imperfection,
                alpha_deg=args.alpha[0], platens=args.platens, weak_zone=args.weak_zone,
                weak_zone_height=args.weak_zone_height)
    sols = _sweep(args, biaxial, True, "resolution", [int(r) for r in args.resolution], "resolution", metric, fixed)
    if len(sols) > 1:
        _overlay(sols, "eps_a", "q_kPa", Path(args.out) / "q_vs_eps_a_meshes.png", "resolution", "axial strain [-]", "q [kPa]")
    return 0


def _run(args):
    from femgran.cases.casefile import run_case

    sol = run_case(args.case_file, progress=args.progress, solver=_solver_given(args))
    if sol.out_dir is not None:
        write_run_record(sol.out_dir, args, completed=sol.completed, stop_reason=sol.stop_reason)
    print(f"{sol.stop_reason}; {len(sol.history) - 1} steps; results in {sol.out_dir}")
    return 0 if sol.completed else 1


def register(subparsers) -> None:
    """Add ``triaxial``, ``footing``, ``biaxial`` and ``run``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = subparsers.add_parser("triaxial", help="3D triaxial specimen between rigid platens", formatter_class=fmt,
                              description="Drained triaxial compression of the 50x50x100 mm specimen (femgran.cases.triaxial).")
    _common(p, "out/triaxial")
    p.add_argument("--p0", type=float, default=100.0, help="cell pressure [kPa]")
    p.add_argument("--platens", choices=["rough", "smooth", "frictional"], default="rough")
    p.add_argument("--platen-friction", type=float, default=0.3, help="platen friction coefficient (--platens frictional)")
    p.add_argument("--axial-strain", type=float, default=0.15, help="final axial strain (default 0.15, the thesis's)")
    p.add_argument("--resolution", type=int, default=4, help="elements across the width")
    p.add_argument("--mesh", help="mesh file (meshio) filling [0,0.05]^2 x [0,0.1] m")
    p.set_defaults(func=_triaxial)

    p = subparsers.add_parser("footing", help="plane-strain rigid strip footing", formatter_class=fmt,
                              description="Load-settlement curve and bearing capacity (femgran.cases.footing).")
    _common(p, "out/footing")
    p.add_argument("--width", type=float, default=1.0, help="footing width B [m]")
    p.add_argument("--unit-weight", type=float, default=18.0, help="unit weight [kN/m3]")
    p.add_argument("--surcharge", type=float, default=0.0, help="surcharge [kPa]")
    p.add_argument("--smooth", action="store_true", help="smooth footing (default rough)")
    p.add_argument("--settlement", type=float, default=None, help="final settlement [m] (default 0.1 B)")
    p.add_argument("--resolution", type=int, default=3, help="elements across the footing half-width")
    p.add_argument("--mesh", help="2D mesh file (surface y = 0, footing centred at x = 0)")
    p.set_defaults(func=_footing)

    p = subparsers.add_parser("biaxial", help="plane-strain biaxial test, shear band", formatter_class=fmt,
                              description="Biaxial compression with an imperfection (femgran.cases.biaxial).")
    _common(p, "out/biaxial")
    p.add_argument("--p0", type=float, default=100.0, help="confining pressure [kPa]")
    p.add_argument("--axial-strain", type=float, default=0.1)
    p.add_argument("--imperfection", type=float, default=0.02)
    p.add_argument("--platens", choices=("smooth", "rough"), default="smooth")
    p.add_argument("--weak-zone", type=float, default=0.0, help="relative drop of eta0 near the left face (CPA)")
    p.add_argument("--weak-zone-height", type=float, default=0.25, help="its height / H, in (0, 1)")
    p.add_argument("--resolution", type=int, nargs="+", default=[8], help="elements across the width (one run each)")
    p.set_defaults(func=_biaxial)

    p = subparsers.add_parser("run", help="run a case file (TOML)", formatter_class=fmt,
                              description=__import__("femgran.cases.casefile", fromlist=["x"]).__doc__)
    p.add_argument("case_file", help="case file (TOML)")
    _solver_flags(p)
    add_progress(p)
    p.set_defaults(func=_run)
