"""Checkpoints, resume and interruption (femgran.checkpoint, femgran.cases.run): a run that stops goes on."""

import json
import os
import re
import shutil
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


def test_an_option_a_later_version_added_at_its_default_does_not_block_a_resume():
    """A checkpoint written before an option existed resumes when the option is at its default None (the
    earlier behaviour); any other value, or a change of an existing key, is refused."""
    from femgran.checkpoint import identity_changes

    old = {"material": {"options": {"stabilisation": 0.1}}, "steps": 40}
    assert identity_changes(old, {"material": {"options": {"stabilisation": 0.1, "relaxation_time": None}},
                                  "steps": 40}) == []
    assert identity_changes(old, {"material": {"options": {"stabilisation": 0.1, "relaxation_time": 0.025}},
                                  "steps": 40}) == ["material.options.relaxation_time: '<absent>' -> 0.025"]
    assert identity_changes({"steps": None}, {"steps": 40}) == ["steps: None -> 40"]


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


def test_a_case_file_s_checkpoint_settings_hold_unless_a_flag_is_given(tmp_path):
    """``femgran run FILE`` keeps the file's ``checkpoint_every`` / ``keep_checkpoints`` (the flags' defaults
    used to replace them by 0 and 2: no checkpoint along the run, while the copied case.toml said 1); a flag
    given on the command line still wins."""
    from femgran.cli import main

    def case(out, every=1, keep=3):
        path = tmp_path / f"{out}.toml"
        path.write_text(f"""[case]\nname = "footing"\nunit_weight = 0.0\nresolution = 1\nsteps = 4\n
settlement_m = 0.004\n[material]\nlaw = "von_mises"\nE_kPa = 30000.0\nnu = 0.3\nyield_stress_kPa = 173.2\n
[output]\nout = "{tmp_path / out}"\nplots = false\ncheckpoint_every = {every}\nkeep_checkpoints = {keep}\n""")
        return str(path)

    def kept(out):
        return sorted(int(re.search(r"(\d+)", p.stem).group(1)) for p in (tmp_path / out / "checkpoints").glob("*.json"))

    assert main(["run", case("a"), "--no-progress"]) == 0
    assert kept("a") == [2, 3, 4]  # every step, the last three kept
    assert main(["run", case("b"), "--no-progress", "--keep-checkpoints", "1"]) == 0
    assert kept("b") == [4]
    assert main(["run", case("c"), "--no-progress", "--checkpoint-every", "2", "--keep-checkpoints", "5"]) == 0
    assert kept("c") == [2, 4]


