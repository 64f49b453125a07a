"""Implicit-gradient regularisation (femgran.gradient, material.GradientVonMises): the point law and the
coupled Newton matrix against finite differences, the homogeneous limit, and a softening bar whose
response converges with the mesh and whose softening zone scales with the length l."""

import json

import numpy as np
import pytest

from femgran.assembly import Discretisation
from femgran.gradient import discretisation_for
from femgran.gradient import GradientDiscretisation, one_dimensional_band
from femgran.mesh import name_box_boundaries, rectangle
from femgran.solver import Dirichlet, NewtonSolver, PathControl
from material import GradientVonMises, VonMises
from material.base import CoupledTangent

E, NU, SY, H = 20000.0, 0.3, 100.0, -2000.0
L, HEIGHT = 1.0, 0.1


def _plastic_states(law, n, rng):
    """n points loaded into the softening range by a random deviatoric strain path (local law)."""
    sig = np.zeros((n, 3, 3))
    state = law.initial_state(n)
    for _ in range(3):
        a = rng.normal(size=(n, 3, 3)) * 4e-3
        sig, state, _ = law.update(0.5 * (a + np.swapaxes(a, 1, 2)), sig, state)
    return sig, state


def test_without_the_nonlocal_input_the_law_is_von_mises():
    rng = np.random.default_rng(1)
    g = GradientVonMises(E, NU, SY, H, length_m=0.1)
    sig, state = _plastic_states(g, 20, rng)
    a = rng.normal(size=(20, 3, 3)) * 2e-3
    de = 0.5 * (a + np.swapaxes(a, 1, 2))
    s1, st1, D1 = g.update(de, sig, state)
    s2, st2, D2 = VonMises(E, NU, SY, H).update(de, sig, {k: v for k, v in state.items() if k != "nonlocal"})
    assert np.array_equal(s1, s2) and np.array_equal(D1, D2)
    assert np.array_equal(st1["nonlocal"], st1["eq_plastic_strain"])  # a homogeneous state: ebar = e
    # and with the nonlocal input equal to the local measure's increment the coupled update agrees
    s3, _, T = g.update(de, sig, state, d_nonlocal=st1["eq_plastic_strain"] - state["nonlocal"])
    assert isinstance(T, CoupledTangent)
    assert np.abs(s3 - s1).max() <= 1e-9 * SY


@pytest.mark.parametrize("m", [1.0, 2.0])
def test_coupled_point_derivatives_match_finite_differences(m):
    rng = np.random.default_rng(2)
    g = GradientVonMises(E, NU, SY, H, length_m=0.1, over_nonlocal=m)
    n = 12
    sig, state = _plastic_states(g, n, rng)
    a = rng.normal(size=(n, 3, 3)) * 2e-3
    de = 0.5 * (a + np.swapaxes(a, 1, 2))
    dn = state["eq_plastic_strain"] * 0.5 + 1e-3
    s0, st0, T = g.update(de, sig, state, d_nonlocal=dn)
    assert (st0["eq_plastic_strain"] > state["eq_plastic_strain"]).all()  # every point loads
    h = 1e-7
    s1, st1, _ = g.update(de, sig, state, d_nonlocal=dn + h)
    s_1, st_1, _ = g.update(de, sig, state, d_nonlocal=dn - h)
    assert np.allclose((s1 - s_1) / (2 * h), T.dstress_dnonlocal, rtol=1e-5, atol=1e-6 * E)
    assert np.allclose((st1["eq_plastic_strain"] - st_1["eq_plastic_strain"]) / (2 * h), T.dlocal_dnonlocal,
                       rtol=1e-5, atol=1e-8)
    for i, j in [(0, 0), (0, 1), (1, 2), (2, 2)]:
        e = np.zeros((3, 3)); e[i, j] = e[j, i] = 1.0
        sp, stp, _ = g.update(de + h * e, sig, state, d_nonlocal=dn)
        sm, stm, _ = g.update(de - h * e, sig, state, d_nonlocal=dn)
        fd_s = (sp - sm) / (2 * h)
        fd_k = (stp["eq_plastic_strain"] - stm["eq_plastic_strain"]) / (2 * h)
        assert np.allclose(fd_s, np.einsum("nijkl,kl->nij", T.dstress_dstrain, e), rtol=1e-5, atol=1e-6 * E)
        assert np.allclose(fd_k, np.einsum("nkl,kl->n", T.dlocal_dstrain, e), rtol=1e-5, atol=1e-8)


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="length_m = 0"):
        GradientVonMises(E, NU, SY, H, length_m=0.0)
    with pytest.raises(ValueError, match="over_nonlocal = 0.5"):
        GradientVonMises(E, NU, SY, H, length_m=0.1, over_nonlocal=0.5)
    with pytest.raises(ValueError, match="local modulus"):
        GradientVonMises(E, NU, SY, 5000.0, length_m=0.1, over_nonlocal=20.0)
    with pytest.raises(ValueError, match="length = -1"):
        GradientDiscretisation(rectangle(np.linspace(0, 1, 3), np.linspace(0, 1, 3)), 1, length=-1.0, scale=E)


