"""Analytic failure of the CPA model: the critical plane (eqs. 2.1-2.5) and strength envelopes.

For a stress sigma (tension positive, kPa) and a plane with unit normal n
(``docs/model.md``, "Analytic failure criterion"):

    t = sigma n,  sigma_N = -n.t (compression +),  t_s = t - (n.t) n,  tau = |t_s|,  s = t_s / tau   (2.1-2.2)
    F(n) = tau - eta_f(n) sigma_N - c(n)                                                               (2.3)

with eta_f(n), c(n) from :mod:`material.anisotropy` (eq. 2.4; optionally with the induced part
beta dev(strain), eq. 3.14-3.15). The material fails when max_n F = 0 (eq. 2.5), the maximum taken over
the **continuous** unit sphere. F is even in n, so the search runs over a hemisphere: a Fibonacci
grid (default 2000 points) gives the starting points, and the best few are refined with a
Nelder-Mead search in local tangent-plane coordinates (no pole singularity).

Triaxial strength: sigma = -diag(p0, p0, p0 + q) (the major compression along global z), material
axes ``axes_from_alpha(alpha)``; q_f is the root of max_n F(q) = 0 (``scipy.optimize.brentq``).
Isotropic check (eta_f = tan(phi), c = c0): max_n F = R sqrt(1 + eta^2) - eta C - c with the Mohr
circle's centre C and radius R (compression +), so F = 0 is Mohr-Coulomb with tan(phi) = eta:
q_f = 2 (p0 sin(phi) + c cos(phi)) / (1 - sin(phi)), and the critical normal lies at 45 deg + phi/2
from the major compression axis (the plane is inclined at 45 deg - phi/2 to it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize

from material.anisotropy import axes_from_alpha, axes_from_frame, cohesion, default_axes, friction_coefficient
from material.parameters import CPAParameters

__all__ = [
    "CriticalPlane",
    "failure_function",
    "critical_plane",
    "strength_along_path",
    "triaxial_strength",
    "strength_envelope",
    "direct_shear_friction",
    "fibonacci_hemisphere",
    "plot_strength_envelope",
]


@dataclass(frozen=True)
class CriticalPlane:
    """The plane maximising F (eq. 2.5) for one stress.

    Attributes
    ----------
    F : float
        max_n F [kPa]; F < 0: safe, F = 0: failure (eq. 2.5).
    normal : (3,) unit normal of the critical plane, global frame (sign chosen with n_z >= 0).
    slip_direction : (3,) unit shear-traction direction s = t_s / tau (zeros if tau = 0).
    tau : float, shear traction [kPa].
    sigma_n : float, normal traction [kPa], compression positive.
    eta_f : float, friction coefficient of the plane.
    cohesion : float, cohesion of the plane [kPa].
    """

    F: float
    normal: np.ndarray
    slip_direction: np.ndarray
    tau: float
    sigma_n: float
    eta_f: float
    cohesion: float


def fibonacci_hemisphere(n_points: int) -> np.ndarray:
    """(n_points, 3) nearly uniform unit vectors with z >= 0 (Fibonacci lattice)."""
    n_points = int(n_points)
    if n_points < 1:
        raise ValueError(f"n_points = {n_points}: must be >= 1")
    k = np.arange(n_points) + 0.5
    z = 1.0 - k / n_points  # z in (0, 1)
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _check_stress(stress) -> np.ndarray:
    s = np.asarray(stress, dtype=float)
    if s.shape != (3, 3):
        raise ValueError(f"stress_3x3: expected shape (3, 3), got {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("stress_3x3: contains NaN or inf")
    if np.abs(s - s.T).max() > 1e-10 * max(np.abs(s).max(), 1e-300):
        raise ValueError("stress_3x3: not symmetric; allowed: a symmetric Cauchy stress (tension +)")
    return 0.5 * (s + s.T)


def _tractions(stress: np.ndarray, normals: np.ndarray):
    t = normals @ stress  # (M, 3), stress symmetric
    tn = np.einsum("ai,ai->a", t, normals)
    ts = t - tn[:, None] * normals
    tau = np.linalg.norm(ts, axis=1)
    return ts, tau, -tn  # eqs. 2.1-2.2; sigma_N compression +


def failure_function(stress, params: CPAParameters, normals, axes=None, strain=None) -> np.ndarray:
    """F(n) = tau - eta_f(n) sigma_N - c(n) [kPa] (eq. 2.3) for unit normals (M, 3), global frame."""
    s = _check_stress(stress)
    n = np.asarray(normals, dtype=float)
    _, tau, sig_n = _tractions(s, n)
    return tau - friction_coefficient(params, n, axes, strain) * sig_n - cohesion(params, n, axes)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _tangent_basis(n0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(n0[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a = _unit(np.cross(n0, helper))
    return a, np.cross(n0, a)


def _maximise(stress, params, axes, strain, n_grid: int, n_starts: int) -> tuple[float, np.ndarray]:
    grid = fibonacci_hemisphere(n_grid)
    f_grid = failure_function(stress, params, grid, axes, strain)
    # best few distinct starts (several maxima may be nearly equal: symmetric stress states)
    order = np.argsort(f_grid)[::-1]
    starts = [grid[order[0]]]
    for i in order[1:]:
        if len(starts) >= n_starts:
            break
        if min(1.0 - abs(grid[i] @ s0) for s0 in starts) > 1e-2:
            starts.append(grid[i])
    best_f, best_n = f_grid[order[0]], grid[order[0]]
    scale = max(float(np.abs(stress).max()), 1e-12)
    for n0 in starts:
        a, b = _tangent_basis(n0)

        def neg_f(x, n0=n0, a=a, b=b):
            n = _unit(n0 + x[0] * a + x[1] * b)[None, :]
            return -failure_function(stress, params, n, axes, strain)[0] / scale

        res = minimize(
            neg_f, np.zeros(2), method="Nelder-Mead",
            options={"xatol": 1e-11, "fatol": 1e-15, "initial_simplex": [[0, 0], [0.03, 0], [0, 0.03]], "maxiter": 2000},
        )
        f = -res.fun * scale
        if f > best_f:
            best_f, best_n = f, _unit(n0 + res.x[0] * a + res.x[1] * b)
    return float(best_f), best_n


def critical_plane(
    stress_3x3, params: CPAParameters, axes=None, *, strain=None, n_grid: int = 2000, n_starts: int = 4
) -> CriticalPlane:
    """Maximise F(n) (eq. 2.3) over the continuous unit sphere (eq. 2.5).

    Parameters
    ----------
    stress_3x3 : (3, 3) Cauchy stress [kPa], tension positive, global frame.
    params : CPAParameters
    axes : (3, 3) material axes (columns e1, e2, e3); default ``axes_from_alpha(0)`` (e2 = global z).
    strain : (3, 3), optional
        Total strain (tension +) for the induced anisotropy beta dev(strain) (eq. 3.15); default none.
    n_grid : int
        Points of the Fibonacci hemisphere grid that seeds the search.
    n_starts : int
        How many of the best distinct grid points are refined by the local search.

    Returns
    -------
    CriticalPlane with ``.F`` [kPa], ``.normal``, ``.slip_direction`` and the tractions on the plane.
    """
    s = _check_stress(stress_3x3)
    if not isinstance(params, CPAParameters):
        raise ValueError(f"params: expected CPAParameters, got {type(params).__name__}")
    R = default_axes() if axes is None else axes_from_frame(axes)
    f, n = _maximise(s, params, R, strain, n_grid, n_starts)
    if n[2] < 0 or (n[2] == 0 and n[0] < 0):
        n = -n
    ts, tau, sig_n = _tractions(s, n[None, :])
    slip = ts[0] / tau[0] if tau[0] > 1e-14 * max(np.abs(s).max(), 1e-300) else np.zeros(3)
    return CriticalPlane(
        F=f,
        normal=n,
        slip_direction=slip,
        tau=float(tau[0]),
        sigma_n=float(sig_n[0]),
        eta_f=float(friction_coefficient(params, n[None, :], R, strain)[0]),
        cohesion=float(cohesion(params, n[None, :], R)[0]),
    )


def strength_along_path(
    params: CPAParameters,
    stress0,
    direction,
    axes=None,
    *,
    strain=None,
    rule: str | None = None,
    q_max: float = 1e7,
    xtol: float = 1e-10,
) -> float:
    """The load factor q >= 0 at which sigma = stress0 + q direction reaches max_n F = 0 (eq. 2.5).

    ``rule=None`` maximises F over the continuous sphere (the model's strength envelope); a rule name
    of :func:`material.planes.available_rules` maximises over that rule's planes only, attached to the
    material frame (n_a = R n_a^ref) -- the strength limit of the discretised model with zeta = 1,
    which is never below the continuous one. ``stress0`` must be safe (max F < 0) and the path must
    fail below ``q_max``; otherwise ``ValueError``. The bracket grows geometrically, then ``brentq``
    finds the root to a relative tolerance ``xtol``.
    """
    s0 = _check_stress(stress0)
    d = _check_stress(direction)
    R = default_axes() if axes is None else axes_from_frame(axes)
    if rule is None:

        def g(q: float) -> float:
            return _maximise(s0 + q * d, params, R, strain, 2000, 4)[0]

    else:
        from material.planes import integration_rule, rotate_normals

        planes = rotate_normals(integration_rule(rule)[0], R)

        def g(q: float) -> float:
            return float(failure_function(s0 + q * d, params, planes, R, strain).max())

    g0 = g(0.0)
    if g0 >= 0.0:
        raise ValueError(f"stress0: already at or beyond failure (max F = {g0:.6g} kPa >= 0)")
    scale = max(float(np.abs(s0).max()), float(params.c0), 1.0) / max(float(np.abs(d).max()), 1e-300)
    lo, hi = 0.0, 0.5 * scale
    while g(hi) < 0.0:
        lo, hi = hi, 2.0 * hi
        if hi > q_max:
            raise ValueError(f"the stress path does not reach failure below q = {q_max:g}")
    return float(brentq(g, lo, hi, xtol=1e-14, rtol=max(xtol, 4.5e-16)))


def triaxial_strength(params: CPAParameters, p0_kPa: float, alpha_deg: float, **kwargs) -> float:
    """Failure deviator q_f [kPa] (compression +) of a drained triaxial compression test.

    sigma = -diag(p0, p0, p0 + q) (tension +; major compression along global z), material axes
    ``axes_from_alpha(alpha_deg)`` (alpha: angle between the loading axis and the deposition axis e2);
    q_f solves max_n F = 0 over the continuous sphere (eqs. 2.3-2.5), or over the planes of
    ``rule=...`` only (see :func:`strength_along_path`).
    """
    p0 = float(p0_kPa)
    if not (np.isfinite(p0) and p0 >= 0.0):
        raise ValueError(f"p0_kPa = {p0_kPa!r}: must be >= 0 (confining pressure, compression +)")
    if p0 == 0.0 and params.c0 == 0.0:
        return 0.0  # cohesionless material without confinement has no strength
    axes = axes_from_alpha(alpha_deg)
    return strength_along_path(params, -p0 * np.eye(3), -np.diag([0.0, 0.0, 1.0]), axes, **kwargs)


def strength_envelope(params: CPAParameters, p0_kPa: float, alphas_deg, **kwargs) -> np.ndarray:
    """q_f [kPa] of :func:`triaxial_strength` for each deposition angle in ``alphas_deg`` (degrees);
    keyword arguments (e.g. ``rule=``) are passed on."""
    alphas = np.atleast_1d(np.asarray(alphas_deg, dtype=float))
    return np.array([triaxial_strength(params, p0_kPa, a, **kwargs) for a in alphas])


def direct_shear_friction(params: CPAParameters, alpha_deg) -> np.ndarray:
    """eta_f on a shear plane whose normal makes ``alpha_deg`` with e2 (eq. 2.20): the direct-shear slope."""
    a = np.deg2rad(np.atleast_1d(np.asarray(alpha_deg, dtype=float)))
    normals = np.column_stack([np.sin(a), np.zeros_like(a), np.cos(a)])  # e2 = z (default axes)
    return friction_coefficient(params, normals)


def plot_strength_envelope(params: CPAParameters, p0_kPa=(50.0, 100.0), alphas_deg=None, ax=None):
    """Plot q_f against the deposition angle for each confining pressure; returns the matplotlib figure."""
    import matplotlib

    if ax is None:
        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5, 3.5))
    else:
        fig = ax.figure
    alphas = np.linspace(0.0, 90.0, 19) if alphas_deg is None else np.asarray(alphas_deg, dtype=float)
    for p0 in np.atleast_1d(p0_kPa):
        ax.plot(alphas, strength_envelope(params, float(p0), alphas), "o-", label=f"p0 = {p0:g} kPa")
    ax.set_xlabel("deposition angle alpha [deg]")
    ax.set_ylabel("q_f [kPa] (compression +)")
    ax.set_title(f"CPA triaxial strength ({params.name})")
    ax.legend()
    fig.tight_layout()
    return fig
