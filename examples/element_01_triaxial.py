"""Drained triaxial compression of Ottawa sand C109 at alpha = 0 and 90 (thesis Figs. 20-21).

Runs the CPA law (preset ``ottawa_c109``) through :func:`material.driver.triaxial` at p0 = 50 and
100 kPa, compares the peak with the analytic critical-plane strength and writes CSV + PNG to
``out/examples/element_01``. Run: ``python examples/element_01_triaxial.py``.
"""

from pathlib import Path

from matplotlib.figure import Figure

from material import driver, load_preset
from material.failure import triaxial_strength


def main(out="out/examples/element_01", steps=150):
    out = Path(out)
    params = load_preset("ottawa_c109")
    fig = Figure(figsize=(10, 4), layout="constrained")
    ax_q, ax_v = fig.subplots(1, 2)
    peaks = {}
    for p0 in (50.0, 100.0):
        for alpha in (0.0, 90.0):
            res = driver.triaxial(params, p0_kPa=p0, alpha_deg=alpha, axial_strain=0.15, steps=steps)
            res.to_csv(out / f"triaxial_p{p0:g}_a{alpha:g}.csv")
            label = f"p0={p0:g} kPa, alpha={alpha:g}"
            ax_q.plot(res["eps_a"], res["q_kPa"], label=label)
            ax_v.plot(res["eps_a"], res["eps_v"], label=label)
            peaks[(p0, alpha)] = res["q_kPa"].max()
            qf = triaxial_strength(params, p0, alpha)
            print(f"{label}: q at 15 % = {peaks[(p0, alpha)]:.1f} kPa, analytic strength q_f = {qf:.1f} kPa")
    ax_q.set(xlabel="eps_a (compression +)", ylabel="q = sigma_a - sigma_r [kPa]")
    ax_v.set(xlabel="eps_a (compression +)", ylabel="eps_v (compression +)")
    ax_q.legend(fontsize=8)
    fig.savefig(out / "triaxial.png", dpi=120)
    return peaks


if __name__ == "__main__":
    main()
