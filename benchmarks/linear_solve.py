"""The direct solver's fill-reducing ordering on the solver's own matrices.

Runs each case until the Newton solver's ``nth`` linear solve, takes that matrix and right-hand side,
and solves them with SuperLU under scipy's default column ordering (COLAMD) and under the solver's
:data:`femgran.solver.DIRECT_ORDERING`, printing the best of ``--repeat`` times, the fill of L + U, the
time ratio and the difference of the solutions. The cases:

* ``footing``: the default strip footing (resolution 3) on the plane-strain Drucker-Prager cone;
* ``band24`` / ``band48``: the quadratic shear-band study of ``examples/fe_04_biaxial_meshes.py`` with the
  implicit gradient (l = 6 mm, H = 3 W, 24 / 48 elements across: the coupled displacement-nonlocal
  system, structurally symmetric but not symmetric);
* ``triaxial``: the 3D specimen with rough platens (``femgran triaxial``'s default mesh).

With ``--whole-run N`` it also runs each case's first N steps once with each ordering (in this process,
one after the other) and prints the wall times and their ratio: what the ordering saves a whole run, the
material updates and assemblies included.

    python benchmarks/linear_solve.py [--cases footing band24 band48 triaxial] [--repeat 3] [--nth 3]
                                      [--whole-run N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse.linalg as spla

import femgran.solver as fsolver
from femgran.cases import Biaxial, Footing, Output, Triaxial, run

BAND_MATERIAL = {"preset": "ottawa_c109", "stabilisation": 0.01, "nonlocal_length": 0.006,
                 "set": {"E": 60000.0, "zeta": 1.05, "softening_slip": 0.03, "residual_ratio": 0.65,
                         "eta_c_ratio": 0.0}}


def _band(n: int):
    case = Biaxial(p0_kPa=100.0, axial_strain=0.015, steps=60, imperfection=0.0, weak_zone=0.1,
                   weak_zone_height=1 / 18, weak_zone_size=1 / 3, platens="rough", height_ratio=3.0,
                   resolution=n, order=2)
    return case, BAND_MATERIAL


CASES = {
    "footing": lambda: (Footing(resolution=3), {"law": "drucker_prager", "E_kPa": 6000.0, "nu": 0.3,
                                                "cohesion_kPa": 0.0, "friction_deg": 30.0}),
    "band24": lambda: _band(24),
    "band48": lambda: _band(48),
    "triaxial": lambda: (Triaxial(platens="rough"), {"preset": "ottawa_c109", "stabilisation": 0.1}),
}


class _Taken(BaseException):
    """Raised from inside the solver once the matrix is taken (not an Exception: no cut-back catches it)."""

    def __init__(self, K, b):
        super().__init__()
        self.K, self.b = K, b


def take_matrix(name: str, nth: int):
    """(K, b) of the ``nth`` direct solve of case ``name``."""
    case, material = CASES[name]()
    seen = [0]
    original = fsolver.direct_solve

    def taking(K, b):
        seen[0] += 1
        if seen[0] == nth:
            raise _Taken(K.tocsc(), np.array(b))
        return original(K, b)

    fsolver.direct_solve = taking
    try:
        run(case, material, solver={"linear_solver": "superlu"}, output=Output(None))
    except _Taken as taken:
        return taken.K, taken.b
    finally:
        fsolver.direct_solve = original
    raise RuntimeError(f"{name}: fewer than {nth} linear solves")


def whole_run(name: str, steps: int, ordering: str) -> float:
    """Wall time of case ``name``'s first ``steps`` steps with the direct solver's ``ordering``."""
    case, material = CASES[name]()
    saved = fsolver.DIRECT_ORDERING
    fsolver.DIRECT_ORDERING = ordering
    try:
        t0 = time.perf_counter()
        run(case, material, solver={"linear_solver": "superlu"}, output=Output(None), max_steps=steps)
        return time.perf_counter() - t0
    finally:
        fsolver.DIRECT_ORDERING = saved


def _time(K, b, ordering: str, repeat: int):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        lu = spla.splu(K, permc_spec=ordering)
        x = lu.solve(b)
        best = min(best, time.perf_counter() - t0)
    return best, lu.L.nnz + lu.U.nnz, x


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", choices=tuple(CASES), default=list(CASES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nth", type=int, default=3, help="take the matrix of this linear solve of each run")
    ap.add_argument("--whole-run", type=int, default=0, metavar="N", help="also time the first N steps of each run "
                    "with either ordering")
    args = ap.parse_args(argv)
    new = fsolver.DIRECT_ORDERING
    print(f"{'case':<10}{'DOFs':>8}{'nnz':>10}{'COLAMD [s]':>12}{new + ' [s]':>20}{'fill ratio':>12}"
          f"{'time ratio':>12}{'|dx|/|x|':>10}")
    for name in args.cases:
        K, b = take_matrix(name, args.nth)
        t_old, fill_old, x_old = _time(K, b, "COLAMD", args.repeat)
        t_new, fill_new, x_new = _time(K, b, new, args.repeat)
        diff = np.abs(x_new - x_old).max() / np.abs(x_old).max()
        print(f"{name:<10}{K.shape[0]:>8}{K.nnz:>10}{t_old:>12.4f}{t_new:>20.4f}{fill_new / fill_old:>12.2f}"
              f"{t_old / t_new:>12.2f}{diff:>10.1e}")
    if args.whole_run:
        print(f"\nthe first {args.whole_run} steps of each run [s]:")
        for name in args.cases:
            t_old, t_new = (whole_run(name, args.whole_run, o) for o in ("COLAMD", new))
            print(f"{name:<10} COLAMD {t_old:8.1f}   {new} {t_new:8.1f}   ratio {t_old / t_new:5.2f}")


if __name__ == "__main__":
    main()
