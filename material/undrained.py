"""Undrained behaviour in effective stress: the soil skeleton's law plus the pore water as a penalty.

:class:`Undrained` wraps any material. The pore water takes the volumetric strain with the bulk modulus
``K = K_w / n`` (the water's bulk modulus over the porosity; water: 2.2e6 kPa, so 5.5e6 kPa at n = 0.4),
the usual penalty formulation of undrained analysis in effective stress:

    u = u_n - K tr(d_eps)           (excess pore pressure, compression positive)
    sigma = sigma' - u I            (total stress, tension positive; sigma' from the wrapped law)
    D = D' + K (I x I)              (consistent tangent)

The solver works with the total stress; the wrapped law sees the effective stress sigma' = sigma + u I.
The excess pore pressure is the state key ``pore_pressure_kPa`` (written as a field and, by the cases,
as the history column of its mean). With K much larger than the skeleton's bulk modulus the volume hardly
changes: the constant-volume element test is the limit (its pore pressure is the constraint's multiplier).
The initial stress is effective and the initial excess pore pressure zero.
"""

from __future__ import annotations

import numpy as np

from material.base import check_batch, check_positive

__all__ = ["Undrained", "WATER_BULK_MODULUS_KPA"]

WATER_BULK_MODULUS_KPA = 2.2e6


class Undrained:
    """``law`` (any material) with undrained pore water of bulk modulus ``bulk_modulus_kPa`` = K_w / n."""

    def __init__(self, law, bulk_modulus_kPa: float = WATER_BULK_MODULUS_KPA / 0.4):
        self.law = law
        self.bulk_modulus = check_positive("pore_bulk_modulus_kPa", bulk_modulus_kPa)
        self.axes = getattr(law, "axes", None)
        self.params = getattr(law, "params", None)

    def __repr__(self) -> str:
        return f"Undrained({self.law!r}, bulk_modulus_kPa={self.bulk_modulus:g})"

    @property
    def replay_dir(self):
        return getattr(self.law, "replay_dir", None)

    def with_replay_dir(self, path) -> "Undrained":
        law = self.law.with_replay_dir(path) if hasattr(self.law, "with_replay_dir") else self.law
        return Undrained(law, self.bulk_modulus)

    def initial_state(self, n_points: int, stress=None, *, element_size=None):
        state = dict(self.law.initial_state(n_points, stress=stress, element_size=element_size))
        state["pore_pressure_kPa"] = np.zeros(int(n_points))
        return state

    @property
    def rate_dependent(self) -> bool:
        """The wrapped law takes the step's size (``step_fraction``, :attr:`material.CPAModel.rate_dependent`)."""
        return bool(getattr(self.law, "rate_dependent", False))

    @property
    def relaxation_time(self) -> float | None:
        """The wrapped law's (:func:`material.base.step_fraction`)."""
        return getattr(self.law, "relaxation_time", None)

    def update(self, d_strain, stress, state, step_fraction: float = 1.0):
        de, sig = check_batch(d_strain, stress)
        u_n = np.asarray(state["pore_pressure_kPa"], dtype=float)
        eye = np.eye(3)
        effective = sig + u_n[:, None, None] * eye
        inner = {k: v for k, v in state.items() if k != "pore_pressure_kPa"}
        extra = {"step_fraction": step_fraction} if self.rate_dependent else {}
        s_eff, new, tangent = self.law.update(de, effective, inner, **extra)
        u = u_n - self.bulk_modulus * np.trace(de, axis1=1, axis2=2)
        new = dict(new)
        new["pore_pressure_kPa"] = u
        if tangent is not None:
            tangent = np.asarray(tangent) + self.bulk_modulus * np.einsum("ij,kl->ijkl", eye, eye)[None]
        return s_eff - u[:, None, None] * eye, new, tangent
