"""Example fe_03: bearing capacity of a rough strip footing against the bedding angle (CPA law).

Sand with self weight (18 kN/m^3) and a 10 kPa surcharge, B = 1 m, ``ottawa_c109``; bedding angles
0, 30, 60, 90 deg (deposition axis from the vertical). Writes ``out/fe_03_footing/summary.csv`` and the
load-settlement curves. With the thesis's soft sand (E = 6000 kPa) the curve has no peak within 0.1 B,
so the bearing capacity is the pressure at s = 0.1 B (settlement criterion); the plateau ratio tells how
far from a limit load the run ended. Compare with Azami, Pietruszczak & Guo (2010): the bearing
capacity falls as the bedding inclines.

    python examples/fe_03_footing_alpha.py [--quick]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from femgran.cases import footing


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="out/fe_03_footing")
    ap.add_argument("--alphas", type=float, nargs="+", help="bedding angles [deg] (default 0 30 60 90; quick: 0 90)")
    args = ap.parse_args(argv)
    res, steps, alphas = (2, 20, (0.0, 90.0)) if args.quick else (3, 40, (0.0, 30.0, 60.0, 90.0))
    alphas = tuple(args.alphas) if args.alphas else alphas
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = {}
    with open(out / "summary.csv", "w") as f:
        f.write("alpha_deg,pressure_at_10pct_kPa,largest_pressure_kPa,plateau_ratio,completed\n")
        for a in alphas:
            sol = footing(None, 1.0, 18.0, 10.0, True, a, settlement_m=0.1, steps=steps, resolution=res,
                          out=out / f"alpha_{a:g}")
            x = sol.extra
            result[a] = x["pressure_at_10pct_kPa"]
            f.write(f"{a:g},{x['pressure_at_10pct_kPa']:.6g},{x['bearing_capacity_kPa']:.6g},{x['plateau_ratio']:.3g},"
                    f"{int(sol.completed)}\n")
            f.flush()
            print(f"alpha {a:4g}: pressure at s = 0.1 B {x['pressure_at_10pct_kPa']:.1f} kPa, largest "
                  f"{x['bearing_capacity_kPa']:.1f} kPa, plateau ratio {x['plateau_ratio']:.2f} [{sol.stop_reason}]")
    return result


if __name__ == "__main__":
    main()