@pytest.mark.parametrize("m", [1.2, 2.0, 4.0])
def test_the_closed_form_band_is_the_widest_zone_of_the_discrete_rate_problem(m):
    """The rate problem of one_dimensional_band by finite differences (h = l/50 on 24 l, zero flux at the
    ends): for a plastic zone |x| <= a the plastic rate comes out positive everywhere in it with a jump to 0
    at its edges when a < w/2, negative near its edges when a > w/2; the zone whose edge rate is 0 (found by
    bisection) is the closed form's, to a grid cell, and so is its profile."""
    import scipy.sparse as sparse
    import scipy.sparse.linalg as sparse_linalg

    ell, n = 1.0, 1201
    x = np.linspace(-12 * ell, 12 * ell, n)
    h = x[1] - x[0]
    lap = sparse.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="lil") / h**2
    lap[0, 1] = lap[n - 1, n - 2] = 2 / h**2
    helm = sparse.eye(n) - ell**2 * lap.tocsr()

    def plastic_rate(a):
        """d kappa for the zone |x| <= a: d ebar - l^2 d ebar'' = d kappa, m d ebar + (1 - m) d kappa = 1."""
        k = np.flatnonzero(np.abs(x) <= a)
        P = sparse.csr_matrix((np.ones(k.size), (k, np.arange(k.size))), shape=(n, k.size))
        A = sparse.bmat([[helm, -P], [m * P.T, (1 - m) * sparse.eye(k.size)]], format="csc")
        rate = np.zeros(n)
        rate[k] = sparse_linalg.spsolve(A, np.concatenate([np.zeros(n), np.ones(k.size)]))[n:]
        return rate, k[-1]

    closed = one_dimensional_band(ell, m)
    lo, hi = 0.25 * closed.zone_width_m, closed.zone_width_m
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        rate, edge = plastic_rate(mid)
        lo, hi = (mid, hi) if rate[edge] > 0 else (lo, mid)
    rate, _ = plastic_rate(lo)
    assert 2 * lo == pytest.approx(closed.zone_width_m, abs=2 * h)
    assert np.ptp(x[rate >= 0.5 * rate.max()]) == pytest.approx(closed.fwhm_m, abs=2 * h)
    assert np.abs(rate / rate.max() - closed.profile(x)).max() < 0.02
    assert plastic_rate(0.6 * closed.zone_width_m)[0].min() < 0  # a wider zone is not admissible
    with pytest.raises(ValueError, match="over_nonlocal = 1.0"):
        one_dimensional_band(ell, 1.0)
    with pytest.raises(ValueError, match="length_m = 0"):
        one_dimensional_band(0.0)


