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
  ``failed_points`` (status FAILED);
* ``rate``: the estimated order of convergence log(r_k / r_k-1) / log(r_k-1 / r_k-2) of the accepted
  iterates (2 for quadratic, 1 for linear convergence).

The rows are kept in memory (:attr:`NewtonLog.rows`, also as :meth:`NewtonLog.table`) and, with a
path, appended to a CSV file as they come (``newton_log.csv`` in a case's run folder).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from material.base import STATUS_FAILED

__all__ = ["NewtonLog", "COLUMNS"]

COLUMNS = ("step", "attempt", "iteration", "load_factor", "residual", "line_search", "accepted",
           "points_switched", "planes_switched", "loading_points", "apex_points", "local_iterations_mean",
           "local_iterations_max", "continuation_points", "failed_points", "rate")


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

    def __init__(self, path=None):
        self.path = None if path is None else Path(path)
        self.rows: list[dict] = []
        self._previous = None
        self._accepted: list[float] = []
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text(",".join(COLUMNS) + "\n")

    def start_try(self) -> None:
        """A new try of a step begins (first try or after a cut-back): forget the previous iterate."""
        self._previous = None
        self._accepted = []

    def record(self, *, step: int, attempt: int, iteration: int, load_factor: float, residual: float,
               line_search: float, accepted: bool, state: dict, committed: dict | None) -> dict:
        """Add the row of one material evaluation; ``state`` is the trial state it returned."""
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
        row["failed_points"] = int(np.sum(np.asarray(state["status"]) == STATUS_FAILED))
        row["rate"] = math.nan
        if accepted:
            self._accepted.append(residual)
            r = self._accepted
            if len(r) >= 3 and min(r[-3:]) > 0 and r[-2] != r[-3] and r[-1] != r[-2]:
                den = math.log(r[-2] / r[-3])
                row["rate"] = math.log(r[-1] / r[-2]) / den if den != 0 else math.nan
            if mask is not None:
                self._previous = mask.copy()
        self.rows.append(row)
        if self.path is not None:
            with open(self.path, "a") as f:
                f.write(",".join(repr(float(row[c])) for c in COLUMNS) + "\n")
        return row

    def table(self) -> dict[str, np.ndarray]:
        """The rows as columns (name -> array)."""
        return {c: np.array([r[c] for r in self.rows], dtype=float) for c in COLUMNS}

    def summary(self) -> dict:
        """Figures of the whole run: accepted iterations per converged step, switches and rates."""
        t = self.table()
        if not self.rows:
            return {}
        acc = t["accepted"] == 1
        out = {
            "evaluations": len(self.rows),
            "accepted_iterations": int(acc.sum()),
            "line_search_rejections": int((~acc).sum()),
            "mean_points_switched": float(np.nanmean(t["points_switched"][acc])) if acc.any() else math.nan,
            "max_apex_points": float(np.nanmax(t["apex_points"])) if np.isfinite(t["apex_points"]).any() else math.nan,
            "max_failed_points": int(np.nanmax(t["failed_points"])),
            "median_rate": float(np.nanmedian(t["rate"])) if np.isfinite(t["rate"]).any() else math.nan,
        }
        return out
