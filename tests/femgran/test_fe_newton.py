"""Solver verification: patch tests, Taylor test, Lame cylinder, Newton convergence, cut-backs, output."""

import numpy as np
import pytest

import material
from femgran.assembly import Discretisation
from femgran.mesh import box, name_box_boundaries, rectangle
from femgran.output import SeriesWriter, read_pvd
from femgran.solver import Dirichlet, History, NewtonSolver, SolverOptions
from material.base import STATUS_FAILED


def _distorted(mesh, amount=0.07, seed=1):
    p = mesh.p.copy()
    lo, hi = p.min(axis=1, keepdims=True), p.max(axis=1, keepdims=True)
    interior = np.all((p > lo + 1e-9) & (p < hi - 1e-9), axis=0)
    p[:, interior] += amount * np.random.default_rng(seed).uniform(-1, 1, size=(p.shape[0], interior.sum()))
    return name_box_boundaries(type(mesh)(p, mesh.t))


@pytest.mark.parametrize("kind,order", [("hex", 1), ("tet", 2), ("quad", 1), ("tri", 2)])
def test_patch_test_linear_elasticity_is_exact(kind, order):
    """A linear displacement prescribed on the boundary of a distorted patch: strain exact inside."""
    if kind in ("hex", "tet"):
        mesh = box(1.0, 1.0, 1.0, 3, 3, 3, kind=kind)
    else:
        mesh = rectangle(np.linspace(0, 1, 4), np.linspace(0, 1, 4), kind=kind)
    mesh = _distorted(mesh) if kind in ("hex", "quad") else mesh
    d = Discretisation(mesh, order)
    dim = d.dim
    H = np.array([[1.0, 0.4, -0.3], [0.2, -0.7, 0.5], [0.1, 0.3, 0.6]])[:dim, :dim] * 1e-3
    x = d.dof_coordinates()
    boundary = d.facet_scalar_dofs(mesh.boundary_facets())
    u_exact = (x @ H.T).ravel()  # dof = dim * node + component
    bc = Dirichlet(d.vector_dofs(boundary), u_exact[d.vector_dofs(boundary)])
    mat = material.LinearElastic(2e4, 0.3)
    sol = NewtonSolver(d, mat, [bc], options=SolverOptions(tol=1e-12)).run(1)
    interior = np.setdiff1d(np.arange(d.ndofs), bc.dofs)
    np.testing.assert_allclose(sol.u[interior], u_exact[interior], atol=1e-14)
    eps = np.zeros((3, 3))
    eps[:dim, :dim] = 0.5 * (H + H.T)
    np.testing.assert_allclose(sol.state["strain"], np.broadcast_to(eps, sol.state["strain"].shape), atol=1e-15)


def _plastic_cube(n=2):
    mesh = _distorted(box(1.0, 1.0, 1.0, n, n, n), 0.05)
    d = Discretisation(mesh, 1)
    b = mesh.boundaries
    bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
    bcs = [Dirichlet(d.vector_dofs(bot), 0.0, name="bottom"),
           Dirichlet(d.vector_dofs(top, [0]), 0.02, name="shear"),
           Dirichlet(d.vector_dofs(top, [2]), -0.004, name="top")]
    return d, bcs


def test_taylor_remainder_of_the_assembled_tangent_has_slope_two():
    d, bcs = _plastic_cube()
    mat = material.VonMises(1e4, 0.3, 20.0, 500.0)
    s = NewtonSolver(d, mat, bcs)
    s.run(2)  # a plastic state
    rng = np.random.default_rng(3)
    du0 = rng.normal(scale=2e-3, size=d.ndofs)
    v = rng.normal(scale=1e-3, size=d.ndofs)
    r0, D0 = s._evaluate(du0, s.t)
    assert (s.points.trial_state["eq_plastic_strain"] > s.points.state["eq_plastic_strain"]).mean() > 0.5
    Kv = d.stiffness(D0) @ v
    hs = np.array([1e-1, 5e-2, 2.5e-2, 1.25e-2])
    rem = np.array([np.linalg.norm(s._evaluate(du0 + h * v, s.t)[0] - r0 - h * Kv) for h in hs])
    slopes = np.diff(np.log(rem)) / np.diff(np.log(hs))
    print("Taylor remainders", rem, "slopes", slopes)
    assert np.all(slopes > 1.9) and np.all(slopes < 2.2)
    rem1 = np.array([np.linalg.norm(s._evaluate(du0 + h * v, s.t)[0] - r0) for h in hs])
    assert np.all(np.diff(np.log(rem1)) / np.diff(np.log(hs)) < 1.1)  # without the tangent: slope 1