def _bar(n, ell, *, imperfection=0.05, local=False, order=1):
    """A plane-strain bar L x HEIGHT in tension, thinner by ``imperfection`` in a smooth bump at mid-length,
    free laterally; ends u_x = 0 / prescribed; the path control is the elongation of its middle 0.3..0.7."""
    msh = rectangle(np.linspace(0, L, n + 1), np.linspace(0, HEIGHT, 2))
    msh.p[1] *= 1.0 - imperfection * np.exp(-((msh.p[0] - 0.5 * L) / 0.1) ** 2)
    msh = name_box_boundaries(msh)
    law = VonMises(E, NU, SY, H) if local else GradientVonMises(E, NU, SY, H, length_m=ell)
    d = discretisation_for(law, msh, order)
    x = d.dof_coordinates()
    corner = np.flatnonzero(np.hypot(x[:, 0], x[:, 1]) < 1e-12)
    bcs = [Dirichlet(d.vector_dofs(corner, [1]), 0.0, ramp=False),
           Dirichlet(d.vector_dofs(d.facet_scalar_dofs(msh.boundaries["left"]), [0]), 0.0, ramp=False),
           Dirichlet(d.vector_dofs(d.facet_scalar_dofs(msh.boundaries["right"]), [0]), 0.02, name="end")]
    a, b = np.flatnonzero(np.isclose(x[:, 0], 0.3)), np.flatnonzero(np.isclose(x[:, 0], 0.7))
    control = PathControl(np.concatenate([d.vector_dofs(b, [0]), d.vector_dofs(a, [0])]),
                          np.concatenate([np.full(len(b), 1 / len(b)), np.full(len(a), -1 / len(a))]),
                          name="middle_elongation_m")
    return d, law, bcs, control


def _run(n, ell, **kw):
    d, law, bcs, control = _bar(n, ell, **kw)
    solver = NewtonSolver(d, law, bcs)
    sol = solver.run(steps=60, control=control, control_end=1.2e-2,
                     observers=[lambda s: {"force": -float(np.sum(s.reaction[bcs[1].dofs]))}])
    kappa = solver.points.state["eq_plastic_strain"].reshape(d.nelems, d.nqp).mean(axis=1)
    x = d.mesh.p[0, d.mesh.t].mean(axis=0)
    columns, inverse = np.unique(np.round(x, 9), return_inverse=True)
    profile = np.bincount(inverse, kappa) / np.bincount(inverse)
    zone = columns[profile > 0.5 * profile.max()]
    width = float(np.ptp(zone)) + L / n  # full width at half maximum of the plastic strain, to one element
    return sol, width, d


def test_coupled_newton_matrix_is_the_derivative_of_the_coupled_residual():
    """At a softening state of the bar, K (du, d ebar) against central differences of the full residual."""
    d, law, bcs, control = _bar(10, 0.1)
    solver = NewtonSolver(d, law, bcs)
    sol = solver.run(steps=12, control=control, control_end=6e-3)
    assert sol.completed
    rng = np.random.default_rng(3)
    du = rng.normal(size=d.ndofs) * 1e-4
    du[d.n_displacement_dofs:] = np.abs(du[d.n_displacement_dofs:]) * 0.1

    def residual(v):
        de = d.strain(v)
        stress, tangent, _ = solver.points.evaluate(de, **d.point_inputs(v))
        return d.internal_force(stress, tangent, solver.u + v), tangent

    r0, tangent = residual(du)
    assert (solver.points.trial_state["eq_plastic_strain"] > solver.points.state["eq_plastic_strain"]).any()
    K = d.stiffness(tangent)
    direction = rng.normal(size=d.ndofs)
    h = 1e-8
    fd = (residual(du + h * direction)[0] - residual(du - h * direction)[0]) / (2 * h)
    assert np.linalg.norm(fd - K @ direction) <= 1e-5 * np.linalg.norm(fd)
    assert np.abs(K[d.n_displacement_dofs:, : d.n_displacement_dofs]).max() > 0  # the coupling is there


