"""Contact law of Appendix B: linear normal spring + dashpot, tangential spring with Coulomb limit.

Conventions (2D disks of unit thickness, SI inside the engine): forces in N/m, stiffness in N/m per m
of thickness, masses in kg/m. For a pair (i, j) the unit normal ``n`` points from i to j, the
tangent is ``t = (-n_y, n_x)``; the overlap is ``delta = r_i + r_j - |x_j - x_i|`` (eq. B.6).

* normal force (compression positive) ``f_n = k_n delta - gamma_n m_eff v_n`` (eq. B.7), with
  ``v_n = (v_rel . n)`` positive when separating; the dashpot uses the LAMMPS parameterisation
  (``gamma_n`` in 1/s times the effective mass), so the damping ratio of a pair is
  ``gamma_n / 2 * sqrt(m_eff / k_n)``;
* tangential displacement ``zeta += v_t dt`` (eq. B.9), trial force ``k_t zeta`` (eq. B.8) plus an
  optional tangential dashpot, Coulomb limit ``|f_t| <= mu max(f_n, 0)`` (eq. B.10): when sliding,
  ``zeta`` is rescaled to the limit (the history is kept in ``zeta``, an array parallel to the
  pair list).

The force on i is ``-f_n n + f_t t``; on j the opposite. Torques: ``r_i f_t`` on i and ``r_j f_t``
on j (both the same sign).
"""

from __future__ import annotations

from dataclasses import dataclass, asdict, replace

import numpy as np

# indices into the packed parameter array used by the kernels
KN, KT, MU, GAMMA_N, GAMMA_T, LOCAL_DAMPING, KN_WALL, GAMMA_WALL = range(8)
N_PARAMS = 8


@dataclass(frozen=True)
class ContactLaw:
    """Parameters of the contact law and of the damping (SI, per metre of thickness).

    Attributes
    ----------
    kn, kt : float
        Normal and tangential contact stiffness [N/m per m], > 0.
    friction : float
        Interparticle friction coefficient mu = tan(phi_s) [-], >= 0.
    gamma_n, gamma_t : float
        Contact dashpots [1/s]: damping force = gamma * m_eff * relative velocity.
    local_damping : float
        Cundall's local non-viscous damping coefficient in [0, 1): each force component is reduced by
        ``local_damping * |F| sign(v)``. It removes energy only from accelerating motion and adds no
        rate-dependent drag to a steady deformation, which is why PFC uses it (0.7) for quasi-static
        runs; we use it the same way.
    kn_wall : float
        Normal stiffness of the rigid, frictionless walls [N/m per m] (0 -> same as ``kn``).
    density : float
        Particle density [kg/m^3] (2650, quartz).
    """

    kn: float = 2.0e8
    kt: float = 2.0e8
    friction: float = float(np.tan(np.radians(30.0)))
    gamma_n: float = 0.0
    gamma_t: float = 0.0
    local_damping: float = 0.7
    kn_wall: float = 0.0
    density: float = 2650.0

    def __post_init__(self) -> None:
        checks = {
            "kn": self.kn > 0, "kt": self.kt > 0, "friction": self.friction >= 0,
            "gamma_n": self.gamma_n >= 0, "gamma_t": self.gamma_t >= 0,
            "local_damping": 0 <= self.local_damping < 1, "kn_wall": self.kn_wall >= 0,
            "density": self.density > 0,
        }
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (ok and np.isfinite(value)):
                raise ValueError(f"contact law: {name}={value!r} is not allowed (see ContactLaw docstring for bounds)")

    def replace(self, **changes) -> "ContactLaw":
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return asdict(self)

    def packed(self) -> np.ndarray:
        """The parameter array read by the kernels (index constants KN, KT, ... of this module)."""
        p = np.zeros(N_PARAMS)
        p[KN], p[KT], p[MU] = self.kn, self.kt, self.friction
        p[GAMMA_N], p[GAMMA_T], p[LOCAL_DAMPING] = self.gamma_n, self.gamma_t, self.local_damping
        p[KN_WALL] = self.kn_wall if self.kn_wall > 0 else self.kn
        p[GAMMA_WALL] = self.gamma_n
        return p


def critical_time_step(radii: np.ndarray, law: ContactLaw) -> float:
    """Critical time step sqrt(m_min / k_max) [s] (PFC's estimate; leapfrog is stable below it).

    ``k_max`` is the largest of the normal, tangential and wall stiffnesses. The engine runs at
    ``safety * critical_time_step`` (default safety 0.25, leaving room for particles with several
    contacts and for the rotational degree of freedom).
    """
    m_min = law.density * np.pi * float(np.min(radii)) ** 2
    k_max = max(law.kn, law.kt, law.kn_wall)
    return float(np.sqrt(m_min / k_max))


def pair_forces_reference(pos, vel, angvel, radius, mass, zeta_of_pair, law: ContactLaw, dt: float):
    """Plain numpy O(N^2) reference of one force evaluation over all pairs i < j.

    Parameters
    ----------
    pos, vel : (N, 2) arrays [m], [m/s]; angvel : (N,) [rad/s]; radius, mass : (N,) [m], [kg/m]
    zeta_of_pair : dict {(i, j): zeta} tangential displacement before the step [m]
    law : ContactLaw
    dt : float, time step [s] (zeta is incremented by v_t dt, eq. B.9)

    Returns
    -------
    force : (N, 2) [N/m], torque : (N,) [N], zeta : dict of the updated tangential displacements of
    the pairs in contact.
    """
    n = len(radius)
    force = np.zeros((n, 2))
    torque = np.zeros(n)
    new_zeta = {}
    i_idx, j_idx = np.triu_indices(n, 1)
    d = pos[j_idx] - pos[i_idx]
    dist = np.hypot(d[:, 0], d[:, 1])
    overlap = radius[i_idx] + radius[j_idx] - dist
    for i, j, dv, dd, ov in zip(i_idx, j_idx, d, dist, overlap):  # reference only: clarity over speed
        if ov <= 0:
            continue
        nrm = dv / dd
        tan = np.array([-nrm[1], nrm[0]])
        v_rel = vel[j] - vel[i] - (angvel[j] * radius[j] + angvel[i] * radius[i]) * tan
        v_n, v_t = v_rel @ nrm, v_rel @ tan
        m_eff = mass[i] * mass[j] / (mass[i] + mass[j])
        f_n = law.kn * ov - law.gamma_n * m_eff * v_n  # eq. B.7
        zeta = zeta_of_pair.get((i, j), 0.0) + v_t * dt  # eq. B.9
        f_t = law.kt * zeta + law.gamma_t * m_eff * v_t  # eq. B.8
        limit = law.friction * max(f_n, 0.0)
        if abs(f_t) > limit:  # eq. B.10
            f_t = np.sign(f_t) * limit
            zeta = (f_t - law.gamma_t * m_eff * v_t) / law.kt
        f_i = -f_n * nrm + f_t * tan
        force[i] += f_i
        force[j] -= f_i
        torque[i] += radius[i] * f_t
        torque[j] += radius[j] * f_t
        new_zeta[(i, j)] = zeta
    return force, torque, new_zeta
