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
The branch that the update follows from sigma_n, the rate problem that chooses it at the kinks, and
the continuation past limit points are in :mod:`material._cpa_point` and :mod:`material._cpa_rate`.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from material._cpa_plane import (
    NO_REFCOUNT,
    compaction_weight,
    fallback_shear,
    hardening,
    measures_of_parts,
    plane_stress,
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
#: (:func:`material._cpa_rate._uniqueness_floor`) instead of ``stabilisation``.
#: ``locate``: where the branch ends within the step, the halvings that locate its limit point (0: the point
#: fails there instead; :func:`material._cpa_point.update_past_limits`).
Options = namedtuple("Options", ["tol", "maxit", "max_halvings", "tangent", "stabilisation", "step", "minimal",
                                 "locate"])

#: Options of the continuation past limit points (:func:`material._cpa_point.update_past_limits`):
#: ``max_points``, the limit points one step may pass (0: none, the one-step problem of
#: :func:`material._cpa_point.point_update`); ``fd_step``, the step of the forward-difference tangent relative
#: to |d_eps| + |sigma_n| / E (tensor components). The values
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
#: :func:`material._cpa_point.point_update`, never written by :func:`evaluate`.
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


@njit(cache=True, error_model="numpy")
def make_workspace(M):
    """Scratch arrays of one thread for :func:`material._cpa_point.point_update` (M planes)."""
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


@njit(cache=True, inline="always", error_model="numpy")
def take_iterate(sig_from, dk_from, sig_to, dk_to):
    """Copy an iterate's stress (6,) and slip increments (M,) into another's."""
    for i in range(6):
        sig_to[i] = sig_from[i]
    for a in range(dk_to.shape[0]):
        dk_to[a] = dk_from[a]


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
        take_iterate(sig_try, dk_try, sig, dk)
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
