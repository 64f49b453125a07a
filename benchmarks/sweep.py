"""Sweep engine: a study on a local Dask cluster against the same runs one after the other, in one process.

    python benchmarks/sweep.py [--runs 8] [--kind element|footing] [--workers 2]

``element``: drained triaxial element tests (600 steps each, p0 from 50 kPa up); ``footing``: the strip
footing on its coarse mesh (resolution 2, 20 steps, the CPA law with the step stabilisation 0.1) at
alpha = 0, 30, 60, 90 (more runs: with surcharges of 2, 4... kPa). Prints the wall time of each way (the serial baseline runs first, in this process; the cluster's
start-up and the workers' imports and numba compilations are counted), their ratio (the speed-up,
ideally the number of workers), the runs' own times on the workers, the engine's own cost per run measured on runs that do nothing, and the
time a second call takes to find every run complete (resume).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path


def _runs(kind: str, n: int):
    from material.sweep import Run

    if kind == "element":
        return [Run(f"p0_{50 + 10 * i}", "material.sweep:element",
                    {"test": "triaxial", "steps": 600, "p0_kPa": 50.0 + 10 * i}, {"p0_kPa": 50.0 + 10 * i})
                for i in range(n)]
    # the angles of the figure set (femgran.figures), which all run to their end; more runs add surcharges
    points = [(a, 2.0 * (i // 4)) for i, a in enumerate([0.0, 30.0, 60.0, 90.0] * (n // 4 + 1))][:n]
    return [Run(f"alpha_{a:g}_q_{q:g}", "femgran.sweep:case_target",
                {"case": "footing", "fields": {"alpha_deg": a, "surcharge_kPa": q, "resolution": 2, "steps": 20},
                 "material": {"preset": "ottawa_c109", "stabilisation": 0.1}}, {}) for a, q in points]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--kind", choices=("element", "footing"), default="element")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    from material.sweep import Run, sweep

    runs = _runs(args.kind, args.runs)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sweep(runs[:1], tmp / "warm", scheduler="serial", progress=False)  # this process's numba compilation
        t0 = time.perf_counter()
        serial = sweep(runs, tmp / "serial", scheduler="serial", progress=False)
        t_serial = time.perf_counter() - t0
        t0 = time.perf_counter()
        dask = sweep(runs, tmp / "dask", workers=args.workers, progress=False)
        t_dask = time.perf_counter() - t0
        t0 = time.perf_counter()
        again = sweep(runs, tmp / "dask", workers=args.workers, progress=False)
        t_again = time.perf_counter() - t0
        empty = [Run(f"noop_{i}", "builtins:dict", {}) for i in range(50)]  # dict(out=...): a run doing nothing
        t0 = time.perf_counter()
        sweep(empty, tmp / "noop", scheduler="serial", progress=False)
        t_noop = (time.perf_counter() - t0) / len(empty)
    for name, result in (("serial", serial), ("LocalCluster", dask)):
        for r in result.records:
            if r["status"] != "completed":
                raise SystemExit(f"{name}: run {r['key']} {r['status']}: {r['message']}")
    if again.skipped != len(runs):
        raise SystemExit(f"the second call ran {again.ran} run(s) again instead of none")
    per_run = sum(r["wall_time_s"] for r in serial.records) / len(runs)
    print(f"{len(runs)} {args.kind} runs, {per_run:.2f} s each (serial, one process)")
    print(f"serial, this process:           {t_serial:7.2f} s")
    print(f"LocalCluster, {args.workers} workers:         {t_dask:7.2f} s   speed-up {t_serial / t_dask:.2f} "
          f"(ideal {args.workers}; includes the cluster's start-up and the workers' first compilations)")
    on_workers = sum(r["wall_time_s"] for r in dask.records)
    first = sorted(r["wall_time_s"] for r in dask.records)[-args.workers:]
    print(f"  the runs' own times on the workers: {on_workers:.2f} s in all ({on_workers / len(runs):.2f} s each; the "
          f"slowest {', '.join(f'{t:.2f}' for t in first)} s: a worker's first run imports and loads the kernels)")
    print(f"again (all complete, resume):   {t_again:7.3f} s")
    print(f"engine cost per run (no-op run): {1e3 * t_noop:6.1f} ms  ({t_noop / per_run:.3f} of a run)")


if __name__ == "__main__":
    main()
