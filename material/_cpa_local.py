"""The local problem of the CPA law at one Gauss point, and its solver.

The backward-Euler step (``docs/cpa_law.md``, section 3) asks for the end-of-step stress sigma, the slip
increments dkappa_a of the planes and the opening dlambda of the mean-stress cut-off such that

    R     = S (sigma - sigma_n) + (1/t) sum_a w_a dkappa_a m_a(sigma) + dlambda I/3 - d_eps = 0
    dkappa_a >= 0,   g_a = etah_a(sigma) - eta(kappa_n,a + dkappa_a) <= 0,   dkappa_a g_a = 0   (every plane)
    dlambda  >= 0,   p(sigma) = tr(sigma)/3 <= 0,                            dlambda p = 0

The update is *defined* as the solution of these equations on the branch that starts at the solution
(sigma_n, dkappa = 0, dlambda = 0) of the problem with no increment and is followed as the increment
grows from 0 to d_eps; the algorithm only finds it. So the stress is a deterministic function of
(d_eps, sigma_n, state_n), continuous in d_eps wherever the branch is, and nothing in it depends on how
the global Newton got there. (Other solutions may exist away from the branch: measured at the apex,
where Newton from the elastic trial landed on one of three different exact solutions of a point.)
This definition holds where one branch leaves sigma_n, that is where the rate problem at sigma_n has one
solution (``docs/cpa_law.md``, section 4). Where it has several, several branches leave sigma_n, and the
one the update returns is the one the solver reaches: its first step is the whole increment, so it is
the solution Newton lands on from the tangent predictor, and a finer first step can land elsewhere
(measured at a point of the alpha = 0 footing: first fractions 1 to 1/32 give one answer, 1/64 to 1/1024
a branch that folds at 0.016 of the increment, 1/4096 the first answer again). It is still a
deterministic function of the step's inputs, but not a continuous one there.
With the step stabilisation the floor of a plane over the fraction lam of a step of f relaxation times is
floor0 / (lam f): it grows without bound as lam -> 0, so the branch starts at the committed state even
when that state lies above the planes' curves (the overstress of earlier steps), and the update tends to
the committed state as the step does.

Unknowns and equations of the semismooth Newton method
------------------------------------------------------
* A *weak* plane (kappa_n <= A: eta(kappa_n) <= zeta eta_f / 2, which every plane starts as) has its
  complementarity solved in closed form for a given stress: dkappa = max(0, kappa(etah) - kappa_n) with
  kappa(etah) = A etah / (zeta eta_f - etah) (2.16 inverted). Its slip vector dkappa t_s / T is then
  smooth where the shear traction vanishes (dkappa ~ tau), which the slip as an unknown is not
  (measured: a Newton on (sigma, dkappa) stalls on such planes, whose slip direction turns fast). Its
  stress must stay below the barrier etah < zeta eta_f.
* A *strong* plane (kappa_n > A, or past the peak of a softening law) keeps dkappa as an unknown with
  the Fischer-Burmeister equation Phi(dkappa/A, v) = 0, Phi(u, v) = u + v - sqrt(u^2 + v^2), which holds
  iff the complementarity does (near failure kappa(etah) has a pole but eta(kappa) does not), and its
  overstress in the traction form

      v = (sigma~ (eta + h dkappa) - T) / (sigma~_n (1 + h A))  =  (sigma~ / sigma~_n) (eta + h dkappa - etah) / (1 + h A),

  h the step stabilisation's floor (0 for the thesis's law), sigma~_n the plane's shifted normal stress at
  sigma_n. Both factors are positive constants or positive functions of the stress, so the solution is
  that of the ratio form eta + h dkappa - etah, and so is the tangent (they multiply v = 0 where the
  plane loads); only the Newton iterates differ. The traction form is affine in (sigma~, T) for a given
  slip, where the ratio T / sigma~ is a quotient whose linearisation fails when sigma~ changes by a large
  factor within the step (measured on a shallow point of the stiff sand's footing, 24 planes loading at
  15 times their failure ratio, relaxing over f = 1e-3 to 0.1 relaxation times: 185-385 local iterations
  with 5-12 halvings in the ratio form, the line search creeping at 2^-4 to 2^-13 of the Newton step, and
  a failure at f = 1; 7-10 iterations without a halving in the traction form, 40 with 2 at f = 1).
  Dividing by 1 + h A keeps v at the scale the tolerance on Phi assumes: the floor grows as 1 / (lam f)
  for short steps, and v without the division could not be computed to that tolerance (measured on the
  same point: with f = 1e-6 Phi stalled at 1e-11 for 150 iterations and the point failed for a strain
  increment of 5e-8; with the division it converges in 7 to 14, at f = 1e-5 to 1e-8 alike).
* The cut-off: Phi(dlambda, -p/K) = 0.
Which planes are strong depends on the committed kappa_n only, so it is part of the definition of the
equations, not of the iteration. The strong slips are eliminated from each linearised system plane by
plane (a rank-one term each), leaving 7 x 7 (stress and opening). The merit function
psi = (|R / r|^2 + sum Phi_a^2 + (Phi_0 / r)^2) / 2 (r the strain scale of the point) is continuously
differentiable and the semismooth Newton direction is a descent direction for it, so a backtracking
(Armijo) line search always makes progress unless the Jacobian is singular; near a solution with a
non-singular Jacobian the convergence is superlinear (De Luca, Facchinei & Kanzow 1996; quadratic here,
the pieces being smooth). Where the solution is not strictly complementary (a plane whose slip and
overstress both vanish, common at the apex) it creeps instead; after two cut steps in a row a few full
steps on the minimum function, the active-set Newton of the same equations, are tried
(:func:`_active_set_phase`).

Following the branch
--------------------
Newton starts at the solution for no increment, so its first step is the tangent predictor. A plane
that loaded in the last step sits exactly on its kink there, and the generalised derivative must pick a
branch for it (:data:`_ON_CURVE`): the loading branch by default. When that Newton does not converge,
the branch of each plane on its kink (and of the cut-off, where it is on) is chosen by solving the rate
problem at sigma_n, a linear complementarity problem (:func:`_rate_active_set`, Lemke's method: the
coupling of non-associated planes near failure or at low stress need not be a P-matrix, and then the
all-loading guess can keep Newton away from the one active set that solves it; measured on a point of a
footing at 97 % mobilisation). If
Newton still fails, the equations are solved for the fraction lambda = 1/2, 1/4, ... of the increment,
each from the solution at the last fraction reached, and lambda is doubled again after each success, up
to 1. The answer is the solution at lambda = 1 of the one-step problem: the fractions only supply
starting points, they are not sub-steps. When the branch ends before lambda = 1 (a limit point of the
strain-driven response) :func:`point_update` reports ``FAILED`` with the fraction it reached, and
:func:`update_past_limits` goes on from the limit state (next section).

Past a limit point
------------------
Where the branch ends at a fraction lam* < 1 of the increment, lam* is located by bisection (the last
fraction that integrates), the state there becomes the start of the rest of the increment,
(1 - lam*) d_eps, and the rest is integrated the same way, up to ``Limits.max_points`` times. This is
still a deterministic function of (d_eps, sigma_n, state_n), and it is continuous where the one-step
answer jumps: as lam* -> 1 the rest vanishes, and as lam* -> 0 the rest is the whole increment. The
tangent there is the forward difference of this function (6 more continuations): the response past the
limit is continuous but too steep for the one-step linearisation to describe. The limit is located
between the last fraction the continuation reached and the one it failed at, each trial a Newton solve
from the solution at the last fraction reached: 8-10 ms per limit point without the tangent, 4-5 times
less than the first version, a Python loop over the points' arrays that bisects the whole fraction with
solves from the start of the rest (``benchmarks/limit_points.py``). That loop is kept as the reference the
tests compare against (:func:`material.cpa_reference.follow_past_limits`).

Most of a continuation's Newton iterations are in the solves that fail beyond the limit before the
halvings run out, each taking all its iterations with line searches of up to 40 halvings. The
continuations of the tangent take the same sequence of fractions as the step's own, and skip the solves
that failed there far beyond the limit (:func:`_fails_again`); with the forward
difference this makes the tangent 2.8 times cheaper on the stored points (the footing's fold point 37 ms
with it, against 102 ms with the central difference and no skipping) and the rough-platen triaxial
specimen at alpha = 0 (120 steps, where limit points were 95 % of the time) 2.0 times faster, with the
same Newton iterations and the same stresses to 1e-10 (``docs/cpa_law.md``, section 3). The cheaper
shortcut, starting the continuations' bisections from the located limit, does not compute the same
function: the limit moves by up to 3.5 % of the increment under a perturbation of 1e-9 of its scale, and
the branch reached through another sequence of fractions can end elsewhere (measured: one column of the
fold point's tangent came out half its value).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from material._cpa_plane import (
    ISQ2,
    NO_REFCOUNT,
    REFCOUNT,
    compaction_weight,
    fallback_shear,
    hardening,
    induced_slope,
    induced_tensor,
    measures_of_parts,
    plane_directions,
    plane_stress,
    plane_strengths,
    ratio_barrier,
    shear_pair,
    slip_of_ratio,
    softening_branch,
    sym_parts,
    tensor_parts,
)

# status codes (material.base), and one of point_update only: its branch ends at a limit point within the
# step (the outputs are the limit state; update_past_limits goes on from it)
OK = 0
FAILED = 2
LIMIT = 3

#: The constants of the law, in the global frame (Mandel vectors/matrices).
Law = namedtuple("Law", [
    "normals",      # (M, 3) plane normals
    "nn6",          # (M, 6) Mandel(n n)
    "weights",      # (M,) sum 1
    "cohesion",     # (M,) c_a [kPa]
    "omega6",       # (6,) inherent anisotropy tensor
    "coeffs",       # (K,) a1, a2, ... of eta_f
    "eta0", "beta", "alpha_hat", "beta_hat",
    "zeta", "A", "inv_t", "eta_c_ratio",
    "apex_stress",  # c_apex: the tension at which the loading cones have their apex [kPa]
    "rounding",     # b: the rounding of the planes' tips [kPa]
    "kstar",        # peak slip A / (zeta - 1) of the softening law (inf without)
    "residual",     # eta_residual / eta_f of the softening law
    "compaction_stress",  # p_c: below it the planes' compaction fades [kPa]
    "bulk",         # K [kPa]
    "comp", "stiff",  # (6, 6) elastic compliance and stiffness
])

#: Options of the local solver.
#: ``step``: the size of this step in relaxation times of the step stabilisation (one nominal step by default).
#: ``minimal``: the floor's mu of each point is the least that makes its rate problem uniquely solvable
#: (:func:`_uniqueness_floor`) instead of ``stabilisation``.
#: ``locate``: where the branch ends within the step, the halvings that locate its limit point (0: the point
#: fails there instead; :func:`update_past_limits`).
Options = namedtuple("Options", ["tol", "maxit", "max_halvings", "tangent", "stabilisation", "step", "minimal",
                                 "locate"])

#: Options of the continuation past limit points (:func:`update_past_limits`): ``max_points``, the limit
#: points one step may pass (0: none, the one-step problem of :func:`point_update`); ``fd_step``, the step
#: of the forward-difference tangent relative to |d_eps| + |sigma_n| / E (tensor components). The values
#: and their measurements are the class attributes ``MAX_LIMIT_POINTS`` ... of :class:`material.cpa.CPAModel`.
Limits = namedtuple("Limits", ["max_points", "fd_step"])

#: The data of one point's local problem (fixed during its solution except ``de``, the increment of the
#: current fraction, and ``select``).
Point = namedtuple("Point", [
    "sig_n", "de", "kap_n",  # (6,), (6,), (M,) start of step and increment
    "soft",                  # softening slip scale of the point (0: none)
    "eta_f", "shift",        # (M,) strengths and shifts c_a / eta_f,a + c_apex at the end of the step
    "strong",                # (M,) bool: slip is an unknown (kappa_n > A, or past a softening peak)
    "select",                # (M + 1,) bool: at its kink a plane takes the loading (True) or elastic branch;
                             # select[M]: the same for the mean-stress cut-off (True: p stays 0, the cut-off opens)
    "floor",                 # (M,) the step stabilisation's hardening floor of each plane [1/m] (0: none)
    "r_scale",               # strain scale of the residual
    "post",                  # (M,) bool: past its softening peak at the start, coupled by the gradient
    "coupled",               # any post: the gradient's unknown S and its equation are in the system
    "c0", "m_over",          # the gradient's shift m t d_ebar [m] of the step and its m (implicit gradient)
    "nl_shift",              # (M,) the shift kappa_hat - kappa a plane past its peak has accumulated [m]
])

#: Row length of the plane-major arrays (PlaneData, and the workspace's per-plane rows), a compile-time
#: constant >= M (the largest rule has 78 planes). The loops of :func:`evaluate` that write several rows
#: index flat views of these arrays, ``row * _ROW + a``: with the rows a known distance apart the compiler
#: vectorises them. (With the row length read from the array at run time it has to check at run time that no
#: two rows overlap, and for 33 planes it judged those checks too costly and ran the loops scalar: measured on
#: the states of benchmarks/material_update.py, an evaluation with the Jacobian took 1.35 us instead of 1.03.)
_ROW = 128

#: Per-plane constants of the law in plane-major (structure-of-arrays) layout, made with each thread's
#: workspace by :func:`plane_data`, so that the sums over planes of :func:`evaluate` run on contiguous rows.
#: ``normal``, ``nn`` and ``fallback`` are rows of ``table`` (_NG, _ROW) (rows _G_*; its first M columns).
PlaneData = namedtuple("PlaneData", [
    "normal",    # (3, _ROW) normals
    "nn",        # (6, _ROW) Mandel(n n)
    "fallback",  # (3, _ROW) the shear direction of a plane that carries no shear (_cpa_plane.fallback_shear)
    "wt",        # (M,) w_a / t
    "table",     # (_NG, _ROW) the three above
])
_G_N, _G_NN, _G_F = 0, 3, 9
_NG = 12

#: Rows of the workspace ``plane`` array (per-plane values at the current iterate). The first group
#: depends on the stress only (with the shear direction s of the plane, (_P_SX, _P_SY, _P_SZ)), the second
#: on the plane law.
(_P_ST, _P_RATIO, _P_INV_ST, _P_INV_T, _P_S_T, _P_DIL, _P_DWC, _P_SX, _P_SY, _P_SZ,
 _P_SLIP, _P_CB, _P_KP, _P_ETA, _P_ALPHA, _P_GAMMA) = range(16)
#: ... and one row that is constant during a point's solution: the inverse of the plane's shifted normal
#: stress at sigma_n, the unit of a strong plane's overstress in the traction form (:func:`evaluate`); set by
#: :func:`point_update`, never written by :func:`evaluate`.
_P_INV_ST0 = 16
_NP = 17
#: Rows of the workspace ``dirs`` array: m_a, b_a, Mandel(sym(s (x) n)), Mandel(sym(r (x) n)) (6 rows each).
_D_M, _D_B, _D_SN, _D_RN = 0, 6, 12, 18
_ND = 24
#: Size of the condensed Newton system: stress (6) and the cut-off's opening, and with the implicit
#: gradient the sum S of the slip increments of the planes past their peak.
_NSYS = 8

#: Rows of the workspace ``coef`` array: per-plane coefficients of the flow in R and in the Newton system.
_C_SS, _C_NS, _C_SN, _C_NN, _C_RR, _C_R, _C_RHS = range(7)

#: Scratch arrays of one thread (M planes), made by :func:`make_workspace`. Per-plane vectors are stored
#: plane-major, (6, M), so that the sums over planes run on contiguous rows; the arrays of per-plane rows
#: are _ROW long (their first M columns are used).
Work = namedtuple("Work", [
    "plane", "trial_plane",   # (_NP, _ROW) per-plane values (rows _P_*) at the iterate (and a line-search trial:
                              # :func:`_newton`) / scratch
    "dirs",                   # (_ND, _ROW) the next four (rows _D_*)
    "mvec", "bvec",           # (6, _ROW) flow vector m_a and b_a = d etah_a / d sigma
    "sn", "rn",               # (6, _ROW) Mandel(sym(s (x) n)), Mandel(sym(r (x) n)) of the shear pair (s, r)
    "coef",                   # (7, _ROW) coefficients (rows _C_*)
    "wg",                     # (_ROW,) scratch: w_a / t gamma_a of the gradient's column of S
    "dk", "dk_try", "dk_step", "dk_done",  # (M,) slip increments: iterate, trial, Newton step, last solution
    "eta_f", "deta_f", "shift",            # (M,) strengths, their slope in x_a, shift c_a / eta_f,a + c_apex
    "strong", "select",       # (M,) and (M + 1,) bool, see Point
    "floor",                  # (M,) see Point
    "floor0",                 # (M,) the floor of one relaxation time, mu (w/t) G / sigma~ at sigma_n
    "post",                   # (M,) bool, see Point
    "J", "J8",                # condensed Newton matrix (7, 7), and (_NSYS, _NSYS) with the gradient's unknown
                              # (two contiguous arrays: the LU on a 7 x 7 view of the larger one was 2-3 % slower)
    "rhs", "step", "piv",     # its right-hand side, step and pivots (_NSYS,) (the leading 7 without the gradient)
    "vecs",                   # (12, 6) small vectors (rows _V_*)
    "mats",                   # (2, 6, 6): d Lambda / d eps, induced correction T
    "tableau",                # (M + 1, 2 M + 4) Lemke's tableau of the rate problem (the planes and the cut-off)
    "basis",                  # (M + 1,) int: its basic variables
])
_V_R, _V_SIG, _V_SIG_TRY, _V_SIG_DONE, _V_LAM, _V_EPS, _V_DE, _V_ELL, _V_S0, _V_S1, _V_S2, _V_COL = range(12)
#: Modes of the recorded path (:func:`update_past_limits`): off; record the fractions :func:`point_update` tries
#: and their outcomes; read them (the perturbed continuations of the tangent past a limit point).
_PATH_OFF, _PATH_RECORD, _PATH_READ = 0, 1, 2
#: Capacity of the recorded path: fractions, and parts (a step past 16 limit points has 17; a part tries about
#: 20 fractions before it locates its limit). Past either, recording stops and nothing is skipped.
_PATH, _PATH_PARTS = 1024, 64
#: Layout of the recorded path, one array of a thread (its own argument of point_update: a field of Work
#: would add to every call that passes the workspace; measured, four arrays more in Work made
#: ``benchmarks/material_update.py`` 8 % slower): the mode, parts recorded, fractions recorded, the part
#: read next and the fraction read next (counts held as floats); from _PATH_END each part's end in the
#: fractions, from _PATH_LIMIT each part's limit (its end's fraction; 1: the part ended the step), from
#: _PATH_FRAC the fractions tried, negative where the solve failed.
_PATH_MODE, _PATH_NPARTS, _PATH_N, _PATH_RPART, _PATH_RPOS = range(5)
_PATH_END = 5
_PATH_LIMIT = _PATH_END + _PATH_PARTS
_PATH_FRAC = _PATH_LIMIT + _PATH_PARTS
_PATH_SIZE = _PATH_FRAC + _PATH
#: A continuation of the tangent skips a solve that failed in the unperturbed step at the same point of the
#: same sequence of fractions when the fraction lies beyond (1 + _BEYOND) times that part's limit: it fails
#: again. Measured on the footing's fold point: a perturbation of 1e-9 of the scale moves the limit by up to
#: 3.5 % (0.0387-0.0416 against 0.0401 of the increment), so 0.25 leaves a margin of seven. (A skipped solve
#: that would have converged could change only the tangent: the stress is the step's own continuation.)
_BEYOND = 0.25


@njit(cache=True, error_model="numpy")
def make_workspace(M):
    """Scratch arrays of one thread for :func:`point_update` (M planes)."""
    if M > _ROW:
        raise ValueError("more planes than the kernel's row length _ROW (material._cpa_local)")
    dirs = np.empty((_ND, _ROW))
    return Work(np.empty((_NP, _ROW)), np.empty((_NP, _ROW)), dirs, dirs[_D_M:_D_M + 6], dirs[_D_B:_D_B + 6],
                dirs[_D_SN:_D_SN + 6], dirs[_D_RN:_D_RN + 6], np.empty((7, _ROW)), np.empty(_ROW),
                np.empty(M), np.empty(M), np.empty(M),
                np.empty(M), np.empty(M), np.empty(M), np.empty(M),
                np.zeros(M, dtype=np.bool_), np.ones(M + 1, dtype=np.bool_), np.zeros(M), np.zeros(M),
                np.zeros(M, dtype=np.bool_),
                np.empty((7, 7)), np.empty((_NSYS, _NSYS)), np.empty(_NSYS), np.empty(_NSYS),
                np.empty(_NSYS, dtype=np.int64),
                np.empty((12, 6)), np.empty((2, 6, 6)),
                np.empty((M + 1, 2 * M + 4)), np.empty(M + 1, dtype=np.int64))


@njit(cache=True, error_model="numpy")
def make_path():
    """The recorded path of one thread (:data:`_PATH_MODE` ...), off."""
    return np.zeros(_PATH_SIZE)


@njit(cache=True, error_model="numpy")
def plane_data(law):
    """The per-plane constants of ``law`` in plane-major layout (:data:`PlaneData`)."""
    M = law.normals.shape[0]
    if M > _ROW:
        raise ValueError("more planes than the kernel's row length _ROW (material._cpa_local)")
    table = np.zeros((_NG, _ROW))
    normal, nn, fallback = table[_G_N:_G_N + 3], table[_G_NN:_G_NN + 6], table[_G_F:_G_F + 3]
    wt = np.empty(M)
    for a in range(M):
        n0, n1, n2 = law.normals[a, 0], law.normals[a, 1], law.normals[a, 2]
        normal[0, a], normal[1, a], normal[2, a] = n0, n1, n2
        fallback[0, a], fallback[1, a], fallback[2, a] = fallback_shear(n0, n1, n2)
        for i in range(6):
            nn[i, a] = law.nn6[a, i]
        wt[a] = law.weights[a] * law.inv_t
    return PlaneData(normal, nn, fallback, wt, table)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _lu_factor(A, piv):
    """In-place LU with partial pivoting of a small square matrix; returns False if singular. (The 7 x 7
    system of a point without the gradient is factorised by a copy of the loops whose size is a compile-time
    constant, which the compiler unrolls: the same operations in the same order, the same factors to the bit.
    Measured with :func:`_lu_solve` so: the update with the tangent of benchmarks/material_update.py's
    states, 1 thread, 1.10 times as fast.)"""
    if A.shape[0] == 7:
        return _lu_factor_n(A, piv, 7)
    return _lu_factor_n(A, piv, A.shape[0])


@njit(cache=True, inline="always", error_model="numpy")
def _lu_factor_n(A, piv, n):
    """:func:`_lu_factor` of the leading n x n block."""
    for k in range(n):
        p = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                p = i
        piv[k] = p
        if big == 0.0 or not np.isfinite(big):
            return False
        if p != k:
            for j in range(n):
                tmp = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = tmp
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            A[i, k] *= inv
            f = A[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
    return True


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _lu_solve(LU, piv, b):
    """Solve in place for one right-hand side (the 7 x 7 system unrolled, as :func:`_lu_factor`)."""
    if LU.shape[0] == 7:
        _lu_solve_n(LU, piv, b, 7)
    else:
        _lu_solve_n(LU, piv, b, LU.shape[0])


@njit(cache=True, inline="always", error_model="numpy")
def _lu_solve_n(LU, piv, b, n):
    """:func:`_lu_solve` with the leading n x n block."""
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= LU[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= LU[i, j] * b[j]
        b[i] = acc / LU[i, i]


#: A plane whose slip or overstress is below this (relative) is on its loading/unloading kink for the
#: choice of the generalised derivative (``Point.select``): a plane that loaded in the last step sits
#: exactly on its hardening curve at the start of the next (round-off aside). Only Newton directions
#: depend on this choice, never the equations or their solution.
_ON_CURVE = 1e-12


@njit(cache=True, error_model="numpy")
def _fb(u, v, loading):
    """Fischer-Burmeister function Phi(u, v) = u + v - sqrt(u^2 + v^2) and its (generalised) partial
    derivatives; at the kink (u, v) = (0, 0) (to round-off) the element (0, 1) of the generalised
    Jacobian (the loading branch) or (1, 0) (the elastic one)."""
    r = np.sqrt(u * u + v * v)
    if abs(u) <= _ON_CURVE and abs(v) <= _ON_CURVE:
        return u + v - r, (0.0, 1.0) if loading else (1.0, 0.0)
    return u + v - r, (1.0 - u / r, 1.0 - v / r)


@njit(cache=True, error_model="numpy")
def _min_branch(u, v, loading):
    """The minimum function min(u, v) of the same complementarity and its derivative: the active-set
    equation of the side the iterate is on, v = 0 where u > v (the pair loads), u = 0 where u < v (elastic);
    at a tie the branch ``loading`` chooses (:func:`_active_set_phase`)."""
    if u > v or (u == v and loading):
        return v, (0.0, 1.0)
    return u, (1.0, 0.0)


#: Floating-point freedoms of :func:`evaluate`: fused multiply-add and reassociated sums, which lets the
#: sums over planes vectorise (results change at round-off). No "nnan"/"ninf": the admissibility tests rely on
#: comparisons with NaN and inf.
_FAST = {"contract", "reassoc", "nsz", "arcp"}


@njit(cache=True, error_model="numpy", fastmath=_FAST, **NO_REFCOUNT)
def evaluate(law, pd, pt, sig, dk, dl, S, want_jac, active_set, plane, ws):
    """Residuals (and the condensed Newton system) at the iterate (sig, dk[strong], dl, S).

    Fills ``dk`` of the weak planes (their closed-form slip), ``plane`` (per-plane values, rows _P_*),
    ``ws.mvec``/``ws.bvec`` (flow vector m_a and b_a = d etah_a / d sigma of every plane), the strain
    residual ``ws.vecs[_V_R]``, and with ``want_jac`` the condensed Jacobian ``ws.J`` (7, 7; ``ws.J8``, 8 x 8,
    when ``pt.coupled``) and right-hand side ``ws.rhs`` of the Newton step. ``pd`` is :func:`plane_data` of
    ``law``. With ``active_set`` the complementarity of the strong planes and the cut-off is in the minimum
    function of :func:`_min_branch` instead of Fischer-Burmeister's (:func:`_active_set_phase`); the weak
    planes' are the same in both. Returns (admissible, merit, max |R|, max of |Phi_a| and of the gradient's
    |g_S| / A, |Phi_0|);
    an iterate is not admissible where a plane's shifted normal stress is not positive, a weak plane is at
    or past its barrier (without stabilisation), or a strong plane's kappa <= -A/2.

    The implicit gradient (``pt.coupled``; ``docs/regularisation.md``, section 3): a plane past its peak
    softens with kappa_hat = kappa_n + nl_shift_a + dkappa + c0 - m S, S = sum of the slip increments of those planes,
    with the equation g_S = S - sum dkappa = 0. Its slip's linearisation gains gamma_a dS, and S is the
    eighth unknown of the condensed system.

    Three passes over the planes: the stress measures and directions (they depend on the stress only),
    the plane law (slip, Fischer-Burmeister) with the coefficients of the plane's terms, and the sums of
    the terms into R and the Newton system over contiguous rows (these vectorise).
    """
    M = law.normals.shape[0]
    comp = law.comp
    A = law.A
    b_r = law.rounding
    R, rhs = ws.vecs[_V_R], ws.rhs
    J = ws.J8 if pt.coupled else ws.J
    for i in range(6):
        acc = -pt.de[i]
        for j in range(6):
            acc += comp[i, j] * (sig[j] - pt.sig_n[j])
        R[i] = acc + (dl / 3.0 if i < 3 else 0.0)
    nn, sn, rn, mv, bv = pd.nn, ws.sn, ws.rn, ws.mvec, ws.bvec
    p_c = law.compaction_stress
    eta_c = law.eta_c_ratio
    # 1. the planes' stress measures, shear direction s, then the pair (s, r = n x s), flow m (2.7) and
    # b = d etah / d sigma, in two loops over flat views of the plane-major arrays (rows _ROW apart, see
    # _ROW) that the compiler vectorises; the stress is read before the loop. (Measured: as one loop over the
    # planes that read the stress array and wrote 31 rows of 2-d arrays it ran scalar, at 58 % of this function's
    # time: the 2 square roots and 4 divisions of each plane, and its stores.)
    geo = pd.table.reshape(_NG * _ROW)
    pf = plane.reshape(_NP * _ROW)
    df = ws.dirs.reshape(_ND * _ROW)
    parts = tensor_parts(sig)
    for a in range(M):
        n0, n1, n2 = geo[_G_N * _ROW + a], geo[(_G_N + 1) * _ROW + a], geo[(_G_N + 2) * _ROW + a]
        sigma_t, tau, T, ts0, ts1, ts2 = measures_of_parts(parts, n0, n1, n2, pt.shift[a], b_r)
        inv_st = 1.0 / sigma_t
        inv_T = 1.0 / T
        ratio = T * inv_st  # mobilised ratio
        wc, dwc = compaction_weight(sigma_t, p_c)
        pf[_P_ST * _ROW + a] = sigma_t
        pf[_P_RATIO * _ROW + a] = ratio
        pf[_P_INV_ST * _ROW + a] = inv_st
        pf[_P_INV_T * _ROW + a] = inv_T
        pf[_P_S_T * _ROW + a] = tau * inv_T
        pf[_P_DIL * _ROW + a] = ratio - eta_c * pt.eta_f[a] * wc  # d psi / d sigma_N (2.17): < 0 compaction, > 0 dilation
        pf[_P_DWC * _ROW + a] = dwc
        s0, s1, s2, _, _, _ = shear_pair(n0, n1, n2, ts0, ts1, ts2, tau, geo[_G_F * _ROW + a],
                                         geo[(_G_F + 1) * _ROW + a], geo[(_G_F + 2) * _ROW + a])
        pf[_P_SX * _ROW + a], pf[_P_SY * _ROW + a], pf[_P_SZ * _ROW + a] = s0, s1, s2
    for a in range(M):
        n0, n1, n2 = geo[_G_N * _ROW + a], geo[(_G_N + 1) * _ROW + a], geo[(_G_N + 2) * _ROW + a]
        s0, s1, s2 = pf[_P_SX * _ROW + a], pf[_P_SY * _ROW + a], pf[_P_SZ * _ROW + a]
        r0, r1, r2 = n1 * s2 - n2 * s1, n2 * s0 - n0 * s2, n0 * s1 - n1 * s0  # r = n x s (shear_pair)
        sn_parts = sym_parts(s0, s1, s2, n0, n1, n2)
        rn_parts = sym_parts(r0, r1, r2, n0, n1, n2)
        s_t, dil = pf[_P_S_T * _ROW + a], pf[_P_DIL * _ROW + a]
        ratio, inv_st = pf[_P_RATIO * _ROW + a], pf[_P_INV_ST * _ROW + a]
        for i in range(6):
            nn_i = geo[(_G_NN + i) * _ROW + a]
            s_i = s_t * sn_parts[i]
            df[(_D_SN + i) * _ROW + a] = sn_parts[i]
            df[(_D_RN + i) * _ROW + a] = rn_parts[i]
            df[(_D_M + i) * _ROW + a] = s_i + dil * nn_i
            df[(_D_B + i) * _ROW + a] = (s_i + ratio * nn_i) * inv_st
    # 2. the plane law: admissibility, slip, the slip's linearisation d dkappa = alpha + cb b . d sigma,
    # and the coefficients of the plane's terms (rows _C_*)
    cf = ws.coef
    phi2 = 0.0
    phimax = 0.0
    post_slip = 0.0  # the gradient's sums over the planes past their peak: slips, alpha, gamma
    post_alpha = 0.0
    post_gamma = 0.0
    for a in range(M):
        sigma_t = plane[_P_ST, a]
        if not sigma_t > 0.0:
            return False, np.inf, np.inf, np.inf, np.inf
        ratio = plane[_P_RATIO, a]
        ef = pt.eta_f[a]
        kn = pt.kap_n[a]
        h = pt.floor[a]  # the step stabilisation's floor: g = etah - eta(kappa) - h dkappa
        cb = 0.0
        alpha = 0.0
        gamma = 0.0
        kp = 0.0
        if pt.strong[a]:
            k = kn + dk[a]
            if k <= -0.5 * A:
                return False, np.inf, np.inf, np.inf, np.inf
            coupled = pt.coupled and pt.post[a]
            if coupled:  # the gradient's shift, on the (continued) softening branch
                eta, deta = softening_branch(k + pt.nl_shift[a] + pt.c0 - pt.m_over * S, ef, law.kstar, pt.soft,
                                             law.residual)
            else:
                eta, deta = hardening(k, ef, law.zeta, A, law.kstar, pt.soft, law.residual)  # (2.16)
            # the overstress in the traction form, (sigma~ (eta + h dkappa) - T) / sigma~_n, over the scale
            # sv = 1 + h A (1, or the floor's share over a slip A where it is larger)
            sv = 1.0 + h * A
            sc = sigma_t * plane[_P_INV_ST0, a] / sv
            level = eta + h * dk[a]
            if active_set:
                phi, (pu, pv) = _min_branch(dk[a] / A, sc * (level - ratio), pt.select[a])
            else:
                phi, (pu, pv) = _fb(dk[a] / A, sc * (level - ratio), pt.select[a])
            pv = pv * sc
            phi2 += phi * phi
            phimax = max(phimax, abs(phi))
            slip = dk[a]
            den = pu / A + pv * (deta + h)
            if abs(den) < 1e-300:
                den = 1e-300
            alpha = -phi / den  # d dkappa = alpha + cb b . d sigma + gamma d S
            cb = pv / den
            if coupled:
                gamma = pv * pt.m_over * deta / den
                post_slip += slip
                post_alpha += alpha
                post_gamma += gamma
        else:
            level = ratio  # (a weak plane's equation is in the ratio: its slip is a function of the stress)
            if h == 0.0 and not ratio < ratio_barrier(ef, law.zeta, pt.soft) * (1.0 - 1e-12):
                return False, np.inf, np.inf, np.inf, np.inf
            slip, kp, eta = slip_of_ratio(ratio, kn, ef, law.zeta, A, h * A)  # (2.16) inverted
            on_kink = abs(slip) <= _ON_CURVE * (A + kn)
            if slip < 0.0 or (on_kink and not pt.select[a]):
                # elastic: below its curve, or on its kink with the elastic branch chosen. A plane that loaded
                # in the last step sits on its kink at sigma_n with a slip of round-off size and either sign:
                # it takes the chosen branch, value and derivative alike (measured: with its round-off slip
                # positive it kept the loading derivative against the rate problem's choice, the Newton
                # direction did not descend, and a footing point at 0.3 kPa failed for every fraction of its
                # step)
                slip = 0.0
                if not on_kink or not pt.select[a]:
                    kp = 0.0
            dk[a] = slip
            cb = kp
        plane[_P_SLIP, a] = slip
        plane[_P_CB, a] = cb
        plane[_P_KP, a] = kp
        plane[_P_ETA, a] = eta
        plane[_P_ALPHA, a] = alpha
        plane[_P_GAMMA, a] = gamma
        # the plane's terms in R (2.9) and the Newton system, in the span of sn, rn, nn:
        # J += wt [slip d m / d sigma + cb m (x) b'], b' = (s_t sn + level nn) / sigma~ the derivative of the
        # plane's equation in the stress (b = d etah / d sigma for a weak plane, level = etah; in the traction
        # form of a strong plane level = eta + h dkappa, and b' = b at its solution where it loads),
        # d m / d sigma = ((b_r / T)^2 sn (x) sn + rn (x) rn) / T (the slip direction turning)
        #                 + nn (x) (b + eta_c w' nn)
        wt = pd.wt[a] if (slip != 0.0 or cb != 0.0) else 0.0  # an elastic plane: no flow, no terms
        inv_st = plane[_P_INV_ST, a]
        inv_T = plane[_P_INV_T, a]
        s_t = plane[_P_S_T, a]
        f_s = cb * s_t  # coefficient of sn in (slip nn + cb m)
        f_n = slip + cb * plane[_P_DIL, a]  # of nn
        cf[_C_SS, a] = wt * (slip * b_r * b_r * inv_T * inv_T * inv_T + f_s * s_t * inv_st)
        cf[_C_NS, a] = wt * f_n * s_t * inv_st
        cf[_C_SN, a] = wt * f_s * level * inv_st
        cf[_C_NN, a] = wt * ((slip * ratio + cb * plane[_P_DIL, a] * level) * inv_st
                             + slip * eta_c * ef * plane[_P_DWC, a])
        cf[_C_RR, a] = wt * slip * inv_T
        cf[_C_R, a] = wt * slip
        cf[_C_RHS, a] = wt * alpha
    # 3. the sums of the planes' terms
    c_r, c_rhs = cf[_C_R], cf[_C_RHS]
    for i in range(6):
        m_i = mv[i]
        acc = 0.0
        acc_h = 0.0
        for a in range(M):
            acc += c_r[a] * m_i[a]
            acc_h += c_rhs[a] * m_i[a]
        R[i] += acc
        rhs[i] = -acc_h
    if want_jac:
        c_ss, c_ns, c_sn, c_nn, c_rr = cf[_C_SS], cf[_C_NS], cf[_C_SN], cf[_C_NN], cf[_C_RR]
        for i in range(7):
            for j in range(7):
                J[i, j] = comp[i, j] if (i < 6 and j < 6) else 0.0
        for i in range(3):
            J[i, 6] = 1.0 / 3.0
        # row i of the sums, its six entries in one pass over the planes (a loop of reductions without stores,
        # which vectorises; measured: one pass per entry, over (u, v, z) rows stored first, took 40 % of this
        # function's time)
        for i in range(6):
            sn_i, nn_i, rn_i = sn[i], nn[i], rn[i]
            j0 = j1 = j2 = j3 = j4 = j5 = 0.0
            for a in range(M):
                u = c_ss[a] * sn_i[a] + c_ns[a] * nn_i[a]  # (.) (x) sn
                v = c_sn[a] * sn_i[a] + c_nn[a] * nn_i[a]  # (.) (x) nn
                z = c_rr[a] * rn_i[a]                      # (.) (x) rn
                j0 += u * sn[0, a] + v * nn[0, a] + z * rn[0, a]
                j1 += u * sn[1, a] + v * nn[1, a] + z * rn[1, a]
                j2 += u * sn[2, a] + v * nn[2, a] + z * rn[2, a]
                j3 += u * sn[3, a] + v * nn[3, a] + z * rn[3, a]
                j4 += u * sn[4, a] + v * nn[4, a] + z * rn[4, a]
                j5 += u * sn[5, a] + v * nn[5, a] + z * rn[5, a]
            J[i, 0] += j0
            J[i, 1] += j1
            J[i, 2] += j2
            J[i, 3] += j3
            J[i, 4] += j4
            J[i, 5] += j5
    # mean-stress cut-off
    p = (sig[0] + sig[1] + sig[2]) / 3.0
    if active_set:
        phi0, (pu0, pv0) = _min_branch(dl, -p / law.bulk, pt.select[M])
    else:
        phi0, (pu0, pv0) = _fb(dl, -p / law.bulk, pt.select[M])
    rmax = 0.0
    rn2 = 0.0
    for i in range(6):
        rmax = max(rmax, abs(R[i]))
        rn2 += R[i] * R[i]
    if want_jac:
        for i in range(3):
            J[6, i] = -pv0 / (3.0 * law.bulk)
        J[6, 6] = pu0
        for i in range(6):
            rhs[i] -= R[i]
        rhs[6] = -phi0
    if pt.coupled:
        g_s = S - post_slip
        phi2 += (g_s / A) ** 2
        phimax = max(phimax, abs(g_s) / A)
        if want_jac:  # the column of S in R, and the row of g_S: dS - sum (alpha + cb b . d sigma + gamma dS)
            wg = ws.wg
            gam = plane[_P_GAMMA]
            for a in range(M):
                wg[a] = pd.wt[a] * gam[a]
            for i in range(6):
                acc = 0.0
                acc_b = 0.0
                for a in range(M):
                    acc += wg[a] * mv[i, a]
                    if pt.post[a]:  # (b' of the traction form, see _newton)
                        acc_b += plane[_P_CB, a] * (bv[i, a] + _level_shift(plane, pt, dk, a) * nn[i, a])
                J[i, 7] = acc
                J[7, i] = -acc_b
            J[6, 7] = 0.0
            J[7, 6] = 0.0
            J[7, 7] = 1.0 - post_gamma
            rhs[7] = -g_s + post_alpha
    merit = 0.5 * (rn2 / (pt.r_scale * pt.r_scale) + phi2 + (phi0 / pt.r_scale) ** 2)
    return True, merit, rmax, phimax, abs(phi0)


@njit(cache=True, error_model="numpy", fastmath=_FAST, **NO_REFCOUNT)
def inverse_shifted_normal_stress(sig, pd, shift, least, out, M):
    """out[a] = 1 / max(sigma~_a, least) at the stress ``sig``: sigma~_a = -n_a . sig . n_a + shift_a."""
    geo = pd.table.reshape(_NG * _ROW)
    nn = _G_NN * _ROW
    s0, s1, s2 = sig[0], sig[1], sig[2]
    s3, s4, s5 = sig[3], sig[4], sig[5]
    for a in range(M):
        sn = (s0 * geo[nn + a] + s1 * geo[nn + _ROW + a] + s2 * geo[nn + 2 * _ROW + a] + s3 * geo[nn + 3 * _ROW + a]
              + s4 * geo[nn + 4 * _ROW + a] + s5 * geo[nn + 5 * _ROW + a])
        out[a] = 1.0 / max(shift[a] - sn, least)


@njit(cache=True, inline="always", error_model="numpy")
def _level_shift(plane, pt, dk, a):
    """(eta + h dkappa - etah) / sigma~ of a strong plane at the iterate: b' - b = this times Mandel(n n), where
    b' is the derivative in the stress of its equation's traction form and b = d etah / d sigma (the rows of
    ``ws.bvec``); 0 at a solution where the plane loads."""
    return (plane[_P_ETA, a] + pt.floor[a] * dk[a] - plane[_P_RATIO, a]) * plane[_P_INV_ST, a]


#: The active-set phase (:func:`_active_set_phase`): its full Newton steps at most, how often one solve may
#: start it, and after how many cut steps in a row. Measured on the stored points of the tests (the footing's
#: apex, cut-off and edge points; the overstressed point of the stiff sand's footing with the step
#: stabilisation) and on 23 failure files of the isotropic footing: with 3 steps the apex and cut-off points
#: took 45-62 iterations instead of 9-13; with 6 the overstressed point took 62-80 at one relaxation time
#: instead of 11; starting after 3 cut steps instead of 2 changed little.
_PHASE_STEPS = 4
_PHASES = 2
_PHASE_AFTER = 2


@njit(cache=True, inline="always", error_model="numpy")
def _converged(opt, pt, rmax, phimax, phi0, floor):
    """The local solver's convergence test (the residuals of Fischer-Burmeister's form)."""
    return rmax <= opt.tol * pt.r_scale + floor and phimax <= opt.tol and phi0 <= opt.tol * pt.r_scale + floor


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _newton_step(pd, pt, dk, J, piv, n, ws):
    """The Newton step of the condensed system whose LU factors are ``J``: (stress, opening[, S]) into
    ``ws.step`` and the strong planes' slip steps into ``ws.dk_step``, from ``ws.plane`` of the iterate."""
    step, plane = ws.step[:n], ws.plane
    for i in range(n):
        step[i] = ws.rhs[i]
    _lu_solve(J, piv, step)
    d_s = step[7] if pt.coupled else 0.0
    for a in range(pt.kap_n.shape[0]):
        if pt.strong[a]:
            acc = 0.0
            accn = 0.0
            for j in range(6):
                acc += ws.bvec[j, a] * step[j]
                accn += pd.nn[j, a] * step[j]
            acc += _level_shift(plane, pt, dk, a) * accn  # b' = b + (level - etah) nn / sigma~ (evaluate)
            ws.dk_step[a] = plane[_P_ALPHA, a] + plane[_P_CB, a] * acc + plane[_P_GAMMA, a] * d_s
    return d_s


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _active_set_phase(law, pd, opt, pt, sig, dk, dl, S, merit0, floor, ws):
    """Full Newton steps on the minimum function from the iterate (sig, dk, dl, S): the active-set Newton
    (primal-dual active set) of the complementarity, each step the one of the smooth equations of the side
    every strong plane and the cut-off are on (:func:`_min_branch`), with no line search. Returns
    (converged, steps, dl, S): on convergence (the test of Fischer-Burmeister's form, :func:`_converged`)
    the solution, with ``ws.J`` the Jacobian of :func:`evaluate` there (not yet factored); otherwise the last
    iterate if its merit is below ``merit0`` (the merit where the phase started), or else the iterate given,
    restored; then ``ws.plane`` and ``ws.J`` are stale.

    Why. Fischer-Burmeister's Newton converges superlinearly where the solution is strictly complementary,
    and creeps where it is not: at a plane whose slip and overstress both vanish at the solution, each
    Newton step carries the slip past 0 and the line search cuts it (measured: a point of the isotropic
    footing at p = 0 with 48 loading planes, nearly perfectly plastic, kappa up to 590 A,
    tests/material/data/footing_apex_point.npz: all-loading or the rate problem's set, the merit fell by
    about 0.9 an iteration at step lengths 2^-3 ... 2^-14, Phi stalled at 2e-8 after 25 iterations, and the
    point failed for every fraction of its increment; the reference's Newton on the same equations needed
    37 iterations). The minimum function's step puts each plane on the side it is on, so it drops such a
    plane at once: the point converges in 8 iterations. The minimum function has no smooth merit, so the
    steps are taken as they come (a watchdog: the merit may rise on the way; taking only steps that lower it
    lost the gain, the stored points then took 39-66 iterations instead of 9-13). After
    :data:`_PHASE_STEPS` steps Fischer-Burmeister's Newton goes on from the last iterate if its merit is
    below the phase's start (measured on the overstressed point of the stiff sand's footing with the step
    stabilisation, one relaxation time: 11 iterations, against 41 without the phase and 73 with the phase
    always restoring its start), else from the start, as it does after an inadmissible iterate."""
    n = _NSYS if pt.coupled else 7
    J, piv = (ws.J8 if pt.coupled else ws.J), ws.piv[:n]
    M = pt.kap_n.shape[0]
    save_sig, save_dk = ws.vecs[_V_S0], ws.trial_plane[0]
    for i in range(6):
        save_sig[i] = sig[i]
    for a in range(M):
        save_dk[a] = dk[a]
    dl0, s0 = dl, S
    steps = 0
    while steps < _PHASE_STEPS:
        ok = evaluate(law, pd, pt, sig, dk, dl, S, True, True, ws.plane, ws)[0]
        if not ok or not _lu_factor(J, piv):
            break
        d_s = _newton_step(pd, pt, dk, J, piv, n, ws)
        steps += 1
        for i in range(6):
            sig[i] += ws.step[i]
        for a in range(M):
            if pt.strong[a]:
                dk[a] += ws.dk_step[a]
        dl += ws.step[6]
        S += d_s
        ok, merit, rmax, phimax, phi0 = evaluate(law, pd, pt, sig, dk, dl, S, True, False, ws.plane, ws)
        if not ok:
            break
        if _converged(opt, pt, rmax, phimax, phi0, floor):
            return True, steps, dl, S
        if steps == _PHASE_STEPS and merit < merit0:
            return False, steps, dl, S  # (not converged, the merit below the start: Fischer-Burmeister goes on)
    for i in range(6):
        sig[i] = save_sig[i]
    for a in range(M):
        dk[a] = save_dk[a]
    return False, steps, dl0, s0


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _newton(law, pd, opt, pt, sig, dk, dl_in, S_in, ws):
    """Semismooth Newton with a backtracking line search on the merit function, from (sig, dk, dl_in, S_in).
    After an iteration whose full step the line search cut, the active-set phase (:func:`_active_set_phase`)
    is tried from the iterate, at most :data:`_PHASES` times.

    Returns (converged, iterations, dl, S). On convergence ws.J holds the LU factors of the condensed
    Jacobian at the solution, and sig, dk, ws.plane, ws.mvec, ws.bvec the solution."""
    n = _NSYS if pt.coupled else 7
    plane = ws.plane
    J, step, piv = (ws.J8 if pt.coupled else ws.J), ws.step[:n], ws.piv[:n]
    dk_try, dk_step = ws.dk_try, ws.dk_step
    strong = pt.strong
    M = pt.kap_n.shape[0]
    sig_try = ws.vecs[_V_SIG_TRY]
    floor = 0.0
    for i in range(6):
        floor = max(floor, abs(pt.sig_n[i]), abs(sig[i]))
    cmax = 0.0
    for i in range(6):
        cmax = max(cmax, abs(law.comp[i, i]))
    floor = 1e-14 * floor * cmax  # round-off of S (sigma - sigma_n)
    dl = dl_in
    S = S_in
    ok, merit, rmax, phimax, phi0 = evaluate(law, pd, pt, sig, dk, dl, S, True, False, plane, ws)
    if not ok:
        return False, 0, dl, S
    phases = _PHASES
    cuts = 0  # the last steps in a row that were shorter than Newton's
    extra = 0  # the active-set phases' steps
    for it in range(opt.maxit + 1):
        if _converged(opt, pt, rmax, phimax, phi0, floor):
            return _lu_factor(J, piv), it + extra, dl, S
        if cuts >= _PHASE_AFTER and phases > 0 and it < opt.maxit:
            phases -= 1
            done, steps, dl, S = _active_set_phase(law, pd, opt, pt, sig, dk, dl, S, merit, floor, ws)
            extra += steps
            if done:
                return _lu_factor(J, piv), it + extra, dl, S
            # (the iterate's J, rhs, plane again)
            ok, merit, rmax, phimax, phi0 = evaluate(law, pd, pt, sig, dk, dl, S, True, False, plane, ws)
        if it == opt.maxit or not _lu_factor(J, piv):
            return False, it + extra, dl, S
        d_s = _newton_step(pd, pt, dk, J, piv, n, ws)
        alpha = 1.0
        accepted = False
        for _ls in range(40):
            for i in range(6):
                sig_try[i] = sig[i] + alpha * step[i]
            for a in range(M):
                dk_try[a] = dk[a] + alpha * dk_step[a] if strong[a] else 0.0
            dl_try = dl + alpha * step[6]
            s_try = S + alpha * d_s
            # the trial is evaluated into ``plane`` itself: once the Newton step and dk_step are formed nothing
            # reads the iterate's per-plane values again (a rejected trial is evaluated anew, and a failed search
            # returns unconverged), so the accepted trial's 16 rows need no copy (measured: without the copy the
            # update with the tangent of benchmarks/material_update.py's states, 1 thread, 1.13 times as fast)
            ok2, merit2, rmax2, phimax2, phi02 = evaluate(law, pd, pt, sig_try, dk_try, dl_try, s_try, True, False,
                                                          plane, ws)
            if ok2 and merit2 <= (1.0 - 1e-4 * alpha) * merit:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            return False, it + extra, dl, S
        cuts = cuts + 1 if alpha < 1.0 else 0
        for i in range(6):
            sig[i] = sig_try[i]
        for a in range(M):
            dk[a] = dk_try[a]
        dl = dl_try
        S = s_try
        merit, rmax, phimax, phi0 = merit2, rmax2, phimax2, phi02
    return False, opt.maxit + extra, dl, S


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _ratios(law, sig, shift, out):
    """Mobilised ratio etah_a of every plane at ``sig`` into ``out`` (inf where sigma~ <= 0)."""
    for a in range(law.normals.shape[0]):
        sigma_t, tau, T, _, _, _ = plane_stress(sig, law.normals[a], shift[a], law.rounding)
        out[a] = T / sigma_t if sigma_t > 0.0 else np.inf


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _is_elastic(law, trial, kap_n, soft, eta_f, shift, post, c0, nl_shift):
    """The elastic trial is the solution: no mean tension, no plane above its reached level (stops at the
    first plane that loads; a plane ``post`` past its peak under the implicit gradient has its level at the
    shifted slip kappa_n + nl_shift + c0)."""
    if trial[0] + trial[1] + trial[2] > 0.0:
        return False
    for a in range(kap_n.shape[0]):
        sigma_t, tau, T, _, _, _ = plane_stress(trial, law.normals[a], shift[a], law.rounding)
        eta = _level(law, kap_n[a], eta_f[a], soft, post[a], nl_shift[a] + c0)[0]
        if not (sigma_t > 0.0 and T <= sigma_t * eta):
            return False
    return True


