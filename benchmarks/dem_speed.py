"""DEM speed: dem (numba) against LAMMPS on the same 4,096-disk packing, same contact law and time step.

    python benchmarks/dem_speed.py [--steps 20000] [--lammps-dir DIR] [--no-lammps] [--protocol]

The problem (the one of the LAMMPS reference inputs prep.in, bench.in, export.in): 4,096 polydisperse
disks (d uniform in 0.2-0.6 mm, 2650 kg/m3), Hookean contact with history k_n = 1e8 N/m, k_t = 2/7 k_n,
gamma_n = 5e5 1/s (gamma_t = gamma_n / 2, as LAMMPS's NULL), mu = 0.5, dt = 1e-7 s, dense packing at
100 kPa, then biaxial loading (axial strain rate 1/s, lateral stress 100 kPa).

The LAMMPS folder is given by ``--lammps-dir DIR`` or the environment variable ``FEMGRAN_LAMMPS_DIR``;
it holds LAMMPS's ``packing.dump`` (made by prep.in + export.in) and/or those input files. If LAMMPS
(``lmp``) is installed and the inputs are there, the script prepares the packing in that folder when
needed and times ``bench.in`` in the same run. Without a folder (or without its packing) it generates a
packing of the same specification itself and prints as the baseline the LAMMPS figures quoted in
README_FIGURES (Debian's LAMMPS, 29 Sep 2021 update 2, measured on a 2-core machine on this problem:
1 process and ``mpirun -np 2``), saying so.

Differences to keep in mind: LAMMPS runs a periodic box with a Berendsen barostat; dem runs the same
disks inside four rigid frictionless servo walls (its experiments' boundary). At 2 cores LAMMPS uses
2 MPI ranks on one run; dem runs single-threaded (a second thread did not pay for one 4,000-disk
run), so at 2 cores it is timed as two independent runs at once (the way a sweep uses the cores).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import dem  # noqa: E402
from dem.contacts import ContactLaw  # noqa: E402

LAMMPS_DIR_ENV = "FEMGRAN_LAMMPS_DIR"
LAMMPS_INPUTS = ("prep.in", "bench.in", "export.in")
# particle-steps/s (low, high) of LAMMPS per core count: Debian's LAMMPS (29 Sep 2021 update 2) on a
# 2-core machine, same problem; 1 process, and 2 MPI ranks
README_FIGURES = {1: (11.9e6, 12.2e6), 2: (19.0e6, 20.3e6)}
LAW = ContactLaw(kn=1e8, kt=2.0 / 7.0 * 1e8, friction=0.5, gamma_n=5e5, gamma_t=2.5e5, local_damping=0.0,
                 density=2650.0)
DT = 1e-7


def read_dump(path: Path):
    """positions (N,2) [m] relative to the box centre, radii (N,), box size (2,) from a LAMMPS dump."""
    lines = path.read_text().splitlines()
    k = lines.index("ITEM: BOX BOUNDS pp pp pp")
    lo_hi = np.array([[float(v) for v in lines[k + 1 + i].split()] for i in range(2)])
    start = next(i for i, ln in enumerate(lines) if ln.startswith("ITEM: ATOMS")) + 1
    data = np.array([[float(v) for v in ln.split()] for ln in lines[start:]])
    data = data[np.argsort(data[:, 0])]
    size = lo_hi[:, 1] - lo_hi[:, 0]
    pos = data[:, 1:3] - lo_hi.mean(axis=1)
    return pos, data[:, 3], size


def own_packing(seed: int = 12345):
    """Same specification without LAMMPS: 4,096 disks, d uniform 0.2-0.6 mm, compressed to 100 kPa."""
    # number-uniform diameters as a mass-based sieve curve: mass finer ~ (d^3 - a^3) / (b^3 - a^3)
    d_mm = np.linspace(0.2, 0.6, 17)
    finer = 100 * (d_mm**3 - 0.2**3) / (0.6**3 - 0.2**3)
    psd_path = Path(tempfile.mkdtemp()) / "uniform.csv"
    psd_path.write_text("diameter_mm,percent_finer\n" + "".join(f"{a:.4f},{b:.6f}\n" for a, b in zip(d_mm, finer)))
    # prepared with local damping (the benchmark law has none, like LAMMPS), timed with LAW
    prep = LAW.replace(local_damping=0.7)
    sample = dem.generate(4096, psd=psd_path, seed=seed, aspect=1.0, law=prep)
    state = dem.isotropic_compression(sample, p_kPa=100.0, law=prep)
    state.law = LAW
    return state


def bench_state(pos, radii, size) -> dem.DEMState:
    """The packing between walls at the box bounds, settled under 100 kPa servo walls (not timed)."""
    state = dem.DEMState(positions=pos, radii=radii, half_size=0.5 * np.asarray(size), law=LAW)
    # disks straddling the periodic boundary overlap the walls: push them inside first
    for c in range(2):
        lim = 0.5 * size[c] - radii
        state.positions[:, c] = np.clip(state.positions[:, c], -lim, lim)
    sim = dem.Simulation(state, dt=DT)
    sim.set_servo((-100.0, -100.0), max_rate=5.0)
    sim.advance(20000)
    return state


def run_dem(state: dem.DEMState, steps: int) -> float:
    """Particle-steps per second of biaxial loading (axial -1/s, lateral servo 100 kPa)."""
    st = state.copy()
    sim = dem.Simulation(st, dt=DT)
    st.boundary_rate[:] = [[0.0, 0.0], [0.0, -1.0]]
    sim.set_servo((-100.0, None), max_rate=2.0)
    sim.advance(200)  # warm-up (JIT already compiled by the settling run)
    t0 = time.perf_counter()
    sim.advance(steps)
    return st.n_particles * steps / (time.perf_counter() - t0)


def _worker(args):
    path, steps = args
    return run_dem(dem.load(path), steps)


def run_lammps(workdir: Path, steps: int, ranks: int) -> float | None:
    cmd = ["lmp", "-in", "bench.in", "-var", "N", str(steps)]
    if ranks > 1:
        if shutil.which("mpirun") is None:
            return None
        cmd = ["mpirun", "--allow-run-as-root", "-np", str(ranks)] + cmd
    out = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True)
    m = re.search(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms", out.stdout)
    if m is None:
        print(f"  LAMMPS ({ranks} rank(s)) failed: {out.stderr.strip()[-300:]}")
        return None
    loop, _, n, atoms = float(m.group(1)), m.group(2), int(m.group(3)), int(m.group(4))
    return atoms * n / loop


def prepare_lammps(workdir: Path) -> bool:
    """Make ``packing.dump`` in ``workdir`` with LAMMPS if needed; False without ``lmp`` or its inputs."""
    if shutil.which("lmp") is None:
        return False
    missing = [name for name in LAMMPS_INPUTS if not (workdir / name).exists()]
    if missing:
        print(f"LAMMPS inputs {missing} not in {workdir}: LAMMPS not run")
        return False
    if not (workdir / "dense100kPa.restart").exists():
        subprocess.run(["lmp", "-in", "prep.in"], cwd=workdir, capture_output=True, check=True)
    if not (workdir / "packing.dump").exists():
        subprocess.run(["lmp", "-in", "export.in"], cwd=workdir, capture_output=True, check=True)
    return True


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--lammps-dir", type=Path, default=None,
                    help=f"folder with packing.dump and/or prep.in, bench.in, export.in (default: ${LAMMPS_DIR_ENV}; "
                         "neither: dem's own packing and the quoted LAMMPS figures)")
    ap.add_argument("--no-lammps", action="store_true", help="do not run LAMMPS even if installed")
    ap.add_argument("--protocol", action="store_true", help="also time the full thesis protocol for 4,000 disks")
    args = ap.parse_args(argv)

    env_dir = os.environ.get(LAMMPS_DIR_ENV)
    workdir = args.lammps_dir or (Path(env_dir) if env_dir else None)
    if workdir is not None and not workdir.is_dir():
        ap.error(f"LAMMPS folder {str(workdir)!r} does not exist")
    have_lammps = workdir is not None and (not args.no_lammps) and prepare_lammps(workdir)
    dump = None if workdir is None else workdir / "packing.dump"
    if dump is not None and dump.exists():
        pos, radii, size = read_dump(dump)
        print(f"packing: LAMMPS packing.dump ({len(radii)} disks, box {size[0] * 1e3:.2f} x {size[1] * 1e3:.2f} mm)")
        state = bench_state(pos, radii, size)
    else:
        why = "no LAMMPS folder given" if workdir is None else f"no packing.dump in {workdir}"
        print(f"packing: {why} -> dem generated a packing of the same specification")
        state = own_packing()
    print(f"settled state: Z = {dem.coordination_number(state, exclude_rattlers=False):.2f} contacts/disk, "
          f"wall stress {np.diag(dem.stress_from_walls(state)).round(1)} kPa")
    print(f"same law: kn={LAW.kn:.3g} N/m, kt={LAW.kt:.3g}, gamma_n={LAW.gamma_n:.3g} 1/s, mu={LAW.friction}, dt={DT:g} s; "
          f"{args.steps} steps of biaxial loading")
    print("(the machine is shared with other jobs: figures fluctuate)")

    ours1 = run_dem(state, args.steps)
    path = Path(tempfile.mkdtemp()) / "bench_state.npz"
    dem.save(state, path)
    with mp.get_context("spawn").Pool(2) as pool:
        t0 = time.perf_counter()
        pool.map(_worker, [(path, args.steps)] * 2)  # compile/warm the workers
        t0 = time.perf_counter()
        rates = pool.map(_worker, [(path, args.steps)] * 2)
    ours2 = sum(rates)

    for cores, ours in ((1, ours1), (2, ours2)):
        measured = run_lammps(workdir, args.steps, cores) if have_lammps else None
        if measured is not None:
            base, label = measured, "LAMMPS measured now"
        else:
            lo, hi = README_FIGURES[cores]
            base, label = 0.5 * (lo + hi), (f"LAMMPS {lo / 1e6:.1f}-{hi / 1e6:.1f} M (not run here: quoted figure, "
                                            "Debian LAMMPS 29 Sep 2021 on a 2-core machine)")
        print(f"{cores} core(s): dem {ours / 1e6:6.2f} M particle-steps/s | {label}: {base / 1e6:6.2f} M | "
              f"ratio dem/LAMMPS = {ours / base:.2f}")

    if args.protocol:
        t0 = time.perf_counter()
        sample = dem.generate(4000, seed=1)
        t1 = time.perf_counter()
        iso = dem.isotropic_compression(sample, p_kPa=100.0)
        t2 = time.perf_counter()
        run = dem.biaxial(iso, axial_strain=0.05)
        t3 = time.perf_counter()
        dem.rotate_strain(run.final, rotation_deg=90.0)
        t4 = time.perf_counter()
        print(f"thesis protocol, 4000 disks, 1 core: generation {t1 - t0:.0f} s, isotropic {t2 - t1:.0f} s, "
              f"biaxial (5 %) {t3 - t2:.0f} s, rotation 90 deg {t4 - t3:.0f} s; total {t4 - t0:.0f} s")


if __name__ == "__main__":
    main()
