"""What the material does inside each global Newton iteration: a log to find out why Newton is slow.

:class:`NewtonLog` records one row per global iteration (every material evaluation of the solver,
line-search trials included) with

* ``step``, ``attempt`` (0 for the first try of a step, 1.. after cut-backs), ``iteration``,
  ``load_factor``, ``residual`` (relative, as the solver's test), ``line_search`` (the step length s
  that produced this iterate; 1 for a full Newton step, 0 for the predictor) and ``accepted`` (whether
  the iterate was kept: line-search trials that were rejected have 0);
* ``points_switched`` / ``planes_switched``: points whose set of loading planes (CPA: state key
  ``loading``; laws with ``eq_plastic_strain``: plastic or not) differs from the previous accepted
  iterate of the same step, and the number of planes that switched between loading and not;
* ``loading_points``: points with at least one loading plane (or plastic);
* ``apex_points``: points within the apex region of their law (state key ``near_apex``);
* ``local_iterations_mean`` / ``_max`` (state key ``iterations``, over the plastic points),
  ``continuation_points`` (state key ``continuation`` > 0: the local solver needed its outer loop),
  ``limit_points`` (state key ``limit_points`` > 0: the step went on from a limit point of its branch),
  ``failed_points`` (status FAILED);
* ``rate``: the estimated order of convergence log(r_k / r_k-1) / log(r_k-1 / r_k-2) of the accepted
  iterates (2 for quadratic, 1 for linear convergence);
* on the rows of full Newton steps (line search s = 1), what made the step miss: ``overshoot`` (its
  residual over the iterate's), ``overshoot_points``, ``overshoot_pressure``, ``overshoot_unloading``,
  ``overshoot_planes``, ``overshoot_point`` (:func:`full_step_overshoot`; NaN on the other rows; only
  ``overshoot`` for a coupled discretisation).

The rows are kept in memory (:attr:`NewtonLog.rows`, also as :meth:`NewtonLog.table`) and, with a
path, appended to a CSV file as they come (``newton_log.csv`` in a case's run folder).

:func:`kinks_along` looks inside one iteration: it evaluates the material along a Newton direction and
finds the points whose response has a kink there (and where), which is what makes a full Newton step
overshoot; :func:`solver_kinks_along` does the same from a solver's increment and direction.

:func:`zero_step_drift` checks what a cut-back relies on: that the material returns the committed stress
for a vanishing step. Where it does not (an update that relaxes an overstress over the step whatever its
size, or a law whose equations change between steps), the step's problem stays a finite distance from
the committed equilibrium however far the step is cut back, and cut-backs cannot help; ``femgran replay``
prints it for the state a run stopped in.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from material.base import STATUS_FAILED

__all__ = ["NewtonLog", "COLUMNS", "full_step_overshoot", "kinks_along", "solver_kinks_along", "stall_report",
           "zero_step_drift", "uniqueness_report", "cpa_law", "rice_indicator", "ellipticity_summary",
           "ellipticity_report"]

COLUMNS = ("step", "attempt", "iteration", "load_factor", "residual", "line_search", "accepted",
           "points_switched", "planes_switched", "loading_points", "apex_points", "local_iterations_mean",
           "local_iterations_max", "continuation_points", "limit_points", "failed_points", "rate",
           "overshoot", "overshoot_points", "overshoot_pressure", "overshoot_unloading", "overshoot_planes",
           "overshoot_point")


DESCRIPTIONS = {
    "step": "load step", "attempt": "try of the step (0, then one per cut-back)",
    "iteration": "global Newton iteration (0: the predictor)", "load_factor": "load factor of the try [-]",
    "residual": "relative residual of this evaluation [-]",
    "line_search": "step length along the Newton direction (0 for the predictor)",
    "accepted": "1 if the iterate was taken, 0 for a rejected line-search trial",
    "points_switched": "points whose set of loading planes changed since the last accepted iterate",
    "planes_switched": "planes that changed between loading and not since the last accepted iterate",
    "loading_points": "points with at least one loading plane", "apex_points": "points at the rounded apex",
    "local_iterations_mean": "mean local Newton iterations of the points that iterated",
    "local_iterations_max": "largest local Newton iteration count",
    "continuation_points": "points that needed the continuation of the local solver",
    "limit_points": "points whose step passed a limit point of its branch (went on from the limit state)",
    "failed_points": "points that could not be integrated", "rate": "estimated order of convergence",
    "overshoot": "full Newton step: |residual| over the iterate's, the force of the stress the tangent did not "
                 "predict over the force it predicted",
    "overshoot_points": "full Newton step: fewest points holding half of the unpredicted stress (times volume)",
    "overshoot_pressure": "full Newton step: mean stress of the point with the most unpredicted stress [kPa], "
                          "compression +",
    "overshoot_unloading": "full Newton step: loading planes that stopped loading at that point",
    "overshoot_planes": "full Newton step: loading planes of that point at the iterate (against those of the "
                        "other points: docs/cpa_law.md, section 4)",
    "overshoot_point": "full Newton step: index of the point with the most unpredicted stress (the order of the "
                       "output's point data)",
}


def full_step_overshoot(volume, stress0, tangent0, stress1, direction, loading0=None,
                        loading1=None) -> dict | None:
    """Which points make a full Newton step miss the tangent's prediction.

    The Newton direction is computed from the tangent D0 at the iterate; along it each point's stress is
    predicted as sigma0 + D0 : d_eps, d_eps = ``direction`` (N, 3, 3) the direction's strain, and the full
    step returns sigma1. The residual at the full step is the internal force of the unpredicted stress
    sigma1 - sigma0 - D0 : d_eps (the predicted part cancels the iterate's residual when the linear solve is
    exact), so |r(full step)| / |r(iterate)| measures the miss (the solver logs it as ``overshoot``) and
    this function says where it comes from. ``volume`` (N,): the points' integration weights. Returns

    * ``share`` (N,): each point's |unpredicted stress| (Frobenius) times its volume, over the sum;
    * ``overshoot_points``: the fewest points whose shares add up to half (1 or 2: a few points make the
      step miss; hundreds: the whole body responds nonlinearly; 0 when nothing is missed beyond round-off);
    * ``overshoot_pressure``: the mean stress -tr(sigma0)/3 of the largest share [kPa];
    * ``overshoot_unloading``: how many of its loading planes stop loading at the full step (when the
      law reports ``loading``, (N, planes) bool, at the iterate and at the full step; else NaN);
    * ``overshoot_planes``: how many planes load at that point at the iterate (NaN likewise);
    * ``overshoot_point``: that point's index (NaN when nothing is missed): whether one place, e.g. a
      corner, makes the steps miss, or the misses wander over the plastic zone.

    None when the tangent is not a plain (N, 3, 3, 3, 3) array (a coupled field's tangent). No material
    call and no assembly (about 0.2 ms for 2,430 points).
    """
    if not isinstance(tangent0, np.ndarray) or tangent0.ndim != 5:
        return None
    n = len(tangent0)
    predicted = np.matmul(tangent0.reshape(n, 9, 9), np.asarray(direction).reshape(n, 9, 1)).reshape(n, 9)
    missed = np.asarray(stress1).reshape(n, 9) - np.asarray(stress0).reshape(n, 9) - predicted
    volume = np.asarray(volume).ravel()
    score = np.linalg.norm(missed, axis=1) * volume
    total = score.sum()
    if total <= 1e-12 * np.sum(np.linalg.norm(predicted, axis=1) * volume):
        total = 0.0  # round-off: the response is linear along the step
    share = score / total if total > 0 else np.zeros_like(score)
    top = int(np.argmax(share))
    out = {"share": share,
           "overshoot_points": int(np.searchsorted(np.cumsum(np.sort(share)[::-1]), 0.5) + 1) if total > 0 else 0,
           "overshoot_pressure": float(-np.trace(np.asarray(stress0)[top]) / 3.0), "overshoot_unloading": math.nan,
           "overshoot_planes": math.nan, "overshoot_point": top if total > 0 else math.nan}
    if loading0 is not None and loading1 is not None:
        l0, l1 = np.asarray(loading0, dtype=bool), np.asarray(loading1, dtype=bool)
        if l0.shape == l1.shape and l0.ndim == 2:
            out["overshoot_unloading"] = int((l0[top] & ~l1[top]).sum())
            out["overshoot_planes"] = int(l0[top].sum())
    return out


def _loading_mask(state, committed) -> np.ndarray | None:
    """(N, k) bool: which planes (or the point, k = 1) load in this iterate; None if the law says nothing."""
    if "loading" in state:
        return np.asarray(state["loading"], dtype=bool).reshape(len(state["loading"]), -1)
    if "eq_plastic_strain" in state and committed is not None and "eq_plastic_strain" in committed:
        return (np.asarray(state["eq_plastic_strain"]) > np.asarray(committed["eq_plastic_strain"]))[:, None]
    return None


class NewtonLog:
    """Per-iteration record of a :class:`femgran.solver.NewtonSolver` run (see the module docstring).

    Parameters
    ----------
    path : path or None
        CSV file the rows are appended to as they come (the header is written first); None keeps them
        in memory only.
    """

    def __init__(self, path=None, resume_rows: int | None = None):
        self.path = None if path is None else Path(path)
        self.rows_written = 0 if resume_rows is None else int(resume_rows)
        self.rows: list[dict] = []
        self._previous = None
        self._accepted: list[float] = []
        self._writer = None
        if self.path is not None:
            from material.table import TableWriter, truncate_rows

            if resume_rows is not None:  # a resumed run: drop the rows written after its checkpoint
                truncate_rows(self.path, resume_rows)
            self._writer = TableWriter(self.path, title="Newton log", descriptions=DESCRIPTIONS,
                                       append=resume_rows is not None)

    def start_try(self) -> None:
        """A new try of a step begins (first try or after a cut-back): forget the previous iterate."""
        self._previous = None
        self._accepted = []

    def record(self, *, step: int, attempt: int, iteration: int, load_factor: float, residual: float,
               line_search: float, accepted: bool, state: dict, committed: dict | None,
               overshoot: dict | None = None) -> dict:
        """Add the row of one material evaluation; ``state`` is the trial state it returned; ``overshoot``
        the :func:`full_step_overshoot` of a full Newton step."""
        mask = _loading_mask(state, committed)
        row = {"step": step, "attempt": attempt, "iteration": iteration, "load_factor": load_factor,
               "residual": residual, "line_search": line_search, "accepted": int(bool(accepted))}
        if mask is not None and self._previous is not None and self._previous.shape == mask.shape:
            diff = mask != self._previous
            row["points_switched"] = int(diff.any(axis=1).sum())
            row["planes_switched"] = int(diff.sum())
        else:
            row["points_switched"] = row["planes_switched"] = math.nan
        row["loading_points"] = int(mask.any(axis=1).sum()) if mask is not None else math.nan
        row["apex_points"] = int(np.sum(state["near_apex"])) if "near_apex" in state else math.nan
        its = np.asarray(state.get("iterations", []))
        active = its[its > 0] if its.size else its
        row["local_iterations_mean"] = float(active.mean()) if active.size else 0.0
        row["local_iterations_max"] = int(its.max()) if its.size else 0
        row["continuation_points"] = int(np.sum(np.asarray(state["continuation"]) > 0)) if "continuation" in state \
            else math.nan
        row["limit_points"] = int(np.sum(np.asarray(state["limit_points"]) > 0)) if "limit_points" in state \
            else math.nan
        row["failed_points"] = int(np.sum(np.asarray(state["status"]) == STATUS_FAILED))
        row["rate"] = math.nan
        for c in ("overshoot", "overshoot_points", "overshoot_pressure", "overshoot_unloading", "overshoot_planes",
                  "overshoot_point"):
            row[c] = math.nan if overshoot is None else overshoot[c]
        if accepted:
            self._accepted.append(residual)
            r = self._accepted
            if len(r) >= 3 and min(r[-3:]) > 0 and r[-2] != r[-3] and r[-1] != r[-2]:
                den = math.log(r[-2] / r[-3])
                row["rate"] = math.log(r[-1] / r[-2]) / den if den != 0 else math.nan
            if mask is not None:
                self._previous = mask.copy()
        self.rows.append(row)
        if self._writer is not None:
            self._writer.write({c: row[c] for c in COLUMNS})
        self.rows_written += 1
        return row

    def table(self) -> dict[str, np.ndarray]:
        """The rows as columns (name -> array)."""
        return {c: np.array([r[c] for r in self.rows], dtype=float) for c in COLUMNS}

    def summary(self) -> dict:
        """Figures of the whole run: evaluations, accepted iterations, switches of points and planes between
        loading and not (per accepted iterate and summed over the run), the largest apex and failed counts, the
        median convergence rate, and the full Newton steps the line search rejected."""
        t = self.table()
        if not self.rows:
            return {}
        acc = t["accepted"] == 1
        out = {
            "evaluations": len(self.rows),
            "accepted_iterations": int(acc.sum()),
            "line_search_rejections": int((~acc).sum()),
            "mean_points_switched": float(np.nanmean(t["points_switched"][acc])) if acc.any() else math.nan,
            # along the accepted path of the whole run: how often a point's set of loading planes changed (a
            # number per run, not per step, for the CPA footing: docs/cpa_law.md, section 4)
            "points_switched_total": int(np.nansum(t["points_switched"][acc])),
            "planes_switched_total": int(np.nansum(t["planes_switched"][acc])),
            "max_apex_points": float(np.nanmax(t["apex_points"])) if np.isfinite(t["apex_points"]).any() else math.nan,
            "max_failed_points": int(np.nanmax(t["failed_points"])),
            "median_rate": float(np.nanmedian(t["rate"])) if np.isfinite(t["rate"]).any() else math.nan,
        }
        full = np.isfinite(t["overshoot"])
        missed = full & ~acc
        out["full_steps"] = int(full.sum())
        out["full_steps_rejected"] = int(missed.sum())
        out["median_overshoot_points_rejected"] = float(np.median(t["overshoot_points"][missed])) if missed.any() \
            else math.nan
        return out


def kinks_along(material, stress, state, d_strain, direction, s, *, along: dict | None = None,
                **inputs) -> dict[str, np.ndarray]:
    """The material's response along the straight path d_strain + s * direction, s in ``s`` (uniform).

    stress (N, 3, 3) and state: the committed start of the step; d_strain, direction (N, 3, 3): the
    strain increment of the current iterate and of the Newton direction. Each s is one material call
    from the committed state (as the solver makes them). Per point the stress rate along s,
    d sigma / ds, is taken on each interval; its largest jump between neighbouring intervals, relative
    to the largest rate of that point, is ``slope_jump`` (about h times the curvature where the response
    is smooth, of order 1 at a kink), at ``s_kink`` (the grid point between the two intervals). Where
    the state has ``loading`` (CPA), ``loading_before`` / ``loading_after`` count the loading planes on
    either side of the kink. Also ``rate`` (N,): the largest |d sigma / ds| [kPa per unit s], and
    ``failed_at`` (N,): the first s at which the point's update fails (status FAILED; NaN where it never
    does), where the branch the update follows from the start of the step ends.
    ``inputs``: the material's other inputs, as the solver passes them (``step_fraction``); ``along``: those
    that move with s, name -> (value at s = 0, change per unit s), e.g. the increment of a coupled field at
    the points (``d_nonlocal`` of the implicit gradient), which the Newton direction moves with the strain.
    """
    s = np.asarray(s, dtype=float)
    if s.ndim != 1 or s.size < 3 or not np.allclose(np.diff(s), s[1] - s[0]) or s[1] <= s[0]:
        raise ValueError(f"s: need at least 3 increasing, equally spaced values, got {s!r}")
    n = len(stress)
    sig, loading, failed = [], [], []
    for si in s:
        copy = {k: np.array(v, copy=True) for k, v in state.items()}
        moving = {k: np.asarray(a) + si * np.asarray(b) for k, (a, b) in (along or {}).items()}
        out, st, _ = material.update(d_strain + si * direction, stress, copy, **inputs, **moving)
        sig.append(out.reshape(n, 9))
        failed.append(np.asarray(st["status"]) == STATUS_FAILED if "status" in st else np.zeros(n, bool))
        if "loading" in st:
            loading.append(np.asarray(st["loading"]).sum(axis=1))
    sig = np.array(sig)  # (ns, N, 9)
    slope = np.diff(sig, axis=0) / (s[1] - s[0])  # (ns - 1, N, 9)
    rate = np.abs(slope).max(axis=(0, 2))
    jump = np.abs(np.diff(slope, axis=0)).max(axis=2) / np.maximum(rate, 1e-300)  # (ns - 2, N)
    k = jump.argmax(axis=0)
    pts = np.arange(n)
    failed = np.array(failed)
    out = {"slope_jump": jump[k, pts], "s_kink": s[k + 1], "rate": rate,
           "failed_at": np.where(failed.any(axis=0), s[failed.argmax(axis=0)], np.nan)}
    if loading:
        loading = np.array(loading)
        out["loading_before"], out["loading_after"] = loading[k, pts], loading[k + 2, pts]
    return out


def solver_kinks_along(solver, du, ddu, s) -> dict[str, np.ndarray]:
    """:func:`kinks_along` for a :class:`femgran.solver.NewtonSolver` at the iterate du with Newton
    direction ddu (unknown vectors), from its committed stress and state; a coupled field's increment at
    the points (``disc.point_inputs``) moves along with the strain."""
    d_strain, direction = solver.disc.strain(du), solver.disc.strain(ddu)  # the strain is linear in u
    rate, along = _inputs_along(solver, du, ddu)
    return kinks_along(solver.points.material, solver.points.stress, solver.points.state, d_strain, direction, s,
                       along=along, **rate)


def _inputs_along(solver, du, ddu) -> tuple[dict, dict]:
    """The material's inputs besides the strain along du + s ddu: (those that stay, ``step_fraction`` of a
    rate-dependent law; those that move, name -> (value at du, change per unit s)). The coupled fields'
    point values are linear in the unknowns (interpolations), so two evaluations give them at every s."""
    rate = {"step_fraction": solver.step_fraction} if getattr(solver.points.material, "rate_dependent", False) else {}
    at0, at1 = solver.disc.point_inputs(du), solver.disc.point_inputs(du + ddu)
    return rate, {k: (np.asarray(at0[k]), np.asarray(at1[k]) - np.asarray(at0[k])) for k in at0}


def zero_step_drift(material, stress, state, inputs=None, step_fractions=(1.0, 2.0 ** -8)) -> dict[float, np.ndarray]:
    """The stress change of a zero strain increment from the committed (stress, state), relative to each
    point's largest stress component: (N,) for each step size in ``step_fractions`` (in the law's relaxation
    times, :func:`material.base.step_fraction`; used only by a ``rate_dependent`` law). ``inputs``: the
    material's other inputs for a zero increment (a coupled discretisation's ``point_inputs`` of a zero
    displacement, e.g. ``d_nonlocal`` = 0).

    A law whose update is continuous at the committed state gives round-off for every size; a step
    stabilisation with a relaxation time of the current step (instead of a fixed one) gives a drift that
    does not shrink with the step (measured in ``docs/cpa_law.md``, section 4)."""
    stress = np.asarray(stress, dtype=float)
    n = stress.shape[0]
    scale = np.maximum(np.abs(stress).max(axis=(1, 2)), 1e-300)
    out = {}
    for f in step_fractions:
        extra = dict(inputs or {})
        if getattr(material, "rate_dependent", False):
            extra["step_fraction"] = float(f)
        copy = {k: np.array(v, copy=True) for k, v in state.items()}
        s, _, _ = material.update(np.zeros((n, 3, 3)), stress, copy, **extra)
        out[float(f)] = np.abs(np.asarray(s) - stress).max(axis=(1, 2)) / scale
    return out


def stall_report(solver, points: int = 21) -> str:
    """Why the last try of a step found no decrease of the residual along its Newton direction, as one
    sentence (empty when that try ended otherwise). A coupled field's increment at the points (the implicit
    gradient's ``d_nonlocal``, the back stress's fields) moves along the direction with the strain.

    The solver keeps the iterate, the direction and the shortest trial s of that line search
    (``NewtonSolver.stalled``); the material is evaluated at ``points`` equally spaced s in [0, s] from the
    committed state (:func:`kinks_along`). A point whose update fails there has, beyond that s, no solution
    that its local solver reaches on the branch from the start of the step (the branch ends at a fold, or
    the local iterations run out: ``replay`` its inputs with a larger ``maxit`` to tell which). The residual
    cannot fall below the jump this makes, and cutting the step back does not remove it when that s lies in
    the direction the equilibrium needs. Such a point is then evaluated at the full Newton step too; where it
    integrates there, the law's strain-driven problem has a second solution from the same start, and
    the sentence gives both branches' loading planes and second-order work (a negative one is a
    softening response: the material state is unstable). Where no point fails, the sentence names the
    point with the largest jump of its stress rate. Either way it ends with the law's uniqueness at the
    iterate itself (:func:`_iterate_uniqueness`: the committed state's report misses the planes that load
    within the step, e.g. every plane of an in-situ state inside its elastic margin). Measured on the
    thesis-sand footing in ``docs/cpa_law.md``, section 4."""
    last = getattr(solver, "stalled", None)
    if last is None:
        return ""
    du, ddu, s_short = last
    s = np.linspace(0.0, s_short, max(int(points), 3))
    probe = solver_kinks_along(solver, du, ddu, s)
    pts = solver.points
    mean = -np.trace(pts.stress, axis1=1, axis2=2) / 3.0
    where = f"along the last Newton direction (its line search tried down to s = {s_short:.2g})"
    bad = np.flatnonzero(np.isfinite(probe["failed_at"]))
    if bad.size == 0:
        i = int(np.argmax(probe["slope_jump"]))
        return (f"{where} every point's update has a solution; the largest jump of a point's stress rate is at "
                f"point {i} (mean stress {mean[i]:.3g} kPa, at s = {probe['s_kink'][i]:.2g})"
                + _iterate_uniqueness(solver, du))
    i = int(bad[np.argmin(probe["failed_at"][bad])])
    s_fail = float(probe["failed_at"][i])
    s_before = float(s[max(int(np.searchsorted(s, s_fail)) - 1, 0)])
    d_strain, direction = solver.disc.strain(du), solver.disc.strain(ddu)
    rate, along = _inputs_along(solver, du, ddu)
    branches = []
    for si in (s_before, 1.0):
        copy = {k: np.array(v[i:i + 1], copy=True) for k, v in pts.state.items()}
        de = d_strain[i:i + 1] + si * direction[i:i + 1]
        moving = {k: a[i:i + 1] + si * b[i:i + 1] for k, (a, b) in along.items()}
        sig, st, _ = pts.material.update(de, pts.stress[i:i + 1], copy, **rate, **moving)
        ok = "status" not in st or int(np.asarray(st["status"])[0]) != STATUS_FAILED
        planes = int(np.asarray(st["loading"])[0].sum()) if "loading" in st else None
        work = float(np.sum((np.asarray(sig)[0] - pts.stress[i]) * de[0]))
        branches.append((ok, planes, work))
    (_, planes0, work0), (ok1, planes1, work1) = branches
    text = (f"{where} the update of {bad.size} point(s) fails on its branch from the start of the step beyond "
            f"s = {s_fail:.2g} (point {i}: mean stress {mean[i]:.3g} kPa")
    if planes0 is not None:
        text += f", {planes0} loading planes before it, second-order work {work0:.2g} kPa"
    if ok1:
        text += (f"; at the full Newton step it integrates on another branch from the same start"
                 + (f", {planes1} loading planes, second-order work {work1:.2g} kPa" if planes1 is not None else "")
                 + ": the strain-driven problem has two solutions there")
    return text + "; docs/cpa_law.md, section 4)" + _iterate_uniqueness(solver, du)


def _iterate_uniqueness(solver, du) -> str:
    """For :func:`stall_report`: where the CPA law's rate problem has no unique solution (by the sufficient
    condition of :meth:`material.CPAModel.uniqueness_floor`) at the iterate du, whose planes loading within
    the step the committed state's report (:func:`uniqueness_report`) does not see; empty where it is unique
    at every point, or for another law."""
    law = cpa_law(solver.points.material)
    if law is None:
        return ""
    pts = solver.points
    rate = {"step_fraction": solver.step_fraction} if getattr(pts.material, "rate_dependent", False) else {}
    copy = {k: np.array(v, copy=True) for k, v in pts.state.items()}
    sig, st, _ = pts.material.update(solver.disc.strain(du), pts.stress, copy, **rate, **solver.disc.point_inputs(du))
    mu = law.uniqueness_floor(sig, st)
    lost = mu > 0.0
    if not lost.any():
        return "; at the iterate the rate problem is unique at every point (by the sufficient condition)"
    worst = int(np.argmax(mu))
    loading = np.asarray(st["loading"]).sum(axis=1) if "loading" in st else None
    planes = f", {int(loading[worst])} loading planes" if loading is not None else ""
    return (f"; at the iterate (with the planes that load within the step) the rate problem has no unique solution "
            f"(by the sufficient condition) at {int(lost.sum())} of {mu.size} points, up to mu = {mu[worst]:.3g} "
            f"(point {worst}, mean stress {-np.trace(sig[worst]) / 3.0:.3g} kPa{planes})")


def cpa_law(material):
    """The CPA law of ``material`` (itself, or the law inside the undrained wrapper), or None for another law."""
    law = material
    while not hasattr(law, "uniqueness_floor") and hasattr(law, "law"):
        law = law.law
    return law if hasattr(law, "uniqueness_floor") else None


def uniqueness_report(material, stress, state) -> str:
    """Where a CPA law's rate problem at the committed (stress, state) has no unique solution, as one
    sentence (empty where every point's has one, or for a law without :meth:`material.CPAModel.uniqueness_floor`).

    The thesis's non-associated law near failure can have several stress rates for one strain rate
    (``docs/cpa_law.md``, section 4): a global Newton that meets such a point cannot converge below the jump
    of its response, so a run that stops there is told so. The bound is the least uniform step
    stabilisation that restores uniqueness at the start of the step by a sufficient condition; it does not
    see planes that join within a step, so a run can also stop where it reports none."""
    law = cpa_law(material)
    if law is None:
        return ""
    stress = np.asarray(stress, dtype=float)
    mu = law.uniqueness_floor(stress, state)
    lost = mu > 0.0
    if not lost.any():
        return ""
    worst = int(np.argmax(mu))
    p = -np.trace(stress[worst]) / 3.0
    return (f"the CPA law's rate problem has no unique solution (by the sufficient condition) at {int(lost.sum())} "
            f"of {mu.size} points of the last converged step; the least step stabilisation that restores it there "
            f"is up to mu = {mu[worst]:.3g} (point {worst}, mean stress {p:.3g} kPa; this run's stabilisation: "
            f"{law.options.stabilisation!r}; docs/cpa_law.md, section 4)")



def rice_indicator(tangent, dim: int, coarse: bool = False):
    """Rice's indicator (N,) of a committed tangent (N, 3, 3, 3, 3) (:func:`material.localisation.ellipticity`;
    a gradient law's :class:`material.base.CoupledTangent` gives its d sigma / d eps), or None without one
    (before the first step). Normals in the model's plane for ``dim`` 2 (plane strain, axisymmetry) on a
    1 degree grid, over a hemisphere for 3 on a 5 degree grid (``coarse``: 10 degrees, for the field
    written at every step)."""
    from material.localisation import ellipticity

    T = getattr(tangent, "dstress_dstrain", tangent)
    if T is None or np.ndim(T) != 5:
        return None
    if dim == 2:
        return ellipticity(T, plane=(0, 1), resolution_deg=1.0)["indicator"]
    return ellipticity(T, plane=None, resolution_deg=10.0 if coarse else 5.0)["indicator"]


def ellipticity_summary(tangent, dim: int) -> dict:
    """Rice's localisation condition on a committed tangent, the consistent tangent of a run's last
    converged step (:func:`rice_indicator`): ``non_elliptic_points``, the points that have lost ellipticity
    (indicator below -:data:`material.localisation.ONSET`: past the onset), their share
    ``non_elliptic_fraction`` and the least indicator ``ellipticity_min``. Empty without a tangent.

    Where points have lost ellipticity, the body's rate problem admits bands there, and what a local
    rate-independent law computes beyond may depend on the mesh (``docs/cpa_law.md``, section 4, measures
    it on the footings)."""
    from material.localisation import ONSET

    ind = rice_indicator(tangent, dim)
    if ind is None:
        return {}
    lost = int(np.sum(ind < -ONSET))
    return {"non_elliptic_points": lost, "non_elliptic_fraction": lost / max(ind.size, 1),
            "ellipticity_min": float(ind.min()) if ind.size else float("nan")}


def ellipticity_report(summary: dict) -> str:
    """One sentence from :func:`ellipticity_summary` (empty where every point is elliptic)."""
    lost = summary.get("non_elliptic_points", 0)
    if not lost:
        return ""
    return (f"the tangent of the last converged step has lost ellipticity (Rice's condition, det(n.D.n) < 0) at "
            f"{lost} points ({100 * summary['non_elliptic_fraction']:.1f} %): there the body's rate problem admits "
            "bands, and a local law's results beyond may depend on the mesh (docs/cpa_law.md, section 4)")
