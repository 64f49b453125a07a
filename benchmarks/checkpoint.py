"""Checkpoint cost: writing one against one Newton iteration, its size on disk, and the resume time.

    python benchmarks/checkpoint.py [--resolution 8] [--steps 3]

Runs the triaxial specimen (CPA ``ottawa_c109``, 33 planes, hexahedra resolution x resolution x 2
resolution, 8 points each) with a checkpoint after every step, and prints: the mean time of one Newton
iteration (the step's wall time over its iterations), the time a checkpoint costs the run (the copy of
its state; the files are written by a background thread) and the time writing its files takes, their
ratios to one iteration (target: below 0.1), the size of one checkpoint on disk, and the time to load and
restore it.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resolution", type=int, default=8)
    ap.add_argument("--steps", type=int, default=3)
    args = ap.parse_args(argv)

    from femgran import checkpoint as ck
    from femgran.cases import Output, Triaxial, run

    writes: list[float] = []
    files: list[float] = []
    original, original_files = ck.Checkpointer.write, ck.Checkpointer._write_files

    def timed(self, *a, **k):
        self.wait()  # not the previous checkpoint's files: this one's cost to the run
        t0 = time.perf_counter()
        out = original(self, *a, **k)
        writes.append(time.perf_counter() - t0)
        return out

    def timed_files(self, *a, **k):
        t0 = time.perf_counter()
        original_files(self, *a, **k)
        files.append(time.perf_counter() - t0)

    ck.Checkpointer.write, ck.Checkpointer._write_files = timed, timed_files
    case = Triaxial(resolution=args.resolution, steps=args.steps, axial_strain=0.002 * args.steps, platens="rough")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        sol = run(case, "ottawa_c109", output=Output(out, plots=False, write_every=1000, checkpoint_every=1))
        h = sol.history
        per_iteration = float(np.sum(h["wall_time_s"][1:]) / np.sum(h["iterations"][1:]))
        last = ck.latest(out)
        size = last.stat().st_size + last.with_suffix(".npz").stat().st_size
        t0 = time.perf_counter()
        resumed = run(case, "ottawa_c109", output=Output(out, plots=False, write_every=1000), resume=True)
        resume_s = time.perf_counter() - t0
    ck.Checkpointer.write, ck.Checkpointer._write_files = original, original_files
    n_points = 8 * args.resolution**3 * 2
    write_s = float(np.mean(writes[1:] if len(writes) > 1 else writes))
    files_s = float(np.mean(files[1:] if len(files) > 1 else files))
    print(f"triaxial specimen, resolution {args.resolution}: {n_points} points x 33 planes, "
          f"{sol.extra['params']['ndofs']} DOFs, {len(h) - 1} steps, completed {sol.completed and resumed.completed}")
    print(f"one Newton iteration {per_iteration * 1e3:.1f} ms; a checkpoint costs the run {write_s * 1e3:.1f} ms "
          f"(ratio {write_s / per_iteration:.3f}, target < 0.1); its files take {files_s * 1e3:.1f} ms in the "
          f"background (ratio {files_s / per_iteration:.3f})")
    print(f"checkpoint size {size / 2**20:.1f} MiB ({size / n_points:.0f} bytes per point); "
          f"resume (load, restore, rebuild the run) {resume_s:.2f} s")


if __name__ == "__main__":
    main()