def test_the_ellipticity_command_counts_the_points_past_the_onset_at_each_checkpoint(tmp_path, capsys):
    """``femgran ellipticity RUN``: at the thesis sand's footing (resolution 1, step stabilisation 0.1) the
    law's own loading tangent has lost ellipticity at 2 of 630 points at the end where the committed
    (stabilised) tangent has not, and a strengthening on the plastic strain (H_g = 1000 m) takes that away;
    with associated flow the law keeps ellipticity, which a back stress keeps and a modulus on the plastic
    strain does not; the table is written next to the run; a modulus without a kind is refused."""
    from femgran.cli import main

    out = tmp_path / "ft"
    assert main(["footing", "--resolution", "1", "--steps", "4", "--settlement", "0.01", "--stabilisation", "0.1",
                 "--no-progress", "--out", str(out), "--checkpoint-every", "2", "--keep-checkpoints", "5"]) == 0
    assert main(["ellipticity", str(out), "--strengthening", "plastic_strain", "--modulus", "10", "1000"]) == 0
    t = read_table(out / "ellipticity.csv")
    assert list(t["step"]) == [2, 4] and list(t["points"]) == [630, 630]
    assert list(t["committed"]) == [0, 0] and list(t["law"]) == [0, 2]
    assert list(t["plastic_strain_1000"]) == [0, 0]
    # with associated flow (no stabilisation) the law keeps ellipticity; a modulus on the plastic strain does
    # not keep the rate problem symmetric and costs 2 points, a back stress keeps it
    assoc = tmp_path / "assoc"
    assert main(["footing", "--resolution", "1", "--steps", "4", "--settlement", "0.01", "--set", "eta_c_ratio=0",
                 "--no-progress", "--out", str(assoc), "--checkpoint-every", "2", "--keep-checkpoints", "5"]) == 0
    assert main(["ellipticity", str(assoc), "--strengthening", "plastic_strain", "--modulus", "1000"]) == 0
    t = read_table(assoc / "ellipticity.csv")
    assert list(t["law"]) == [0, 0] and list(t["plastic_strain_1000"]) == [0, 2]
    assert main(["ellipticity", str(assoc), "--strengthening", "back_stress", "--modulus", "1e3", "1e5"]) == 0
    t = read_table(assoc / "ellipticity.csv")
    assert list(t["back_stress_1000"]) == [0, 0] and list(t["back_stress_100000"]) == [0, 0]
    capsys.readouterr()
    assert main(["ellipticity", str(out), "--modulus", "10"]) == 2
    assert "give both (a kind and one or more moduli) or neither" in capsys.readouterr().err
    assert main(["ellipticity", str(tmp_path)]) == 2


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
    # the stiff sand's first step misses the tangent's prediction at dozens of points, not at a pair
    missed = re.search(r"(\d+) full Newton step\(s\) rejected, half of the missed stress at (\d+)-(\d+) point", text)
    assert missed and int(missed[1]) >= 1 and int(missed[2]) >= 10
    assert "a zero strain increment over 0.00390625 relaxation time(s) moves 0 of" in text  # the thesis's law
    assert "the rate problem of every one of the" in text or "the rate problem has no unique solution" in text
    assert "elliptic at every point (least indicator" in text or "has lost ellipticity (Rice's condition" in text
    replayed = json.loads((out / "replay" / "status.json").read_text())
    assert replayed["reason"] == stopped["reason"]  # the same step fails the same way, deterministically


def test_uniqueness_report_names_the_points_whose_rate_problem_has_several_solutions():
    """The sentence a stopped run and `femgran replay` carry: at the near-failure point of the material tests
    (three rate solutions) both stored points lose uniqueness, with the bound 0.082 of the minimal
    stabilisation; an in-situ state and a law without planes give nothing."""
    from pathlib import Path

    import material
    from femgran.diagnostics import uniqueness_report
    from material.cpa import CPAModel
    from material.parameters import parameters_from_dict

    d = dict(np.load(Path(__file__).parents[1] / "material" / "data" / "near_failure_point.npz"))
    model = CPAModel(parameters_from_dict(json.loads(str(d["params_json"]))), rule=str(d["rule"]), axes=d["axes"])
    state = {k[len("state__"):]: v for k, v in d.items() if k.startswith("state__")}
    note = uniqueness_report(model, d["stress"], state)
    assert "has no unique solution (by the sufficient condition) at 2 of 2 points" in note
    assert "mu = 0.082" in note and "this run's stabilisation: 0.0" in note
    sig = np.repeat(-100.0 * np.eye(3)[None], 3, axis=0)
    assert uniqueness_report(model, sig, model.initial_state(3, stress=sig)) == ""
    elastic = material.LinearElastic(1e4, 0.3)
    assert uniqueness_report(elastic, sig, elastic.initial_state(3)) == ""


def test_a_run_that_stops_says_where_the_law_lost_uniqueness(tmp_path, monkeypatch):
    """The stop message of a run (and status.json) ends with the probe of its last stalled line search and
    the uniqueness report of the last converged state when they have something to say (here stubbed: the
    real ones need a footing near failure, minutes of run; both are tested on their own)."""
    import femgran.diagnostics as diagnostics

    monkeypatch.setattr(diagnostics, "uniqueness_report", lambda law, stress, state: "REPORT")
    monkeypatch.setattr(diagnostics, "stall_report", lambda solver: "STALL")
    sol = run(Footing(resolution=1, steps=6, settlement_m=0.01), {"preset": "ottawa_c109", "set": {"E": 60000}},
              solver={"max_iter": 4, "max_cuts": 0}, output=Output(tmp_path / "r", plots=False))
    assert not sol.completed and sol.stop_reason.endswith("; STALL; REPORT")
    assert json.loads((tmp_path / "r" / "status.json").read_text())["reason"].endswith("; STALL; REPORT")


