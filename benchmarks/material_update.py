"""Speed of the CPA Gauss-point update (issue: >= 300,000 updates/s per core with the tangent).

100,000 Gauss points are brought to a hardening state (a drained-triaxial-like strain path at
p0 = 100 kPa, spread over the points so that mobilisation varies from ~0.2 to ~0.8), then one more
strain increment is integrated: with the consistent tangent on 1 and 2 threads, and without the
tangent. Baseline in the same process: the linear-elastic update of material.LinearElastic.

The last lines put the update against this core's arithmetic: the floating-point operations of one update,
counted from the source of ``material._cpa_local.evaluate`` (:data:`FLOPS_PER_PLANE`) times the evaluations
of the residual and Jacobian it needs (at least its local Newton iterations + 1), over the rate at which
the same core multiplies two 1024 x 1024 matrices (numpy's BLAS on one thread: about the most a core
does). So a reader sees what share of the core the kernel uses and what share the target of 300,000
updates/s would need.

    python benchmarks/material_update.py [--points 100000] [--repeat 3] [--rule bazant-oh-33] [--stabilisation MU]
"""

from __future__ import annotations

import os

# one BLAS thread for the matrix product that measures the core (read when numpy loads its BLAS; the CPA
# kernel itself calls no BLAS)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import timeit  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from material import CPAModel, LinearElastic, load_preset  # noqa: E402
from material.anisotropy import axes_from_alpha  # noqa: E402

#: Floating-point operations per plane of one evaluation of ``material._cpa_local.evaluate`` with the
#: Jacobian (a loading plane on its hardening branch; a square root or a division counted as one, although
#: each takes the core several times an addition's slot, so the count is low rather than high), by pass:
FLOPS_PER_PLANE = {
    "stress measures: traction, sigma_n, shear traction, tau, T, 1/sigma~, 1/T, compaction weight, s": 58,
    "directions: r = n x s, sym(s (x) n), sym(r (x) n), flow vector m and b (6 components each)": 75,
    "plane law: hardening, Fischer-Burmeister and its derivatives, slip linearisation, 7 coefficients": 68,
    "sums: the strain residual (6 rows x 2 sums)": 24,
    "sums: the Jacobian (6 rows x (u, v, z and 6 entries of 3 products))": 258,
}


def _hardening_state(model, n, rng):
    sig = np.repeat(-100.0 * np.eye(3)[None], n, axis=0)
    state = model.initial_state(n, stress=sig)
    base = np.array([[0.8e-3, 1e-4, 2e-4], [1e-4, 0.6e-3, -1.5e-4], [2e-4, -1.5e-4, -2e-3]])
    scale = rng.uniform(0.5, 2.0, size=n)[:, None, None]
    de = base[None] * scale
    for _ in range(6):
        sig, state, _ = model.update(de, sig, state)
    return sig, state, de


def _best(fn, repeat):
    """The shortest of `repeat` timed calls (the caller has compiled the kernel)."""
    return min(timeit.repeat(fn, number=1, repeat=repeat))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rule", default="bazant-oh-33")
    ap.add_argument("--stabilisation", default=None, help="of the CPA law (default: CPAModel's)")
    args = ap.parse_args(argv)
    n = args.points
    rng = np.random.default_rng(0)
    options = {} if args.stabilisation is None else {"stabilisation": args.stabilisation}
    model = CPAModel(load_preset("ottawa_c109"), rule=args.rule, axes=axes_from_alpha(30.0), **options)
    sig, state, de = _hardening_state(model, n, rng)
    mob = state["mobilised_ratio"]
    print(f"CPA update, {n} points, rule {args.rule} ({model.n_planes} planes); mobilised ratio "
          f"{mob.min():.2f}..{mob.max():.2f} (median {np.median(mob):.2f})")
    model.update(de[:10], sig[:10], {k: v[:10] for k, v in state.items()})  # compile
    max_threads = numba.config.NUMBA_NUM_THREADS
    results = {}
    for threads in sorted({1, min(2, max_threads)}):
        numba.set_num_threads(threads)
        t = _best(lambda: model.update(de, sig, state), args.repeat)
        results[("tangent", threads)] = t
        t = _best(lambda: model.update(de, sig, state, tangent=False), args.repeat)
        results[("no tangent", threads)] = t
    numba.set_num_threads(max_threads)
    _, st1, _ = model.update(de, sig, state)
    its = st1["iterations"]
    print(f"Newton iterations per point: mean {its.mean():.2f}, max {its.max()}; "
          f"points that needed continuation: {(st1['continuation'] > 0).sum()}")
    elastic = LinearElastic(6000.0, 0.33)
    est = elastic.initial_state(n)
    t_el = _best(lambda: elastic.update(de, sig, est), args.repeat)
    print(f"{'variant':<28}{'time [s]':>10}{'updates/s':>14}{'per thread':>14}")
    for (kind, threads), t in results.items():
        print(f"{kind + f', {threads} thread(s)':<28}{t:>10.3f}{n / t:>14,.0f}{n / t / threads:>14,.0f}")
    print(f"{'baseline LinearElastic':<28}{t_el:>10.3f}{n / t_el:>14,.0f}")
    t1 = results[("tangent", 1)]
    print(f"ratio CPA(tangent, 1 thread) / LinearElastic: {t1 / t_el:.1f}x the time")
    # the "minimal" step stabilisation computes each plastic point's floor from its rate problem
    other = "minimal" if model.options.stabilisation != "minimal" else 0.0
    numba.set_num_threads(1)
    t_other = _best(lambda: model.replace(stabilisation=other).update(de, sig, state), args.repeat)
    numba.set_num_threads(max_threads)
    print(f"stabilisation {other!r} (tangent, 1 thread): {n / t_other:,.0f} updates/s, {t_other / t1:.2f}x the "
          f"time of {model.options.stabilisation!r}")
    print(f"target >= 300,000 updates/s per core with tangent: {n / t1:,.0f} on 1 thread "
          f"({'met' if n / t1 >= 3e5 else 'NOT met'})")
    _arithmetic(model.n_planes, its.mean(), n / t1, args.repeat)


def _arithmetic(planes: int, iterations: float, rate: float, repeat: int) -> None:
    """Print the update's floating-point operations against this core's matrix-product rate."""
    a = np.random.default_rng(1).random((1024, 1024))
    peak = 2.0 * 1024**3 / _best(lambda: a @ a, repeat)
    per_update = planes * sum(FLOPS_PER_PLANE.values()) * (iterations + 1.0)
    print(f"arithmetic: >= {per_update:,.0f} flops per update ({planes} planes x {sum(FLOPS_PER_PLANE.values())} "
          f"x {iterations + 1.0:.2f} evaluations, counted from the source); this core's 1024^2 matrix product "
          f"on one thread: {peak / 1e9:.1f} GFLOP/s")
    print(f"  the update uses {rate * per_update / 1e9:.2f} GFLOP/s ({rate * per_update / peak:.0%} of it); "
          f"300,000 updates/s would need {3e5 * per_update / 1e9:.1f} GFLOP/s ({3e5 * per_update / peak:.0%}); "
          f"at the full rate {peak / per_update:,.0f} updates/s")


if __name__ == "__main__":
    main()
