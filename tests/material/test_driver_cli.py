"""``femgran element ...``: files written, defaults, bad input (material.cli)."""

import json

import numpy as np
import pytest

from femgran.cli import main
from material import load_parameters, load_preset
from material.results import read_csv


def test_element_triaxial_writes_run_folder(tmp_path):
    out = tmp_path / "element"
    rc = main(["element", "triaxial", "--steps", "30", "--out", str(out), "--no-progress"])
    assert rc == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["parameters.toml", "run.json", "summary.csv", "sweep.json", "triaxial.png",
                     "triaxial_p0_100_alpha_0", "triaxial_p0_100_alpha_90"]
    run = json.loads((out / "run.json").read_text())
    assert run["test"] == "triaxial" and run["seed"] is None and run["femgran_version"]
    assert all(r["status"] == "completed" for r in run["runs"]) and run["ran"] == 2
    assert load_parameters(out / "parameters.toml") == load_preset("ottawa_c109")
    res = read_csv(out / "triaxial_p0_100_alpha_0" / "triaxial.csv")
    assert len(res) == 31 and res.plot_pairs == [("eps_a", "q_kPa"), ("eps_a", "eps_v")]
    assert res.metadata["parameters"]["eta0"] == pytest.approx(0.8896)
    assert res["q_kPa"][-1] > read_csv(out / "triaxial_p0_100_alpha_90" / "triaxial.csv")["q_kPa"][-1]
    # the same command again finds both runs complete and runs nothing
    assert main(["element", "triaxial", "--steps", "30", "--out", str(out), "--no-progress"]) == 0
    assert json.loads((out / "run.json").read_text())["skipped"] == 2


def test_element_rotation_with_override(tmp_path):
    rc = main(["element", "rotation", "--dpsi", "90", "--set", "beta=5", "--steps", "20", "--out", str(tmp_path),
               "--no-progress", "--no-plot"])
    assert rc == 0
    assert load_parameters(tmp_path / "parameters.toml").beta == 5.0
    res = read_csv(tmp_path / "rotation_p0_14_dpsi_90" / "rotation.csv")
    assert res.metadata["delta_psi_deg"] == 90.0
    assert np.abs(res["eps_zz"]).max() < 1e-12


def test_element_path_replays_csv(tmp_path):
    f = tmp_path / "lab.csv"
    rows = ["sig_xx_kPa,sig_yy_kPa,eps_zz,sig_yz_kPa,sig_xz_kPa,sig_xy_kPa"]
    rows += [f"-50,-50,{-0.002 * i},0,0,0" for i in range(6)]
    f.write_text("\n".join(rows) + "\n")
    rc = main(["element", "path", str(f), "--substeps", "3", "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 0
    res = read_csv(tmp_path / "o" / "path_lab" / "path.csv")
    assert len(res) == 16
    assert np.abs(res["sig_xx_kPa"] + 50.0).max() < 1e-8 * np.abs(res.stress).max()


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--set", "gamma=1"], "unknown parameter"),
        (["--set", "beta"], "KEY=VALUE"),
        (["--set", "nu=0.7"], "'nu'"),
        (["--p0", "-5"], "p0_kPa"),
        (["--preset", "nope"], "unknown preset"),
        (["--params", "missing.toml"], "missing.toml"),
    ],
)
def test_element_bad_input(tmp_path, capsys, argv, match):
    rc = main(["element", "triaxial", "--steps", "2", "--out", str(tmp_path), "--no-progress", *argv])
    assert rc == 2
    assert match in capsys.readouterr().err