@njit(cache=True, inline="always", error_model="numpy")
def _level(law, kappa_n, eta_f, soft, post, c0):
    """The hardening level eta and its slope of a plane at the start of the step: (2.16) at kappa_n, or for a
    plane past its peak under the implicit gradient the softening branch at kappa_n + c0."""
    if post:
        return softening_branch(kappa_n + c0, eta_f, law.kstar, soft, law.residual)
    return hardening(kappa_n, eta_f, law.zeta, law.A, law.kstar, soft, law.residual)


@njit(cache=True, error_model="numpy")
def _lemke(tab, basis, n, maxpivots):
    """Lemke's complementary pivoting for the LCP w = M z + q >= 0, z >= 0, z . w = 0 (n variables).

    ``tab`` (n, 2n + 2) holds [I | -M | -1 | q] on entry (columns: w_0..w_n-1, z_0..z_n-1, z_0art, rhs),
    ``basis`` receives the basic variables. Returns True on a solution (z_i = rhs of the row where z_i
    is basic), False on a ray termination or too many pivots (no solution found)."""
    art = 2 * n
    rhs_col = 2 * n + 1
    for i in range(n):
        basis[i] = i  # w basic
    r = 0
    qmin = tab[0, rhs_col]
    for i in range(1, n):
        if tab[i, rhs_col] < qmin:
            qmin = tab[i, rhs_col]
            r = i
    if qmin >= 0.0:
        return True  # z = 0
    entering = art
    for _ in range(maxpivots):
        # pivot on (r, entering)
        pv = tab[r, entering]
        for j in range(2 * n + 2):
            tab[r, j] /= pv
        for i in range(n):
            if i != r:
                f = tab[i, entering]
                if f != 0.0:
                    for j in range(2 * n + 2):
                        tab[i, j] -= f * tab[r, j]
        leaving = basis[r]
        basis[r] = entering
        if leaving == art:
            return True
        entering = leaving + n if leaving < n else leaving - n  # the complement of the leaving variable
        # ratio test: rows with a positive entry in the entering column
        r = -1
        best = np.inf
        for i in range(n):
            c = tab[i, entering]
            if c > 1e-12:
                ratio = tab[i, rhs_col] / c
                if ratio < best - 1e-14 or (abs(ratio - best) <= 1e-14 and basis[i] == art):
                    best = ratio
                    r = i
        if r < 0:
            return False  # ray termination
    return False


