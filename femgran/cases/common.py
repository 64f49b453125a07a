"""Shared plumbing of the cases: run folders, parameter records, solver options.

The material of a case comes from :func:`material.factory.make_material`, as for the element drivers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from material.base import check_positive, check_steps  # noqa: F401  (the cases' validation)

__all__ = ["run_folder", "material_record", "solver_options", "newton_log", "check_positive", "check_steps",
           "nodes_near", "keep_failed_points"]


def keep_failed_points(material, out_dir):
    """The material a run uses: when it can keep the inputs of points that fail to integrate and has no
    folder of its own, a copy writing them to ``out_dir/failed_points`` (one replay file per failure,
    :func:`material.cpa.replay`); otherwise the material itself. The user's object is never changed."""
    if out_dir is None or getattr(material, "replay_dir", None) is not None or not hasattr(material, "with_replay_dir"):
        return material
    return material.with_replay_dir(Path(out_dir) / "failed_points")


def material_record(material) -> dict:
    """A JSON-able description of the material (its repr, parameters and axes if it has them)."""
    rec = {"repr": repr(material), "type": type(material).__name__}
    params = getattr(material, "params", None)
    if params is not None and hasattr(params, "to_dict"):
        rec["parameters"] = params.to_dict()
    for attr in ("E", "nu", "yield_stress", "hardening"):
        if hasattr(material, attr):
            rec[attr] = float(getattr(material, attr))
    options = getattr(material, "options", None)
    if options is not None and hasattr(options, "__dataclass_fields__"):
        rec["options"] = {k: getattr(options, k) for k in options.__dataclass_fields__}
    axes = getattr(material, "axes", None)
    if axes is not None:
        rec["axes_columns_e1_e2_e3"] = np.asarray(axes).tolist()
    return rec


def run_folder(out) -> Path | None:
    if out is None:
        return None
    p = Path(out)
    p.mkdir(parents=True, exist_ok=True)
    return p


def solver_options(solver=None, *, linear_solver: str | None = None, tol: float | None = None,
                   where: str = "solver"):
    """The SolverOptions of a case: ``solver`` (a SolverOptions, a mapping of its fields, or None: the
    solver's defaults) with the shorthands ``linear_solver`` and ``tol`` applied on top when given.
    Every case, the command line and the ``[solver]`` table of a case file go through here."""
    from femgran.solver import SolverOptions

    if tol is not None:
        tol = check_positive("tol", tol)
    return SolverOptions.resolve(solver, where=where, linear_solver=linear_solver, tol=tol)


def newton_log(out_dir, resume_rows: int | None = None):
    """The Newton log of a run: ``newton_log.csv`` in the run folder (in memory without one); a resumed
    run keeps its first ``resume_rows`` rows and appends."""
    from femgran.diagnostics import NewtonLog

    return NewtonLog(None if out_dir is None else Path(out_dir) / "newton_log.csv", resume_rows)


def nodes_near(disc, point, tol: float = 1e-9) -> np.ndarray:
    """Scalar DOFs located at ``point`` (within tol times the mesh size)."""
    x = disc.dof_coordinates()
    span = np.ptp(disc.mesh.p, axis=1).max()
    return np.flatnonzero(np.linalg.norm(x - np.asarray(point, float)[None, :], axis=1) <= tol * span)
