"""Checkpoints of a boundary-value run: everything needed to continue it, in plain files.

A checkpoint is a pair in ``<run folder>/checkpoints/``: ``step_NNNNNN.npz`` (numpy arrays: the
displacements ``u``, the committed stress, every key of the material state as ``state__<key>``, the
committed tangent and the last increment the predictor extrapolates) and ``step_NNNNNN.json`` (the load
factor and step size, the step count, the history rows so far, the Newton residuals, the state of the
field series and of the Newton log, and the identity of the inputs: the run's parameter record and the
package version). No pickle: ``np.load(..., allow_pickle=False)`` and ``json`` read them.

Both files are written under temporary names and renamed, the ``.json`` last, so a kill during the write
leaves the previous checkpoint whole; a checkpoint counts only when its ``.json`` exists. The last
``keep`` checkpoints are kept.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from material.table import jsonable

__all__ = ["Checkpointer", "latest", "load", "restore", "identity_changes", "FORMAT"]

FORMAT = "femgran-checkpoint/1"


def _paths(folder: Path, n_step: int) -> tuple[Path, Path]:
    return folder / f"step_{n_step:06d}.npz", folder / f"step_{n_step:06d}.json"


def latest(run_folder) -> Path | None:
    """The ``.json`` of the newest complete checkpoint in a run folder (None if there is none)."""
    found = sorted((Path(run_folder) / "checkpoints").glob("step_*.json"))
    return found[-1] if found else None


_NEEDED = ("u", "stress")


def load(json_path) -> tuple[dict, dict]:
    """(arrays, info) of a checkpoint; a truncated or corrupted one raises ``ValueError`` naming the file."""
    import zipfile

    json_path = Path(json_path)
    npz = json_path.with_suffix(".npz")
    try:
        info = json.loads(json_path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"checkpoint {json_path}: unreadable ({exc}); remove it to resume from the one before") from None
    if info.get("format") != FORMAT:
        raise ValueError(f"checkpoint {json_path}: not a checkpoint of this format (format = {info.get('format')!r}, "
                         f"expected {FORMAT!r})")
    try:
        with np.load(npz, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"checkpoint {npz}: truncated or corrupted ({type(exc).__name__}: {exc}); remove it and its "
                         ".json to resume from the one before") from None
    missing = [k for k in _NEEDED if k not in arrays]
    if missing:
        raise ValueError(f"checkpoint {npz}: arrays {missing} missing (a truncated or foreign file)")
    return arrays, info


def identity_changes(saved: dict, now: dict, prefix: str = "") -> list[str]:
    """The keys (dotted) whose values differ between two parameter records."""
    changed = []
    for key in sorted(set(saved) | set(now)):
        a, b = saved.get(key, "<absent>"), now.get(key, "<absent>")
        if isinstance(a, dict) and isinstance(b, dict):
            changed += identity_changes(a, b, f"{prefix}{key}.")
        elif a != b:
            changed.append(f"{prefix}{key}: {a!r} -> {b!r}")
    return changed


def restore(solver, arrays: dict, info: dict) -> dict:
    """Put the solver where the checkpoint was (its stage set already, :meth:`NewtonSolver.set_stage`); returns
    the run state the solver's ``run(resume=...)`` takes."""
    pts = solver.points
    solver.u = arrays["u"].copy()
    if "u_start" in arrays:
        solver.u_start = arrays["u_start"].copy()
    solver.t = float(info["t"])
    pts.stress = arrays["stress"].copy()
    pts.state = {k[len("state__"):]: arrays[k].copy() for k in arrays if k.startswith("state__")}
    pts.revert()
    solver._committed_tangent = arrays["tangent"].copy() if "tangent" in arrays else None
    solver._last_increment = (arrays["last_du"].copy(), float(info["last_dt"])) if "last_du" in arrays else None
    return {"dt": float(info["dt"]), "n_step": int(info["n_step"]), "history": info["history"],
            "residual_log": info["residual_log"]}


class Checkpointer:
    """Writes the checkpoints of one run (module docstring) every ``every`` converged steps (0: only when
    :meth:`write` is called, at the end or a stop), keeping the last ``keep``."""

    def __init__(self, run_folder, identity: dict, every: int = 0, keep: int = 2):
        self.folder = Path(run_folder) / "checkpoints"
        self.identity = jsonable(identity)
        self.every = int(every)
        self.keep = max(int(keep), 1)
        self.last_step = None

    def due(self, n_step: int) -> bool:
        return self.every > 0 and n_step % self.every == 0

    def write(self, solver, run_state: dict, writer=None) -> Path:
        """A checkpoint of the solver's committed state after ``run_state["n_step"]`` converged steps."""
        from material.version import __version__

        n = int(run_state["n_step"])
        self.folder.mkdir(parents=True, exist_ok=True)
        npz, js = _paths(self.folder, n)
        pts = solver.points
        arrays = {"u": solver.u, "u_start": solver.u_start, "stress": pts.stress,
                  **{f"state__{k}": np.asarray(v) for k, v in pts.state.items()}}
        if solver._committed_tangent is not None:
            arrays["tangent"] = solver._committed_tangent
        last = solver._last_increment
        if last is not None:
            arrays["last_du"] = last[0]
        info = {"format": FORMAT, "femgran_version": __version__, "t": solver.t, "dt": run_state["dt"], "n_step": n,
                "stage": int(getattr(solver, "stage", 0)),
                "last_dt": None if last is None else float(last[1]),
                "history": run_state["history"].rows(),
                "residual_log": [list(map(float, r)) for r in run_state["residual_log"]],
                "writer": None if writer is None else writer.state(),
                "newton_log_rows": solver.log.rows_written if hasattr(solver.log, "rows_written") else None,
                "identity": self.identity}
        tmp_npz = npz.with_name(".tmp_" + npz.name)
        with open(tmp_npz, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp_npz, npz)
        tmp_js = js.with_name(".tmp_" + js.name)
        tmp_js.write_text(json.dumps(jsonable(info)) + "\n")
        os.replace(tmp_js, js)  # the checkpoint exists from here on
        self.last_step = n
        for old in sorted(self.folder.glob("step_*.json"))[:-self.keep]:
            old.with_suffix(".npz").unlink(missing_ok=True)
            old.unlink(missing_ok=True)
        return js