#: A plane is on its hardening curve at sigma_n for the rate problem when its mobilised ratio lies within this
#: (relative) of its level, and the cut-off is on when -p / K lies within this times the point's strain scale.
#: It must not be tighter than the local solver's tolerance: a plane that loaded in the last step ends it with
#: |sigma~ (eta - etah) / sigma~_n| <= tol (1e-12), so its gap eta - etah is up to tol sigma~_n / sigma~ where
#: sigma~ fell within the step (measured: 1.6e-12 on the edge point of the isotropic footing stored as
#: tests/material/data/footing_edge_vertex_point.npz; a test at 1e-12 left that plane out, the first Newton
#: step overstressed it and the point failed for every fraction of its increment). A plane 1e-9 below its
#: curve that the rate problem wrongly counts as on it loses nothing: the choice only sets the branch of a
#: plane on its kink (:data:`_ON_CURVE`), and the equations are those of the plane.
_RATE_ON_CURVE = 1e-9


@njit(cache=True, error_model="numpy")
def _rate_coupling(law, pt, ws, on, with_floor, cutoff):
    """The coupling matrix of the rate problem at sigma_n: fills ``on`` with the n planes on their hardening
    curve, ``ws.bvec``/``ws.mvec`` of those planes at sigma_n, and Lemke's tableau (:func:`_lemke`) of the
    problem of size nn = n (+ 1 with ``cutoff``: the mean-stress cut-off as the last unknown) in its columns
    nn..2nn-1 with -H: H_ab = (w_b / t) b_a . C m_b + (eta'_a + floor_a) delta_ab (``with_floor``: the step
    stabilisation's floor ``pt.floor`` included). Returns n.

    The planes on their curve load at rates x >= 0; their overstress rates are q - H x with
    q_a = b_a . C d_eps (the elastic rate of etah_a): H decides whether the rate problem has one solution
    for every q (H a P-matrix) or several. With ``cutoff`` the cut-off opens at the rate x_0 >= 0 (its plastic
    volumetric strain rate) with the rate of -p / K, w_0 = -(c . d_eps - c . i x_0 / 3 - sum_b (w_b / t) c . m_b
    x_b) / K >= 0 (c = C i / 3, i = (1, 1, 1, 0, 0, 0); c = K i for isotropic elasticity), and its opening
    lowers each plane's overstress rate by (b_a . c) x_0: H_a0 = b_a . c.
    """
    M = pt.kap_n.shape[0]
    n = 0
    sig = pt.sig_n
    hard = ws.dk_try  # eta' of each plane on its curve (scratch)
    sn6, rn6 = ws.vecs[_V_S1], ws.vecs[_V_S2]
    for a in range(M):
        sigma_t, tau, T, ts0, ts1, ts2 = plane_stress(sig, law.normals[a], pt.shift[a], law.rounding)
        plane_directions(law.normals[a], ts0, ts1, ts2, tau, sn6, rn6)
        ratio = T / sigma_t
        eta, deta = _level(law, pt.kap_n[a], pt.eta_f[a], pt.soft, pt.coupled and pt.post[a],
                           pt.nl_shift[a] + pt.c0)
        if sigma_t > 0.0 and ratio >= eta - _RATE_ON_CURVE * (1.0 + eta):
            on[n] = a
            n += 1
            hard[a] = deta + (pt.floor[a] if with_floor else 0.0)
            # m and b at sigma_n
            s_t = tau / T
            wc, _ = compaction_weight(sigma_t, law.compaction_stress)
            dil = ratio - law.eta_c_ratio * pt.eta_f[a] * wc
            for i in range(6):
                s_i = s_t * sn6[i]
                ws.bvec[i, a] = (s_i + ratio * law.nn6[a, i]) / sigma_t
                ws.mvec[i, a] = s_i + dil * law.nn6[a, i]
    nn = n + 1 if cutoff else n
    tab = ws.tableau
    cm = ws.vecs[_V_COL]  # C m_b
    ci = ws.vecs[_V_S1]  # c = C i / 3 (the stress rate of a unit volumetric strain rate, over 3)
    for i in range(6):
        ci[i] = (law.stiff[i, 0] + law.stiff[i, 1] + law.stiff[i, 2]) / 3.0
    for jb in range(n):
        bpl = on[jb]
        for i in range(6):
            acc = 0.0
            for j in range(6):
                acc += law.stiff[i, j] * ws.mvec[j, bpl]
            cm[i] = acc
        wt = law.weights[bpl] * law.inv_t
        for ia in range(n):
            apl = on[ia]
            acc = 0.0
            for i in range(6):
                acc += ws.bvec[i, apl] * cm[i]
            h = wt * acc + (hard[apl] if ia == jb else 0.0)
            tab[ia, nn + jb] = -h  # the tableau holds -M (M = H)
        if cutoff:
            acc = 0.0
            for i in range(6):
                acc += ci[i] * ws.mvec[i, bpl]
            tab[n, nn + jb] = -wt * acc / law.bulk
    if cutoff:
        for ia in range(n):
            acc = 0.0
            for i in range(6):
                acc += ws.bvec[i, on[ia]] * ci[i]
            tab[ia, nn + n] = -acc
        tab[n, nn + n] = -(ci[0] + ci[1] + ci[2]) / (3.0 * law.bulk)
    return n