def test_newton_converges_quadratically_on_a_plastic_step():
    d, bcs = _plastic_cube(3)
    mat = material.VonMises(1e4, 0.3, 20.0, 200.0)
    sol = NewtonSolver(d, mat, bcs, options=SolverOptions(tol=1e-12, line_search=0)).run(2)
    res = np.array(sol.residuals[-1])
    print("Newton residual sequence (plastic step):", res)
    assert sol.state["eq_plastic_strain"].min() > 0  # every point plastic
    assert len(res) <= 8
    # quadratic: log r_{k+1} / log r_k >= 1.7 once in the asymptotic range
    tail = res[(res < 1e-2) & (res > 1e-14)]
    assert tail.size >= 2
    rates = np.log(tail[1:]) / np.log(tail[:-1])
    assert np.all(rates > 1.7), rates


def _lame_error(n_theta):
    a, b, p, E, nu = 1.0, 2.0, 10.0, 1e4, 0.3
    import skfem

    m = rectangle(np.linspace(a, b, 7), np.linspace(0, np.pi / 2, n_theta + 1))
    r, th = m.p
    mesh = skfem.MeshQuad(np.vstack([r * np.cos(th), r * np.sin(th)]), m.t)
    mesh = mesh.with_boundaries({
        "inner": lambda x: np.abs(np.hypot(x[0], x[1]) - a) < 0.05,
        "x0": lambda x: np.abs(x[0]) < 1e-9, "y0": lambda x: np.abs(x[1]) < 1e-9})
    d = Discretisation(mesh, 2)
    bcs = [Dirichlet(d.vector_dofs(d.facet_scalar_dofs(mesh.boundaries["x0"]), [0]), 0.0),
           Dirichlet(d.vector_dofs(d.facet_scalar_dofs(mesh.boundaries["y0"]), [1]), 0.0)]
    f = d.pressure_force(mesh.boundaries["inner"], p)
    sol = NewtonSolver(d, material.LinearElastic(E, nu), bcs, f_ramp=f).run(1)
    x = d.dof_coordinates()
    rr = np.hypot(x[:, 0], x[:, 1])
    ur = (sol.u.reshape(-1, 2) * x).sum(axis=1) / rr
    # closed form (plane strain): u_r = (1+nu) a^2 p / (E (b^2 - a^2)) ((1 - 2 nu) r + b^2 / r)
    exact = (1 + nu) * a**2 * p / (E * (b**2 - a**2)) * ((1 - 2 * nu) * rr + b**2 / rr)
    return np.abs(ur - exact).max() / exact.max()


def test_lame_cylinder_internal_pressure_matches_closed_form():
    """Plane-strain thick cylinder a = 1, b = 2 under internal pressure, quarter model, Q2 elements.

    The straight-sided mesh approximates the circles to O(h^2): the error must be small and fall
    about 4x when the angular spacing halves.
    """
    e8, e16 = _lame_error(8), _lame_error(16)
    print("Lame cylinder: max relative error of u_r", e8, e16)
    assert e16 < 2e-3
    assert e8 / e16 > 3.5


class _StepLimited:
    """Test double: a law that fails (STATUS_FAILED) on increments larger than ``limit``."""

    def __init__(self, inner, limit):
        self.inner, self.limit = inner, limit

    def initial_state(self, n, stress=None, *, element_size=None):
        return self.inner.initial_state(n, stress=stress)

    def update(self, d_strain, stress, state):
        s, st, D = self.inner.update(d_strain, stress, state)
        size = np.abs(d_strain).max(axis=(1, 2))
        bad = size > self.limit
        st["status"] = np.where(bad, STATUS_FAILED, st["status"]).astype(np.int8)
        st["step_ratio"] = np.where(bad, 0.9 * self.limit / np.maximum(size, 1e-300), 1.0)
        return np.where(bad[:, None, None], stress, s), st, D


def test_cutback_recovers_from_a_too_large_step():
    d, bcs = _plastic_cube()
    vm = material.VonMises(1e4, 0.3, 20.0, 200.0)
    fine = NewtonSolver(d, vm, bcs).run(40)
    coarse = NewtonSolver(d, _StepLimited(vm, 2e-3), bcs).run(1, dt_max=1.0)
    assert coarse.completed
    assert coarse.history["cutbacks"].max() >= 1 and len(coarse.history) > 2
    # path-dependent plasticity: the cut run agrees with a fine run to the step-size error
    r_fine, r_cut = fine.history["top_reaction"][-1], coarse.history["top_reaction"][-1]
    assert abs(r_cut - r_fine) < 0.02 * abs(r_fine)


def _steps(sol):
    """(size, cut-backs, Newton iterations) of each converged step of a run."""
    h = sol.history
    return np.diff(h["load_factor"]), np.asarray(h["cutbacks"][1:]), np.asarray(h["iterations"][1:])


