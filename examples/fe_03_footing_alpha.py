"""Example fe_03: bearing capacity of a rough strip footing against the bedding angle (CPA law).

The thesis sand ``ottawa_c109`` with self weight (18 kN/m^3), B = 1 m, no surcharge (``--surcharge``),
rough footing, the default mesh; bedding angles 0, 15, ..., 90 deg (deposition axis from the vertical).
With the thesis's soft sand (E = 6000 kPa) the curve has no peak within 0.1 B, so the bearing capacity
is the pressure at s = 0.1 B (settlement criterion). The runs use the step stabilisation of
:class:`material.CPAModel` (``--stabilisation``, default 0.1): without it the thesis's non-associated
law is not uniquely solvable at a few points near failure and the runs stop between 0.02 and 0.07 B
(``docs/cpa_law.md``, section 4). The stabilisation's overstress raises the pressures: at s = 0.1 B
``--stabilisation 0.01`` gives 2.7-5 % less at 15-90 deg (in two to three times the steps) and lets a
second mechanism form at 0 deg; each run's ``summary.json`` has ``stabilisation_overstress_p99``.
``--preset``, ``--params FILE`` and ``--set KEY=VALUE`` change the sand as on the command line: e.g.
``--stabilisation 0 --set compaction_stress=20`` runs the wider compaction fade that carries every angle
on the default mesh without the stabilisation, at the price of the thesis's dilatancy (not a finer mesh at
0 deg; ``docs/cpa_law.md``, section 4).
``--relaxation-times TAU ...`` gives the stabilisation relaxation times of its own instead of one nominal
step, each run with max(40, 1/TAU) nominal steps, so that every curve is converged in the step and the
curves tend to the thesis's law as TAU -> 0 (``docs/cpa_law.md``, section 4). Writes
``out/fe_03_footing/summary.csv``, the load-settlement curves and ``capacity_vs_alpha.png``. Compare
with Azami, Pietruszczak & Guo (2010): the capacity is largest for horizontal bedding and falls as the
bedding inclines.

    python examples/fe_03_footing_alpha.py [--quick] [--alphas 0 45 90] [--surcharge 10]
    python examples/fe_03_footing_alpha.py --relaxation-times 0.025 0.00625 0.0015625
    python examples/fe_03_footing_alpha.py --stabilisation 0 --set compaction_stress=20 --out out/fe_03_pc20
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from femgran.cases import footing
from material.commandline import add_parameters, parameters_from_args
from material.factory import make_material
from material.table import TableWriter


def _plot(out: Path, sols: dict) -> None:
    """Load-settlement curves of the first relaxation time's runs, and pressure at 0.1 B against alpha for
    each; ``sols`` maps (tau, alpha) to a solution (tau None: one nominal step)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.6))
    taus = list(dict.fromkeys(tau for tau, _ in sols))
    for (tau, a), sol in sols.items():
        if tau == taus[0]:
            ax1.plot(sol.history["settlement_m"], sol.history["pressure_kPa"], label=f"alpha = {a:g}")
    ax1.set_xlabel("settlement [m]")
    ax1.set_ylabel("mean footing pressure [kPa]")
    ax1.legend(fontsize=7)
    ax1.grid(alpha=0.3)
    for tau in taus:
        alphas = sorted(a for t, a in sols if t == tau)
        label = "relaxation time: one nominal step" if tau is None else f"relaxation time {tau:g}"
        ax2.plot(alphas, [sols[tau, a].extra["pressure_at_10pct_kPa"] for a in alphas], "o-", label=label)
    ax2.set_xlabel("bedding angle alpha [deg] (axis from vertical)")
    ax2.set_ylabel("pressure at s = 0.1 B [kPa]")
    ax2.legend(fontsize=7)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "capacity_vs_alpha.png", dpi=120)
    plt.close(fig)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="two angles on the coarse mesh in 20 steps")
    ap.add_argument("--out", default="out/fe_03_footing")
    ap.add_argument("--alphas", type=float, nargs="+", help="bedding angles [deg] (default 0 15 ... 90; quick: 0 90)")
    ap.add_argument("--surcharge", type=float, default=0.0, help="surcharge beside the footing [kPa]")
    ap.add_argument("--stabilisation", type=float, default=0.1, help="step stabilisation of the CPA law")
    ap.add_argument("--relaxation-times", type=float, nargs="+", metavar="TAU",
                    help="relaxation times of the stabilisation in load factor, one series of runs each with "
                         "max(steps, 1/TAU) nominal steps (default: one nominal step)")
    add_parameters(ap)
    args = ap.parse_args(argv)
    try:
        params = parameters_from_args(args)
    except (KeyError, ValueError, OSError) as err:  # an unknown key, a value out of range, a missing file
        ap.error(str(err).strip('"'))
    res, steps, alphas = (2, 20, (0.0, 90.0)) if args.quick else (3, 40, tuple(range(0, 91, 15)))
    alphas = tuple(float(a) for a in (args.alphas or alphas))
    taus = tuple(args.relaxation_times or (None,))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result, sols = {}, {}
    summary = TableWriter(out / "summary.csv", title="strip footing against the bedding angle",
                          descriptions={"relaxation_time": "relaxation time of the stabilisation in load factor "
                                                           "(nan: one nominal step)",
                                        "pressure_at_5pct_kPa": "mean footing pressure at s = 0.05 B [kPa]",
                                        "pressure_at_10pct_kPa": "mean footing pressure at s = 0.1 B [kPa]"})
    for tau in taus:
        n = steps if tau is None else max(steps, int(np.ceil(1.0 / tau - 1e-9)))
        for a in alphas:
            mat = make_material(params, alpha_deg=a, plane_strain=True, stabilisation=args.stabilisation,
                                relaxation_time=tau)
            name = f"alpha_{a:g}" if tau is None else f"tau_{tau:g}/alpha_{a:g}"
            sol = footing(mat, 1.0, 18.0, args.surcharge, True, a, settlement_m=0.1, steps=n, resolution=res,
                          out=out / name, plots=False)
            h = sol.history
            s, p = h["settlement_m"], h["pressure_kPa"]
            at5 = float(np.interp(0.05, s, p)) if s.max() >= 0.05 else float("nan")
            its = h["iterations"][1:].mean()
            result[tau, a], sols[tau, a] = sol.extra["pressure_at_10pct_kPa"], sol
            summary.write({"relaxation_time": np.nan if tau is None else tau, "alpha_deg": a,
                           "pressure_at_5pct_kPa": at5, "pressure_at_10pct_kPa": result[tau, a],
                           "steps": len(h) - 1, "newton_iterations_per_step": its, "completed": int(sol.completed)})
            print(f"{'' if tau is None else f'tau {tau:g}, '}alpha {a:4g}: pressure at s = 0.1 B {result[tau, a]:.1f} "
                  f"kPa, {len(h) - 1} steps, {its:.2f} Newton iterations per step [{sol.stop_reason}]")
    summary.close()
    _plot(out, sols)
    return result if args.relaxation_times else {a: v for (_, a), v in result.items()}


if __name__ == "__main__":
    main()
