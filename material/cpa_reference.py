"""Plain-numpy reference of the CPA law's equations, for testing the numba kernel.

Slow and simple on purpose: full 3x3 tensors, one Gauss point, vectorised over planes only. It
evaluates the strain residual of the implicit scheme (MODEL.md, "Integration at a Gauss point")

    R(sigma) = C^-1 : (sigma - sigma_n) + (1/t) sum_a w_a sym(dg_a (x) n_a) - d_eps

so a test can check that the kernel's converged stress zeroes it, independently of the kernel's
Jacobian, Mandel algebra and sub-stepping.
"""

from __future__ import annotations

import numpy as np

from material.anisotropy import induced_tensor, series
from material.elastic import isotropic_compliance


def plane_strengths(model, strain: np.ndarray) -> np.ndarray:
    """eta_f of every plane of ``model`` for the total strain (3, 3) (eqs. 2.4, 3.14, 3.15)."""
    p = model.params
    omega = (model.axes @ np.diag([p.omega1, -2 * p.omega1, p.omega1]) @ model.axes.T
             + induced_tensor(p.beta, strain, p.alpha_hat, p.beta_hat))
    x = np.einsum("ai,ij,aj->a", model.normals, omega, model.normals)
    return p.eta0 * series(x, p.a)


def residual(model, sigma, sigma_n, d_strain, kappa_n, strain_end) -> np.ndarray:
    """Strain residual (3, 3) of one (sub)step at the trial stress ``sigma`` (all tension +)."""
    p = model.params
    n = model.normals
    w = model.weights
    c = model._cohesion
    eta_f = plane_strengths(model, strain_end)
    t = n @ sigma.T                                   # traction t_a = sigma n_a
    sigma_N = -np.einsum("ai,ai->a", t, n)            # compression positive
    ts = t + sigma_N[:, None] * n                     # shear traction
    tau = np.linalg.norm(ts, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        etah = (tau - c) / sigma_N                    # mobilised ratio
        s = ts / tau[:, None]
    zef = p.zeta * eta_f
    eta_reached = zef * kappa_n / (p.A + kappa_n)     # (2.16)
    loading = (sigma_N > 0) & (tau > 0) & (etah >= eta_reached)
    dkappa = np.zeros_like(tau)
    kap = p.A * etah[loading] / (zef[loading] - etah[loading])
    dkappa[loading] = np.maximum(kap - kappa_n[loading], 0.0)
    q = np.where(loading, tau / (sigma_N + c / eta_f), 0.0)
    dil = p.eta_c_ratio * eta_f - q                   # d psi / d sigma_N (2.17)
    dg = dkappa[:, None] * (np.where(loading[:, None], s, 0.0) - dil[:, None] * n)  # (2.7)
    d_eps_p = np.einsum("a,ai,aj->ij", w, dg, n) / p.t
    d_eps_p = 0.5 * (d_eps_p + d_eps_p.T)             # (2.9)
    S = isotropic_compliance(p.E, p.nu)
    return np.einsum("ijkl,kl->ij", S, sigma - sigma_n) + d_eps_p - d_strain
