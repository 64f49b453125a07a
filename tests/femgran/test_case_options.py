"""The solver options reach every case by every route: Python, the command line and a case file."""

import json

import pytest

from femgran.cases import biaxial, element, footing, run_case, triaxial
from femgran.solver import SolverOptions
from material import DruckerPrager

# the first step of each case is plastic: one Newton iteration and no cut-back cannot converge
STARVED = {"max_iter": 1, "max_cuts": 0}
CHEAP = {
    element: dict(axial_strain=0.01, steps=2),
    triaxial: dict(axial_strain=0.01, steps=2, resolution=1, plots=False),
    footing: dict(resolution=1, steps=2, plots=False),
    biaxial: dict(axial_strain=0.01, steps=2, resolution=2, plots=False),
}


@pytest.mark.parametrize("case", list(CHEAP), ids=lambda f: f.__name__)
@pytest.mark.parametrize("given", [SolverOptions(**STARVED), STARVED], ids=["SolverOptions", "mapping"])
def test_every_case_takes_the_solver_options_from_python(case, given):
    assert case(None, **CHEAP[case]).completed
    sol = case(None, solver=given, **CHEAP[case])
    assert not sol.completed
    assert sol.stop_reason.startswith("stopped at t = 0: no convergence in 1 iterations")
    assert sol.stop_reason.endswith("0 cut-backs did not help")


def test_the_shorthands_replace_the_fields_of_the_solver_options(tmp_path):
    sol = footing(DruckerPrager(30000, 0.3, cohesion_kPa=5.0, friction_deg=30.0), resolution=1, steps=2,
                  settlement_m=0.01, plots=False, out=tmp_path, tol=1e-7, linear_solver="superlu",
                  solver=SolverOptions(max_iter=9, tol=1e-5))
    record = json.loads((tmp_path / "parameters.json").read_text())["solver"]
    assert record == {**SolverOptions().to_dict(), "max_iter": 9, "tol": 1e-7, "linear_solver": "superlu"}
    assert sol.extra["params"]["solver"] == record


def test_the_command_line_passes_the_solver_options(tmp_path):
    from femgran.cli import main

    argv = ["footing", "--law", "drucker_prager", "--friction", "30", "--cohesion", "5", "--resolution", "1",
            "--steps", "2", "--settlement", "0.01", "--no-progress", "--out", str(tmp_path),
            "--tol", "1e-7", "--max-iter", "9", "--max-cuts", "3", "--line-search", "4", "--predictor", "tangent"]
    assert main(argv) == 0
    record = json.loads((tmp_path / "parameters.json").read_text())["solver"]
    assert record == {**SolverOptions().to_dict(), "tol": 1e-7, "max_iter": 9, "max_cuts": 3, "line_search": 4,
                      "predictor": "tangent"}
    assert main(argv[:-10] + ["--max-iter", "0"]) == 2  # bad value: a clear error, exit code 2


def test_a_case_file_passes_the_solver_table(tmp_path):
    case = tmp_path / "case.toml"
    body = ('case = "footing"\nout = "{out}"\n[material]\nlaw = "drucker_prager"\nE_kPa = 30000.0\nnu = 0.3\n'
            'cohesion_kPa = 5.0\nfriction_deg = 30.0\n[parameters]\nresolution = 1\nsteps = 2\n'
            'settlement_m = 0.01\nplots = false\n[solver]\n{solver}\n')
    case.write_text(body.format(out=tmp_path / "run", solver="tol = 1e-7\nmax_iter = 9\nline_search = 4"))
    assert run_case(case).completed
    record = json.loads((tmp_path / "run" / "parameters.json").read_text())["solver"]
    assert record == {**SolverOptions().to_dict(), "tol": 1e-7, "max_iter": 9, "line_search": 4}
    case.write_text(body.format(out=tmp_path / "run", solver="max_iterations = 9"))
    with pytest.raises(ValueError, match=r"\[solver\] of case.toml: unknown key\(s\) \['max_iterations'\]; "
                                         r"allowed \[.*'max_iter'"):
        run_case(case)


@pytest.mark.parametrize("bad, match", [({"tol": 2.0}, "tol"), ({"max_iter": 0}, "max_iter"),
                                        ({"dt_min": 0.0}, "dt_min"), ({"line_search": -1}, "line_search"),
                                        ({"predictor": "secant"}, "predictor")])
def test_bad_solver_options_name_the_key_and_the_allowed_values(bad, match):
    with pytest.raises(ValueError, match=match):
        SolverOptions.resolve(bad)


def test_femgran_run_overrides_the_solver_table_of_a_case_file(tmp_path):
    from femgran.cli import main

    case = tmp_path / "cavity.toml"
    case.write_text(f'[case]\nname = "cavity"\nsteps = 2\n[material]\nlaw = "von_mises"\nE_kPa = 1e5\nnu = 0.3\n'
                    f'yield_stress_kPa = 173.2\n[solver]\nmax_iter = 9\n[output]\nout = "{tmp_path / "run"}"\n'
                    f'plots = false\n')
    assert main(["run", str(case), "--no-progress", "--tol", "1e-7"]) == 0
    record = json.loads((tmp_path / "run" / "parameters.json").read_text())["solver"]
    assert (record["max_iter"], record["tol"]) == (9, 1e-7)
    assert json.loads((tmp_path / "run" / "run.json").read_text())["completed"] is True