def test_a_stall_at_the_first_step_of_the_stiff_sand_is_the_non_associated_law_losing_uniqueness(tmp_path):
    """The stiff thesis sand (E = 60 MPa, c0 = 0) stops in its first footing step: the committed in-situ
    state has no loading plane, so the uniqueness report of the last converged state is empty, and the stall
    probe checks the iterate, where planes load within the step: there hundreds of points fail the
    sufficient condition for a unique rate problem (256 of 630 on this mesh). The same sand with associated
    flow on every plane (eta_c = 0) runs the same steps to the end (docs/cpa_law.md, section 4)."""
    case = Footing(resolution=1, steps=6, settlement_m=0.01)
    sand = {"preset": "ottawa_c109", "set": {"E": 60000, "c0": 0.0}}
    sol = run(case, sand, solver={"max_cuts": 2}, output=Output(tmp_path / "thesis", plots=False))
    assert not sol.completed and sol.stop_reason.startswith("stopped at t = 0: line search")
    note = sol.stop_reason.split("at the iterate (with the planes that load within the step) ")[1]
    lost, total = (int(x) for x in note.split("(by the sufficient condition) at ")[1].split(" points")[0].split(" of "))
    assert total == 630 and lost >= 100
    associated = {"preset": "ottawa_c109", "set": {"E": 60000, "c0": 0.0, "eta_c_ratio": 0.0}}
    assert run(case, associated, solver={"max_cuts": 2}, output=Output(tmp_path / "assoc", plots=False)).completed


def test_a_kill_during_a_checkpoint_write_leaves_the_previous_one_and_a_corrupted_one_is_named(tmp_path):
    out = Output(tmp_path / "r", plots=False, checkpoint_every=2, keep_checkpoints=3)
    run(CASE, SAND, output=out)
    folder = tmp_path / "r" / "checkpoints"
    newest = latest(tmp_path / "r")
    # a write killed before its .json was renamed into place: an .npz (and a temporary) without a .json
    (folder / "step_000099.npz").write_bytes(b"partial")
    (folder / ".tmp_step_000099.json").write_text("{")
    assert latest(tmp_path / "r") == newest
    resumed = run(CASE, SAND, output=out, resume=True)  # from the last complete checkpoint: nothing left to do
    assert resumed.completed
    newest.with_suffix(".npz").write_bytes(newest.with_suffix(".npz").read_bytes()[:100])  # truncated
    with pytest.raises(ValueError, match=rf"checkpoint {newest.with_suffix('.npz')}: truncated or corrupted"):
        run(CASE, SAND, output=out, resume=True)
    newest.write_text('{"format": ')
    with pytest.raises(ValueError, match=rf"checkpoint {newest}: unreadable"):
        run(CASE, SAND, output=out, resume=True)


KILLED_RUN = """
import pathlib, sys, time
from femgran import checkpoint
from femgran.cases import Footing, Triaxial, Output, run

write_files = checkpoint.Checkpointer._write_files


def write_then_hang(self, n, arrays, text):  # the run goes no further than one step past checkpoint 3
    write_files(self, n, arrays, text)
    if n == 3:
        pathlib.Path(sys.argv[2], "checkpoint_3_on_disk").touch()
        time.sleep(3600)


checkpoint.Checkpointer._write_files = write_then_hang
case = {"footing": Footing(resolution=1, steps=12, settlement_m=0.02),
        "triaxial": Triaxial(resolution=1, steps=12, axial_strain=0.02)}[sys.argv[1]]
run(case, {"preset": "ottawa_c109", "stabilisation": 0.1},
    output=Output(sys.argv[2], plots=False, checkpoint_every=1, keep_checkpoints=2))
"""


