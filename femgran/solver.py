"""Incremental Newton-Raphson solver for small-strain elastoplastic boundary-value problems.

The algorithm (one load step from load factor t_n to t_{n+1} = t_n + dt):

1. Displacement increment du: prescribed DOFs get u_D(t_{n+1}) - u_n; the others start from the
   tangent predictor K_n du = f_ext(t_{n+1}) - f_int(sigma_n) with the last converged tangent K_n, or
   (``predictor="extrapolate"``, after the first step) the last converged increment scaled to the new
   step, or zero (``predictor="none"``).
2. Newton iteration k: strain increment d_eps = B du at every quadrature point; ONE material call
   ``update(d_eps, sigma_n, state_n)`` from the committed start-of-step state gives sigma, the state and
   the consistent tangent D; residual r = f_int(sigma) - f_ext(t_{n+1}) on the free DOFs. A coupled
   discretisation (:mod:`femgran.gradient`: u and a nonlocal field) adds the field's increment at the
   points to the call (``disc.point_inputs``) and the field's rows to r and K; the rest is unchanged.
3. Converged when |r_free| <= tol * max(|f_ext|, |reaction|, force_floor) (the reaction is the internal
   force on the prescribed DOFs). Otherwise solve K_ff ddu = -r_free with K = sum B^T D B (numba kernel,
   :mod:`femgran.assembly`), and update du <- du + s ddu with the step length s of a backtracking line
   search: s = 1 whenever the full Newton step reduces |r| sufficiently (Armijo), otherwise shorter
   steps chosen by quadratic interpolation; if no step down to 2**-line_search reduces |r|, the step
   fails and is cut back (a non-descent step is never taken).
4. On convergence the trial state is committed (:class:`femgran.state.PointState`), the step is
   recorded (history row, output files) and dt grows by ``grow`` (up to ``dt_max``) after an easy step
   (or, with ``SolverOptions.easy_steps``, after that many easy steps in a row without a cut-back).
   On failure (material STATUS_FAILED points, too many iterations, a residual that is not finite or
   explodes) the state is reverted and dt is cut by the points' suggested step ratio (at most 1/2).
   After ``max_cuts`` successive cuts, or dt < dt_min, the run stops cleanly: every converged step is
   already saved and the returned :class:`Solution` says why it stopped.

Path following (``run(..., control=PathControl(...), control_end=c)``): where the response snaps back
(a softening band that unloads the rest of the body elastically faster than it opens), no load factor
and no prescribed displacement grows monotonically along the path. Indirect displacement control then
prescribes, step by step, a quantity that does, c(u) = sum_i w_i u_i (e.g. the opening of the band),
and makes the load factor t an unknown of each step: Newton solves the bordered system

    K_ff ddu_f + (K_fD ubar_D - f_ramp,f) dt = -r_f,      w . ddu = c_target - c(u)

by two solves with K_ff (ubar_D = d u_D / d t); the steps run in c / c_end from 0 to 1, so step sizes,
cut-backs and dt_min read as in load control. The constraint is linear, so it holds after the first
iteration; the iterations take full steps (a line search would scale the constraint's correction too).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from femgran.state import PointState
from material.base import step_fraction
from material.table import Table, read_table

__all__ = ["Dirichlet", "PathControl", "SolverOptions", "Solution", "History", "NewtonSolver", "LinearSolver",
           "linear_solve", "LINEAR_SOLVERS", "HISTORY_COLUMNS", "history_descriptions"]

LINEAR_SOLVERS = ("auto", "superlu", "amg-gmres", "ilu-gmres")
PREDICTORS = ("tangent", "extrapolate", "none")


@dataclass
class Dirichlet:
    """Prescribed displacement on a set of vector DOFs.

    u[dofs] = values * t if ``ramp`` (t the load factor, 0 -> t_end) else ``values`` (constant).
    A ``name`` adds the columns ``<name>_displacement`` (mean prescribed value, m) and
    ``<name>_reaction`` (sum of the reaction forces on these DOFs, kN, or kN/m in plane strain) to
    the history.
    """

    dofs: np.ndarray
    values: float | np.ndarray = 0.0
    ramp: bool = True
    name: str | None = None

    def __post_init__(self):
        self.dofs = np.asarray(self.dofs, dtype=np.int64).ravel()
        if self.dofs.size == 0:
            raise ValueError(f"Dirichlet condition {self.name or ''!s}: names no nodes (empty DOF set)")
        v = np.asarray(self.values, dtype=float)
        if v.ndim and v.shape != self.dofs.shape:
            raise ValueError(f"Dirichlet {self.name}: values shape {v.shape} != dofs shape {self.dofs.shape}")
        self.values = np.broadcast_to(v, self.dofs.shape).copy()

    def at(self, t: float) -> np.ndarray:
        return self.values * t if self.ramp else self.values


@dataclass
class PathControl:
    """Indirect displacement control (module docstring): the quantity c(u) = sum_i weights_i u[dofs_i]
    [m], measured from the start of the stage, grows by a prescribed amount in every step; the load
    factor follows. ``name`` is its history column."""

    dofs: np.ndarray
    weights: np.ndarray
    name: str = "control"

    def __post_init__(self):
        self.dofs = np.asarray(self.dofs, dtype=np.int64).ravel()
        self.weights = np.broadcast_to(np.asarray(self.weights, dtype=float), self.dofs.shape).copy()
        if self.dofs.size == 0 or not np.all(np.isfinite(self.weights)) or not np.any(self.weights):
            raise ValueError(f"PathControl {self.name}: needs DOFs and finite, not all zero, weights")

    def value(self, u: np.ndarray) -> float:
        return float(self.weights @ u[self.dofs])


@dataclass
class SolverOptions:
    """Newton, step-control and linear-solver settings.

    tol : relative residual tolerance (free-DOF force norm / reference force norm).
    force_floor : smallest reference force norm [kN] (guards zero-load states).
    max_iter : Newton iterations per try; max_cuts : successive cut-backs before a clean stop.
    dt_min : smallest load-factor step; grow : dt factor after an easy step (at most ``easy_iter`` Newton
    iterations). easy_steps : None (the default) grows after every easy step, cut back or not; N >= 1 only
    after N consecutive easy steps none of which was cut back (Abaqus/Standard's automatic incrementation
    grows after two such increments). Measured with N = 2 against the default, material evaluations and
    cut-backs (``femgran footing ... --easy-steps 2``; ``examples/fe_04_biaxial_meshes.py --easy-steps 2``):
    * the quadratic shear-band study (l = 6 mm, 36 elements across) from its checkpoint at 1.48 % axial
      strain into the peak (1.76 %): to 1.72 %, 448 evaluations and 6 cut-backs against 747 and 14. By
      default every second step there was cut back: a step that converged after a cut-back grew at once
      back toward the size that had failed, and each failed try ran its 25 iterations (about 65
      evaluations, against 10-12 for a step that converges);
    * the isotropic CPA footing: E = 60 MPa, resolution 2, 1,157 and 4 against 1,275 and 9; E = 6 MPa 488
      and 0 both on resolution 2, 825 and 2 against 720 and 1 on resolution 3; the same pressures. The
      thesis sand at alpha = 90 deg 407 and 4 against 491 and 8; stabilised (mu = 0.1) at alpha = 0 253
      and 2 against 251 and 2;
    * but the thesis sand at alpha = 0 and 30 deg, whose runs stop or go on as the path through points
      without a unique rate problem decides (``docs/cpa_law.md``, section 4), stops at t = 0.0032 and 0.58
      instead of 0.71 and 1: so it is not the default.
    line_search : the shortest trial step of the line search is 2**-line_search times the Newton step
    (0 disables the line search: plain Newton, every full step taken). See ``NewtonSolver._line_search``.
    predictor : first guess of each step's free displacements: "extrapolate" (the default: the last
    converged increment scaled by dt / dt_last, and the tangent predictor for the first step and after a
    cut-back; on a monotonic path it carries the plastic mechanism of the last step, which the last
    tangent, taken at its start, does not: measured on the CPA footing, 6.7 -> 4.1 Newton iterations per
    step, on the Drucker-Prager footing 2.5 -> 3.3), "tangent" (from the last converged tangent, so the
    prescribed displacements spread smoothly into the body) or "none" (prescribed DOFs only).
    linear_solver : "superlu" (direct), "amg-gmres" (pyamg smoothed aggregation preconditioning GMRES)
    or "ilu-gmres", or "auto" (the default, chosen by measurement, benchmarks/fe_newton.py: SuperLU for
    plane strain below 200k DOFs and 3D below 10k DOFs, AMG-GMRES above); krylov_tol : relative
    tolerance of the Krylov solvers.
    A step is accepted only when its residual is below ``tol``; otherwise it is cut back.
    """

    tol: float = 1e-8
    force_floor: float = 1e-10
    max_iter: int = 25
    max_cuts: int = 8
    dt_min: float = 1e-7
    grow: float = 1.5
    easy_iter: int = 6
    easy_steps: int | None = None
    line_search: int = 8
    predictor: str = "extrapolate"
    linear_solver: str = "auto"
    krylov_tol: float = 1e-10

    def __post_init__(self):
        if self.linear_solver not in LINEAR_SOLVERS:
            raise ValueError(f"linear_solver = {self.linear_solver!r}: allowed {LINEAR_SOLVERS}")
        if self.predictor not in PREDICTORS:
            raise ValueError(f"predictor = {self.predictor!r}: allowed {PREDICTORS}")
        if not (0 < self.tol < 1):
            raise ValueError(f"tol = {self.tol!r}: allowed 0 < tol < 1")
        if int(self.max_iter) < 1 or int(self.max_cuts) < 0:
            raise ValueError(f"max_iter = {self.max_iter}, max_cuts = {self.max_cuts}: "
                             "need max_iter >= 1, max_cuts >= 0")
        if not (0 < self.dt_min < 1) or self.grow < 1 or int(self.line_search) < 0 or int(self.easy_iter) < 0:
            raise ValueError(f"dt_min = {self.dt_min!r}, grow = {self.grow!r}, line_search = {self.line_search!r}, "
                             f"easy_iter = {self.easy_iter!r}: need 0 < dt_min < 1, grow >= 1, line_search >= 0, "
                             "easy_iter >= 0")
        if self.easy_steps is not None and (int(self.easy_steps) != self.easy_steps or self.easy_steps < 1):
            raise ValueError(f"easy_steps = {self.easy_steps!r}: allowed None or integers >= 1")
        if not (0 < self.krylov_tol < 1) or not (self.force_floor > 0):
            raise ValueError(f"krylov_tol = {self.krylov_tol!r}, force_floor = {self.force_floor!r}: need "
                             "0 < krylov_tol < 1, force_floor > 0")

    def to_dict(self) -> dict:
        """The options as a plain dict (the record a run writes, the ``[solver]`` table of a case file); an
        option at the default None (the earlier behaviour) is left out, as TOML has no None."""
        return {f: getattr(self, f) for f in self.__dataclass_fields__ if getattr(self, f) is not None}

    @classmethod
    def resolve(cls, solver=None, where: str = "solver", **overrides) -> "SolverOptions":
        """SolverOptions from ``solver`` (None: the defaults; a SolverOptions; or a mapping of its fields)
        with the ``overrides`` whose value is not None applied on top (the cases' ``tol`` and
        ``linear_solver`` shorthands). A key that is not a field raises ``ValueError`` naming it, ``where``
        and the allowed keys."""
        if solver is None:
            base = {}
        elif isinstance(solver, cls):
            base = solver.to_dict()
        elif hasattr(solver, "keys"):
            base = dict(solver)
        else:
            raise TypeError(f"{where} = {solver!r}: expected SolverOptions, a mapping of its fields, or None")
        base.update({k: v for k, v in overrides.items() if v is not None})
        unknown = sorted(set(base) - set(cls.__dataclass_fields__))
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {unknown}; allowed {sorted(cls.__dataclass_fields__)}")
        return cls(**base)


class History(Table):
    """Table of global quantities, one row per converged step (:class:`material.table.Table`; a column
    a row lacks is NaN there). Columns: :data:`HISTORY_COLUMNS`, the named Dirichlet conditions'
    displacement and reaction, and the case's own."""

    title = "FE history"

    @classmethod
    def read_csv(cls, path) -> "History":
        """A history written by :meth:`write_csv` or a run folder's ``history.csv``."""
        return read_table(path, cls)


