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

__all__ = ["Problem", "Output", "run", "case_record", "param", "case", "describe"]


def param(default, help: str, *, flags: tuple = (), negative: str | None = None):
    """A field of a case dataclass with its meaning, unit and allowed values (``help``), which the class
    docstring, ``femgran <case> --help`` and the case-file documentation show. ``flags``: its command-line
    names (default ``--field-name``); ``negative``: a flag that sets a bool field to False."""
    return field(default=default, metadata={"help": help, "flags": tuple(flags), "negative": negative})


def describe(cls, indent: int = 4) -> str:
    """The fields of a case as text: name, default, meaning."""
    pad = " " * indent
    return "\n".join(f"{pad}{f.name} = {f.default!r}: {f.metadata.get('help', '')}" for f in dataclasses.fields(cls))


def case(cls):
    """Class decorator of a case: a frozen dataclass whose docstring ends with its fields (:func:`describe`)."""
    cls = dataclass(frozen=True)(cls)
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n\n    Fields (name = default: meaning)::\n\n" + describe(cls, 8) + "\n"
    return cls


@dataclass
class Problem:
    """What a case builds for one material: everything the solver needs and what to observe.

    observe : ``f(solver) -> dict`` of history columns for each converged step; ``solver.reaction``
        holds the out-of-balance force (the reactions on the prescribed DOFs) of that step.
    columns : meaning, unit and sign convention of each column ``observe`` gives (the history's header).
    record : what ``build`` chose (mesh, resolved defaults, ...), written to ``parameters.json``.
    data : anything ``summarise`` needs besides the solution.
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


@dataclass(frozen=True)
class Output:
    """Where and how a run writes: ``out`` the run folder (None: nothing on disk), ``write_every`` the
    field series every N converged steps (the history gets every step), ``plots`` the case's figures,
    ``progress`` a progress bar."""

    out: str | Path | None = None
    progress: bool = False
    write_every: int = 1
    plots: bool = True

    def __post_init__(self):
        if isinstance(self.write_every, bool) or int(self.write_every) != self.write_every or self.write_every < 1:
            raise ValueError(f"write_every = {self.write_every!r}: allowed integers >= 1")


def case_record(case) -> dict:
    """The case's fields as JSON-able values (paths as strings)."""
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(case).items()}


def run(case, material=None, *, solver=None, output: Output | None = None):
    """Run ``case`` with ``material`` (anything :func:`material.factory.make_material` takes), the solver
    options ``solver`` (:class:`femgran.solver.SolverOptions`, a mapping of its fields, or None) and
    ``output``. Returns the :class:`femgran.solver.Solution` with the case's summary as attributes."""
    from femgran.cases.common import keep_failed_points, material_record, newton_log, run_folder, solver_options
    from femgran.solver import NewtonSolver
    from material.factory import make_material

    output = Output() if output is None else output
    options = solver_options(solver)
    out_dir = run_folder(output.out)
    mat = make_material(material, alpha_deg=getattr(case, "alpha_deg", None), plane_strain=case.plane_strain)
    problem = case.build(keep_failed_points(mat, out_dir))
    newton = NewtonSolver(problem.disc, problem.material, problem.dirichlet, f_fixed=problem.f_fixed,
                          initial_stress=problem.initial_stress, options=options, log=newton_log(out_dir))
    params = {"case": case.name, **case_record(case), **problem.record, "solver": options.to_dict(),
              "material": material_record(problem.material), "ndofs": problem.disc.ndofs}
    writer = None
    if out_dir is not None:
        from femgran.output import SeriesWriter, write_parameters

        write_parameters(out_dir / "parameters.json", params)
        writer = SeriesWriter(out_dir, problem.disc, name=case.name, every=output.write_every)
    observers = [] if problem.observe is None else [problem.observe]
    sol = newton.run(case.steps, writer=writer, progress=output.progress, observers=observers,
                     fixed_steps=problem.fixed_steps, descriptions=problem.columns)
    summary = case.summarise(sol, problem)
    sol.extra.update(params=params, **summary)
    if out_dir is not None:
        from femgran.output import write_parameters

        if summary:
            write_parameters(out_dir / "summary.json", summary)
        if output.plots and hasattr(case, "plots"):
            case.plots(sol, problem, out_dir)
    return sol
