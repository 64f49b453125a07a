"""Sample generation (Appendix A), stress/strain operators (Appendix C), state files."""

import numpy as np
import pytest

import dem
from dem import measures
from dem.psd import PSD, load_psd, ks_distance


def test_number_cdf_converts_mass_fractions():
    """Two segments with equal mass: the finer one holds more particles, in the ratio of <d^2>."""
    psd = PSD([1e-3, 2e-3, 4e-3], [0.0, 0.5, 1.0])
    d2_fine = (1 + 2 + 4) / 3 * 1e-6
    d2_coarse = (4 + 8 + 16) / 3 * 1e-6
    share_fine = (1 / d2_fine) / (1 / d2_fine + 1 / d2_coarse)
    assert psd.number_cdf(2e-3) == pytest.approx(share_fine, rel=1e-12)  # = 0.8


def test_sampled_sizes_follow_psd():
    psd = load_psd("ottawa_c109")
    d = psd.sample(4000, np.random.default_rng(7))
    # KS critical value at 5 % for n = 4000 is 1.36 / sqrt(n) = 0.0215
    assert ks_distance(d, psd) < 1.36 / np.sqrt(4000)
    # and the mass-weighted curve of the sample reproduces the sieve curve at D50
    order = np.sort(d)
    mass = np.cumsum(order**2) / np.sum(order**2)
    assert np.interp(0.5, mass, order) == pytest.approx(0.374e-3, rel=0.03)


def test_generated_sample_follows_psd(generated):
    psd = load_psd("ottawa_c109")
    assert ks_distance(2 * generated.radii, psd) < 1.36 / np.sqrt(generated.n_particles)


def test_frictionless_expansion_is_isostatic(generated):
    """Frictionless jammed packing: Z (rattlers excluded) near 4 and the constraint count C = 2 N."""
    z = dem.coordination_number(generated, exclude_rattlers=True)
    assert 3.6 < z < 4.2
    i, j, *_ = measures.contacts(generated)
    p, *_ = measures.wall_contacts(generated)
    active = ~dem.rattlers(generated)
    constraints = np.sum(active[i] & active[j]) + np.sum(active[p])
    assert constraints / (2 * active.sum()) == pytest.approx(1.0, abs=0.03)


def test_isotropic_state_walls_and_contacts_agree(isotropic):
    """At equilibrium sigma(C.4, walls) = sigma(C.5, contacts) within 1 % of p, and p = 100 kPa."""
    walls = dem.stress_from_walls(isotropic)
    contacts = dem.stress_from_contacts(isotropic)
    assert np.diag(walls) == pytest.approx([-100.0, -100.0], rel=0.01)
    np.testing.assert_allclose(contacts, walls, atol=1.0)
    assert 0.12 < dem.porosity(isotropic) < 0.22


def test_strain_from_boundary_segments_is_exact_for_affine_walls(isotropic):
    state = isotropic.copy()
    state.boundary_strain = np.array([[0.01, 0.004], [0.004, -0.02]])
    eps = dem.strain_from_boundary(state)  # eqs. C.13-C.15
    np.testing.assert_allclose(eps, state.boundary_strain, atol=1e-14)


def test_state_file_round_trip(tmp_path, isotropic):
    path = dem.save(isotropic, tmp_path / "iso.npz")
    back = dem.load(path)
    np.testing.assert_array_equal(back.positions, isotropic.positions)
    np.testing.assert_array_equal(back.pair_zeta, isotropic.pair_zeta)
    assert back.law == isotropic.law
    assert back.meta["seed"] == 2
    with np.load(path, allow_pickle=False) as data:  # plain arrays only
        assert "positions" in data.files
