"""``femgran triaxial|footing|biaxial|cavity|run``: the boundary-value cases on the command line.

Every field of a case dataclass is a flag (``--field-name``, or the short name its ``param`` gives, e.g.
``--alpha`` for ``alpha_deg``), with the field's help; so a case added to :mod:`femgran.cases` is on the
command line without a line here. The material, solver and output flags are the same for every case.

Examples::

    femgran triaxial --alpha 0 45 90 --platens rough            # -> out/triaxial/alpha_0 ... + comparison
    femgran footing --alpha 0 30 60 90 --surcharge 10           # bearing capacity vs bedding angle
    femgran footing --law von_mises --E 30000 --yield-stress 173.2 --unit-weight 0   # Prandtl check
    femgran footing --law mohr_coulomb --E 6000 --cohesion 0 --friction 30          # N_gamma, Mohr-Coulomb
    femgran biaxial --resolution 8 16 32                        # three meshes on one plot
    femgran cavity --law von_mises --E 1e5 --yield-stress 173.2 # Hill's cylinder
    femgran run case.toml --max-iter 40                         # a case file (femgran.cases.casefile)

A sweep (several values of one field, e.g. ``--alpha 0 45 90``) is a study on the sweep engine
(:mod:`material.sweep`: a local Dask cluster, ``--workers``, or ``--scheduler ADDRESS``): one run folder
per value under ``--out`` (``alpha_0``, ...), ``summary.csv`` with every run's summary as they finish,
and comparison plots; the same command again completes only the runs not yet complete (a run
interrupted mid-way continues from its checkpoint). ``femgran sweep`` sweeps several fields at once.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from material.commandline import add_out, add_parameters, add_progress, parse_set, write_run_record

__all__ = ["register"]

_TYPES = {"float": float, "int": int, "str": str, "bool": bool}
_SOLVER_FLAGS = ("tol", "max_iter", "max_cuts", "easy_steps", "line_search", "predictor", "linear_solver")


def _material(args) -> dict:
    """The ``[material]`` table of the flags (:func:`material.factory.make_material` takes it as it is, and
    the run folder's ``case.toml`` records it for ``femgran run --resume``)."""
    if args.law == "cpa":
        spec = {"law": "cpa", "set": parse_set(args.set), "stabilisation": args.stabilisation}
        spec.update({"parameters": args.params} if args.params else {"preset": args.preset})
        if args.relaxation_time is not None:
            spec["relaxation_time"] = args.relaxation_time
        if args.nonlocal_length is not None:
            spec["nonlocal_length"] = args.nonlocal_length
        if args.back_stress is not None:
            spec["back_stress_modulus"], spec["back_stress_length"] = args.back_stress
        if args.rule is not None:
            spec["rule"] = args.rule
    elif args.law == "von_mises":
        spec = {"law": "von_mises", "E_kPa": args.E, "nu": args.nu, "yield_stress_kPa": args.yield_stress}
    elif args.law in ("drucker_prager", "mohr_coulomb"):
        spec = {"law": args.law, "E_kPa": args.E, "nu": args.nu, "cohesion_kPa": args.cohesion,
                "friction_deg": args.friction_deg}
    else:
        spec = {"law": "linear_elastic", "E_kPa": args.E, "nu": args.nu}
    if not spec.get("set"):
        spec.pop("set", None)
    return spec


def _stabilisation(text: str):
    """``--stabilisation``: a number or "minimal" (checked by :class:`material.CPAModel`)."""
    try:
        return float(text)
    except ValueError:
        if text.strip().lower() == "minimal":
            return "minimal"
        raise argparse.ArgumentTypeError(f"{text!r}: allowed a number 0 <= MU <= 1 or 'minimal'") from None


def _material_flags(p):
    g = p.add_argument_group("material")
    g.add_argument("--law", choices=["cpa", "von_mises", "drucker_prager", "mohr_coulomb", "linear_elastic"],
                   default="cpa")
    add_parameters(g)
    g.add_argument("--stabilisation", type=_stabilisation, default=0.0, metavar="MU",
                   help="CPA step stabilisation (default 0: the thesis's law; 0.1 lets the non-associated sand "
                        "carry a footing to its end; 'minimal': each point's least MU for a unique rate problem, "
                        "docs/cpa_law.md section 4)")
    g.add_argument("--relaxation-time", type=float, default=None, metavar="TAU",
                   help="relaxation time of the CPA step stabilisation in load factor (a stage runs from 0 to 1; "
                        "default: one nominal step). With TAU the result converges as --steps grows; without it "
                        "the viscosity shrinks with the step (docs/cpa_law.md section 4)")
    from material.planes import available_rules

    g.add_argument("--rule", choices=sorted(available_rules()), default=None,
                   help="CPA integration planes (default bazant-oh-33; equator-78 resolves the critical planes "
                        "of plane strain to 5 deg: docs/cpa_law.md section 5.3)")
    g.add_argument("--nonlocal-length", type=float, default=None, metavar="L",
                   help="CPA with post-peak softening: regularise it by the implicit gradient of length L [m] "
                        "instead of the crack band (docs/regularisation.md)")
    g.add_argument("--back-stress", type=float, nargs=2, default=None, metavar=("H", "L"),
                   help="CPA: a gradient back stress H (eps_p - ebar_p) on every plane, H [kPa], ebar_p the "
                        "plastic strain smoothed over the length L [m] (four more nodal fields in plane strain, six in 3D; "
                        "docs/regularisation.md section 5)")
    g.add_argument("--E", type=float, default=3e4, help="Young's modulus of the reference laws [kPa]")
    g.add_argument("--nu", type=float, default=0.3, help="Poisson's ratio of the reference laws")
    g.add_argument("--yield-stress", type=float, default=100.0 * np.sqrt(3), help="von Mises yield stress [kPa]")
    g.add_argument("--cohesion", type=float, default=1.0, help="Drucker-Prager / Mohr-Coulomb cohesion [kPa]")
    g.add_argument("--friction", dest="friction_deg", type=float, default=35.0,
                   help="Drucker-Prager / Mohr-Coulomb friction angle [deg]")


def _solver_flags(p):
    s = p.add_argument_group("solver (femgran.solver.SolverOptions; default: its values)")
    s.add_argument("--tol", type=float, default=None, help="relative residual tolerance of the Newton iterations")
    s.add_argument("--max-iter", type=int, default=None, help="Newton iterations per attempt of a step")
    s.add_argument("--max-cuts", type=int, default=None, help="successive step cut-backs before a clean stop")
    s.add_argument("--easy-steps", type=int, default=None, metavar="N",
                   help="the step grows only after N consecutive easy steps without a cut-back (default: after "
                        "every easy step; 2 saves 40 %% of the evaluations into the shear-band study's peak, "
                        "see SolverOptions)")
    s.add_argument("--line-search", type=int, default=None, metavar="K",
                   help="shortest line-search step 2**-K of the Newton step (0: plain Newton)")
    s.add_argument("--predictor", choices=["extrapolate", "tangent", "none"], default=None,
                   help="first guess of each step's displacements")
    s.add_argument("--linear-solver", default=None, choices=["auto", "superlu", "amg-gmres", "ilu-gmres"],
                   help="auto: SuperLU for small and plane-strain problems, AMG-GMRES for large 3D ones")


def _solver_given(args) -> dict:
    return {k: getattr(args, k) for k in _SOLVER_FLAGS if getattr(args, k) is not None}


def _flags(f) -> list[str]:
    return list(f.metadata.get("flags") or ()) or [f"--{f.name.replace('_', '-')}"]


def _case_flags(p, cls) -> None:
    """One flag per field of ``cls``; numbers take one or more values (several: a sweep)."""
    g = p.add_argument_group(f"{cls.name} (femgran.cases.{cls.__name__}; default: the field's)")
    for f in dataclasses.fields(cls):
        typ = _TYPES[str(f.type).split("|")[0].strip()]
        help_ = f"{f.metadata.get('help', '')} (default {f.default!r})"
        if typ is bool:
            g.add_argument(*_flags(f), dest=f.name, action=argparse.BooleanOptionalAction, default=f.default,
                           help=help_)
            if f.metadata.get("negative"):
                g.add_argument(f.metadata["negative"], dest=f.name, action="store_false", help=argparse.SUPPRESS)
        elif typ in (int, float):
            g.add_argument(*_flags(f), dest=f.name, type=typ, nargs="+", default=f.default, metavar="VALUE",
                           help=help_)
        else:
            g.add_argument(*_flags(f), dest=f.name, type=typ, default=f.default, help=help_)


def _sweep_field(args, cls):
    """(field, values) of the one field given several values (None, [None] if none); more is an error."""
    lists = {f.name: v for f in dataclasses.fields(cls) if isinstance(v := getattr(args, f.name), list) and len(v) > 1}
    if len(lists) > 1:
        raise ValueError(f"several values for {sorted(lists)}: a command sweeps one field at a time")
    return next(iter(lists.items())) if lists else (None, [None])


def _run_case(args, cls) -> int:
    """One run here, in this process; several values of one field: a study on the sweep engine."""
    from femgran.cases.base import Output, run
    from femgran.cases.common import solver_options

    out = Path(args.out)
    # the checkpoint flags checked before anything runs
    Output(None, checkpoint_every=args.checkpoint_every or 0, keep_checkpoints=args.keep_checkpoints)
    key, values = _sweep_field(args, cls)
    fixed = {f.name: (v[0] if isinstance(v := getattr(args, f.name), list) else v) for f in dataclasses.fields(cls)}
    solver = solver_options(_solver_given(args))
    if key is None:
        case = cls(**fixed)
        sol = run(case, _material(args), solver=solver,
                  output=Output(out, args.progress, checkpoint_every=args.checkpoint_every or 0,
                                keep_checkpoints=args.keep_checkpoints), resume=args.resume)
        print(f"{cls.headline} = {sol.extra[cls.headline]:.4g}; {sol.stop_reason}; results in {out}")
        write_run_record(out, args, runs=[{cls.headline: sol.extra[cls.headline], "completed": sol.completed}])
        return 0 if sol.completed else 1
    return _run_study(args, cls, out, key, values, fixed, solver)


def _run_study(args, cls, out: Path, key: str, values, fixed: dict, solver) -> int:
    """The runs of a sweep over ``key`` on :func:`material.sweep.sweep` (one folder each, resumable), then
    the comparison plots of the runs that have a history."""
    from femgran.solver import History
    from material.sweep import Run, sweep

    label = _flags(next(f for f in dataclasses.fields(cls) if f.name == key))[0].lstrip("-").replace("-", "_")
    for v in values:
        cls(**{**fixed, key: v})  # every run's fields checked before any runs
    every = {} if args.checkpoint_every is None else {"checkpoint_every": args.checkpoint_every}  # else the sweep's
    runs = [Run(f"{label}_{v:g}", "femgran.sweep:case_target",
                {"case": cls.name, "fields": {**fixed, key: v}, "material": _material(args),
                 "solver": solver.to_dict(), **every}, {key: v}) for v in values]
    if args.resume:
        print(f"{cls.name} sweep: every run not yet complete continues from its checkpoint (--resume is implied)")
    result = sweep(runs, out, scheduler=args.scheduler, workers=args.workers, progress=args.progress,
                   title=f"{cls.name} sweep over {key}")
    sols = []
    for v, rec in zip(values, result.records):
        head = rec["summary"].get(cls.headline, float("nan"))
        what = rec["summary"].get("stop_reason") or rec["message"] or rec["status"]
        print(f"{label} = {v:g}: {cls.headline} = {head:.4g}; {what}; results in {out / rec['key']}")
        if (out / rec["key"] / "history.csv").is_file():
            sols.append((v, History.read_csv(out / rec["key"] / "history.csv")))
    write_run_record(out, args, runs=[{"value": v, "key": r["key"], "status": r["status"],
                                       cls.headline: r["summary"].get(cls.headline)}
                                      for v, r in zip(values, result.records)], ran=result.ran, skipped=result.skipped)
    if sols:
        for x, y in cls.compare:
            _overlay(sols, x, y, out / f"{y}_vs_{x}.png", label, sols[0][1].descriptions)
    return 0 if result.completed else 1


def _overlay(sols, x, y, path, label, descriptions):
    from femgran.output import plot_curves

    plot_curves([(f"{label} = {v:g}", h[x], h[y], "-") for v, h in sols], path,
                xlabel=f"{x}: {descriptions.get(x, '')}", ylabel=f"{y}: {descriptions.get(y, '')}")


def _checkpoint_flags(p, from_file: bool = False):
    """``--checkpoint-every`` and ``--keep-checkpoints``. With ``from_file`` (``femgran run``) they default to
    None: the case file's ``[output]`` values hold unless a flag is given (a default of 0 used to switch off the
    checkpoints a file asked for, while the run folder's copy of the file still showed them)."""
    from femgran.sweep import STUDY_CHECKPOINT_EVERY

    g = p.add_argument_group("checkpoints (femgran.checkpoint)")
    every, keep = ("the case file's [output] checkpoint_every", "the file's keep_checkpoints") if from_file else \
        ("0 for one run, which checkpoints at its end, on a stop and on Ctrl-C; "
         f"{STUDY_CHECKPOINT_EVERY} for each run of a study, whose Dask workers cannot catch Ctrl-C", "2")
    g.add_argument("--checkpoint-every", type=int, default=None, metavar="N",
                   help=f"a checkpoint every N converged steps (default {every})")
    g.add_argument("--keep-checkpoints", type=int, default=None if from_file else 2, metavar="K",
                   help=f"keep the last K (default {keep})")


def _study_flags(p):
    g = p.add_argument_group("sweeps (several values of one field: material.sweep on Dask, resumable)")
    g.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local Dask cluster (default: the machine's cores)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler (tcp://host:8786); 'serial' runs here, one by one")


def _run(args):
    from femgran.cases.casefile import run_case

    if (args.case_file is None) == (args.resume is None):
        raise ValueError("femgran run: give a case file, or --resume OUT (a run folder), not both")
    over = {k: v for k in ("checkpoint_every", "keep_checkpoints") if (v := getattr(args, k)) is not None}
    if args.resume is not None:
        folder = Path(args.resume)
        if not (folder / "case.toml").is_file():
            raise FileNotFoundError(f"--resume {folder}: no case.toml there (a run whose material was a Python "
                                    "object resumes from Python: femgran.cases.run(..., resume=True))")
        sol = run_case(folder / "case.toml", progress=args.progress, solver=_solver_given(args), resume=True,
                       out=folder, **over)
    else:
        sol = run_case(args.case_file, progress=args.progress, solver=_solver_given(args), **over)
    if sol.out_dir is not None:
        write_run_record(sol.out_dir, args, completed=sol.completed, stop_reason=sol.stop_reason)
    print(f"{sol.stop_reason}; {len(sol.history) - 1} steps; results in {sol.out_dir}")
    return 0 if sol.completed else 1


def _replay(args) -> int:
    """Re-run, from the last checkpoint of a run folder, the step at which the run stopped, with diagnostics."""
    from femgran import checkpoint as ck
    from femgran.cases.base import Output, run
    from femgran.cases.casefile import load_case
    from femgran.cases.common import solver_options
    from material.table import read_table

    folder = Path(args.run_folder)
    if not (folder / "case.toml").is_file():
        raise FileNotFoundError(f"replay {folder}: no case.toml there (not a run folder of femgran, or a run whose "
                                "material was a Python object: femgran.cases.run(..., resume=FOLDER, max_steps=1))")
    last = ck.latest(folder)
    if last is None:
        raise FileNotFoundError(f"replay {folder}: no checkpoint in {folder / 'checkpoints'}")
    info = ck.load(last)[1]
    case, material, solver, _ = load_case(folder / "case.toml")
    solver = solver_options({**solver.to_dict(), **_solver_given(args)})
    dest = Path(args.out) if args.out else folder / "replay"
    sol = run(case, material, solver=solver, output=Output(dest, progress=False, plots=False), resume=folder,
              max_steps=1)
    print(f"replay of {folder} from its checkpoint after step {info['n_step']} (t = {info['t']:.6g}, "
          f"next step dt = {info['dt']:.3g}): {sol.stop_reason}")
    log = read_table(dest / "newton_log.csv")
    for step, attempt in sorted({(int(s), int(a)) for s, a in zip(log["step"], log["attempt"])}):
        rows = (log["step"] == step) & (log["attempt"] == attempt)
        kept = rows & (log["accepted"] == 1)
        seq = " ".join(f"{r:.1e}" for r in log["residual"][kept])
        print(f"  step {step} try {attempt} (load factor {log['load_factor'][rows][0]:.6g}): residuals {seq}; "
              f"most failed points {int(np.nanmax(log['failed_points'][rows]))}, most switching points "
              f"{np.nanmax(log['points_switched'][rows]) if np.isfinite(log['points_switched'][rows]).any() else 0:.0f}"
              f"{_overshoot_note(log, rows)}")
    from femgran.cases.base import build_problem

    problem = build_problem(case, material)  # once, for the three reports on the checkpoint
    _print_zero_step_drift(problem, last)
    _print_uniqueness(problem, last)
    _print_ellipticity(problem, last)
    replays = sorted((dest / "failed_points").glob("*.npz"))
    print(f"  {len(replays)} replay file(s) of failed points in {dest / 'failed_points'} (material.cpa.replay)"
          if replays else "  no material point failed")
    write_run_record(dest, args, replayed_from=str(folder), checkpoint_step=info["n_step"],
                     completed=sol.completed, stop_reason=sol.stop_reason, failed_point_files=[p.name for p in replays])
    return 0


def _overshoot_note(log, rows) -> str:
    """What the rejected full Newton steps of one try of a step had in common (Newton log columns
    ``overshoot_*``, :func:`femgran.diagnostics.full_step_overshoot`); empty for a log without them."""
    if "overshoot" not in log.columns:
        return ""
    missed = rows & np.isfinite(log["overshoot"]) & (log["accepted"] == 0)
    if not missed.any():
        return ""
    pts, p = log["overshoot_points"][missed], log["overshoot_pressure"][missed]
    return (f"; {int(missed.sum())} full Newton step(s) rejected, half of the missed stress at "
            f"{np.nanmin(pts):.0f}-{np.nanmax(pts):.0f} point(s), the worst at "
            f"{np.nanmin(p):.1f}-{np.nanmax(p):.1f} kPa mean stress")


def _print_zero_step_drift(problem, checkpoint) -> None:
    """How far the material moves the checkpoint's committed stress for a zero strain increment, over a
    relaxation time of the law (one nominal step unless it has its own) and over the smallest step the
    cut-backs reach (:func:`femgran.diagnostics.zero_step_drift`);
    a point counts as moved above 1e-9 of its largest stress component (the local solver converges to 1e-12
    of the point's strain scale, so a consistent law stays below it: the thesis sand's footing, 2e-13)."""
    from femgran import checkpoint as ck
    from femgran.diagnostics import zero_step_drift

    arrays = ck.load(checkpoint)[0]
    state = {k[len("state__"):]: arrays[k] for k in arrays if k.startswith("state__")}
    inputs = problem.disc.point_inputs(np.zeros(problem.disc.ndofs))
    for f, rel in zero_step_drift(problem.material, arrays["stress"], state, inputs).items():
        moved = rel > 1e-9
        print(f"  a zero strain increment over {f:g} relaxation time(s) moves {int(moved.sum())} of {rel.size} points' "
              f"stress, by up to {rel.max():.2g} of their largest component"
              + ("" if f == 1.0 or not moved.any() else
                 " (the committed state is not the step problem's solution as the step vanishes: cut-backs cannot "
                 "reach an equilibrium next to it)"))


def _print_uniqueness(problem, checkpoint) -> None:
    """Where the CPA law's rate problem at the checkpoint's committed state has no unique solution, and the
    least uniform step stabilisation that would restore it there (:func:`femgran.diagnostics.uniqueness_report`;
    a sufficient condition, blind to planes that join within a step)."""
    from femgran import checkpoint as ck
    from femgran.diagnostics import cpa_law, uniqueness_report

    law = cpa_law(problem.material)
    if law is None:
        return
    arrays = ck.load(checkpoint)[0]
    state = {k[len("state__"):]: arrays[k] for k in arrays if k.startswith("state__")}
    note = uniqueness_report(law, arrays["stress"], state)
    print(f"  {note}" if note else
          f"  the rate problem of every one of the {len(arrays['stress'])} points is uniquely solvable at the checkpoint")


def _print_ellipticity(problem, checkpoint) -> None:
    """Where the checkpoint's committed tangent admits a band (Rice's condition,
    :func:`femgran.diagnostics.ellipticity_summary`)."""
    from femgran import checkpoint as ck
    from femgran.diagnostics import ellipticity_report, ellipticity_summary

    arrays = ck.load(checkpoint)[0]
    summary = ellipticity_summary(ck.committed_tangent(arrays), problem.disc.dim)
    if summary:
        print(f"  {ellipticity_report(summary) or 'the tangent of the checkpoint is elliptic at every point'} "
              f"(least indicator {summary['ellipticity_min']:.3g})")


def _ellipticity(args) -> int:
    """``femgran ellipticity``: the points past Rice's onset at each checkpoint of a run folder."""
    from femgran import checkpoint as ck
    from femgran.cases.base import build_problem
    from femgran.cases.casefile import load_case
    from femgran.diagnostics import rice_indicator
    from material.localisation import ONSET
    from material.table import Table

    folder = Path(args.run_folder)
    if not (folder / "case.toml").is_file():
        raise FileNotFoundError(f"ellipticity {folder}: no case.toml there (not a run folder of femgran)")
    if (args.strengthening is None) != (not args.modulus):
        raise ValueError(f"--strengthening {args.strengthening} --modulus {' '.join(map(str, args.modulus))}: give "
                         "both (a kind and one or more moduli) or neither")
    if any(not (np.isfinite(h) and h >= 0.0) for h in args.modulus):
        raise ValueError(f"--modulus {' '.join(map(str, args.modulus))}: allowed finite numbers >= 0")
    paths = sorted((folder / "checkpoints").glob("step_*.json"))
    if not paths:
        raise FileNotFoundError(f"ellipticity {folder}: no checkpoint in {folder / 'checkpoints'} (run it with "
                                "--checkpoint-every N)")
    case, material, _, _ = load_case(folder / "case.toml")
    problem = build_problem(case, material)
    law = problem.material
    while not hasattr(law, "loading_tangent") and hasattr(law, "law"):
        law = law.law  # (the undrained wrapper)
    if not hasattr(law, "loading_tangent"):
        raise TypeError(f"ellipticity {folder}: the run's material {law!r} is not a CPA law")
    dim = problem.disc.dim
    variants = [("law", "none", 0.0)] + [(f"{args.strengthening}_{h:g}", args.strengthening, h) for h in args.modulus]
    rows = {"step": [], "t": [], "points": [], "committed": []} | {name: [] for name, _, _ in variants} | \
        {"singular": []}
    for path in paths:
        arrays, info = ck.load(path)
        state = {k[len("state__"):]: arrays[k] for k in arrays if k.startswith("state__")}
        rows["step"].append(int(info["n_step"]))
        rows["t"].append(float(info["t"]))
        rows["points"].append(len(arrays["stress"]))
        committed = rice_indicator(ck.committed_tangent(arrays), dim)
        rows["committed"].append(-1 if committed is None else int(np.sum(committed < -ONSET)))
        singular = 0
        for name, kind, h in variants:
            D = law.loading_tangent(arrays["stress"], state, strengthening=kind, modulus=h)
            nan = np.isnan(D).reshape(len(D), -1).any(axis=1)
            singular = max(singular, int(nan.sum()))
            rows[name].append(int(np.sum(rice_indicator(np.where(nan[:, None, None, None, None], 0.0, D), dim)[~nan]
                                         < -ONSET)))
        rows["singular"].append(singular)
    desc = {"step": "converged step of the checkpoint", "t": "load factor", "points": "quadrature points",
            "committed": "points past Rice's onset on the committed tangent (-1: none stored)",
            "law": "the same on the law's rate-independent loading tangent"}
    desc |= {name: f"the same with the strengthening {kind}, H_g = {h:g}" for name, kind, h in variants[1:]}
    desc["singular"] = "points whose rate problem is singular (no loading tangent; not counted above), most of any column"
    table = Table(rows, desc, {"run": str(folder)}, title="points past Rice's onset at each checkpoint")
    out = table.write_csv(folder / "ellipticity.csv")
    print(" ".join(f"{c:>{max(9, len(c))}}" for c in rows))
    for i in range(len(rows["step"])):
        print(" ".join(f"{rows[c][i]:>{max(9, len(c))}{'.4f' if c == 't' else ''}}" for c in rows))
    print(f"-> {out}")
    return 0


def _band_history(args) -> int:
    from femgran.band import band_history, is_zone

    table = band_history(args.run_folder, args.window, name=args.name, law=args.law)
    path = table.write_csv(Path(args.run_folder) / "band_history.csv")
    print(f"{'axial strain [%]':>18} {'q [kPa]':>15}   band: angle [deg], thickness [mm], contrast, "
          f"heights where it meets the left / right side [mm], friction / dilatancy inside it [deg]"
          + (", the law's band at that friction, the element sheared as the inside of the arm [deg] (its Rice "
             "indicator) / sheared the other way" if args.law else "") + "   | other arm")
    for r in table.rows():
        arms = []
        for prefix in ("", "conjugate_"):
            if r[prefix + "localised"]:
                arms.append(f"{r[prefix + 'angle_deg']:5.1f} {'rising' if r[prefix + 'rising'] else 'falling':7s} "
                            f"{1e3 * r[prefix + 'thickness_m']:5.1f} {r[prefix + 'contrast']:5.3g} "
                            f"{1e3 * r[prefix + 'left_y_m']:6.1f} / {1e3 * r[prefix + 'right_y_m']:6.1f} "
                            f"{r[prefix + 'friction_deg']:5.1f} / {r[prefix + 'dilatancy_deg']:5.1f}"
                            + (f"  law {r[prefix + 'law_angle_deg']:5.1f} ({r[prefix + 'law_indicator']:+.3f}) / "
                               f"{r[prefix + 'law_other_angle_deg']:5.1f}" if args.law else ""))
            elif is_zone(r[prefix + "contrast"], r[prefix + "peak_width_m"], r[prefix + "section_m"]):
                zone = f"zone {1e3 * r[prefix + 'peak_width_m']:.1f} of {1e3 * r[prefix + 'section_m']:.1f}"
                arms.append(f"{zone:>56}")
            else:
                arms.append(f"{'no band':>56}")
        print(f"{100 * r['eps_from']:8.2f} -{100 * r['eps_to']:6.2f}   {r['q_from_kPa']:6.1f} -{r['q_to_kPa']:6.1f}   "
              f"{arms[0]}   | {arms[1]}")
    print(f"-> {path}")
    return 0


def register(subparsers) -> None:
    """Add one subcommand per case (its fields as flags) and ``run``."""
    from femgran.cases.casefile import case_types

    fmt = argparse.RawDescriptionHelpFormatter
    for name, cls in case_types().items():
        if name == "element":  # ``femgran element`` is the material drivers' command; this case runs by file
            continue
        summary = (cls.__doc__ or name).strip().splitlines()[0]
        p = subparsers.add_parser(name, help=summary, description=summary, formatter_class=fmt)
        _case_flags(p, cls)
        _material_flags(p)
        _solver_flags(p)
        _checkpoint_flags(p)
        p.add_argument("--resume", action="store_true",
                       help=f"continue the run in --out from its last checkpoint (the same flags; only --{cls.extend.replace('_', '-')} "
                            "may differ: the loading then goes on to its new end)")
        _study_flags(p)
        add_out(p, f"out/{name}")
        add_progress(p)
        p.set_defaults(func=lambda args, cls=cls: _run_case(args, cls))

    p = subparsers.add_parser("replay", help="re-run the step at which a run stopped, with diagnostics",
                              description="From the last checkpoint of a run folder, run its next step again and "
                                          "report each try's residuals, the points that failed and their replay files.")
    p.add_argument("run_folder", help="the folder of the run that stopped")
    p.add_argument("--out", default=None, help="where the replay writes (default RUN_FOLDER/replay)")
    _solver_flags(p)
    p.set_defaults(func=_replay)

    p = subparsers.add_parser(
        "ellipticity", help="where the law admits a band at each checkpoint, with and without a strengthening",
        description="Rice's condition at each checkpoint of a run folder: on the committed tangent (the run's "
                    "own, the step stabilisation's where it has one) and on the law's rate-independent loading "
                    "tangent (material.CPAModel.loading_tangent), also with the stiffness a gradient term would give "
                    "a short disturbance (--strengthening, --modulus). Writes RUN_FOLDER/ellipticity.csv and prints "
                    "it: the points past the onset of each.")
    p.add_argument("run_folder", help="a run folder with checkpoints (femgran run ... --checkpoint-every N)")
    p.add_argument("--strengthening", choices=("plane", "sum", "plastic_strain", "back_stress"), default=None,
                   help="plane: H_g on each plane's slip [1/m]; sum: on the sum of the slips [1/m]; plastic_strain: "
                        "on the plastic strain [m]; back_stress: a back stress H_g (eps_p - ebar_p) [kPa] "
                        "(docs/regularisation.md, section 4)")
    p.add_argument("--modulus", type=float, nargs="+", default=[], metavar="H_G",
                   help="the strengthening's modulus H_g, one or more")
    p.set_defaults(func=_ellipticity)

    p = subparsers.add_parser("band", help="the band active in each window of axial strain after the peak",
                              description="The band active in each window of axial strain after the peak, both arms, "
                                          "from a run folder's VTK series (femgran.band.band_history). Writes "
                                          "RUN_FOLDER/band_history.csv and prints it.")
    p.add_argument("run_folder", help="the folder of a biaxial (or triaxial) run with its VTK series")
    p.add_argument("--window", type=float, default=0.005, help="axial strain of each window (default 0.005)")
    p.add_argument("--name", default="biaxial", help="the case's name, of NAME.pvd (default biaxial)")
    p.add_argument("--law", action="store_true",
                   help="beside each arm, the band the law itself forms at the friction inside it (Rice's condition "
                        "on the plane-strain element path of the run's material, femgran.band.law_band_angles; "
                        "a biaxial run whose case.toml holds its material), with the element sheared as the inside "
                        "of the arm and, after a slash, the other way (they differ at alpha = 0 and 90 deg)")
    p.set_defaults(func=_band_history)

    p = subparsers.add_parser("run", help="run a case file (TOML)", formatter_class=fmt,
                              description=__import__("femgran.cases.casefile", fromlist=["x"]).__doc__)
    p.add_argument("case_file", nargs="?", help="case file (TOML)")
    p.add_argument("--resume", metavar="OUT", default=None,
                   help="continue the run in folder OUT from its last checkpoint (its case.toml and inputs)")
    _solver_flags(p)
    _checkpoint_flags(p, from_file=True)
    add_progress(p)
    p.set_defaults(func=_run)
