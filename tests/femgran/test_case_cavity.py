"""The case added on the skeleton in one module: a cylindrical cavity against its closed forms."""

import json

import pytest

from femgran.cases import run_case
from femgran.cases.cavity import Cavity, cavity, elastic_pressure, limit_pressure
from material import LinearElastic, VonMises

E, NU, A, B = 1e5, 0.3, 0.1, 0.2


def test_the_elastic_cylinder_follows_lame():
    sol = cavity(LinearElastic(E, NU), expansion=1e-3, steps=1, plots=False)
    dp = sol.history["pressure_kPa"][-1] - 100.0
    assert dp == pytest.approx(elastic_pressure(1e-3 * A, A, B, E, NU), rel=5e-3)


@pytest.mark.parametrize("p0", [0.0, 100.0])
def test_the_von_mises_cylinder_collapses_at_hills_pressure(p0):
    sol = cavity(VonMises(E, NU, 173.2), p0_kPa=p0, expansion=0.03, steps=20, plots=False)
    p = sol.history["pressure_kPa"]
    assert sol.completed and sol.history["iterations"][1:].mean() <= 4
    assert p[-1] == pytest.approx(limit_pressure(p0, A, B, 173.2), rel=5e-3)
    assert abs(p[-1] - p[-5]) < 1e-3 * p[-1]  # the plateau of a collapse, not a hardening branch


def test_the_cavity_runs_from_a_case_file(tmp_path):
    path = tmp_path / "cavity.toml"
    path.write_text(f'[case]\nname = "cavity"\nexpansion = 0.03\nsteps = 10\np0_kPa = 0.0\n'
                    f'[material]\nlaw = "von_mises"\nE_kPa = {E}\nnu = {NU}\nyield_stress_kPa = 173.2\n'
                    f'[output]\nout = "{tmp_path / "run"}"\nplots = false\n')
    sol = run_case(path)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["final_pressure_kPa"] == pytest.approx(limit_pressure(0.0, A, B, 173.2), rel=1e-2)
    assert (tmp_path / "run" / "cavity.pvd").is_file() and sol.extra["params"]["case"] == "cavity"


@pytest.mark.parametrize("bad, match", [({"outer_radius_m": 0.05}, "outer_radius_m = 0.05: must be > inner"),
                                        ({"steps": 0}, "steps = 0"), ({"order": 3}, "order = 3"),
                                        ({"expansion": -1.0}, "expansion = -1.0")])
def test_bad_geometry_is_named_when_the_case_is_made(bad, match):
    with pytest.raises(ValueError, match=match):
        Cavity(**bad)
