"""Composite material (laws on point sets) and the frictional platens built on it."""

import numpy as np
import pytest

import material
from femgran.cases import triaxial
from material.composite import Composite


def test_composite_dispatches_points_and_keeps_each_state(rng):
    vm = material.VonMises(1e4, 0.3, 10.0, 100.0)
    el = material.LinearElastic(2e4, 0.25)
    assign = np.array([0, 1, 0, 1, 1])
    comp = Composite([vm, el], assign)
    st = comp.initial_state(5)
    de = rng.normal(scale=2e-3, size=(5, 3, 3))
    de = 0.5 * (de + np.swapaxes(de, 1, 2))
    s, st2, D = comp.update(de, np.zeros((5, 3, 3)), st)
    s_vm, st_vm, D_vm = vm.update(de[assign == 0], np.zeros((2, 3, 3)), vm.initial_state(2))
    s_el, _, D_el = el.update(de[assign == 1], np.zeros((3, 3, 3)), el.initial_state(3))
    np.testing.assert_allclose(s[assign == 0], s_vm)
    np.testing.assert_allclose(s[assign == 1], s_el)
    np.testing.assert_allclose(D[assign == 0], D_vm)
    np.testing.assert_allclose(st2["0:eq_plastic_strain"][assign == 0], st_vm["eq_plastic_strain"])
    np.testing.assert_allclose(st2["strain"], de)
    assert st["0:eq_plastic_strain"].shape == (5,)  # full size, every array has the leading axis N
    with pytest.raises(ValueError, match="assignment"):
        Composite([vm, el], np.array([0, 2]))


def test_frictional_platens_lie_between_smooth_and_rough():
    law = material.DruckerPrager(3e4, 0.3, 0.0, 35.0, 5.0, match="compression")
    kw = dict(p0_kPa=100.0, alpha_deg=0.0, axial_strain=0.02, steps=10, resolution=2, plots=False)
    q = {}
    for name, pl, mu in [("smooth", "smooth", 0.3), ("low", "frictional", 0.05), ("mid", "frictional", 0.3),
                         ("rough", "rough", 0.3)]:
        sol = triaxial(law, platens=pl, friction=mu, **kw)
        assert sol.completed
        q[name] = sol.history["q_kPa"][-1]
    assert q["smooth"] < q["low"] < q["mid"] <= q["rough"] * 1.01
    assert q["low"] - q["smooth"] < 0.1 * (q["rough"] - q["smooth"])  # mu = 0.05: nearly smooth
    with pytest.raises(ValueError, match="friction"):
        triaxial(law, platens="frictional", friction=-1.0)


def test_newton_log_sees_the_planes_of_a_weak_zone_specimen(tmp_path):
    """A CPA specimen with a weak zone is a Composite of two CPA laws: their plane states are merged, so
    the Newton log counts loading points and local iterations as for one law (it read NaN before)."""
    from femgran.cases.biaxial import biaxial

    sol = biaxial(None, 100.0, axial_strain=0.004, steps=2, resolution=4, imperfection=0.0, weak_zone=0.1,
                  weak_zone_height=0.25, out=tmp_path / "bx", plots=False)
    assert sol.completed
    from material.table import read_table

    log = read_table(tmp_path / "bx" / "newton_log.csv")
    assert np.isfinite(log["loading_points"]).all() and log["loading_points"].max() > 0
    assert log["local_iterations_max"].max() > 0
