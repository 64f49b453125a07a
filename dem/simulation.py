"""Run a DEM state forward: list management, batches of steps inside one @njit call, errors.

:class:`Simulation` owns the working arrays (Verlet list, per-pair forces) of one state and advances
it by ``n`` steps with a given boundary-strain rate and servo setting. Python loops only over
batches; all particle/contact loops are inside :mod:`dem.engine`.
"""

from __future__ import annotations

import numpy as np

from . import engine
from .contacts import critical_time_step
from .neighbours import _build_half_list, _transfer_history, _transpose
from .state import DEMState


class ParticleEscapedError(ValueError):
    """A particle left the box (or the state became non-finite); the message names the checkpoint."""


class Simulation:
    """Advance a :class:`DEMState` in place.

    Parameters
    ----------
    state : DEMState
    dt : float or None
        Time step [s]; None -> ``safety * critical_time_step``. A value above the critical time step
        raises ValueError.
    safety : float
        Fraction of the critical time step used when ``dt`` is None (default 0.25).
    skin : float or None
        Verlet skin [m]; None -> 0.3 * mean radius.
    """

    def __init__(self, state: DEMState, dt: float | None = None, safety: float = 0.25, skin: float | None = None):
        self.state = state
        dt_crit = critical_time_step(state.radii, state.law)
        if dt is None:
            dt = state.dt if state.dt > 0 else safety * dt_crit
        if not (np.isfinite(dt) and 0 < dt <= dt_crit):
            raise ValueError(
                f"time step dt={dt!r} s is not allowed: it must lie in (0, {dt_crit:.4g}] s, the critical "
                f"time step sqrt(m_min/k_max) of this sample (use a safety factor, e.g. 0.25)")
        state.dt = float(dt)
        self.dt = float(dt)
        self.skin = float(skin) if skin is not None else 0.3 * float(np.mean(state.radii))
        self.prm = state.law.packed()
        n = state.n_particles
        self.mass = state.masses
        self.inertia = 0.5 * self.mass * state.radii**2
        self.wall_sigma = np.zeros((2, 2))
        self.wall_count = np.zeros(4, np.int64)
        self.servo = np.zeros(engine.SERVO_SIZE)
        self.a, self.b = (float(v) for v in state.half_size)
        # build the list from the state's explicit contact history
        istart, pj = _build_half_list(state.positions, state.radii, self.skin)
        old_istart = np.zeros(n + 1, np.int64)
        order = np.lexsort((state.pair_j, state.pair_i))
        pi_sorted = np.asarray(state.pair_i, np.int64)[order]
        np.add.at(old_istart, pi_sorted + 1, 1)
        old_istart = np.cumsum(old_istart)
        zeta = _transfer_history(old_istart, np.asarray(state.pair_j, np.int32)[order],
                                 np.asarray(state.pair_zeta, float)[order], istart, pj)
        self._install_list(istart, pj, zeta)
        if state.steps == 0 and not np.any(state.forces):
            self.compute_forces()

    # ---------------------------------------------------------------- list
    def _install_list(self, istart, pj, zeta):
        st = self.state
        self.istart, self.pj, self.zeta = istart, pj, zeta
        self.jstart, self.jorder = _transpose(istart, pj, st.n_particles)
        self.fpair = np.zeros((len(pj), 2))
        self.ftpair = np.zeros(len(pj))
        self.pos_ref = st.positions.copy()
        self.E_ref = st.boundary_strain.copy()
        self.wall_list = engine._near_walls(st.positions, st.radii, st.boundary_strain, self.a, self.b, self.skin)

    def rebuild(self) -> None:
        st = self.state
        istart, pj = _build_half_list(st.positions, st.radii, self.skin)
        zeta = _transfer_history(self.istart, self.pj, self.zeta, istart, pj)
        self._install_list(istart, pj, zeta)

    def set_radii(self, radii: np.ndarray) -> None:
        """Change the radii (radius expansion): masses follow, the list is rebuilt."""
        self.state.radii = np.ascontiguousarray(radii, float)
        self.mass = self.state.masses
        self.inertia = 0.5 * self.mass * self.state.radii**2
        self.rebuild()

    def set_law(self, law) -> None:
        self.state.law = law
        self.prm = law.packed()

    def compute_forces(self) -> None:
        """Forces of the current configuration without advancing the history (dt = 0)."""
        st = self.state
        engine._forces(st.positions, st.velocities, st.angular_velocities, st.radii, self.mass,
                       self.istart, self.pj, self.jstart, self.jorder, self.zeta, self.fpair, self.ftpair,
                       self.wall_list, self.prm, st.boundary_strain, st.boundary_rate, self.a, self.b, 0.0,
                       st.forces, st.torques, self.wall_sigma, self.wall_count)

    # ---------------------------------------------------------------- stepping
    def set_servo(self, target_kPa=(None, None), alpha: float = 0.5, max_rate: float = 1.0) -> None:
        """Servo-control the wall stress sigma_xx and/or sigma_yy (kPa, tension positive; None = off)."""
        self.servo[:] = 0.0
        for c, t in enumerate(target_kPa):
            if t is not None:
                self.servo[c] = 1.0
                self.servo[2 + c] = 1e3 * float(t)
        self.servo[4] = alpha
        self.servo[5] = max_rate

    def advance(self, n_steps: int, checkpoint=None) -> None:
        """Advance ``n_steps`` steps. ``checkpoint`` (a path) is named in the error if a particle escapes."""
        st = self.state
        done = 0
        while done < n_steps:
            k, status = engine._advance(
                n_steps - done, self.dt, st.positions, st.velocities, st.angular_velocities, st.forces,
                st.torques, st.radii, self.mass, self.inertia, self.istart, self.pj, self.jstart,
                self.jorder, self.zeta, self.fpair, self.ftpair, self.wall_list, self.pos_ref, self.E_ref,
                self.skin, self.prm, st.boundary_strain, st.boundary_rate, self.servo, self.a, self.b,
                self.wall_sigma, self.wall_count)
            done += k
            st.steps += k
            st.time += k * self.dt
            if status == engine.REBUILD:
                self.rebuild()
            elif status in (engine.ESCAPED, engine.NOT_FINITE):
                what = "a particle left the box" if status == engine.ESCAPED else "the state became non-finite"
                where = f"; last checkpoint: {checkpoint}" if checkpoint else "; no checkpoint was written"
                raise ParticleEscapedError(
                    f"DEM run stopped at step {st.steps} (t = {st.time:.4g} s): {what} "
                    f"(time step or loading rate too large for this sample){where}")
        self.sync()

    def sync(self) -> None:
        """Copy the contact history (pairs in contact) back into the state."""
        st = self.state
        rows = np.repeat(np.arange(st.n_particles), np.diff(self.istart))
        keep = self.zeta != 0.0
        st.pair_i = rows[keep].astype(np.int64)
        st.pair_j = self.pj[keep].astype(np.int64)
        st.pair_zeta = self.zeta[keep].copy()

    @property
    def wall_stress_kPa(self) -> np.ndarray:
        """(2, 2) wall stress (C.4) of the last force evaluation [kPa], tension positive."""
        return self.wall_sigma / self.state.area / 1e3
