"""Shared plumbing of the cases: material construction, run folders, parameter records."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["make_material", "axes_plane_strain", "run_folder", "material_record", "solver_options"]


def axes_plane_strain(alpha_deg: float) -> np.ndarray:
    """Material axes of a plane-strain case whose vertical is global y.

    e2 (deposition axis) = (sin a, cos a, 0) at ``alpha_deg`` from y in the x-y plane,
    e1 = (cos a, -sin a, 0), e3 = z (out of plane); columns e1, e2, e3, right-handed.
    """
    a = np.radians(float(alpha_deg))
    if not np.isfinite(a):
        raise ValueError(f"alpha_deg = {alpha_deg!r}: must be finite")
    e1 = np.array([np.cos(a), -np.sin(a), 0.0])
    e2 = np.array([np.sin(a), np.cos(a), 0.0])
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def make_material(material, alpha_deg: float, *, plane_strain: bool, rule: str = "bazant-oh-33",
                  stabilisation: float = 0.0):
    """The material of a case.

    ``None``: the default CPA law ``CPAModel(load_preset("ottawa_c109"))``; a preset name or
    CPAParameters: a CPAModel; in both cases with material axes for ``alpha_deg`` (3D: z vertical,
    :func:`material.anisotropy.axes_from_alpha`; plane strain: y vertical, :func:`axes_plane_strain`)
    and the step ``stabilisation`` of :class:`material.CPAModel`. A material object is used as given
    (its own axes and options; ``alpha_deg`` is only recorded).
    """
    from material import CPAModel, CPAParameters, load_preset
    from material.anisotropy import axes_from_alpha

    if material is None or isinstance(material, (str, CPAParameters)):
        params = load_preset("ottawa_c109" if material is None else material) if not isinstance(material, CPAParameters) else material
        axes = axes_plane_strain(alpha_deg) if plane_strain else axes_from_alpha(alpha_deg)
        return CPAModel(params, rule=rule, axes=axes, stabilisation=stabilisation)
    return material


def keep_failed_points(material, out_dir) -> None:
    """Let a CPA material write the inputs of points that fail to integrate to ``out_dir/failed_points``
    (one replay file per failure, :func:`material.cpa.replay`), unless it already has a replay folder."""
    if out_dir is not None and hasattr(material, "replay_dir") and material.replay_dir is None:
        from pathlib import Path

        material.replay_dir = Path(out_dir) / "failed_points"


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


def newton_log(out_dir):
    """The Newton log of a run: ``newton_log.csv`` in the run folder (in memory without one)."""
    from femgran.diagnostics import NewtonLog

    return NewtonLog(None if out_dir is None else Path(out_dir) / "newton_log.csv")


def check_positive(name: str, value, allow_zero: bool = False) -> float:
    v = float(value)
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name} = {value!r}: must be {'>= 0' if allow_zero else '> 0'}")
    return v


def nodes_near(disc, point, tol: float = 1e-9) -> np.ndarray:
    """Scalar DOFs located at ``point`` (within tol times the mesh size)."""
    x = disc.dof_coordinates()
    span = np.ptp(disc.mesh.p, axis=1).max()
    return np.flatnonzero(np.linalg.norm(x - np.asarray(point, float)[None, :], axis=1) <= tol * span)
