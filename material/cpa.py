"""The microplane Critical Plane Approach (CPA) law of anisotropic sand, as a Gauss-point routine.

Theory: thesis sections 2.3 and 3.5, with the package's corrections and decisions written down in
``docs/cpa_law.md``. The numba kernels are :mod:`material._cpa_plane` (one plane),
:mod:`material._cpa_local` (the local problem of one point and its solver), :mod:`material._cpa_rate`
(the rate problem at the start of a step), :mod:`material._cpa_point` (the update of one point and its
tangent) and :mod:`material._cpa_kernel` (the loop over points); this module validates input, prepares the plane data
in the global frame, and owns the state layout and the failure replay files.

The update in brief
-------------------
Backward Euler: the end-of-step stress, the slip increments of the planes and the opening of a
mean-stress cut-off solve the strain residual and one complementarity condition per plane (a plane's
slip grows only while its mobilised ratio sits on its hardening curve) and for the cut-off. The stress
is the solution of these equations, a deterministic function of (d_strain, stress, state), found by a
semismooth Newton method from the start of the step with a line search on a merit function, with
continuation in the fraction of the increment as the one outer loop; the consistent tangent is the
derivative of that solution (:mod:`material._cpa_point`).

Where the branch followed from the start ends before the end of the increment (a limit point of the
strain-driven response: the non-associated planes of a point near failure can lose the uniqueness of
their rate problem, ``docs/cpa_law.md`` section 4), the state at the limit point, located by bisection
in the fraction of the increment, is taken as the start of the rest of the increment, which is followed
the same way (up to :attr:`CPAModel.MAX_LIMIT_POINTS` times). The stress stays a deterministic function
of (d_strain, stress, state), and it is continuous where the one-step answer was not: through the onset
of a limit point (the fraction tends to 1) and where the limit moves to the start of the step (the rest
is then the whole increment). At such a point the tangent is the forward difference of this function
(``state["limit_points"]`` counts them; the rate-independent local hardening law only). With the step
stabilisation a branch that folds is replaced by the floor homotopy: the whole increment's equations
solved along the stabilisation's floor, from a multiple of it down to it (``material._cpa_point``). A point
that still cannot be integrated returns its start-of-step stress, ``status = STATUS_FAILED`` and the fraction
it reached as a suggested step ratio, never NaN; its inputs are kept (and written to ``replay_dir``) so
:func:`replay` can re-run it.

Decisions not fixed by the thesis (``docs/cpa_law.md`` gives the reasons and the measurements)
-------------------------------------------------------------------------------------------
* The apex: the mobilised ratio is sqrt(tau^2 + b^2) / (sigma_N + c / eta_f + c_a), with
  c_a = :attr:`CPAParameters.apex_stress` (default 0.04 kPa) and b = c_a / 10: every loading surface is
  a convex cone with a rounded tip in tension, so a point can reach and leave zero stress without a
  singularity; a cohesion enters as a shift of the normal stress (the failure surface
  tau = c + eta_f sigma_N is the thesis's).
* The compaction of a plane fades below the normal stress :attr:`CPAParameters.compaction_stress`
  (default 2 kPa): without it the strain-driven update of a contractive plane set at low stress has no
  solution (measured on the surface points of a footing).
* Tension cut-off: the mean stress cannot be tensile; an extension beyond it opens the material
  (plastic volumetric strain, ``state["cutoff_opening"]``).
* ``initial_state(n, stress=sigma0)`` puts every plane 5 % above the hardening level of sigma0 (kappa_a
  from its mobilised ratio, as after a monotonic history) and counts no plastic strain for it, so an
  in-situ (K0) stress starts inside a small elastic range.
* State variable of each plane: the accumulated slip kappa [m]; the loading threshold eta(kappa_n) is
  evaluated with the current eta_f, so with induced anisotropy a strengthened plane needs a higher
  ratio to load again.
* Elasticity: isotropic Hooke (E, nu), the macroscopic limit of the plane-based form (2.15).
"""

from __future__ import annotations

import copy
import itertools
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from material import _cpa_kernel as _k
from material._cpa_local import Law, Limits, Options
from material._cpa_plane import APEX_ROUNDING
from material.anisotropy import axes_from_frame, cohesion, default_axes, inherent_tensor
from material.base import (BackStressTangent, CoupledTangent, STATUS_FAILED, STATUS_OK, State, as_stress_batch,
                           check_batch, check_state)
from material.elastic import mandel_elastic
from material.parameters import CPAParameters, load_preset, parameters_from_dict
from material.tensors import to_mandel

__all__ = ["CPAModel", "replay", "mandel_elastic"]

_STATE_KEYS = ("strain", "plastic_strain", "kappa")


@dataclass(frozen=True)
class _Options:
    maxit: int = 25
    max_halvings: int = 12
    tol: float = 1e-12
    stabilisation: float | str = 0.0
    relaxation_time: float | None = None


#: The value of ``stabilisation`` that computes each point's mu (:class:`CPAModel`).
MINIMAL = "minimal"


