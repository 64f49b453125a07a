"""Example fe_02: the triaxial specimen between rough and smooth platens at alpha = 0, 45, 90 (CPA).

Section 2.2.2 of the thesis: for an inclined bedding the specimen tends to distort; smooth platens let
it (uniform stress, the element test), rough platens prevent it (non-uniform stress). Prints the peak
deviator, the distortion of the top (smooth) and the non-uniformity CV of sqrt(3 J2) (rough), and writes
one run folder per case under ``out/fe_02_triaxial`` (ParaView series, history, PNGs).

    python examples/fe_02_triaxial_platens.py                 # 4 x 4 x 8 hexahedra, 15 % axial strain
    python examples/fe_02_triaxial_platens.py --quick         # 2 x 2 x 4, 2 %
    python examples/fe_02_triaxial_platens.py --stabilisation 0.1

With the thesis's law (the default) the rough specimen at alpha = 0 stops near 13.7 % axial strain, where
about half of it has lost ellipticity and some points' rate problems have several solutions (its stop
reason is printed); the step stabilisation 0.1 of ``material.CPAModel`` carries it to 15 % and changes the
peak by about 0.4 % (README, "Boundary-value problems").
"""

from __future__ import annotations

import argparse
from pathlib import Path

from femgran.cases import triaxial


def _mu(text: str) -> float:
    """``--stabilisation``: a number 0 <= mu <= 1 (the range material.CPAModel allows)."""
    try:
        mu = float(text)
    except ValueError:
        mu = float("nan")
    if not 0.0 <= mu <= 1.0:
        raise argparse.ArgumentTypeError(f"stabilisation = {text!r}: allowed a number 0 <= mu <= 1")
    return mu


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="out/fe_02_triaxial")
    ap.add_argument("--stabilisation", type=_mu, default=0.0, metavar="MU",
                    help="step stabilisation of the CPA law (default 0: the thesis's law)")
    args = ap.parse_args(argv)
    law = None if args.stabilisation == 0.0 else {"law": "cpa", "stabilisation": args.stabilisation}
    res, strain, steps = (2, 0.02, 8) if args.quick else (4, 0.15, 45)
    out = {}
    for platens in ("smooth", "rough"):
        for alpha in (0.0, 45.0, 90.0):
            sol = triaxial(law, 100.0, alpha, platens, axial_strain=strain, steps=steps, resolution=res,
                           out=Path(args.out) / f"{platens}_alpha_{alpha:g}")
            h = sol.history
            out[(platens, alpha)] = (sol.peak_q_kPa, h["top_shift_mm"][-1], h["cv_q"][-1])
            print(f"{platens:>6} alpha {alpha:4g}: peak q {sol.peak_q_kPa:7.1f} kPa, top shift {h['top_shift_mm'][-1]:+.4f} mm, "
                  f"CV(q) {h['cv_q'][-1]:.3f}  [{sol.stop_reason}]")
    return out


if __name__ == "__main__":
    main()
