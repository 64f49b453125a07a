"""Speed of the CPA update past limit points: the kernel's continuation against the reference loop.

The points are the two stored in the tests: the fold point of the alpha = 0 footing (the thesis's law,
one limit point per step along its line) and the near-failure point (8 limit points in one step). The
kernel (`material._cpa_point.update_past_limits`, numba, warm-started bisection) is timed against
`material.cpa_reference.follow_past_limits` (the first version: a Python loop over the points' arrays,
bisecting the whole fraction with solves from the start of the rest), both without the tangent, and the
kernel with its forward-difference tangent (whose continuations skip the solves that failed far
beyond the limit in the step's own). Times are the best of ``--repeat`` runs after a warm-up; the
ratios are what to quote.

    python benchmarks/limit_points.py [--repeat 3] [--copies 4]
"""

from __future__ import annotations

import argparse
import json
import timeit
from pathlib import Path

import numpy as np

from material.cpa import CPAModel
from material.cpa_reference import follow_past_limits
from material.parameters import parameters_from_dict

DATA = Path(__file__).resolve().parents[1] / "tests" / "material" / "data"


def _point(name, copies, s=None):
    d = dict(np.load(DATA / name))
    model = CPAModel(parameters_from_dict(json.loads(str(d["params_json"]))), rule=str(d["rule"]), axes=d["axes"])
    state = {k[len("state__"):]: v for k, v in d.items() if k.startswith("state__")}
    de = d["d_strain"][:1]
    if s is not None:  # along the stored Newton direction: one limit point per step
        de = de + np.asarray(s)[:, None, None] * d["direction"][:1]
    n = de.shape[0] * copies
    rep = np.arange(n) % de.shape[0]
    return model, np.ascontiguousarray(de[rep]), d["stress"][:1][np.zeros(n, int)], \
        {k: v[:1][np.zeros(n, int)] for k, v in state.items()}


def _best(fn, repeat):
    """The shortest of `repeat` timed calls, after one untimed call that compiles the kernel."""
    fn()
    return min(timeit.repeat(fn, number=1, repeat=repeat))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--copies", type=int, default=4, help="copies of each point in the batch")
    args = ap.parse_args(argv)
    cases = {
        "fold point, s = 1e-3 .. 4e-3 (1 limit point)": _point("footing_fold_point.npz", args.copies,
                                                                [1e-3, 2e-3, 3e-3, 4e-3]),
        "near-failure point (8 limit points)": _point("near_failure_point.npz", args.copies),
    }
    print(f"{'points':48s} {'n':>4s} {'reference s':>12s} {'kernel s':>10s} {'ratio':>7s} {'kernel+tangent s':>17s}")
    for label, (model, de, sig, state) in cases.items():
        t_ref = _best(lambda: follow_past_limits(model, de, sig, state), args.repeat)
        t_ker = _best(lambda: model.update(de, sig, state, tangent=False), args.repeat)
        t_tan = _best(lambda: model.update(de, sig, state, tangent=True), args.repeat)
        print(f"{label:48s} {de.shape[0]:4d} {t_ref:12.3f} {t_ker:10.3f} {t_ref / t_ker:7.1f} {t_tan:17.3f}")


if __name__ == "__main__":
    main()
