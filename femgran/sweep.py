"""``femgran sweep``: any run of the package over a grid or a list of parameter sets (engine: :mod:`material.sweep`).

What can be swept (``KIND``):

* ``element:TEST`` -- an element test of :mod:`material.driver` (``element:triaxial``,
  ``element:direct-shear``, ...); keys: the driver's keywords (``p0_kPa``, ``alpha_deg``, ``steps``...);
* a boundary-value case (``footing``, ``triaxial``, ``biaxial``, ``cavity``, ``element``); keys: the
  case's fields (``alpha_deg``, ``settlement_m``, ``resolution``...);
* ``dem:table4`` -- a DEM experiment of the thesis's Table 4 (:func:`dem.sweep.table4_run`); keys:
  ``test``, ``scale``, ``seed``, ``axial_strain``, ``rotation_deg``;
* ``identify:triaxial`` and ``identify:direct-shear`` -- a parameter identification
  (:mod:`material.identify`); keys: its keywords (``preset``, ``p0_kPa``...).

A key ``material.NAME`` sets the material: a ``[material]`` key (``material.preset``,
``material.law``, ``material.stabilisation``, ``material.E_kPa`` of a reference law...) or, for the CPA
law, a parameter (``material.beta``, ``material.eta0``: the ``set`` table); ``solver.NAME`` sets a Newton
solver option of a case (``solver.max_iter``).

Examples::

    femgran sweep footing --grid alpha_deg=0,30,60,90 --set surcharge_kPa=10 --out out/bearing
    femgran sweep element:triaxial --grid p0_kPa=50,100 alpha_deg=0,45,90 material.beta=0,5
    femgran sweep dem:table4 --grid test=T01,T02,T03 --set scale=0.05
    femgran sweep study.toml --scheduler tcp://10.0.0.5:8786      # runs on an existing Dask cluster

A study file (TOML) says the same::

    [sweep]
    run = "footing"
    [fixed]
    surcharge_kPa = 10
    "material.stabilisation" = 0.1
    [grid]
    alpha_deg = [0, 30, 60, 90]
    # or, instead of [grid], a list of parameter sets:
    # [[points]]
    # alpha_deg = 0
    # settlement_m = 0.05

A series of relaxation times of the CPA law's step stabilisation, each run with as many steps as its
relaxation time needs (``docs/cpa_law.md``, section 4), is a list of points::

    [fixed]
    "material.stabilisation" = 0.1
    [[points]]
    "material.relaxation_time" = 0.00625
    steps = 160
    [[points]]
    "material.relaxation_time" = 0.0015625
    steps = 640

Each run writes into ``OUT/<key>`` (``alpha_deg_30``...); ``OUT/summary.csv`` and ``OUT/sweep.json``
gather the runs as they finish; the same command again completes only the runs not yet complete.
"""

from __future__ import annotations

import dataclasses
import inspect
import sys
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from material.commandline import add_out, add_progress, write_run_record
from material.sweep import ELEMENT_TESTS, Run, grid, key_of, sweep

__all__ = ["runs_for", "kinds", "case_target", "register", "STUDY_CHECKPOINT_EVERY"]

_IDENTIFY = ("triaxial", "direct-shear")


def kinds() -> dict[str, str]:
    """KIND -> what it runs."""
    from femgran.cases.casefile import case_types

    out = {f"element:{t}": f"element test {t} (material.driver)" for t in ELEMENT_TESTS}
    out.update({name: f"boundary-value case {cls.__name__} (femgran.cases)" for name, cls in case_types().items()})
    out["dem:table4"] = "DEM experiment of Table 4 (dem.sweep.table4_run)"
    out.update({f"identify:{t}": f"identification from {t} data (material.identify)" for t in _IDENTIFY})
    return out


# ------------------------------------------------------------------------------------------ targets
#: A study's runs write a checkpoint every this many converged steps unless told otherwise. A run on a Dask
#: worker cannot catch Ctrl-C or the worker's end, so without them a killed study loses each running run
#: whole; a run here in the main process checkpoints on a stop and on Ctrl-C and needs none (its command
#: line's default is 0). Measured on the thesis sand's footing (43 steps, two checkpoints kept, the default):
#: 2.2 MB more on disk than the final checkpoint alone, and no change of the run's time beyond its spread
#: (11.3-12.0 s against 12.9-14.8 s without, one after the other).
STUDY_CHECKPOINT_EVERY = 10


