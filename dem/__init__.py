"""Numba 2D DEM of disks: sample generation, biaxial and strain-rotation experiments, stereological fabric.

Public API::

    import dem
    sample = dem.generate(n_particles=4000, psd="ottawa_c109", seed=1)
    sample = dem.isotropic_compression(sample, p_kPa=100.0)
    run = dem.biaxial(sample, sigma_lateral_kPa=100.0, axial_strain=0.05)
    rot = dem.rotate_strain(run.final, rotation_deg=90.0)
    fab = dem.fabric(run.final, measure="areal_porosity")

Modules: ``contacts`` (contact law, O(N^2) reference), ``neighbours`` (Verlet half list), ``engine``
(numba kernels: forces, velocity Verlet, servo walls), ``simulation`` (batches of steps), ``state``
(state and .npz I/O), ``psd`` (sieve curve -> number CDF, sampling), ``generate`` (Appendix A),
``measures`` (Appendix C: stress, strain, porosity, coordination), ``experiments`` (biaxial, rotation),
``stereology`` (fabric, Section 3.4.1), ``calibrate`` (evolution-law constants -> parameter file).
"""

from .contacts import ContactLaw, critical_time_step
from .state import DEMState, save, load
from .psd import PSD, load_psd, ks_distance
from .simulation import Simulation, ParticleEscapedError
from .generate import generate, isotropic_compression
from .measures import (stress_from_walls, stress_from_contacts, strain_from_boundary, porosity,
                       coordination_number, contact_fabric, inertial_number, rattlers)
from .experiments import Run, biaxial, rotate_strain, strain_at, principal_angle_deg
from .stereology import Fabric, FabricFit, fabric, delta_deg

__all__ = [
    "ContactLaw", "critical_time_step", "DEMState", "save", "load", "PSD", "load_psd", "ks_distance",
    "Simulation", "ParticleEscapedError", "generate", "isotropic_compression", "stress_from_walls",
    "stress_from_contacts", "strain_from_boundary", "porosity", "coordination_number", "contact_fabric",
    "inertial_number", "rattlers", "Run", "biaxial", "rotate_strain", "strain_at", "principal_angle_deg",
    "Fabric", "FabricFit", "fabric", "delta_deg",
]