#: Descriptions of the history columns the solver writes for every run.
HISTORY_COLUMNS = {
    "step": "converged load step (0: the initial state)",
    "load_factor": "load factor t of the step, 0..t_end [-]",
    "iterations": "Newton iterations of the step [-]",
    "residual": "relative residual at convergence (out-of-balance force / reference force) [-]",
    "cutbacks": "step cut-backs before this step converged [-]",
    "wall_time_s": "wall time of the step [s]",
}


def history_descriptions(dirichlet, extra: dict | None = None) -> dict:
    """Descriptions of every column a run's history gets: the solver's, the named Dirichlet conditions'
    (``<name>_displacement`` [m], ``<name>_reaction`` [kN, or kN/m in plane strain], tension +) and ``extra``."""
    out = dict(HISTORY_COLUMNS)
    for d in dirichlet:
        if d.name:
            out[f"{d.name}_displacement"] = f"mean prescribed displacement of '{d.name}' [m]"
            out[f"{d.name}_reaction"] = f"sum of the reaction forces on '{d.name}' [kN, or kN/m in plane strain]"
    out.update(extra or {})
    return out


@dataclass
class Solution:
    """Result of :meth:`NewtonSolver.run`.

    u : (ndofs,) displacement [m]; stress : (N, 3, 3) [kPa]; state : material state dict;
    history : :class:`History`; completed : whether t_end was reached; stop_reason : text;
    out_dir : run folder (or None); residuals : per converged step, the Newton residual sequence.
    extra : case-specific results, also readable as attributes (``sol.bearing_capacity_kPa``, ...).
    """

    u: np.ndarray
    stress: np.ndarray
    state: dict
    history: History
    completed: bool
    stop_reason: str
    out_dir: object = None
    residuals: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)

    def __getattr__(self, name):
        extra = self.__dict__.get("extra", {})
        if name in extra:
            return extra[name]
        raise AttributeError(name)


