"""Averaged quantities of a state (Appendix C): stress from walls and contacts, strain from the
boundary, porosity, coordination number, contact-normal fabric. Plain numpy (these run per record,
not per step). Public stresses in kPa, tension positive."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .engine import _walls
from .state import DEMState


def contacts(state: DEMState):
    """Particle-particle contacts of a state.

    Returns
    -------
    i, j : (C,) int; normal : (C, 2) unit vector from i to j; f_n, f_t : (C,) normal (compression +)
    and tangential forces [N/m] (static parts: spring forces, dashpots omitted); branch : (C, 2) x_j - x_i [m]
    """
    pos, r = state.positions, state.radii
    tree = cKDTree(pos)
    pairs = tree.query_pairs(2.0 * float(r.max()), output_type="ndarray")
    if len(pairs) == 0:
        z = np.zeros(0)
        return np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2)), z, z, np.zeros((0, 2))
    i, j = pairs[:, 0], pairs[:, 1]
    swap = i > j
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    branch = pos[j] - pos[i]
    dist = np.hypot(branch[:, 0], branch[:, 1])
    overlap = r[i] + r[j] - dist
    on = overlap > 0
    i, j, branch, dist, overlap = i[on], j[on], branch[on], dist[on], overlap[on]
    normal = branch / dist[:, None]
    f_n = state.law.kn * overlap  # eq. B.7 (spring part)
    zeta = {(a, b): z for a, b, z in zip(state.pair_i.tolist(), state.pair_j.tolist(), state.pair_zeta.tolist())}
    f_t = state.law.kt * np.array([zeta.get((a, b), 0.0) for a, b in zip(i.tolist(), j.tolist())])
    return i, j, normal, f_n, f_t, branch


def wall_contacts(state: DEMState):
    """Particle-wall contacts: particle index (C,), wall index (C,), contact point (C,2) [m], force on
    the particle (C,2) [N/m] (spring part; walls are frictionless)."""
    a, b = state.half_size
    centre, normal, _ = _walls(state.boundary_strain, a, b)
    kn_wall = state.law.kn_wall if state.law.kn_wall > 0 else state.law.kn
    dist = np.einsum("nkc,kc->nk", state.positions[:, None, :] - centre[None], normal)
    overlap = state.radii[:, None] - dist
    p, k = np.nonzero(overlap > 0)
    point = state.positions[p] - dist[p, k][:, None] * normal[k]
    force = (kn_wall * overlap[p, k])[:, None] * normal[k]
    return p, k, point, force


def stress_from_walls(state: DEMState) -> np.ndarray:
    """Average stress from the wall forces, eq. C.4: sigma_ij = (1/V) sum x_i^m T_j^m; (2,2) kPa, tension +."""
    _, _, point, force = wall_contacts(state)
    return point.T @ force / state.area / 1e3


def stress_from_contacts(state: DEMState) -> np.ndarray:
    """Average stress from the contact forces, eq. C.5: sigma_ij = (1/V) sum l_i^c T_j^c; (2,2) kPa.

    The branch vector l (C.6) runs from i to j and T is the force on j; the sign is chosen so that
    compressive contacts give a negative (tension-positive) stress. Wall contacts contribute with the branch from the particle centre to
    the contact point.
    """
    i, j, normal, f_n, f_t, branch = contacts(state)
    tangent = np.column_stack([-normal[:, 1], normal[:, 0]])
    force_on_j = f_n[:, None] * normal - f_t[:, None] * tangent
    sigma = -branch.T @ force_on_j  # compression -> negative (tension positive)
    p, k, point, force = wall_contacts(state)
    sigma += (point - state.positions[p]).T @ force
    sigma = 0.5 * (sigma + sigma.T)
    return sigma / state.area / 1e3


def strain_from_boundary(state: DEMState, reference: DEMState | None = None) -> np.ndarray:
    """Average strain from the boundary segments, eqs. C.13-C.15; (2,2), tension positive.

    F_iJ = (1/V0) e_JK sum_beta X_K^beta dx_i^beta over the four segments (X: reference segment
    centres, dx: deformed segment vectors), eps = sym(F) - I (C.14). ``reference`` defaults to the
    undeformed rectangle of the same state.
    """
    a, b = state.half_size
    ref = np.array([[-a, -b], [a, -b], [a, b], [-a, b]])  # counter-clockwise
    F_ref = np.eye(2) if reference is None else reference.deformation_gradient
    X = ref @ F_ref.T
    x = ref @ state.deformation_gradient.T
    V0 = abs(np.linalg.det(F_ref)) * 4 * a * b
    e = np.array([[0.0, -1.0], [1.0, 0.0]])  # e_JK for a counter-clockwise traversal
    F = np.zeros((2, 2))
    for s in range(4):
        Xc = 0.5 * (X[s] + X[(s + 1) % 4])  # segment centre, reference configuration
        dx = x[(s + 1) % 4] - x[s]  # segment vector after deformation
        F += np.outer(dx, e @ Xc) / V0  # C.13
    return 0.5 * (F + F.T) - np.eye(2)  # C.14


def porosity(state: DEMState) -> float:
    """Void fraction of the region inside the walls, from the disk areas (overlaps neglected)."""
    return float(1.0 - np.pi * np.sum(state.radii**2) / state.area)


def contact_counts(state: DEMState) -> np.ndarray:
    """(N,) number of contacts of each particle (particles and walls)."""
    i, j, *_ = contacts(state)
    p, *_ = wall_contacts(state)
    return np.bincount(np.concatenate([i, j, p]), minlength=state.n_particles)


def rattlers(state: DEMState, min_contacts: int | None = None) -> np.ndarray:
    """(N,) bool: particles carrying no load, found by repeatedly removing particles with fewer than
    ``min_contacts`` contacts (default 3 if frictionless, else 2)."""
    if min_contacts is None:
        min_contacts = 3 if state.law.friction == 0 else 2
    i, j, *_ = contacts(state)
    p, *_ = wall_contacts(state)
    active = np.ones(state.n_particles, bool)
    while True:
        keep = active[i] & active[j]
        count = np.bincount(np.concatenate([i[keep], j[keep], p[active[p]]]), minlength=state.n_particles)
        drop = active & (count < min_contacts)
        if not drop.any():
            return ~active
        active &= ~drop


def coordination_number(state: DEMState, exclude_rattlers: bool = True) -> float:
    """Mean number of contacts per particle Z = 2 C_pp / N (+ wall contacts / N); rattlers excluded."""
    i, j, *_ = contacts(state)
    p, *_ = wall_contacts(state)
    active = ~rattlers(state) if exclude_rattlers else np.ones(state.n_particles, bool)
    if not active.any():
        return 0.0
    keep = active[i] & active[j]
    return float((2 * keep.sum() + active[p].sum()) / active.sum())


def contact_fabric(state: DEMState) -> np.ndarray:
    """Contact-normal fabric tensor phi_ij = <n_i n_j> (2,2) over particle contacts (trace 1)."""
    _, _, normal, *_ = contacts(state)
    if len(normal) == 0:
        return 0.5 * np.eye(2)
    return normal.T @ normal / len(normal)


def inertial_number(strain_rate: float, state: DEMState, pressure_kPa: float) -> float:
    """I = |strain rate| d_mean sqrt(rho / p): quasi-static when below 1e-3."""
    d = 2.0 * float(np.mean(state.radii))
    return float(abs(strain_rate) * d * np.sqrt(state.law.density / max(abs(pressure_kPa) * 1e3, 1e-12)))
