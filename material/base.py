"""The material interface every law in :mod:`material` implements, and what the FE solver relies on.

A material object has two methods::

    state = material.initial_state(n_points, stress=sigma0)
    stress, state, tangent = material.update(d_strain, stress, state)

* ``d_strain`` and ``stress``: (N, 3, 3) small strain increment and Cauchy stress at the start of the
  step, **tension positive**, kPa. ``d_strain`` must be symmetric.
* ``tangent``: (N, 3, 3, 3, 3) consistent tangent d(stress_{n+1}) / d(d_strain), kPa, with the minor
  symmetries of a symmetric-to-symmetric map (it may lack the major symmetry: non-associated flow).
* ``state``: a plain ``dict[str, numpy.ndarray]`` whose arrays all have the leading axis N. ``update``
  never modifies its input state; it returns a new dict (so the solver can keep the state at the start
  of a step, commit on convergence, and revert on cut-back). Every law's state carries:

  - ``"status"`` (N,) int8: ``STATUS_OK`` (0), ``STATUS_SUBSTEPPED`` (1: converged with internal
    sub-steps), ``STATUS_FAILED`` (2: no converged stress; the returned stress is the start-of-step
    stress and must not be committed).
  - ``"step_ratio"`` (N,) float: the fraction of the increment the point suggests for the next try
    (1 where it converged).
  - ``"strain"`` (N, 3, 3): the total strain (tension positive), accumulated by ``update``.

  Laws add their own internal variables (plastic strain, hardening variables, ...).

Gradient-enhanced laws (implicit gradient regularisation of softening; :mod:`femgran.gradient` solves the
coupled problem) take one more input and return a richer tangent::

    stress, state, tangent = material.update(d_strain, stress, state, d_nonlocal=d_ebar)

* ``material.nonlocal_length`` [m]: the length l of the Helmholtz equation ebar - l^2 lap(ebar) = e that
  links the nodal nonlocal field ebar to the law's local measure e (e.g. the equivalent plastic strain).
* ``d_nonlocal`` (N,): the step's increment of ebar at the points; ``state["nonlocal"]`` keeps the
  committed ebar.
* ``tangent`` is then a :class:`CoupledTangent` of the five point quantities the coupled assembly needs.
  Without ``d_nonlocal`` the law is local (ebar = e, as in any homogeneous test) and the tangent is the
  ordinary (N, 3, 3, 3, 3) array.

Rate-dependent laws (``material.rate_dependent`` true, e.g. the CPA law with its step stabilisation, a
viscosity) also take the step's size::

    stress, state, tangent = material.update(d_strain, stress, state, step_fraction=f)

* ``f`` > 0: the step's size in units of the law's relaxation time. A law with a ``relaxation_time``
  attribute (not None) states it in the run's time, the load factor of the FE solver (each stage runs from
  0 to 1) or the share of a segment of an element path; without one (the CPA law's default) the relaxation
  time is the run's nominal step, so the FE solver passes the load-factor step over the nominal one and
  the element drivers 1 for each step (1 / n for each of the n sub-steps of a step they cut back).
  :func:`step_fraction` computes f. A law whose relaxation follows the
  step's size returns the committed state as f and d_strain tend to zero, so a cut-back brings the step's
  problem back to the committed equilibrium.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

__all__ = [
    "step_fraction",
    "Material",
    "BackStressTangent",
    "CoupledTangent",
    "STATUS_OK",
    "STATUS_SUBSTEPPED",
    "STATUS_FAILED",
    "as_stress_batch",
    "check_batch",
    "check_state",
    "copy_state",
    "take_state",
    "where_state",
    "check_positive",
    "check_steps",
]

STATUS_OK = 0
STATUS_SUBSTEPPED = 1
STATUS_FAILED = 2

State = dict[str, np.ndarray]


class CoupledTangent(NamedTuple):
    """The response of a gradient-enhanced law at N points, for the coupled (u, ebar) Newton system.

    ``dstress_dstrain`` (N, 3, 3, 3, 3) kPa, ``dstress_dnonlocal`` (N, 3, 3) kPa, ``local`` (N,) the local
    measure e at the end of the step, ``dlocal_dstrain`` (N, 3, 3) and ``dlocal_dnonlocal`` (N,): all
    derivatives of the end-of-step values with respect to the step's increments of strain and of ebar.
    """

    dstress_dstrain: np.ndarray
    dstress_dnonlocal: np.ndarray
    local: np.ndarray
    dlocal_dstrain: np.ndarray
    dlocal_dnonlocal: np.ndarray


class BackStressTangent(NamedTuple):
    """The response of a law with a gradient back stress at N points, for a coupled (u, ebar_p) Newton system
    whose nonlocal field is the plastic strain tensor (e.g. :class:`material.CPAModel` with a
    ``back_stress_modulus``).

    ``dstress_dstrain`` and ``dstress_dnonlocal`` (N, 3, 3, 3, 3) kPa, ``local`` (N, 3, 3) the plastic strain
    eps_p at the end of the step, ``dlocal_dstrain`` and ``dlocal_dnonlocal`` (N, 3, 3, 3, 3): the derivatives
    of the end-of-step values with respect to the step's increments of strain and of ebar_p.
    """

    dstress_dstrain: np.ndarray
    dstress_dnonlocal: np.ndarray
    local: np.ndarray
    dlocal_dstrain: np.ndarray
    dlocal_dnonlocal: np.ndarray


class Material(Protocol):
    """Structural type of a Gauss-point material (see the module docstring)."""

    def initial_state(self, n_points: int, stress=None, *, element_size=None) -> State: ...

    def update(self, d_strain: np.ndarray, stress: np.ndarray, state: State) -> tuple[np.ndarray, State, np.ndarray]: ...


def as_stress_batch(stress, n_points: int, name: str = "stress") -> np.ndarray:
    """Broadcast ``None`` (zero), a (3, 3) or an (N, 3, 3) tensor to a validated (N, 3, 3) float array."""
    n_points = int(n_points)
    if n_points < 0:
        raise ValueError(f"n_points = {n_points}: must be >= 0")
    if stress is None:
        return np.zeros((n_points, 3, 3))
    s = np.asarray(stress, dtype=float)
    if s.shape == (3, 3):
        s = np.broadcast_to(s, (n_points, 3, 3)).copy()
    if s.shape != (n_points, 3, 3):
        raise ValueError(f"{name}: expected shape (3, 3) or ({n_points}, 3, 3), got {s.shape}")
    _check_finite_symmetric(s, name)
    return s


def check_batch(d_strain, stress) -> tuple[np.ndarray, np.ndarray]:
    """Validate the inputs of ``update``: shapes (N, 3, 3), finite, symmetric. Returns float arrays."""
    de = np.asarray(d_strain, dtype=float)
    s = np.asarray(stress, dtype=float)
    if de.ndim != 3 or de.shape[1:] != (3, 3):
        raise ValueError(f"d_strain: expected shape (N, 3, 3), got {de.shape}")
    if s.shape != de.shape:
        raise ValueError(f"stress: expected shape {de.shape} (same as d_strain), got {s.shape}")
    _check_finite_symmetric(de, "d_strain")
    _check_finite_symmetric(s, "stress")
    return de, s


def _check_finite_symmetric(a: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(a).all(axis=(1, 2))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: {int(bad.sum())} tensor(s) contain NaN or inf (first at point {i})")
    scale = np.abs(a).max(axis=(1, 2))
    asym = np.abs(a - np.swapaxes(a, 1, 2)).max(axis=(1, 2))
    bad = asym > 1e-10 * np.maximum(scale, 1e-300) + 1e-300
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{name}: {int(bad.sum())} tensor(s) are not symmetric (first at point {i}, "
            f"max |a - a^T| = {asym[i]:.3g}); allowed: symmetric tensors"
        )


def check_state(state: State, n_points: int, required: tuple[str, ...]) -> None:
    """Raise ``ValueError`` if ``state`` lacks a key or an array does not have the leading axis N."""
    if not isinstance(state, dict):
        raise ValueError(f"state: expected the dict returned by initial_state(), got {type(state).__name__}")
    for key in required:
        if key not in state:
            raise ValueError(f"state: missing key {key!r}; did it come from this material's initial_state()?")
    for key, arr in state.items():
        if np.shape(arr)[:1] != (n_points,):
            raise ValueError(f"state[{key!r}]: leading axis {np.shape(arr)[:1]} does not match N = {n_points}")


def copy_state(state: State) -> State:
    """A deep copy (every array copied)."""
    return {k: np.array(v, copy=True) for k, v in state.items()}


def take_state(state: State, index) -> State:
    """The state of a subset of points (``index`` as for numpy fancy indexing on the leading axis)."""
    return {k: v[index] for k, v in state.items()}


def where_state(mask: np.ndarray, new: State, old: State) -> State:
    """Per point: ``new`` where ``mask`` (N,) is true, else ``old``."""
    out = {}
    for k in new:
        m = mask.reshape((-1,) + (1,) * (new[k].ndim - 1))
        out[k] = np.where(m, new[k], old[k])
    return out


def check_positive(name: str, value, allow_zero: bool = False) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``allow_zero``), else ``ValueError`` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name} = {value!r}: must be {'>= 0' if allow_zero else '> 0'} (finite)")
    return v


def check_steps(steps, name: str = "steps") -> int:
    """``steps`` as an int >= 1, else ``ValueError`` naming it."""
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"{name} = {steps!r}: must be an integer >= 1")
    return int(steps)


def step_fraction(material, dt: float, nominal: float) -> float:
    """The size of a step of duration ``dt`` in units of ``material``'s relaxation time: ``dt /
    material.relaxation_time`` when the law has one, else ``dt / nominal`` (a relaxation time of one nominal
    step). ``dt`` and ``nominal`` are in the run's time (module docstring)."""
    tau = getattr(material, "relaxation_time", None)
    return float(dt) / float(nominal if tau is None else tau)