#: Fill-reducing column ordering of SuperLU for the direct solves. The finite-element matrices here are
#: structurally symmetric (the coupled gradient systems too, whose values are not), and the minimum degree
#: ordering of A^T + A is the one SuperLU's documentation gives for that case; measured against COLAMD
#: (scipy's default) on matrices of the solver's own runs, with the same partial pivoting and solutions
#: equal to 3e-13 (``python benchmarks/linear_solve.py``, idle and loaded machine): half the fill and
#: 1.9-3.0 times as fast on the default footing (2k DOFs) and the 24-element quadratic shear-band system
#: (16k DOFs), a third of the fill and 3.7-4.2 times as fast on the 48-element one (63k DOFs); the first 20
#: steps of the whole runs (``--whole-run 20``, idle): 1.08 times as fast (band, 24 elements), 1.14 (the
#: Drucker-Prager footing).
DIRECT_ORDERING = "MMD_AT_PLUS_A"

#: SuperLU's threshold for a diagonal pivot, in its symmetric mode: the diagonal entry of a column is the pivot
#: unless it is smaller than this fraction of the column's largest entry (then the largest is). The matrices
#: here are structurally symmetric with a nonzero diagonal, the case for which SuperLU's guide pairs the
#: symmetric mode and a small threshold with the ordering on A^T + A; partial pivoting (threshold 1) leaves
#: the ordering's pivots wherever an off-diagonal entry is larger. Measured on whole runs (``python
#: benchmarks/linear_solve.py --cases gradient --whole-run 999`` and ``--cases footing cpa_footing --whole-run
#: 40``; the same number of solves either way, so the same Newton path): on the coupled gradient system of
#: the shear-band benchmark (``benchmarks/gradient.py --law cpa``, 453 solves) partial pivoting turned away
#: from the diagonal once the law softened and quadrupled the fill (up to 319k against 76k entries of L + U),
#: 4.60 s of direct solves against 1.27 s, largest relative residual 8.5e-14 against 2.1e-14; the first 40
#: steps of the CPA footing 2.50 against 2.05 s of solves, of the Drucker-Prager footing 1.11 against 0.88 s.
DIAG_PIVOT_THRESHOLD = 0.01


def direct_solve(K: sp.spmatrix, b: np.ndarray) -> np.ndarray:
    """K x = b by SuperLU with the ordering :data:`DIRECT_ORDERING` and the diagonal preferred as pivot
    (:data:`DIAG_PIVOT_THRESHOLD`). An exactly singular K gives NaN (as ``scipy.sparse.linalg.spsolve``
    does), which the Newton solver reports as a failed linear solve."""
    try:
        lu = spla.splu(K.tocsc(), permc_spec=DIRECT_ORDERING, diag_pivot_thresh=DIAG_PIVOT_THRESHOLD,
                       options={"SymmetricMode": True})
    except RuntimeError:  # "Factor is exactly singular"
        return np.full(K.shape[0], np.nan)
    return lu.solve(np.asarray(b, dtype=float))


def _preconditioner(K, method, near_nullspace, blocks=None):
    if method == "amg-gmres" and blocks is not None:
        return _block_preconditioner(K, near_nullspace, blocks)
    if method == "amg-gmres":
        import pyamg

        # smoothed aggregation on the symmetric part (the tangent is mildly non-symmetric), with the
        # rigid-body modes as near-null space
        sym = (0.5 * (K + K.T)).tocsr()
        return pyamg.smoothed_aggregation_solver(sym, B=near_nullspace).aspreconditioner()
    ilu = spla.spilu(K.tocsc(), drop_tol=1e-5, fill_factor=10)
    return spla.LinearOperator(K.shape, ilu.solve)


def _block_preconditioner(K, near_nullspace, blocks):
    """Block Gauss-Seidel preconditioner of a coupled system [[A, B], [C, D]] (displacement first, then one
    more field, e.g. the nonlocal field of :mod:`femgran.gradient`): z_u = AMG(A) r_u, z_e = AMG(D)(r_e - C z_u),
    each diagonal block with its own smoothed-aggregation hierarchy (A with the rigid-body modes)."""
    import pyamg

    u, e = blocks
    A, C, D = K[u][:, u], K[e][:, u], K[e][:, e]
    amg_u = pyamg.smoothed_aggregation_solver((0.5 * (A + A.T)).tocsr(),
                                              B=None if near_nullspace is None else near_nullspace[u])
    amg_e = pyamg.smoothed_aggregation_solver((0.5 * (D + D.T)).tocsr())
    Mu, Me = amg_u.aspreconditioner(), amg_e.aspreconditioner()

    def apply(r):
        z = np.empty_like(r)
        z[u] = Mu @ r[u]
        z[e] = Me @ (r[e] - C @ z[u])
        return z

    return spla.LinearOperator(K.shape, apply)


def _gmres(K, b, M, tol):
    its = [0]

    def count(_):
        its[0] += 1

    x, info = spla.gmres(K, b, M=M, rtol=tol, restart=80, maxiter=10, callback=count, callback_type="pr_norm")
    return x, info, its[0]