@njit(cache=True, error_model="numpy", **REFCOUNT)
def _rate_active_set(law, pt, ws):
    """Choose the branch of every plane on its kink at sigma_n, and of the mean-stress cut-off, by the rate
    problem (sets ``pt.select``).

    The planes on their hardening curve at sigma_n load at rates x >= 0 with the rates of their
    overstress g_dot = q - H x <= 0 and x . g_dot = 0 (:func:`_rate_coupling`); where the cut-off is on at
    sigma_n (p within :data:`_RATE_ON_CURVE` of 0) its opening rate is one more unknown of the same kind
    (measured: a point of the isotropic footing at p = 0 with 28 planes on their curves; left out, the rate
    problem chose the elastic branch for 12 of them because the increment's volumetric part would have put
    the point into mean tension, the first Newton step overstressed them and the point failed for every
    fraction of its increment). Solved by Lemke's method; where it finds no solution the choice stays the
    loading branch for all. Returns whether a solution was found. (The implicit gradient's coupling of the
    planes past their peak through S is left out: the choice only supplies the starting branches.)
    """
    M = pt.kap_n.shape[0]
    sig = pt.sig_n
    cutoff = -(sig[0] + sig[1] + sig[2]) / (3.0 * law.bulk) <= _RATE_ON_CURVE * pt.r_scale
    on = np.empty(M, dtype=np.int64)
    n = _rate_coupling(law, pt, ws, on, True, cutoff)
    for a in range(M):
        pt.select[a] = False
    pt.select[M] = not cutoff  # (off its kink the cut-off's choice is never read)
    nn = n + 1 if cutoff else n
    if nn == 0:
        return True
    tab = ws.tableau
    cde = ws.vecs[_V_S0]  # C d_eps
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += law.stiff[i, j] * pt.de[j]
        cde[i] = acc
    for ia in range(nn):
        for j in range(nn):
            tab[ia, j] = 1.0 if j == ia else 0.0
        tab[ia, 2 * nn] = -1.0
        acc = 0.0
        if ia < n:
            for i in range(6):
                acc += ws.bvec[i, on[ia]] * cde[i]
        else:  # the cut-off: q_0 = c . d_eps / K = (C d_eps) . i / (3 K)
            acc = (cde[0] + cde[1] + cde[2]) / (3.0 * law.bulk)
        tab[ia, 2 * nn + 1] = -acc  # q of the LCP is -q
        # (columns beyond 2nn + 1 unused)
    # q over its largest entry: the complementary set is unchanged, and so independent of the increment's size
    # (measured on the footing's point at p = 0 stored as tests/material/data/footing_cutoff_point.npz: without
    # it, Lemke's absolute tolerances chose another set for the increment scaled by 1e-4 than for the
    # increment, the cut-off closed where it opens, and the point failed)
    qmax = 0.0
    for ia in range(nn):
        qmax = max(qmax, abs(tab[ia, 2 * nn + 1]))
    if qmax > 0.0:
        for ia in range(nn):
            tab[ia, 2 * nn + 1] /= qmax
    found = _lemke(tab[:nn, :2 * nn + 2], ws.basis[:nn], nn, 4 * nn + 10)
    if not found:
        for ia in range(n):
            pt.select[on[ia]] = True
        pt.select[M] = True
        return False
    for i in range(nn):
        v = ws.basis[i]
        if nn <= v < 2 * nn and tab[i, 2 * nn + 1] > 0.0:
            if v - nn < n:
                pt.select[on[v - nn]] = True
            else:
                pt.select[M] = True
    return True


