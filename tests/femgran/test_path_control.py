"""Path following through a snap-back (femgran.solver.PathControl) against its closed form."""

import numpy as np
import pytest

from femgran.assembly import Discretisation
from femgran.mesh import name_box_boundaries, rectangle
from femgran.solver import Dirichlet, NewtonSolver, PathControl, SolverOptions
from material import VonMises, driver
from material.composite import Composite

E, NU = 20000.0, 0.3
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
L, HEIGHT, N = 1.0, 0.1, 20  # a bar of 20 elements; element 10 is weaker and softens
h = L / N


def _bar():
    m = name_box_boundaries(rectangle(np.linspace(0, L, N + 1), np.linspace(0, HEIGHT, 2)))
    d = Discretisation(m, 1, "standard")
    strong = VonMises(E, NU, 100.0, hardening_kPa=-2 * G)
    weak = VonMises(E, NU, 90.0, hardening_kPa=-2 * G)
    centres = m.p[0, m.t].mean(axis=0)
    is_weak = (np.abs(centres - (N // 2 + 0.5) * h) < 0.5 * h).astype(np.int64)
    law = Composite([strong, weak], np.repeat(is_weak, d.nqp))
    left = d.facet_scalar_dofs(m.boundaries["left"])
    right = d.facet_scalar_dofs(m.boundaries["right"])
    every = np.arange(d.ndofs // 2)
    # uniaxial strain along x (u_y = 0 everywhere): every element is homogeneous, the bar is a chain of springs
    bcs = [Dirichlet(d.vector_dofs(every, [1]), 0.0, ramp=False),
           Dirichlet(d.vector_dofs(left, [0]), 0.0, ramp=False),
           Dirichlet(d.vector_dofs(right, [0]), 0.01, name="end")]
    nodes_x = m.p[0]
    a = np.flatnonzero(np.isclose(nodes_x, (N // 2) * h))
    b = np.flatnonzero(np.isclose(nodes_x, (N // 2 + 1) * h))
    opening = PathControl(np.concatenate([d.vector_dofs(b, [0]), d.vector_dofs(a, [0])]),
                          np.concatenate([np.full(len(b), 1 / len(b)), np.full(len(a), -1 / len(a))]),
                          name="weak_elongation_m")
    return d, law, bcs, opening


def test_path_control_follows_the_snap_back_of_a_softening_bar():
    """The weak element's elongation grows step by step; the load factor follows it up to the peak and back
    down the snap-back. Closed form: the weak element's own stress-strain curve (the element driver, uniaxial
    strain) in series with the elastic rest, u_end = c + (L - h) sigma / M, M = K + 4 G / 3."""
    d, law, bcs, opening = _bar()
    solver = NewtonSolver(d, law, bcs, options=SolverOptions(line_search=0))
    sol = solver.run(steps=40, control=opening, control_end=8.5e-3 * h,
                     observers=[lambda s: {"force": -float(np.sum(s.reaction[bcs[1].dofs]))}])
    assert sol.completed, sol.stop_reason
    hist = sol.history
    c, u_end, force = hist["weak_elongation_m"], hist["end_displacement"], hist["force"]
    sigma = force / HEIGHT
    path = driver.LoadPath()
    path.add(9000, eps_xx=9e-3, eps_yy=0.0, eps_zz=0.0, eps_yz=0.0, eps_xz=0.0, eps_xy=0.0)
    ref = driver.run_path(VonMises(E, NU, 90.0, hardening_kPa=-2 * G), path)
    sigma_ref = np.interp(c / h, ref["eps_xx"], ref["sig_xx_kPa"])
    u_ref = c + (L - h) * sigma_ref / (K + 4 * G / 3)
    assert np.abs(sigma - sigma_ref).max() <= 1e-6 * sigma_ref.max()
    assert np.abs(u_end - u_ref).max() <= 1e-6 * u_ref.max()
    peak = int(np.argmax(sigma))
    assert 0 < peak < len(sigma) - 5 and sigma[-1] < 0.95 * sigma[peak]  # through the peak, into the softening
    assert u_end[-1] < u_end[peak] - 1e-5  # the snap-back: the end moves back while the weak element opens
    assert hist["iterations"][1:].max() <= 3  # J2 with linear softening: Newton converges in a few iterations


def test_displacement_control_cannot_pass_the_snap_back():
    """The same bar under the end displacement alone: past the peak no state with a larger end displacement
    lies on the softening branch; the run stops at the peak (measured: t = 0.585, Newton cycling between two
    iterates, the steps cut below dt_min), every converged step before it kept."""
    d, law, bcs, _ = _bar()
    sol = NewtonSolver(d, law, bcs, options=SolverOptions(line_search=0, max_cuts=4)).run(steps=40, t_end=1.0)
    sigma = sol.history["end_reaction"] / HEIGHT
    assert not sol.completed and sigma.max() == pytest.approx(157.5, rel=1e-3)  # stopped at the peak


def test_a_control_without_dofs_or_end_is_named():
    with pytest.raises(ValueError, match="needs DOFs"):
        PathControl(np.zeros(0, dtype=int), np.zeros(0))
    d, law, bcs, opening = _bar()
    with pytest.raises(ValueError, match="control_end = None"):
        NewtonSolver(d, law, bcs).run(steps=2, control=opening)


def test_the_biaxial_case_under_lateral_control_follows_the_load_controlled_path():
    """Biaxial(control_strain=...) prescribes the lateral expansion and lets the platen follow: on a
    rate-independent law (Drucker-Prager) the two controls trace the same curve (measured: 0.7 kPa of 244,
    the interpolation between the 40 steps of each), with fewer iterations per step (1.0 against 1.5)."""
    from femgran.cases import Output, run
    from femgran.cases.biaxial import Biaxial
    from material import DruckerPrager

    dp = DruckerPrager(3e4, 0.3, 1.0, 35.0, 5.0)
    load = run(Biaxial(resolution=4, axial_strain=0.02, steps=40), dp, output=Output(None)).history
    lateral = run(Biaxial(resolution=4, axial_strain=0.02, steps=40, control_strain=0.012), dp,
                  output=Output(None)).history
    assert lateral["lateral_expansion_m"][-1] == pytest.approx(0.012 * 0.05, rel=1e-12)
    inside = lateral["eps_a"] <= load["eps_a"][-1]
    q_load = np.interp(lateral["eps_a"][inside], load["eps_a"], load["q_kPa"])
    assert np.abs(lateral["q_kPa"][inside] - q_load).max() <= 5e-3 * load["q_kPa"].max()
    with pytest.raises(ValueError, match="control_strain = -1"):
        Biaxial(control_strain=-1.0)
