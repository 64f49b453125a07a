"""Example fe_04: plane-strain biaxial test on three meshes (shear band, mesh dependence).

CPA ``ottawa_c109``, p0 = 100 kPa, a 2 % geometric imperfection, Q1 B-bar elements with 8, 16, 32
elements across the width. Prints the peak friction and dilatancy angles, the measured band angle
(or that no band formed) and the Coulomb / Roscoe / Arthur angles; one plot with the three curves.

    python examples/fe_04_biaxial_meshes.py [--quick]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from femgran.cases import biaxial


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="out/fe_04_biaxial")
    args = ap.parse_args(argv)
    resolutions, strain, steps = ((4,), 0.05, 10) if args.quick else ((8, 16, 32), 0.2, 60)
    sols = {}
    for n in resolutions:
        sol = biaxial(None, 100.0, 0.0, axial_strain=strain, steps=steps, resolution=n, out=Path(args.out) / f"resolution_{n}")
        sols[n] = sol
        ref = sol.reference_angles_deg
        band = f"band at {sol.band_angle_deg:.1f} deg" if sol.localised else "no localised band"
        print(f"resolution {n}: peak phi {sol.peak_friction_deg:.1f}, psi {sol.peak_dilatancy_deg:.1f} deg; {band}; "
              f"Coulomb {ref['coulomb']:.1f}, Roscoe {ref['roscoe']:.1f}, Arthur {ref['arthur']:.1f}")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.6))
    for n, s in sols.items():
        ax.plot(s.history["eps_a"], s.history["q_kPa"], label=f"{n} elements across")
    ax.set_xlabel("axial strain")
    ax.set_ylabel("q = s1 - s3 [kPa]")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(Path(args.out) / "q_vs_eps_a_meshes.png", dpi=120)
    return sols


if __name__ == "__main__":
    main()