#: The minimal stabilisation takes its bound on mu this much larger: the bound makes the symmetric part of
#: the scaled coupling positive semi-definite only, and the coupling moves with the stress within the step.
#: (At the near-failure point of the tests the bound is 0.075 and the coupling becomes a P-matrix between
#: mu = 0.04 and 0.06: the bound itself is conservative there.)
_FLOOR_MARGIN = 1.1


@njit(cache=True, error_model="numpy")
def _cholesky_succeeds(S):
    """Whether the symmetric matrix S is positive definite: its Cholesky factorisation, in place (the factor
    overwrites the lower triangle and the diagonal of S)."""
    n = S.shape[0]
    for j in range(n):
        acc = S[j, j]
        for k in range(j):
            acc -= S[j, k] * S[j, k]
        if not acc > 0.0:
            return False
        ljj = np.sqrt(acc)
        S[j, j] = ljj
        for i in range(j + 1, n):
            acc = S[i, j]
            for k in range(j):
                acc -= S[i, k] * S[j, k]
            S[i, j] = acc / ljj
    return True


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def floor_units(law, inv_st, out, M):
    """The step stabilisation's floor of every plane per unit mu, into ``out``: its elastic self-coupling
    (w_a / t) G / sigma~_a [1/m] at the start-of-step stress, given ``inv_st`` = 1 / max(sigma~_a, apex stress)
    (:func:`inverse_shifted_normal_stress`; ``docs/cpa_law.md``, section 3)."""
    g_mod = 0.5 / law.comp[5, 5]  # shear modulus (the Mandel compliance of a shear is 1 / (2 G))
    for a in range(M):
        out[a] = law.weights[a] * law.inv_t * g_mod * inv_st[a]


