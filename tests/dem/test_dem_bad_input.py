"""Bad input gives a clear error naming the value and what is allowed."""

import numpy as np
import pytest

import dem
from dem.psd import PSD


def test_too_many_particles_for_the_box():
    with pytest.raises(ValueError, match="impossible packing"):
        dem.generate(5000, width_m=0.005, height_m=0.005)


def test_psd_not_monotone(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("diameter_mm,percent_finer\n0.1,0\n0.2,60\n0.3,40\n0.4,100\n")
    with pytest.raises(ValueError, match="monotone"):
        dem.generate(100, psd=path)
    with pytest.raises(ValueError, match="strictly increasing"):
        PSD([2e-4, 1e-4], [0.0, 1.0])
    with pytest.raises(KeyError, match="unknown PSD"):
        dem.load_psd("ottawa_c190")


def test_time_step_above_stable_limit(isotropic):
    limit = dem.critical_time_step(isotropic.radii, isotropic.law)
    with pytest.raises(ValueError, match="critical time step"):
        dem.Simulation(isotropic.copy(), dt=1.5 * limit)


def test_particle_leaving_the_box_stops_with_its_checkpoint(tmp_path, isotropic):
    dem.biaxial(isotropic, axial_strain=0.004, n_records=4, out=tmp_path, checkpoint_every=12000)
    ckpt = tmp_path / "checkpoint.npz"
    state = dem.load(ckpt)
    state.velocities[0] = [1e5, 0.0]  # a particle shot out of the box
    dem.save(state, ckpt)
    with pytest.raises(dem.ParticleEscapedError, match="left the box.*checkpoint.npz"):
        dem.biaxial(isotropic, axial_strain=0.004, n_records=4, out=tmp_path, resume=True)


def test_other_bad_arguments(isotropic):
    with pytest.raises(ValueError, match="p_kPa"):
        dem.isotropic_compression(isotropic, p_kPa=-5.0)
    with pytest.raises(ValueError, match="measure"):
        dem.fabric(isotropic, measure="porosity")
    with pytest.raises(ValueError, match="friction"):
        dem.ContactLaw(friction=-0.1)
    with pytest.raises(FileNotFoundError):
        dem.load("no/such/state.npz")
