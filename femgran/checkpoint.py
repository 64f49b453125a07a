"""Checkpoints of a boundary-value run: everything needed to continue it, in plain files.

A checkpoint is a pair in ``<run folder>/checkpoints/``: ``step_NNNNNN.npz`` (numpy arrays: the
displacements ``u``, the committed stress, every key of the material state as ``state__<key>``, the
committed tangent, as its 36 independent entries when it has both minor symmetries exactly, and the
last increment the predictor extrapolates) and ``step_NNNNNN.json`` (the load
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

from material.base import BackStressTangent, CoupledTangent
from material.table import jsonable

__all__ = ["Checkpointer", "latest", "load", "restore", "committed_tangent", "identity_changes", "FORMAT"]

FORMAT = "femgran-checkpoint/1"


_PAIRS = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
_I = np.array([p[0] for p in _PAIRS])
_J = np.array([p[1] for p in _PAIRS])


def _pack_tangent(T) -> dict[str, np.ndarray]:
    """The committed tangent in as few numbers as keep it exactly: the 36 independent entries when it has
    both minor symmetries to the bit (the CPA kernel's does), otherwise all 81; a gradient law's
    :class:`material.base.CoupledTangent` adds its other fields as ``coupled__<field>``, a
    :class:`material.base.BackStressTangent` as ``backstress__<field>``."""
    for kind, prefix in ((CoupledTangent, "coupled__"), (BackStressTangent, "backstress__")):
        if isinstance(T, kind):
            out = {f"{prefix}{k}": np.asarray(v) for k, v in T._asdict().items() if k != "dstress_dstrain"}
            return {**out, **_pack_tangent(T.dstress_dstrain)}
    T = np.asarray(T)
    if np.array_equal(T, T.swapaxes(1, 2)) and np.array_equal(T, T.swapaxes(3, 4)):
        return {"tangent36": np.ascontiguousarray(T[:, _I[:, None], _J[:, None], _I[None, :], _J[None, :]])}
    return {"tangent": T}


def committed_tangent(arrays: dict):
    """The committed tangent that a checkpoint's arrays (:func:`load`) hold, or None."""
    T = _unpack_stress_strain(arrays)
    if T is None:
        return T
    for kind, prefix in ((CoupledTangent, "coupled__"), (BackStressTangent, "backstress__")):
        fields = {k[len(prefix):]: arrays[k].copy() for k in arrays if k.startswith(prefix)}
        if fields:
            return kind(dstress_dstrain=T, **fields)
    return T


def _unpack_stress_strain(arrays: dict) -> np.ndarray | None:
    if "tangent" in arrays:
        return arrays["tangent"].copy()
    if "tangent36" in arrays:
        t36 = arrays["tangent36"]
        T = np.empty((t36.shape[0], 3, 3, 3, 3))
        for a, (i, j) in enumerate(_PAIRS):
            for b, (k, l) in enumerate(_PAIRS):
                v = t36[:, a, b]
                T[:, i, j, k, l] = T[:, j, i, k, l] = T[:, i, j, l, k] = T[:, j, i, l, k] = v
        return T
    return None


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
    """The keys (dotted) whose values differ between two parameter records. A key that only one record has,
    with the value None in it, is no change: an option a later version added at its default, which is the
    earlier behaviour (e.g. ``material.options.relaxation_time`` of the CPA law), so its checkpoints resume."""
    changed = []
    for key in sorted(set(saved) | set(now)):
        a, b = saved.get(key, "<absent>"), now.get(key, "<absent>")
        if isinstance(a, dict) and isinstance(b, dict):
            changed += identity_changes(a, b, f"{prefix}{key}.")
        elif a != b and not (key not in saved and b is None or key not in now and a is None):
            changed.append(f"{prefix}{key}: {a!r} -> {b!r}")
    return changed


def _unknowns(solver, u: np.ndarray, what: str) -> np.ndarray:
    """A copy of the checkpoint's unknown vector ``what`` for the solver's discretisation, which may adapt
    an earlier layout of its fields (``adapt_unknowns``: the back stress's six fields in plane strain);
    a vector of another length raises ``ValueError`` naming both."""
    disc = solver.disc
    adapt = getattr(disc, "adapt_unknowns", None)
    if adapt is not None:
        return np.array(adapt(u, f"checkpoint {what}"), copy=True)
    if np.shape(u) != (disc.ndofs,):
        raise ValueError(f"checkpoint {what}: {np.shape(u)[0]} unknowns, where this run's mesh and fields have "
                         f"{disc.ndofs}: the checkpoint belongs to another run")
    return np.array(u, copy=True)


def restore(solver, arrays: dict, info: dict, scale: float = 1.0) -> dict:
    """Put the solver where the checkpoint was (its stage set already, :meth:`NewtonSolver.set_stage`); returns
    the run state the solver's ``run(resume=...)`` takes."""
    pts = solver.points
    solver.u = _unknowns(solver, arrays["u"], "u")
    if "u_start" in arrays:
        solver.u_start = _unknowns(solver, arrays["u_start"], "u_start")
    solver.t = float(info["t"]) * scale  # scale: old end / new end of an extended loading stage
    pts.stress = arrays["stress"].copy()
    pts.state = {k[len("state__"):]: arrays[k].copy() for k in arrays if k.startswith("state__")}
    pts.revert()
    solver._committed_tangent = committed_tangent(arrays)
    solver._last_increment = None
    if "last_du" in arrays:  # (du, dt) of the last step, and its dc under path control
        last_du = _unknowns(solver, arrays["last_du"], "last_du")
        solver._last_increment = (last_du, float(info["last_dt"]) * scale) + \
            ((float(info["last_dc"]),) if info.get("last_dc") is not None else ())
    return {"dt": float(info["dt"]) * scale, "n_step": int(info["n_step"]), "history": info["history"],
            "residual_log": info["residual_log"], "easy_streak": int(info.get("easy_streak", 0))}


class Checkpointer:
    """Writes the checkpoints of one run (module docstring) every ``every`` converged steps (0: only when
    :meth:`write` is called, at the end or a stop), keeping the last ``keep``.

    The run pays only for a copy of its state: the files are written by a background thread while the next
    steps run (one checkpoint at a time, in order; :meth:`wait` returns when the last one is on disk, and
    :meth:`write` waits for the one before). Measured on the 128,000-point specimen (``python
    benchmarks/checkpoint.py --resolution 20``, 54,243 DOFs): one Newton iteration 3.7 s; the copy the run
    waits for 0.22 s (0.06 of an iteration); the files, 104 MiB, 0.31 s in the background (0.08). Written
    in the foreground the files took 0.35-0.45 s, 0.10-0.12 of an iteration.
    """

    def __init__(self, run_folder, identity: dict, every: int = 0, keep: int = 2):
        from concurrent.futures import ThreadPoolExecutor

        self.folder = Path(run_folder) / "checkpoints"
        self.identity = jsonable(identity)
        self.every = int(every)
        self.keep = max(int(keep), 1)
        self.last_step = None
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="femgran-checkpoint")
        self._pending = None

    def due(self, n_step: int) -> bool:
        return self.every > 0 and n_step % self.every == 0

    def write(self, solver, run_state: dict, writer=None, data: dict | None = None) -> Path:
        """A checkpoint of the solver's committed state after ``run_state["n_step"]`` converged steps (the
        arrays are copied now; the files follow in the background, see the class docstring), with the
        case's arrays ``data`` (:attr:`femgran.cases.base.Problem.persist`) as ``data__<key>``."""
        from material.version import __version__

        self.wait()
        n = int(run_state["n_step"])
        self.folder.mkdir(parents=True, exist_ok=True)
        pts = solver.points
        arrays = {"u": solver.u, "u_start": solver.u_start, "stress": pts.stress,
                  **{f"state__{k}": np.asarray(v) for k, v in pts.state.items()}}
        if solver._committed_tangent is not None:
            arrays.update(_pack_tangent(solver._committed_tangent))
        arrays.update({f"data__{k}": np.asarray(v) for k, v in (data or {}).items()})
        last = solver._last_increment
        if last is not None:
            arrays["last_du"] = last[0]
        arrays = {k: np.array(v, copy=True) for k, v in arrays.items()}  # the run goes on changing its own
        info = {"format": FORMAT, "femgran_version": __version__, "t": solver.t, "dt": run_state["dt"], "n_step": n,
                "easy_streak": int(run_state.get("easy_streak", 0)),
                "stage": int(getattr(solver, "stage", 0)),
                "last_dt": None if last is None else float(last[1]),
                "last_dc": None if last is None or len(last) < 3 else float(last[2]),
                "history": run_state["history"].rows(),
                "residual_log": [list(map(float, r)) for r in run_state["residual_log"]],
                "writer": None if writer is None else writer.state(),
                "newton_log_rows": solver.log.rows_written if hasattr(solver.log, "rows_written") else None,
                "identity": self.identity}
        text = json.dumps(jsonable(info)) + "\n"
        self.last_step = n
        self._pending = self._pool.submit(self._write_files, n, arrays, text)
        return _paths(self.folder, n)[1]

    def _write_files(self, n: int, arrays: dict, text: str) -> None:
        npz, js = _paths(self.folder, n)
        tmp_npz = npz.with_name(".tmp_" + npz.name)
        with open(tmp_npz, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp_npz, npz)
        tmp_js = js.with_name(".tmp_" + js.name)
        tmp_js.write_text(text)
        os.replace(tmp_js, js)  # the checkpoint exists from here on
        for old in sorted(self.folder.glob("step_*.json"))[:-self.keep]:
            old.with_suffix(".npz").unlink(missing_ok=True)
            old.unlink(missing_ok=True)

    def wait(self) -> None:
        """Return when the checkpoint being written is on disk (an error in writing it is raised here)."""
        if self._pending is not None:
            pending, self._pending = self._pending, None
            pending.result()

    def close(self) -> None:
        self.wait()
        self._pool.shutdown(wait=True)
