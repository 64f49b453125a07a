"""The skeleton every case shares: a case is data plus two functions.

A case is a frozen dataclass of its geometry, loads and options (validated when it is made, before any
computation) with

* ``build(material) -> Problem``: mesh, discretisation, boundary conditions, loads, initial stress,
  the history columns to observe and a record of what was built;
* ``summarise(solution, problem) -> dict``: the case's results (attributes of the solution and
  ``summary.json``);
* ``plots(solution, problem, out_dir)``: its figures (optional).

:func:`run` owns the rest, the same for every case: the material (:func:`material.factory.make_material`,
with the case's ``alpha_deg`` and frame), the failed-point folder (given to a copy of the law, never set on
the user's object), the solver and its options, the run folder with ``parameters.json``, the field series
and ``history.csv`` written step by step, ``newton_log.csv``, ``summary.json`` and the plots. Adding a
case is one module with one dataclass (:mod:`femgran.cases.cavity` is the example).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

__all__ = ["Problem", "Output", "run", "case_record", "param", "case", "describe", "Drainage"]


def param(default, help: str, *, flags: tuple = (), negative: str | None = None):
    """A field of a case dataclass with its meaning, unit and allowed values (``help``), which the class
    docstring, ``femgran <case> --help`` and the case-file documentation show. ``flags``: its command-line
    names (default ``--field-name``); ``negative``: a flag that sets a bool field to False."""
    return field(default=default, metadata={"help": help, "flags": tuple(flags), "negative": negative})


def describe(cls, indent: int = 4) -> str:
    """The fields of a case as text: name, default, meaning."""
    pad = " " * indent
    return "\n".join(f"{pad}{f.name} = {f.default!r}: {f.metadata.get('help', '')}" for f in dataclasses.fields(cls))


DRAINAGE = ("drained", "undrained")


@dataclass(frozen=True, kw_only=True)
class Drainage:
    """The pore water of a case, a base of every case (keyword-only fields, after the case's own)."""

    drainage: str = param("drained", "'drained' or 'undrained' (pore water as a penalty, material.undrained)")
    pore_bulk_modulus_kPa: float = param(5.5e6, "undrained: bulk modulus of the pore water over the porosity, "
                                                "K_w / n [kPa] (water 2.2e6 kPa, n = 0.4)")


def case(cls):
    """Class decorator of a case: a frozen dataclass whose docstring ends with its fields (:func:`describe`);
    the drainage fields (:class:`Drainage`) are checked before the case's own ``__post_init__``."""
    own = cls.__dict__.get("__post_init__")

    def post_init(self):
        if self.drainage not in DRAINAGE:
            raise ValueError(f"drainage = {self.drainage!r}: allowed {DRAINAGE}")
        if not (np.isfinite(self.pore_bulk_modulus_kPa) and self.pore_bulk_modulus_kPa > 0):
            raise ValueError(f"pore_bulk_modulus_kPa = {self.pore_bulk_modulus_kPa!r}: must be > 0 (finite)")
        if own is not None:
            own(self)

    cls.__post_init__ = post_init
    cls = dataclass(frozen=True)(cls)
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n\n    Fields (name = default: meaning)::\n\n" + describe(cls, 8) + "\n"
    return cls


@dataclass
class Stage:
    """One stage of a staged run: its boundary conditions (prescribed displacements from the stage's start),
    the loads that act from its start (``f_fixed``) and grow with its load factor (``f_ramp``), its steps."""

    name: str
    dirichlet: list
    f_fixed: np.ndarray | None = None
    f_ramp: np.ndarray | None = None
    steps: int = 1
    elastic: bool = False  # linear elasticity with the law's E and nu; at the end the law starts from the stress
    control: object = None  # femgran.solver.PathControl: path following to control_end (the load factor follows)
    control_end: float | None = None


def _elastic_twin(law):
    """Linear elasticity with the E and nu of ``law`` (an elastic stage: gravity switched on)."""
    from material import LinearElastic

    inner = getattr(law, "law", law)  # an Undrained law: its skeleton
    E = getattr(inner, "E", None) or getattr(getattr(inner, "params", None), "E", None)
    nu = getattr(inner, "nu", None) or getattr(getattr(inner, "params", None), "nu", None)
    if E is None or nu is None:
        raise ValueError(f"an elastic stage needs the material's E and nu; {type(law).__name__} has none")
    return LinearElastic(float(E), float(nu))


def _use_material(newton, law, *, restart: bool) -> None:
    """Give the solver ``law`` for the next stage; ``restart``: its state starts from the present stress
    (``initial_state(stress=...)``, as a law switched on after an elastic stage)."""
    pts = newton.points
    newton.material = pts.material = law
    if restart:
        pts.state = law.initial_state(pts.n_points, stress=pts.stress, element_size=newton.disc.element_size())
        pts.revert()
    newton._committed_tangent = None

@dataclass
class Problem:
    """What a case builds for one material: everything the solver needs and what to observe.

    observe : ``f(solver) -> dict`` of history columns for each converged step; ``solver.reaction``
        holds the out-of-balance force (the reactions on the prescribed DOFs) of that step.
    columns : meaning, unit and sign convention of each column ``observe`` gives (the history's header).
    record : what ``build`` chose (mesh, resolved defaults, ...), written to ``parameters.json``.
    data : anything ``summarise`` needs besides the solution.
    persist : the keys of ``data`` (numpy arrays, replaced rather than changed in place) that the checkpoints
        keep and a resumed run gets back: what ``observe`` accumulates over the steps for ``summarise``.
    stages : a staged run (:class:`Stage`), each from the end state of the one before; the history gets the
        columns ``stage`` and ``time`` (stage k spans k..k+1), as does the field series. None: one stage of
        ``dirichlet``, ``f_fixed`` and the case's ``steps``.
    control, control_end : path following of the single stage (:class:`femgran.solver.PathControl`): the
        steps prescribe its quantity up to ``control_end`` and the load factor follows (past a snap-back).
    """

    disc: object
    material: object
    dirichlet: list
    f_fixed: np.ndarray | None = None
    initial_stress: np.ndarray | None = None
    observe: Callable | None = None
    columns: dict = field(default_factory=dict)
    record: dict = field(default_factory=dict)
    fixed_steps: bool = False
    data: dict = field(default_factory=dict)
    persist: tuple = ()
    stages: list | None = None
    control: object = None
    control_end: float | None = None


@dataclass(frozen=True)
class Output:
    """Where and how a run writes: ``out`` the run folder (None: nothing on disk), ``write_every`` the
    field series every N converged steps (the history gets every step), ``plots`` the case's figures,
    ``progress`` a progress bar, ``checkpoint_every`` a checkpoint every N converged steps (0: only at the
    end, on a stop and on an interruption), ``keep_checkpoints`` how many are kept."""

    out: str | Path | None = None
    progress: bool = False
    write_every: int = 1
    plots: bool = True
    checkpoint_every: int = 0
    keep_checkpoints: int = 2

    def __post_init__(self):
        for key, low in (("write_every", 1), ("checkpoint_every", 0), ("keep_checkpoints", 1)):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ValueError(f"{key} = {v!r}: allowed integers >= {low}")


def case_record(case) -> dict:
    """The case's fields as JSON-able values (paths as strings)."""
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(case).items()}


