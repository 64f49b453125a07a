"""Isotropic linear elasticity behind the common material interface (see :mod:`material.base`)."""

from __future__ import annotations

import numpy as np

from material.base import STATUS_OK, State, as_stress_batch, check_batch, check_state

__all__ = ["LinearElastic", "isotropic_stiffness", "isotropic_compliance"]


def isotropic_stiffness(E: float, nu: float) -> np.ndarray:
    """Hooke's law C_ijkl = lambda d_ij d_kl + mu (d_ik d_jl + d_il d_jk), (3, 3, 3, 3) kPa."""
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    mu = E / (2.0 * (1.0 + nu))
    d = np.eye(3)
    return (
        lam * np.einsum("ij,kl->ijkl", d, d)
        + mu * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d))
    )


def isotropic_compliance(E: float, nu: float) -> np.ndarray:
    """Inverse of :func:`isotropic_stiffness` on symmetric tensors, (3, 3, 3, 3) 1/kPa."""
    d = np.eye(3)
    sym = 0.5 * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d))
    return (1.0 + nu) / E * sym - nu / E * np.einsum("ij,kl->ijkl", d, d)


def mandel_elastic(E: float, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """Isotropic stiffness and compliance as 6x6 Mandel matrices (kPa, 1/kPa), from the tensors above."""
    from material.tensors import to_mandel_matrix

    return to_mandel_matrix(isotropic_stiffness(E, nu)), to_mandel_matrix(isotropic_compliance(E, nu))


def _check_elastic(E: float, nu: float) -> tuple[float, float]:
    E, nu = float(E), float(nu)
    if not (np.isfinite(E) and E > 0):
        raise ValueError(f"E_kPa = {E!r}: must be > 0 (finite)")
    if not -1.0 < nu < 0.5:
        raise ValueError(f"nu = {nu!r}: allowed -1 < nu < 0.5")
    return E, nu


class LinearElastic:
    """Isotropic Hooke law, sigma_{n+1} = sigma_n + C : d_strain.

    Parameters
    ----------
    E_kPa : float
        Young's modulus [kPa], > 0.
    nu : float
        Poisson's ratio, -1 < nu < 0.5.
    """

    def __init__(self, E_kPa: float, nu: float):
        self.E, self.nu = _check_elastic(E_kPa, nu)
        self.stiffness = isotropic_stiffness(self.E, self.nu)

    def __repr__(self) -> str:
        return f"LinearElastic(E_kPa={self.E:g}, nu={self.nu:g})"

    def initial_state(self, n_points: int, stress=None, *, element_size=None) -> State:
        """State of ``n_points`` points; ``stress`` and ``element_size`` are part of the material protocol
        (validated, not stored: elasticity has no length scale)."""
        as_stress_batch(stress, n_points)
        n = int(n_points)
        return {
            "strain": np.zeros((n, 3, 3)),
            "status": np.zeros(n, dtype=np.int8),
            "step_ratio": np.ones(n),
        }

    def update(self, d_strain, stress, state: State):
        """(N,3,3) strain increment and stress (tension +) -> stress, state, tangent (N,3,3,3,3)."""
        de, s = check_batch(d_strain, stress)
        n = de.shape[0]
        check_state(state, n, ("strain",))
        new_stress = s + np.einsum("ijkl,nkl->nij", self.stiffness, de)
        new_state = {
            "strain": state["strain"] + de,
            "status": np.full(n, STATUS_OK, dtype=np.int8),
            "step_ratio": np.ones(n),
        }
        tangent = np.broadcast_to(self.stiffness, (n, 3, 3, 3, 3))
        return new_stress, new_state, tangent