def case_target(out, case: str, fields: Mapping | None = None, material=None, solver=None,
                checkpoint_every: int = STUDY_CHECKPOINT_EVERY) -> dict:
    """Sweep target: the boundary-value case ``case`` with ``fields`` into ``out``; returns its scalar
    summary (the case's headline and the rest of ``Solution.extra``: scalars and strings, and ``{k}_{sub}``
    for a mapping of them; ``summary.csv`` keeps the numbers, ``sweep.json`` all), ``completed``,
    ``stop_reason`` and ``steps``.

    The run writes a checkpoint every ``checkpoint_every`` converged steps (:data:`STUDY_CHECKPOINT_EVERY` by
    default; 0: only at its end or stop), and a run folder that holds a checkpoint of this run (a study
    interrupted mid-run, a worker killed) continues from it."""
    from femgran import checkpoint as ck
    from femgran.cases.base import Output, run
    from femgran.cases.casefile import case_types

    cls = case_types()[case]
    resume = ck.latest(Path(out)) is not None
    sol = run(cls(**dict(fields or {})), material, solver=solver,
              output=Output(out, progress=False, checkpoint_every=checkpoint_every), resume=resume)
    summary: dict[str, Any] = {}
    for k, v in sol.extra.items():  # scalars and strings, and mappings of them one level deep (k_sub); not the inputs
        if k == "params":
            continue
        for name, x in (v.items() if isinstance(v, Mapping) else [(None, v)]):
            if isinstance(x, (bool, int, float, str, np.bool_, np.integer, np.floating)):
                summary[k if name is None else f"{k}_{name}"] = x.item() if hasattr(x, "item") else x
    summary.update(completed=bool(sol.completed), stop_reason=sol.stop_reason, steps=len(sol.history) - 1)
    return summary


# ------------------------------------------------------------------------------------------ studies
def _split(kind: str, values: Mapping) -> tuple[dict, dict, dict]:
    """Flat keys -> (the run's own keywords, the material, the solver options)."""
    from material.factory import LAWS

    own, material, solver = {}, {}, {}
    for key, value in values.items():
        head, dot, name = key.partition(".")
        if dot and head == "material":
            law = values.get("material.law", "cpa")
            if name == "law" or name in LAWS.get(law, ()):
                material[name] = value
            elif law == "cpa":
                material.setdefault("set", {})[name] = value
            else:
                raise ValueError(f"{key} = {value!r}: law {law!r} has the keys {sorted(LAWS[law])}")
        elif dot and head == "solver":
            solver[name] = value
        elif dot:
            raise ValueError(f"key {key!r}: allowed a field of {kind}, material.NAME or solver.NAME")
        else:
            own[key] = value
    return own, material, solver