def build_problem(case, material=None, out_dir=None) -> Problem:
    """The case's :class:`Problem` for ``material`` (anything :func:`material.factory.make_material` takes),
    with the case's drainage; failed points write their replay files under ``out_dir`` (None: nowhere)."""
    from femgran.cases.common import keep_failed_points
    from material.factory import make_material

    mat = make_material(material, alpha_deg=getattr(case, "alpha_deg", None), plane_strain=case.plane_strain)
    problem = case.build(mat if out_dir is None else keep_failed_points(mat, out_dir))
    if getattr(case, "drainage", "drained") == "undrained":
        from material.undrained import Undrained

        problem.material = Undrained(problem.material, case.pore_bulk_modulus_kPa)
    return problem


def run(case, material=None, *, solver=None, output: Output | None = None, resume: bool | str | Path = False,
        max_steps: int | None = None):
    """Run ``case`` with ``material`` (anything :func:`material.factory.make_material` takes), the solver
    options ``solver`` (:class:`femgran.solver.SolverOptions`, a mapping of its fields, or None) and
    ``output``. Returns the :class:`femgran.solver.Solution` with the case's summary as attributes.

    Checkpoints (:mod:`femgran.checkpoint`) go to ``<out>/checkpoints`` every ``output.checkpoint_every``
    converged steps, at the end, on a clean stop and on an interruption (Ctrl-C, SIGTERM: the run then
    records ``"interrupted": true`` in ``status.json`` and raises ``KeyboardInterrupt``). ``resume=True``
    continues the run in ``output.out`` from its last checkpoint, to the bit the run it continues would have
    computed; inputs that differ from the checkpoint's are refused, naming what changed. ``resume=FOLDER``
    starts from the last checkpoint of another run folder and writes a new series in ``output.out`` (the
    replay of a failed step). ``max_steps``: stop after that many converged steps.
    """
    from femgran import checkpoint as ck
    from femgran.cases.common import material_record, newton_log, run_folder, solver_options
    from femgran.solver import NewtonSolver
    from material.table import jsonable

    output = Output() if output is None else output
    options = solver_options(solver)
    out_dir = run_folder(output.out)
    problem = build_problem(case, material, out_dir)
    observers = [] if problem.observe is None else [problem.observe]
    if getattr(case, "drainage", "drained") == "undrained":
        weights = problem.disc.dx.ravel()
        observers.append(lambda s: {"pore_pressure_kPa": float(np.average(s.points.state["pore_pressure_kPa"],
                                                                           weights=weights))})
        problem.columns = {**problem.columns, "pore_pressure_kPa": "mean excess pore pressure [kPa], compression +"}
    params = {"case": case.name, **case_record(case), **problem.record, "solver": options.to_dict(),
              "material": material_record(problem.material), "ndofs": problem.disc.ndofs}
    saved, scale = None, 1.0
    elsewhere = not isinstance(resume, bool) and resume is not None
    if resume is not False and resume is not None:
        saved, scale = _checkpoint_to_resume(Path(resume) if elsewhere else out_dir, params,
                                             getattr(case, "extend", None), problem.disc)
    continuing = saved is not None and not elsewhere  # the same folder: its files go on
    log = newton_log(out_dir, saved[1]["newton_log_rows"] if continuing else None)
    newton = NewtonSolver(problem.disc, problem.material, problem.dirichlet, f_fixed=problem.f_fixed,
                          initial_stress=problem.initial_stress, options=options, log=log)
    stages = problem.stages or [Stage(case.name, problem.dirichlet, problem.f_fixed, None, case.steps,
                                      control=problem.control, control_end=problem.control_end)]
    k0 = 0 if saved is None else int(saved[1].get("stage", 0))
    law = problem.material
    if problem.stages:
        newton.set_stage(stages[k0].dirichlet, stages[k0].f_fixed, stages[k0].f_ramp)
        if stages[k0].elastic:
            _use_material(newton, _elastic_twin(law), restart=saved is None)
    if saved is not None and scale != 1.0:
        if k0 != len(stages) - 1:
            scale = 1.0  # the loading stage has not begun: it starts at 0 whatever its end
        else:
            _rescale_history(saved[1], scale, out_dir if continuing else None)
    run_state = None if saved is None else ck.restore(newton, *saved, scale=scale)
    if saved is not None:
        for key in problem.persist:
            if f"data__{key}" not in saved[0]:
                raise ValueError(f"checkpoint: lacks the case's {key!r} (written by an older version); rerun the case "
                                 "from the start")
            problem.data[key] = saved[0][f"data__{key}"].copy()
    writer = ckpt = None
    if out_dir is not None:
        from femgran.output import SeriesWriter, write_parameters

        if not continuing or scale != 1.0:  # a new run, or one whose end moved
            write_parameters(out_dir / "parameters.json", params)
            _write_case_file(out_dir, case, material, options, output)
        writer = SeriesWriter(out_dir, problem.disc, name=case.name, every=output.write_every,
                              resume=saved[1]["writer"] if continuing else None)
        ckpt = ck.Checkpointer(out_dir, jsonable(params), every=output.checkpoint_every, keep=output.keep_checkpoints)
    first = 0 if run_state is None else run_state["n_step"]
    if problem.stages:
        columns = {**problem.columns, "stage": "stage of the run (0, 1, ...)",
                   "time": "stage + its load factor (the time of the field series)"}
        observers.append(lambda s: {"stage": s.stage, "time": s.time_offset + s.t})
    else:
        columns = problem.columns
    with _interruptions() as signals:
        def after_step(solver, state):
            if ckpt is not None and (ckpt.due(state["n_step"]) or signals):
                ckpt.write(solver, state, writer, {k: problem.data[k] for k in problem.persist})
            if signals:
                return f"interrupted by {signals[0]} at t = {solver.t:.6g}"
            if max_steps is not None and state["n_step"] - first >= max_steps:
                return f"stopped after {max_steps} step(s) as asked (max_steps), at t = {solver.t:.6g}"
            return None

        for k in range(k0, len(stages)):
            stage = stages[k]
            if k > k0:  # the next stage starts from the end of this one (stage k0 is set up above)
                newton.set_stage(stage.dirichlet, stage.f_fixed, stage.f_ramp)
                if stage.elastic:
                    _use_material(newton, _elastic_twin(law), restart=True)
                elif stages[k - 1].elastic:
                    _use_material(newton, law, restart=True)
                run_state = {"dt": 1.0 / stage.steps, "n_step": newton.run_state["n_step"],
                             "history": newton.run_state["history"].rows(),
                             "residual_log": newton.run_state["residual_log"]}
            newton.stage, newton.time_offset = k, float(k) if problem.stages else 0.0
            sol = newton.run(stage.steps, writer=writer, progress=output.progress, observers=observers,
                             fixed_steps=problem.fixed_steps, descriptions=columns, resume=run_state,
                             after_step=after_step, close_writer=False, control=stage.control,
                             control_end=stage.control_end)
            if not sol.completed:
                if problem.stages:
                    sol.stop_reason = f"stage {stage.name!r}: {sol.stop_reason}"
                break
    from femgran.diagnostics import ellipticity_report, ellipticity_summary

    localisation = ellipticity_summary(newton._committed_tangent, newton.disc.dim)
    if not sol.completed and not signals:
        from femgran.diagnostics import stall_report, uniqueness_report

        for note in (stall_report(newton),
                     uniqueness_report(newton.points.material, newton.points.stress, newton.points.state),
                     ellipticity_report(localisation)):
            if note:
                sol.stop_reason = f"{sol.stop_reason}; {note}"
    if writer is not None:
        writer.close(newton, sol.completed, sol.stop_reason)
    if ckpt is not None:
        if ckpt.last_step != newton.run_state["n_step"]:
            ckpt.write(newton, newton.run_state, writer,  # the end, or the last converged step of a stop
                       {k: problem.data[k] for k in problem.persist})
        ckpt.close()  # every checkpoint on disk before the run returns
    summary = {**case.summarise(sol, problem), **_overstress_summary(newton.points), **localisation}
    sol.extra.update(params=params, **summary)
    sol.extra["newton_log"] = newton.log  # femgran.diagnostics.NewtonLog of this process's part of the run
    if out_dir is not None:
        from femgran.output import write_parameters

        if summary:
            write_parameters(out_dir / "summary.json", summary)
        if output.plots and hasattr(case, "plots"):
            case.plots(sol, problem, out_dir)
    if signals:
        if out_dir is not None:
            _mark_interrupted(out_dir)
        raise KeyboardInterrupt(f"{sol.stop_reason}; every converged step is in {out_dir}; continue with "
                                f"femgran run --resume {out_dir}" if out_dir is not None else sol.stop_reason)
    return sol