@njit(cache=True, error_model="numpy", **REFCOUNT)
def _uniqueness_floor(law, pt, ws, unit):
    """The least mu of the step stabilisation for which the rate problem at sigma_n is uniquely solvable, by
    a sufficient condition (the ``"minimal"`` stabilisation; ``docs/cpa_law.md``, section 4).

    With the floor mu unit_a (``unit`` (M,): the plane's elastic self-coupling (w_a / t) G / sigma~_a) the
    coupling matrix of the planes on their curve is H + mu U. A matrix whose rows, scaled by positive
    numbers d_a, give a positive definite symmetric part is a P-matrix: its rate problem has one solution
    for every strain rate (Cottle, Pang & Stone 1992, 3.3). With d_a = w_a sigma~_a the scaled elastic
    coupling is (w_a w_b / t) m_a . C (sigma~_b b_b): symmetric positive semi-definite for associated flow
    (m = sigma~ b), so only the non-associated part and the hardening decide. (Without the row scaling the
    rows of planes near their apex, b_a ~ 1 / sigma~_a, dominate: measured on a footing point at 0.1 kPa,
    a bound of 1e13 against none needed with it.) So H + mu U is a P-matrix for
    mu > -lambda_min, lambda_min the least eigenvalue of F^-1/2 sym(D H) F^-1/2, D = diag(d), F = D U.
    Returns _FLOOR_MARGIN max(0, -lambda_min): 0 where the thesis's law is uniquely solvable at the point.
    """
    on = ws.basis  # (scratch: Lemke's basis is not in use)
    n = _rate_coupling(law, pt, ws, on, False, False)
    if n == 0:
        return 0.0
    tab = ws.tableau
    d, f = ws.trial_plane[0], ws.trial_plane[1]  # (scratch)
    for ia in range(n):
        a = on[ia]
        sigma_t = plane_stress(pt.sig_n, law.normals[a], pt.shift[a], law.rounding)[0]
        d[ia] = law.weights[a] * sigma_t
        f[ia] = d[ia] * unit[a]
    S = tab[:n, :n]  # the scaled symmetric part, in the tableau's first columns (-H is in the next n)
    for sweep in range(2):
        for ia in range(n):
            for jb in range(n):
                S[ia, jb] = -0.5 * (d[ia] * tab[ia, n + jb] + d[jb] * tab[jb, n + ia]) / np.sqrt(f[ia] * f[jb])
        # most points' rate problems are uniquely solvable: a Cholesky factorisation says so at a fraction of
        # the cost of the eigenvalue (measured: the eigenvalue at every plastic point took 4.4 times the
        # update); it overwrites S, which the second sweep makes again for the eigenvalue
        if sweep == 0 and _cholesky_succeeds(S):
            return 0.0
    lmin = np.linalg.eigvalsh(np.ascontiguousarray(S))[0]
    return _FLOOR_MARGIN * max(0.0, -lmin)


@njit(cache=True, inline="always", error_model="numpy")
def _keep_start(law, tangent, sig_n, kap_n, sig_out, kap_out, D_out, loading):
    """The outputs of a failed update: the start of the step, no plane loading, the elastic tangent."""
    for i in range(6):
        sig_out[i] = sig_n[i]
        if tangent:
            for j in range(6):
                D_out[i, j] = law.stiff[i, j]
    for a in range(kap_n.shape[0]):
        kap_out[a] = kap_n[a]
        loading[a] = False


@njit(cache=True, inline="always", error_model="numpy", **NO_REFCOUNT)
def _tried(lam, converged, path):
    """When recording, :func:`point_update` has tried the fraction ``lam`` (converged or not)."""
    if path[_PATH_MODE] != _PATH_RECORD:
        return
    n = int(path[_PATH_N])
    if n >= _PATH:
        path[_PATH_MODE] = _PATH_OFF  # (past the capacity: nothing is skipped)
        return
    path[_PATH_FRAC + n] = lam if converged else -lam
    path[_PATH_N] = n + 1


