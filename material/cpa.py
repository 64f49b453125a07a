"""The microplane Critical Plane Approach (CPA) law of anisotropic sand, as a Gauss-point routine.

Theory: thesis sections 2.3 and 3.5, with the signs and corrections of MODEL.md. The kernel is in
:mod:`material._cpa_kernel` (numba, vectorised over Gauss points); this module validates input,
prepares the plane data in the global frame and owns the state layout and the failure replay files.

Algorithm (implicit, strain driven; see the kernel's docstring for the equations)
-------------------------------------------------------------------------------
Unknown: the end-of-step stress. For each plane the hardening law (2.16) is inverted, so the slip is an
explicit function of the stress on a loading plane, ``kappa = A etah / (zeta eta_f - etah)``; a plane
loads when its mobilised ratio ``etah`` exceeds the level ``eta(kappa_n)`` it has reached (kappa never
decreases). The strain residual is solved by Newton's method with the analytic 6x6 Jacobian and a line
search; the slips of the loading planes are unknowns too (the hardening law is an equation per plane),
so nothing is singular as a plane approaches failure. The consistent tangent is the inverse Jacobian, corrected for the dependence of eta_f on the total strain (induced
anisotropy, 3.14-3.15). A step that does not converge is split inside the routine: a failing sub-step
is halved and retried from the last converged state, down to 2**-max_substep_level of the increment,
and the rest goes on with the size that worked; the tangent follows the sub-steps by the chain rule. A
point whose sub-stepping stops on its way to the apex (the rest of the increment, elastically or as
its last sub-step went, would take its mean stress past zero) goes to the apex. A point that still
fails returns its start-of-step stress, ``status = STATUS_FAILED`` and a suggested step ratio, never
NaN, and its inputs are kept (and written to ``replay_dir``) so that :func:`replay` can re-run it.

Decisions not fixed by the thesis (documented here, MODEL.md asks for it)
-------------------------------------------------------------------------
* State variable of each plane: the accumulated tangential slip kappa [m]. The loading threshold is
  ``eta(kappa_n) = zeta eta_f kappa_n / (A + kappa_n)`` evaluated with the *current* eta_f, so that with
  induced anisotropy a strengthened plane needs a higher ratio to load again.
* ``initial_state(n, stress=sigma0)`` puts every plane on the hardening curve of sigma0 (kappa_a from
  the mobilised ratio of sigma0, as after a monotonic history) and counts no plastic strain for it, so
  an anisotropic in-situ stress (K0) does not release a burst of slip in the first step.
* Tension cut-off: the loading surfaces of (2.16) all pass through sigma_N = 0, so the law admits no
  shear on a plane in tension (beyond the cohesion). When no admissible stress follows an increment
  and the elastic trial stress has no compression left (mean stress >= 0), the point goes to the apex,
  stress free; the misfit becomes plastic opening, kappa is unchanged, and the tangent is
  ``cutoff_stiffness`` times the elastic one (default 1e-6, so that a structure stays solvable).
  A point that no sub-stepping can integrate also goes to the apex when sub-stepping ran into it, when
  the trial stress pulls a plane apart, or when its stress is within one increment's elastic stress of
  zero or below 1e-4 of the elastic stiffness (0.9 kPa for the presets: practically stress free,
  typically at the free surface beside a footing). ``state["tension_cutoff"]`` flags such points.
* Active-set cycling: the local problem of non-associated flow on many planes can have no consistent
  active set for an increment (a plane loads when elastic and unloads when loading). When every
  normal attempt fails, a last resort lets such a plane stay elastic with an overstress of at most
  1 % of its strength (the band of :func:`material._cpa_kernel._solve_substep`).
* Elasticity: isotropic Hooke (E, nu), the macroscopic limit of the plane-based form (2.15)
  normalised as in MODEL.md.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from material import _cpa_kernel as _k
from material.anisotropy import axes_from_frame, cohesion, default_axes, inherent_tensor
from material.base import (
    STATUS_FAILED,
    STATUS_OK,
    STATUS_SUBSTEPPED,
    State,
    as_stress_batch,
    check_batch,
    check_state,
)
from material.parameters import CPAParameters, load_preset, parameters_from_dict

__all__ = ["CPAModel", "replay", "mandel_elastic"]

_STATE_KEYS = ("strain", "plastic_strain", "kappa")


def mandel_elastic(E: float, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """Isotropic stiffness and compliance as 6x6 Mandel matrices (kPa, 1/kPa)."""
    K = E / (3.0 * (1.0 - 2.0 * nu))
    G = E / (2.0 * (1.0 + nu))
    one = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    vol = np.outer(one, one) / 3.0
    dev = np.eye(6) - vol
    return 3.0 * K * vol + 2.0 * G * dev, vol / (3.0 * K) + dev / (2.0 * G)


def _mandel1(a: np.ndarray) -> np.ndarray:
    r = np.sqrt(2.0)
    return np.array([a[0, 0], a[1, 1], a[2, 2], r * a[1, 2], r * a[0, 2], r * a[0, 1]])


@dataclass(frozen=True)
class _Options:
    maxit: int = 30
    max_substep_level: int = 6
    tol: float = 1e-10
    tol_hardening: float = 1e-12
    cutoff_stiffness: float = 1e-6


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
        Newton iterations per (sub)step before the step is split.
    max_substep_level : int
        The smallest sub-step inside the routine is 2**-max_substep_level of the increment.
    tol : float
        Convergence: |R| <= tol |d_eps| (Mandel norms, strain units).
    cutoff_stiffness : float
        Tangent of a point on the tension cut-off, as a fraction of the elastic stiffness.
    replay_dir : path, optional
        Where the inputs of failed points are written (one ``.npz`` per failing call) for :func:`replay`.
    threads : int, optional
        Numba threads for the update (default: numba's setting).
    regularise : bool
        Scale the post-peak softening by each point's element size (``softening_slip t / h``, the
        default; :meth:`initial_state`). False applies the law as if every element were one band
        thickness t wide, whatever its size: the unregularised, mesh-dependent reference.
    """

    def __init__(self, params: CPAParameters | str = "ottawa_c109", rule: str = "bazant-oh-33", axes=None, *,
                 maxit: int = 30, max_substep_level: int = 6, tol: float = 1e-10, cutoff_stiffness: float = 1e-6,
                 replay_dir: str | os.PathLike | None = None, threads: int | None = None, regularise: bool = True):
        from material.planes import integration_rule

        if isinstance(params, str):
            params = load_preset(params)
        if not isinstance(params, CPAParameters):
            raise ValueError(f"params: expected CPAParameters or a preset name, got {type(params).__name__}")
        if int(maxit) < 1:
            raise ValueError(f"maxit = {maxit!r}: must be >= 1")
        if not 0 <= int(max_substep_level) <= 12:
            raise ValueError(f"max_substep_level = {max_substep_level!r}: allowed 0..12")
        if not (0 < float(tol) < 1e-3):
            raise ValueError(f"tol = {tol!r}: allowed 0 < tol < 1e-3")
        if not (0 <= float(cutoff_stiffness) <= 1):
            raise ValueError(f"cutoff_stiffness = {cutoff_stiffness!r}: allowed 0..1")
        self.params = params
        self.rule = rule
        self.axes = default_axes() if axes is None else axes_from_frame(axes)
        self.options = _Options(int(maxit), int(max_substep_level), float(tol), 1e-12, float(cutoff_stiffness))
        self.replay_dir = None if replay_dir is None else Path(replay_dir)
        self.threads = threads
        self.regularise = bool(regularise)
        self.last_failure: dict | None = None

        normals_ref, weights = integration_rule(rule)
        self.normals = np.ascontiguousarray(normals_ref @ self.axes.T)  # n_a = R n_a^ref
        self.weights = np.ascontiguousarray(weights, dtype=float)
        n = self.normals
        r = np.sqrt(2.0)
        self._nn6 = np.ascontiguousarray(np.column_stack([
            n[:, 0] ** 2, n[:, 1] ** 2, n[:, 2] ** 2, r * n[:, 1] * n[:, 2], r * n[:, 0] * n[:, 2], r * n[:, 0] * n[:, 1],
        ]))
        self._om6 = _mandel1(inherent_tensor(params.omega1, self.axes))
        self._cohesion = np.ascontiguousarray(cohesion(params, self.normals, self.axes), dtype=float)
        self._coeffs = np.ascontiguousarray(params.a, dtype=float)
        self._stiff, self._comp = mandel_elastic(params.E, params.nu)

    @property
    def n_planes(self) -> int:
        return self.normals.shape[0]

    def __repr__(self) -> str:
        return f"CPAModel({self.params.name!r}, rule={self.rule!r}, planes={self.n_planes})"

    # ----------------------------------------------------------------------------- friction
    def friction_coefficients(self, strain=None) -> np.ndarray:
        """eta_f of every plane (M,), or (N, M) for a batch of total strains (N, 3, 3)."""
        if strain is None:
            strain = np.zeros((1, 3, 3))
            squeeze = True
        else:
            strain = np.asarray(strain, dtype=float)
            squeeze = strain.ndim == 2
            strain = strain.reshape(-1, 3, 3)
        eps6 = _k.to_mandel(np.ascontiguousarray(strain))
        out = np.empty((eps6.shape[0], self.n_planes))
        d = np.empty(self.n_planes)
        lam = np.empty(6)
        p = self.params
        for i in range(eps6.shape[0]):  # small helper for output, not on the hot path
            _k._lambda6(eps6[i], p.beta, p.alpha_hat, p.beta_hat, lam)
            _k._plane_strengths(self._nn6, self._om6, lam, self._coeffs, p.eta0, out[i], d)
        return out[0] if squeeze else out

    # ----------------------------------------------------------------------------- state
    def initial_state(self, n_points: int, stress=None, *, elastic_margin: float = 0.05,
                      element_size=None) -> State:
        """State of ``n_points`` Gauss points that carry the initial stress ``stress`` (tension +).

        Each plane starts at the hardening level of that stress: kappa_a = A e_a / (zeta eta_f,a - e_a)
        with e_a = (1 + elastic_margin) etah_a, etah_a the mobilised ratio of ``stress`` (0 for an
        isotropic stress), capped at 0.98 zeta eta_f,a. The default margin of 5 % gives an in-situ
        (e.g. K0) state a small elastic range: a sand consolidated under that stress reloads elastically
        at first, and a boundary-value problem does not start with every plane of every point exactly
        on its loading/unloading kink (where Newton's method converges poorly). ``elastic_margin=0``
        puts every plane exactly on its hardening curve. The plastic strain and the total strain start
        at zero. A stress that reaches the failure surface on some plane is rejected.

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
            t = np.einsum("nij,aj->nai", sig, self.normals)
            sN = -np.einsum("nai,ai->na", t, self.normals)
            ts = t + sN[..., None] * self.normals[None]
            tau = np.linalg.norm(ts, axis=-1)
            c = self._cohesion[None, :]
            zef = self.params.zeta * self.friction_coefficients()[None, :]
            bad_tension = (sN <= 0) & (tau > c + 1e-12 * np.abs(sig).max(axis=(1, 2))[:, None])
            with np.errstate(divide="ignore", invalid="ignore"):
                etah = np.where(sN > 0, (tau - c) / np.where(sN > 0, sN, 1.0), 0.0)
            bad = bad_tension | (etah >= zef * (1 - 1e-9))
            if bad.any():
                i = int(np.flatnonzero(bad.any(axis=1))[0])
                raise ValueError(
                    f"initial stress: {int(bad.any(axis=1).sum())} point(s) are at or beyond the failure surface "
                    f"of some plane (first: point {i}); allowed: stresses strictly inside the CPA strength envelope"
                )
            # round-off shear (|tau| ~ 1e-16 |sigma|) counts as none, as in the kernel
            tiny = 1e-13 * np.abs(sig).max(axis=(1, 2))[:, None]
            etah = np.where(tau <= tiny, 0.0, np.maximum(etah, 0.0))
            # the reached level sits `elastic_margin` above the initial mobilisation (capped below the
            # barrier): a small elastic range around the in-situ stress
            # (below the peak eta_f when the planes can soften)
            cap = 0.98 * (zef / self.params.zeta if self.params.softening_slip > 0 else zef)
            level = np.minimum(etah * (1.0 + elastic_margin), np.maximum(etah, cap))
            kappa = self.params.A * level / (zef - level)
        return {
            "strain": np.zeros((n, 3, 3)),
            "plastic_strain": np.zeros((n, 3, 3)),
            "kappa": kappa,
            "status": np.zeros(n, dtype=np.int8),
            "step_ratio": np.ones(n),
            "substeps": np.ones(n, dtype=np.int32),
            "iterations": np.zeros(n, dtype=np.int32),
            "tension_cutoff": np.zeros(n, dtype=bool),
            "mobilised_ratio": np.zeros(n),
            "predictor": np.zeros((n, 6, 6)),
            "element_size": h,
        }

    def _softening_scale(self, state: State, n: int) -> np.ndarray:
        """Per point slip scale of the post-peak softening, softening_slip t / h (0: none)."""
        p = self.params
        if p.softening_slip == 0.0:
            return np.zeros(n)
        h = state.get("element_size")
        if h is None or not self.regularise:
            return np.full(n, p.softening_slip)
        return p.softening_slip * p.t / np.asarray(h, dtype=float)

    # ----------------------------------------------------------------------------- update
    def update(self, d_strain, stress, state: State, *, tangent: bool = True):
        """Integrate the law over a strain increment at N Gauss points.

        Parameters
        ----------
        d_strain : (N, 3, 3) strain increment, tension positive, symmetric.
        stress : (N, 3, 3) Cauchy stress at the start of the step [kPa], tension positive.
        state : dict from :meth:`initial_state` or a previous :meth:`update` (not modified).
        tangent : bool
            Compute the consistent tangent (default). Without it the third return value is None.

        Returns
        -------
        stress : (N, 3, 3) [kPa]
        state : dict (new arrays): strain, plastic_strain (N,3,3); kappa (N,M) [m]; status (N,) int8;
            step_ratio, mobilised_ratio (N,); substeps, iterations (N,) int32; tension_cutoff (N,) bool;
            predictor (N,6,6): the Mandel tangent of the point's last plastic step, used only as the
            starting guess of the next Newton solve (a missing key is allowed and means none).
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
        sig6 = _k.to_mandel(sig)
        de6 = _k.to_mandel(de)
        eps6 = _k.to_mandel(np.ascontiguousarray(state["strain"], dtype=float))
        kap_n = np.ascontiguousarray(state["kappa"], dtype=float)
        sig_out = np.empty_like(sig6)
        kap_out = np.empty_like(kap_n)
        D = np.empty((n, 6, 6)) if tangent else np.empty((n, 0, 0))
        status = np.empty(n, dtype=np.int8)
        substeps = np.empty(n, dtype=np.int32)
        iterations = np.empty(n, dtype=np.int32)
        cutoff = np.empty(n, dtype=np.bool_)
        mobilised = np.empty(n)
        o = self.options
        iopt = np.array([o.maxit, o.max_substep_level, 1 if tangent else 0], dtype=np.int64)
        fopt = np.array([o.tol, o.tol_hardening, o.cutoff_stiffness])
        p = self.params
        if tangent:
            D_arg = D
        else:
            D_arg = np.empty((n, 6, 6))  # untouched scratch of the right shape (kernel writes nothing)
        pred = state.get("predictor")
        if pred is None or pred.shape != (n, 6, 6):
            pred = np.zeros((n, 6, 6))
        pred = np.ascontiguousarray(pred, dtype=float)
        prev_threads = None
        if self.threads is not None:
            import numba

            prev_threads = numba.get_num_threads()
            numba.set_num_threads(int(self.threads))
        try:
            _k.cpa_batch(sig6, de6, eps6, kap_n, self.normals, self._nn6, self.weights, self._cohesion, self._om6,
                         self._coeffs, p.eta0, p.beta, p.alpha_hat, p.beta_hat, p.zeta, p.A, 1.0 / p.t,
                         p.eta_c_ratio, self._comp, self._stiff,
                         iopt, fopt, sig_out, kap_out, D_arg, status, substeps, iterations, cutoff, mobilised, pred,
                         p.kappa_instability, self._softening_scale(state, n), p.residual_ratio)
        finally:
            if prev_threads is not None:
                import numba

                numba.set_num_threads(prev_threads)
        new_sig = _k.from_mandel(sig_out)
        # plastic strain increment: the part of d_eps the elastic compliance does not explain (exact at
        # the converged residual; the opening at the tension cut-off)
        d_eps_p6 = de6 - sig_out @ self._comp.T + sig6 @ self._comp.T
        d_eps_p = _k.from_mandel(np.ascontiguousarray(d_eps_p6))
        failed = status == STATUS_FAILED
        ok = ~failed
        step_ratio = np.ones(n)
        step_ratio[status == STATUS_SUBSTEPPED] = 1.0 / np.maximum(substeps[status == STATUS_SUBSTEPPED], 1)
        step_ratio[failed] = 0.25 / (1 << o.max_substep_level) if o.max_substep_level < 3 else 0.25
        new_state = {
            "strain": np.where(ok[:, None, None], state["strain"] + de, state["strain"]),
            "plastic_strain": np.where(ok[:, None, None], state["plastic_strain"] + d_eps_p, state["plastic_strain"]),
            "kappa": kap_out,
            "status": status,
            "step_ratio": step_ratio,
            "substeps": substeps,
            "iterations": iterations,
            "tension_cutoff": cutoff,
            "mobilised_ratio": mobilised,
            # Mandel tangent of the last plastic step: the Newton predictor of the next one
            "predictor": (np.where(((iterations > 0) & ok & ~cutoff)[:, None, None], D, pred) if tangent else pred),
        }
        if "element_size" in state:
            new_state["element_size"] = state["element_size"]
        if failed.any():
            self._record_failure(de, sig, state, np.flatnonzero(failed))
        tan = _k.tangent_from_mandel(D) if tangent else None
        return new_sig, new_state, tan

    # ----------------------------------------------------------------------------- replay
    def _record_failure(self, de, sig, state, idx) -> None:
        import json

        record = {
            "d_strain": de[idx],
            "stress": sig[idx],
            "point_index": idx,
            "params_json": np.array(json.dumps(self.params.to_dict())),
            "rule": np.array(self.rule),
            "axes": self.axes,
            "options_json": np.array(json.dumps(self.options.__dict__)),
        }
        for key, arr in state.items():
            record[f"state__{key}"] = np.asarray(arr)[idx]
        self.last_failure = record
        if self.replay_dir is not None:
            self.replay_dir.mkdir(parents=True, exist_ok=True)
            path = self.replay_dir / f"cpa-failure-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}-{idx[0]}.npz"
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


def replay(path, **model_options):
    """Re-run the failed points stored in a replay file; returns (model, stress, state, tangent).

    ``model_options`` override the stored integration options (e.g. ``max_substep_level=10``) to
    study whether more sub-steps would have saved the point.
    """
    import json

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"replay file {str(path)!r} does not exist")
    with np.load(path, allow_pickle=False) as f:
        data = {k: f[k] for k in f.files}
    params = parameters_from_dict(json.loads(str(data["params_json"])), source=str(path))
    options = json.loads(str(data["options_json"]))
    options.pop("barrier", None)
    options.pop("tol_hardening", None)
    options.update(model_options)
    model = CPAModel(params, rule=str(data["rule"]), axes=data["axes"], **options)
    state = {k[len("state__"):]: v for k, v in data.items() if k.startswith("state__")}
    stress, new_state, tangent = model.update(data["d_strain"], data["stress"], state)
    return model, stress, new_state, tangent


# re-exported status codes for convenience
STATUS = {"ok": STATUS_OK, "substepped": STATUS_SUBSTEPPED, "failed": STATUS_FAILED}