def _overstress_summary(points) -> dict:
    """What a step stabilisation changed in the last converged step (a law that is ``rate_dependent``):
    over the points with a loading plane, the 99th percentile and the largest of ``state["overstress"]``,
    the share of a plane's mobilised ratio that the stabilisation's floor carries above the hardening
    curve (``docs/cpa_law.md``, section 4). Empty for other laws."""
    over = points.state.get("overstress")
    if over is None or not getattr(points.material, "rate_dependent", False):
        return {}
    loading = np.asarray(points.state["loading"]).any(axis=1)
    o = np.asarray(over, float)[loading] if loading.any() else np.zeros(1)
    return {"stabilisation_overstress_p99": float(np.quantile(o, 0.99)),
            "stabilisation_overstress_max": float(o.max())}


def _rescale_history(info: dict, scale: float, out_dir) -> None:
    """A resumed run whose loading stage was extended (its end moved): the load factors already recorded,
    in the history, the series and the files, are rescaled so that t keeps its meaning (the fraction of
    the new end)."""
    stage = int(info.get("stage", 0))
    for row in info["history"]:
        if int(row.get("stage", 0)) == stage:
            row["load_factor"] = row["load_factor"] * scale
            if "time" in row:
                row["time"] = stage + (row["time"] - stage) * scale
    if info.get("writer"):
        info["writer"]["datasets"] = [[stage + (t - stage) * scale if t >= stage else t, f]
                                      for t, f in info["writer"]["datasets"]]
        if info["writer"]["last_written"] is not None and info["writer"]["last_written"] >= stage:
            info["writer"]["last_written"] = stage + (info["writer"]["last_written"] - stage) * scale
    if out_dir is not None:  # history.csv is rewritten with the rescaled rows (the writer then appends)
        from material.table import Table, read_table

        path = Path(out_dir) / "history.csv"
        old = read_table(path)
        table = Table(title=old.title, descriptions=old.descriptions, metadata=old.metadata, convention=old.convention)
        for row in info["history"]:
            table.append(row)
        table.write_csv(path)
        info["writer"]["count"] = len(info["history"])


