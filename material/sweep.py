"""One engine for every study: many runs over a grid or a list of parameter sets, on dask.distributed.

A study is a list of :class:`Run`: a key (the run's folder under the study's ``out``), a target (a
function named ``"package.module:function"``, imported where the run executes) and its JSON-able
keyword arguments. The target is called as ``target(out=FOLDER, **kwargs)``, writes what it computes
into ``FOLDER`` and returns a mapping of scalars for the summary. :func:`sweep` runs the list:

* **where**: by default on a ``LocalCluster`` of worker processes with one thread each (one numba
  thread, one BLAS thread), as many as the machine has cores; ``scheduler="tcp://host:8786"`` uses an
  existing Dask cluster instead, so a study that outgrows one machine runs unchanged on many (the
  workers need the package installed and see the same file system); ``scheduler="serial"`` runs in
  this process, one run after the other (what a single run, or a debugger, wants);
* **what is kept**: each run, when it ends, writes ``FOLDER/sweep_run.json`` (status, message, summary,
  wall time, its arguments); ``out/summary.csv`` (:class:`material.table.Table`, one row per run, in
  the order of the list) and ``out/sweep.json`` (every record, messages included) are rewritten as the
  runs finish, so an interrupted study leaves every finished run on disk and a summary of them;
* **failures**: a run that raises is recorded with its message (and ``FOLDER/error.txt``, the
  traceback) and the others go on; a worker that dies (a crash, memory) is the same;
* **resume**: running the same study again skips each run whose ``sweep_run.json`` says completed with
  the same target and arguments; failed, missing and changed runs are run again.

The study-level command is ``femgran sweep``; ``femgran element``, the case commands (``femgran
footing --alpha 0 30 60 90``), ``femgran dem sweep`` and ``femgran figures`` all run their studies here.
"""

from __future__ import annotations

import importlib
import itertools
import json
import os
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from material.table import Table, jsonable

__all__ = ["Run", "SweepResult", "grid", "key_of", "sweep", "MARKER", "WORKER_ENVIRONMENT"]

MARKER = "sweep_run.json"
#: How long a study waits for the scheduler at ``scheduler=ADDRESS`` to answer [s].
CONNECT_TIMEOUT_S = 20
#: Environment of the LocalCluster's worker processes: one numba and one BLAS thread per process, so
#: that N processes on N cores do not oversubscribe them (dask's own default sets the BLAS ones).
WORKER_ENVIRONMENT = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                      "MKL_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


@dataclass(frozen=True)
class Run:
    """One run of a study.

    Parameters
    ----------
    key : str
        The run's folder name under the study's output folder (letters, digits, ``_ - . =``).
    target : str
        ``"package.module:function"``; called as ``function(out=FOLDER, **kwargs)``, returns a mapping
        of scalars (or None).
    kwargs : mapping
        JSON-able keyword arguments (recorded next to the results, compared on resume).
    values : mapping
        The swept values of this run (columns of the summary); default: none.
    """

    key: str
    target: str
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    values: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        allowed = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.=+")
        if not self.key or self.key in (".", "..") or not set(self.key) <= allowed:
            raise ValueError(f"run key {self.key!r}: allowed a non-empty folder name of letters, digits and _-.=+")
        module, _, name = self.target.partition(":")
        if not module or not name:
            raise ValueError(f"run {self.key!r}: target {self.target!r}: allowed 'package.module:function'")
        object.__setattr__(self, "kwargs", jsonable(dict(self.kwargs)))
        object.__setattr__(self, "values", jsonable(dict(self.values)))
        try:
            json.dumps(self.kwargs, allow_nan=True)
        except TypeError as exc:  # pragma: no cover - jsonable turns unknowns into strings
            raise ValueError(f"run {self.key!r}: kwargs are not JSON-able: {exc}") from None


def grid(**axes) -> list[dict]:
    """The cartesian product of the axes, in order: ``grid(p0_kPa=[50, 100], alpha_deg=[0, 90])`` -> 4 dicts."""
    for name, values in axes.items():
        if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
            raise ValueError(f"grid axis {name!r} = {values!r}: allowed a list of values")
        if len(list(values)) == 0:
            raise ValueError(f"grid axis {name!r} is empty: allowed a list of one or more values")
    names = list(axes)
    return [dict(zip(names, combo)) for combo in itertools.product(*(list(axes[n]) for n in names))]


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v)).lower()
    if isinstance(v, (int, float, np.integer, np.floating)):
        return f"{float(v):g}"
    if isinstance(v, (list, tuple)):
        return "-".join(_fmt(x) for x in v)
    return "".join(c if c.isalnum() or c in "-." else "-" for c in str(v))


