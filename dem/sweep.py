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

import sys
from pathlib import Path

import numpy as np

from material.table import Table

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


def table4_run(out, test: str = "T05", scale: float = 0.1, seed: int = 1, axial_strain: float = 0.05,
               rotation_deg: float = 90.0, grid_spacing_m: float = 1e-5, progress: bool = False) -> dict:
    """One Table 4 test into the folder ``out`` (a sweep target, :mod:`material.sweep`); returns its summary.

    Writes ``isotropic.npz``, the ``biaxial/`` and ``rotation/`` runs and their fabric series
    (``fabric_mil.csv``, ``fabric_areal_porosity.csv``)."""
    import dem
    from .calibrate import fabric_series

    law = law_of(test)
    if not (isinstance(scale, (int, float)) and 0.0 < scale <= 1.0):
        raise ValueError(f"scale = {scale!r}: allowed a fraction of the thesis's particle number in (0, 1]")
    n, aspect = TABLE4[test][:2]
    n = max(50, int(round(n * scale)))
    folder = Path(out)
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
            Table(series, title=f"DEM fabric ({measure}) along the {stage}").write_csv(
                folder / stage / f"fabric_{measure}.csv")
    return {"n_particles": n, "porosity0": float(dem.porosity(iso)),
            "phi_peak_deg": float(np.nanmax(biax["phi_mob_deg"])), "max_inertial_number":
            float(max(np.nanmax(biax["inertial_number"]), np.nanmax(rot["inertial_number"])))}


def run_test(test_id: str, out, scale: float = 0.1, seed: int = 1, axial_strain: float = 0.05,
             rotation_deg: float = 90.0, grid_spacing_m: float = 1e-5, progress: bool = False) -> dict:
    """Run one Table 4 test into ``out/<test_id>`` (here, in this process); returns a summary dict."""
    summary = table4_run(Path(out) / test_id, test_id, scale, seed, axial_strain, rotation_deg, grid_spacing_m,
                         progress)
    return {"test": test_id, **summary}


def sweep(out, tests=None, full: bool = False, scale: float = 0.1, seed: int = 1, workers: int | None = None,
          axial_strain: float = 0.05, rotation_deg: float = 90.0, progress: bool = False,
          scheduler: str | None = None) -> list[dict]:
    """Run the Table 4 tests (default: all) on the sweep engine (:func:`material.sweep.sweep`: a local Dask
    cluster of ``workers`` processes, or ``scheduler``; resumable) into ``out/<test>``, then write the
    summary, the figures (``out/figures``) of the tests that completed and return their summary dicts (a test
    that failed is reported on stderr and in ``out/sweep.json``)."""
    from material.sweep import Run, sweep as run_sweep

    tests = list(TABLE4) if not tests else list(tests)
    for t in tests:
        law_of(t)  # validates the ids
    scale = 1.0 if full else scale
    out = Path(out)
    runs = [Run(t, "dem.sweep:table4_run", {"test": t, "scale": scale, "seed": seed, "axial_strain": axial_strain,
                                             "rotation_deg": rotation_deg}, {"test_index": list(TABLE4).index(t)})
            for t in tests]
    result = run_sweep(runs, out, scheduler=scheduler, workers=workers, progress=progress, title="Table 4")
    for r in result.records:
        if r["status"] != "completed":
            print(f"Table 4 sweep: {r['key']} {r['status']}: {r['message']} (the same command again runs the runs "
                  "not complete)", file=sys.stderr)
    summary = [{"test": r["key"], **r["summary"]} for r in result.records if r["status"] == "completed"]
    done = [s["test"] for s in summary]
    (out / "summary_tests.txt").write_text("\n".join(done) + "\n")
    if not done:
        return summary
    from .figures import sweep_figures

    sweep_figures(out, done)
    return summary
