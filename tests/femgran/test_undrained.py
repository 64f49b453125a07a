"""Undrained boundary-value problems in effective stress (material.undrained, drainage = "undrained")."""

import numpy as np
import pytest

from femgran.cases import Element, Footing, Output, run
from femgran.cases.footing import prandtl_pressure
from material import CPAModel, VonMises, driver, load_preset
from material.anisotropy import axes_from_alpha
from material.undrained import Undrained


@pytest.fixture(scope="module")
def sand():
    return CPAModel(load_preset("ottawa_c109"), axes=axes_from_alpha(30.0))


@pytest.mark.parametrize("bulk", [5.5e6, 5.5e7])
def test_one_undrained_element_is_the_drivers_undrained_test(sand, bulk, tmp_path):
    """The FE element and the driver's undrained test with the same pore water (K = K_w / n) agree to the
    solvers' tolerances; the constant-volume test (K infinite) is the limit, approached as the skeleton's
    bulk modulus over K: 0.11 % at the default K (5.5e6 kPa: water over a porosity of 0.4), ten times less
    at ten times K."""
    ref = driver.triaxial(sand, 100.0, 30.0, axial_strain=0.02, steps=20, drained=False, pore_bulk_modulus_kPa=bulk)
    limit = driver.triaxial(sand, 100.0, 30.0, axial_strain=0.02, steps=20, drained=False)
    case = Element(p0_kPa=100.0, alpha_deg=30.0, axial_strain=0.02, steps=20, drainage="undrained",
                   pore_bulk_modulus_kPa=bulk)
    sol = run(case, sand, output=Output(tmp_path, plots=False))
    h = sol.history
    assert sol.completed and ref["u_kPa"][-1] > 50.0  # the contractive sand builds up pore pressure
    assert np.abs(h["q_kPa"] - ref["q_kPa"]).max() <= 1e-6 * np.abs(ref["q_kPa"]).max()
    assert np.abs(h["pore_pressure_kPa"] - ref["u_kPa"]).max() <= 1e-6 * np.abs(ref["u_kPa"]).max()
    gap = np.abs(ref["u_kPa"] - limit["u_kPa"]).max() / np.abs(limit["u_kPa"]).max()
    assert 0.5e-3 * 5.5e6 / bulk < gap < 1.5e-3 * 5.5e6 / bulk
    import meshio  # the pore pressure is a field of the series

    last = sorted(tmp_path.glob("element_*.vtu"))[-1]
    assert "pore_pressure_kPa" in meshio.read(last).point_data


def test_an_undrained_footing_on_a_von_mises_soil_reaches_prandtl():
    c_u = 100.0
    sol = run(Footing(unit_weight=0.0, settlement_m=0.2, steps=30, drainage="undrained"),
              VonMises(3e4, 0.3, c_u * np.sqrt(3)))
    assert sol.completed
    assert sol.bearing_capacity_kPa == pytest.approx(prandtl_pressure(c_u), rel=0.05)


def test_the_undrained_tangent_is_the_derivative_of_the_total_stress():
    law = Undrained(CPAModel(load_preset("ottawa_c109")), 1e5)
    state = law.initial_state(1, stress=-100.0 * np.eye(3))
    sig0 = -100.0 * np.eye(3)[None]
    de = np.array([[[1e-4, 2e-5, 0.0], [2e-5, 3e-5, 0.0], [0.0, 0.0, -4e-4]]])
    s, new, D = law.update(de, sig0, state)
    assert new["pore_pressure_kPa"][0] == pytest.approx(-1e5 * np.trace(de[0]))
    h = 1e-9
    for k, l in ((0, 0), (2, 2), (0, 1)):
        e = np.zeros((1, 3, 3))
        e[0, k, l] = e[0, l, k] = h
        fd = (law.update(de + e, sig0, state)[0] - law.update(de - e, sig0, state)[0]) / (2 * h)
        an = np.einsum("nijkl,nkl->nij", D, e) / h
        np.testing.assert_allclose(fd, an, rtol=1e-5, atol=1e-3)
    with pytest.raises(ValueError, match="pore_bulk_modulus_kPa = -1"):
        Undrained(law.law, -1.0)
    with pytest.raises(ValueError, match="drainage = 'wet'"):
        Footing(drainage="wet")
