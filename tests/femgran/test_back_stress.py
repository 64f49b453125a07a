"""The gradient back stress in the FE solver (femgran.gradient.BackStressDiscretisation): the coupled Newton
matrix against central differences of the coupled residual, a homogeneous specimen that follows the local
law, and the field in the output and the checkpoints."""

import numpy as np
import pytest

from femgran.gradient import discretisation_for
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
    """Rough platens, 1 % axial strain, half the last step's increment on (every point loading): K (du,
    d ebar_p) against central differences of the full residual along a random direction (measured 1.9e-11
    with the four fields of plane strain. An earlier version of this test perturbed with a random du of
    1e-5 and measured 1.1e-7 with six fields; with four such a du unloads 9-20 of the 128 points)."""
    newton, sol = _solver()
    assert sol.completed and sol.history["iterations"][1:].max() <= 3
    d = newton.disc
    assert isinstance(d, BackStressDiscretisation) and d.ndofs == 2 * 45 + 4 * 45  # Q1 on 4 x 8 elements, plane strain
    rng = np.random.default_rng(1)
    du = 0.5 * newton._last_increment[0] + rng.normal(size=d.ndofs) * 1e-6  # on along the path, every point loading

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
    assert np.linalg.norm(fd - K @ direction) <= 1e-8 * np.linalg.norm(fd)
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


def test_plane_strain_carries_four_components_and_follows_the_six():
    """In plane strain ebar_p carries xx, yy, zz and xy: the run at alpha = 30 deg with all six fields gives the
    same displacements and stresses to round-off (the out-of-plane shears of eps_p and ebar_p stay zero there),
    with a third fewer nonlocal unknowns."""
    from femgran.gradient import ALL_COMPONENTS, PLANE_COMPONENTS

    four, sol4 = _solver(steps=6)
    d4 = four.disc
    assert d4.components == PLANE_COMPONENTS and d4.n_nonlocal_dofs == 4 * 45
    d6 = BackStressDiscretisation(d4.mesh, d4.order, d4.volumetric, length=d4.length, scale=d4.scale,
                                  components=ALL_COMPONENTS)
    law = make_material(load_preset("ottawa_c109"), alpha_deg=30.0, plane_strain=True, stabilisation=0.1, **BACK)
    problem = build_problem(Biaxial(resolution=4, axial_strain=0.01, steps=6, platens="rough", alpha_deg=30.0), law)
    f6 = np.zeros(d6.ndofs)
    f6[:d4.n_displacement_dofs] = problem.f_fixed[:d4.n_displacement_dofs]
    six = NewtonSolver(d6, problem.material, problem.dirichlet, f_fixed=f6, initial_stress=problem.initial_stress)
    sol6 = six.run(steps=6)
    assert sol4.completed and sol6.completed
    n0 = d4.n_displacement_dofs
    assert np.abs(four.u[:n0] - six.u[:n0]).max() <= 1e-9 * np.abs(six.u[:n0]).max()
    assert np.abs(four.points.stress - six.points.stress).max() <= 1e-8 * np.abs(six.points.stress).max()
    fields = six.u[n0:].reshape(6, -1)
    assert np.abs(fields[[3, 4]]).max() <= 1e-14 * np.abs(fields).max() and np.abs(fields).max() > 1e-4
    # a checkpoint's vector of six fields is taken up; one with out-of-plane fields or another length is not
    kept = np.concatenate([six.u[:n0], fields[list(PLANE_COMPONENTS)].ravel()])
    assert np.array_equal(d4.adapt_unknowns(six.u), kept)
    bent = six.u.copy()
    bent[n0 + 3 * 45] = 1e-3
    with pytest.raises(ValueError, match=r"u: the components \(3, 4\) of ebar_p, which this discretisation does not"):
        d4.adapt_unknowns(bent)
    with pytest.raises(ValueError, match=r"last_du: 100 unknowns, where this mesh and back stress have 270"):
        d4.adapt_unknowns(np.zeros(100), "last_du")
    with pytest.raises(ValueError, match=r"components = \(0, 1, 2\): allowed \(0, 1, 2, 5\)"):
        BackStressDiscretisation(d4.mesh, 1, length=0.01, scale=1.0, components=(0, 1, 2))


def test_a_checkpoint_of_six_fields_resumes_on_the_four_of_plane_strain(tmp_path, monkeypatch):
    """A run checkpointed when plane strain carried all six fields (simulated: the module's plane set made
    the six) resumes with four, and ends where the run with four all along ends."""
    from femgran import gradient

    case = Biaxial(resolution=4, axial_strain=0.01, steps=6, platens="rough", weak_zone=0.1, imperfection=0.0)
    spec = {"preset": "ottawa_c109", "stabilisation": 0.1, **BACK}
    whole = run(case, spec, output=Output(out=tmp_path / "whole", plots=False))
    with monkeypatch.context() as m:
        m.setattr(gradient, "PLANE_COMPONENTS", gradient.ALL_COMPONENTS)
        part = run(case, spec, output=Output(out=tmp_path / "part", plots=False, checkpoint_every=3), max_steps=3)
    n0 = build_problem(case, spec).disc.n_displacement_dofs
    assert part.u.size == n0 + 6 * 45 and whole.u.size == n0 + 4 * 45
    resumed = run(case, spec, output=Output(out=tmp_path / "part", plots=False), resume=True)
    assert whole.completed and resumed.completed
    assert np.abs(resumed.u - whole.u).max() <= 1e-9 * np.abs(whole.u).max()


def test_a_law_with_out_of_plane_plastic_shears_is_refused_in_plane_strain():
    """The bedding turned about the horizontal in-plane axis (deposition axis out of the x-y plane, the
    material not set up for plane strain): the plastic strain gets out-of-plane shears, which the four
    plane-strain fields cannot carry; the run says so instead of dropping them."""
    plane = make_material(load_preset("ottawa_c109"), alpha_deg=30.0, plane_strain=True, stabilisation=0.1, **BACK)
    tilted = make_material(load_preset("ottawa_c109"), alpha_deg=30.0, plane_strain=False, stabilisation=0.1, **BACK)
    problem = build_problem(Biaxial(resolution=4, axial_strain=0.01, steps=4, platens="rough", alpha_deg=30.0), plane)
    newton = NewtonSolver(problem.disc, tilted, problem.dirichlet, f_fixed=problem.f_fixed,
                          initial_stress=problem.initial_stress)
    with pytest.raises(ValueError, match=r"out-of-plane shears .*plane_strain_axes"):
        newton.run(steps=4)
