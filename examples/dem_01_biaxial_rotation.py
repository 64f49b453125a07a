"""DEM virtual experiment of the thesis's chapter 3, coarse: generation, 100 kPa, biaxial, rotation.

Generates an Ottawa C109 sample (Appendix A), compresses it to 100 kPa, runs a biaxial compression at
100 kPa lateral stress and a rotation of the principal strain axes at constant eps_v, eps_q
(eq. 3.10), measures the fabric (MIL, Section 3.4.1) and calibrates beta of Lambda = beta e (3.15)
into a parameter file that ``material.load_parameters`` reads. Writes to ``out/examples/dem_01``.
Run: ``python examples/dem_01_biaxial_rotation.py`` (about a minute with n=400).
"""

from pathlib import Path

import numpy as np

import dem
from dem.calibrate import calibrate


def main(out="out/examples/dem_01", n=400, axial_strain=0.04, rotation_deg=90.0):
    out = Path(out)
    sample = dem.generate(n, seed=1)
    iso = dem.isotropic_compression(sample, p_kPa=100.0)
    print(f"sample: {n} disks, porosity {dem.porosity(iso):.3f}, Z {dem.coordination_number(iso):.2f}")
    biax = dem.biaxial(iso, sigma_lateral_kPa=100.0, axial_strain=axial_strain, out=out / "biaxial", n_records=20)
    rot = dem.rotate_strain(biax.final, rotation_deg=rotation_deg, increment_deg=2.0, out=out / "rotation")
    phi = float(np.nanmax(biax["phi_mob_deg"]))
    lead = (rot["alpha_sigma_deg"] - rot["alpha_eps_deg"] + 90) % 180 - 90
    print(f"peak mobilised friction {phi:.1f} deg; stress leads strain by {np.nanmean(lead[1:]):.1f} deg on average")
    cal = calibrate([biax, rot])
    path = cal.write(out / "calibrated.toml")
    print(f"beta = {cal.beta:.3f}, delta = {cal.delta_mean_deg:.1f} +- {cal.delta_std_deg:.1f} deg -> {path}")
    return {"phi_peak_deg": phi, "beta": cal.beta, "parameters": path}


if __name__ == "__main__":
    main()
