"""Example fe_03: bearing capacity of a rough strip footing against the bedding angle (CPA law).

Sand with self weight (18 kN/m^3) and a 10 kPa surcharge, B = 1 m, ``ottawa_c109``; bedding angles
0, 30, 60, 90 deg (deposition axis from the vertical). Writes ``out/fe_03_footing/summary.csv`` and the
load-settlement curves. Compare with Azami, Pietruszczak & Guo (2010): the bearing capacity falls as
the bedding inclines.

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
    args = ap.parse_args(argv)
    res, steps, alphas = (2, 20, (0.0, 90.0)) if args.quick else (3, 40, (0.0, 30.0, 60.0, 90.0))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = {}
    with open(out / "summary.csv", "w") as f:
        f.write("alpha_deg,bearing_capacity_kPa,completed\n")
        for a in alphas:
            sol = footing(None, 1.0, 18.0, 10.0, True, a, settlement_m=0.1, steps=steps, resolution=res,
                          out=out / f"alpha_{a:g}")
            result[a] = sol.bearing_capacity_kPa
            f.write(f"{a:g},{sol.bearing_capacity_kPa:.6g},{int(sol.completed)}\n")
            print(f"alpha {a:4g}: largest mean pressure {sol.bearing_capacity_kPa:.1f} kPa [{sol.stop_reason}]")
    return result


if __name__ == "__main__":
    main()