def linear_solve(K: sp.spmatrix, b: np.ndarray, method: str = "superlu", tol: float = 1e-10,
                 near_nullspace: np.ndarray | None = None, blocks=None) -> np.ndarray:
    """Solve K x = b (K square, possibly non-symmetric) with ``method`` in :data:`LINEAR_SOLVERS` (one shot)."""
    return LinearSolver(method, tol, near_nullspace, blocks=blocks).solve(K, b)


class LinearSolver:
    """K x = b for a sequence of related matrices (Newton iterations).

    "superlu": direct, every time. "amg-gmres" / "ilu-gmres": GMRES preconditioned by a smoothed-
    aggregation AMG hierarchy (pyamg) or an incomplete LU, built at the first solve of each load step
    (:meth:`new_step`) and REUSED for the step's following matrices; rebuilt when GMRES needs more than
    ``reuse_its`` iterations, and a direct solve is the last resort. Building it once per step makes every
    step a function of its start alone, so a run resumed from a checkpoint computes what the run it
    continues computes: measured on a triaxial specimen resumed at step 3, the displacements agree to
    2e-16 (relative), as two fresh runs do (3e-16: the threaded BLAS sums in varying order), where reusing
    the preconditioner across steps left 1.5e-13. The price, measured on the 54,243-DOF specimen
    (``benchmarks/checkpoint.py --resolution 20``): 3.93 s against 3.72 s per Newton iteration.
    "auto": superlu for plane strain below 200k DOFs and 3D below 10k DOFs, else amg-gmres.
    ``blocks`` (displacement indices, other-field indices) of a coupled system: amg-gmres then uses the
    block preconditioner of :func:`_block_preconditioner` (one AMG hierarchy per field).
    """

    def __init__(self, method: str = "auto", tol: float = 1e-10, near_nullspace=None, reuse_its: int = 40,
                 blocks=None):
        if method not in LINEAR_SOLVERS:
            raise ValueError(f"linear solver {method!r}: allowed {LINEAR_SOLVERS}")
        self.method, self.tol, self.near_nullspace, self.reuse_its = method, tol, near_nullspace, reuse_its
        self.blocks = blocks
        self._M = None
        self.last_iterations = 0

    def new_step(self) -> None:
        """A new load step (or a new try of one): the next solve builds its preconditioner afresh."""
        self._M = None

    def resolve(self, n: int, dim: int) -> str:
        if self.method != "auto":
            return self.method
        return "superlu" if (dim == 2 and n < 200_000) or n < 10_000 else "amg-gmres"

    def solve(self, K, b, dim: int = 3, rtol: float | None = None):
        """x with |K x - b| <= rtol |b| (Krylov; default ``tol``) or a direct solve."""
        method = self.resolve(K.shape[0], dim)
        tol = self.tol if rtol is None else max(float(rtol), self.tol)
        if method == "superlu":
            return direct_solve(K, b)
        K = K.tocsr()
        fresh = self._M is None
        if fresh:
            self._M = _preconditioner(K, method, self.near_nullspace, self.blocks)
        x, info, its = _gmres(K, b, self._M, tol)
        if (info != 0 or its > self.reuse_its) and not fresh:
            self._M = _preconditioner(K, method, self.near_nullspace, self.blocks)
            x, info, its = _gmres(K, b, self._M, tol)
        self.last_iterations = its
        if info != 0 or not np.all(np.isfinite(x)):
            self._M = None
            return direct_solve(K, b)  # fall back to the direct solver
        return x


class _StepFailure(Exception):
    """A step that cannot be completed: ``brief`` says why, ``ratio`` the cut-back it suggests. ``detail``, a
    function of no argument returning a clause, is what more the material can say; it is asked only when the
    reason is read (a run's stop message), not at each cut-back or line-search trial."""

    def __init__(self, reason: str, ratio: float = 0.5, detail=None):
        super().__init__(reason)
        self.brief, self.ratio, self._detail = reason, ratio, detail

    @property
    def reason(self) -> str:
        if self._detail is not None:
            self.brief, self._detail = self.brief + self._detail(), None
        return self.brief


