"""Biaxial compression, strain rotation, fabric (Section 3.4), checkpoints and resume."""

import numpy as np
import pytest

import dem
from dem.stereology import _intercepts, area_porosity_in_domain, delta_deg, intercepts_reference


def _wrap90(angle_deg):
    return (np.asarray(angle_deg) + 90.0) % 180.0 - 90.0


def test_biaxial_holds_lateral_stress_and_is_quasi_static(biaxial_run):
    run = biaxial_run
    assert run["eps_a"][-1] == pytest.approx(0.04, rel=1e-3)
    lateral = run["sigma_xx_kPa"][1:]
    assert np.median(np.abs(lateral + 100.0)) < 2.0  # the servo holds 100 kPa (compression) ...
    assert np.max(np.abs(lateral + 100.0)) < 12.0  # ... up to short slip events of a 300-disk sample
    assert np.max(run["inertial_number"]) < 1e-3
    assert 15.0 < np.max(run["phi_mob_deg"]) < 40.0  # mobilised friction of a dense 2D assembly
    # walls and contacts agree during shearing to a few percent (not exactly static)
    np.testing.assert_allclose(run["contact_sigma_yy_kPa"], run["sigma_yy_kPa"], rtol=0.05)


def test_fabric_stays_coaxial_with_strain_in_biaxial():
    """|delta| (MIL fabric and contact normals vs strain deviator) small in axial compression (Fig. 39).

    1000 disks: with 300 the MIL tensor of the circular domain is dominated by sampling noise."""
    iso = dem.isotropic_compression(dem.generate(1000, seed=1))
    run = dem.biaxial(iso, axial_strain=0.03, n_records=12)
    mil, contact = [], []
    for k in range(2, len(run.snapshots)):
        state = run.snapshot_state(k)
        mil.append(delta_deg(dem.fabric(state, measure="mil", grid_spacing_m=1e-5).omega, state.boundary_strain))
        contact.append(delta_deg(dem.contact_fabric(state), state.boundary_strain))
    assert np.median(np.abs(mil)) < 6.0  # thesis: |delta| about 4-5 deg (Fig. 39)
    assert np.median(np.abs(contact)) < 3.0


def test_rotation_keeps_invariants_and_stress_is_not_coaxial(rotation_run, biaxial_run):
    rot = rotation_run
    # eq. 3.10: constant eps_q at the increment ends; inside an increment the path is the chord
    np.testing.assert_allclose(rot["eps_q"], rot["eps_q"][0], rtol=1 - np.cos(np.radians(2.0)) + 1e-9)
    np.testing.assert_allclose(rot["eps_v"], rot["eps_v"][0], atol=1e-9)  # and eps_v
    assert rot["alpha_eps_deg"][-1] == pytest.approx(90.0, abs=1e-6) or rot["alpha_eps_deg"][-1] == pytest.approx(-90.0, abs=1e-6)
    # the strain increment leads the strain by 45 deg; the stress lies in between (Figs. 28, 44)
    mid = (rot["alpha_eps_deg"] > 10) & (rot["alpha_eps_deg"] < 80)
    lead = _wrap90(rot["alpha_sigma_deg"][mid] - rot["alpha_eps_deg"][mid])
    assert np.mean(lead) > 10.0
    incr = _wrap90(rot["alpha_deps_deg"][mid] - rot["alpha_eps_deg"][mid])
    np.testing.assert_allclose(incr, 45.0, atol=1.5)


def test_intercept_kernel_matches_reference(isotropic):
    c = isotropic.positions - isotropic.corners().mean(axis=0)
    for theta in (0.0, 0.7, 2.1):
        fast = _intercepts(c, isotropic.radii, 3e-3, 2e-5, theta)
        slow = intercepts_reference(c, isotropic.radii, 3e-3, 2e-5, theta)
        np.testing.assert_allclose(fast, slow, rtol=1e-12)