@njit(cache=True, inline="always", error_model="numpy", **NO_REFCOUNT)
def _part_ends(lam_end, path):
    """When recording, a part of the step has ended at the fraction ``lam_end`` (its limit, or 1); when
    reading, the next part is read from its beginning."""
    if path[_PATH_MODE] == _PATH_READ:
        k = int(path[_PATH_RPART]) + 1
        path[_PATH_RPART] = k
        if k < path[_PATH_NPARTS]:
            path[_PATH_RPOS] = path[_PATH_END + k - 1]
        return
    if path[_PATH_MODE] != _PATH_RECORD:
        return
    k = int(path[_PATH_NPARTS])
    if k >= _PATH_PARTS:
        path[_PATH_MODE] = _PATH_OFF
        return
    path[_PATH_END + k] = path[_PATH_N]
    path[_PATH_LIMIT + k] = lam_end
    path[_PATH_NPARTS] = k + 1


@njit(cache=True, inline="always", error_model="numpy", **NO_REFCOUNT)
def _fails_again(lam, path):
    """When reading: the unperturbed step tried ``lam`` next in this part, failed, and ``lam`` lies beyond
    (1 + _BEYOND) times the part's limit (then the solve is skipped: it fails again). Moves the reading on
    while the sequence of fractions is the recorded one.

    The continuations of the tangent past a limit point (:func:`update_past_limits`) take the same sequence
    of fractions as a fresh follow of their increments; each solve that fails far beyond the limit runs to
    the last Newton iteration with line searches of up to 40 halvings, and those are about half of a follow's
    iterations (the footing's fold point: 9 of its 13 failed solves, 185 of its 388 iterations, are skipped).
    Skipping a solve that fails anyway leaves the follow as it was: the same fractions, the same limit, the
    same stress."""
    if path[_PATH_MODE] != _PATH_READ:
        return False
    k = int(path[_PATH_RPART])
    if k >= path[_PATH_NPARTS]:
        return False
    pos, end = int(path[_PATH_RPOS]), int(path[_PATH_END + k])
    if pos >= end:
        return False
    rec = path[_PATH_FRAC + pos]
    if abs(rec) != lam:  # (the sequence has left the recorded one: nothing more is skipped in this part)
        path[_PATH_RPOS] = end
        return False
    path[_PATH_RPOS] = pos + 1
    return rec < 0.0 and lam > (1.0 + _BEYOND) * path[_PATH_LIMIT + k]


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def point_update(law, pd, opt, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, D_out,
                 loading, grad_out, ws, path):
    """Integrate one Gauss point (Mandel vectors; see the module docstring for the algorithm).

    ``pd`` is :func:`plane_data` of ``law``, ``ws`` the thread's :func:`make_workspace`, ``path`` its
    :func:`make_path` (off, except in :func:`update_past_limits`). ``c0``, ``m_over`` and
    ``nl_shift`` (M,): the implicit gradient's shift m t d_ebar [m] of this step, m (``m_over`` = 0: no
    gradient) and the shift each plane past its peak has accumulated (its kappa_hat - kappa at the start).
    Outputs: sig_out (6,), kap_out (M,), D_out (6, 6) d sigma / d d_eps (if ``opt.tangent``), loading (M,)
    bool (planes whose slip grows), grad_out (14,): S, d S / d d_eps (6), d sigma / d c0 (6), d S / d c0
    (S the sum of the slip increments of the planes past their peak; zeros without the gradient, the
    derivatives only with ``opt.tangent``). Returns (status, Newton iterations, continuation halvings, the
    fraction of the increment reached (1 unless failed), opening dlambda of the cut-off, largest
    etah_a / eta_f,a at the end, the mu of the step stabilisation's floor (0 at an elastic point), the
    stabilisation's overstress: the largest h_a dkappa_a / etah_a of the loading planes, the part of a plane's
    mobilised ratio that the floor carries above its hardening curve (0 without the stabilisation)).
    """
    M = kap_n.shape[0]
    vecs = ws.vecs
    eta_f, shift, strong, dk, dk_done, plane = ws.eta_f, ws.shift, ws.strong, ws.dk, ws.dk_done, ws.plane
    eps_end = vecs[_V_EPS]
    lam6 = vecs[_V_LAM]
    for i in range(6):
        eps_end[i] = eps_n[i] + de[i]
    induced_tensor(eps_end, law.beta, law.alpha_hat, law.beta_hat, lam6)  # (3.15)
    plane_strengths(law.nn6, law.omega6, lam6, law.coeffs, law.eta0, eta_f, ws.deta_f)  # (2.4)
    post = ws.post
    coupled = False
    for a in range(M):
        shift[a] = law.cohesion[a] / eta_f[a] + law.apex_stress
        strong[a] = kap_n[a] > law.A or (soft > 0.0 and kap_n[a] >= law.kstar)
        post[a] = m_over > 0.0 and soft > 0.0 and kap_n[a] >= law.kstar
        coupled = coupled or post[a]
        ws.select[a] = True
    ws.select[M] = True
    for i in range(14):
        grad_out[i] = 0.0
    sig = vecs[_V_SIG]
    for i in range(6):
        acc = sig_n[i]
        for j in range(6):
            acc += law.stiff[i, j] * de[j]
        sig[i] = acc
    if _is_elastic(law, sig, kap_n, soft, eta_f, shift, post, c0, nl_shift):
        ratios = ws.dk_try  # scratch
        _ratios(law, sig, shift, ratios)
        best = 0.0
        for a in range(M):
            kap_out[a] = kap_n[a]
            loading[a] = False
            best = max(best, ratios[a] / eta_f[a])
        for i in range(6):
            sig_out[i] = sig[i]
        if opt.tangent:
            for i in range(6):
                for j in range(6):
                    D_out[i, j] = law.stiff[i, j]
        return OK, 0, 0, 1.0, 0.0, best, 0.0, 0.0
    # the strain scale of the point: the increment, or the elastic strain of its stress
    smax = law.apex_stress
    dmax = 0.0
    for i in range(6):
        smax = max(smax, abs(sig_n[i]))
        dmax = max(dmax, abs(de[i]))
    r_scale = dmax + smax * law.comp[0, 0]
    de_lam = vecs[_V_DE]
    # the step stabilisation's floor of each plane over a nominal step: mu times its elastic self-coupling
    # (w/t) G / sigma~ (uniform mu, or the point's least mu for a unique rate problem with opt.minimal);
    # over the fraction lam of a step of size opt.step it is floor0 / (lam opt.step)
    unit = ws.floor0
    stabilised = opt.minimal or opt.stabilisation > 0.0
    # the unit of a strong plane's overstress (evaluate), 1 / sigma~ at sigma_n (at least the apex stress, as
    # in floor_units: any positive constant gives the same solution), for every plane in one loop over the
    # plane-major rows, which vectorises
    inverse_shifted_normal_stress(sig_n, pd, shift, law.apex_stress, plane[_P_INV_ST0], M)
    if stabilised:
        floor_units(law, plane[_P_INV_ST0], unit, M)
    for a in range(M):
        if not stabilised:  # (the thesis's law: no floor)
            unit[a] = 0.0
        ws.floor[a] = 0.0
    pt = Point(sig_n, de_lam, kap_n, soft, eta_f, shift, strong, ws.select, ws.floor, r_scale, post, coupled, c0,
               m_over, nl_shift)
    mu = _uniqueness_floor(law, pt, ws, unit) if opt.minimal else opt.stabilisation
    for a in range(M):
        ws.floor0[a] = mu * unit[a]
        ws.floor[a] = ws.floor0[a] / opt.step
    # follow the branch in the fraction lam of the increment, from the solution at lam = 0 (the start of
    # the step); Newton's first step from a solution is the tangent predictor of the next fraction
    sig_done = vecs[_V_SIG_DONE]
    for i in range(6):
        sig_done[i] = sig_n[i]
    for a in range(M):
        dk_done[a] = 0.0
    dl_done = 0.0
    s_done = 0.0
    lam_done = 0.0
    h = 1.0
    halvings = 0
    total_its = 0
    rate_solved = False
    while lam_done < 1.0:
        lam = min(1.0, lam_done + h)
        for i in range(6):
            de_lam[i] = lam * de[i]
            sig[i] = sig_done[i]
        for a in range(M):
            dk[a] = dk_done[a] if strong[a] else 0.0
            ws.floor[a] = ws.floor0[a] / (lam * opt.step)
        converged, dl, S = False, 0.0, 0.0
        if not _fails_again(lam, path):  # (the tangent's continuations past a limit point: _fails_again)
            converged, its, dl, S = _newton(law, pd, opt, pt, sig, dk, dl_done, s_done, ws)
            total_its += its
        _tried(lam, converged, path)
        if converged:
            lam_done = lam
            for i in range(6):
                sig_done[i] = sig[i]
            for a in range(M):
                dk_done[a] = dk[a]
            dl_done = dl
            s_done = S
            h = min(2.0 * h, 1.0)
        elif lam_done == 0.0 and not rate_solved:
            # the branches at the kinks of sigma_n from the rate problem, then the same fraction again
            _rate_active_set(law, Point(sig_n, de, kap_n, soft, eta_f, shift, strong, ws.select, ws.floor, r_scale,
                                        post, coupled, c0, m_over, nl_shift), ws)
            rate_solved = True
        else:
            h *= 0.5
            halvings += 1
            if halvings > opt.max_halvings and opt.locate > 0 and lam_done > 0.0:
                # the branch ends between lam_done and the fraction tried last: its end, by bisection, each
                # trial a Newton solve from the solution at the last fraction reached
                lo, hi = lam_done, min(1.0, lam_done + 2.0 * h)
                width = 0.5 ** opt.locate
                while hi - lo > width:
                    mid = 0.5 * (lo + hi)
                    for i in range(6):
                        de_lam[i] = mid * de[i]
                        sig[i] = sig_done[i]
                    for a in range(M):
                        dk[a] = dk_done[a] if strong[a] else 0.0
                    converged, its, dl, S = _newton(law, pd, opt, pt, sig, dk, dl_done, s_done, ws)
                    total_its += its
                    if not converged:
                        hi = mid
                        continue
                    lo = mid
                    for i in range(6):
                        sig_done[i] = sig[i]
                    for a in range(M):
                        dk_done[a] = dk[a]
                    dl_done = dl
                    s_done = S
                _part_ends(lo, path)
                # the limit state (the planes' slips and ratios evaluated again at it)
                for i in range(6):
                    de_lam[i] = lo * de[i]
                    sig_out[i] = sig_done[i]
                for a in range(M):
                    dk[a] = dk_done[a] if strong[a] else 0.0
                evaluate(law, pd, pt, sig_done, dk, dl_done, s_done, False, False, plane, ws)
                best = 0.0
                for a in range(M):
                    slip = plane[_P_SLIP, a]
                    kap_out[a] = kap_n[a] + max(slip, 0.0)
                    loading[a] = slip > (0.0 if not strong[a] else 1e-12 * law.A)
                    best = max(best, plane[_P_RATIO, a] / eta_f[a])
                return LIMIT, total_its, halvings, lo, dl_done, best, mu, 0.0
            if halvings > opt.max_halvings:
                _keep_start(law, opt.tangent, sig_n, kap_n, sig_out, kap_out, D_out, loading)
                return FAILED, total_its, halvings, lam_done, 0.0, np.nan, mu, 0.0
    _part_ends(1.0, path)
    # the solution at lam = 1 (sig, dk, plane and the LU factors of J are those of the last Newton solve)
    best = 0.0
    over = 0.0
    for a in range(M):
        slip = plane[_P_SLIP, a]
        kap_out[a] = kap_n[a] + max(slip, 0.0)
        loading[a] = slip > (0.0 if not strong[a] else 1e-12 * law.A)
        best = max(best, plane[_P_RATIO, a] / eta_f[a])
        if slip > 0.0:  # the floor's share of the plane's ratio: etah = eta(kappa) + h dkappa (ws.floor: lam = 1)
            over = max(over, ws.floor[a] * slip / plane[_P_RATIO, a])
    for i in range(6):
        sig_out[i] = sig[i]
    grad_out[0] = s_done
    if opt.tangent:
        _tangent(law, soft, eps_end, strong, pt, ws, D_out, grad_out)
    return OK, total_its, halvings, 1.0, dl_done, best, mu, over


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _tangent(law, soft, eps_end, strong, pt, ws, D_out, grad_out):
    """Consistent tangent d sigma / d d_eps at the converged solution (ws.J holds its LU factors), and with
    the implicit gradient the derivatives of S in ``grad_out`` (see :func:`point_update`).

    Differentiating the equations at the solution: J7 [d sigma; d lambda] = [(I - T) d d_eps; 0], where
    J7 is the condensed Newton matrix and T = sum_a t_a (x) l_a collects the dependence of the plane laws
    on the end-of-step strain through eta_f,a (induced anisotropy, 3.14-3.15): l_a = d eta_f,a / d eps and
    t_a = d R / d eta_f,a (with the strong planes' slips condensed). With the gradient the system is
    J8 [d sigma; d lambda; d S] = [(I - T) d d_eps; 0; -t_S . d d_eps] (t_S: the row of g_S = S - sum dkappa),
    and the shift c0 enters through the planes past their peak, d dkappa_a / d c0 = delta_a = -gamma_a / m:
    J8 [d sigma; d lambda; d S] / d c0 = [-sum wt delta_a m_a; 0; sum delta_a].
    """
    M = strong.shape[0]
    n = _NSYS if pt.coupled else 7
    T = ws.mats[1]
    t_s = ws.vecs[_V_COL]  # the row of g_S in T
    for i in range(6):
        t_s[i] = 0.0
        for j in range(6):
            T[i, j] = 0.0
    if law.beta != 0.0:
        L = ws.mats[0]
        induced_slope(eps_end, law.beta, law.alpha_hat, law.beta_hat, L, ws.vecs[_V_S0:_V_S2 + 1])
        ell = ws.vecs[_V_ELL]
        for a in range(M):
            slip = ws.plane[_P_SLIP, a]
            cb = ws.plane[_P_CB, a]
            if slip == 0.0 and cb == 0.0:
                continue
            ef = ws.eta_f[a]
            ratio = ws.plane[_P_RATIO, a]
            dst = -law.cohesion[a] / (ef * ef)  # d sigma~ / d eta_f (the cohesion's shift c / eta_f)
            dr = -ratio / ws.plane[_P_ST, a] * dst  # d etah / d eta_f
            nn = law.nn6[a]
            wt = law.weights[a] * law.inv_t
            dg = 0.0
            if strong[a]:
                dg = dr - ws.plane[_P_ETA, a] / ef  # d g / d eta_f (eta is proportional to eta_f)
                cm = wt * cb * dg
            else:
                # d slip / d eta_f at fixed stress: (d etah / d eta_f - eta / eta_f) / (eta' + h)
                cm = wt * ws.plane[_P_KP, a] * (dr - ws.plane[_P_ETA, a] / ef)
            # d m / d eta_f = (d etah / d eta_f - eta_c_ratio (w + eta_f w' d sigma~ / d eta_f)) nn6
            wc, dwc = compaction_weight(ws.plane[_P_ST, a], law.compaction_stress)
            cn = wt * slip * (dr - law.eta_c_ratio * (wc + ef * dwc * dst))
            for j in range(6):
                acc = 0.0
                for i in range(6):
                    acc += nn[i] * L[i, j]
                ell[j] = ws.deta_f[a] * acc
            for i in range(6):
                ti = cm * ws.mvec[i, a] + cn * nn[i]
                for j in range(6):
                    T[i, j] += ti * ell[j]
            if pt.coupled and pt.post[a]:  # d g_S / d eta_f,a = - d dkappa_a / d eta_f,a
                for j in range(6):
                    t_s[j] -= cb * dg * ell[j]
    J, piv, col = (ws.J8 if pt.coupled else ws.J), ws.piv[:n], ws.step[:n]
    for j in range(6):
        for i in range(6):
            col[i] = (1.0 if i == j else 0.0) - T[i, j]
        col[6] = 0.0
        if pt.coupled:
            col[7] = -t_s[j]
        _lu_solve(J, piv, col)
        for i in range(6):
            D_out[i, j] = col[i]
        if pt.coupled:
            grad_out[1 + j] = col[7]
    if pt.coupled:
        for i in range(n):
            col[i] = 0.0
        for a in range(M):
            if pt.post[a]:
                delta = -ws.plane[_P_GAMMA, a] / pt.m_over
                col[7] += delta
                wd = law.weights[a] * law.inv_t * delta
                for i in range(6):
                    col[i] -= wd * ws.mvec[i, a]
        _lu_solve(J, piv, col)
        for i in range(6):
            grad_out[7 + i] = col[i]
        grad_out[13] = col[7]


