"""The gradient back stress in the FE solver (femgran.gradient.BackStressDiscretisation): the coupled Newton
matrix against central differences of the coupled residual, a homogeneous specimen that follows the local
law, and the field in the output and the checkpoints."""

import numpy as np
import pytest

from femgran.assembly import discretisation_for
from femgran.cases import Biaxial, Output, run
from femgran.cases.base import build_problem
from femgran.gradient import BackStressDiscretisation
from femgran.solver import NewtonSolver
from material import load_preset
from material.base import BackStressTangent
from material.factory import make_material

BACK = {"back_stress_modulus": 1.0e4, "back_stress_length": 0.01}


def _solver(alpha=30.0, steps=10, **case):
    law = make_material(load_preset("ottawa_c109"), alpha_deg=alpha, plane_strain=True, stabilisation=0.1, **BACK)
    problem = build_problem(Biaxial(resolution=4, axial_strain=0.01, steps=steps, platens="rough", alpha_deg=alpha,
                                    **case), law)
    newton = NewtonSolver(problem.disc, problem.material, problem.dirichlet, f_fixed=problem.f_fixed,
                          initial_stress=problem.initial_stress)
    return newton, newton.run(steps=steps)


def test_coupled_newton_matrix_is_the_derivative_of_the_coupled_residual():
    """Rough platens, 1 % axial strain (every point loading): K (du, d ebar_p) against central differences
    of the full residual along a random direction (measured 1.1e-7; without the step stabilisation the
    law's own kinks along the direction leave 4e-5 here, and 1.7e-4 without the back stress)."""
    newton, sol = _solver()
    assert sol.completed and sol.history["iterations"][1:].max() <= 3
    d = newton.disc
    assert isinstance(d, BackStressDiscretisation) and d.ndofs == 2 * 45 + 6 * 45  # Q1 on 4 x 8 elements
    rng = np.random.default_rng(3)
    du = rng.normal(size=d.ndofs) * 1e-5

    def residual(v):
        stress, tangent, _ = newton.points.evaluate(d.strain(v), **d.point_inputs(v))
        return d.internal_force(stress, tangent, newton.u + v), tangent

    _, tangent = residual(du)
    assert isinstance(tangent, BackStressTangent)
    assert (newton.points.trial_state["kappa"] > newton.points.state["kappa"]).any(axis=1).all()
    K = d.stiffness(tangent)
    direction = rng.normal(size=d.ndofs)
    h = 1e-9
    fd = (residual(du + h * direction)[0] - residual(du - h * direction)[0]) / (2 * h)
    assert np.linalg.norm(fd - K @ direction) <= 1e-5 * np.linalg.norm(fd)
    n0 = d.n_displacement_dofs
    assert abs(K[n0:, :n0]).max() > 1.0 and abs(K[:n0, n0:]).max() > 1.0  # the coupling is there


def test_a_homogeneous_specimen_follows_the_local_law(tmp_path):
    """Smooth platens, no weak zone: ebar_p = eps_p everywhere, X = 0, and q is the local law's (to the
    solver's tolerance); the VTK output carries ebar_p and a checkpoint holds the coupled tangent."""
    fields = dict(resolution=2, axial_strain=0.02, steps=8, platens="smooth", imperfection=0.0)
    spec = {"preset": "ottawa_c109", "stabilisation": 0.1}
    with_back = run(Biaxial(**fields), {**spec, **BACK}, output=Output(out=tmp_path / "back", checkpoint_every=4))
    local = run(Biaxial(**fields), spec)
    assert with_back.completed and local.completed
    q_b, q_l = with_back.history["q_kPa"], local.history["q_kPa"]
    assert q_l[-1] > 100.0
    assert np.abs(q_b - q_l).max() <= 1e-6 * q_l.max()
    import meshio

    from femgran import checkpoint as ck

    mesh = meshio.read(sorted((tmp_path / "back").glob("*.vtu"))[-1])
    ebar = mesh.point_data["nonlocal_plastic_strain"]
    assert ebar.shape[1] == 9 and np.abs(ebar).max() > 1e-4
    arrays, _ = ck.load(ck.latest(tmp_path / "back"))
    assert isinstance(ck.committed_tangent(arrays), BackStressTangent)


def test_bad_input_of_the_discretisation_and_a_composite():
    from material.composite import Composite

    law = make_material(load_preset("ottawa_c109"), plane_strain=True, **BACK)
    mesh = build_problem(Biaxial(resolution=2), law).disc.mesh
    with pytest.raises(ValueError, match=r"length = -1.0: must be > 0"):
        BackStressDiscretisation(mesh, 1, length=-1.0, scale=1.0)
    with pytest.raises(ValueError, match=r"back stress lengths"):
        Composite([law, law.replace(back_stress_length=0.02)], np.zeros(4, dtype=int))
    with pytest.raises(ValueError, match=r"back stress lengths"):
        Composite([law, law.replace(back_stress_modulus=0.0, back_stress_length=None)], np.zeros(4, dtype=int))
    same = Composite([law, law], np.arange(4) % 2)
    assert same.back_stress_length == 0.01 and isinstance(discretisation_for(same, mesh, 1), BackStressDiscretisation)


def test_a_back_stress_run_resumes_to_the_bit_and_the_command_line_takes_it(tmp_path, capsys):
    """Rough platens, weak corner (the back stress is non-zero): stopped after 3 steps and resumed from its
    checkpoint, the run computes what the uninterrupted one computes, ebar_p included; the command line's
    --back-stress H L builds the law and records it."""
    from femgran.cli import main

    case = Biaxial(resolution=4, axial_strain=0.01, steps=6, platens="rough", weak_zone=0.1, imperfection=0.0)
    spec = {"preset": "ottawa_c109", "stabilisation": 0.1, **BACK}
    whole = run(case, spec, output=Output(out=tmp_path / "whole", plots=False))
    run(case, spec, output=Output(out=tmp_path / "part", plots=False, checkpoint_every=3), max_steps=3)
    resumed = run(case, spec, output=Output(out=tmp_path / "part", plots=False), resume=True)
    assert whole.completed and resumed.completed
    n0 = build_problem(case, spec).disc.n_displacement_dofs
    assert np.abs(whole.u[n0:]).max() > 1e-4  # ebar_p is part of what is compared
    assert np.array_equal(resumed.u, whole.u)
    assert main(["biaxial", "--back-stress", "1e4", "0.01", "--axial-strain", "0.01", "--steps", "6",
                 "--resolution", "4", "--weak-zone", "0.1", "--imperfection", "0", "--platens", "rough",
                 "--out", str(tmp_path / "cli"), "--no-progress"]) == 0
    assert "gradient back stress: modulus H = 10000 kPa, length l = 0.01 m" in \
        (tmp_path / "cli" / "parameters.json").read_text()
    assert "back_stress_modulus = 10000.0" in (tmp_path / "cli" / "case.toml").read_text()