class CPAModel:
    """Microplane CPA elastoplastic law with inherent and induced anisotropy.

    Parameters
    ----------
    params : CPAParameters or str
        Material constants, or the name of a preset (``"ottawa_c109"``, ``"ottawa_c109_induced"``).
    rule : str
        Integration rule of the planes (:func:`material.planes.available_rules`), default Bazant-Oh 33.
    axes : (3, 3) array, optional
        Material axes, columns e1, e2, e3 (e2 = deposition axis); default ``axes_from_alpha(0)``
        (e2 = global z). The planes are attached to this frame: n_a = R n_a^ref.
    maxit : int
        Newton iterations of the local solver per continuation level.
    max_halvings : int
        How often the continuation may halve the fraction of the increment before the point fails.
    tol : float
        Convergence of the local solver: |R| <= tol (|d_eps| + |sigma_n| / E) and every
        complementarity residual <= tol (dimensionless).
    stabilisation : float or "minimal"
        mu in [0, 1]: a Perzyna-type viscosity. The step equation of a loading plane is
        etah = eta(kappa_n + dkappa) + h_a dkappa / f, with the floor h_a = mu (w_a / t) G / sigma~_a (mu times
        the plane's elastic self-coupling at sigma_n) and f the step's size in relaxation times
        (``step_fraction`` of :meth:`update`): a hardening of at least h_a / f within the step, an overstress
        h_a tau dkappa/dt (``docs/cpa_law.md``, section 4). It makes the step's complementarity problem
        uniquely solvable where the coupling of non-associated planes near failure has no unique rate
        solution. A shorter step (a cut-back) relaxes the overstress a longer one left only in proportion to
        its length, so the update tends to the committed state as the step tends to zero. 0 (the default)
        solves the thesis's law. ``"minimal"``: each point takes, at the start of each step, the least mu for
        which the coupling matrix of its planes on their curves is a P-matrix by a sufficient condition (its
        rate problem has one solution): 0 wherever the thesis's law is uniquely solvable, so the law is
        changed only at the points where it has no unique response (``state["stabilisation"]`` records
        each point's mu). Measured, it does not carry the thesis-sand footings: points lose uniqueness
        through planes that join within a step, which the start of the step does not show
        (``docs/cpa_law.md``, section 4); 0.1 does. ``state["overstress"]`` records what the floor
        changes: the largest share of a loading plane's mobilised ratio it carries above the hardening
        curve (0 for the thesis's law); compare a run with one at a smaller mu.
    relaxation_time : float, optional
        tau > 0 of the stabilisation, in the run's time: the load factor of an FE stage (0 to 1) or the
        share of a segment of an element path (:func:`material.base.step_fraction`). None (the default):
        one nominal step of the run, so the viscosity shrinks as the nominal steps are refined and a result
        mixes the step's error with the viscosity's; with a given tau the run converges, as the steps are
        refined, to the viscous solution of that tau (measured on the stiff sand's footing: 1150.7, 1149.4
        and 1148.0 kPa with 40, 80 and 160 nominal steps at tau = 1/40, where one nominal step gave 1150.7,
        1011.5 and 899.2 kPa; ``docs/cpa_law.md``, section 4), and the rate-independent law is its limit tau -> 0.
        Only with a stabilisation (``stabilisation`` > 0 or "minimal").
    replay_dir : path, optional
        Where the inputs of failed points are written (one ``.npz`` per failing call) for :func:`replay`.
    threads : int, optional
        Numba threads for the update (default: numba's setting).
    regularise : bool
        Scale the post-peak softening by each point's element size (``softening_slip t / h``, the
        default; :meth:`initial_state`). False applies the law as if every element were one band
        thickness t wide, whatever its size: the unregularised, mesh-dependent reference.
    nonlocal_length : float, optional
        l [m] > 0: regularise the post-peak softening by an implicit gradient instead of the crack band
        (``docs/regularisation.md``, section 3; the FE cases then solve for the nonlocal field ebar of the
        post-peak slip strain, :mod:`femgran.gradient`). Needs a softening law (``softening_slip`` > 0).
    over_nonlocal : float
        m > 1 of the gradient: a plane past its peak softens with kappa + m t (ebar - e), e the point's
        post-peak slip strain (default 2).
    back_stress_modulus, back_stress_length : float, optional
        H_g [kPa] >= 0 and l_b [m] > 0 of a gradient back stress X = H_g (eps_p - ebar_p): every plane's
        ratio is taken at sigma - X, with ebar_p the nonlocal plastic strain tensor,
        ebar_p - l_b^2 lap(ebar_p) = eps_p (``docs/regularisation.md``, section 5). In a homogeneous state
        ebar_p = eps_p and X = 0: the element tests and the calibration are the law's. :meth:`update` takes the
        step's increment of ebar_p (``d_nonlocal_plastic_strain``); 0 (default): no back stress. Not combined
        with ``nonlocal_length``, nor yet with induced anisotropy (``beta`` != 0). The FE cases solve for
        ebar_p (:class:`femgran.gradient.BackStressDiscretisation`).
    """

    TANGENTS = ("tensor", "mandel")  # forms of the tangent :meth:`update` returns

    def __init__(self, params: CPAParameters | str = "ottawa_c109", rule: str = "bazant-oh-33", axes=None, *,
                 maxit: int = 25, max_halvings: int = 12, tol: float = 1e-12, stabilisation: float | str = 0.0,
                 relaxation_time: float | None = None, replay_dir: str | os.PathLike | None = None,
                 threads: int | None = None, regularise: bool = True,
                 nonlocal_length: float | None = None, over_nonlocal: float = 2.0,
                 back_stress_modulus: float = 0.0, back_stress_length: float | None = None):
        from material.planes import integration_rule

        if isinstance(params, str):
            params = load_preset(params)
        if not isinstance(params, CPAParameters):
            raise ValueError(f"params: expected CPAParameters or a preset name, got {type(params).__name__}")
        if int(maxit) < 1:
            raise ValueError(f"maxit = {maxit!r}: must be >= 1")
        if not 0 <= int(max_halvings) <= 30:
            raise ValueError(f"max_halvings = {max_halvings!r}: allowed 0..30")
        if not (0 < float(tol) < 1e-3):
            raise ValueError(f"tol = {tol!r}: allowed 0 < tol < 1e-3")
        stabilisation = _check_stabilisation(stabilisation)
        relaxation_time = _check_relaxation_time(relaxation_time, stabilisation)
        if nonlocal_length is not None:
            if not (np.isfinite(float(nonlocal_length)) and float(nonlocal_length) > 0.0):
                raise ValueError(f"nonlocal_length = {nonlocal_length!r}: must be > 0 (m), or None for no gradient")
            if params.softening_slip <= 0.0:
                raise ValueError(f"nonlocal_length = {nonlocal_length!r}: regularises the post-peak softening, but "
                                 f"softening_slip = {params.softening_slip!r}; allowed with softening_slip > 0 "
                                 "(and zeta > 1)")
        back_stress_modulus, back_stress_length = _check_back_stress(back_stress_modulus, back_stress_length,
                                                                     nonlocal_length, float(params.beta))
        if not (np.isfinite(float(over_nonlocal)) and float(over_nonlocal) > 1.0):
            raise ValueError(f"over_nonlocal = {over_nonlocal!r}: must be > 1 (with 1 the band keeps narrowing)")
        self._nonlocal_length = None if nonlocal_length is None else float(nonlocal_length)
        self.over_nonlocal = float(over_nonlocal)
        self.params = params
        self.rule = rule
        self.axes = default_axes() if axes is None else axes_from_frame(axes)
        self.options = _Options(int(maxit), int(max_halvings), float(tol), stabilisation, relaxation_time)
        self.replay_dir = None if replay_dir is None else Path(replay_dir)
        self.threads = threads
        self.regularise = bool(regularise)
        self.last_failure: dict | None = None

        normals_ref, weights = integration_rule(rule)
        self.normals = np.ascontiguousarray(normals_ref @ self.axes.T)  # n_a = R n_a^ref
        self.weights = np.ascontiguousarray(weights, dtype=float)
        self._nn6 = np.ascontiguousarray(to_mandel(np.einsum("ai,aj->aij", self.normals, self.normals)))  # n (x) n
        self._om6 = to_mandel(inherent_tensor(params.omega1, self.axes))
        self._cohesion = np.ascontiguousarray(cohesion(params, self.normals, self.axes), dtype=float)
        self._coeffs = np.ascontiguousarray(params.a, dtype=float)
        self._stiff, self._comp = mandel_elastic(params.E, params.nu)
        p = params
        self._law = Law(self.normals, self._nn6, self.weights, self._cohesion, self._om6, self._coeffs,
                        float(p.eta0), float(p.beta), float(p.alpha_hat), float(p.beta_hat), float(p.zeta),
                        float(p.A), 1.0 / p.t, float(p.eta_c_ratio), float(p.apex_stress),
                        APEX_ROUNDING * float(p.apex_stress),
                        float(p.kappa_instability), float(p.residual_ratio), float(p.compaction_stress),
                        float(p.bulk_modulus),
                        self._comp, self._stiff)
        self.back_stress_modulus = back_stress_modulus
        self._back_stress_length = back_stress_length
        self._shifted = None if back_stress_modulus == 0.0 else _ShiftedElasticity(self._law, p.E, p.nu,
                                                                                   back_stress_modulus)

    def replace(self, *, params: CPAParameters | None = None, axes=None, **options) -> "CPAModel":
        """A new law with the same rule, axes and options as this one except those given (``params``,
        ``axes``, or any keyword of the constructor); this law is unchanged."""
        kw = dict(rule=self.rule, maxit=self.options.maxit, max_halvings=self.options.max_halvings,
                  tol=self.options.tol, stabilisation=self.options.stabilisation,
                  relaxation_time=self.options.relaxation_time, replay_dir=self.replay_dir,
                  threads=self.threads, regularise=self.regularise, nonlocal_length=self._nonlocal_length,
                  over_nonlocal=self.over_nonlocal, back_stress_modulus=self.back_stress_modulus,
                  back_stress_length=self._back_stress_length)
        kw.update(options)
        return CPAModel(self.params if params is None else params, axes=self.axes if axes is None else axes, **kw)

    def with_replay_dir(self, path) -> "CPAModel":
        """This law writing the inputs of its failing points to ``path`` (a copy: this object keeps its folder)."""
        new = copy.copy(self)
        new.replay_dir = None if path is None else Path(path)
        new.last_failure = None
        return new

    @property
    def n_planes(self) -> int:
        return self.normals.shape[0]

    @property
    def nonlocal_length(self) -> float:
        """The gradient's length l [m] (``AttributeError`` for the local law: the crack band or none)."""
        if self._nonlocal_length is None:
            raise AttributeError("nonlocal_length: this CPA law has no gradient regularisation")
        return self._nonlocal_length

    @property
    def back_stress_length(self) -> float:
        """The back stress's length l_b [m] (``AttributeError`` for a law without the back stress)."""
        if self._back_stress_length is None:
            raise AttributeError("back_stress_length: this CPA law has no gradient back stress")
        return self._back_stress_length

    @property
    def relaxation_time(self) -> float | None:
        """tau of the step stabilisation in the run's time, or None: one nominal step (``relaxation_time``
        of the constructor; :func:`material.base.step_fraction`)."""
        return self.options.relaxation_time

    @property
    def E(self) -> float:
        """Young's modulus [kPa] (the scale of the nonlocal field's equation, :mod:`femgran.gradient`)."""
        return float(self.params.E)

    def __repr__(self) -> str:
        return f"CPAModel({self.params.name!r}, rule={self.rule!r}, planes={self.n_planes})"

    # ----------------------------------------------------------------------------- friction
    def friction_coefficients(self, strain=None) -> np.ndarray:
        """eta_f of every plane (M,), or (N, M) for a batch of total strains (N, 3, 3) (eqs. 2.4, 3.15)."""
        if strain is None:
            strain = np.zeros((1, 3, 3))
            squeeze = True
        else:
            strain = np.asarray(strain, dtype=float)
            squeeze = strain.ndim == 2
            strain = strain.reshape(-1, 3, 3)
        p = self.params
        out = _k.strengths(self._nn6, self._om6, self._coeffs, p.eta0, p.beta, p.alpha_hat, p.beta_hat,
                           _k.to_mandel(np.ascontiguousarray(strain)))
        return out[0] if squeeze else out

    def mobilised_ratios(self, stress, strain=None) -> np.ndarray:
        """etah_a = tau_a / N(sigma_N,a + c_a / eta_f,a) of every plane, (N, M), for stresses (N, 3, 3)
        (tension +) and total strains (N, 3, 3) (default 0; they set eta_f with induced anisotropy)."""
        sig = np.ascontiguousarray(np.asarray(stress, dtype=float).reshape(-1, 3, 3))
        eps = np.zeros_like(sig) if strain is None else np.asarray(strain, dtype=float).reshape(-1, 3, 3)
        ef = self.friction_coefficients(eps)
        return _k.ratios(self._law, _k.to_mandel(sig), np.ascontiguousarray(ef))

    # ----------------------------------------------------------------------------- state
    def initial_state(self, n_points: int, stress=None, *, elastic_margin: float = 0.05,
                      element_size=None) -> State:
        """State of ``n_points`` Gauss points that carry the initial stress ``stress`` (tension +).

        Each plane starts at the hardening level of that stress: kappa_a = A e_a / (zeta eta_f,a - e_a)
        with e_a = (1 + elastic_margin) etah_a, etah_a the mobilised ratio of ``stress`` (0 for an
        isotropic stress), capped at 0.98 of the largest ratio the hardening branch reaches. The default
        margin of 5 % gives an in-situ (e.g. K0) state a small elastic range: a sand consolidated under
        that stress reloads elastically at first, and a boundary-value problem does not start with every
        plane of every point exactly on its loading/unloading kink. ``elastic_margin=0`` puts every plane
        exactly on its hardening curve. The plastic strain and the total strain start at zero. A stress
        with mean tension or at the failure surface of some plane is rejected.

        ``element_size`` (scalar or (N,) [m], default t): the size h of the finite element each point
        belongs to, which the post-peak softening law needs (``softening_slip > 0``): beyond the peak the
        slip of a plane is read as a displacement jump across a band of thickness t smeared over h, so
        the softening slip scale of the point is ``softening_slip t / h`` (the crack-band method,
        Bazant & Oh 1983; Pietruszczak & Mroz 1981 for the averaging over an element with a band). The FE
        solver passes it (:class:`femgran.state.PointState`); element drivers leave it at t, where the
        point is the band.
        """
        if not (0.0 <= float(elastic_margin) <= 1.0):
            raise ValueError(f"elastic_margin = {elastic_margin!r}: allowed 0..1")
        sig = as_stress_batch(stress, n_points)
        n = sig.shape[0]
        h = np.full(n, self.params.t) if element_size is None else np.broadcast_to(
            np.asarray(element_size, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(h) & (h > 0)):
            raise ValueError(f"element_size: {int(np.sum(~(np.isfinite(h) & (h > 0))))} value(s) are not "
                             "finite and > 0; allowed: element sizes in m, > 0")
        M = self.n_planes
        kappa = np.zeros((n, M))
        if n and np.any(sig):
            p = self.params
            tension = np.trace(sig, axis1=1, axis2=2) > 0.0
            etah = self.mobilised_ratios(sig)
            ef = self.friction_coefficients()[None, :]
            barrier = ef if p.softening_slip > 0 else p.zeta * ef
            bad = tension | (etah >= barrier * (1 - 1e-9)).any(axis=1)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ValueError(
                    f"initial stress: {int(bad.sum())} point(s) have a mean tension or are at or beyond the "
                    f"failure surface of some plane (first: point {i}); allowed: compressive stresses strictly "
                    "inside the CPA strength envelope"
                )
            level = np.minimum(etah * (1.0 + elastic_margin), np.maximum(etah, 0.98 * barrier))
            kappa = p.A * level / (p.zeta * ef - level)
        return {
            "strain": np.zeros((n, 3, 3)),
            "plastic_strain": np.zeros((n, 3, 3)),
            "kappa": kappa,
            "status": np.zeros(n, dtype=np.int8),
            "step_ratio": np.ones(n),
            "iterations": np.zeros(n, dtype=np.int32),
            "continuation": np.zeros(n, dtype=np.int32),
            "loading": np.zeros((n, M), dtype=bool),
            "cutoff_opening": np.zeros(n),
            "mobilised_ratio": np.zeros(n),
            "stabilisation": np.zeros(n),
            "overstress": np.zeros(n),
            "limit_points": np.zeros(n, dtype=np.int32),
            "near_apex": np.abs(sig).max(axis=(1, 2)) <= 10.0 * self.params.apex_stress,
            "element_size": h,
            **({} if self._nonlocal_length is None else {"nonlocal": np.zeros(n), "post_peak_strain": np.zeros(n),
                                                          "nonlocal_shift": np.zeros((n, M))}),
            **({} if self._shifted is None else {"nonlocal_plastic_strain": np.zeros((n, 3, 3)),
                                                 "back_stress": np.zeros((n, 3, 3))}),
        }

    def _softening_scale(self, state: State, n: int) -> np.ndarray:
        """Per point slip scale of the post-peak softening, softening_slip t / h (0: none); softening_slip itself
        where a gradient (the implicit gradient or the back stress) regularises instead of the crack band."""
        p = self.params
        if p.softening_slip == 0.0:
            return np.zeros(n)
        h = state.get("element_size")
        if h is None or not self.regularise or self._nonlocal_length is not None or self._shifted is not None:
            return np.full(n, p.softening_slip)
        return p.softening_slip * p.t / np.asarray(h, dtype=float)

    def _committed(self, stress, state: State):
        """(N, stress (N, 3, 3), kappa (N, M)) of committed states, checked (the diagnostics' input)."""
        n = np.asarray(state["kappa"]).shape[0] if "kappa" in state else 0
        sig = as_stress_batch(stress, n)
        check_state(state, n, _STATE_KEYS)
        kap = np.ascontiguousarray(state["kappa"], dtype=float)
        if kap.shape != (n, self.n_planes):
            raise ValueError(f"state['kappa']: shape {kap.shape} does not match ({n}, {self.n_planes})")
        return n, sig, kap

    def uniqueness_floor(self, stress, state: State) -> np.ndarray:
        """The least mu of the step stabilisation for which the rate problem of each committed state (stress,
        state) is uniquely solvable by the sufficient condition of the ``"minimal"`` stabilisation, (N,):
        0 where the thesis's law has one response to every strain rate, and otherwise how far the point is from
        it (``docs/cpa_law.md``, section 4). A diagnostic of where and how much the law loses uniqueness (what
        ``femgran replay`` prints for a stopped run); it does not see planes that join within a step."""
        n, sig, kap = self._committed(stress, state)
        out = np.empty(n)
        eps6 = _k.to_mandel(np.ascontiguousarray(state["strain"], dtype=float))
        _k.uniqueness_floors(self._law, _k.to_mandel(sig), eps6, kap, self._softening_scale(state, n), out)
        return out

    #: A failed point "stops at the peak of its planes" when, at 0.99 of the fraction its branch reached, a
    #: loading plane has kappa / kappa* within this of 1. Measured: on the plane-strain element path with
    #: ``equator-78`` (alpha = 0) kappa / kappa* = 0.9998 there, the branch having reached 0.984 of the
    #: increment; at a point of the crack-band biaxial run without the stabilisation (12 elements) the
    #: plane passed kappa* on the branch (1.0023 at 0.83 of the increment) and came back to it, 1.0003 at
    #: 0.99 of the 0.92 reached; the run's two other failed points had planes 25 % and 27 % past it.
    PEAK_STOP_TOLERANCE = 0.01

    def explain_failure(self, d_strain, stress, state: State, *, points=None, reached=None, **update_inputs) -> list:
        """Why the update of each point fails, as far as the law can tell: a sentence or None per point, (N,).

        The one cause it names: a softening point whose branch ends where a loading plane is at its peak
        kappa* (:attr:`PEAK_STOP_TOLERANCE`), the kink of its hardening curve. On the element path such a
        point snaps back: the planes still hardening beside the softening ones, with the elasticity, are
        more compliant than the softening planes, so going on would ask the strain to go back, and no
        strain-driven solution continues (``docs/cpa_law.md``, section 5.2, "The point snaps back at its
        peak"). ``update_inputs``: what :meth:`update` was given besides the increment (``step_fraction``,
        ``d_nonlocal``, ...), per point where they are arrays. ``points``: the indices of the points to explain
        (default all); the list then has one entry per index. ``reached``: the fraction of the increment each
        point's update reached (its state's ``reached``, per point explained), which the caller of a failed
        update has: given, the failed update is not run again. The element drivers and the FE solver add the
        sentence to the message of a run that stops."""
        de, sig = check_batch(d_strain, stress)
        if points is not None:
            idx = np.asarray(points, dtype=np.int64)
            n_all = de.shape[0]
            de, sig = de[idx], sig[idx]
            state = {k: np.asarray(v)[idx] for k, v in state.items()}
            update_inputs = {k: (np.asarray(v)[idx] if np.ndim(v) and np.shape(v)[0] == n_all else v)
                             for k, v in update_inputs.items()}
        out = [None] * de.shape[0]
        if self.params.softening_slip <= 0.0:
            return out
        quiet = self.with_replay_dir(None)  # a copy: no second replay file, and this law's last_failure kept
        if reached is None:
            _, new, _ = quiet.update(de, sig, state, tangent=False, **update_inputs)
            reached = np.where(np.asarray(new["status"]) == STATUS_FAILED, np.asarray(new["reached"], dtype=float), 1.0)
        reached = np.asarray(reached, dtype=float)
        if reached.shape != (de.shape[0],):
            raise ValueError(f"reached: expected shape ({de.shape[0]},), one fraction per point, got {reached.shape}")
        failed = np.flatnonzero(reached < 1.0)
        if failed.size == 0:
            return out
        reached = reached[failed]
        sub = {k: np.asarray(v)[failed] for k, v in state.items()}
        inputs = {k: (np.asarray(v)[failed] if np.ndim(v) else v) for k, v in update_inputs.items()}
        short = 0.99 * reached[:, None, None] * de[failed]
        _, before, _ = quiet.update(short, sig[failed], sub, tangent=False, **inputs)
        off = np.where(before["loading"], np.abs(before["kappa"] / self.params.kappa_instability - 1.0), np.inf)
        nearest = off.argmin(axis=1)
        ratio = 1.0 + (before["kappa"] / self.params.kappa_instability - 1.0)[np.arange(failed.size), nearest]
        at_peak = (before["status"] != STATUS_FAILED) & (off.min(axis=1) <= self.PEAK_STOP_TOLERANCE)
        scale = self._softening_scale(sub, failed.size)
        for i in np.flatnonzero(at_peak):
            here = "" if np.isclose(scale[i], self.params.softening_slip, rtol=1e-9, atol=0.0) else \
                f", scaled by the crack band to {scale[i]:.3g} m at this point"
            out[int(failed[i])] = (
                f"the point snaps back at the peak of its planes: its branch ends at {reached[i]:.3g} of the "
                f"increment with a loading plane at kappa* (kappa / kappa* = {ratio[i]:.6f}), and no strain-driven "
                f"solution goes on (the planes still hardening are more compliant than the softening ones); a "
                f"gentler softening (softening_slip = {self.params.softening_slip:g} m now{here}) or the step "
                "stabilisation carries it (docs/cpa_law.md, section 5.2)")
        return out

    def loading_tangent(self, stress, state: State, *, strengthening: str = "none", modulus: float = 0.0,
                        mandel: bool = False) -> np.ndarray:
        """The rate-independent loading tangent of each committed state (stress, state): (N, 3, 3, 3, 3), or
        (N, 6, 6) Mandel with ``mandel``. A diagnostic of the law itself: every plane at or above its curve
        loads with eta' at its committed slip, the step stabilisation left out (which :meth:`update` over a
        zero step does not give: without the stabilisation it first relaxes the overstress a stabilised run
        carries). With a ``nonlocal_length`` the planes past their peak carry the gradient's coupling with
        ebar held fixed, the short-wave limit. Rice's condition on it
        (:func:`material.localisation.ellipticity`) says where the law admits a band.

        ``strengthening`` and ``modulus`` add to the rate problem the stiffness a gradient term would give a
        disturbance shorter than its length (``docs/regularisation.md``, section 4): ``"plane"``, H_g on each
        plane's own slip [1/m]; ``"sum"``, H_g on the sum of the slips, what one scalar field carries [1/m];
        ``"plastic_strain"``, H_g (w_a / t)(w_b / t) m_a : m_b on the plastic strain the slips make together
        [m]; ``"back_stress"``, a back stress H_g (eps_p - ebar_p) [kPa] that every plane's ratio sees, which
        keeps an associated law's rate problem symmetric (``plastic_strain`` does not: on the associated
        footing it makes 6-36 points non-elliptic that the law alone keeps elliptic); ``"none"``.
        The mean-stress cut-off is left out. A point whose rate problem is singular (no
        loading tangent) gets NaN."""
        kinds = _k.STRENGTHENINGS
        if strengthening not in kinds:
            raise ValueError(f"strengthening = {strengthening!r}: allowed {', '.join(map(repr, kinds))}")
        modulus = _nonnegative("modulus", modulus)
        n, sig, kap = self._committed(stress, state)
        m_over = self.over_nonlocal if self._nonlocal_length is not None else 0.0
        shift = np.zeros_like(kap)
        if m_over > 0.0 and "nonlocal_shift" in state:
            shift = np.ascontiguousarray(state["nonlocal_shift"], dtype=float)
            if shift.shape != kap.shape:
                raise ValueError(f"state['nonlocal_shift']: shape {shift.shape} does not match {kap.shape}")
        out = np.empty((n, 6, 6))
        eps6 = _k.to_mandel(np.ascontiguousarray(state["strain"], dtype=float))
        _k.loading_tangents(self._law, _k.to_mandel(sig), eps6, kap, self._softening_scale(state, n), shift,
                            m_over, kinds.index(strengthening), modulus, out)
        return out if mandel else _k.tangent_from_mandel(out)

    # ----------------------------------------------------------------------------- update
    @property
    def rate_dependent(self) -> bool:
        """True with the step stabilisation: :meth:`update` then takes the step's size (``step_fraction``)."""
        return self.options.stabilisation == MINIMAL or self.options.stabilisation > 0.0

    def update(self, d_strain, stress, state: State, *, tangent: bool | str = True, d_nonlocal=None,
               step_fraction: float = 1.0, d_nonlocal_plastic_strain=None):
        """Integrate the law over a strain increment at N Gauss points.

        Parameters
        ----------
        d_strain : (N, 3, 3) strain increment, tension positive, symmetric.
        stress : (N, 3, 3) Cauchy stress at the start of the step [kPa], tension positive.
        state : dict from :meth:`initial_state` or a previous :meth:`update` (not modified).
        tangent : bool or "mandel"
            Compute the consistent tangent (default). Without it the third return value is None;
            ``"mandel"`` returns it as (N, 6, 6) Mandel matrices, the form the law computes (no
            conversion: the element drivers work in it, :data:`TANGENTS`).
        d_nonlocal : None or (N,)
            A law with a ``nonlocal_length``: the step's increment of the nonlocal field ebar at the points
            (the FE solver passes it, :mod:`femgran.gradient`); the tangent is then a
            :class:`material.base.CoupledTangent` and ``state["nonlocal"]`` the end-of-step ebar. Without
            it the law is local (ebar = e, a homogeneous test) and ``state["nonlocal"]`` follows e.
        step_fraction : float > 0
            The step's size in units of the stabilisation's relaxation time (:attr:`relaxation_time`, by
            default one nominal step): the FE solver and the element drivers pass it to a
            :attr:`rate_dependent` law (:func:`material.base.step_fraction`). Without the stabilisation it
            changes nothing.
        d_nonlocal_plastic_strain : None or (N, 3, 3)
            A law with a ``back_stress_modulus``: the step's increment of the nonlocal plastic strain ebar_p at
            the points; ``state["nonlocal_plastic_strain"]`` holds the committed ebar_p and the tangent is a
            :class:`material.base.BackStressTangent`. Without it the law is local (ebar_p = eps_p, no back
            stress) and ``state["nonlocal_plastic_strain"]`` follows eps_p.

        Returns
        -------
        stress : (N, 3, 3) [kPa]
        state : dict (new arrays): strain, plastic_strain (N,3,3); kappa (N,M) [m]; status (N,) int8;
            step_ratio (N,) (the fraction of the increment a failed point reached; 1 otherwise);
            reached (N,) the fraction of the increment the local solver reached on its branch (1 unless failed);
            iterations, continuation (N,) int32 (local Newton iterations, and how often the
            continuation halved the increment); loading (N, M) bool (planes whose slip grew in the step);
            cutoff_opening (N,) accumulated plastic volumetric opening at the tension cut-off;
            mobilised_ratio (N,) the largest etah_a / eta_f,a; near_apex (N,) bool (every stress
            component below 10 apex_rounding, where the rounding changes the law by more than 1 %);
            stabilisation (N,) the mu of the step stabilisation's floor at each point in the step (0 at an
            elastic point); overstress (N,) the stabilisation's overstress of the step: the largest
            h_a dkappa_a / etah_a over the loading planes, the share of a plane's mobilised ratio above its
            hardening curve (0 without the stabilisation; ``docs/cpa_law.md``, section 4); limit_points (N,) int32:
            the limit points of its branch the step passed (module docstring); element_size (N,) [m].
        tangent : (N, 3, 3, 3, 3) d stress / d d_strain [kPa], or None.
        """
        de, sig = check_batch(d_strain, stress)
        n = de.shape[0]
        check_state(state, n, _STATE_KEYS)
        if state["kappa"].shape != (n, self.n_planes):
            raise ValueError(
                f"state['kappa']: shape {state['kappa'].shape} does not match ({n}, {self.n_planes}) planes of "
                f"rule {self.rule!r}; was the state made by another model?"
            )
        f = float(step_fraction) if np.ndim(step_fraction) == 0 else np.nan
        if not (np.isfinite(f) and f > 0.0):
            raise ValueError(f"step_fraction = {step_fraction!r}: allowed a finite number > 0 (the step's size in "
                             f"relaxation times)")
        if d_nonlocal_plastic_strain is not None:
            dnp = self._check_nonlocal_plastic_strain(d_nonlocal_plastic_strain, n, tangent, state)
            new_sig, new_state, tan = self._integrate_back_stress(de, sig, state, tangent, dnp, f)
        else:
            new_sig, new_state, tan = self._integrate(de, sig, state, tangent, d_nonlocal, f)
            if self._shifted is not None:  # the local law: ebar_p = eps_p, no back stress
                new_state["nonlocal_plastic_strain"] = new_state["plastic_strain"].copy()
                new_state["back_stress"] = np.zeros_like(new_sig)
        failed = np.flatnonzero(new_state["status"] == STATUS_FAILED)
        if failed.size:
            self._record_failure(de, sig, state, failed, d_nonlocal, f, d_nonlocal_plastic_strain)
        return new_sig, new_state, tan

    def _check_nonlocal_plastic_strain(self, value, n, tangent, state) -> np.ndarray:
        """``d_nonlocal_plastic_strain`` of :meth:`update`, validated: (N, 3, 3) finite, symmetric."""
        if self._shifted is None:
            raise ValueError("d_nonlocal_plastic_strain: this CPA law has no back stress (back_stress_modulus = 0); "
                             "allowed only with back_stress_modulus > 0")
        d = np.asarray(value, dtype=float)
        if d.shape != (n, 3, 3) or not np.all(np.isfinite(d)):
            raise ValueError(f"d_nonlocal_plastic_strain: expected a finite array of shape ({n}, 3, 3), got "
                             f"shape {d.shape}" + ("" if d.shape != (n, 3, 3) else " with non-finite values"))
        if not np.allclose(d, np.swapaxes(d, 1, 2), rtol=0.0, atol=1e-12 * max(1.0, float(np.abs(d).max()))):
            raise ValueError("d_nonlocal_plastic_strain: not symmetric; allowed symmetric (N, 3, 3) tensors")
        if tangent == "mandel":
            raise ValueError("tangent = 'mandel': the coupled tangent of d_nonlocal_plastic_strain comes in tensor "
                             "form; allowed True or False")
        check_state(state, n, ("nonlocal_plastic_strain",))
        return d

    def _integrate_back_stress(self, de, sig, state, tangent, d_np, f):
        """One step with the gradient back stress X = H_g (eps_p - ebar_p), ebar_p = the committed value plus
        ``d_np`` (validated input).

        Every plane sees s = sigma - X. Within the step X = H_g (eps_p,n + d_eps_p - ebar_p,n - d_ebar_p) with
        d_eps_p = d_eps - C d_sigma, so s - s_n = D d_eps + H_g d_ebar_p - (D + H_g I) d_eps_p: the law's own
        step from the committed s_n = sigma_n - X_n with the stiffer elasticity D^ = D + H_g I (K + H_g / 3,
        G + H_g / 2) and the increment d_e^ = C^ (D d_eps + H_g d_ebar_p). The kernel runs unchanged on those
        variables and sigma = s + H_g (eps_p - ebar_p). With A = d s / d d_e^ the kernel's tangent and
        Q = C^ D:

            d sigma / d d_eps = (A + H_g (I - C^ A)) Q,      d eps_p / d d_eps = (I - C^ A) Q,
            d eps_p / d ebar_p = H_g (C^ - C^ A C^),
            d sigma / d ebar_p = H_g A C^ + H_g d eps_p / d ebar_p - H_g I

        The start s_n holds the committed back stress, so the step stabilisation's floor, computed at s_n, is
        the same for every d_ebar_p, and with ebar_p = eps_p (X = 0 at the end) the step is the law's to
        round-off. (A first version started from sigma_n minus the end-of-step X_n with the committed
        plastic strain: its floor moved with d_ebar_p, the derivatives in ebar_p were off by 3e-4 with
        mu = 0.1, and a homogeneous specimen left the law by 2e-6 of q.) Induced anisotropy (beta != 0) is
        refused: its strengths follow the strain, which d_e^ is not, so the kernel's tangent would have to
        carry the strengths' slope through Q^-1 and give the tangent at fixed strengths besides (measured
        with that mapping built: d sigma / d ebar_p off by 5e-4).

        The step stabilisation keeps the law's floor (its mu scaled by G / G^); its ``"minimal"`` form solves
        the rate problem of the shifted variables, so the least mu it finds includes the back stress's
        coupling. The continuation past limit points is not used (its bookkeeping of the strain is the law's): a point
        whose branch ends within the step fails and is cut back like any other.
        """
        bs, H = self._shifted, self.back_stress_modulus
        ebar_n = np.asarray(state["nonlocal_plastic_strain"], dtype=float)
        ebar = ebar_n + d_np
        x_n = H * (np.asarray(state["plastic_strain"], dtype=float) - ebar_n)
        d_shifted = bs.to_shifted(de) + H * _k.from_mandel(np.ascontiguousarray(_k.to_mandel(d_np) @ bs.comp.T))
        s_hat, new_state, A = self._integrate(d_shifted, sig - x_n, state, "mandel" if tangent else False,
                                              None, f, limits=False, shifted=bs)
        ok = (new_state["status"] != STATUS_FAILED)[:, None, None]
        new_state["strain"] = np.where(ok, state["strain"] + de, state["strain"])
        eps_p = new_state["plastic_strain"]
        x = H * (eps_p - ebar)
        # (a failed point keeps its start: its stress, field and back stress as committed)
        new_state["nonlocal_plastic_strain"] = np.where(ok, ebar, ebar_n)
        new_state["back_stress"] = np.where(ok, x, x_n)
        new_sig = np.where(ok, s_hat + x, sig)
        if not tangent:
            return new_sig, new_state, None
        eye, C, Q = np.eye(6), bs.comp, bs.shift_map
        CA = np.einsum("ij,njk->nik", C, A)
        dep_de = np.einsum("nij,jk->nik", eye - CA, Q)
        dep_deb = H * (C - np.einsum("nij,jk->nik", CA, C))
        dsig_de = np.einsum("nij,jk->nik", A + H * (eye - CA), Q)
        dsig_deb = H * np.einsum("nij,jk->nik", A, C) + H * dep_deb - H * eye
        t = _k.tangent_from_mandel
        dsig_de, dsig_deb, dep_de, dep_deb = (t(np.ascontiguousarray(a)) for a in (dsig_de, dsig_deb, dep_de, dep_deb))
        return new_sig, new_state, BackStressTangent(dsig_de, dsig_deb, eps_p.copy(), dep_de, dep_deb)

    def _integrate(self, de, sig, state, tangent, d_nonlocal, f, max_halvings=None, limits=True, shifted=None):
        """One backward-Euler step of the kernel at every point (validated input; no failure record);
        ``max_halvings`` overrides the option's; ``limits=False``: the one-step problem, without the
        continuation past limit points (:attr:`_passes_limit_points` decides otherwise); ``shifted``: the
        back stress's variables (:meth:`_integrate_back_stress`), whose elasticity the kernel takes."""
        law, comp = (self._law, self._comp) if shifted is None else (shifted.law, shifted.comp)
        n = de.shape[0]
        M = self.n_planes
        sig6 = _k.to_mandel(sig)
        de6 = _k.to_mandel(de)
        eps6 = _k.to_mandel(np.ascontiguousarray(state["strain"], dtype=float))
        kap_n = np.ascontiguousarray(state["kappa"], dtype=float)
        p = self.params
        gradient = self._nonlocal_length is not None
        if d_nonlocal is not None and not gradient:
            raise ValueError("d_nonlocal: this CPA law has no nonlocal_length (no gradient regularisation)")
        c0, m_over = np.zeros(n), 0.0
        shift_n = np.zeros((n, M))
        if gradient:
            check_state(state, n, ("nonlocal",))
            e_n = np.asarray(state["post_peak_strain"], dtype=float) if "post_peak_strain" in state else \
                self._post_peak_strain(kap_n)  # (a state of an older version)
            if "nonlocal_shift" in state:
                shift_n = np.ascontiguousarray(state["nonlocal_shift"], dtype=float)
                if shift_n.shape != (n, M):
                    raise ValueError(f"state['nonlocal_shift']: shape {shift_n.shape} does not match ({n}, {M})")
            if d_nonlocal is not None:
                dnl = np.asarray(d_nonlocal, dtype=float)
                if dnl.shape != (n,) or not np.all(np.isfinite(dnl)):
                    raise ValueError(f"d_nonlocal: expected a finite array of shape ({n},), got {dnl.shape}")
                if tangent == "mandel":
                    raise ValueError("tangent = 'mandel': the coupled tangent of d_nonlocal comes in tensor form")
                m_over = self.over_nonlocal
                c0 = m_over * p.t * dnl  # this step's shift of the slip of every plane past its peak
        sig_out = np.empty_like(sig6)
        kap_out = np.empty_like(kap_n)
        D = np.empty((n, 6, 6))
        loading = np.empty((n, M), dtype=np.bool_)
        status = np.empty(n, dtype=np.int8)
        iterations = np.empty(n, dtype=np.int32)
        halvings = np.empty(n, dtype=np.int32)
        reached = np.empty(n)
        opening = np.empty(n)
        mobilised = np.empty(n)
        floor_mu = np.empty(n)
        overstress = np.empty(n)
        o = self.options
        minimal = o.stabilisation == MINIMAL
        halvings_cap = o.max_halvings if max_halvings is None else int(max_halvings)
        passes = limits and self._passes_limit_points and int(self.MAX_LIMIT_POINTS) > 0
        # (the floor is mu times an elastic self-coupling proportional to G: in the back stress's variables mu
        # scales by G / G^, so that the floor, and with X = 0 the step, are the law's)
        mu = 0.0 if minimal else o.stabilisation * (1.0 if shifted is None else shifted.floor_scale)
        opt = Options(o.tol, o.maxit, halvings_cap, bool(tangent), mu, f, minimal,
                      int(self.LIMIT_BISECTIONS) if passes else 0)
        lim = Limits(int(self.MAX_LIMIT_POINTS) if passes else 0, float(self.LIMIT_FD_STEP))
        limit_points = np.empty(n, dtype=np.int32)
        prev_threads = None
        if self.threads is not None:
            import numba

            prev_threads = numba.get_num_threads()
            numba.set_num_threads(int(self.threads))
        grad_out = np.empty((n, 14))
        soft = self._softening_scale(state, n)
        try:
            _k.cpa_batch(law, opt, lim, sig6, de6, eps6, kap_n, soft, c0, m_over, shift_n,
                         sig_out, kap_out, D, loading, grad_out, status, iterations, halvings, reached, opening,
                         mobilised, floor_mu, overstress, limit_points)
        finally:
            if prev_threads is not None:
                import numba

                numba.set_num_threads(prev_threads)
        new_sig = _k.from_mandel(sig_out)
        # plastic strain increment: the part of d_eps the elastic compliance does not explain (exact at
        # the converged residual; it includes the cut-off's opening)
        d_eps_p = _k.plastic_increment(de6, sig_out, sig6, comp)
        failed = status == STATUS_FAILED
        ok = ~failed
        step_ratio = np.where(failed, np.where(reached > 0, 0.9 * reached, 0.25), 1.0)
        new_state = {
            "strain": np.where(ok[:, None, None], state["strain"] + de, state["strain"]),
            "plastic_strain": np.where(ok[:, None, None], state["plastic_strain"] + d_eps_p, state["plastic_strain"]),
            "kappa": kap_out,
            "status": status,
            "step_ratio": step_ratio,
            "reached": np.where(failed, reached, 1.0),
            "iterations": iterations,
            "continuation": halvings,
            "loading": loading,
            "cutoff_opening": np.asarray(state.get("cutoff_opening", np.zeros(n))) + np.where(ok, opening, 0.0),
            "mobilised_ratio": np.where(ok, mobilised, state.get("mobilised_ratio", np.zeros(n))),
            "stabilisation": floor_mu,
            "overstress": overstress,
            "limit_points": limit_points,
            # within the rounded apex, where N differs from the normal stress by more than 1 %
            "near_apex": np.abs(sig_out).max(axis=1) <= 10.0 * self.params.apex_stress,
        }
        if "element_size" in state:
            new_state["element_size"] = state["element_size"]
        tan = (D if tangent == "mandel" else _k.tangent_from_mandel(D)) if tangent else None
        if not gradient:
            return new_sig, new_state, tan
        # the local measure e grows by S / t, S the slip increments of the planes past their peak at the start
        # (a plane that passes its peak within a step counts from the next step on: e is continuous in time)
        post = (kap_n >= p.kappa_instability) & (soft > 0)[:, None]
        S = np.where(post, kap_out - kap_n, 0.0).sum(axis=1)
        new_state["post_peak_strain"] = e_n + S / p.t
        if d_nonlocal is None:  # the local law: the field follows the point's own post-peak slip strain
            new_state["nonlocal"] = new_state["post_peak_strain"].copy()
            new_state["nonlocal_shift"] = shift_n
            return new_sig, new_state, tan
        new_state["nonlocal"] = np.asarray(state["nonlocal"], dtype=float) + dnl
        # the shift kappa_hat - kappa of those planes grows by c0 - m S = m t (d_ebar - d_e); a plane that passed
        # its peak in this step starts from 0 in the next (its kappa_hat is then kappa: continuous)
        new_state["nonlocal_shift"] = np.where(post & ok[:, None], shift_n + (c0 - m_over * S)[:, None], shift_n)
        # grad_out: S (the sum of the slip increments of the planes past their peak), d S / d d_eps (Mandel),
        # d sigma / d c0 (Mandel), d S / d c0; with c0 = m t d_ebar and e = e_n + S / t
        scale = m_over * p.t  # d c0 / d ebar
        return new_sig, new_state, CoupledTangent(
            tan, _k.from_mandel(np.ascontiguousarray(grad_out[:, 7:13] * scale)), e_n + grad_out[:, 0] / p.t,
            _k.from_mandel(np.ascontiguousarray(grad_out[:, 1:7] / p.t)), grad_out[:, 13] * m_over)

    # ------------------------------------------------------------------ limit points of the strain-driven step
    #: Limit points one step may pass (each restarts the rest of the increment from the limit state). The
    #: near-failure point of the tests passes 8 in one step (the rest of its step folds again after 0.6, 1.2,
    #: 2.6, 5.3, 11, 25, 65 and 43 % of what is left).
    MAX_LIMIT_POINTS = 16
    #: A limit point is located to 2**-40 of the increment (by bisection between the last fraction the local
    #: solver reached and the one it failed at, each trial a Newton solve from the solution at the last
    #: fraction reached). The local solver itself reaches the limit only to about 1e-11 of the increment
    #: (measured on the footing's fold point with solves from the start of the step: the limit found with
    #: 12, 4 and 2 continuation halvings agrees to 1e-11), so finer bisection finds nothing more.
    LIMIT_BISECTIONS = 40
    #: Step of the finite-difference tangent past a limit point, relative to |d_eps| + |sigma_n| / E. Measured
    #: on the footing's fold point (``tests/material/data/footing_fold_point.npz``): the response past the limit
    #: is continuous but steep (the stress moves 0.01 kPa over 1.5e-9 of strain), and directional differences
    #: agree to four digits for perturbations from 1e-11 to 1e-7 of that scale; 1e-6 straddles the steep
    #: part and gives a third of the slope.
    LIMIT_FD_STEP = 1e-9

    @property
    def _passes_limit_points(self) -> bool:
        """The continuation past limit points applies to the rate-independent local hardening law. Not with
        the stabilisation, whose floor depends on the step's size, nor with the gradient coupling, whose shift
        of the step enters the step's problem as a whole: neither splits into the parts of a step. Nor, for
        now, with a softening law: with the first version of the continuation (a Python loop over the failed
        points' arrays, about 2 s per point) the crack-band biaxial study of the tests (``fe_04``) had 1 to 21
        points past their limit in 23 steps and took 125 s instead of 17 s, where the global cut-backs had
        carried those points past their peak before. With the numba version (milliseconds per point), measured
        on 2026-12-07 with the continuation switched on for the softening law of the shear-band study
        (``zeta`` 1.05, ``softening_slip`` 0.03, associated, no stabilisation): the crack-band biaxial run on
        12 elements to 6 % (``fe_04 --resolutions 12 --variants regularised --stabilisation 0``) still stops,
        at t = 0.441 instead of 0.428, in 33.2 s instead of 18.8 s; on the plane-strain element path with
        ``equator-78`` (400 steps to 5 %) alpha = 60 deg goes on to 5 % where it stops at its peak without,
        while alpha = 0 and 30 deg stop at their peak either way (76 of the 78 planes load there; the branch
        of the driver's small increments folds at 0.2-0.9 of them and the continuation from the limit state
        fails in turn). Not enough to switch it on. The stops at alpha = 0 and 30 deg are no limit point that a
        continuation could pass: the point snaps back where its first planes reach kappa*, and no strain-driven
        solution continues the branch (``docs/cpa_law.md``, section 5.2, "The point snaps back at its peak";
        with softening_slip 0.1 m the same path softens to 6 %)."""
        return not self.rate_dependent and self._nonlocal_length is None and self.params.softening_slip == 0.0

    def _post_peak_strain(self, kappa) -> np.ndarray:
        """sum of kappa_a - kappa* over the planes past their peak, divided by t (N,): the local measure e of a
        state written before e was a state variable ("post_peak_strain")."""
        kstar = self.params.kappa_instability
        return np.where(kappa >= kstar, kappa - kstar, 0.0).sum(axis=1) / self.params.t

    # ----------------------------------------------------------------------------- replay
    def _record_failure(self, de, sig, state, idx, d_nonlocal=None, step_fraction: float = 1.0,
                        d_nonlocal_plastic_strain=None) -> None:
        import json

        record = {
            "d_strain": de[idx],
            "stress": sig[idx],
            "point_index": idx,
            "step_fraction": np.array(step_fraction),
            "params_json": np.array(json.dumps(self.params.to_dict())),
            "rule": np.array(self.rule),
            "axes": self.axes,
            "options_json": np.array(json.dumps({**self.options.__dict__, "regularise": self.regularise,
                                                 "nonlocal_length": self._nonlocal_length,
                                                 "over_nonlocal": self.over_nonlocal,
                                                 "back_stress_modulus": self.back_stress_modulus,
                                                 "back_stress_length": self._back_stress_length})),
        }
        if d_nonlocal is not None:
            record["d_nonlocal"] = np.asarray(d_nonlocal, dtype=float)[idx]
        if d_nonlocal_plastic_strain is not None:
            record["d_nonlocal_plastic_strain"] = np.asarray(d_nonlocal_plastic_strain, dtype=float)[idx]
        for key, arr in state.items():
            record[f"state__{key}"] = np.asarray(arr)[idx]
        self.last_failure = record
        if self.replay_dir is not None:
            self.replay_dir.mkdir(parents=True, exist_ok=True)
            # the process's running number keeps two failures of one second at the same first point apart (the
            # name had only the second: a run failing twice a second kept the last)
            path = self.replay_dir / (f"cpa-failure-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}-"
                                      f"{next(_FAILURE_NUMBER):05d}-{idx[0]}.npz")
            np.savez(path, **record)
            self.last_failure["path"] = str(path)

    def dump_failure(self, path) -> Path:
        """Write the inputs of the points that failed in the last call to ``path`` (.npz) for :func:`replay`."""
        if self.last_failure is None:
            raise ValueError("dump_failure: no point has failed in this model's updates")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, **{k: v for k, v in self.last_failure.items() if k != "path"})
        return path


