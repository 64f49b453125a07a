"""Direct shear (simple shear of a band of thickness t) at sigma_n = 50 kPa for alpha = 0 ... 90.

Shows the dilation growing with the deposition angle (thesis Figs. 5-7) and compares the peak
ratio tau/sigma_n with the direct-shear friction coefficient eta_f(alpha) of the preset. Some runs
stop before the full displacement when the CPA update fails close to the limit state; the table
keeps the converged steps (``res.completed`` / ``res.message``).
Run: ``python examples/element_02_direct_shear.py``.
"""

import warnings
from pathlib import Path

import numpy as np

from material import driver, load_preset
from material.anisotropy import axes_from_alpha, friction_coefficient


def main(out="out/examples/element_02", steps=300):
    out = Path(out)
    params = load_preset("ottawa_c109")
    runs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for alpha in (0.0, 30.0, 45.0, 60.0, 90.0):
            res = driver.direct_shear(params, sigma_n_kPa=50.0, alpha_deg=alpha, steps=steps)
            res.to_csv(out / f"direct_shear_a{alpha:g}.csv")
            eta_f = friction_coefficient(params, np.array([[0.0, 0.0, 1.0]]), axes_from_alpha(alpha))[0]
            dn = np.interp(5e-4, res["shear_displacement_m"], res["normal_displacement_m"])
            print(f"alpha={alpha:4g}: max tau/sigma_n = {res['tau_over_sigma_n'].max():.3f} (eta_f = {eta_f:.3f}), "
                  f"normal displacement at 0.5 mm = {dn * 1e3:+.4f} mm, reached {res['shear_displacement_m'][-1] * 1e3:.2f} mm")
            runs[alpha] = res
    fig = runs[0.0].plot()
    fig.savefig(out / "direct_shear_a0.png", dpi=120)
    return runs


if __name__ == "__main__":
    main()
