"""``femgran sweep``: any run over a grid or a list, from flags or a study file (femgran.sweep)."""

import json

import pytest

from femgran.cases.cavity import limit_pressure
from femgran.cli import main
from femgran.sweep import read_study, runs_for
from material.table import read_table


def test_an_element_grid_from_flags(tmp_path):
    out = tmp_path / "s"
    assert main(["sweep", "element:triaxial", "--grid", "p0_kPa=50,100", "material.beta=0,5", "--set", "steps=20",
                 "--scheduler", "serial", "--out", str(out), "--no-progress"]) == 0
    summary = read_table(out / "summary.csv")
    assert summary.metadata["runs"] == ["p0_kPa_50_material-beta_0", "p0_kPa_50_material-beta_5",
                                        "p0_kPa_100_material-beta_0", "p0_kPa_100_material-beta_5"]
    assert list(summary["p0_kPa"]) == [50, 50, 100, 100] and list(summary["material.beta"]) == [0, 5, 0, 5]
    # the summary carries each run's peak: doubling p0 about doubles the strength of a frictional law
    assert summary["max_q_kPa"][2] > 1.8 * summary["max_q_kPa"][0]
    run = json.loads((out / "p0_kPa_100_material-beta_5" / "sweep_run.json").read_text())
    assert run["kwargs"]["material"] == {"set": {"beta": 5}} and run["status"] == "completed"


def test_a_study_file_runs_a_case_on_a_local_cluster_and_resumes(tmp_path):
    study = tmp_path / "study.toml"
    study.write_text('''
[sweep]
run = "cavity"
workers = 2
[fixed]
expansion = 0.03
steps = 10
[fixed.material]
law = "von_mises"
E_kPa = 1e5
nu = 0.3
yield_stress_kPa = 173.2
[grid]
p0_kPa = [0, 50]
''')
    out = tmp_path / "cav"
    assert main(["sweep", str(study), "--out", str(out), "--no-progress"]) == 0
    summary = read_table(out / "summary.csv")
    for p0, p in zip(summary["p0_kPa"], summary["final_pressure_kPa"]):  # Hill's collapse pressure
        assert p == pytest.approx(limit_pressure(p0, 0.1, 0.2, 173.2), rel=1e-2)
    assert (out / "p0_kPa_50" / "cavity.pvd").is_file()
    assert main(["sweep", str(study), "--out", str(out), "--no-progress"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["ran"] == 0 and record["skipped"] == 2


def test_a_list_of_points_and_the_run_keys():
    runs = runs_for("footing", fixed={"material.stabilisation": 0.1},
                    points=[{"alpha_deg": 0.0}, {"alpha_deg": 30.0, "settlement_m": 0.05}])
    assert [r.key for r in runs] == ["alpha_deg_0", "alpha_deg_30_settlement_m_0.05"]
    assert runs[1].kwargs["fields"] == {"alpha_deg": 30.0, "settlement_m": 0.05}
    assert runs[1].kwargs["material"] == {"stabilisation": 0.1}


@pytest.mark.parametrize("argv, match", [
    (["footing", "--grid", "alpha=0,30"], "footing: unknown key"),
    (["element:nope"], "allowed element:TEST"),
    (["element:triaxial", "--grid", "p0=50,100"], "unknown key(s) ['p0']"),
    (["dem:table4", "--grid", "material.beta=0,5"], "do not apply"),
    (["cavity", "--grid", "p0_kPa=0,50", "--set", "material.law=von_mises", "material.beta=5"], "law 'von_mises' has"),
    (["nothing"], "KIND 'nothing': allowed"),
    (["element:triaxial", "--grid", "p0_kPa"], "expected KEY=VALUE"),
    (["footing", "--grid", "alpha_deg=abc"], "footing: alpha_deg = 'abc': allowed a number"),
    (["element:triaxial", "--set", "material.nope=3"], "material.*: unknown parameter(s) ['nope']"),
])
def test_bad_studies_are_named_before_anything_runs(argv, match, tmp_path, capsys):
    assert main(["sweep", *argv, "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    assert match in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_study_file_with_a_bad_table_is_named(tmp_path):
    bad = tmp_path / "s.toml"
    bad.write_text("[sweep]\nrun = \"footing\"\n[grids]\nalpha_deg = [0]\n")
    with pytest.raises(ValueError, match=r"unknown table\(s\) \['grids'\]"):
        read_study(bad)


def test_an_identification_sweep_over_the_series_order(tmp_path):
    out = tmp_path / "id"
    assert main(["sweep", "identify:direct-shear", "--grid", "order=2,3", "--set", "data=fig8",
                 "--scheduler", "serial", "--out", str(out), "--no-progress"]) == 0
    summary = read_table(out / "summary.csv")
    # both orders reproduce the Fig. 8 slopes closely; the third-order series fits them no worse
    assert (summary["r2_slope"] > 0.99).all() and summary["rms_slope"][1] <= summary["rms_slope"][0]
    assert (out / "order_3" / "parameters.toml").is_file()