@pytest.mark.parametrize("name", ["footing", "triaxial"])
def test_a_run_killed_mid_run_resumes_to_the_uninterrupted_run(tmp_path, name):
    import subprocess
    import sys
    import time

    from femgran.cases import Footing, Triaxial

    case = {"footing": Footing(resolution=1, steps=12, settlement_m=0.02),
            "triaxial": Triaxial(resolution=1, steps=12, axial_strain=0.02)}[name]
    full = run(case, SAND, output=Output(tmp_path / "full", plots=False))
    script = tmp_path / "killed.py"
    script.write_text(KILLED_RUN)
    # the child holds after its third checkpoint (KILLED_RUN), so the kill lands mid-run however loaded the
    # machine is; the deadline only keeps a broken child from hanging the test
    child = subprocess.Popen([sys.executable, str(script), name, str(tmp_path / "killed")])
    deadline, marker = time.time() + 900, tmp_path / "killed" / "checkpoint_3_on_disk"
    while not marker.exists() and child.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    child.send_signal(signal.SIGKILL)  # no chance to clean up
    child.wait()
    assert marker.exists(), f"the child run did not reach its third checkpoint (exit code {child.returncode})"
    stopped_at = load(latest(tmp_path / "killed"))[1]["n_step"]
    assert stopped_at == 3 < len(full.history) - 1  # killed in mid-run
    resumed = run(case, SAND, output=Output(tmp_path / "killed", plots=False), resume=True)
    np.testing.assert_array_equal(resumed.u, full.u)
    np.testing.assert_array_equal(resumed.stress, full.stress)
    a, b = _numbers(tmp_path / "full"), _numbers(tmp_path / "killed")
    for key in a:
        np.testing.assert_array_equal(b[key], a[key])


def test_a_geostatic_stage_then_the_load_is_the_single_stage_footing():
    single = run(Footing(resolution=1, steps=6, settlement_m=0.01), SAND)
    staged = run(Footing(resolution=1, steps=6, settlement_m=0.01, staged=True), SAND)
    h = staged.history
    assert list(h["stage"]) == [0, 0] + [1] * 6
    np.testing.assert_allclose(h["time"][-2:], [1 + 5 / 6, 2.0], rtol=1e-14)
    last = h["stage"] == 1
    np.testing.assert_allclose(h["pressure_kPa"][last], single.history["pressure_kPa"][1:], rtol=1e-8)
    np.testing.assert_allclose(staged.u, single.u, rtol=0, atol=1e-8 * np.abs(single.u).max())
    assert staged.bearing_capacity_kPa == pytest.approx(single.bearing_capacity_kPa, rel=1e-8)


@pytest.mark.parametrize("interrupt_at", [6, 7])  # the last step of the surcharge stage, the first of the footing
def test_a_three_stage_run_resumes_across_a_stage_boundary(tmp_path, monkeypatch, interrupt_at):
    case = Footing(resolution=1, steps=6, settlement_m=0.01, surcharge_kPa=10.0, staged=True)
    full = run(case, SAND, output=Output(tmp_path / "full", plots=False))
    assert list(full.history["stage"]) == [0, 0] + [1] * 5 + [2] * 6
    assert full.history["pressure_kPa"][-1] > 10.0 and np.isnan(full.pressure_at_10pct_kPa)  # s < 0.1 B
    _interrupt_at(monkeypatch, interrupt_at)
    with pytest.raises(KeyboardInterrupt):
        run(case, SAND, output=Output(tmp_path / "cut", plots=False))
    monkeypatch.undo()
    assert load(latest(tmp_path / "cut"))[1]["stage"] == (1 if interrupt_at == 6 else 2)
    resumed = run(case, SAND, output=Output(tmp_path / "cut", plots=False), resume=True)
    np.testing.assert_array_equal(resumed.u, full.u)
    a, b = _numbers(tmp_path / "full"), _numbers(tmp_path / "cut")
    for key in a:
        np.testing.assert_array_equal(b[key], a[key])


