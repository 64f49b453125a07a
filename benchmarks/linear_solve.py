"""The direct solver's ordering and pivoting on the solver's own matrices.

Three SuperLU factorisations: scipy's default (COLAMD ordering, partial pivoting), the solver's ordering
:data:`femgran.solver.DIRECT_ORDERING` with partial pivoting, and the solver's own (that ordering with the
diagonal preferred as pivot, :data:`femgran.solver.DIAG_PIVOT_THRESHOLD`). Runs each case until the Newton
solver's ``nth`` linear solve, takes that matrix and right-hand side and solves them all three ways, printing
the best of ``--repeat`` times, the fill of L + U and the relative residual of each, and the time ratios
against scipy's default. The cases:

* ``footing``: the default strip footing (resolution 3) on the plane-strain Drucker-Prager cone;
* ``cpa_footing``: the same footing on the thesis sand (``femgran footing --alpha 0``'s material);
* ``band24`` / ``band48``: the quadratic shear-band study of ``examples/fe_04_biaxial_meshes.py`` with the
  implicit gradient (l = 6 mm, H = 3 W, 24 / 48 elements across: the coupled displacement-nonlocal
  system, structurally symmetric but not symmetric);
* ``gradient``: the CPA run of ``benchmarks/gradient.py`` with the implicit gradient (12 linear elements
  across, 923 DOFs, to 4.2 %): the coupled system through the whole softening (take ``--nth 400``);
* ``triaxial``: the 3D specimen with rough platens (``femgran triaxial``'s default mesh).

With ``--whole-run N`` it also runs each case's first N steps once with each factorisation (in this
process, one after the other) and prints, for each, the wall time, the time in the direct solves, their
number, the largest relative residual and the largest fill: what the factorisation saves a whole run, the
material updates and assemblies included, and that the runs took the same Newton iterations.

    python benchmarks/linear_solve.py [--cases footing cpa_footing band24 band48 gradient triaxial]
                                      [--repeat 3] [--nth 3] [--whole-run N]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

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


def _gradient():
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from gradient import _setups

    laws, case = _setups("cpa", None, None)
    return case, laws["gradient"]


CASES = {
    "footing": lambda: (Footing(resolution=3), {"law": "drucker_prager", "E_kPa": 6000.0, "nu": 0.3,
                                                "cohesion_kPa": 0.0, "friction_deg": 30.0}),
    "cpa_footing": lambda: (Footing(resolution=3, alpha_deg=0.0), {"preset": "ottawa_c109"}),
    "band24": lambda: _band(24),
    "band48": lambda: _band(48),
    "gradient": _gradient,
    "triaxial": lambda: (Triaxial(platens="rough"), {"preset": "ottawa_c109", "stabilisation": 0.1}),
}


class _Taken(BaseException):
    """Raised from inside the solver once the matrix is taken (not an Exception: no cut-back catches it)."""

    def __init__(self, K, b):
        super().__init__()
        self.K, self.b = K, b


#: name: (ordering, splu keywords); the first is the baseline of the ratios, the last the solver's own.
FACTORISATIONS = {
    "COLAMD": ("COLAMD", {}),
    "MMD": (fsolver.DIRECT_ORDERING, {}),
    "MMD+diag": (fsolver.DIRECT_ORDERING, {"diag_pivot_thresh": fsolver.DIAG_PIVOT_THRESHOLD,
                                           "options": {"SymmetricMode": True}}),
}


def _factor(K, name: str):
    ordering, keywords = FACTORISATIONS[name]
    return spla.splu(K.tocsc(), permc_spec=ordering, **keywords)


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


def whole_run(name: str, steps: int, factorisation: str) -> dict:
    """Case ``name``'s first ``steps`` steps with the direct solves by ``factorisation``: wall time, the
    solves' time, their number, largest relative residual and largest fill."""
    case, material = CASES[name]()
    seen = []

    def solving(K, b):
        t0 = time.perf_counter()
        lu = _factor(K, factorisation)
        x = lu.solve(b)
        seen.append((time.perf_counter() - t0, np.linalg.norm(K @ x - b) / np.linalg.norm(b), lu.L.nnz + lu.U.nnz))
        return x

    original = fsolver.direct_solve
    fsolver.direct_solve = solving
    try:
        t0 = time.perf_counter()
        run(case, material, solver={"linear_solver": "superlu"}, output=Output(None), max_steps=steps)
        wall = time.perf_counter() - t0
    finally:
        fsolver.direct_solve = original
    a = np.array(seen)
    return {"wall": wall, "solves": a[:, 0].sum(), "n": len(a), "residual": a[:, 1].max(), "fill": a[:, 2].max()}


def _time(K, b, factorisation: str, repeat: int):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        lu = _factor(K, factorisation)
        x = lu.solve(b)
        best = min(best, time.perf_counter() - t0)
    return best, lu.L.nnz + lu.U.nnz, np.linalg.norm(K @ x - b) / np.linalg.norm(b)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", choices=tuple(CASES), default=list(CASES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nth", type=int, default=3, help="take the matrix of this linear solve of each run")
    ap.add_argument("--whole-run", type=int, default=0, metavar="N", help="also time the first N steps of each run "
                    "with each factorisation")
    args = ap.parse_args(argv)
    names = list(FACTORISATIONS)
    print("time [ms] / fill of L + U / relative residual of each factorisation; time ratio against " + names[0])
    for name in args.cases:
        K, b = take_matrix(name, args.nth)
        rows = {f: _time(K, b, f, args.repeat) for f in names}
        base = rows[names[0]][0]
        print(f"{name} ({K.shape[0]} DOFs, {K.nnz} entries, solve {args.nth}):")
        for f, (t, fill, res) in rows.items():
            print(f"  {f:<10}{t * 1e3:10.2f}{fill:>11}{res:>10.1e}   ratio {base / t:5.2f}")
    if args.whole_run:
        print(f"\nthe first {args.whole_run} steps of each run: wall [s], the direct solves [s], their number, "
              f"largest relative residual, largest fill")
        for name in args.cases:
            for f in names:
                r = whole_run(name, args.whole_run, f)
                print(f"  {name:<12}{f:<10}{r['wall']:8.1f}{r['solves']:8.2f}{r['n']:6d}{r['residual']:10.1e}"
                      f"{r['fill']:>10.0f}")


if __name__ == "__main__":
    main()