class NewtonSolver:
    """Incremental Newton solver (see the module docstring for the algorithm).

    Parameters
    ----------
    disc : femgran.assembly.Discretisation
    material : object with ``initial_state(n, stress=...)`` and ``update(d_strain, stress, state)``
    dirichlet : list of :class:`Dirichlet`
    f_fixed : (ndofs,) external force applied in full from t = 0 (self weight, cell pressure) [kN]
    f_ramp : (ndofs,) external force scaled by the load factor t [kN]
    initial_stress : None, (3, 3) or (N, 3, 3) in-situ stress [kPa], tension positive
    options : :class:`SolverOptions`
    log : :class:`femgran.diagnostics.NewtonLog`, optional
        Records every material evaluation of the Newton iterations (what the material did, and the
        convergence rate); :attr:`log` is always set (an in-memory log by default).
    """

    def __init__(self, disc, material, dirichlet, *, f_fixed=None, f_ramp=None, initial_stress=None,
                 options: SolverOptions | None = None, log=None):
        from femgran.diagnostics import NewtonLog

        check_material(material)
        self.disc = disc
        self.material = material
        self.options = options or SolverOptions()
        self.points = PointState(material, disc.n_points, initial_stress, element_size=disc.element_size())
        self.u = np.zeros(disc.ndofs)
        self.t = 0.0
        self.time_offset = 0.0  # the series time of a staged run: stage k spans [k, k + 1]
        self._committed_tangent = None
        self.stalled = None  # (du, ddu, s) of the last try whose line search found no decrease
        self.log = NewtonLog() if log is None else log
        self.set_stage(dirichlet, f_fixed, f_ramp)

    def set_stage(self, dirichlet, f_fixed=None, f_ramp=None, *, u_start=None) -> None:
        """Boundary conditions and loads of a (new) stage, from the present state: the prescribed values of
        ``dirichlet`` are displacements from ``u_start`` (default: the present displacements), ``f_fixed``
        acts from the start of the stage and ``f_ramp`` grows with its load factor t, reset to 0."""
        n = self.disc.ndofs
        self.dirichlet = list(dirichlet)
        for d in self.dirichlet:
            if d.dofs.min() < 0 or d.dofs.max() >= n:
                raise ValueError(f"Dirichlet {d.name}: DOF index out of range 0..{n - 1}")
        self.f_fixed = np.zeros(n) if f_fixed is None else np.asarray(f_fixed, float)
        self.f_ramp = np.zeros(n) if f_ramp is None else np.asarray(f_ramp, float)
        for name, f in (("f_fixed", self.f_fixed), ("f_ramp", self.f_ramp)):
            if f.shape != (n,) or not np.all(np.isfinite(f)):
                raise ValueError(f"{name}: expected a finite vector of shape ({n},), got {f.shape}")
        self.u_start = self.u.copy() if u_start is None else np.asarray(u_start, float).copy()
        self.t = 0.0
        all_d = np.concatenate([d.dofs for d in self.dirichlet]) if self.dirichlet else np.zeros(0, np.int64)
        self.constrained = np.unique(all_d)
        self.free = np.setdiff1d(np.arange(n), self.constrained)
        self._near_nullspace = None
        self.linear = None  # LinearSolver, made at the first solve
        self._last_increment = None  # (du, dt) of the last converged step, for the extrapolating predictor
        # the step being solved, in relaxation times of a rate-dependent law (material.base.step_fraction:
        # the law's relaxation_time, or one nominal step)
        self.step_fraction = 1.0

    # ------------------------------------------------------------------ pieces
    def prescribed(self, t: float) -> np.ndarray:
        """(n_constrained,) prescribed displacements at load factor t (later conditions win)."""
        u = self.u_start.copy()
        for d in self.dirichlet:
            u[d.dofs] = self.u_start[d.dofs] + d.at(t)
        return u[self.constrained]

    def external(self, t: float) -> np.ndarray:
        return self.f_fixed + t * self.f_ramp

    def _evaluate(self, du, t):
        """Material update for the trial increment du; residual r (ndofs,), failed mask."""
        de = self.disc.strain(du)
        self._trial_strain = de  # the full Newton step's row of the log takes its direction's strain from it
        inputs = self._point_inputs(du)
        stress, tangent, failed = self.points.evaluate(de, **inputs)
        if failed.any():
            where = getattr(self.points.material, "replay_dir", None)
            hint = f" (their inputs: {where})" if where is not None else ""
            raise _StepFailure(f"{int(failed.sum())} material point(s) failed{hint}", self.points.suggested_ratio(),
                               self._why_failed(de, failed, inputs))
        r = self.disc.internal_force(stress, tangent, self.u + du) - self.external(t)
        if not np.all(np.isfinite(r)):
            raise _StepFailure("residual not finite")
        return r, tangent

    def _why_failed(self, de, failed, inputs):
        """The material's own reading of its failed points (``explain_failure``, e.g. the CPA law's point that
        snaps back at the peak of its planes) as a function that returns a clause of the stop message: how
        many points it explains, and the first one's sentence ("" if the law has none). None for a material
        without it. The function reads the committed state, which a cut-back keeps; it keeps the failed
        update's fraction reached itself (the trial state, which the cut-back drops), so that update is not
        run again."""
        explain = getattr(self.points.material, "explain_failure", None)
        if explain is None:
            return None
        idx = np.flatnonzero(failed)
        extra = dict(inputs)
        if "reached" in self.points.trial_state:
            extra["reached"] = np.asarray(self.points.trial_state["reached"], dtype=float)[idx]
        stress, state = self.points.stress, self.points.state

        def clause() -> str:
            why = [w for w in explain(de, stress, state, points=idx, **extra) if w]
            return f"; {len(why)} of them: {why[0]}" if why else ""

        return clause

    def _point_inputs(self, du) -> dict:
        """The material's inputs besides the strain increment: the coupled field's increment
        (``disc.point_inputs``) and, for a rate-dependent law, the step's size in its relaxation times."""
        inputs = self.disc.point_inputs(du)
        if getattr(self.points.material, "rate_dependent", False):
            inputs["step_fraction"] = self.step_fraction
        return inputs

    def _norms(self, r, t):
        rf = np.linalg.norm(r[self.free])
        ref = max(np.linalg.norm(self.external(t)), np.linalg.norm(r[self.constrained]), self.options.force_floor)
        return rf, ref

    def _nullspace(self):
        if self._near_nullspace is None:
            x = self.disc.dof_coordinates()
            d = self.disc.dim
            ns = x.shape[0]
            modes = []
            for c in range(d):
                m = np.zeros((ns, d)); m[:, c] = 1.0; modes.append(m.ravel())
            pairs = [(0, 1)] if d == 2 else [(0, 1), (1, 2), (0, 2)]
            for i, j in pairs:
                m = np.zeros((ns, d)); m[:, i] = -x[:, j]; m[:, j] = x[:, i]; modes.append(m.ravel())
            full = np.zeros((self.disc.ndofs, len(modes)))  # zero on the DOFs of a coupled field
            full[: ns * d] = np.column_stack(modes)
            self._near_nullspace = full[self.free]
        return self._near_nullspace

    def _blocks(self):
        """(displacement, other field) positions within the free DOFs of a coupled discretisation, else None."""
        nu = self.disc.n_displacement_dofs
        if nu == self.disc.ndofs:
            return None
        return np.flatnonzero(self.free < nu), np.flatnonzero(self.free >= nu)

    def _solve_free(self, K, rhs_free, rtol=None):
        Kff = K[self.free][:, self.free]
        if self.linear is None:
            opt = self.options
            method = LinearSolver(opt.linear_solver).resolve(self.free.size, self.disc.dim)
            self.linear = LinearSolver(method, opt.krylov_tol, self._nullspace() if method == "amg-gmres" else None,
                                       blocks=self._blocks())
        x = self.linear.solve(Kff, rhs_free, self.disc.dim, rtol)
        if not np.all(np.isfinite(x)):
            raise _StepFailure("linear solve failed (singular tangent?)")
        return x

    def _predict(self, du, t_new):
        """Tangent predictor: K_n du = f_ext(t_new) - f_int(sigma_n) with the prescribed part of du."""
        if self._committed_tangent is None:
            zero = np.zeros(self.disc.ndofs)
            _, self._committed_tangent, _ = self.points.evaluate(np.zeros((self.disc.n_points, 3, 3)),
                                                                 **self._point_inputs(zero))
            self.points.revert()
        K = self.disc.stiffness(self._committed_tangent)
        r0 = self.disc.internal_force(self.points.stress, self._committed_tangent, self.u) - self.external(t_new)
        rhs = -(r0 + K @ du)[self.free]
        du = du.copy()
        du[self.free] = self._solve_free(K, rhs, 1e-3)
        return du

    def step(self, t_new: float, *, step: int = 0, attempt: int = 0):
        """Try one step to load factor t_new from the committed state. Returns (du, iterations, residuals).

        Raises ``_StepFailure`` (the caller cuts back) when a material point fails, the residual is not
        finite or explodes, or ``max_iter`` iterations do not bring it below ``tol``.
        """
        from femgran.diagnostics import full_step_overshoot

        opt = self.options
        self.log.start_try()
        self.stalled = None
        if self.linear is not None:
            self.linear.new_step()

        def evaluate(du, it, s, rf_before=None):
            """Material update and residual of the iterate du, logged; (r, tangent, rf, ref) or raises."""
            try:
                r, tangent = self._evaluate(du, t_new)
            except _StepFailure:
                self.log.record(step=step, attempt=attempt, iteration=it, load_factor=t_new, residual=np.nan,
                                line_search=s, accepted=False, state=self.points.trial_state,
                                committed=self.points.state)
                raise
            rf, ref = self._norms(r, t_new)
            accepted = rf_before is None or rf <= rf_before
            over = None
            if s == 1.0 and base is not None:  # a full Newton step: where it left the tangent's prediction
                stress0, tangent0, loading0, strain0, rf0 = base
                over = {"overshoot_points": np.nan, "overshoot_pressure": np.nan, "overshoot_unloading": np.nan,
                        "overshoot_planes": np.nan, "overshoot_point": np.nan}
                if isinstance(tangent0, np.ndarray):  # (a coupled field's tangent: the ratio only)
                    over.update(full_step_overshoot(self.disc.dx, stress0, tangent0, self.points.trial_stress,
                                                    self._trial_strain - strain0, loading0,
                                                    self.points.trial_state.get("loading")) or {})
                over["overshoot"] = rf / rf0 if rf0 > 0 else np.nan
            self.log.record(step=step, attempt=attempt, iteration=it, load_factor=t_new, residual=rf / ref,
                            line_search=s, accepted=accepted, state=self.points.trial_state, committed=self.points.state,
                            overshoot=over)
            return r, tangent, rf, ref

        du = np.zeros(self.disc.ndofs)
        du[self.constrained] = self.prescribed(t_new) - self.u[self.constrained]
        if opt.predictor == "extrapolate" and self._last_increment is not None and attempt == 0:
            du_last, dt_last = self._last_increment
            du[self.free] = du_last[self.free] * ((t_new - self.t) / dt_last)
        elif opt.predictor != "none":
            du = self._predict(du, t_new)
        base = None
        r, tangent, rf, ref = evaluate(du, 0, 0.0)
        residuals = [rf / ref]
        for it in range(1, opt.max_iter + 1):
            if residuals[-1] <= opt.tol:
                return du, it - 1, residuals
            K = self.disc.stiffness(tangent)
            ddu = np.zeros_like(du)
            # inexact Newton (Krylov solvers): forcing term eta_k = min(1e-3, 0.1 |r_k| / ref) keeps the
            # convergence quadratic while sparing GMRES iterations far from the solution
            ddu[self.free] = self._solve_free(K, -r[self.free], min(1e-3, 0.1 * residuals[-1]))
            # the iterate's stress, tangent, loading planes and strain: the full step's row logs what it missed
            base = (self.points.trial_stress, tangent, self.points.trial_state.get("loading"), self._trial_strain, rf)
            s, r_new, tangent_new, rf_new, ref_new = self._line_search(evaluate, du, ddu, it, rf)
            du = du + s * ddu
            r, tangent, rf, ref = r_new, tangent_new, rf_new, ref_new
            residuals.append(rf / ref)
            if it >= 3 and residuals[-1] > 1e4 * residuals[0]:  # only without line search
                raise _StepFailure("Newton diverging")
        if residuals[-1] <= opt.tol:
            return du, opt.max_iter, residuals
        tail = ", ".join(f"{x:.1e}" for x in residuals[-6:])
        raise _StepFailure(f"no convergence in {opt.max_iter} iterations (residual {residuals[-1]:.2e}; "
                           f"last residuals {tail})")

    def step_controlled(self, control: PathControl, c_new: float, *, step: int = 0, attempt: int = 0):
        """One step of path following: to c(u - u_start) = ``c_new``, the load factor an unknown.

        Returns (du, t_new, iterations, residuals); raises ``_StepFailure`` as :meth:`step` does."""
        opt = self.options
        self.log.start_try()
        self.stalled = None
        if self.linear is not None:
            self.linear.new_step()
        n = self.disc.ndofs
        w = np.zeros(n)
        np.add.at(w, control.dofs, control.weights)
        ubar = np.zeros(n)
        ubar[self.constrained] = self.prescribed(1.0) - self.prescribed(0.0)
        dc = c_new - control.value(self.u - self.u_start)
        du, t_new = np.zeros(n), self.t
        last = self._last_increment
        if last is not None and len(last) == 3 and attempt == 0 and last[2] != 0.0:
            du_last, _, dc_last = self._last_increment  # the last converged step, scaled to this one
            du = du_last * (dc / dc_last)
            t_new = self.t + (self._last_increment[1]) * (dc / dc_last)
            du[self.constrained] = self.prescribed(t_new) - self.u[self.constrained]
        residuals = []
        for it in range(opt.max_iter + 1):
            try:
                r, tangent = self._evaluate(du, t_new)
            except _StepFailure:
                self.log.record(step=step, attempt=attempt, iteration=it, load_factor=t_new, residual=np.nan,
                                line_search=1.0, accepted=False, state=self.points.trial_state,
                                committed=self.points.state)
                raise
            rf, ref = self._norms(r, t_new)
            g = float(w @ du) - dc
            residuals.append(rf / ref)
            self.log.record(step=step, attempt=attempt, iteration=it, load_factor=t_new, residual=rf / ref,
                            line_search=1.0, accepted=True, state=self.points.trial_state, committed=self.points.state)
            if residuals[-1] <= opt.tol and abs(g) <= 1e-10 * max(abs(dc), 1e-300):
                return du, t_new, it, residuals
            if it == opt.max_iter:
                break
            K = self.disc.stiffness(tangent)
            q = K @ ubar - self.f_ramp  # d r / d t
            x1 = self._solve_free(K, -r[self.free], min(1e-3, 0.1 * residuals[-1]))
            x2 = self._solve_free(K, -q[self.free], 1e-10)
            wf = w[self.free]
            denominator = float(wf @ x2 + w[self.constrained] @ ubar[self.constrained])
            if denominator == 0.0 or not np.isfinite(denominator):
                raise _StepFailure(f"path control {control.name}: the controlled quantity does not respond to "
                                   "the load here (choose DOFs that open with the mechanism)")
            dt = (-g - float(wf @ x1)) / denominator
            du[self.free] += x1 + dt * x2
            du[self.constrained] += dt * ubar[self.constrained]
            t_new += dt
            if it >= 3 and residuals[-1] > 1e4 * residuals[1]:  # [0] may be the committed state's: ~0
                raise _StepFailure("Newton diverging")
        tail = ", ".join(f"{x:.1e}" for x in residuals[-6:])
        raise _StepFailure(f"no convergence in {opt.max_iter} iterations under path control (residual "
                           f"{residuals[-1]:.2e}; last residuals {tail})")

    def _line_search(self, evaluate, du, ddu, it, rf):
        """Step length s along the Newton direction ddu: the first trial with a sufficient decrease of |r|.

        Armijo condition |r(du + s ddu)| <= (1 - 1e-4 s) |r(du)|, tried from s = 1; after a failed trial
        the next s minimises the quadratic model of phi(s) = |r(s)|^2 / 2 through phi(0), phi'(0) =
        -2 phi(0) (the Newton direction) and the failed trial, kept in [s/4, s/2] (a trial whose
        material update fails counts as s/2). Below s = 2**-line_search there is no decrease along this
        direction and the step fails (the caller cuts back): a step that does not reduce the residual is
        never taken.

        Why strict: on the isotropic CPA footing (critical-plane Mohr-Coulomb, 33 near-perfectly-plastic
        planes) 44 % of the Newton iterations needed a shorter step and in 16 % no step down to 1/16 reduced
        |r|; taking the last trial anyway (the earlier rule) led to two-cycles until max_iter and to
        cut-backs. The tangent is consistent there (|r(s)| / |r| = 1 - s to 1e-5 for small s); the full
        step overshoots because hundreds of points switch between elastic and plastic, and a decrease exists
        at s ~ 2**-6..2**-8. With this rule the same footing (resolution 2, E = 6 MPa) ran in 40 steps
        without a cut-back and with a third fewer material evaluations (470 against 718).

        On that failure ``self.stalled`` keeps (du, ddu, s): the iterate, the direction and the shortest
        trial, which :func:`femgran.diagnostics.stall_report` probes at a run's stop (None after any other
        end of a try).

        Why s/4 and not the textbook s/10: the overshoot comes from a few points whose response has a
        kink along the direction (``femgran.diagnostics.kinks_along``: 9 of 1,386 points, the first at
        s = 0.05, every other point linear), so |r(s)| is nearly linear up to the first kink and the
        quadratic model, which sees only the overshoot at s = 1, undershoots it by far. Material
        evaluations with [s/10, s/2] against [s/4, s/2]: isotropic footing E = 60 MPa, resolution 2:
        1288 / 924; E = 6 MPa: 470 / 486; thesis sand (mu = 0.1, resolution 3): 288 / 271.
        """
        opt = self.options
        if opt.line_search == 0:
            r_new, tangent_new, rf_new, ref_new = evaluate(du + ddu, it, 1.0)
            return 1.0, r_new, tangent_new, rf_new, ref_new
        s, s_min = 1.0, 2.0 ** -opt.line_search
        while True:
            try:
                r_new, tangent_new, rf_new, ref_new = evaluate(du + s * ddu, it, s, (1.0 - 1e-4 * s) * rf)
                if rf_new <= (1.0 - 1e-4 * s) * rf:
                    return s, r_new, tangent_new, rf_new, ref_new
                q = rf_new / rf
                s_model = s / (1.0 + q * q) if s == 1.0 else s * s / (q * q - 1.0 + 2.0 * s)
            except _StepFailure:
                s_model = 0.5 * s
            if s <= s_min:
                self.stalled = (du.copy(), ddu.copy(), s)  # femgran.diagnostics.stall_report reads it
                raise _StepFailure(f"line search: no decrease of the residual along the Newton direction "
                                   f"down to step length {s:.1e} (iteration {it})")
            s = min(0.5 * s, max(0.25 * s, s_model))

    # ------------------------------------------------------------------ driver
    def run(self, steps: int = 10, t_end: float = 1.0, *, dt_max: float | None = None, writer=None,
            progress: bool = False, observers=(), fixed_steps: bool = False, descriptions: dict | None = None,
            resume: dict | None = None, after_step=None, close_writer: bool = True,
            control: PathControl | None = None, control_end: float | None = None) -> Solution:
        """Load from t = 0 to ``t_end`` in nominally ``steps`` equal steps, cutting back and regrowing dt.

        writer : object with ``write(t, solver)`` called after every converged step (and once at t = 0).
        observers : callables ``f(solver) -> dict`` adding columns to each history row; ``solver.reaction``
            then holds f_int - f_ext of the converged step (the reactions on the prescribed DOFs).
        dt_max : largest load-factor step (default t_end / steps: regrowth after a cut-back never
            exceeds the nominal step).
        descriptions : meaning, unit and sign convention of the observers' columns (the history's header).
        resume : the run state of a checkpoint (:func:`femgran.checkpoint.restore`, which has put the solver
            where the checkpoint was): the run continues from there as if it had not stopped.
        after_step : ``f(solver, run_state) -> str | None`` called after every converged step (and its
            step-size update) with ``run_state`` = dt, n_step, history, residual_log; a string stops the
            run cleanly with that reason (an interruption).
        fixed_steps : no regrowth at all after a cut-back (equal steps whenever nothing fails, e.g. to
            compare step by step with material.driver).
        control, control_end : path following (module docstring): the steps go from c = 0 to
            ``control_end`` [m] of the :class:`PathControl` quantity (t_end is then not used; the run's
            "position" c / control_end plays the part of t in the step sizes).
        """
        opt = self.options
        steps = int(steps)
        if steps < 1:
            raise ValueError(f"steps = {steps}: must be >= 1")
        if control is not None:
            if control_end is None or not np.isfinite(control_end) or control_end == 0.0:
                raise ValueError(f"control_end = {control_end!r}: path control needs the end value of "
                                 f"{control.name} (finite, not 0)")
            t_end = 1.0  # the position c / control_end runs from 0 to 1

        def position() -> float:
            return self.t if control is None else control.value(self.u - self.u_start) / control_end

        dt0 = float(t_end) / steps
        dt_max = dt0 if dt_max is None else float(dt_max)
        dt = dt0
        self.history_descriptions = history_descriptions(self.dirichlet, descriptions)
        history = History(descriptions=self.history_descriptions)
        residual_log = []
        easy = 0  # consecutive easy steps without a cut-back since dt last grew (SolverOptions.easy_steps)
        if resume is not None:
            dt, n_step0 = float(resume["dt"]), int(resume["n_step"])
            easy = int(resume.get("easy_streak", 0))
            for r in resume["history"]:
                history.append(r)
            residual_log = [list(r) for r in resume["residual_log"]]
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=float(t_end), unit="load", bar_format="{l_bar}{bar}| t={n:.3f}/{total:.3f} {postfix}")
            bar.update(self.t)  # a resumed run starts where its checkpoint was
        if resume is None:
            row = self._row(0, 0, [0.0], 0, observers)
            if control is not None:
                row[control.name] = control.value(self.u - self.u_start)
            history.append(row)
            if writer is not None:
                writer.write(self.time_offset, self, row)
        completed, reason = False, ""
        cuts, n_step = 0, (0 if resume is None else n_step0)
        self.run_state = {"dt": dt, "n_step": n_step, "history": history, "residual_log": residual_log,
                          "easy_streak": easy}
        while position() < t_end * (1 - 1e-12):
            dt = min(dt, t_end - position())
            self.step_fraction = step_fraction(self.points.material, dt, dt0)
            t0 = time.perf_counter()
            try:
                if control is None:
                    t_new = self.t + dt
                    du, iters, residuals = self.step(t_new, step=n_step + 1, attempt=cuts)
                else:
                    du, t_new, iters, residuals = self.step_controlled(control, (position() + dt) * control_end,
                                                                       step=n_step + 1, attempt=cuts)
            except _StepFailure as exc:
                self.points.revert()
                cuts += 1
                ratio = min(0.5, max(exc.ratio, 0.1))
                dt *= ratio
                if cuts > opt.max_cuts:
                    reason = f"stopped at {self._where(control, position())}: {exc.reason}; {cuts - 1} cut-backs did not help"
                    break
                if dt < opt.dt_min:
                    reason = (f"stopped at {self._where(control, position())}: {exc.reason}; the next load step, {dt:.2g}, would be "
                              f"below dt_min = {opt.dt_min:g} (the steps had already been cut to {dt / ratio:.2g})")
                    break
                if bar is not None:
                    bar.set_postfix_str(f"cut-back ({exc.brief}), dt={dt:.3g}")
                continue
            self.points.commit()
            self._committed_tangent = self.points.tangent
            self._last_increment = (du, t_new - self.t) if control is None else \
                (du, t_new - self.t, control.value(du))
            self.u = self.u + du
            self.t = t_new
            n_step += 1
            residual_log.append(residuals)
            row = self._row(n_step, iters, residuals, cuts, observers)
            if control is not None:
                row[control.name] = control.value(self.u - self.u_start)
            row["wall_time_s"] = time.perf_counter() - t0
            history.append(row)
            if writer is not None:
                writer.write(self.time_offset + self.t, self, row)
            if bar is not None:
                bar.update(dt)
                bar.set_postfix_str(f"it={iters} res={residuals[-1]:.1e} cuts={cuts}")
            easy = easy + 1 if (iters <= opt.easy_iter and cuts == 0) else 0
            cuts = 0
            if opt.easy_steps is None:  # the earlier rule: every easy step grows, cut back or not
                grows = iters <= opt.easy_iter
            else:
                grows = easy >= opt.easy_steps
            if not fixed_steps and grows:
                dt, easy = min(dt * opt.grow, dt_max), 0
            self.run_state = {"dt": dt, "n_step": n_step, "history": history, "residual_log": residual_log,
                              "easy_streak": easy}
            stop = None if after_step is None else after_step(self, self.run_state)
            if stop:
                reason = stop
                break
        else:
            completed, reason = True, (f"reached t = {t_end:g}" if control is None
                                       else f"reached {control.name} = {control_end:g}")
        if bar is not None:
            bar.close()
        if writer is not None and close_writer:
            writer.close(self, completed, reason)
        return Solution(u=self.u.copy(), stress=self.points.stress.copy(), state=self.points.state,
                        history=history, completed=completed, stop_reason=reason,
                        out_dir=getattr(writer, "out_dir", None), residuals=residual_log)

    def _where(self, control, position: float) -> str:
        if control is None:
            return f"t = {self.t:.6g}"
        return f"{control.name} = {control.value(self.u - self.u_start):.6g} (t = {self.t:.6g})"

    def _row(self, n_step, iters, residuals, cuts, observers):
        r = self.disc.internal_force(self.points.stress) - self.external(self.t)
        self.reaction = r  # computed once per step; the observers read it
        row = {"step": n_step, "load_factor": self.t, "iterations": iters, "residual": residuals[-1], "cutbacks": cuts}
        for d in self.dirichlet:
            if d.name:
                row[f"{d.name}_displacement"] = float(np.mean(self.u[d.dofs]))
                row[f"{d.name}_reaction"] = float(np.sum(r[d.dofs]))
        for obs in observers:
            row.update(obs(self))
        return row