def test_an_isotropic_consolidation_stage_leaves_the_cpa_law_as_it_finds_it():
    """An isotropic stress puts no shear on any plane: shearing after consolidating from 50 to 100 kPa is
    shearing from 100 kPa (to the solver's tolerance)."""
    from femgran.cases import Triaxial

    direct = run(Triaxial(platens="smooth", resolution=1, steps=8, axial_strain=0.02), "ottawa_c109")
    staged = run(Triaxial(platens="smooth", resolution=1, steps=8, axial_strain=0.02, consolidation_from_kPa=50.0),
                 "ottawa_c109")
    h = staged.history
    shearing = h["stage"] == 1
    assert list(h["stage"]).count(0) == 11 and shearing.sum() == 8
    np.testing.assert_allclose(h["eps_a"][shearing], direct.history["eps_a"][1:], rtol=1e-12)
    assert np.abs(h["q_kPa"][shearing] - direct.history["q_kPa"][1:]).max() < 1e-4 * direct.peak_q_kPa


def test_replay_of_a_step_whose_points_fail_reports_them(tmp_path):
    """A law given one local iteration and no continuation cannot take the footing's plastic steps: its
    points fail, the run stops, and the replay from the checkpoint finds the same points and their files."""
    from femgran.cases import footing
    from material import CPAModel
    from material.factory import plane_strain_axes

    brittle = CPAModel("ottawa_c109", axes=plane_strain_axes(0.0), maxit=1, max_halvings=0)
    stopped = footing(brittle, resolution=1, steps=4, settlement_m=0.02, out=tmp_path / "run", plots=False,
                      checkpoint_every=1, solver={"max_cuts": 1})
    assert not stopped.completed and "failed" in stopped.stop_reason
    replay = run(Footing(resolution=1, steps=4, settlement_m=0.02), brittle, solver={"max_cuts": 1},
                 output=Output(tmp_path / "replay", plots=False), resume=tmp_path / "run", max_steps=1)
    assert replay.stop_reason == stopped.stop_reason.replace(str(tmp_path / "run"), str(tmp_path / "replay"))
    log = read_table(tmp_path / "replay" / "newton_log.csv")
    assert log["failed_points"].max() > 0
    assert list((tmp_path / "replay" / "failed_points").glob("*.npz"))  # replay files of the failed points


