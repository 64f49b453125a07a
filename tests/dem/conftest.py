"""Shared small samples for the DEM tests (a few hundred disks; generated once per session)."""

import pytest

import dem


@pytest.fixture(scope="session")
def generated():
    """300 Ottawa disks after frictionless radius expansion (Appendix A)."""
    return dem.generate(300, seed=2)


@pytest.fixture(scope="session")
def isotropic(generated):
    """The same sample isotropically compressed to 100 kPa with friction tan 30 deg."""
    return dem.isotropic_compression(generated, p_kPa=100.0)


@pytest.fixture(scope="session")
def biaxial_run(isotropic):
    return dem.biaxial(isotropic, sigma_lateral_kPa=100.0, axial_strain=0.04, n_records=16)


@pytest.fixture(scope="session")
def rotation_run(biaxial_run):
    return dem.rotate_strain(biaxial_run.final, rotation_deg=90.0, increment_deg=2.0, snapshot_every=5)