def test_the_step_grows_only_after_two_easy_steps_without_a_cut_back():
    """SolverOptions.easy_steps: dt grows by ``grow`` only after that many consecutive converged steps that
    were not cut back and took at most ``easy_iter`` iterations. On a law that fails above a strain
    increment, growth after every easy step (easy_steps = None, the default: the earlier rule) grows the
    step right after a cut-back, back toward the size that failed, and is cut back more often; and a run
    stopped between two easy steps and resumed from its run state takes the same steps."""
    d, bcs = _plastic_cube()
    vm = material.VonMises(1e4, 0.3, 20.0, 200.0)
    runs = {k: NewtonSolver(d, _StepLimited(vm, 2e-3), bcs, options=SolverOptions(easy_steps=k)).run(2)
            for k in (None, 2)}
    after = {}
    for k, sol in runs.items():
        assert sol.completed
        size, cuts, iters = _steps(sol)
        grew = np.flatnonzero(size[1:] > size[:-1] * (1 + 1e-9)) + 1
        grew = grew[grew < len(size) - 1]  # (the last step is cut to the end of the loading)
        np.testing.assert_allclose(size[grew], 1.5 * size[grew - 1], rtol=1e-12)
        after[k] = [(cuts[j - 1] == 0, j >= 2 and cuts[j - 2] == 0 and iters[j - 2] <= 6) for j in grew]
    assert after[2] and all(a and b for a, b in after[2])
    assert any(not a for a, b in after[None])  # the earlier rule grows the step after a cut-back one
    assert _steps(runs[2])[1].sum() == 3 and _steps(runs[None])[1].sum() == 6
    with pytest.raises(ValueError, match="easy_steps = 0: allowed None or integers >= 1"):
        SolverOptions(easy_steps=0)
    # stopped after step 3 (the first easy step after a cut-back one) and resumed from its run state
    solver = NewtonSolver(d, _StepLimited(vm, 2e-3), bcs, options=SolverOptions(easy_steps=2))
    first = solver.run(2, after_step=lambda s, state: "stop" if state["n_step"] == 3 else None)
    assert not first.completed and solver.run_state["easy_streak"] == 1
    resumed = solver.run(2, resume={**solver.run_state, "history": solver.run_state["history"].rows()})
    np.testing.assert_allclose(_steps(resumed)[0], _steps(runs[2])[0], rtol=1e-12)


class _RateRecorder(_StepLimited):
    """Test double: a rate-dependent law (``rate_dependent``) that records the step size it is given."""

    rate_dependent = True

    def __init__(self, inner, limit):
        super().__init__(inner, limit)
        self.fractions = []

    def update(self, d_strain, stress, state, step_fraction=1.0):
        self.fractions.append(step_fraction)
        return super().update(d_strain, stress, state)


def test_a_rate_dependent_law_gets_the_step_size_in_nominal_steps():
    """The solver passes a rate-dependent law each step's size over the nominal step: 1 for the nominal
    steps, less after a cut-back (the CPA law's step stabilisation relaxes over one nominal step); a law
    that is not rate dependent gets no such input (the element drivers' laws)."""
    d, bcs = _plastic_cube()
    law = _RateRecorder(material.VonMises(1e4, 0.3, 20.0, 200.0), 2e-3)
    sol = NewtonSolver(d, law, bcs).run(4)
    assert sol.completed and sol.history["cutbacks"].max() >= 1
    f = np.array(law.fractions)
    assert f.max() == 1.0 and 0.0 < f.min() <= 0.5 and set(np.round(f, 12)) > {1.0}
    assert NewtonSolver(d, _StepLimited(law.inner, 1.0), bcs).run(2).completed  # no step_fraction keyword


def test_a_rate_dependent_law_with_a_relaxation_time_gets_the_step_in_it():
    """A law with a ``relaxation_time`` tau gets each step's load-factor size over tau, whatever the
    nominal step (material.base.step_fraction); the Composite and the undrained wrapper pass it on, and a
    Composite whose rate-dependent laws have different relaxation times is refused."""
    from material.composite import Composite
    from material.undrained import Undrained

    d, bcs = _plastic_cube()
    law = _RateRecorder(material.VonMises(1e4, 0.3, 20.0, 200.0), 2e-3)
    law.relaxation_time = 0.1
    sol = NewtonSolver(d, law, bcs).run(4)  # nominal step 0.25: 2.5 relaxation times
    assert sol.completed and sol.history["cutbacks"].max() >= 1
    f = np.array(law.fractions)
    assert f.max() == pytest.approx(2.5) and f.min() <= 1.25
    assert Undrained(law, 1e5).relaxation_time == 0.1
    n = d.n_points
    assert Composite([law, law.inner], np.zeros(n, dtype=int)).relaxation_time == 0.1
    other = _RateRecorder(law.inner, 2e-3)
    other.relaxation_time = 0.2
    with pytest.raises(ValueError, match=r"laws: relaxation times \[0.1, 0.2\] differ"):
        Composite([law, other], np.zeros(n, dtype=int))