def test_switching_gravity_on_elastically_is_the_k0_start_with_k0_from_poisson():
    """geostatic = "gravity": an elastic stage loads the layer by its weight (sigma_yy = -gamma |y|,
    sigma_xx = nu / (1 - nu) sigma_yy in this confined column), then the law starts from that stress; the
    footing on it is the footing on the K0 start with K0 = nu / (1 - nu)."""
    nu, gamma = 0.33, 18.0
    case = Footing(resolution=1, steps=6, settlement_m=0.01, staged=True, geostatic="gravity")
    first = run(case, SAND, max_steps=1)  # the gravity stage alone
    assert first.history["stage"][-1] == 0
    from material import LinearElastic

    y = case.build(LinearElastic(6000.0, nu)).disc.quadrature_points()[:, 1]
    sig = first.stress
    np.testing.assert_allclose(sig[:, 1, 1], -gamma * np.abs(y), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(sig[:, 0, 0], nu / (1 - nu) * sig[:, 1, 1], rtol=1e-6, atol=1e-6)
    gravity = run(case, SAND)
    k0 = run(Footing(resolution=1, steps=6, settlement_m=0.01, staged=True, K0=nu / (1 - nu)), SAND)
    np.testing.assert_allclose(gravity.history["pressure_kPa"][-6:], k0.history["pressure_kPa"][-6:], rtol=1e-9)
    np.testing.assert_allclose(gravity.stress, k0.stress, rtol=0, atol=1e-9 * np.abs(k0.stress).max())
    with pytest.raises(ValueError, match="geostatic = 'gravity' switches gravity on in a stage of its own"):
        Footing(geostatic="gravity")


@pytest.mark.parametrize("interrupt_at", [1, 2])  # the end of the elastic gravity stage, the first step after it
def test_a_run_with_an_elastic_stage_resumes_across_the_switch(tmp_path, monkeypatch, interrupt_at):
    case = Footing(resolution=1, steps=4, settlement_m=0.01, surcharge_kPa=10.0, staged=True, geostatic="gravity")
    full = run(case, SAND, output=Output(tmp_path / "full", plots=False))
    _interrupt_at(monkeypatch, interrupt_at)
    with pytest.raises(KeyboardInterrupt):
        run(case, SAND, output=Output(tmp_path / "cut", plots=False))
    monkeypatch.undo()
    resumed = run(case, SAND, output=Output(tmp_path / "cut", plots=False), resume=True)
    np.testing.assert_array_equal(resumed.u, full.u)
    np.testing.assert_array_equal(resumed.stress, full.stress)


def test_a_finished_footing_goes_on_to_a_larger_settlement(tmp_path):
    """The one change a resume accepts: the end of the loading (here the target settlement). The load
    factors already recorded are rescaled, so the history and the series go on monotonically, and the end
    point is the run that aimed there from the start."""
    from femgran.output import read_pvd

    out = Output(tmp_path / "r", plots=False)
    first = run(Footing(resolution=1, steps=6, settlement_m=0.01), SAND, output=out)
    shutil.copytree(tmp_path / "r", tmp_path / "s")
    longer = run(Footing(resolution=1, steps=6, settlement_m=0.02), SAND, output=out, resume=True)
    direct = run(Footing(resolution=1, steps=12, settlement_m=0.02), SAND)
    h = read_table(tmp_path / "r" / "history.csv")
    assert len(h) == len(longer.history) > len(first.history)
    assert np.all(np.diff(h["settlement_m"]) > 0) and np.all(np.diff(h["load_factor"]) > 0)
    np.testing.assert_allclose(h["load_factor"][len(first.history) - 1], 0.5, rtol=1e-12)
    assert np.all(np.diff([t for t, _ in read_pvd(tmp_path / "r" / "footing.pvd")]) > 0)
    assert longer.history["settlement_m"][-1] == pytest.approx(0.02)
    # the extended run's later steps are twice the direct run's, and the step stabilisation's overstress is
    # first order in the step: 0.5 % apart (51.85 against 51.58 kPa)
    assert longer.history["pressure_kPa"][-1] == pytest.approx(direct.history["pressure_kPa"][-1], rel=1e-2)
    assert abs(longer.history["pressure_kPa"][-1] / direct.history["pressure_kPa"][-1] - 1) > 1e-3
    # steps scaled with the end keep the step and the stabilisation's relaxation time: the direct run
    same_step = run(Footing(resolution=1, steps=12, settlement_m=0.02), SAND,
                    output=Output(tmp_path / "s", plots=False), resume=True)
    assert len(same_step.history) == len(direct.history)
    np.testing.assert_allclose(same_step.history["pressure_kPa"], direct.history["pressure_kPa"], rtol=1e-9)
    np.testing.assert_allclose(same_step.u, direct.u, rtol=0, atol=1e-9 * np.abs(direct.u).max())
    assert json.loads((tmp_path / "r" / "parameters.json").read_text())["settlement_m"] == 0.02
    with pytest.raises(ValueError, match=r"K0: 0.5 -> 0.6; .*\(only settlement_m, and steps with it, may change on a resume"):
        run(Footing(resolution=1, steps=6, settlement_m=0.03, K0=0.6), SAND, output=out, resume=True)


def test_a_case_command_resumes_with_a_larger_settlement(tmp_path):
    from femgran.cli import main

    base = ["footing", "--resolution", "1", "--steps", "4", "--stabilisation", "0.1", "--no-progress", "--out",
            str(tmp_path)]
    assert main(base + ["--settlement", "0.01"]) == 0
    assert main(base + ["--settlement", "0.015", "--resume"]) == 0
    h = read_table(tmp_path / "history.csv")
    assert h["settlement_m"][-1] == pytest.approx(0.015) and np.all(np.diff(h["settlement_m"]) > 0)
    assert main(base + ["--settlement", "0.02", "--K0", "0.6", "--resume"]) == 2  # any other change: refused