def _checkpoint_to_resume(out_dir, params: dict, extend: str | None = None, disc=None):
    """The checkpoint to resume from and the scale of its load factor: 1, or old end / new end when the only
    change is the case's ``extend`` field (e.g. a larger target settlement), with or without a change of
    ``steps``. The nominal step after the resume is the new end over the new ``steps``: steps scaled as the
    end keep the step (and the step stabilisation's relaxation time, one nominal step) of the run so far,
    so the extended run is the run that aimed at the new end from the start. A different ``ndofs`` is no
    change when the discretisation ``disc`` takes up the checkpoint's vectors (its ``adapt_unknowns``: the
    plane-strain back stress from a checkpoint of six fields)."""
    from femgran import checkpoint as ck
    from material.table import jsonable

    if out_dir is None:
        raise ValueError("resume=True: needs output.out, the run folder of the run to continue")
    out_dir = Path(out_dir)
    path = ck.latest(out_dir)
    if path is None:
        raise FileNotFoundError(f"resume {out_dir}: no checkpoint to continue from ({out_dir}/checkpoints is empty)")
    arrays, info = ck.load(path)
    now = jsonable(params)
    changes = ck.identity_changes(info["identity"], now)
    saved_ndofs = info["identity"].get("ndofs")
    if hasattr(disc, "adapt_unknowns") and saved_ndofs != now.get("ndofs"):
        try:
            disc.adapt_unknowns(np.zeros(int(saved_ndofs)))
            changes = [c for c in changes if not c.startswith("ndofs:")]
        except (TypeError, ValueError):
            pass  # another layout: the change stays and is reported
    scale = 1.0
    if extend and any(c.startswith(f"{extend}:") for c in changes) \
            and all(c.startswith((f"{extend}:", "steps:")) for c in changes):
        old, new = info["identity"][extend], now[extend]
        if isinstance(old, (int, float)) and isinstance(new, (int, float)) and new > 0:
            scale, changes = old / new, []
    if changes:
        raise ValueError(f"resume {out_dir}: the inputs differ from those of the checkpoint: " + "; ".join(changes)
                         + (f" (only {extend}, and steps with it, may change on a resume: the loading then goes on to "
                            "its new end)"
                            if extend else ""))
    info["identity"] = now
    return (arrays, info), scale