def key_of(values: Mapping, labels: Mapping[str, str] | None = None) -> str:
    """A folder name for swept values: ``{"alpha_deg": 30, "p0_kPa": 50}`` -> ``alpha_deg_30_p0_kPa_50``
    (``labels`` renames the fields, e.g. ``{"alpha_deg": "alpha"}``); ``run`` for no values."""
    labels = labels or {}
    return "_".join(f"{labels.get(k, k).replace('.', '-')}_{_fmt(v)}" for k, v in values.items()) or "run"


# ------------------------------------------------------------------------------------------ one run
def _write_json(path: Path, record: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(jsonable(record), indent=2) + "\n")
    os.replace(tmp, path)


def _fingerprint(run: Run) -> str:
    return json.dumps({"target": run.target, "kwargs": run.kwargs}, sort_keys=True)


def _record(run: Run, status: str, message: str = "", summary=None, wall: float = float("nan")) -> dict:
    from material.version import __version__

    return {"key": run.key, "target": run.target, "kwargs": run.kwargs, "values": run.values, "status": status,
            "message": message, "summary": jsonable(dict(summary or {})), "wall_time_s": round(wall, 3),
            "femgran_version": __version__}


def execute(run: Run, folder) -> dict:
    """Run one :class:`Run` into ``folder`` (here, in this process) and write its ``sweep_run.json``.

    An exception of the target is caught and recorded (status ``failed``, its message; the traceback
    in ``folder/error.txt``); the record is returned either way."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / MARKER).unlink(missing_ok=True)
    (folder / "error.txt").unlink(missing_ok=True)
    t0 = time.perf_counter()
    try:
        module, _, name = run.target.partition(":")
        fn = getattr(importlib.import_module(module), name)
        summary = fn(out=folder, **run.kwargs)
        if summary is not None and not isinstance(summary, Mapping):
            raise TypeError(f"{run.target} returned {type(summary).__name__}; a sweep target returns a mapping")
        completed = bool((summary or {}).get("completed", True))
        status = "completed" if completed else "stopped"
        message = str((summary or {}).get("stop_reason", "")) if not completed else ""
        record = _record(run, status, message, summary, time.perf_counter() - t0)
    except Exception as exc:  # recorded, not fatal: the other runs of the study go on
        (folder / "error.txt").write_text(traceback.format_exc())
        record = _record(run, "failed", f"{type(exc).__name__}: {exc}", None, time.perf_counter() - t0)
    _write_json(folder / MARKER, record)
    return record


def _done(run: Run, folder: Path) -> dict | None:
    """The record of a finished run of the same target and arguments in ``folder`` (None otherwise)."""
    path = folder / MARKER
    if not path.is_file():
        return None
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    same = json.dumps({"target": rec.get("target"), "kwargs": rec.get("kwargs")}, sort_keys=True) == _fingerprint(run)
    return rec if same and rec.get("status") in ("completed", "stopped") else None


# ------------------------------------------------------------------------------------------ the study
@dataclass
class SweepResult:
    """What :func:`sweep` did: one record per run (in the order of the list) and the counts.

    ``ran`` runs executed now, ``skipped`` found complete on disk, ``failed`` raised (or lost their
    worker), ``stopped`` ended early without an error (a case that did not reach its end)."""

    out: Path
    records: list[dict]
    ran: int
    skipped: int
    dashboard: str | None = None

    @property
    def failed(self) -> int:
        return sum(r["status"] == "failed" for r in self.records)

    @property
    def stopped(self) -> int:
        return sum(r["status"] == "stopped" for r in self.records)

    @property
    def completed(self) -> bool:
        return all(r["status"] == "completed" for r in self.records)

    def summary(self) -> Table:
        return read_summary(self.out)

    def __getitem__(self, key: str) -> dict:
        for r in self.records:
            if r["key"] == key:
                return r
        raise KeyError(f"no run {key!r} in this sweep; runs: {[r['key'] for r in self.records]}")


def _summary_table(records: list[dict], title: str) -> Table:
    rows = []
    for i, rec in enumerate(records):
        row = {"run": i}
        for k, v in {**rec.get("values", {}), **rec.get("summary", {})}.items():
            if isinstance(v, (bool, int, float)) and k != "run":
                row[k] = float(v)
        row["completed"] = float(rec["status"] == "completed")
        row["wall_time_s"] = float(rec.get("wall_time_s", np.nan))
        rows.append(row)
    table = Table(title=title, metadata={"runs": [r["key"] for r in records],
                                         "status": [r["status"] for r in records]})
    table.descriptions.update(run="index of the run in the study (sweep.json: its folder and message)",
                              completed="1 if the run reached its end, 0 if it stopped, failed or is pending",
                              wall_time_s="wall time of the run [s]")
    for row in rows:
        table.append(row)
    return table


def _write_summary(out: Path, runs: list[Run], records: dict[str, dict], title: str, counts: dict) -> None:
    ordered = [records.get(r.key) or _record(r, "pending") for r in runs]
    _summary_table(ordered, title).write_csv(out / "summary.csv")
    _write_json(out / "sweep.json", {"title": title, **counts, "runs": ordered})


def read_summary(out) -> Table:
    """The ``summary.csv`` of a study folder."""
    from material.table import read_table

    return read_table(Path(out) / "summary.csv")


def _n_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _client(scheduler: str | None, workers: int):
    """A dask Client on a new LocalCluster (``scheduler`` None) or on the cluster at ``scheduler``."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s"), None
        except OSError as exc:
            raise ValueError(f"scheduler = {scheduler!r}: no Dask scheduler answers there ({exc}); allowed: the "
                             "address a 'dask scheduler' printed, e.g. tcp://10.0.0.5:8786, or none") from None
    # the workers' environment is in place when they are spawned: a worker imports numba while it starts (the
    # parent's main module), before the Nanny's ``env`` reaches its os.environ; numba then launches its threads
    # with the machine's count and refuses to compile anything once the environment says otherwise ("Cannot
    # set NUMBA_NUM_THREADS ...": measured with a stale numba cache, e.g. the first study after an install).
    # This process's own environment is restored once they run (numba here keeps the configuration it has).
    saved = {key: os.environ.get(key) for key in WORKER_ENVIRONMENT}
    os.environ.update(WORKER_ENVIRONMENT)
    try:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR, env=dict(WORKER_ENVIRONMENT))  # ":0": any free port
    except RuntimeError as exc:
        raise RuntimeError(f"the local Dask cluster could not start its {workers} worker process(es) ({exc}). The "
                           "workers are spawned: a script that runs a study needs the `if __name__ == "
                           "\"__main__\":` guard (and cannot be read from stdin); or run it with "
                           "scheduler=\"serial\"") from None
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    return Client(cluster), cluster


