"""Cost of the implicit-gradient regularisation: the same biaxial run with and without it, same mesh.

``--law von_mises`` (default): plane-strain biaxial test (femgran.cases.Biaxial, W = 50 mm, p0 = 50 kPa,
4 % axial strain) of a softening von Mises solid (E = 20 MPa, sigma_y = 150 kPa, H = -1 MPa), local
(material.VonMises) against the implicit gradient (material.GradientVonMises, l = 10 mm).

``--law cpa``: the shear-band study of examples/fe_04 (CPA ottawa_c109 with softening, E = 60 MPa, step
stabilisation 0.1, rough platens, weak corner, p0 = 100 kPa) to 4.2 % in 168 steps, the crack band against
the implicit gradient (l = 6 mm) and the gradient back stress (H_g = 1 MPa, l_b = 6 mm unless ``--back-stress H L``;
four more nodal fields in plane strain).

Prints the wall time of each (best of ``--repeat``), the Newton iterations per step, and the ratio
gradient / baseline (the run without the gradient, in the same process), and for the CPA law the back
stress's too.

    python benchmarks/gradient.py [--law von_mises|cpa] [--resolution R] [--steps S] [--repeat 3] [--back-stress H L]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from femgran.cases import Biaxial, Output, run
from material import GradientVonMises, VonMises


def _once(law, case):
    t0 = time.perf_counter()
    sol = run(case, law, output=Output(None))
    return time.perf_counter() - t0, sol


def _setups(which: str, resolution: int | None, steps: int | None, back_stress=(1000.0, 0.006)):
    """(laws {name: law}, the case) of ``which``; the first law is the baseline. ``back_stress`` is (H_g [kPa],
    l_b [m]) of the CPA law's back stress."""
    if which == "von_mises":
        laws = {"local": VonMises(20000.0, 0.3, 150.0, -1000.0),
                "gradient": GradientVonMises(20000.0, 0.3, 150.0, -1000.0, length_m=0.01)}
        return laws, Biaxial(p0_kPa=50.0, axial_strain=0.04, steps=steps or 80, resolution=resolution or 10)
    from material import load_preset
    from material.factory import make_material

    params = load_preset("ottawa_c109").replace(E=60000.0, zeta=1.05, softening_slip=0.03, residual_ratio=0.65)
    laws = {"crack band": make_material(params, alpha_deg=0.0, plane_strain=True, stabilisation=0.1),
            "gradient": make_material(params, alpha_deg=0.0, plane_strain=True, stabilisation=0.1,
                                      nonlocal_length=0.006),
            "back stress": make_material(params, alpha_deg=0.0, plane_strain=True, stabilisation=0.1,
                                         back_stress_modulus=back_stress[0], back_stress_length=back_stress[1])}
    return laws, Biaxial(p0_kPa=100.0, axial_strain=0.042, steps=steps or 168, resolution=resolution or 12,
                         imperfection=0.0, weak_zone=0.1, weak_zone_height=1.0 / 12.0, weak_zone_size=1.0 / 3.0,
                         platens="rough")  # the set-up of examples/fe_04_biaxial_meshes.py


def main(argv=None) -> float:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--law", choices=("von_mises", "cpa"), default="von_mises")
    ap.add_argument("--resolution", type=int, default=None, help="elements across the width (von_mises: 10, where "
                                                                   "the local run completes; cpa: 12)")
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--back-stress", type=float, nargs=2, default=[1000.0, 0.006], metavar=("H", "L"),
                    help="cpa: the back stress's modulus H [kPa] and length l_b [m] (default 1000 0.006)")
    args = ap.parse_args(argv)
    if not all(math.isfinite(v) and v > 0 for v in args.back_stress):  # NaN too, as examples/fe_04 checks
        ap.error(f"--back-stress: H and L must be > 0 (finite), got {args.back_stress[0]:g} {args.back_stress[1]:g}")
    laws, case = _setups(args.law, args.resolution, args.steps, tuple(args.back_stress))
    for law in laws.values():
        _once(law, dataclasses.replace(case, resolution=2, steps=2))  # compile
    best = {}
    for name, law in laws.items():
        times = []
        for _ in range(args.repeat):
            dt, sol = _once(law, case)
            times.append(dt)
        its = np.asarray(sol.history["iterations"][1:], float)
        best[name] = min(times)
        print(f"{name:11s} {best[name]:7.2f} s (min of {args.repeat}), {its.mean():.2f} Newton iterations per step, "
              f"completed {sol.completed}, final q {sol.history['q_kPa'][-1]:.1f} kPa")
    baseline = next(iter(best))
    ratio = best["gradient"] / best[baseline]
    print(f"ratio gradient / {baseline} on {case.resolution} elements across: {ratio:.2f} (target <= 2)")
    if "back stress" in best:
        print(f"ratio back stress / {baseline}: {best['back stress'] / best[baseline]:.2f} (target <= 2)")
    return ratio


if __name__ == "__main__":
    main()