def _keywords(fn, exclude=()) -> list[str]:
    return [n for n, p in inspect.signature(fn).parameters.items() if n not in ("out", *exclude)
            and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


def _check_keywords(kind: str, allowed: list[str], own: Mapping) -> None:
    unknown = [k for k in own if k not in allowed]
    if unknown:
        raise ValueError(f"{kind}: unknown key(s) {unknown}; allowed {allowed} and material.NAME, solver.NAME")


def _check_material(kind: str, material: Mapping) -> None:
    """The CPA parameter changes of a study, checked against the parameter set before anything runs."""
    if material.get("law", "cpa") != "cpa" or not material.get("set"):
        return
    from material.commandline import with_changes
    from material.parameters import load_parameters, load_preset

    base = load_parameters(material["parameters"]) if "parameters" in material else \
        load_preset(material.get("preset", "ottawa_c109"))
    try:
        with_changes(base, dict(material["set"]))
    except KeyError as exc:
        raise ValueError(f"{kind}: material.*: {exc.args[0] if exc.args else exc}") from None


def _check_types(kind: str, cls, own: Mapping) -> None:
    """A value of the wrong kind for a case field is named with what is allowed (before anything runs)."""
    types = {f.name: str(f.type).split("|")[0].strip() for f in dataclasses.fields(cls)}
    for key, value in own.items():
        want = types.get(key)
        if want in ("float", "int") and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise ValueError(f"{kind}: {key} = {value!r}: allowed a number")
        if want == "bool" and not isinstance(value, bool):
            raise ValueError(f"{kind}: {key} = {value!r}: allowed true or false")


def _run_of(kind: str, values: Mapping, labels: Mapping | None = None) -> Run:
    """The :class:`Run` of ``kind`` with the flat ``values`` (validated here, before anything runs)."""
    from femgran.cases.casefile import case_types

    own, material, solver = _split(kind, values)
    _check_material(kind, material)
    key = key_of({k: v for k, v in values.items()}, labels) if values else "run"
    if kind.startswith("element:"):
        from material import driver

        test = kind.split(":", 1)[1]
        if test not in ELEMENT_TESTS:
            raise ValueError(f"KIND {kind!r}: allowed element:TEST with TEST in {list(ELEMENT_TESTS)}")
        if solver:
            raise ValueError(f"{kind}: solver.* keys apply to the boundary-value cases only")
        engine = _keywords(driver.run_path, ("model", "path", "log", "progress", "state"))
        own_keys = ["path_file", "substeps"] if test == "path" else \
            _keywords(getattr(driver, test.replace("-", "_")), ("model_or_params", "rule", "log", "progress"))
        _check_keywords(kind, own_keys + engine, own)
        return Run(key, "material.sweep:element", {"test": test, "material": material or None, **own}, values)
    if kind == "dem:table4":
        from dem.sweep import table4_run

        _check_keywords(kind, _keywords(table4_run, ("progress",)), own)
        if material or solver:
            raise ValueError("dem:table4: material.* and solver.* keys do not apply (the contact law is the test's)")
        return Run(key, "dem.sweep:table4_run", own, values)
    if kind.startswith("identify:"):
        from material import identify

        name = kind.split(":", 1)[1]
        if name not in _IDENTIFY:
            raise ValueError(f"KIND {kind!r}: allowed identify:{' or identify:'.join(_IDENTIFY)}")
        fn = identify.direct_shear if name == "direct-shear" else identify.triaxial
        _check_keywords(kind, _keywords(identify.sweep_target, ("method",)) + _keywords(fn, ("envelopes", "curves")),
                        own)
        if material or solver:
            raise ValueError(f"{kind}: material.* and solver.* keys do not apply; use preset=NAME")
        return Run(key, "material.identify:sweep_target", {"method": name, **own}, values)
    cases = case_types()
    if kind not in cases:
        raise ValueError(f"KIND {kind!r}: allowed {sorted(kinds())}")
    cls = cases[kind]
    _check_keywords(kind, [f.name for f in dataclasses.fields(cls)], own)
    _check_types(kind, cls, own)
    cls(**own)  # validates the values now, with the case's own messages
    from femgran.cases.common import solver_options

    solver_options(solver)
    return Run(key, "femgran.sweep:case_target",
               {"case": kind, "fields": own, "material": material or None, "solver": solver or None}, values)


def runs_for(kind: str, *, fixed: Mapping | None = None, axes: Mapping | None = None,
             points: list[Mapping] | None = None, labels: Mapping | None = None) -> list[Run]:
    """The runs of a study: ``kind`` (:func:`kinds`) with ``fixed`` values, over the grid ``axes`` (or the
    list ``points``); each run's folder is named after its swept values (``labels`` renames keys)."""
    if axes and points:
        raise ValueError("a study has a grid or a list of points, not both")
    fixed = dict(fixed or {})
    sets = grid(**axes) if axes else [dict(p) for p in (points or [{}])]
    runs = []
    for swept in sets:
        run = _run_of(kind, {**fixed, **swept}, labels)
        runs.append(Run(key_of(swept, labels) if swept else "run", run.target, run.kwargs, swept))
    return runs


# ------------------------------------------------------------------------------------------ command line
def _value(text: str):
    text = text.strip()
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def _pairs(items, flag: str, lists: bool) -> dict:
    out = {}
    for item in items or []:
        if "=" not in item:
            raise ValueError(f"{flag} {item!r}: expected KEY=VALUE" + (",VALUE..." if lists else ""))
        key, text = (s.strip() for s in item.split("=", 1))
        values = [_value(v) for v in text.split(",")]
        out[key] = values if lists else (values if len(values) > 1 else values[0])
    return out


def _flatten(table: Mapping, prefix: str = "") -> dict:
    out = {}
    for k, v in table.items():
        if isinstance(v, Mapping):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def read_study(path) -> dict:
    """A study file (module docstring) as ``{"run", "fixed", "axes", "points", "scheduler", "workers"}``."""
    import tomllib

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"study file {str(path)!r} does not exist")
    with open(path, "rb") as f:
        data = tomllib.load(f)
    unknown = sorted(set(data) - {"sweep", "fixed", "grid", "points"})
    if unknown:
        raise ValueError(f"study file {path}: unknown table(s) {unknown}; allowed [sweep], [fixed], [grid], [[points]]")
    head = data.get("sweep", {})
    if "run" not in head:
        raise ValueError(f"study file {path}: [sweep] needs run = KIND; allowed KIND {sorted(kinds())}")
    extra = sorted(set(head) - {"run", "scheduler", "workers"})
    if extra:
        raise ValueError(f"study file {path}: [sweep] key(s) {extra}; allowed run, scheduler, workers")
    axes = {k: (v if isinstance(v, list) else [v]) for k, v in _flatten(data.get("grid", {})).items()}
    return {"run": head["run"], "fixed": _flatten(data.get("fixed", {})), "axes": axes,
            "points": [_flatten(p) for p in data.get("points", [])] or None,
            "scheduler": head.get("scheduler"), "workers": head.get("workers")}