def test_the_stall_probe_moves_the_nonlocal_field_along_the_newton_direction():
    """``femgran.diagnostics``: along a Newton direction of the coupled problem the points' nonlocal
    increment moves with the strain. At a softening state of the bar the probe's stress rates are those of
    the solver's own evaluations of du + s ddu (to round-off), and differ from those with the nonlocal
    increment held at the iterate's; ``stall_report`` answers for a coupled run (it used to stay silent)."""
    from femgran.diagnostics import solver_kinks_along, stall_report

    d, law, bcs, control = _bar(10, 0.1)
    solver = NewtonSolver(d, law, bcs)
    assert solver.run(steps=12, control=control, control_end=6e-3).completed
    rng = np.random.default_rng(4)
    du = rng.normal(size=d.ndofs) * 1e-5
    ddu = np.zeros(d.ndofs)
    ddu[d.n_displacement_dofs:] = 1e-3 * rng.random(d.ndofs - d.n_displacement_dofs)  # the nonlocal field only
    s = np.linspace(0.0, 1.0, 5)
    probe = solver_kinks_along(solver, du, ddu, s)
    stresses = [solver.points.evaluate(d.strain(du + si * ddu), **d.point_inputs(du + si * ddu))[0].reshape(-1, 9)
                for si in s]
    rate = np.abs(np.diff(stresses, axis=0) / 0.25).max(axis=(0, 2))
    assert rate.max() > 0.0  # the field alone moves the softening points' stress
    np.testing.assert_allclose(probe["rate"], rate, rtol=1e-9, atol=1e-9 * rate.max())
    solver.stalled = (du, ddu, 0.25)
    note = stall_report(solver)
    assert note.startswith("along the last Newton direction (its line search tried down to s = 0.25)")


def test_a_homogeneous_specimen_follows_the_local_law():
    """No imperfection: ebar = e everywhere, so the gradient bar is the local von Mises bar (to the solver's
    tolerance), through the peak and the softening."""
    sol_g, _, d = _run(10, 0.1, imperfection=0.0)
    d_l, law, bcs, control = _bar(10, 0.1, imperfection=0.0, local=True)
    sol_l = NewtonSolver(d_l, law, bcs).run(steps=60, control=control, control_end=1.2e-2,
                                            observers=[lambda s: {"force": -float(np.sum(s.reaction[bcs[1].dofs]))}])
    assert sol_g.completed and sol_l.completed
    f_g, f_l = sol_g.history["force"], sol_l.history["force"]
    assert f_g[-1] < 0.8 * f_g.max()  # well into the softening
    assert np.abs(f_g - f_l).max() <= 1e-6 * f_l.max()


@pytest.mark.filterwarnings("ignore:Matrix is exactly singular")  # the local runs soften to zero strength
def test_softening_bar_converges_with_the_mesh_and_its_zone_scales_with_the_length():
    """Measured (force at 1.2e-2 middle elongation, kN/m; peak 10.93): l = 0.1 on 20/40/80 elements
    7.284/7.154/7.105, zone 0.30/0.30/0.275; l = 0.05 on 40/80 elements zone 0.15/0.15. The local law on
    the same meshes localises in a few elements and its softening follows the mesh."""
    runs = {n: _run(n, 0.1) for n in (20, 40, 80)}
    forces = {n: r[0].history["force"][-1] for n, r in runs.items()}
    peak = runs[80][0].history["force"].max()
    assert all(r[0].completed for r in runs.values())
    assert forces[20] < 0.75 * peak  # softening
    assert abs(forces[40] - forces[80]) < 0.01 * peak and abs(forces[20] - forces[80]) < 0.02 * peak
    widths = {n: r[1] for n, r in runs.items()}
    assert max(widths.values()) - min(widths.values()) <= L / 80 * 2.01  # the same zone, to two fine elements
    # the closed form of the one-dimensional zone (FWHM 2.85 l for m = 2): measured 0.275 on 80 elements
    assert widths[80] == pytest.approx(one_dimensional_band(0.1).fwhm_m, abs=1.01 * L / 80)
    half = {n: _run(n, 0.05)[1] for n in (40, 80)}
    assert half[80] == pytest.approx(0.5 * widths[80], abs=2.01 * L / 80)  # zone proportional to l
    assert half[80] == pytest.approx(one_dimensional_band(0.05).fwhm_m, abs=1.01 * L / 80)  # measured 0.15
    assert abs(half[40] - half[80]) <= 2.01 * L / 80
    assert max(r[0].history["iterations"][1:].mean() for r in runs.values()) < 2.5  # Newton stays fast
    # the local law: at the same elongation 6e-3 the force follows the mesh (measured 6.23 / 3.45 kN/m)
    at = {n: np.interp(6e-3, r[0].history["middle_elongation_m"], r[0].history["force"]) for n, r in runs.items()}
    local = {n: _run(n, None, local=True)[0].history for n in (20, 40)}
    at_local = {n: np.interp(6e-3, h["middle_elongation_m"], h["force"]) for n, h in local.items()}
    assert abs(at[20] - at[40]) < 0.01 * peak and abs(at_local[20] - at_local[40]) > 0.2 * peak