@njit(cache=True, error_model="numpy")
def _without_tangent(opt):
    """``opt`` without the tangent."""
    return Options(opt.tol, opt.maxit, opt.max_halvings, False, opt.stabilisation, opt.step, opt.minimal, opt.locate)


@njit(cache=True, error_model="numpy", **REFCOUNT)
def _follow_past_limits(law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out,
                        loading, grad_out, ws, path, lam0, its0, hv0, dl0):
    """The step followed past the limit points of its branch, no tangent (``opt.locate`` > 0). ``lam0`` > 0:
    :func:`point_update` of the whole step has ended at a limit point at that fraction, and ``sig_out``,
    ``kap_out``, ``loading`` hold the limit state (its iterations, halvings and opening: its0, hv0, dl0);
    ``lam0`` = 0: start with that call. Returns (ok, Newton iterations, continuation halvings, cut-off
    opening, all summed over the parts of the step, the largest etah_a / eta_f,a, mu and overstress at the
    end, limit points passed); sig_out, kap_out and loading (planes that loaded in any part) hold the end
    state when ok."""
    M = kap_n.shape[0]
    one = _without_tangent(opt)
    D_none = np.empty((6, 6))  # (not written without the tangent)
    cur_sig, cur_eps, rest = sig_n.copy(), eps_n.copy(), de.copy()
    cur_kap = kap_n.copy()
    path_load = np.zeros(M, dtype=np.bool_)
    st, lam, its_sum, hv_sum, dl_sum = LIMIT, lam0, its0, hv0, dl0
    best, mu, over = 0.0, 0.0, 0.0
    if lam0 == 0.0:
        st, its_sum, hv_sum, lam, dl_sum, best, mu, over = point_update(
            law, pd, one, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, D_none, loading,
            grad_out, ws, path)
    count = 0
    while st == LIMIT and count < lim.max_points:
        # the limit state starts the rest of the step
        count += 1
        for i in range(6):
            cur_sig[i] = sig_out[i]
            cur_eps[i] += lam * rest[i]
            rest[i] *= 1.0 - lam
        for a in range(M):
            cur_kap[a] = kap_out[a]
            path_load[a] = path_load[a] or loading[a]
        st, its, hv, lam, dl, best, mu, over = point_update(
            law, pd, one, cur_sig, rest, cur_eps, cur_kap, soft, c0, m_over, nl_shift, sig_out, kap_out, D_none,
            loading, grad_out, ws, path)
        its_sum += its
        hv_sum += hv
        dl_sum += dl
    if st != OK:
        return False, its_sum, hv_sum, dl_sum, best, mu, over, count
    for a in range(M):
        loading[a] = loading[a] or path_load[a]
    return True, its_sum, hv_sum, dl_sum, best, mu, over, count


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def update_past_limits(law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out,
                       D_out, loading, grad_out, ws, path):
    """:func:`point_update`, and where its branch ends at a limit point within the step (``opt.locate`` > 0),
    the step followed past the limit points of the branch (module docstring, "Past a limit point"), with
    the forward-difference tangent there. Returns point_update's tuple and the number of limit points
    passed. A point that cannot be followed fails as point_update fails: its start-of-step stress, the
    fraction its branch reached. (The continuation, which allocates, is :func:`_past_limit_points`: this
    function, called for every point, runs without reference counting.)"""
    # the fractions the branch tries are recorded for the tangent's continuations past a limit point
    path[_PATH_MODE] = _PATH_RECORD if opt.tangent and lim.max_points > 0 else _PATH_OFF
    path[_PATH_NPARTS] = 0
    path[_PATH_N] = 0
    st, its, hv, lam, dl, best, mu, over = point_update(
        law, pd, opt, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, D_out, loading,
        grad_out, ws, path)
    if st != LIMIT:
        path[_PATH_MODE] = _PATH_OFF
        return st, its, hv, lam, dl, best, mu, over, 0
    return _past_limit_points(law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out,
                              kap_out, D_out, loading, grad_out, ws, path, lam, its, hv, dl)


@njit(cache=True, error_model="numpy", **REFCOUNT)
def _past_limit_points(law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out,
                       D_out, loading, grad_out, ws, path, lam, its, hv, dl):
    """The rest of :func:`update_past_limits` after :func:`point_update` has ended at a limit point at the
    fraction ``lam`` (its iterations, halvings and opening: its, hv, dl): the continuation and its tangent."""
    reached = lam
    ok, its, hv, dl, best, mu, over, count = _follow_past_limits(
        law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, loading, grad_out,
        ws, path, lam, its, hv, dl)
    M = kap_n.shape[0]
    if ok and opt.tangent:
        # the step of the difference: fd_step (|d_eps| + |sigma_n| / E), in tensor components
        size_de = 0.0
        size_sig = 0.0
        for i in range(6):
            w = 1.0 if i < 3 else ISQ2
            size_de = max(size_de, w * abs(de[i]))
            size_sig = max(size_sig, w * abs(sig_n[i]))
        h = lim.fd_step * (size_de + size_sig * law.comp[0, 0])
        de_p, sig_p, kap_p, load_p, grad_p = de.copy(), np.empty(6), np.empty(M), np.empty(M, dtype=np.bool_), \
            np.empty(14)
        if path[_PATH_MODE] == _PATH_RECORD:
            path[_PATH_MODE] = _PATH_READ
        for j in range(6):
            path[_PATH_RPART] = 0  # read from the first part's first fraction
            path[_PATH_RPOS] = 0
            de_p[j] = de[j] + h
            ok = ok and _follow_past_limits(law, pd, opt, lim, sig_n, de_p, eps_n, kap_n, soft, c0, m_over,
                                            nl_shift, sig_p, kap_p, load_p, grad_p, ws, path, 0.0, 0, 0, 0.0)[0]
            for i in range(6):  # (s+ - s) / h
                D_out[i, j] = (sig_p[i] - sig_out[i]) / h
            de_p[j] = de[j]
    path[_PATH_MODE] = _PATH_OFF
    if not ok:
        _keep_start(law, opt.tangent, sig_n, kap_n, sig_out, kap_out, D_out, loading)
        return FAILED, its, hv, reached, 0.0, np.nan, mu, 0.0, 0
    for i in range(14):
        grad_out[i] = 0.0
    return OK, its, hv, 1.0, dl, best, mu, over, count
