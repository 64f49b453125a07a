"""The parametric study of Table 4 (N1-N3 sample sizes, T01-T07 contact parameters) as one call.

Each test: generation (Appendix A) -> isotropic compression to 100 kPa -> biaxial compression at
100 kPa lateral stress -> 90 deg rotation of the principal strain axes (eq. 3.10), with the fabric
(MIL and areal porosity) along both stages written to CSV.

Stiffness units: Table 4 lists K_N, K_S "in N/m". Taken literally for unit-thickness disks, 100 kPa
would press them into overlaps of about half a diameter (f ~ p d ~ 37 N/m against 2e5 N/m), so we
read them as kN/m (the project's force unit): K_N = 2e5 kN/m = 2e8 N/m gives overlaps of ~5e-4 d.
Box sizes follow from the PSD (the disks of Table 4's N in a box of the table's aspect ratio); the
default run is reduced to ``scale`` (0.1) of the thesis's particle numbers; ``full=True`` runs N as
in the table.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from pathlib import Path

import numpy as np

from material.table import Table, read_table

from .contacts import ContactLaw

TABLE4 = {  # id: (N, H/W, K_N [kN/m], K_S [kN/m], phi_s [deg])
    "N1": (2000, 1.0, 2e5, 2e5, 30.0),
    "N2": (4000, 1.0, 2e5, 2e5, 30.0),
    "N3": (10000, 1.0, 2e5, 2e5, 30.0),
    "T01": (4000, 45 / 40, 2e5, 2e4, 20.0),
    "T02": (4000, 45 / 40, 2e5, 2e4, 30.0),
    "T03": (4000, 45 / 40, 2e5, 2e4, 40.0),
    "T04": (4000, 45 / 40, 2e5, 2e5, 20.0),
    "T05": (4000, 45 / 40, 2e5, 2e5, 30.0),
    "T06": (4000, 45 / 40, 2e5, 2e5, 40.0),
    "T07": (4000, 45 / 40, 5e4, 5e4, 30.0),
}


def law_of(test_id: str) -> ContactLaw:
    if test_id not in TABLE4:
        raise KeyError(f"unknown Table 4 test {test_id!r}; allowed: {list(TABLE4)}")
    _, _, kn, ks, phi = TABLE4[test_id]
    return ContactLaw(kn=1e3 * kn, kt=1e3 * ks, friction=float(np.tan(np.radians(phi))))


def run_test(test_id: str, out, scale: float = 0.1, seed: int = 1, axial_strain: float = 0.05,
             rotation_deg: float = 90.0, grid_spacing_m: float = 1e-5, progress: bool = False) -> dict:
    """Run one Table 4 test into ``out/<test_id>``; returns a summary dict."""
    import dem
    from .calibrate import fabric_series

    law = law_of(test_id)
    n, aspect = TABLE4[test_id][:2]
    n = max(50, int(round(n * scale)))
    folder = Path(out) / test_id
    folder.mkdir(parents=True, exist_ok=True)
    sample = dem.generate(n, seed=seed, law=law, aspect=aspect, progress=progress)
    iso = dem.isotropic_compression(sample, p_kPa=100.0, law=law)
    dem.save(iso, folder / "isotropic.npz")
    biax = dem.biaxial(iso, axial_strain=axial_strain, out=folder / "biaxial", progress=progress, n_records=60,
                       snapshot_every=3)
    rot = dem.rotate_strain(biax.final, rotation_deg=rotation_deg, increment_deg=1.0, out=folder / "rotation",
                            progress=progress, snapshot_every=5)
    for stage, run in (("biaxial", biax), ("rotation", rot)):
        for measure in ("mil", "areal_porosity"):
            series = fabric_series(run, measure=measure, grid_spacing_m=grid_spacing_m)
            write_csv(folder / stage / f"fabric_{measure}.csv", series)
    return {"test": test_id, "n_particles": n, "porosity0": float(dem.porosity(iso)),
            "phi_peak_deg": float(np.nanmax(biax["phi_mob_deg"])), "max_inertial_number":
            float(max(np.nanmax(biax["inertial_number"]), np.nanmax(rot["inertial_number"])))}


def write_csv(path, columns: dict, descriptions: dict | None = None, title: str = "DEM table") -> Path:
    """Columns as a :class:`material.table.Table` CSV (commented header)."""
    return Table(columns, descriptions, title=title).write_csv(path)


def read_csv(path) -> Table:
    """A table written by :func:`write_csv` or a run's ``history.csv``."""
    return read_table(path)


def _run_one(args):
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    return run_test(*args)


def sweep(out, tests=None, full: bool = False, scale: float = 0.1, seed: int = 1, jobs: int = 2,
          axial_strain: float = 0.05, rotation_deg: float = 90.0, progress: bool = False) -> list[dict]:
    """Run the Table 4 tests (default: all) and write per-run CSVs, the figures and a calibration."""
    tests = list(TABLE4) if not tests else list(tests)
    for t in tests:
        law_of(t)  # validates the ids
    scale = 1.0 if full else scale
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    args = [(t, out, scale, seed, axial_strain, rotation_deg, 1e-5, progress and jobs == 1) for t in tests]
    if jobs > 1 and len(tests) > 1:
        with mp.get_context("spawn").Pool(min(jobs, len(tests))) as pool:
            summary = pool.map(_run_one, args)
    else:
        summary = [_run_one(a) for a in args]
    write_csv(out / "summary.csv", {k: [s[k] for s in summary] for k in ("n_particles", "porosity0", "phi_peak_deg",
                                                                         "max_inertial_number")})
    (out / "summary_tests.txt").write_text("\n".join(s["test"] for s in summary) + "\n")
    from .figures import sweep_figures

    sweep_figures(out, tests)
    return summary