def test_cases_take_a_gradient_law(tmp_path):
    """A gradient law in a case gets the coupled discretisation, and the VTK output carries ebar."""
    from femgran.cases import Biaxial, Output, run

    law = GradientVonMises(E, NU, 150.0, -500.0, length_m=0.01)
    sol = run(Biaxial(p0_kPa=50.0, axial_strain=0.01, steps=5, resolution=4), law, output=Output(out=tmp_path))
    assert sol.completed
    assert sol.u.size == 2 * 45 + 45  # 5 x 9 vertices (Q1): the displacement and the nonlocal field
    import meshio

    vtu = sorted(tmp_path.rglob("*.vtu"))[-1]
    assert "nonlocal" in meshio.read(vtu).point_data
    assert isinstance(discretisation_for(VonMises(E, NU, SY), rectangle(np.linspace(0, 1, 2), np.linspace(0, 1, 2))),
                      Discretisation)


def test_a_composite_of_gradient_laws_is_one_gradient_law():
    """The bar with its imperfection as a weaker middle (a Composite of two gradient laws) against the same
    Composite with two identical laws, which must reproduce the single law's run exactly; different lengths
    are refused."""
    from material.composite import Composite

    d, law, bcs, control = _bar(20, 0.1)
    twin = Composite([law, GradientVonMises(E, NU, SY, H, length_m=0.1)], np.arange(d.n_points) % 2)
    assert twin.nonlocal_length == 0.1 and isinstance(discretisation_for(twin, d.mesh, 1), GradientDiscretisation)
    runs = [NewtonSolver(d, m, bcs).run(steps=30, control=control, control_end=1.2e-2,
                                        observers=[lambda s: {"force": -float(np.sum(s.reaction[bcs[1].dofs]))}])
            for m in (law, twin)]
    assert np.array_equal(runs[0].history["force"], runs[1].history["force"])
    with pytest.raises(ValueError, match="nonlocal lengths"):
        Composite([law, GradientVonMises(E, NU, SY, H, length_m=0.2)], np.zeros(4, dtype=int))
    with pytest.raises(ValueError, match="nonlocal lengths"):
        Composite([law, VonMises(E, NU, SY, H)], np.zeros(4, dtype=int))


def test_biaxial_shear_band_of_a_gradient_law_does_not_depend_on_the_mesh(tmp_path):
    """Plane-strain biaxial compression of a softening von Mises solid, l = 10 mm, W = 50 mm, meshes of 20 and
    30 elements across (h = l/4, l/6), 40 steps. Measured: q at 4 % 118.84 / 118.68 kPa (peak 167.2), band
    thickness 25.2 / 24.8 mm. (examples/fe_05_gradient_band.py: with l = 5 mm the band is 13.2 / 13.3 mm;
    the local law gives bands of 4.2 / 2.8 / 2.3 mm on 10 / 20 / 30 elements and stops on the finer two.)"""
    from femgran.cases import Biaxial, Output, run

    out = {}
    for res in (20, 30):
        law = GradientVonMises(20000.0, 0.3, 150.0, -1000.0, length_m=0.01)
        sol = run(Biaxial(p0_kPa=50.0, axial_strain=0.04, steps=40, resolution=res), law,
                  output=Output(out=tmp_path / f"r{res}", write_every=1000))
        assert sol.completed, sol.stop_reason
        summary = json.loads((tmp_path / f"r{res}" / "summary.json").read_text())
        assert "implicit gradient: length l = 0.01 m" in (tmp_path / f"r{res}" / "parameters.json").read_text()
        q = sol.history["q_kPa"]
        out[res] = (q[-1], q.max(), summary["band_thickness_m"], summary["localised"])
    (q20, peak, t20, loc20), (q30, _, t30, loc30) = out[20], out[30]
    assert q20 < 0.8 * peak and abs(q20 - q30) < 0.005 * peak
    assert loc20 and loc30 and abs(t20 - t30) <= 0.05 / 30  # within one element of the finer mesh
    assert 2.0 * 0.01 <= t30 <= 3.0 * 0.01


