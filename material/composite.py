"""Different material laws on different sets of quadrature points, behind the one-material interface.

:class:`Composite` is itself a material (``initial_state`` / ``update``), so the solver is unchanged.
Each law keeps its own state, stored at full size N under prefixed keys (``"<k>:<key>"``, k the index of
the law) and updated only on its own points; the shared keys every law has (``"strain"``, ``"status"``,
``"step_ratio"``) and the keys of :data:`_MERGED` that the laws having them give in the same shape
(plastic strain, mobilised ratio, the planes' slips and loading flags, the local solver's counts: what
the output and :class:`femgran.diagnostics.NewtonLog` read) are merged at full size; a point of a law
without such a key gets zeros there.
"""

from __future__ import annotations

import copy

import numpy as np

from material.base import STATUS_OK, BackStressTangent, CoupledTangent, as_stress_batch, check_batch

__all__ = ["Composite"]

_SHARED = ("strain", "status", "step_ratio", "reached")
_MERGED = ("plastic_strain", "mobilised_ratio", "eq_plastic_strain", "kappa", "loading", "near_apex", "iterations",
           "continuation", "nonlocal")


class Composite:
    """``laws[k]`` acts on the points where ``assignment == k``.

    Parameters
    ----------
    laws : sequence of material objects
    assignment : (N,) int array, the law index of every point (element-major point numbering,
        see :mod:`femgran.state`).
    """

    def __init__(self, laws, assignment):
        self.laws = list(laws)
        a = np.asarray(assignment)
        if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"assignment: expected a 1D integer array, got {a.dtype} {a.shape}")
        if a.size and (a.min() < 0 or a.max() >= len(self.laws)):
            raise ValueError(f"assignment: law indices must be in 0..{len(self.laws) - 1}")
        self.assignment = a
        self.index = [np.flatnonzero(a == k) for k in range(len(self.laws))]
        self.axes = getattr(self.laws[0], "axes", None)
        self.n_points = a.size
        lengths = {getattr(law, "nonlocal_length", None) for law in self.laws}
        if len(lengths) > 1:
            raise ValueError(f"laws: nonlocal lengths {sorted(lengths, key=str)} differ; a Composite of gradient-"
                             "enhanced laws needs one length (and no local law among them)")
        self._nonlocal_length = lengths.pop()
        back = {getattr(law, "back_stress_length", None) for law in self.laws}
        if len(back) > 1:
            raise ValueError(f"laws: back stress lengths {sorted(back, key=str)} differ; a Composite of laws with "
                             "a gradient back stress needs one length (and no law without it among them)")
        self._back_stress_length = back.pop()
        taus = {getattr(law, "relaxation_time", None) for law in self.laws if getattr(law, "rate_dependent", False)}
        if len(taus) > 1:
            raise ValueError(f"laws: relaxation times {sorted(taus, key=str)} differ; one step_fraction goes to every "
                             "rate-dependent law of a Composite, so they need one relaxation time (or None each: "
                             "one nominal step)")
        self._relaxation_time = taus.pop() if taus else None

    def __repr__(self) -> str:
        parts = ", ".join(f"{law!r} on {idx.size} points" for law, idx in zip(self.laws, self.index))
        return f"Composite({parts})"

    @property
    def nonlocal_length(self) -> float:
        """The laws' common nonlocal length l [m] (gradient-enhanced laws only; ``AttributeError`` otherwise)."""
        if self._nonlocal_length is None:
            raise AttributeError("nonlocal_length: the laws of this Composite are local")
        return self._nonlocal_length

    @property
    def back_stress_length(self) -> float:
        """The laws' common back stress length l_b [m] (``AttributeError`` for laws without the back stress)."""
        if self._back_stress_length is None:
            raise AttributeError("back_stress_length: the laws of this Composite have no gradient back stress")
        return self._back_stress_length

    @property
    def E(self) -> float:
        """Young's modulus of the first law [kPa] (the scale of a coupled discretisation's nonlocal rows)."""
        law = self.laws[0]
        return float(law.E if hasattr(law, "E") else law.params.E)

    @property
    def replay_dir(self):
        """The replay folder of the first law that keeps one (None if none does)."""
        return next((law.replay_dir for law in self.laws if getattr(law, "replay_dir", None) is not None), None)

    def with_replay_dir(self, path) -> "Composite":
        """A copy whose laws that keep failed points write them to ``path`` (this object and its laws unchanged)."""
        new = copy.copy(self)
        new.laws = [law.with_replay_dir(path) if hasattr(law, "with_replay_dir") else law for law in self.laws]
        return new

    def _n(self, n):
        if int(n) != self.assignment.size:
            raise ValueError(f"Composite: {n} points, but the assignment has {self.assignment.size}")
        return int(n)

    def initial_state(self, n_points: int, stress=None, *, element_size=None):
        """States of every law on its points; each law gets the ``element_size`` (N,) of its points."""
        n = self._n(n_points)
        sig = as_stress_batch(stress, n)
        h = None if element_size is None else np.broadcast_to(np.asarray(element_size, float), (n,))
        state = {"strain": np.zeros((n, 3, 3)), "status": np.zeros(n, np.int8), "step_ratio": np.ones(n),
                 "reached": np.ones(n)}
        for k, (law, idx) in enumerate(zip(self.laws, self.index)):
            sub = law.initial_state(idx.size, stress=sig[idx], element_size=None if h is None else h[idx])
            for key, arr in sub.items():
                full = np.zeros((n,) + np.shape(arr)[1:], dtype=np.asarray(arr).dtype)
                full[idx] = arr
                state[f"{k}:{key}"] = full
        self._merge(state)
        return state

    def _merge(self, state):
        for key in _MERGED:
            parts = [(idx, state[f"{k}:{key}"]) for k, idx in enumerate(self.index) if f"{k}:{key}" in state]
            if not parts or any(arr.shape != parts[0][1].shape for _, arr in parts):
                continue  # no law has it, or the laws disagree on its shape (e.g. different plane rules)
            full = np.zeros(parts[0][1].shape, dtype=parts[0][1].dtype)
            for idx, arr in parts:
                full[idx] = arr[idx]
            state[key] = full
        for key in _SHARED:
            for k, idx in enumerate(self.index):
                if f"{k}:{key}" in state:
                    state[key][idx] = state[f"{k}:{key}"][idx]
        return state

    @property
    def rate_dependent(self) -> bool:
        """Any of the laws takes the step's size (``step_fraction``, :attr:`material.CPAModel.rate_dependent`)."""
        return any(getattr(law, "rate_dependent", False) for law in self.laws)

    @property
    def relaxation_time(self) -> float | None:
        """The one relaxation time of the :attr:`rate_dependent` laws (:func:`material.base.step_fraction`)."""
        return self._relaxation_time

    def update(self, d_strain, stress, state, d_nonlocal=None, step_fraction: float = 1.0,
               d_nonlocal_plastic_strain=None):
        """Each law on its points; ``d_nonlocal`` (gradient-enhanced laws, :mod:`material.base`) and
        ``d_nonlocal_plastic_strain`` (laws with a gradient back stress) are split the same way and the
        :class:`material.base.CoupledTangent` or :class:`material.base.BackStressTangent` is merged field by
        field; ``step_fraction`` goes to the :attr:`rate_dependent` laws."""
        de, s = check_batch(d_strain, stress)
        n = self._n(de.shape[0])
        new_stress = np.empty_like(s)
        tangent = None
        new = {"strain": state["strain"] + de, "status": np.full(n, STATUS_OK, np.int8), "step_ratio": np.ones(n),
               "reached": np.ones(n)}
        for k, (law, idx) in enumerate(zip(self.laws, self.index)):
            prefix = f"{k}:"
            sub, extra = self._law_inputs(k, idx, state, d_nonlocal, step_fraction, d_nonlocal_plastic_strain)
            s_k, st_k, D_k = law.update(de[idx], s[idx], sub, **extra)
            new_stress[idx] = s_k
            if tangent is None:
                tangent = _empty_like_tangent(D_k, n)
            _assign_tangent(tangent, idx, D_k)
            for key, arr in st_k.items():
                full = np.array(state[prefix + key], copy=True) if prefix + key in state else \
                    np.zeros((n,) + np.shape(arr)[1:], dtype=np.asarray(arr).dtype)
                full[idx] = arr
                new[prefix + key] = full
        return new_stress, self._merge(new), tangent

    def _law_inputs(self, k: int, rows, state, d_nonlocal, step_fraction, d_nonlocal_plastic_strain):
        """Law k's state at the point ``rows`` and its inputs besides the strain increment (:meth:`update`):
        ``d_nonlocal`` and ``d_nonlocal_plastic_strain`` at those rows, ``step_fraction`` if it is rate
        dependent."""
        law, prefix = self.laws[k], f"{k}:"
        sub = {key[len(prefix):]: arr[rows] for key, arr in state.items() if key.startswith(prefix)}
        extra = {} if d_nonlocal is None else {"d_nonlocal": np.asarray(d_nonlocal, dtype=float)[rows]}
        if d_nonlocal_plastic_strain is not None:
            extra["d_nonlocal_plastic_strain"] = np.asarray(d_nonlocal_plastic_strain, dtype=float)[rows]
        if getattr(law, "rate_dependent", False):
            extra["step_fraction"] = step_fraction
        return sub, extra

    def explain_failure(self, d_strain, stress, state, *, points=None, reached=None, d_nonlocal=None,
                        step_fraction: float = 1.0, d_nonlocal_plastic_strain=None) -> list:
        """Each law's :meth:`material.CPAModel.explain_failure` on its points among ``points`` (default all):
        one sentence or None per point asked, in their order; a law without it says nothing (None).
        ``reached``: per point asked, as there."""
        de, s = check_batch(d_strain, stress)
        n = self._n(de.shape[0])
        asked = np.arange(n) if points is None else np.asarray(points, dtype=np.int64)
        out = [None] * asked.size
        for k, (law, idx) in enumerate(zip(self.laws, self.index)):
            explain = getattr(law, "explain_failure", None)
            mine = np.flatnonzero(np.isin(asked, idx))
            if explain is None or mine.size == 0:
                continue
            rows = asked[mine]
            sub, extra = self._law_inputs(k, rows, state, d_nonlocal, step_fraction, d_nonlocal_plastic_strain)
            if reached is not None:
                extra["reached"] = np.asarray(reached, dtype=float)[mine]
            for j, why in zip(mine, explain(de[rows], s[rows], sub, **extra)):
                out[int(j)] = why
        return out

    def loading_tangent(self, stress, state, **options):
        """:meth:`material.CPAModel.loading_tangent` of each law on its points (N, 3, 3, 3, 3); a law without
        it (not a CPA law) raises ``TypeError`` naming it."""
        s = as_stress_batch(stress, self._n(np.shape(stress)[0]))
        out = np.empty((s.shape[0], 3, 3, 3, 3))
        for k, (law, idx) in enumerate(zip(self.laws, self.index)):
            if not hasattr(law, "loading_tangent"):
                raise TypeError(f"laws[{k}] = {law!r}: has no loading_tangent (a CPA law's diagnostic)")
            prefix = f"{k}:"
            sub = {key[len(prefix):]: arr[idx] for key, arr in state.items() if key.startswith(prefix)}
            out[idx] = law.loading_tangent(s[idx], sub, **options)
        return out


def _empty_like_tangent(D, n: int):
    """An uninitialised tangent of n points of the kind of ``D`` (an array, a CoupledTangent or a
    BackStressTangent)."""
    if isinstance(D, (CoupledTangent, BackStressTangent)):
        return type(D)(*(np.empty((n,) + np.shape(f)[1:]) for f in D))
    return np.empty((n, 3, 3, 3, 3))


def _assign_tangent(tangent, idx, D) -> None:
    if isinstance(tangent, (CoupledTangent, BackStressTangent)):
        for full, part in zip(tangent, D):
            full[idx] = part
    else:
        tangent[idx] = D