def test_single_disk_intercepts_are_exact():
    """One disk of radius r at the centre of a domain of radius R: void fraction 1 - (r/R)^2."""
    R, r = 1.0, 0.3
    void, length, count = _intercepts(np.zeros((1, 2)), np.array([r]), R, 1e-4, 0.3)
    assert 1 - (length - void) / length == pytest.approx(1 - r**2 / R**2, abs=1e-6)  # area fractions
    assert count == pytest.approx(2 * int(2 * r / 1e-4) + (int(2 / 1e-4) - int(2 * r / 1e-4)), abs=2)


def test_mean_areal_porosity_equals_disk_porosity(isotropic):
    """Table 5 check: mean n from line intercepts = porosity from disk areas (same domain)."""
    fab = dem.fabric(isotropic, measure="areal_porosity", grid_spacing_m=5e-6)
    assert fab.mean == pytest.approx(area_porosity_in_domain(isotropic), abs=1e-3)
    # the whole-sample porosity also counts the looser layer along the walls
    assert fab.mean == pytest.approx(dem.porosity(isotropic), abs=0.04)
    assert fab.values.shape == (18,)


def test_kanatani_fits_reproduce_synthetic_distribution():
    theta = np.arange(0, 180, 10.0)
    t = np.radians(theta)
    x = 0.2 * np.cos(2 * t) + 0.1 * np.sin(2 * t)
    values = 0.3 * (1 + x + 0.5 * x**2)
    fab = dem.Fabric("mil", theta, values, values, np.ones(18), np.ones(18), 1.0, 1.0)
    fit2 = fab.fit(2)
    assert fit2.C == pytest.approx(0.3, rel=1e-6)
    np.testing.assert_allclose(fit2.omega, [[0.2, 0.1], [0.1, -0.2]], atol=1e-6)
    assert fit2.a[0] == pytest.approx(0.5, rel=1e-4)
    assert fab.fit(3).rms < 1e-8 < fab.fit(1).rms


def test_resume_reproduces_uninterrupted_run(tmp_path, isotropic):
    full = dem.biaxial(isotropic, axial_strain=0.004, n_records=8)
    n = full.final.steps - isotropic.steps
    first = dem.biaxial(isotropic, axial_strain=0.004, n_records=8, out=tmp_path, checkpoint_every=int(0.6 * n))
    ckpt = dem.load(tmp_path / "checkpoint.npz")
    assert ckpt.steps < first.final.steps  # the checkpoint lies inside the run
    resumed = dem.biaxial(isotropic, axial_strain=0.004, n_records=8, out=tmp_path, resume=True)
    np.testing.assert_array_equal(resumed.final.positions, full.final.positions)
    np.testing.assert_array_equal(resumed["sigma_yy_kPa"], full["sigma_yy_kPa"])
    lines = [ln for ln in (tmp_path / "history.csv").read_text().splitlines() if not ln.startswith("#")]
    assert len(lines) == len(full["step"]) + 1  # the names and one row per record: no duplicates, no gaps
    np.testing.assert_array_equal(dem.experiments.load_run(tmp_path)["sigma_yy_kPa"], full["sigma_yy_kPa"])


def test_rotation_resume_and_inertial_number(tmp_path, biaxial_run):
    """Adaptive increments (duration from the current pressure) resume bit for bit; I stays < 1e-3."""
    kwargs = dict(rotation_deg=20.0, increment_deg=2.0)
    full = dem.rotate_strain(biaxial_run.final, **kwargs)
    assert np.nanmax(full["inertial_number"]) < 1e-3
    n = full.final.steps - biaxial_run.final.steps
    dem.rotate_strain(biaxial_run.final, out=tmp_path, checkpoint_every=int(0.55 * n), **kwargs)
    resumed = dem.rotate_strain(biaxial_run.final, out=tmp_path, resume=True, **kwargs)
    np.testing.assert_array_equal(resumed.final.positions, full.final.positions)
    np.testing.assert_array_equal(resumed["alpha_sigma_deg"], full["alpha_sigma_deg"])