class _ShiftedElasticity:
    """The law in the back stress's variables (:meth:`CPAModel._integrate_back_stress`): the kernel's constants
    with the elasticity D^ = D + H_g I, and the map Q = C^ D of the strain increment into them."""

    def __init__(self, law: Law, E: float, nu: float, modulus: float):
        K, G = E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))
        Kh, Gh = K + modulus / 3.0, G + modulus / 2.0
        stiff, self.comp = mandel_elastic(9.0 * Kh * Gh / (3.0 * Kh + Gh),
                                          (3.0 * Kh - 2.0 * Gh) / (2.0 * (3.0 * Kh + Gh)))
        self.law = law._replace(stiff=stiff, comp=self.comp, bulk=float(law.bulk) * Kh / K)
        self._q = (K / Kh, G / Gh)
        self.floor_scale = G / Gh  # of the step stabilisation's mu (CPAModel._integrate)
        vol = np.zeros((6, 6))
        vol[:3, :3] = 1.0 / 3.0
        self.shift_map = self._q[0] * vol + self._q[1] * (np.eye(6) - vol)

    def to_shifted(self, d_strain: np.ndarray) -> np.ndarray:
        """Q d_eps of (N, 3, 3) tensors."""
        tr = np.trace(d_strain, axis1=1, axis2=2)[:, None, None] / 3.0
        return self._q[1] * d_strain + (self._q[0] - self._q[1]) * tr * np.eye(3)


