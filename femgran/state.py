"""The material state of the quadrature points at the start and the end of a load step.

scikit-fem keeps quadrature-point fields with tensor indices first and ``(nelems, nqp)`` last,
e.g. a stress field ``(3, 3, nelems, nqp)``. The materials of :mod:`material` work on batches with the
point index first, ``(N, 3, 3)``. femgran numbers the points element-major::

    point = element * nqp + quadrature_point        (N = nelems * nqp)

so a batch reshaped to ``(nelems, nqp, ...)`` is the (element, point) view the kernels of
:mod:`femgran.assembly` use. :class:`PointState` keeps the material state at the start and the end
of a load step (commit on convergence, revert on cut-back, as MGIS does with s0/s1).
"""

from __future__ import annotations

import numpy as np

from material.base import STATUS_FAILED, copy_state

__all__ = ["PointState"]


class PointState:
    """Stress and material state of all quadrature points, at the start (committed) and end (trial) of a step.

    Parameters
    ----------
    material : a material (:class:`material.base.Material`: ``initial_state(n, stress=, element_size=)``
        and ``update(d_strain, stress, state)``)
    n_points : int
        Number of quadrature points N = nelems * nqp.
    initial_stress : None, (3, 3) or (N, 3, 3)
        In-situ stress [kPa], tension positive.
    element_size : None or (N,) [m]
        Size of each point's element, passed to the material (regularised softening, e.g.
        :class:`material.CPAModel`, uses it; laws without a length scale ignore it).
    """

    def __init__(self, material, n_points: int, initial_stress=None, element_size=None):
        from material.base import as_stress_batch

        self.material = material
        self.n_points = int(n_points)
        self.stress = as_stress_batch(initial_stress, self.n_points, "initial_stress")
        self.state = material.initial_state(self.n_points, stress=self.stress, element_size=element_size)
        self.trial_stress = self.stress.copy()
        self.trial_state = copy_state(self.state)
        self.tangent = None

    def evaluate(self, d_strain: np.ndarray, **inputs):
        """Material update over the step increment ``d_strain`` (N, 3, 3) from the committed state.

        ``inputs``: further increments a coupled discretisation passes (``d_nonlocal``). Returns
        ``(stress, tangent, failed)`` with ``failed`` the (N,) mask of STATUS_FAILED points. The result is
        kept as the trial (end-of-step) state.
        """
        stress, state, tangent = self.material.update(d_strain, self.stress, self.state, **inputs)
        self.trial_stress, self.trial_state, self.tangent = stress, state, tangent
        failed = np.asarray(state["status"]) == STATUS_FAILED
        return stress, tangent, failed

    def suggested_ratio(self) -> float:
        """The smallest step ratio the failed points of the last evaluation suggest (1 if none failed)."""
        failed = np.asarray(self.trial_state["status"]) == STATUS_FAILED
        if not failed.any():
            return 1.0
        r = np.asarray(self.trial_state["step_ratio"], dtype=float)[failed]
        r = r[np.isfinite(r) & (r > 0)]
        return float(r.min()) if r.size else 0.5

    def commit(self) -> None:
        """The trial state becomes the start of the next step (on convergence)."""
        self.stress = np.array(self.trial_stress, copy=True)
        self.state = copy_state(self.trial_state)

    def revert(self) -> None:
        """Forget the trial state (on cut-back): the next evaluation starts again from the committed one."""
        self.trial_stress = self.stress.copy()
        self.trial_state = copy_state(self.state)