def test_clean_stop_keeps_the_converged_steps(tmp_path):
    d, bcs = _plastic_cube()
    vm = material.VonMises(1e4, 0.3, 20.0, 200.0)

    class FailsLate(_StepLimited):
        def update(self, d_strain, stress, state):
            s, st, D = self.inner.update(d_strain, stress, state)
            if np.abs(st["strain"]).max() > 0.012:  # cannot go beyond this strain
                st["status"] = np.full(len(s), STATUS_FAILED, np.int8)
                st["step_ratio"] = np.full(len(s), 0.5)
            return s, st, D

    w = SeriesWriter(tmp_path / "run", d)
    sol = NewtonSolver(d, FailsLate(vm, 1.0), bcs, options=SolverOptions(max_cuts=3)).run(10, writer=w)
    assert not sol.completed and "3 cut-backs did not help" in sol.stop_reason
    assert len(sol.history) >= 2 and 0 < sol.history["load_factor"][-1] < 1
    # a smallest step larger than one cut-back allows: the message names dt_min, not the cut-backs
    short = NewtonSolver(d, FailsLate(vm, 1.0), bcs, options=SolverOptions(dt_min=0.06)).run(10)
    assert not short.completed and "below dt_min = 0.06" in short.stop_reason
    import meshio

    entries = read_pvd(tmp_path / "run" / "solution.pvd")
    assert len(entries) == len(sol.history)
    last = meshio.read(entries[-1][1])
    np.testing.assert_allclose(last.point_data["displacement"][:, 0].max(), sol.u.reshape(-1, 3)[:, 0].max(), rtol=1e-12)


def test_interrupted_run_leaves_a_readable_series(tmp_path):
    import meshio
    import pyvista as pv

    d, bcs = _plastic_cube()
    vm = material.VonMises(1e4, 0.3, 20.0, 200.0)
    calls = []

    def interrupt(solver):
        calls.append(solver.t)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return {}

    w = SeriesWriter(tmp_path / "run", d)
    with pytest.raises(KeyboardInterrupt):
        NewtonSolver(d, vm, bcs).run(10, writer=w, observers=[interrupt])
    entries = read_pvd(tmp_path / "run" / "solution.pvd")
    assert [round(t, 10) for t, _ in entries] == [0.0, 0.1, 0.2]
    m = meshio.read(entries[-1][1])
    assert m.point_data["stress"].shape == (m.points.shape[0], 9)
    assert m.cell_data["stress"][0].shape == (d.nelems, 9)
    # 9-component tensor is symmetric, row-major
    s = m.cell_data["stress"][0].reshape(-1, 3, 3)
    np.testing.assert_allclose(s, np.swapaxes(s, 1, 2), atol=1e-9)
    reader = pv.get_reader(str(tmp_path / "run" / "solution.pvd"))
    assert len(reader.time_values) == 3
    reader.set_active_time_value(reader.time_values[-1])
    grid = reader.read()[0]
    np.testing.assert_allclose(np.asarray(grid.point_data["displacement"]), m.point_data["displacement"])
    hist = History.read_csv(tmp_path / "run" / "history.csv")
    assert len(hist) == 3 and hist.descriptions["load_factor"].startswith("load factor")
    # any CSV reader that skips the commented header reads the numbers
    import csv

    with open(tmp_path / "run" / "history.csv") as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    assert len(rows) == 3 and float(rows[-1]["load_factor"]) == hist["load_factor"][-1]