def test_a_material_table_with_a_length_gives_the_gradient_law():
    from material.factory import make_material

    law = make_material({"law": "von_mises", "E_kPa": E, "nu": NU, "yield_stress_kPa": SY, "hardening_kPa": H,
                         "length_m": 0.02})
    assert isinstance(law, GradientVonMises) and law.nonlocal_length == 0.02 and law.over_nonlocal == 2.0
    assert type(make_material({"law": "von_mises", "E_kPa": E, "nu": NU, "yield_stress_kPa": SY})) is VonMises
    with pytest.raises(ValueError, match="length_m = -1"):
        make_material({"law": "von_mises", "E_kPa": E, "nu": NU, "yield_stress_kPa": SY, "length_m": -1})


def test_cpa_shear_band_with_the_gradient_runs_past_the_peak(tmp_path):
    """The CPA law with softening and the implicit gradient (l = 10 mm) in the biaxial case: the coupled
    problem runs into the softening at the solver's tolerance, with the nonlocal field in the output."""
    from femgran.cases import Biaxial, Output, run
    from material import load_preset
    from material.factory import make_material

    params = load_preset("ottawa_c109").replace(E=60000.0, zeta=1.05, softening_slip=0.03, residual_ratio=0.65)
    law = make_material(params, alpha_deg=0.0, plane_strain=True, stabilisation=0.1, nonlocal_length=0.01)
    sol = run(Biaxial(resolution=6, axial_strain=0.045, steps=90, imperfection=0.0, weak_zone=0.1,
                      weak_zone_height=0.01, platens="rough"), law, output=Output(out=tmp_path, write_every=1000))
    assert sol.completed, sol.stop_reason
    q = sol.history["q_kPa"]
    assert q[-1] < 0.97 * q.max() and sol.history["iterations"][1:].mean() < 4.0
    assert "implicit gradient: length l = 0.01 m" in (tmp_path / "parameters.json").read_text()
    import meshio

    ebar = meshio.read(sorted(tmp_path.glob("*.vtu"))[-1]).point_data["nonlocal"]
    assert ebar.max() > 0.0 and ebar.min() >= -1e-9  # the post-peak slip strain, smoothed


def test_the_command_line_takes_the_gradient(tmp_path, capsys):
    from femgran.cli import main

    main(["biaxial", "--set", "zeta=1.05", "--set", "softening_slip=0.03", "--nonlocal-length", "0.01",
          "--axial-strain", "0.004", "--steps", "2", "--resolution", "4", "--out", str(tmp_path), "--no-progress"])
    assert "implicit gradient: length l = 0.01 m" in (tmp_path / "parameters.json").read_text()
    # without softening the gradient has nothing to regularise: one line naming the key and what is allowed
    assert main(["biaxial", "--nonlocal-length", "0.01", "--axial-strain", "0.004", "--steps", "2",
                 "--resolution", "4", "--out", str(tmp_path / "bad"), "--no-progress"]) == 2
    assert "nonlocal_length = 0.01" in capsys.readouterr().err


def test_a_gradient_run_resumes_to_the_bit(tmp_path):
    """A gradient run (cavity expansion, softening von Mises) stopped after 4 steps and resumed from its
    checkpoint computes what the uninterrupted run computes: the displacements and the nonlocal field, to
    the bit with the direct solver."""
    from femgran.cases import Cavity, Output, run

    case = Cavity(expansion=0.02, steps=8, radial_elements=4)
    law = GradientVonMises(20000.0, 0.3, 150.0, -1000.0, length_m=0.02)
    whole = run(case, law, output=Output(out=tmp_path / "whole", plots=False))
    run(case, law, output=Output(out=tmp_path / "part", plots=False), max_steps=4)
    resumed = run(case, law, output=Output(out=tmp_path / "part", plots=False), resume=True)
    assert whole.completed and resumed.completed
    ebar = whole.u[-10:]
    assert np.abs(ebar).max() > 0  # the nonlocal field is part of what is compared
    assert np.array_equal(resumed.u, whole.u)