def sweep(runs: Iterable[Run], out, *, scheduler: str | None = None, workers: int | None = None,
          progress: bool = True, title: str = "sweep", on_record=None) -> SweepResult:
    """Run ``runs`` into ``out/<key>`` (module docstring: where, what is kept, failures, resume).

    Parameters
    ----------
    runs : iterable of Run
        Keys must be unique.
    out : path
        The study's folder.
    scheduler : str, optional
        None: a new LocalCluster of ``workers`` processes (default: the machine's cores, at most one
        per run to do; a single run to do runs here). ``"serial"``: in this process. Otherwise the
        address of a running Dask scheduler.
    workers : int, optional
        Worker processes of the LocalCluster, >= 1.
    progress : bool
        A progress bar over the runs. The Dask cluster's address and dashboard are printed either way (a
        batch job's log, where the command line draws no bar, needs the dashboard's address too).
    on_record : callable, optional
        Called with each record as its run finishes (in this process), e.g. to print it.
    """
    runs = list(runs)
    keys = [r.key for r in runs]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"sweep: run keys must be unique; repeated: {dup}")
    if workers is not None and (not isinstance(workers, (int, np.integer)) or workers < 1):
        raise ValueError(f"workers = {workers!r}: allowed an integer >= 1")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    records: dict[str, dict] = {}
    todo = []
    for run in runs:
        rec = _done(run, out / run.key)
        if rec is None:
            todo.append(run)
        else:
            records[run.key] = rec
    skipped = len(records)
    counts = {"runs": len(runs), "skipped": skipped}
    _write_summary(out, runs, records, title, counts)
    from tqdm import tqdm

    bar = tqdm(total=len(runs), initial=skipped, desc=title, unit="run", disable=not progress)
    n_workers = workers or max(1, min(_n_cores(), len(todo)))
    serial = scheduler == "serial" or (scheduler is None and (n_workers == 1 or len(todo) <= 1))
    dashboard = None

    def finished(rec):
        records[rec["key"]] = rec
        _write_summary(out, runs, records, title, counts)
        bar.update(1)
        if on_record is not None:
            on_record(rec)

    try:
        if serial:
            for run in todo:
                finished(execute(run, out / run.key))
        elif todo:  # (tqdm.write prints above the bar, and without one: it is the class's, not the bar's)
            dashboard = _on_dask(todo, out, scheduler, n_workers, title, skipped, finished, bar.write)
    except KeyboardInterrupt:
        done = sum(r.key in records for r in runs)
        raise KeyboardInterrupt(f"{title}: interrupted with {done} of {len(runs)} runs complete in {out}; the same "
                                "study again runs only the others") from None
    finally:
        bar.close()
        counts.update(ran=sum(r.key in records for r in todo))
        _write_summary(out, runs, records, title, counts)
    ordered = [records[r.key] for r in runs]
    return SweepResult(out, ordered, ran=len(todo), skipped=skipped, dashboard=dashboard)