def test_output_projection_round_trip(tmp_path):
    """Uniform strain written and read back: nodal L2 projection exact, cell averages dx-weighted."""
    import meshio

    d, _ = _plastic_cube()
    H = np.array([[1.0, 0.3, 0.0], [0.0, -0.5, 0.2], [0.1, 0.0, 0.4]]) * 1e-3
    x = d.dof_coordinates()
    bdofs = d.vector_dofs(d.facet_scalar_dofs(d.mesh.boundary_facets()))
    bc = Dirichlet(bdofs, (x @ H.T).ravel()[bdofs])
    w = SeriesWriter(tmp_path / "run", d)
    sol = NewtonSolver(d, material.LinearElastic(1e4, 0.25), [bc]).run(1, writer=w)
    m = meshio.read(read_pvd(w.pvd_path)[-1][1])
    np.testing.assert_allclose(m.point_data["stress"], np.broadcast_to(sol.stress[0].ravel(), (m.points.shape[0], 9)),
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(m.cell_data["strain"][0][:, [0, 4, 8, 1]],
                               np.broadcast_to(0.5 * (H + H.T).ravel()[[0, 4, 8, 1]], (d.nelems, 4)), atol=1e-15)
    np.testing.assert_allclose(m.point_data["displacement"], (m.points @ H.T), atol=1e-15)


def test_bad_boundary_conditions_and_materials():
    d, bcs = _plastic_cube()
    with pytest.raises(ValueError, match="names no nodes"):
        Dirichlet(np.array([], dtype=int), 0.0, name="top")
    with pytest.raises(ValueError, match="out of range"):
        NewtonSolver(d, material.LinearElastic(1e4, 0.3), [Dirichlet([d.ndofs + 5], 0.0)])
    with pytest.raises(ValueError, match="lacks the method"):
        NewtonSolver(d, object(), bcs)
    with pytest.raises(ValueError, match="linear_solver"):
        SolverOptions(linear_solver="mumps")


def test_linear_solvers_agree():
    d, bcs = _plastic_cube(3)
    vm = material.VonMises(1e4, 0.3, 20.0, 200.0)
    ref = NewtonSolver(d, vm, bcs).run(2)
    for method in ("amg-gmres", "ilu-gmres"):
        sol = NewtonSolver(d, vm, bcs, options=SolverOptions(linear_solver=method)).run(2)
        np.testing.assert_allclose(sol.u, ref.u, rtol=1e-6, atol=1e-9)


def test_the_direct_solve_pivots_off_a_small_diagonal_and_reports_a_singular_matrix_as_nan():
    """The diagonal is preferred as pivot only while it is at least DIAG_PIVOT_THRESHOLD of its column's
    largest entry. Here the minimum-degree ordering takes the tiny diagonal's column first; taking that
    diagonal as pivot (threshold 0) gives x_0 = 0 instead of 1."""
    import scipy.sparse as sp

    from femgran.solver import DIAG_PIVOT_THRESHOLD, direct_solve

    assert 0.0 < DIAG_PIVOT_THRESHOLD < 1.0
    tiny = sp.csr_matrix(np.array([[1e-20, 1, 0, 0], [1, 1, 1, 1], [0, 1, 3, 1], [0, 1, 1, 3.0]]))
    np.testing.assert_allclose(direct_solve(tiny, tiny @ np.ones(4)), np.ones(4), rtol=1e-14)
    rng = np.random.default_rng(3)
    n = 60
    A = sp.random(n, n, density=0.1, random_state=rng, format="csr")
    A = (A + A.T + sp.eye(n)).tolil()  # structurally symmetric, as the solver's matrices
    A[0, 0] = 0.0
    A[0, 1] = A[1, 0] = 2.0
    A = A.tocsr()
    x_true = rng.standard_normal(n)
    x = direct_solve(A, A @ x_true)
    assert np.linalg.norm(x - x_true) / np.linalg.norm(x_true) < 1e-11
    singular = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    assert np.isnan(direct_solve(singular, np.array([1.0, 1.0]))).all()


def test_element_size_reaches_a_regularised_material():
    """The solver hands each point's element size to a material whose initial_state takes it (the
    crack-band scaling of CPA softening) and leaves other materials alone."""
    from femgran.assembly import Discretisation
    from femgran.mesh import rectangle
    from femgran.state import PointState
    from material import CPAModel, LinearElastic, load_preset

    m = rectangle(np.linspace(0, 0.2, 5), np.linspace(0, 0.1, 3))  # 0.05 x 0.05 m quads
    d = Discretisation(m, 1)
    h = d.element_size()
    np.testing.assert_allclose(h, 0.05, rtol=1e-12)
    cpa = CPAModel(load_preset("ottawa_c109").replace(zeta=1.05, softening_slip=0.01))
    ps = PointState(cpa, d.n_points, -100 * np.eye(3), element_size=h)
    np.testing.assert_allclose(ps.state["element_size"], 0.05)
    np.testing.assert_allclose(cpa._softening_scale(ps.state, d.n_points), 0.01 * 0.006 / 0.05)
    PointState(LinearElastic(6000.0, 0.3), d.n_points, None, element_size=h)  # no such keyword: not passed
    plain = CPAModel(cpa.params, regularise=False)  # the mesh-dependent reference ignores h
    np.testing.assert_allclose(plain._softening_scale(ps.state, d.n_points), 0.01)


class _StiffTangent:
    """Test double: a law whose tangent is ``factor`` x the true one (1.5: Newton converges only
    linearly; 0.5: every Newton correction overshoots by exactly its own size, a 2-cycle)."""

    def __init__(self, inner, factor=1.5):
        self.inner, self.factor = inner, factor

    def initial_state(self, n, stress=None, *, element_size=None):
        return self.inner.initial_state(n, stress=stress)

    def update(self, d_strain, stress, state):
        s, st, D = self.inner.update(d_strain, stress, state)
        return s, st, self.factor * D


def test_a_step_is_accepted_only_below_the_tolerance():
    """A law whose tangent is 1.5 x the true one converges only linearly: with 4 iterations allowed the
    step is cut back (the residual never reaches tol), and no step of a completed run is above tol."""
    d, bcs = _plastic_cube()
    mat = _StiffTangent(material.VonMises(1e4, 0.3, 20.0, 200.0))
    strict = NewtonSolver(d, mat, bcs, options=SolverOptions(max_iter=4, max_cuts=1, line_search=0)).run(2)
    assert not strict.completed and "no convergence in 4 iterations" in strict.stop_reason
    assert "last residuals" in strict.stop_reason
    patient = NewtonSolver(d, mat, bcs, options=SolverOptions(max_iter=60, line_search=0)).run(2)
    assert patient.completed and patient.history["residual"].max() <= patient.history["residual"][0] + 1e-8


def test_line_search_halves_a_twice_too_long_step_and_never_takes_a_non_descent_step(tmp_path):
    """Elastic cube, tangent 0.5 x the true one: every Newton correction is twice the exact one, so the
    full step leaves |r| unchanged (the logged residual is relative to the reaction, which changes). The quadratic model through |r(0)|, its slope and |r(1)| = |r(0)|
    puts the minimum at s = 1/2, which is the exact solution: one rejected trial, then convergence.
    A tangent with the wrong sign gives no decrease at any step length: the step fails with a message
    instead of taking an uphill step, and the run stops cleanly."""
    from femgran.diagnostics import NewtonLog

    d, bcs = _plastic_cube()
    log = NewtonLog()
    sol = NewtonSolver(d, _StiffTangent(material.LinearElastic(1e4, 0.3), 0.5), bcs, log=log,
                       options=SolverOptions(predictor="none")).run(1)
    assert sol.completed
    t = log.table()
    assert list(t["accepted"]) == [1, 0, 1] and t["line_search"][1:].tolist() == pytest.approx([1.0, 0.5], abs=1e-12)
    assert t["residual"][2] < 1e-12
    uphill = NewtonSolver(d, _StiffTangent(material.LinearElastic(1e4, 0.3), -1.0), bcs,
                          options=SolverOptions(max_cuts=1, predictor="none")).run(1)
    assert not uphill.completed and "line search: no decrease" in uphill.stop_reason


class _FailsBeyond(_StiffTangent):
    """Test double: ``_StiffTangent`` whose update fails (status FAILED, the committed stress back) at the
    points whose strain increment exceeds ``limit`` in any component: a branch that ends."""

    def __init__(self, inner, factor, limit):
        super().__init__(inner, factor)
        self.limit = limit

    def update(self, d_strain, stress, state):
        s, st, D = super().update(d_strain, stress, state)
        bad = np.abs(d_strain).max(axis=(1, 2)) > self.limit
        st["status"] = np.where(bad, STATUS_FAILED, st["status"])
        st["step_ratio"] = np.where(bad, 0.5, st.get("step_ratio", np.ones(len(bad))))
        return np.where(bad[:, None, None], stress, s), st, D


def test_a_stalled_line_search_is_probed_along_its_direction_at_the_stop():
    """``NewtonSolver.stalled`` keeps the last failed line search; ``stall_report`` evaluates the material
    along it. An uphill tangent with every update solvable: the sentence says so. The same with updates that
    fail beyond a strain of 2e-6 (the prescribed step reaches 1e-4): it names the first failing s and a point,
    and says nothing of a second branch (the full step fails too). A try that ends otherwise leaves no probe."""
    from femgran.diagnostics import stall_report

    d, bcs = _plastic_cube()
    opts = SolverOptions(max_cuts=0, predictor="none", line_search=4)
    solver = NewtonSolver(d, _StiffTangent(material.LinearElastic(1e4, 0.3), -1.0), bcs, options=opts)
    assert not solver.run(1).completed and solver.stalled is not None
    assert solver.stalled[2] == 2.0 ** -4
    note = stall_report(solver)
    assert "every point's update has a solution" in note and "tried down to s = 0.062" in note
    folding = NewtonSolver(d, _FailsBeyond(material.LinearElastic(1e4, 0.3), -1.0, 2e-6), bcs, options=opts)
    folding.step_fraction = 1.0
    folding.stalled = (np.zeros(d.ndofs), solver.stalled[1], 2.0 ** -4)
    note = stall_report(folding)
    assert "fails on its branch from the start of the step beyond s = " in note
    assert "two solutions" not in note
    s_fail = float(note.split("beyond s = ")[1].split(" ")[0])
    assert 0.0 < s_fail <= 2.0 ** -4
    fine = NewtonSolver(d, material.LinearElastic(1e4, 0.3), bcs, options=opts)
    assert fine.run(1).completed and fine.stalled is None and stall_report(fine) == ""


def test_newton_log_records_switching_points_and_the_convergence_rate(tmp_path):
    """The log of a von Mises cube that turns plastic all at once: every point loads, none switches
    between iterations, the accepted residuals converge quadratically (rate near 2), and the CSV holds
    every evaluation, line-search trials included."""
    from femgran.diagnostics import COLUMNS, NewtonLog

    d, bcs = _plastic_cube()
    log = NewtonLog(tmp_path / "log.csv")
    sol = NewtonSolver(d, material.VonMises(1e4, 0.3, 20.0, 200.0), bcs, log=log).run(2)
    assert sol.completed
    t = log.table()
    assert len(log.rows) == sum(len(r) for r in sol.residuals) + (t["accepted"] == 0).sum()
    assert np.nanmax(t["loading_points"]) == d.n_points
    switched = t["points_switched"][np.isfinite(t["points_switched"])]
    assert switched.size and (switched == 0).all()
    rates = t["rate"][np.isfinite(t["rate"])]
    assert rates.size and rates.max() > 1.8  # quadratic convergence of the reference law
    from material.table import read_table

    back = read_table(tmp_path / "log.csv")
    assert back.columns == list(COLUMNS) and len(back) == len(log.rows) and back.descriptions["rate"]
    assert log.summary()["accepted_iterations"] == int(t["accepted"].sum())
    assert log.summary()["points_switched_total"] == 0 and log.summary()["planes_switched_total"] == 0


def test_full_step_overshoot_is_nil_for_a_linear_law_and_names_the_point_that_left_the_tangent():
    """femgran.diagnostics.full_step_overshoot: with the stress the tangent predicts nothing is missed; with
    one point's stress changed it is that point alone, with its pressure and the planes it unloaded."""
    from femgran.diagnostics import full_step_overshoot

    d, _ = _plastic_cube()
    n = d.n_points
    rng = np.random.default_rng(3)
    D = material.LinearElastic(1e4, 0.3).update(np.zeros((n, 3, 3)), np.zeros((n, 3, 3)),
                                                 material.LinearElastic(1e4, 0.3).initial_state(n))[2]
    sig0 = -50.0 * np.eye(3) + rng.normal(0.0, 5.0, (n, 3, 3))
    sig0 = 0.5 * (sig0 + sig0.transpose(0, 2, 1))
    deps = rng.normal(0.0, 1e-4, (n, 3, 3))
    deps = 0.5 * (deps + deps.transpose(0, 2, 1))
    sig1 = sig0 + np.einsum("nijkl,nkl->nij", D, deps)
    out = full_step_overshoot(d.dx, sig0, D, sig1, deps)
    assert out["overshoot_points"] == 0 and not out["share"].any() and np.isnan(out["overshoot_unloading"])
    assert np.isnan(out["overshoot_planes"]) and np.isnan(out["overshoot_point"])
    k = 5
    bump = np.zeros((n, 3, 3))
    bump[k] = np.diag([3.0, -1.0, 2.0])
    bump[k + 1] = 0.1 * bump[k]  # a tenth as much at another point of the same volume class
    loading0, loading1 = np.zeros((n, 4), bool), np.zeros((n, 4), bool)
    loading0[k, :3] = True
    loading1[k, 2:] = True  # planes 0 and 1 stop loading, 3 starts
    out = full_step_overshoot(d.dx, sig0, D, sig1 + bump, deps, loading0, loading1)
    v = d.dx.ravel()
    assert out["overshoot_points"] == 1 and out["share"].argmax() == k and out["overshoot_point"] == k
    assert out["share"][k] == pytest.approx(v[k] / (v[k] + 0.1 * v[k + 1]), rel=1e-9)
    assert out["overshoot_pressure"] == pytest.approx(-np.trace(sig0[k]) / 3.0)
    assert out["overshoot_unloading"] == 2 and out["overshoot_planes"] == 3
    assert full_step_overshoot(d.dx, sig0, object(), sig1, deps) is None  # a coupled tangent: not measured


def test_the_newton_log_measures_the_full_steps_by_their_residual_ratio():
    """Every full Newton step of the plastic cube has its overshoot in the log, the residual of the full
    step over the iterate's (the force the tangent did not predict over the force it did); the predictor
    rows have none, and the summary counts them."""
    from femgran.diagnostics import NewtonLog

    d, bcs = _plastic_cube()
    log = NewtonLog()
    # a reference force above the reaction, so that the logged relative residuals are in one unit
    options = SolverOptions(force_floor=1e3, tol=1e-12)
    assert NewtonSolver(d, material.VonMises(1e4, 0.3, 20.0, 200.0), bcs, log=log, options=options).run(2).completed
    t = log.table()
    full = (t["line_search"] == 1.0) & (t["iteration"] > 0)
    assert full.sum() >= 4 and np.isfinite(t["overshoot"][full]).all()
    assert np.isnan(t["overshoot"][t["iteration"] == 0]).all()
    previous = np.flatnonzero(full) - 1  # the iterate each full step started from (no rejected trials here)
    assert np.allclose(t["overshoot"][full], t["residual"][full] / t["residual"][previous], rtol=1e-12)
    assert (t["overshoot"][full] < 1.0).all() and (t["overshoot_points"][full] >= 1).all()
    summary = log.summary()
    assert summary["full_steps"] == int(full.sum()) and summary["full_steps_rejected"] == 0


def test_history_reads_back_what_it_wrote(tmp_path):
    from femgran.solver import History

    d, bcs = _plastic_cube()
    sol = NewtonSolver(d, material.VonMises(1e4, 0.3, 20.0, 200.0), bcs).run(2)
    sol.history.to_csv(tmp_path / "h.csv")
    back = History.read_csv(tmp_path / "h.csv")
    assert back.columns == sol.history.columns
    for c in back.columns:
        np.testing.assert_array_equal(back[c], sol.history[c])  # repr of floats: exact
    (tmp_path / "bad.csv").write_text("# note\na,b\n1,2\n3\n")
    with pytest.raises(ValueError, match="data row 2 has 1 values for 2 columns"):
        History.read_csv(tmp_path / "bad.csv")


def test_extrapolating_predictor_reaches_the_same_states():
    """predictor="extrapolate" (the last increment scaled to the step) is only a first guess: a von Mises
    cube loaded in 6 steps ends in the same state as with the tangent predictor."""
    d, bcs = _plastic_cube()
    mat = material.VonMises(1e4, 0.3, 20.0, 200.0)
    ends = {}
    for pred in ("tangent", "extrapolate"):
        sol = NewtonSolver(d, mat, bcs, options=SolverOptions(predictor=pred)).run(6, fixed_steps=True)
        assert sol.completed
        ends[pred] = sol
    np.testing.assert_allclose(ends["extrapolate"].stress, ends["tangent"].stress, atol=1e-6)
    # the guesses differ (the first step of both is the tangent predictor)
    assert ends["extrapolate"].residuals[0][0] == ends["tangent"].residuals[0][0]
    assert ends["extrapolate"].residuals[2][0] != ends["tangent"].residuals[2][0]
    with pytest.raises(ValueError, match="predictor = 'secant'"):
        SolverOptions(predictor="secant")


def test_kinks_along_finds_where_a_point_starts_to_yield():
    """Simple shear of a von Mises point from zero stress: elastic up to tau = sigma_y / sqrt(3), then
    perfectly plastic. Along the path the stress rate drops from G gamma to zero at that s (to a grid
    interval); an elastic point has no kink. Through the solver: the cube's first step direction."""
    from femgran.diagnostics import kinks_along, solver_kinks_along

    E, nu, sy = 1e4, 0.3, 20.0
    G = E / (2 * (1 + nu))
    gamma = 5e-3
    direction = np.zeros((2, 3, 3))
    direction[:, 0, 1] = direction[:, 1, 0] = gamma / 2
    s = np.linspace(0.0, 1.0, 201)
    vm = material.VonMises(E, nu, sy, 0.0)
    out = kinks_along(vm, np.zeros((2, 3, 3)), vm.initial_state(2), np.zeros((2, 3, 3)), direction, s)
    s_yield = sy / np.sqrt(3) / (G * gamma)
    assert 0.2 < s_yield < 0.9
    np.testing.assert_allclose(out["s_kink"], s_yield, atol=0.005 + 1e-12)
    assert (out["slope_jump"] > 0.5).all() and out["rate"] == pytest.approx(G * gamma, rel=1e-9)
    el = material.LinearElastic(E, nu)
    smooth = kinks_along(el, np.zeros((2, 3, 3)), el.initial_state(2), np.zeros((2, 3, 3)), direction, s)
    assert smooth["slope_jump"].max() < 1e-9
    with pytest.raises(ValueError, match="equally spaced"):
        kinks_along(vm, np.zeros((2, 3, 3)), vm.initial_state(2), np.zeros((2, 3, 3)), direction, [0, 0.1, 0.5])
    d, bcs = _plastic_cube()
    solver = NewtonSolver(d, vm, bcs)
    ddu = np.zeros(d.ndofs)
    ddu[solver.constrained] = solver.prescribed(1.0)  # the boundary displacements alone: the cube yields
    probe = solver_kinks_along(solver, np.zeros(d.ndofs), ddu, np.linspace(0, 1, 21))
    assert probe["slope_jump"].shape == (d.n_points,) and (probe["slope_jump"] > 0.5).any()


def test_zero_step_drift_shows_whether_a_cut_back_can_reach_the_committed_state():
    """The stabilised CPA law, loaded in nominal steps near failure, relaxes its overstress over a nominal
    step with no strain, and by an amount proportional to a shorter step; the thesis's law returns the
    committed stress to round-off."""
    from femgran.diagnostics import zero_step_drift
    from material.anisotropy import axes_from_alpha

    de = np.array([[0.8e-3, 1e-4, 2e-4], [1e-4, 0.6e-3, -1.5e-4], [2e-4, -1.5e-4, -2e-3]])
    drift = {}
    for mu in (0.1, 0.0):
        law = material.CPAModel("ottawa_c109", axes=axes_from_alpha(30.0), stabilisation=mu)
        sig = np.repeat(-100.0 * np.eye(3)[None], 2, axis=0)
        st = law.initial_state(2, stress=sig)
        for _ in range(25):
            sig, st, _ = law.update(np.repeat(de[None], 2, axis=0), sig, st, tangent=False)
        drift[mu] = zero_step_drift(law, sig, st, step_fractions=(1.0, 2.0 ** -8, 2.0 ** -16))
    assert drift[0.1][1.0].min() > 1e-4
    ratio = drift[0.1][2.0 ** -16] / drift[0.1][2.0 ** -8]
    assert (0.5 * 2.0 ** -8 < ratio).all() and (ratio < 2 * 2.0 ** -8).all()  # proportional to the step
    assert max(d.max() for d in drift[0.0].values()) < 1e-12