def check_material(material) -> None:
    """Raise ``ValueError`` unless ``material`` follows the interface of :mod:`material.base`.

    Calls ``initial_state(1)`` and ``update`` with a zero increment: the state must carry "status",
    "step_ratio", "strain"; the stress must be (1, 3, 3) and the tangent (1, 3, 3, 3, 3), finite.
    """
    for m in ("initial_state", "update"):
        if not callable(getattr(material, m, None)):
            raise ValueError(f"material {type(material).__name__}: lacks the method {m}(); "
                             "allowed: objects with initial_state(n, stress=...) and update(d_strain, stress, state)")
    n = int(getattr(material, "n_points", 1))  # laws tied to a point set (Composite) need all of them
    st = material.initial_state(n)
    missing = [k for k in ("status", "step_ratio", "strain") if k not in st]
    if missing:
        raise ValueError(f"material {type(material).__name__}: state lacks {missing}")
    s, st2, D = material.update(np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), st)
    if np.shape(s) != (n, 3, 3) or np.shape(D) != (n, 3, 3, 3, 3) or not np.all(np.isfinite(D)):
        raise ValueError(f"material {type(material).__name__}: update must return stress (N,3,3) and a finite "
                         f"tangent (N,3,3,3,3); got {np.shape(s)} and {np.shape(D)}")
