"""The time-stepping kernel: forces (pairs + walls), velocity Verlet, servo walls, in batches of steps.

The boundary is a rectangle of reference half-sizes (a, b) centred at the origin, mapped by the
homogeneous deformation ``x = F X`` with ``F = I + E`` (E symmetric, tension positive; Appendix D,
eq. D.2 with our sign). Its four sides are rigid, frictionless walls (infinite lines through the
mapped side centres with normals ``F^-T N``, pointing into the sample). ``E`` advances with the rate
``Edot``; the diagonal components flagged in ``servo`` are instead driven by the servo-control law

    u_wall = alpha * dF / (k_n,wall N_c dt)       (PFC's stiffness-based gain)

i.e. ``Edot_ii = 2 alpha (target_ii - sigma_ii) L_j / (W_i k_n,wall N_c dt)`` capped at a maximum
rate, where ``sigma`` is the wall stress (C.4), ``L_j`` the length of the wall, ``W_i`` the sample
size across it and ``N_c`` the mean number of contacts on one of the two walls.

Time integration: velocity Verlet (half kick, drift, forces, half kick); the contact dashpots and the
tangential increments use the mid-step velocities, as LAMMPS does.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .contacts import KN, KT, MU, GAMMA_N, GAMMA_T, LOCAL_DAMPING, KN_WALL, GAMMA_WALL

# status codes returned by _advance
OK, REBUILD, ESCAPED, NOT_FINITE = 0, 1, 2, 3

# servo array layout: [on_xx, on_yy, target_xx, target_yy (Pa, tension +), alpha, max_rate (1/s)]
SERVO_SIZE = 6

# reference wall geometry (unit square scaled by a, b): left, right, bottom, top; inward normals
_WALL_CENTRE = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])
_WALL_NORMAL = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


@njit(cache=True)
def _walls(E, a, b):
    """Deformed wall centres (4,2), inward unit normals (4,2) and lengths (4,) for F = I + E."""
    f00, f01, f10, f11 = 1.0 + E[0, 0], E[0, 1], E[1, 0], 1.0 + E[1, 1]
    det = f00 * f11 - f01 * f10
    centre = np.empty((4, 2))
    normal = np.empty((4, 2))
    length = np.empty(4)
    for k in range(4):
        X = _WALL_CENTRE[k, 0] * a
        Y = _WALL_CENTRE[k, 1] * b
        centre[k, 0] = f00 * X + f01 * Y
        centre[k, 1] = f10 * X + f11 * Y
        N0, N1 = _WALL_NORMAL[k, 0], _WALL_NORMAL[k, 1]
        # F^-T N = (1/det) [[f11, -f10], [-f01, f00]] N
        m0 = (f11 * N0 - f10 * N1) / det
        m1 = (-f01 * N0 + f00 * N1) / det
        s = np.sqrt(m0 * m0 + m1 * m1)
        normal[k, 0] = m0 / s
        normal[k, 1] = m1 / s
        # tangent of the side in the reference frame, mapped: length of F T * (2 * half-size)
        T0, T1 = -N1, N0
        half = b if k < 2 else a
        t0 = f00 * T0 + f01 * T1
        t1 = f10 * T0 + f11 * T1
        length[k] = 2.0 * half * np.sqrt(t0 * t0 + t1 * t1)
    return centre, normal, length


@njit(cache=True)
def _forces(pos, vel, angvel, radius, mass, istart, pj, jstart, jorder, zeta, fpair, ftpair,
            wall_list, prm, E, Edot, a, b, dt, force, torque, wall_sigma, wall_count):
    """One force evaluation: pair forces (first pass, per pair), gather (second pass, per particle),
    wall forces, local damping. Updates ``zeta`` in place (eq. B.9/B.10).

    ``wall_sigma`` (2,2) receives sum over wall contacts of x^m f^m (C.4, before division by the
    area), ``wall_count`` (4,) the number of contacts on each wall.
    """
    n = pos.shape[0]
    kn, kt, mu = prm[KN], prm[KT], prm[MU]
    gn, gt = prm[GAMMA_N], prm[GAMMA_T]
    # pass 1: per-pair forces (force on i stored in fpair, tangential force in ftpair)
    for i in range(n):
        xi, yi, ri = pos[i, 0], pos[i, 1], radius[i]
        for p in range(istart[i], istart[i + 1]):
            j = pj[p]
            dx = pos[j, 0] - xi
            dy = pos[j, 1] - yi
            rsum = ri + radius[j]
            d2 = dx * dx + dy * dy
            if d2 >= rsum * rsum:
                fpair[p, 0] = 0.0
                fpair[p, 1] = 0.0
                ftpair[p] = 0.0
                zeta[p] = 0.0
                continue
            d = np.sqrt(d2)
            nx, ny = dx / d, dy / d
            tx, ty = -ny, nx
            overlap = rsum - d  # eq. B.6
            w = angvel[j] * radius[j] + angvel[i] * ri
            vrx = vel[j, 0] - vel[i, 0] - w * tx
            vry = vel[j, 1] - vel[i, 1] - w * ty
            vn = vrx * nx + vry * ny
            vt = vrx * tx + vry * ty
            meff = mass[i] * mass[j] / (mass[i] + mass[j])
            fn = kn * overlap - gn * meff * vn  # eq. B.7
            z = zeta[p] + vt * dt  # eq. B.9
            ft = kt * z + gt * meff * vt  # eq. B.8
            limit = mu * max(fn, 0.0)
            if abs(ft) > limit:  # eq. B.10, Coulomb slip: rescale the history to the limit
                ft = limit if ft > 0 else -limit
                z = (ft - gt * meff * vt) / kt
            zeta[p] = z
            fpair[p, 0] = -fn * nx + ft * tx
            fpair[p, 1] = -fn * ny + ft * ty
            ftpair[p] = ft
    # pass 2: gather per particle (no scatter, no atomics)
    for k in range(n):
        fx = 0.0
        fy = 0.0
        tq = 0.0
        for p in range(istart[k], istart[k + 1]):
            fx += fpair[p, 0]
            fy += fpair[p, 1]
            tq += ftpair[p]
        for q in range(jstart[k], jstart[k + 1]):
            p = jorder[q]
            fx -= fpair[p, 0]
            fy -= fpair[p, 1]
            tq += ftpair[p]
        force[k, 0] = fx
        force[k, 1] = fy
        torque[k] = tq * radius[k]
    # walls: rigid, frictionless lines; velocity of the wall at x is Edot F^-1 x
    centre, normal, length = _walls(E, a, b)
    knw, gw = prm[KN_WALL], prm[GAMMA_WALL]
    f00, f01, f10, f11 = 1.0 + E[0, 0], E[0, 1], E[1, 0], 1.0 + E[1, 1]
    det = f00 * f11 - f01 * f10
    for c in range(2):
        wall_sigma[c, 0] = 0.0
        wall_sigma[c, 1] = 0.0
    for k in range(4):
        wall_count[k] = 0
    for q in range(wall_list.shape[0]):
        i = wall_list[q]
        for k in range(4):
            nx, ny = normal[k, 0], normal[k, 1]
            dist = (pos[i, 0] - centre[k, 0]) * nx + (pos[i, 1] - centre[k, 1]) * ny
            overlap = radius[i] - dist
            if overlap <= 0.0:
                continue
            cx = pos[i, 0] - dist * nx  # contact point on the wall
            cy = pos[i, 1] - dist * ny
            Xc = (f11 * cx - f01 * cy) / det
            Yc = (-f10 * cx + f00 * cy) / det
            vwx = Edot[0, 0] * Xc + Edot[0, 1] * Yc
            vwy = Edot[1, 0] * Xc + Edot[1, 1] * Yc
            vn = (vel[i, 0] - vwx) * nx + (vel[i, 1] - vwy) * ny  # > 0: moving away from the wall
            fn = knw * overlap - gw * mass[i] * vn
            force[i, 0] += fn * nx
            force[i, 1] += fn * ny
            wall_sigma[0, 0] += cx * fn * nx  # C.4: x_i^m T_j^m
            wall_sigma[0, 1] += cx * fn * ny
            wall_sigma[1, 0] += cy * fn * nx
            wall_sigma[1, 1] += cy * fn * ny
            wall_count[k] += 1
    # Cundall's local non-viscous damping (eq. B.5 with the damping force alpha |F| sign(v))
    alpha = prm[LOCAL_DAMPING]
    if alpha > 0.0:
        for k in range(n):
            for c in range(2):
                if vel[k, c] != 0.0:
                    force[k, c] -= alpha * abs(force[k, c]) * (1.0 if vel[k, c] > 0 else -1.0)
            if angvel[k] != 0.0:
                torque[k] -= alpha * abs(torque[k]) * (1.0 if angvel[k] > 0 else -1.0)


@njit(cache=True)
def _servo_rates(Edot, servo, wall_sigma, wall_count, E, a, b, knw, dt):
    """Stiffness-based servo: update the flagged diagonal components of Edot from the wall stress."""
    area = 4.0 * a * b * ((1.0 + E[0, 0]) * (1.0 + E[1, 1]) - E[0, 1] * E[1, 0])
    for c in range(2):
        if servo[c] == 0.0:
            continue
        sigma = wall_sigma[c, c] / area
        nc = 0.5 * (wall_count[2 * c] + wall_count[2 * c + 1])
        nc = max(nc, 1.0)
        size = 2.0 * (a if c == 0 else b) * (1.0 + E[c, c])
        other = 2.0 * (b if c == 0 else a) * (1.0 + E[1 - c, 1 - c])
        rate = 2.0 * servo[4] * (servo[2 + c] - sigma) * other / (size * knw * nc * dt)
        rate = min(max(rate, -servo[5]), servo[5])
        Edot[c, c] = rate


@njit(cache=True)
def _advance(n_steps, dt, pos, vel, angvel, force, torque, radius, mass, inertia,
             istart, pj, jstart, jorder, zeta, fpair, ftpair, wall_list, pos_ref, E_ref, skin,
             prm, E, Edot, servo, a, b, wall_sigma, wall_count):
    """Advance up to ``n_steps`` velocity-Verlet steps (forces on entry must be current).

    Returns ``(steps_done, status)``: status OK, REBUILD (a particle or a wall moved more than
    skin/2 since the list was built: rebuild and call again), ESCAPED (a particle is wholly outside
    a wall) or NOT_FINITE.
    """
    n = pos.shape[0]
    half = 0.5 * dt
    rmax_half = max(a, b)
    for step in range(n_steps):
        for k in range(n):  # half kick + drift
            im = 1.0 / mass[k]
            vel[k, 0] += half * force[k, 0] * im
            vel[k, 1] += half * force[k, 1] * im
            angvel[k] += half * torque[k] / inertia[k]
            pos[k, 0] += dt * vel[k, 0]
            pos[k, 1] += dt * vel[k, 1]
        for r in range(2):
            for c in range(2):
                E[r, c] += dt * Edot[r, c]
        _forces(pos, vel, angvel, radius, mass, istart, pj, jstart, jorder, zeta, fpair, ftpair,
                wall_list, prm, E, Edot, a, b, dt, force, torque, wall_sigma, wall_count)
        for k in range(n):  # second half kick
            im = 1.0 / mass[k]
            vel[k, 0] += half * force[k, 0] * im
            vel[k, 1] += half * force[k, 1] * im
            angvel[k] += half * torque[k] / inertia[k]
        if servo[0] != 0.0 or servo[1] != 0.0:
            _servo_rates(Edot, servo, wall_sigma, wall_count, E, a, b, prm[KN_WALL], dt)
        # Verlet-list validity: particle displacement and wall displacement since the build
        limit2 = 0.25 * skin * skin
        moved = False
        for k in range(n):
            dx = pos[k, 0] - pos_ref[k, 0]
            dy = pos[k, 1] - pos_ref[k, 1]
            if dx * dx + dy * dy > limit2:
                moved = True
                break
        dE = 0.0
        for r in range(2):
            for c in range(2):
                dE = max(dE, abs(E[r, c] - E_ref[r, c]))
        if dE * 2.0 * rmax_half > 0.5 * skin:
            moved = True
        if moved or step == n_steps - 1:
            status = _check_inside(pos, vel, radius, E, a, b)
            if status != OK:
                return step + 1, status
            if moved:
                return step + 1, REBUILD
    return n_steps, OK


@njit(cache=True)
def _check_inside(pos, vel, radius, E, a, b):
    centre, normal, length = _walls(E, a, b)
    for i in range(pos.shape[0]):
        if not (np.isfinite(pos[i, 0]) and np.isfinite(pos[i, 1]) and np.isfinite(vel[i, 0])):
            return NOT_FINITE
        for k in range(4):
            dist = (pos[i, 0] - centre[k, 0]) * normal[k, 0] + (pos[i, 1] - centre[k, 1]) * normal[k, 1]
            if dist < -radius[i]:
                return ESCAPED
    return OK


@njit(cache=True)
def _near_walls(pos, radius, E, a, b, margin):
    """Indices of the particles within ``margin`` of a wall (the only ones tested against walls)."""
    centre, normal, length = _walls(E, a, b)
    out = np.empty(pos.shape[0], np.int64)
    m = 0
    for i in range(pos.shape[0]):
        for k in range(4):
            dist = (pos[i, 0] - centre[k, 0]) * normal[k, 0] + (pos[i, 1] - centre[k, 1]) * normal[k, 1]
            if dist < radius[i] + margin:
                out[m] = i
                m += 1
                break
    return out[:m]