def _write_case_file(out_dir: Path, case, material, options, output: Output) -> None:
    """``case.toml`` of the run when its material is data (None, a preset, a parameter file, a mapping):
    ``femgran run --resume`` reads it. A material object cannot be written; such a run resumes from Python."""
    from collections.abc import Mapping

    import tomli_w

    if not (material is None or isinstance(material, (str, Path, Mapping))):
        return
    spec = {} if material is None else dict(material) if isinstance(material, Mapping) else \
        {"preset": str(material)} if not str(material).lower().endswith((".toml", ".json")) else \
        {"parameters": str(Path(material).resolve())}
    doc = {"case": {"name": case.name, **{k: v for k, v in case_record(case).items() if v is not None}},
           "material": spec, "solver": options.to_dict(),
           "output": {k: v for k, v in dataclasses.asdict(output).items() if k != "out" and v is not None}}
    (out_dir / "case.toml").write_text(tomli_w.dumps(doc))


def _mark_interrupted(out_dir: Path) -> None:
    import json

    status = out_dir / "status.json"
    data = json.loads(status.read_text()) if status.is_file() else {}
    status.write_text(json.dumps({**data, "completed": False, "interrupted": True}, indent=2))


class _interruptions:
    """Ctrl-C and SIGTERM set a flag (the list of signal names) instead of stopping the process where it
    is: the run ends its step, writes a checkpoint and stops cleanly. Only in the main thread."""

    def __enter__(self):
        import signal
        import threading

        self.signals: list[str] = []
        self.old = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.old[sig] = signal.signal(sig, lambda num, frame: self.signals.append(signal.Signals(num).name))
        return self.signals

    def __exit__(self, *exc):
        import signal

        for sig, handler in self.old.items():
            signal.signal(sig, handler)
        return False