def _nonnegative(name: str, value, unit: str = "") -> float:
    """``value`` as a finite float >= 0, or a ValueError naming ``name``, the value and what is allowed."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r}: allowed a finite number >= 0{unit}") from None
    if not (np.isfinite(out) and out >= 0.0):
        raise ValueError(f"{name} = {value!r}: allowed a finite number >= 0{unit}")
    return out


def _check_back_stress(modulus, length, nonlocal_length, beta) -> tuple[float, float | None]:
    """(H_g, l_b) of the constructor, validated."""
    modulus = _nonnegative("back_stress_modulus", modulus, " (kPa)")
    if modulus == 0.0:
        if length is not None:
            raise ValueError(f"back_stress_length = {length!r}: needs back_stress_modulus > 0 (it is 0)")
        return 0.0, None
    try:
        length = float(length)
    except (TypeError, ValueError):
        raise ValueError(f"back_stress_length = {length!r}: allowed a finite number > 0 (m) with "
                         f"back_stress_modulus = {modulus!r}") from None
    if not (np.isfinite(length) and length > 0.0):
        raise ValueError(f"back_stress_length = {length!r}: allowed a finite number > 0 (m) with "
                         f"back_stress_modulus = {modulus!r}")
    if nonlocal_length is not None:
        raise ValueError(f"back_stress_modulus = {modulus!r} with nonlocal_length = {nonlocal_length!r}: allowed "
                         "one of the two regularisations, not both")
    if beta != 0.0:
        raise ValueError(f"back_stress_modulus = {modulus!r} with induced anisotropy (beta = {beta!r}): not "
                         "supported yet; allowed with beta = 0 (CPAModel._integrate_back_stress says why)")
    return modulus, length


def _check_relaxation_time(value, stabilisation) -> float | None:
    """``relaxation_time`` of :class:`CPAModel`: None or a finite number > 0, given with a stabilisation."""
    if value is None:
        return None
    try:
        tau = float(value)
    except (TypeError, ValueError):
        tau = np.nan
    if isinstance(value, bool) or not (np.isfinite(tau) and tau > 0.0):
        raise ValueError(f"relaxation_time = {value!r}: allowed a finite number > 0 (in the run's time: the load "
                         "factor of an FE stage runs from 0 to 1), or None for one nominal step")
    if stabilisation == 0.0:
        raise ValueError(f"relaxation_time = {value!r}: the relaxation time of the step stabilisation, but "
                         "stabilisation = 0 (the thesis's rate-independent law has none); allowed with "
                         "stabilisation > 0 or 'minimal'")
    return tau


def _check_stabilisation(value) -> float | str:
    """``stabilisation`` of :class:`CPAModel`: a number in [0, 1] or ``"minimal"``."""
    if isinstance(value, str):
        if value.strip().lower() == MINIMAL:
            return MINIMAL
        try:
            value = float(value)
        except ValueError:
            raise ValueError(f"stabilisation = {value!r}: allowed a number 0 <= mu <= 1 or {MINIMAL!r}") from None
    try:
        mu = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"stabilisation = {value!r}: allowed a number 0 <= mu <= 1 or {MINIMAL!r}") from None
    if not (np.isfinite(mu) and 0.0 <= mu <= 1.0):
        raise ValueError(f"stabilisation = {value!r}: allowed a number 0 <= mu <= 1 or {MINIMAL!r}")
    return mu


def replay(path, **model_options):
    """Re-run the failed points stored in a replay file; returns (model, stress, state, tangent).

    ``model_options`` override the stored integration options (e.g. ``max_halvings=20``) to study
    whether a finer continuation would have saved the point; stored options this version does not
    know (files of older versions) are ignored.
    """
    import json

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"replay file {str(path)!r} does not exist")
    with np.load(path, allow_pickle=False) as f:
        data = {k: f[k] for k in f.files}
    params = parameters_from_dict(json.loads(str(data["params_json"])), source=str(path))
    known = set(_Options.__dataclass_fields__) | {"regularise", "nonlocal_length", "over_nonlocal",
                                                  "back_stress_modulus", "back_stress_length"}
    options = {k: v for k, v in json.loads(str(data["options_json"])).items() if k in known}
    options.update(model_options)
    model = CPAModel(params, rule=str(data["rule"]), axes=data["axes"], **options)
    state = {k[len("state__"):]: v for k, v in data.items() if k.startswith("state__")}
    extra = {"d_nonlocal": data["d_nonlocal"]} if "d_nonlocal" in data and model._nonlocal_length is not None else {}
    if "d_nonlocal_plastic_strain" in data and model.back_stress_modulus > 0.0:
        extra["d_nonlocal_plastic_strain"] = data["d_nonlocal_plastic_strain"]
    if "step_fraction" in data:  # files of older versions: a nominal step
        extra["step_fraction"] = float(data["step_fraction"])
    stress, new_state, tangent = model.update(data["d_strain"], data["stress"], state, **extra)
    return model, stress, new_state, tangent


#: the running number of the replay files a process writes (their names, :meth:`CPAModel._record_failure`)
_FAILURE_NUMBER = itertools.count()

# re-exported status codes for convenience
STATUS = {"ok": STATUS_OK, "failed": STATUS_FAILED}