def _on_dask(todo: list[Run], out: Path, scheduler, n_workers: int, title: str, skipped: int, finished,
             say) -> str | None:
    """Run ``todo`` on a Dask cluster, ``finished(record)`` as each ends; returns the dashboard address."""
    from distributed import as_completed

    client, cluster = _client(scheduler, n_workers)
    try:
        dashboard = client.dashboard_link
        workers = len(client.scheduler_info().get("workers", {}))
        say(f"{title}: {len(todo)} run(s) to do ({skipped} already complete) on {workers} worker(s) at "
            f"{client.scheduler.address}" + (f"; dashboard {dashboard}" if dashboard else ""))
        futures = {client.submit(execute, run, str((out / run.key).resolve()), pure=False,
                                 key=f"{title}-{run.key}-{time.time_ns()}"): run for run in todo}
        for future in as_completed(futures):
            run = futures[future]
            try:
                rec = future.result()
            except Exception as exc:  # the worker died (a crash, memory) or could not unpickle the run
                rec = _record(run, "failed", f"{type(exc).__name__}: {exc} (the run's worker was lost)")
                if (out / run.key).is_dir():
                    _write_json(out / run.key / MARKER, rec)
            finished(rec)
        return dashboard
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# ------------------------------------------------------------------------------------------ targets
#: Element tests a sweep can run (:func:`element`): the driver function of each.
ELEMENT_TESTS = ("triaxial", "oedometer", "plane-strain", "true-triaxial", "direct-shear", "simple-shear",
                 "cyclic-simple-shear", "rotation", "path")


def element(out, test: str = "triaxial", material=None, **driver_kwargs) -> dict:
    """Sweep target: one element test of :mod:`material.driver` into ``out/<test>.csv``.

    ``material`` is what :func:`material.factory.make_material` takes as data (a preset name, a parameter
    file, or a ``[material]`` mapping such as ``{"preset": "ottawa_c109", "set": {"beta": 5}, "rule":
    "bazant-oh-33"}``; default: the test's preset). ``test = "path"`` replays ``path_file`` (CSV or TOML,
    ``substeps``). The other keywords go to the driver function (``p0_kPa``, ``alpha_deg``, ``steps``...).
    Returns the peak stress measure, the final volumetric measure, for the plane-strain test Rice's onset
    (``bifurcation_eps_a``, ``_q13_kPa``, ``_band_deg``; NaN where it stays elliptic) and where its path on a
    mirror-symmetric bedding shears (``shear_onset_eps_a``, NaN where it keeps its symmetry), and whether the
    test reached its end.
    """
    from material import driver

    if test not in ELEMENT_TESTS:
        raise ValueError(f"element test = {test!r}: allowed {list(ELEMENT_TESTS)}")
    stem = test.replace("-", "_")
    out = Path(out)
    log = out / f"{stem}.steps.csv"  # written step by step; removed once the table is saved
    if material is None:
        material = "ottawa_c109_induced" if test == "rotation" else "ottawa_c109"
    if test == "path":
        from material.factory import make_material

        kw = dict(driver_kwargs)
        source = kw.pop("path_file", None)
        if source is None:
            raise ValueError("element test 'path': give path_file (a CSV of lab data or a TOML path)")
        substeps = kw.pop("substeps", 1)
        path = (driver.LoadPath.from_toml(source) if str(source).lower().endswith(".toml")
                else driver.LoadPath.from_csv(source, substeps=substeps))
        res = driver.run_path(make_material(material), path, log=log, **kw)
        res.metadata.update(test="path", path_file=str(source))
    else:
        res = getattr(driver, stem)(material, log=log, **driver_kwargs)
    res.to_csv(out / f"{stem}.csv")
    log.unlink(missing_ok=True)
    summary: dict[str, Any] = {"rows": len(res)}
    for col in ("tau_kPa", "t_kPa", "q_kPa"):
        if col in res:
            summary[f"max_{col}"] = float(np.nanmax(res[col]))
            break
    for col in ("normal_displacement_m", "eps_v"):
        if col in res:
            summary[f"final_{col}"] = float(res[col][-1])
            break
    if "bifurcation" in res.metadata:  # the plane-strain test: Rice's onset (NaN where the path stays elliptic)
        onset = res.metadata["bifurcation"] or {}
        summary.update({f"bifurcation_{k}": float(onset.get(k, np.nan))
                        for k in ("eps_a", "q13_kPa", "band_deg", "rising_deg", "falling_deg")})
        branch = res.metadata.get("shear_onset") or {}  # where a mirror-symmetric path shears (NaN: it does not)
        summary["shear_onset_eps_a"] = float(branch.get("eps_a", np.nan))
    summary.update(completed=bool(res.completed), stop_reason=res.message or "")
    return summary
