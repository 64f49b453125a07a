"""Inherent and induced anisotropy: material axes, microstructure tensors, eta_f(n) and c(n).

Conventions (``docs/model.md``, "Material axes and the deposition angle", "Inherent and induced anisotropy"):

* Material axes are a 3x3 array ``R`` whose **columns** are e1, e2, e3; e2 is the deposition axis
  (normal to the bedding planes). A vector with components ``v_ref`` in the material frame has global
  components ``R @ v_ref``.
* Inherent anisotropy tensor in the material frame: Omega = diag(omega1, -2 omega1, omega1), so
  ``Omega_ij n_i n_j = omega1 (1 - 3 cos^2 theta)`` with theta the angle between n and e2 (eq. 2.19).
* Induced anisotropy: Lambda = beta * dev(eps), eps the total strain, tension positive (eq. 3.15);
  the total bias tensor is Omega + Lambda (eq. 3.14).
* eta_f(n) = eta0 (1 + x + a1 x^2 + a2 x^3 + ...), x = (Omega + Lambda)_ij n_i n_j (eq. 2.4).
"""

from __future__ import annotations

import numpy as np

from .parameters import CPAParameters

__all__ = [
    "axes_from_alpha",
    "axes_from_frame",
    "default_axes",
    "inherent_tensor",
    "induced_tensor",
    "series",
    "friction_coefficient",
    "cohesion",
    "coaxial_fabric_direction",
    "deviator",
]


def axes_from_alpha(alpha_deg: float) -> np.ndarray:
    """Material axes for a deposition angle ``alpha_deg`` (degrees) from the global z axis.

    e2 = (sin a, 0, cos a) lies in the global x-z plane, e1 = (cos a, 0, -sin a), e3 = y, so that
    alpha = 0 gives e2 = z (load along the deposition direction, "vertical" sample) and alpha = 90
    gives e2 = x (load parallel to the bedding). The triad is right-handed.

    Returns
    -------
    (3, 3) array whose columns are e1, e2, e3.
    """
    alpha = float(alpha_deg)
    if not np.isfinite(alpha):
        raise ValueError(f"alpha_deg = {alpha_deg!r}: must be a finite angle in degrees")
    a = np.deg2rad(alpha)
    e2 = np.array([np.sin(a), 0.0, np.cos(a)])
    e1 = np.array([np.cos(a), 0.0, -np.sin(a)])
    e3 = np.cross(e1, e2)
    return np.column_stack([e1, e2, e3])


def axes_from_frame(axes, *, tol: float = 1e-8) -> np.ndarray:
    """Validate an explicit frame: a (3, 3) proper rotation whose columns are e1, e2, e3.

    A frame that is orthonormal to ``tol`` but slightly off is re-orthonormalised (polar
    decomposition); a reflection (det < 0) or a non-orthonormal matrix raises ``ValueError``.
    """
    R = np.asarray(axes, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"axes: expected a (3, 3) array of column vectors e1, e2, e3, got shape {R.shape}")
    if not np.all(np.isfinite(R)):
        raise ValueError("axes: contains NaN or inf")
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > 1e-4:
        raise ValueError(f"axes: columns are not orthonormal (max |R^T R - I| = {err:.3g}); allowed: a rotation")
    if np.linalg.det(R) < 0:
        raise ValueError("axes: the frame is left-handed (det < 0); allowed: a proper rotation (det = +1)")
    if err > tol:
        u, _, vt = np.linalg.svd(R)
        R = u @ vt
    return R


def default_axes() -> np.ndarray:
    """The default material frame, ``axes_from_alpha(0)``: e2 = global z."""
    return axes_from_alpha(0.0)


def inherent_tensor(omega1: float, axes=None) -> np.ndarray:
    """Omega = R diag(omega1, -2 omega1, omega1) R^T in the global frame (eq. 2.19), (3, 3)."""
    R = default_axes() if axes is None else axes_from_frame(axes)
    return R @ np.diag([omega1, -2.0 * omega1, omega1]) @ R.T


def deviator(a: np.ndarray) -> np.ndarray:
    """Deviatoric part of (..., 3, 3) tensors."""
    a = np.asarray(a, dtype=float)
    tr = np.trace(a, axis1=-2, axis2=-1)
    return a - tr[..., None, None] / 3.0 * np.eye(3)


