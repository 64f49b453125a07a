"""Stereological fabric (Section 3.4.1): exact line/disk intercepts, MIL and areal porosity, Kanatani fits.

Sampling domain: a circle at the sample centre whose diameter is ``domain_fraction`` (0.85: 15 % of
the width left out near the walls, Fig. 35) times the current sample width. For each direction
theta (every 10 deg by default) a family of parallel test lines with spacing d crosses the circle
(Fig. 36); on each line the solid intervals are the exact chords of the disks (overlaps merged), the
rest of the line inside the circle is void. With sum I the total void length, l the total line
length and N the number of void intercepts in direction theta:

* mean intercept length ``MIL(theta) = sum I / N`` (eq. 3.1);
* areal porosity ``n(theta) = sum I / l`` (eqs. 3.2-3.4 reduce to this in 2D: the section plane is
  the sample itself and the average over the test lines of one family is the discrete integral of
  3.3-3.4).

Kanatani fit (3.5-3.7) with v = (cos theta, sin theta):
``f = C (1 + Omega_ij v_i v_j + sum_k a_(k-2) (Omega_ij v_i v_j)^k)``, Omega traceless symmetric.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .state import DEMState


@njit(cache=True)
def _intercepts(centres, radii, R, spacing, theta):
    """Void length, line length and number of void intercepts of one family of test lines.

    centres (N,2) relative to the domain centre [m], radii (N,), R domain radius, spacing d, theta [rad].
    """
    ux, uy = np.cos(theta), np.sin(theta)
    vx, vy = -uy, ux
    n_lines = int(2.0 * R / spacing)
    mid = 0.5 * (n_lines - 1)
    n = radii.shape[0]
    count = np.zeros(n_lines + 1, np.int64)
    # pass 1: count intervals per line; pass 2: fill
    for sweep in range(2):
        if sweep == 1:
            for k in range(n_lines):
                count[k + 1] += count[k]
            t0 = np.empty(count[n_lines])
            t1 = np.empty(count[n_lines])
            fill = count[:-1].copy()
        for i in range(n):
            r = radii[i]
            sc = centres[i, 0] * vx + centres[i, 1] * vy
            tc = centres[i, 0] * ux + centres[i, 1] * uy
            k0 = max(0, int(np.ceil((sc - r) / spacing + mid)))
            k1 = min(n_lines - 1, int(np.floor((sc + r) / spacing + mid)))
            for k in range(k0, k1 + 1):
                s = (k - mid) * spacing
                h2 = r * r - (s - sc) ** 2
                if h2 <= 0.0 or s * s >= R * R:
                    continue
                half_line = np.sqrt(R * R - s * s)
                h = np.sqrt(h2)
                a = max(tc - h, -half_line)
                b = min(tc + h, half_line)
                if b <= a:
                    continue
                if sweep == 0:
                    count[k + 1] += 1
                else:
                    t0[fill[k]] = a
                    t1[fill[k]] = b
                    fill[k] += 1
    void = 0.0
    length = 0.0
    n_void = 0
    for k in range(n_lines):
        s = (k - mid) * spacing
        if s * s >= R * R:
            continue
        half_line = np.sqrt(R * R - s * s)
        length += 2.0 * half_line
        lo, hi = count[k], count[k + 1]
        order = np.argsort(t0[lo:hi])
        pos = -half_line
        for q in range(hi - lo):
            a = t0[lo + order[q]]
            b = t1[lo + order[q]]
            if a > pos:
                void += a - pos
                n_void += 1
            if b > pos:
                pos = b
        if pos < half_line:
            void += half_line - pos
            n_void += 1
    return void, length, n_void


def intercepts_reference(centres, radii, R, spacing, theta):
    """Plain Python/numpy version of :func:`_intercepts` (same line placement), for the tests."""
    u = np.array([np.cos(theta), np.sin(theta)])
    v = np.array([-u[1], u[0]])
    n_lines = int(2.0 * R / spacing)
    void = length = 0.0
    n_void = 0
    for k in range(n_lines):
        s = (k - 0.5 * (n_lines - 1)) * spacing
        if s * s >= R * R:
            continue
        half = np.sqrt(R * R - s * s)
        length += 2 * half
        dist = centres @ v - s
        hit = np.abs(dist) < radii
        h = np.sqrt(radii[hit] ** 2 - dist[hit] ** 2)
        tc = centres[hit] @ u
        iv = sorted((max(a, -half), min(b, half)) for a, b in zip(tc - h, tc + h) if min(b, half) > max(a, -half))
        pos = -half
        for a, b in iv:
            if a > pos:
                void += a - pos
                n_void += 1
            pos = max(pos, b)
        if pos < half:
            void += half - pos
            n_void += 1
    return void, length, n_void


@dataclass
class FabricFit:
    """Kanatani fit of order ``order`` (3.6 for order 1, 3.7 above): C, Omega (2,2), a (order-1,)."""

    order: int
    C: float
    omega: np.ndarray
    a: np.ndarray
    rms: float

    def __call__(self, theta_deg) -> np.ndarray:
        t = np.radians(np.asarray(theta_deg, float))
        x = self.omega[0, 0] * np.cos(2 * t) + self.omega[0, 1] * np.sin(2 * t)  # Omega_ij v_i v_j
        return self.C * (1 + x + sum(ak * x ** (k + 2) for k, ak in enumerate(self.a)))

    @property
    def principal_angle_deg(self) -> float:
        """Angle from x of the eigenvector of Omega with the larger eigenvalue, in (-90, 90]."""
        return float(0.5 * np.degrees(np.arctan2(self.omega[0, 1], self.omega[0, 0])))


@dataclass
class Fabric:
    """Directional fabric measure of one state: ``values`` per direction, ``mean``, ``omega``, ``fit``."""

    measure: str
    directions_deg: np.ndarray
    values: np.ndarray
    void_length: np.ndarray
    line_length: np.ndarray
    n_intercepts: np.ndarray
    domain_radius: float
    grid_spacing: float

    @property
    def mean(self) -> float:
        return float(np.mean(self.values))

    def fit(self, order: int = 1) -> FabricFit:
        """Kanatani fit (3.5-3.7) of order 1, 2 or 3 by least squares."""
        if order not in (1, 2, 3):
            raise ValueError(f"fit order {order!r}: allowed 1, 2, 3")
        t = np.radians(self.directions_deg)
        A = np.column_stack([np.ones_like(t), np.cos(2 * t), np.sin(2 * t)])
        c, cw1, cw2 = np.linalg.lstsq(A, self.values, rcond=None)[0]
        w = np.array([cw1 / c, cw2 / c])
        a = np.zeros(order - 1)
        if order > 1:
            from scipy.optimize import least_squares

            scale = abs(c) if c != 0 else 1.0

            def resid(x):  # relative residuals (values can be ~1e-5 m for MIL)
                xx = x[1] * np.cos(2 * t) + x[2] * np.sin(2 * t)
                model = x[0] * (1 + xx + sum(x[3 + k] * xx ** (k + 2) for k in range(order - 1)))
                return (model - self.values) / scale

            sol = least_squares(resid, np.concatenate([[c], w, a]), x_scale="jac", xtol=1e-15, ftol=1e-15,
                                gtol=1e-15, max_nfev=2000)
            c, w, a = sol.x[0], sol.x[1:3], sol.x[3:]
        omega = np.array([[w[0], w[1]], [w[1], -w[0]]])
        out = FabricFit(order, float(c), omega, np.asarray(a), 0.0)
        out.rms = float(np.sqrt(np.mean((out(self.directions_deg) - self.values) ** 2)))
        return out

    @property
    def omega(self) -> np.ndarray:
        """(2,2) traceless tensor of the first-order Kanatani fit (3.6)."""
        return self.fit(1).omega


def fabric(state: DEMState, measure: str = "areal_porosity", directions_deg=range(0, 180, 10),
           grid_spacing_m: float = 5e-6, domain_fraction: float = 0.85) -> Fabric:
    """Directional fabric of ``state`` by exact line intercepts (Section 3.4.1).

    Parameters
    ----------
    state : anything with ``.positions`` (N,2) m, ``.radii`` (N,) m and walls (a DEMState)
    measure : "areal_porosity" (n, eqs. 3.2-3.4) or "mil" (eq. 3.1)
    directions_deg : test-line directions [deg]
    grid_spacing_m : test-line spacing d [m] (thesis: 5e-6)
    domain_fraction : diameter of the circular domain / current sample width (0.85)
    """
    if measure not in ("areal_porosity", "mil"):
        raise ValueError(f"measure={measure!r}: allowed 'areal_porosity', 'mil'")
    if not (np.isfinite(grid_spacing_m) and grid_spacing_m > 0):
        raise ValueError(f"grid_spacing_m={grid_spacing_m!r}: must be positive")
    corners = state.corners()
    centre = corners.mean(axis=0)
    width = min(np.linalg.norm(corners[1] - corners[0]), np.linalg.norm(corners[3] - corners[0]))
    R = 0.5 * domain_fraction * width
    if R / grid_spacing_m > 5e6:
        raise ValueError(f"grid_spacing_m={grid_spacing_m!r} gives more than 1e7 test lines; use a larger spacing")
    rel = state.positions - centre
    near = np.hypot(rel[:, 0], rel[:, 1]) < R + state.radii
    rel, radii = np.ascontiguousarray(rel[near]), np.ascontiguousarray(state.radii[near])
    dirs = np.asarray(list(directions_deg), float)
    sums = np.array([_intercepts(rel, radii, R, grid_spacing_m, np.radians(t)) for t in dirs])
    void, length, count = sums[:, 0], sums[:, 1], sums[:, 2]
    values = void / length if measure == "areal_porosity" else void / np.maximum(count, 1)  # eq. 3.4 / 3.1
    return Fabric(measure, dirs, values, void, length, count, R, grid_spacing_m)


def delta_deg(omega, strain) -> float:
    """Angle delta between the eigenvectors of Omega and of the strain deviator, folded into (-45, 45].

    Eigenvectors of 2x2 symmetric tensors come in orthogonal pairs, so the angle between the two
    triads is defined modulo 90 deg.
    """
    e = np.asarray(strain) - 0.5 * np.trace(strain) * np.eye(2)
    a_omega = 0.5 * np.degrees(np.arctan2(2 * omega[0, 1], omega[0, 0] - omega[1, 1]))
    a_e = 0.5 * np.degrees(np.arctan2(2 * e[0, 1], e[0, 0] - e[1, 1]))
    d = (a_omega - a_e + 45.0) % 90.0 - 45.0
    return float(d)


@njit(cache=True)
def _raster_solid(centres, radii, R, n_grid):
    """Point counting: fraction of lattice points inside the circle of radius R that are void."""
    h = 2.0 * R / (n_grid - 1)
    solid = np.zeros((n_grid, n_grid), np.bool_)
    for i in range(radii.shape[0]):
        cx, cy, r = centres[i, 0], centres[i, 1], radii[i]
        k0 = max(0, int(np.ceil((cx - r + R) / h)))
        k1 = min(n_grid - 1, int(np.floor((cx + r + R) / h)))
        m0 = max(0, int(np.ceil((cy - r + R) / h)))
        m1 = min(n_grid - 1, int(np.floor((cy + r + R) / h)))
        for k in range(k0, k1 + 1):
            x = -R + k * h
            for m in range(m0, m1 + 1):
                y = -R + m * h
                if (x - cx) ** 2 + (y - cy) ** 2 < r * r:
                    solid[k, m] = True
    inside = 0
    void = 0
    for k in range(n_grid):
        x = -R + k * h
        for m in range(n_grid):
            y = -R + m * h
            if x * x + y * y < R * R:
                inside += 1
                if not solid[k, m]:
                    void += 1
    return void / inside


def area_porosity_in_domain(state: DEMState, domain_fraction: float = 0.85, n_grid: int = 2000) -> float:
    """Porosity of the circular sampling domain by point counting on an n_grid^2 lattice (a check of
    the intercept porosity that does not use test lines)."""
    corners = state.corners()
    centre = corners.mean(axis=0)
    width = min(np.linalg.norm(corners[1] - corners[0]), np.linalg.norm(corners[3] - corners[0]))
    R = 0.5 * domain_fraction * width
    rel = np.ascontiguousarray(state.positions - centre)
    return float(_raster_solid(rel, np.ascontiguousarray(state.radii), R, n_grid))
