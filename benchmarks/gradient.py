"""Cost of the implicit-gradient regularisation: the same biaxial run with and without it, same mesh.

Plane-strain biaxial test (femgran.cases.Biaxial, W = 50 mm, p0 = 50 kPa, 4 % axial strain) of a softening
von Mises solid (E = 20 MPa, sigma_y = 150 kPa, H = -1 MPa), local (material.VonMises) and with the implicit
gradient (material.GradientVonMises, l = 10 mm), on one mesh; prints the wall time of each (best of
``--repeat``), the Newton iterations per step, and the ratio gradient / local. The local run is the
baseline in the same process. (The CPA law does not take the gradient yet; this measures the coupled
solver on the reference law.)

    python benchmarks/gradient.py [--resolution 10] [--steps 80] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from femgran.cases import Biaxial, Output, run
from material import GradientVonMises, VonMises


def _once(law, resolution: int, steps: int):
    t0 = time.perf_counter()
    sol = run(Biaxial(p0_kPa=50.0, axial_strain=0.04, steps=steps, resolution=resolution), law, output=Output(None))
    return time.perf_counter() - t0, sol


def main(argv=None) -> float:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resolution", type=int, default=10, help="elements across the width (the local run must "
                                                                 "complete: 10 does, finer meshes stop)")
    ap.add_argument("--steps", type=int, default=80)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    laws = {"local": VonMises(20000.0, 0.3, 150.0, -1000.0),
            "gradient": GradientVonMises(20000.0, 0.3, 150.0, -1000.0, length_m=0.01)}
    _once(laws["gradient"], 2, 2)  # compile
    best = {}
    for name, law in laws.items():
        times = []
        for _ in range(args.repeat):
            dt, sol = _once(law, args.resolution, args.steps)
            times.append(dt)
        its = np.asarray(sol.history["iterations"][1:], float)
        best[name] = min(times)
        print(f"{name:9s} {best[name]:7.2f} s (min of {args.repeat}), {its.mean():.2f} Newton iterations per step, "
              f"completed {sol.completed}, final q {sol.history['q_kPa'][-1]:.1f} kPa")
    ratio = best["gradient"] / best["local"]
    print(f"ratio gradient / local on {args.resolution} elements across: {ratio:.2f} (target <= 2)")
    return ratio


if __name__ == "__main__":
    main()