def test_a_biaxial_run_resumed_after_its_peak_measures_the_same_band(tmp_path):
    """The band is measured from the strain at the peak, which the checkpoints carry: a run stopped after its
    peak and resumed gives the uninterrupted run's summary and displacements."""
    from femgran.cases import Biaxial, Output, run

    case = Biaxial(p0_kPa=50.0, axial_strain=0.03, steps=30, resolution=6)
    law = GradientVonMises(20000.0, 0.3, 150.0, -1000.0, length_m=0.01)
    whole = run(case, law, output=Output(out=tmp_path / "whole", plots=False))
    part = run(case, law, output=Output(out=tmp_path / "part", plots=False), max_steps=20)
    assert int(np.argmax(part.history["q_kPa"])) < 15  # stopped well past the peak
    resumed = run(case, law, output=Output(out=tmp_path / "part", plots=False), resume=True)
    assert whole.completed and resumed.completed and whole.localised
    assert np.array_equal(resumed.u, whole.u)
    for key in ("band_angle_deg", "band_thickness_m", "band_contrast", "peak_q_kPa"):
        assert getattr(resumed, key) == getattr(whole, key)


def test_a_biaxial_specimen_twice_as_large_with_twice_the_length_is_the_same_problem_at_twice_the_scale(tmp_path):
    """The CPA law has no length in space (its lengths turn slip into strain at a point), so with the implicit
    gradient the only lengths are the specimen's and l: W = 100 mm with l = 12 mm is W = 50 mm with l = 6 mm at
    twice the scale. The ebar rows scaled by E / l make the coupled residual forces, and the solver takes the
    same Newton iterates, line-search steps and cut-backs on both: q identical to round-off at every step past
    the peak, the band twice as thick at the same angle. With the rows scaled by E alone (before 2026-12-07)
    the two runs parted at the first step after the peak (measured: 14 against 12 steps, peak q 504.0 against
    502.2 kPa)."""
    from femgran.solver import History
    from femgran.sweep import case_target

    material = {"preset": "ottawa_c109", "stabilisation": 0.01,
                "set": {"E": 60000.0, "zeta": 1.05, "softening_slip": 0.03, "residual_ratio": 0.65, "eta_c_ratio": 0.0}}
    fields = {"p0_kPa": 100.0, "axial_strain": 0.03, "steps": 12, "imperfection": 0.0, "weak_zone": 0.1,
              "weak_zone_height": 1.0 / 18.0, "weak_zone_size": 1.0 / 3.0, "platens": "rough", "height_ratio": 3.0,
              "resolution": 6}
    runs = {}
    for width, length in ((0.05, 0.006), (0.1, 0.012)):
        folder = tmp_path / f"w{width}"
        runs[width] = (case_target(folder, "biaxial", {**fields, "width_m": width},
                                   {**material, "nonlocal_length": length}),
                       History.read_csv(folder / "history.csv"))
    (small, h_small), (large, h_large) = runs[0.05], runs[0.1]
    assert small["completed"] and large["completed"] and small["steps"] == large["steps"]
    q_small, q_large = np.asarray(h_small["q_kPa"]), np.asarray(h_large["q_kPa"])
    assert q_small.size == q_large.size and q_small.argmax() < q_small.size - 3  # past the peak
    assert np.abs(q_large - q_small).max() < 1e-9 * q_small.max()
    assert np.array_equal(np.asarray(h_small["iterations"]), np.asarray(h_large["iterations"]))
    assert small["localised"] and large["localised"]
    assert large["band_thickness_m"] == pytest.approx(2.0 * small["band_thickness_m"], rel=1e-6)
    assert large["band_angle_deg"] == pytest.approx(small["band_angle_deg"], abs=1e-6)
