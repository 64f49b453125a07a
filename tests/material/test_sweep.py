"""The sweep engine (material.sweep): Dask against serial, resume after a kill, failures recorded."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from material.results import read_csv
from material.sweep import MARKER, Run, grid, key_of, read_summary, sweep


def _element_runs(steps=40, bad=False):
    runs = [Run(key_of(v), "material.sweep:element", {"test": "triaxial", "steps": steps, **v}, v)
            for v in grid(p0_kPa=[50.0, 100.0], alpha_deg=[0.0, 90.0])]
    if bad:  # a run that raises: p0 must be positive
        runs.insert(1, Run("bad_p0", "material.sweep:element", {"test": "triaxial", "p0_kPa": -1.0}, {"p0_kPa": -1.0}))
    return runs


def test_a_local_cluster_of_two_workers_computes_what_serial_runs_compute(tmp_path):
    runs = _element_runs(bad=True)
    here = sweep(runs, tmp_path / "serial", scheduler="serial", progress=False)
    there = sweep(runs, tmp_path / "dask", workers=2, progress=False)
    assert there.ran == 5 and there.skipped == 0
    for run in runs:
        if run.key == "bad_p0":
            continue
        a = read_csv(tmp_path / "serial" / run.key / "triaxial.csv")
        b = read_csv(tmp_path / "dask" / run.key / "triaxial.csv")
        assert a.columns == b.columns and len(a) == 41
        for c in a.columns:
            assert np.allclose(a[c], b[c], rtol=0.0, atol=1e-12 * max(1.0, np.nanmax(np.abs(a[c]))), equal_nan=True)
    # the run that raises is reported with its message; the other four complete
    for result in (here, there):
        assert result.failed == 1 and sum(r["status"] == "completed" for r in result.records) == 4
        assert result["bad_p0"]["message"].startswith("ValueError: p0_kPa = -1")
    summary = read_summary(tmp_path / "dask")
    assert list(summary["completed"]) == [1, 0, 1, 1, 1]
    assert summary.metadata["status"][1] == "failed"
    assert summary["max_q_kPa"][0] == pytest.approx(here.records[0]["summary"]["max_q_kPa"], rel=1e-12)
    assert "p0_kPa = -1" in (tmp_path / "dask" / "bad_p0" / "error.txt").read_text()
    assert json.loads((tmp_path / "dask" / "sweep.json").read_text())["runs"][1]["status"] == "failed"


_STUDY = """
import sys
from material.sweep import Run, sweep

def main():
    runs = [Run(f"run_{i}", "material.sweep:element",
                {"test": "triaxial", "steps": 1500, "p0_kPa": 50.0 + 10 * i}, {"i": i}) for i in range(8)]
    sweep(runs, sys.argv[1], workers=2, progress=False)

if __name__ == "__main__":
    main()
