"""Sample generation (Appendix A) and isotropic compression with servo-controlled walls.

1. Diameters by inverse-transform sampling of the number-based PSD (:mod:`dem.psd`).
2. Random placement with rejection (uniform centres, A's eta_1/eta_2), largest first, at a reduced
   radius ``placement_factor * r`` so that the random sequential placement can succeed.
3. Radius expansion with zero friction back to the PSD radii (O'Sullivan 2011), then frictionless
   servo compression to a low pressure ``jamming_kPa``: a dense, isostatic packing (Z near 4).
4. :func:`isotropic_compression`: friction switched on, both wall pairs servo-controlled to p.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .contacts import ContactLaw
from .psd import load_psd
from .simulation import Simulation
from .state import DEMState
from . import measures


@njit(cache=True)
def _place(radii, width, height, seed, max_tries):
    """Random sequential placement without overlap (walls included) in [-w/2, w/2] x [-h/2, h/2].

    Returns positions (N,2) and the index of the first particle that could not be placed (-1 if all).
    """
    np.random.seed(seed)
    n = radii.shape[0]
    pos = np.zeros((n, 2))
    cell = 2.0 * radii.max()
    nx = int(width / cell) + 1
    ny = int(height / cell) + 1
    head = -np.ones(nx * ny, np.int64)
    nxt = -np.ones(n, np.int64)
    for i in range(n):
        r = radii[i]
        placed = False
        for _ in range(max_tries):
            x = -0.5 * width + r + np.random.random() * (width - 2 * r)
            y = -0.5 * height + r + np.random.random() * (height - 2 * r)
            cx = min(int((x + 0.5 * width) / cell), nx - 1)
            cy = min(int((y + 0.5 * height) / cell), ny - 1)
            ok = True
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    xx, yy = cx + dx, cy + dy
                    if xx < 0 or yy < 0 or xx >= nx or yy >= ny:
                        continue
                    j = head[yy * nx + xx]
                    while j >= 0:
                        ddx = pos[j, 0] - x
                        ddy = pos[j, 1] - y
                        if ddx * ddx + ddy * ddy < (r + radii[j]) ** 2:
                            ok = False
                            break
                        j = nxt[j]
                    if not ok:
                        break
                if not ok:
                    break
            if ok:
                pos[i, 0] = x
                pos[i, 1] = y
                c = cy * nx + cx
                nxt[i] = head[c]
                head[c] = i
                placed = True
                break
        if not placed:
            return pos, i
    return pos, -1


def generate(n_particles: int = 4000, psd="ottawa_c109", width_m: float | None = None,
             height_m: float | None = None, seed: int = 1, law: ContactLaw | None = None,
             aspect: float = 45.0 / 40.0, box_porosity: float = 0.17, placement_factor: float = 0.7,
             expansion_rate: float = 50.0, jamming_kPa: float = 10.0, progress: bool = False) -> DEMState:
    """Generate a dense, frictionless-jammed sample (Appendix A).

    Parameters
    ----------
    n_particles : int, > 1
    psd : preset name ("ottawa_c109"), CSV path or :class:`dem.psd.PSD` (mass-based sieve curve)
    width_m, height_m : float or None
        Box size [m]. None -> chosen so that the PSD-sized disks fill it at ``box_porosity`` with
        height/width = ``aspect`` (Table 4: 45/40).
    seed : int, the only source of randomness
    law : ContactLaw (its friction is kept for later; the expansion runs frictionless)
    placement_factor : radii are placed at this fraction of their final size, then expanded
    expansion_rate : growth rate of the radii during expansion [1/s]
    jamming_kPa : pressure of the frictionless servo compression that ends the generation [kPa]

    Returns
    -------
    DEMState with meta "stage" = "generated" (radii follow the PSD; positions centred at 0).
    """
    if int(n_particles) != n_particles or n_particles < 2:
        raise ValueError(f"n_particles={n_particles!r}: must be an integer >= 2")
    n_particles = int(n_particles)
    law = law or ContactLaw()
    dist = load_psd(psd)
    rng = np.random.default_rng(seed)
    radii = np.sort(0.5 * dist.sample(n_particles, rng))[::-1].copy()
    solid = float(np.pi * np.sum(radii**2))
    if width_m is None and height_m is None:
        area = solid / (1.0 - box_porosity)
        width_m = float(np.sqrt(area / aspect))
        height_m = aspect * width_m
    elif width_m is None or height_m is None:
        given = width_m if width_m is not None else height_m
        other = solid / (1.0 - box_porosity) / given
        width_m, height_m = (given, other) if width_m is not None else (other, given)
    if not (width_m > 0 and height_m > 0):
        raise ValueError(f"box {width_m!r} x {height_m!r} m: sizes must be positive")
    fraction = solid / (width_m * height_m)
    if fraction > 0.9 or 2 * radii.max() > min(width_m, height_m):
        raise ValueError(
            f"impossible packing: {n_particles} particles of this PSD need a solid area of {solid:.4g} m^2, "
            f"a solid fraction {fraction:.3f} of the {width_m:.4g} x {height_m:.4g} m box (allowed <= 0.9; "
            f"a dense random disk packing holds about 0.84); use fewer particles or a larger box")
    pos, failed = _place(placement_factor * radii, width_m, height_m, seed, 20000)
    if failed >= 0:
        raise ValueError(
            f"impossible packing: could not place particle {failed} of {n_particles} without overlap after "
            f"20000 tries (solid fraction {fraction:.3f} at full size); use fewer particles or a larger box")
    state = DEMState(positions=pos, radii=placement_factor * radii, half_size=[0.5 * width_m, 0.5 * height_m],
                     law=law.replace(friction=0.0),
                     meta={"stage": "placed", "seed": int(seed), "psd": dist.name, "n_particles": n_particles})
    sim = Simulation(state)
    # radius expansion, frictionless (Appendix A): grow to the PSD radii at `expansion_rate`
    total = 1.0 - placement_factor
    n_steps = int(np.ceil(total / placement_factor / expansion_rate / sim.dt))
    batches = max(20, n_steps // 200)
    steps_iter = range(1, batches + 1)
    if progress:
        from tqdm import tqdm
        steps_iter = tqdm(steps_iter, desc="radius expansion", unit="batch")
    for k in steps_iter:
        sim.set_radii(radii * (placement_factor + total * k / batches))
        sim.advance(max(1, n_steps // batches))
    # frictionless servo compression to a low pressure: the dense isostatic state
    _servo_to(sim, -jamming_kPa, max_rate=expansion_rate / 4, progress=progress, unbalanced_max=0.02)
    state.law = law.replace(friction=0.0)
    state.meta.update(stage="generated", jamming_kPa=jamming_kPa, box_porosity=box_porosity,
                      friction=law.friction)  # the friction of the experiments, used by isotropic_compression
    state.velocities[:] = 0.0
    state.angular_velocities[:] = 0.0
    return state


def _servo_to(sim: Simulation, target_kPa: float, max_rate: float, tol: float = 0.01, batch: int = 2000,
              max_steps: int = 3_000_000, progress: bool = False, checkpoint=None, unbalanced_max: float = 0.01) -> None:
    """Run both walls under servo control until the wall stress holds ``target_kPa`` (tension +)
    within ``tol`` and the assembly is static: mean unbalanced force below ``unbalanced_max`` p d."""
    st = sim.state
    sim.set_servo((target_kPa, target_kPa), max_rate=max_rate)
    scale = abs(target_kPa) * 1e3 * 2.0 * float(np.mean(st.radii))
    calm = 0
    done = 0
    while done < max_steps:
        sim.advance(batch, checkpoint=checkpoint)
        done += batch
        s = np.diag(sim.wall_stress_kPa)
        unbalanced = float(np.mean(np.hypot(st.forces[:, 0], st.forces[:, 1]))) / scale
        ok = np.all(np.abs(s - target_kPa) < tol * abs(target_kPa)) and unbalanced < unbalanced_max
        calm = calm + 1 if ok else 0
        if calm >= 3:
            break
    sim.set_servo((None, None))
    st.boundary_rate[:] = 0.0
    sim.sync()


def isotropic_compression(sample: DEMState, p_kPa: float = 100.0, law: ContactLaw | None = None,
                          friction: float | None = None, max_rate: float = 2.0, tol: float = 0.01,
                          progress: bool = False) -> DEMState:
    """Servo-controlled isotropic compression to ``p_kPa`` (compression positive) with friction on.

    ``law`` (default: the sample's law with ``friction`` if given, else the friction of the law given
    to :func:`generate`, else tan 30 deg) is the contact law of the experiments. Returns a new state (the input is not modified), meta stage "isotropic".
    """
    if not (np.isfinite(p_kPa) and p_kPa > 0):
        raise ValueError(f"p_kPa={p_kPa!r}: must be a positive pressure (compression positive)")
    state = sample.copy()
    if law is None:
        mu = friction if friction is not None else state.meta.get("friction", np.tan(np.radians(30.0)))
        law = state.law.replace(friction=float(mu))
    state.law = law
    sim = Simulation(state)
    _servo_to(sim, -float(p_kPa), max_rate=max_rate, tol=tol, progress=progress)
    state.meta.update(stage="isotropic", p_kPa=float(p_kPa), porosity=measures.porosity(state))
    state.velocities[:] = 0.0  # static state: reset the reference for the next stage
    state.angular_velocities[:] = 0.0
    sim.compute_forces()
    return state