def register(subparsers) -> None:
    import argparse

    p = subparsers.add_parser("sweep", help="any run over a grid or a list of parameter sets, on Dask (resumable)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("kind", metavar="KIND|STUDY.toml", help="what to run (see above), or a study file")
    p.add_argument("--grid", nargs="+", metavar="KEY=V1,V2", default=[], help="the axes of the grid")
    p.add_argument("--set", nargs="+", metavar="KEY=VALUE", default=[], dest="fixed",
                   help="values common to every run")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local Dask cluster (default: the machine's cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler (tcp://host:8786); 'serial' runs in this process")
    add_out(p, "out/sweep")
    add_progress(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    if args.kind.lower().endswith(".toml"):
        study = read_study(args.kind)
        fixed = {**study["fixed"], **_pairs(args.fixed, "--set", False)}
        axes = {**study["axes"], **_pairs(args.grid, "--grid", True)}
        kind, points = study["run"], study["points"]
        scheduler, workers = args.scheduler or study["scheduler"], args.workers or study["workers"]
    else:
        kind, fixed, axes, points = args.kind, _pairs(args.fixed, "--set", False), _pairs(args.grid, "--grid", True), None
        scheduler, workers = args.scheduler, args.workers
    runs = runs_for(kind, fixed=fixed, axes=axes or None, points=points)

    def say(rec):
        tail = f": {rec['message']}" if rec["message"] else ""
        print(f"{rec['key']}: {rec['status']}{tail}", file=sys.stderr if rec["status"] == "failed" else sys.stdout)

    result = sweep(runs, args.out, scheduler=scheduler, workers=workers, progress=args.progress, title=kind,
                   on_record=say if not args.progress else None)
    write_run_record(args.out, args, kind=kind, runs=len(runs), ran=result.ran, skipped=result.skipped,
                     failed=result.failed, stopped=result.stopped)
    print(f"{kind}: {len(runs)} run(s): {result.ran} run now, {result.skipped} already complete, "
          f"{result.failed} failed, {result.stopped} stopped early -> {args.out}/summary.csv")
    for rec in result.records:
        if rec["status"] == "failed":
            print(f"  {rec['key']} failed: {rec['message']}", file=sys.stderr)
    return 0 if result.completed else 1