def induced_tensor(beta: float, strain: np.ndarray, alpha_hat: float = 1.0, beta_hat: float = 0.0) -> np.ndarray:
    """Induced anisotropy tensor Lambda, (..., 3, 3) (eqs. 3.8, 3.15).

    Lambda = beta |e| n^Omega with n^Omega = alpha_hat n^e + beta_hat dev(n^e n^e) normalised
    (:func:`coaxial_fabric_direction`), e = dev(strain), strain tension positive. With the defaults
    alpha_hat = 1, beta_hat = 0 this is exactly Lambda = beta e (3.15).
    """
    e = deviator(strain)
    if beta_hat == 0.0 and alpha_hat > 0.0:
        return beta * e
    norm = np.sqrt(np.einsum("...ij,...ij->...", e, e))
    return beta * norm[..., None, None] * coaxial_fabric_direction(strain, alpha_hat, beta_hat)


def series(x: np.ndarray, coeffs) -> np.ndarray:
    """1 + x + c1 x^2 + c2 x^3 + ... (the bracket of eq. 2.4), elementwise, Horner's scheme."""
    x = np.asarray(x, dtype=float)
    acc = np.zeros_like(x)
    for c in reversed(tuple(coeffs)):
        acc = (acc + c) * x
    # acc = c1 x + c2 x^2 + ...; the bracket is 1 + x + x * acc
    return 1.0 + x + x * acc


def _bias(normals: np.ndarray, tensor: np.ndarray) -> np.ndarray:
    n = np.asarray(normals, dtype=float)
    if n.ndim != 2 or n.shape[1] != 3:
        raise ValueError(f"normals: expected shape (M, 3), got {n.shape}")
    norms = np.linalg.norm(n, axis=1)
    if not np.all(np.isfinite(norms)) or np.any(np.abs(norms - 1.0) > 1e-6):
        raise ValueError("normals: every row must be a finite unit vector")
    return np.einsum("ai,ij,aj->a", n, tensor, n)


def friction_coefficient(params: CPAParameters, normals, axes=None, strain=None) -> np.ndarray:
    """eta_f for unit normals (M, 3) given in the global frame (eqs. 2.4, 2.19, 3.14).

    Parameters
    ----------
    params : CPAParameters
    normals : (M, 3) unit vectors, global frame.
    axes : (3, 3) material axes (columns e1, e2, e3); default ``axes_from_alpha(0)`` (e2 = global z).
    strain : (3, 3) total strain, tension positive, for the induced part beta dev(strain); default 0.

    Returns
    -------
    (M,) friction coefficients.
    """
    tensor = inherent_tensor(params.omega1, axes)
    if strain is not None:
        tensor = tensor + induced_tensor(params.beta, np.asarray(strain, dtype=float), params.alpha_hat,
                                         params.beta_hat)
    return params.eta0 * series(_bias(normals, tensor), params.a)


def cohesion(params: CPAParameters, normals, axes=None) -> np.ndarray:
    """c(n) = c0 (1 + x_c + b1 x_c^2 + ...), x_c with Omega^c = diag(w, -2w, w), w = omega1_c (eq. 2.4); (M,) kPa."""
    tensor = inherent_tensor(params.omega1_c, axes)
    return params.c0 * series(_bias(normals, tensor), params.b)


def coaxial_fabric_direction(strain: np.ndarray, alpha_hat: float, beta_hat: float) -> np.ndarray:
    """General coaxial evolution law (eq. 3.8): n^Omega = alpha n^e + beta dev(n^e n^e), normalised.

    ``strain`` (..., 3, 3) total strain (tension positive; in 2D pass a (..., 2, 2) tensor and the
    deviator is taken in 2D). n^e = e/|e| with e its deviator; the product n^e n^e is the
    single-contraction (matrix) product, whose deviator keeps the result traceless. The result is
    normalised to unit Frobenius norm, so it is the *direction* of Omega; a zero deviator returns
    zeros.
    """
    eps = np.asarray(strain, dtype=float)
    d = eps.shape[-1]
    e = eps - np.trace(eps, axis1=-2, axis2=-1)[..., None, None] / d * np.eye(d)
    norm = np.sqrt(np.einsum("...ij,...ij->...", e, e))
    safe = np.where(norm > 0, norm, 1.0)
    ne = e / safe[..., None, None]
    sq = ne @ ne
    sq = sq - np.trace(sq, axis1=-2, axis2=-1)[..., None, None] / d * np.eye(d)
    out = alpha_hat * ne + beta_hat * sq
    onorm = np.sqrt(np.einsum("...ij,...ij->...", out, out))
    out = np.where((onorm > 0)[..., None, None], out / np.where(onorm > 0, onorm, 1.0)[..., None, None], 0.0)
    return out
