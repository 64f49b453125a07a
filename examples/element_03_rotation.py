"""Principal stress rotation in plane strain (directional shear cell, thesis Figs. 45-46).

Hydrostatic 14 kPa, pre-shear with sigma1 along x, unload, reshear with sigma1 rotated by
dpsi = 0, 45, 90 deg, for beta = 0.1, 5, 10 (preset ``ottawa_c109_induced``).
Run: ``python examples/element_03_rotation.py``.
"""

from pathlib import Path

from matplotlib.figure import Figure

from material import driver, load_preset


def main(out="out/examples/element_03", steps=100):
    out = Path(out)
    base = load_preset("ottawa_c109_induced")
    fig = Figure(figsize=(12, 4), layout="constrained")
    axes = fig.subplots(1, 3, sharey=True)
    peaks = {}
    for ax, beta in zip(axes, (0.1, 5.0, 10.0)):
        for dpsi in (0.0, 45.0, 90.0):
            res = driver.rotation(base.replace(beta=beta), p0_kPa=14.0, delta_psi_deg=dpsi, steps=steps)
            res.to_csv(out / f"rotation_beta{beta:g}_dpsi{dpsi:g}.csv")
            reshear = res["stage"] == 2
            ax.plot(res["eps_1r"][reshear], res["q_kPa"][reshear], label=f"dpsi={dpsi:g}")
            peaks[(beta, dpsi)] = res["q_kPa"][reshear].max()
        ax.set(title=f"beta = {beta:g}", xlabel="eps_1 since reshear (compression +)")
        print(f"beta={beta:4g}: q_max(dpsi=0) - q_max(dpsi=90) = {peaks[(beta, 0.0)] - peaks[(beta, 90.0)]:.1f} kPa")
    axes[0].set_ylabel("q = sqrt(3 J2) [kPa]")
    axes[0].legend()
    fig.savefig(out / "rotation.png", dpi=120)
    return peaks


if __name__ == "__main__":
    main()