"""


def _complete(folder):
    return sorted(p.parent.name for p in folder.glob(f"*/{MARKER}")
                  if json.loads(p.read_text())["status"] == "completed")


def test_a_study_killed_halfway_completes_only_its_missing_runs(tmp_path):
    """The study runs on a LocalCluster of two workers in another process; it is killed (with its workers)
    once three runs are complete; the same study again runs only the others."""
    script = tmp_path / "study.py"
    script.write_text(textwrap.dedent(_STUDY))
    out = tmp_path / "study"
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, str(script), str(out)], env=env, start_new_session=True)
    try:
        deadline = time.time() + 240
        while len(_complete(out)) < 3 and proc.poll() is None and time.time() < deadline:
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGKILL)  # as a power cut would: no clean-up
    finally:
        proc.wait()
    before = _complete(out)
    assert 3 <= len(before) < 8, f"the study was not killed halfway: {before}"
    result = sweep([Run(f"run_{i}", "material.sweep:element",
                        {"test": "triaxial", "steps": 1500, "p0_kPa": 50.0 + 10 * i}, {"i": i}) for i in range(8)],
                   out, scheduler="serial", progress=False)
    assert result.skipped == len(before) and result.ran == 8 - len(before) and result.completed
    assert _complete(out) == [f"run_{i}" for i in range(8)]
    # a run whose arguments changed is run again, the others are not
    again = sweep([Run(f"run_{i}", "material.sweep:element",
                       {"test": "triaxial", "steps": 1500 if i else 20, "p0_kPa": 50.0 + 10 * i}, {"i": i})
                   for i in range(8)], out, scheduler="serial", progress=False)
    assert again.ran == 1 and again.skipped == 7 and len(read_csv(out / "run_0" / "triaxial.csv")) == 21


@pytest.mark.parametrize("make, match", [
    (lambda: Run("a/b", "material.sweep:element"), "run key 'a/b'"),
    (lambda: Run("a", "material.sweep"), "target 'material.sweep'"),
    (lambda: grid(alpha_deg=[]), "grid axis 'alpha_deg' is empty"),
    (lambda: grid(alpha_deg=30), "grid axis 'alpha_deg' = 30"),
    (lambda: sweep([Run("a", "m:f"), Run("a", "m:f")], "unused", progress=False), r"repeated: \['a'\]"),
    (lambda: sweep([Run("a", "m:f")], "unused", workers=0, progress=False), "workers = 0"),
])
def test_bad_studies_are_named(make, match, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=match):
        make()


def test_an_unknown_target_is_a_failed_run_not_a_crash(tmp_path):
    result = sweep([Run("x", "material.nothing_here:f"), Run("y", "material.sweep:element", {"test": "nope"})],
                   tmp_path, scheduler="serial", progress=False)
    assert [r["status"] for r in result.records] == ["failed", "failed"]
    assert "No module named 'material.nothing_here'" in result["x"]["message"]
    assert "element test = 'nope': allowed" in result["y"]["message"]


def test_a_study_runs_on_an_existing_dask_cluster(tmp_path, monkeypatch, capsys):
    """``scheduler=ADDRESS``: the runs go to a cluster started elsewhere (here, in this test). Where they go is
    printed without a progress bar too (a batch job's log)."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        result = sweep(_element_runs(steps=10)[:2], tmp_path, scheduler=cluster.scheduler_address, progress=False)
        assert f"2 run(s) to do (0 already complete) on 1 worker(s) at {cluster.scheduler_address}" in \
            capsys.readouterr().out
    assert result.ran == 2 and result.completed
    monkeypatch.setattr("material.sweep.CONNECT_TIMEOUT_S", 2)
    with pytest.raises(ValueError, match="no Dask scheduler answers there"):
        sweep(_element_runs(steps=10)[2:], tmp_path / "x", scheduler="tcp://127.0.0.1:9", progress=False)


_PROBE = '''
import os

import numba
from numba import njit


def report(out):
    """The worker's numba configuration, and a function compiled after its threads are running."""
    numba.get_num_threads()  # launches the threading layer

    @njit
    def plus_one(x):
        return x + 1.0

    return {"env": os.environ.get("NUMBA_NUM_THREADS"), "config": numba.config.NUMBA_NUM_THREADS,
            "threads": numba.get_num_threads(), "compiled": plus_one(1.0)}
'''


_PROBE_STUDY = """
import json
import sys

import numba  # noqa: F401 (the main module imports numba, as the femgran command does)

from material.sweep import Run, sweep

if __name__ == "__main__":
    result = sweep([Run(f"r{i}", "numba_probe:report") for i in range(2)], sys.argv[1], workers=2, progress=False)
    import os
    print(json.dumps([result[f"r{i}"].get("summary") for i in range(2)] + [os.environ.get("NUMBA_NUM_THREADS")]))
"""


def test_local_workers_start_with_one_numba_thread_and_compile(tmp_path):
    """A spawned worker imports the study's main module, and with it numba, before the Nanny's environment
    reaches it: the environment is set before the workers are spawned, so that numba launches one thread
    per worker and a kernel compiled in a worker (a stale cache) does not meet "Cannot set
    NUMBA_NUM_THREADS ... once the threads have been launched"; the study's process gets its own environment
    back (its numba would meet the same error)."""
    (tmp_path / "numba_probe.py").write_text(_PROBE)
    (tmp_path / "study.py").write_text(_PROBE_STUDY)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    env.pop("NUMBA_NUM_THREADS", None)
    out = subprocess.run([sys.executable, str(tmp_path / "study.py"), str(tmp_path / "out")], env=env,
                         capture_output=True, text=True, timeout=240)
    assert out.returncode == 0, out.stderr[-2000:]
    summaries = json.loads(out.stdout.strip().splitlines()[-1])
    # ... and the study's own environment is as it was
    assert summaries == [{"env": "1", "config": 1, "threads": 1, "compiled": 2.0}] * 2 + [None]
