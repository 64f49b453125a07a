"""Why a global Newton step of the CPA footing is cut short: the points with a kink along its direction.

Runs the isotropic CPA footing (the Mohr-Coulomb solid of ``footing_speed.py``) and, at the first
iteration of step ``--step`` or later whose line search accepts s <= 0.1, evaluates every Gauss point
along the Newton direction (``femgran.diagnostics.solver_kinks_along``, s = 0 ... ``--s-max``) and prints
how many points have a kink there, and the worst ones: where (s), how strong (the jump of the stress
rate relative to its largest value), how many planes load on either side, the point's stress.

    python benchmarks/footing_kinks.py [--E 60000] [--resolution 2] [--step 15] [--s-max 0.4]
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> None:
    import femgran.solver as solver_module
    from femgran.cases import footing
    from femgran.diagnostics import solver_kinks_along
    from footing_speed import _material  # the same soils as the speed benchmark (this folder is on the path)

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--E", type=float, default=60000.0)
    ap.add_argument("--resolution", type=int, default=2)
    ap.add_argument("--step", type=int, default=15, help="probe from this load step on (of 40)")
    ap.add_argument("--s-max", type=float, default=0.4)
    args = ap.parse_args(argv)

    # a wrapper around the solver's line search (this script only): probe once, then run as usual
    line_search, step_of = solver_module.NewtonSolver._line_search, solver_module.NewtonSolver.step
    where = {"step": 0, "done": False}

    def step(self, t_new, *, step=0, attempt=0):
        where["step"] = step
        return step_of(self, t_new, step=step, attempt=attempt)

    def probed(self, evaluate, du, ddu, it, rf):
        out = line_search(self, evaluate, du, ddu, it, rf)
        if not where["done"] and where["step"] >= args.step and out[0] <= 0.1 and it >= 3:
            where["done"] = True
            s = np.linspace(0.0, args.s_max, 101)
            k = solver_kinks_along(self, du, ddu, s)
            sig = np.abs(self.points.stress).max(axis=(1, 2))
            strong = k["slope_jump"] > 0.1
            print(f"step {where['step']}, iteration {it}: line search accepted s = {out[0]:.3g}; "
                  f"{strong.sum()} of {len(sig)} points have a kink (stress-rate jump > 10 %) for s <= {args.s_max}; "
                  f"median jump {np.median(k['slope_jump']):.1e}")
            for p in np.argsort(-k["slope_jump"])[:8]:
                print(f"  point {p}: kink at s = {k['s_kink'][p]:.3f}, jump {k['slope_jump'][p]:.2f}, loading planes "
                      f"{k['loading_before'][p]} -> {k['loading_after'][p]}, |sigma| {sig[p]:.2f} kPa")
        return out

    solver_module.NewtonSolver.step, solver_module.NewtonSolver._line_search = step, probed
    try:
        footing(_material("cpa-isotropic", args.E, 0.0), resolution=args.resolution, steps=40,
                settlement_m=0.1 * min(40, args.step + 5) / 40, plots=False, out="out/footing_kinks")
    finally:
        solver_module.NewtonSolver.step, solver_module.NewtonSolver._line_search = step_of, line_search
    if not where["done"]:
        print("no short line-search step met from step", args.step)


if __name__ == "__main__":
    main()
