"""Example fe_01: verify the footing solver against Prandtl's (2 + pi) c_u, with mesh convergence.

Weightless von Mises soil (c_u = sigma_y / sqrt(3) in plane strain), rough rigid strip footing,
Q2 elements with B-bar (Q2/P1) volumetric projection. Prints q_u / ((2 + pi) c_u) per mesh and writes
``out/fe_01_prandtl/convergence.csv`` and ``convergence.png``.

    python examples/fe_01_prandtl.py                  # resolutions 2, 4, 8 (about half a minute)
    python examples/fe_01_prandtl.py --resolutions 1 2
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import material
from femgran.cases import footing
from femgran.cases.footing import prandtl_pressure


def main(argv=None) -> list[tuple[int, int, float]]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resolutions", type=int, nargs="+", default=[2, 4, 8])
    ap.add_argument("--out", default="out/fe_01_prandtl")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    c_u = 100.0
    law = material.VonMises(3e4, 0.3, c_u * np.sqrt(3.0))
    rows = []
    for res in args.resolutions:
        sol = footing(law, 1.0, 0.0, 0.0, True, settlement_m=0.2, steps=40, resolution=res, plots=False,
                      out=out / f"resolution_{res}")
        ratio = sol.bearing_capacity_kPa / prandtl_pressure(c_u)
        rows.append((res, sol.params["ndofs"], ratio))
        print(f"resolution {res} ({sol.params['ndofs']} DOFs): q_u / (2+pi) c_u = {ratio:.4f}")
    np.savetxt(out / "convergence.csv", np.array(rows), delimiter=",", header="resolution,ndofs,qu_over_prandtl",
               comments="")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.6))
    h = 0.5 / np.array([r[0] for r in rows])
    ax.loglog(h, [r[2] - 1 for r in rows], "o-")
    ax.set_xlabel("element size under the footing h / B")
    ax.set_ylabel("q_u / (2+pi) c_u - 1")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=120)
    return rows


if __name__ == "__main__":
    main()
