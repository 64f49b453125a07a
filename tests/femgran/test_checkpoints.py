"""Checkpoints, resume and interruption (femgran.checkpoint, femgran.cases.run): a run that stops goes on."""

import json
import os
import signal

import numpy as np
import pytest

import femgran.solver as solver_module
from femgran.cases import Footing, Output, run
from femgran.checkpoint import latest, load
from material.table import read_table

CASE = Footing(resolution=1, steps=6, settlement_m=0.01)
SAND = {"preset": "ottawa_c109", "stabilisation": 0.1}


def _interrupt_at(monkeypatch, step: int):
    """Send this process SIGINT while the history row of converged step ``step`` is made (mid-run)."""
    row = solver_module.NewtonSolver._row

    def interrupting(self, n_step, *a, **k):
        if n_step == step:
            os.kill(os.getpid(), signal.SIGINT)
        return row(self, n_step, *a, **k)

    monkeypatch.setattr(solver_module.NewtonSolver, "_row", interrupting)


def _numbers(folder):
    t = read_table(folder / "history.csv")
    return {k: t[k] for k in t.columns if k != "wall_time_s"}


def test_an_interrupted_run_resumes_to_the_bit(tmp_path, monkeypatch):
    full = run(CASE, SAND, output=Output(tmp_path / "full", plots=False))
    assert full.completed
    _interrupt_at(monkeypatch, 3)
    with pytest.raises(KeyboardInterrupt, match="interrupted by SIGINT.*femgran run --resume"):
        run(CASE, SAND, output=Output(tmp_path / "cut", plots=False))
    status = json.loads((tmp_path / "cut" / "status.json").read_text())
    assert status["interrupted"] is True and status["completed"] is False
    assert load(latest(tmp_path / "cut"))[1]["n_step"] == 3
    monkeypatch.undo()
    resumed = run(CASE, SAND, output=Output(tmp_path / "cut", plots=False), resume=True)
    assert resumed.completed
    np.testing.assert_array_equal(resumed.u, full.u)
    np.testing.assert_array_equal(resumed.stress, full.stress)
    for key in full.state:
        np.testing.assert_array_equal(resumed.state[key], full.state[key])
    a, b = _numbers(tmp_path / "full"), _numbers(tmp_path / "cut")
    assert a.keys() == b.keys()
    for key in a:  # history.csv continues without duplicates or gaps
        np.testing.assert_array_equal(b[key], a[key])
    assert [f.name for _, f in _pvd(tmp_path / "cut")] == [f.name for _, f in _pvd(tmp_path / "full")]
    assert len(read_table(tmp_path / "cut" / "newton_log.csv")) == len(read_table(tmp_path / "full" / "newton_log.csv"))


def _pvd(folder):
    from femgran.output import read_pvd

    return read_pvd(folder / "footing.pvd")


def test_checkpoints_every_n_steps_keep_the_last_k_and_refuse_changed_inputs(tmp_path):
    out = Output(tmp_path / "r", plots=False, checkpoint_every=2, keep_checkpoints=2)
    sol = run(CASE, SAND, output=out)
    names = sorted(p.name for p in (tmp_path / "r" / "checkpoints").iterdir())
    n = len(sol.history) - 1
    assert names == [f"step_{k:06d}.{ext}" for k in (n - 2 if n % 2 == 0 else n - n % 2, n) for ext in ("json", "npz")]
    assert not list((tmp_path / "r" / "checkpoints").glob(".tmp_*"))  # written under temporary names, renamed
    with pytest.raises(ValueError, match=r"differ from those of the checkpoint: .*surcharge_kPa: 0.0 -> 5.0"):
        run(Footing(resolution=1, steps=6, settlement_m=0.01, surcharge_kPa=5.0), SAND, output=out, resume=True)
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        run(CASE, SAND, output=Output(tmp_path / "empty"), resume=True)


def test_the_command_line_interrupts_with_a_message_and_resumes(tmp_path, monkeypatch, capsys):
    from femgran.cli import main

    out = tmp_path / "ft"
    argv = ["footing", "--resolution", "1", "--steps", "6", "--settlement", "0.01", "--stabilisation", "0.1",
            "--no-progress", "--out", str(out)]
    _interrupt_at(monkeypatch, 2)
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "interrupted by SIGINT" in err and "Traceback" not in err and f"femgran run --resume {out}" in err
    monkeypatch.undo()
    assert main(["run", "--resume", str(out), "--no-progress"]) == 0
    assert json.loads((out / "status.json").read_text())["completed"] is True
    assert len(read_table(out / "history.csv")) == 7


def test_replay_reruns_the_step_at_which_a_run_stopped(tmp_path, capsys):
    from femgran.cli import main

    out = tmp_path / "stopped"
    # four Newton iterations and no cut-back: the stiff sand's plastic first steps cannot converge
    argv = ["footing", "--resolution", "1", "--steps", "6", "--settlement", "0.01", "--set", "E=60000",
            "--max-iter", "4", "--max-cuts", "0", "--no-progress", "--out", str(out)]
    assert main(argv) == 1
    stopped = json.loads((out / "status.json").read_text())
    assert stopped["completed"] is False
    capsys.readouterr()
    assert main(["replay", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"replay of {out} from its checkpoint after step" in text and "residuals" in text
    replayed = json.loads((out / "replay" / "status.json").read_text())
    assert replayed["reason"] == stopped["reason"]  # the same step fails the same way, deterministically
