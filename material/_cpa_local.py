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

Unknowns and equations of the semismooth Newton method
------------------------------------------------------
* A *weak* plane (kappa_n <= A: eta(kappa_n) <= zeta eta_f / 2, which every plane starts as) has its
  complementarity solved in closed form for a given stress: dkappa = max(0, kappa(etah) - kappa_n) with
  kappa(etah) = A etah / (zeta eta_f - etah) (2.16 inverted). Its slip vector dkappa t_s / T is then
  smooth where the shear traction vanishes (dkappa ~ tau), which the slip as an unknown is not
  (measured: a Newton on (sigma, dkappa) stalls on such planes, whose slip direction turns fast). Its
  stress must stay below the barrier etah < zeta eta_f.
* A *strong* plane (kappa_n > A, or past the peak of a softening law) keeps dkappa as an unknown with
  the Fischer-Burmeister equation Phi(dkappa/A, eta - etah) = 0, Phi(u, v) = u + v - sqrt(u^2 + v^2),
  which holds iff the complementarity does; near failure kappa(etah) has a pole but eta(kappa) does not.
* The cut-off: Phi(dlambda, -p/K) = 0.
Which planes are strong depends on the committed kappa_n only, so it is part of the definition of the
equations, not of the iteration. The strong slips are eliminated from each linearised system plane by
plane (a rank-one term each), leaving 7 x 7 (stress and opening). The merit function
psi = (|R / r|^2 + sum Phi_a^2 + (Phi_0 / r)^2) / 2 (r the strain scale of the point) is continuously
differentiable and the semismooth Newton direction is a descent direction for it, so a backtracking
(Armijo) line search always makes progress unless the Jacobian is singular; near a solution with a
non-singular Jacobian the convergence is superlinear (De Luca, Facchinei & Kanzow 1996; quadratic here,
the pieces being smooth).

Following the branch
--------------------
Newton starts at the solution for no increment, so its first step is the tangent predictor. A plane
that loaded in the last step sits exactly on its kink there, and the generalised derivative must pick a
branch for it (:data:`_ON_CURVE`): the loading branch by default. When that Newton does not converge,
the branch of each plane on its kink is chosen by solving the rate problem at sigma_n, a linear
complementarity problem (:func:`_rate_active_set`, Lemke's method: the coupling of non-associated planes
near failure or at low stress need not be a P-matrix, and then the all-loading guess can keep Newton away
from the one active set that solves it; measured on a point of a footing at 97 % mobilisation). If
Newton still fails, the equations are solved for the fraction lambda = 1/2, 1/4, ... of the increment,
each from the solution at the last fraction reached, and lambda is doubled again after each success, up
to 1. The answer is the solution at lambda = 1 of the one-step problem: the fractions only supply
starting points, they are not sub-steps. When the branch ends before lambda = 1 (a limit point of the
strain-driven response) the point reports ``FAILED`` with the fraction it reached as the suggested step
ratio.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from material._cpa_plane import (
    compaction_weight,
    hardening,
    induced_slope,
    induced_tensor,
    plane_directions,
    plane_stress,
    plane_strengths,
    ratio_barrier,
    slip_of_ratio,
)

# status codes (material.base)
OK = 0
FAILED = 2

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
Options = namedtuple("Options", ["tol", "maxit", "max_halvings", "tangent", "stabilisation"])

#: The data of one point's local problem (fixed during its solution except ``de``, the increment of the
#: current fraction, and ``select``).
Point = namedtuple("Point", [
    "sig_n", "de", "kap_n",  # (6,), (6,), (M,) start of step and increment
    "soft",                  # softening slip scale of the point (0: none)
    "eta_f", "shift",        # (M,) strengths and shifts c_a / eta_f,a + c_apex at the end of the step
    "strong",                # (M,) bool: slip is an unknown (kappa_n > A, or past a softening peak)
    "select",                # (M,) bool: at its kink a plane takes the loading (True) or elastic branch
    "floor",                 # (M,) the step stabilisation's hardening floor of each plane [1/m] (0: none)
    "r_scale",               # strain scale of the residual
])

#: Per-plane columns of the workspace ``plane`` array (values at the current iterate).
_P_RATIO, _P_ST, _P_T, _P_SLIP, _P_CB, _P_KP, _P_ETA, _P_ALPHA = range(8)

#: Scratch arrays of one thread (M planes), made by :func:`make_workspace`.
Work = namedtuple("Work", [
    "plane", "trial_plane",   # (M, 8) per-plane values (columns _P_*) at the iterate / at a line-search trial
    "mvec", "bvec",           # (M, 6) flow vector m_a and b_a = d etah_a / d sigma
    "dk", "dk_try", "dk_step", "dk_done",  # (M,) slip increments: iterate, trial, Newton step, last solution
    "eta_f", "deta_f", "shift",            # (M,) strengths, their slope in x_a, shift c_a / eta_f,a + c_apex
    "strong", "select",       # (M,) bool, see Point
    "floor",                  # (M,) see Point
    "J", "rhs", "step", "piv",  # condensed Newton system (7, 7), (7,), (7,), pivots
    "vecs",                   # (12, 6) small vectors (rows _V_*)
    "mats",                   # (2, 6, 6): d Lambda / d eps, induced correction T
    "tableau",                # (M, 2 M + 2) Lemke's tableau of the rate problem
    "basis",                  # (M,) int: its basic variables
])
_V_R, _V_SIG, _V_SIG_TRY, _V_SIG_DONE, _V_LAM, _V_EPS, _V_DE, _V_ELL, _V_S0, _V_S1, _V_S2, _V_COL = range(12)


@njit(cache=True, error_model="numpy")
def make_workspace(M):
    """Scratch arrays of one thread for :func:`point_update` (M planes)."""
    return Work(np.empty((M, 8)), np.empty((M, 8)), np.empty((M, 6)), np.empty((M, 6)), np.empty(M),
                np.empty(M), np.empty(M), np.empty(M), np.empty(M), np.empty(M), np.empty(M),
                np.zeros(M, dtype=np.bool_), np.ones(M, dtype=np.bool_), np.zeros(M), np.empty((7, 7)), np.empty(7),
                np.empty(7), np.empty(7, dtype=np.int64), np.empty((12, 6)), np.empty((2, 6, 6)),
                np.empty((M, 2 * M + 2)), np.empty(M, dtype=np.int64))


@njit(cache=True, error_model="numpy")
def _lu_factor(A, piv):
    """In-place LU with partial pivoting of a small square matrix; returns False if singular."""
    n = A.shape[0]
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


@njit(cache=True, error_model="numpy")
def _lu_solve(LU, piv, b):
    """Solve in place for one right-hand side."""
    n = LU.shape[0]
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
def evaluate(law, pt, sig, dk, dl, want_jac, plane, ws):
    """Residuals (and the condensed 7 x 7 Newton system) at the iterate (sig, dk[strong], dl).

    Fills ``dk`` of the weak planes (their closed-form slip), ``plane`` (per-plane values, columns
    _P_*), ``ws.mvec``/``ws.bvec`` (flow vector m_a and b_a = d etah_a / d sigma of every plane with a
    slip or a loading derivative), the strain residual ``ws.vecs[_V_R]``, and with ``want_jac`` the
    condensed Jacobian ``ws.J`` (7, 7) and right-hand side ``ws.rhs`` (7,) of the Newton step. Returns
    (admissible, merit, max |R|, max |Phi_a|, |Phi_0|); an iterate is not admissible where a plane's
    shifted normal stress is not positive, a weak plane is at or past its barrier (without
    stabilisation), or a strong plane's kappa <= -A/2.
    """
    M = law.normals.shape[0]
    comp = law.comp
    A = law.A
    b_r = law.rounding
    R, J, rhs = ws.vecs[_V_R], ws.J, ws.rhs
    for i in range(6):
        acc = -pt.de[i]
        for j in range(6):
            acc += comp[i, j] * (sig[j] - pt.sig_n[j])
        R[i] = acc + (dl / 3.0 if i < 3 else 0.0)
    if want_jac:
        for i in range(7):
            rhs[i] = 0.0
            for j in range(7):
                J[i, j] = comp[i, j] if (i < 6 and j < 6) else 0.0
        for i in range(3):
            J[i, 6] = 1.0 / 3.0
    phi2 = 0.0
    phimax = 0.0
    for a in range(M):
        ef = pt.eta_f[a]
        kn = pt.kap_n[a]
        sigma_t, tau, T, ts0, ts1, ts2 = plane_stress(sig, law.normals[a], pt.shift[a], b_r)
        if not sigma_t > 0.0:
            return False, np.inf, np.inf, np.inf, np.inf
        inv_st = 1.0 / sigma_t
        ratio = T * inv_st  # mobilised ratio
        wt = law.weights[a] * law.inv_t
        nn = law.nn6[a]
        cb = 0.0
        alpha = 0.0
        kp = 0.0
        eta = 0.0
        if pt.strong[a]:
            k = kn + dk[a]
            if k <= -0.5 * A:
                return False, np.inf, np.inf, np.inf, np.inf
            eta, deta = hardening(k, ef, law.zeta, A, law.kstar, pt.soft, law.residual)  # (2.16)
            # with the step stabilisation's floor h: g = etah - eta(kappa) - h dkappa
            h = pt.floor[a]
            phi, (pu, pv) = _fb(dk[a] / A, eta + h * dk[a] - ratio, pt.select[a])
            deta += h
            phi2 += phi * phi
            phimax = max(phimax, abs(phi))
            slip = dk[a]
            den = pu / A + pv * deta
            if abs(den) < 1e-300:
                den = 1e-300
            alpha = -phi / den  # d dkappa = alpha + cb b . d sigma
            cb = pv / den
        else:
            h = pt.floor[a]
            if h == 0.0 and not ratio < ratio_barrier(ef, law.zeta, pt.soft) * (1.0 - 1e-12):
                return False, np.inf, np.inf, np.inf, np.inf
            slip, kp, eta = slip_of_ratio(ratio, kn, ef, law.zeta, A, h * A)  # (2.16) inverted
            if slip < -_ON_CURVE * (A + kn) or (slip <= 0.0 and not pt.select[a]):
                kp = 0.0  # elastic (below its curve, or on it with the elastic branch chosen)
            if slip <= 0.0:
                slip = 0.0
            dk[a] = slip
            cb = kp
        plane[a, _P_RATIO] = ratio
        plane[a, _P_ST] = sigma_t
        plane[a, _P_T] = T
        plane[a, _P_SLIP] = slip
        plane[a, _P_CB] = cb
        plane[a, _P_KP] = kp
        plane[a, _P_ETA] = eta
        plane[a, _P_ALPHA] = alpha
        if slip == 0.0 and cb == 0.0:
            continue  # an elastic plane: no flow, no terms
        sn6 = ws.mvec[a]  # the plane's own rows as scratch: sn6 becomes m, rn6 becomes b
        rn6 = ws.bvec[a]
        plane_directions(law.normals[a], ts0, ts1, ts2, tau, sn6, rn6)
        inv_T = 1.0 / T
        s_t = tau * inv_T
        wc, dwc = compaction_weight(sigma_t, law.compaction_stress)
        dil = ratio - law.eta_c_ratio * ef * wc  # d psi / d sigma_N (2.17): < 0 compaction, > 0 dilation
        if want_jac:
            # J += wt [slip d m / d sigma + cb m (x) b], all in the span of sn6, rn6, nn6 with
            # m = s_t sn6 + dil nn6 (2.7), b = d etah / d sigma = (s_t sn6 + etah nn6) / sigma~,
            # d m / d sigma = ((b_r / T)^2 sn6 (x) sn6 + rn6 (x) rn6) / T (the slip direction turning)
            #                 + nn6 (x) (b + eta_c w' nn6)
            f_s = cb * s_t  # coefficient of sn6 in (slip nn6 + cb m)
            f_n = slip + cb * dil  # of nn6
            a_ss = wt * (slip * b_r * b_r * inv_T * inv_T * inv_T + f_s * s_t * inv_st)
            a_ns = wt * f_n * s_t * inv_st
            a_sn = wt * f_s * ratio * inv_st
            a_nn = wt * (f_n * ratio * inv_st + slip * law.eta_c_ratio * ef * dwc)
            a_rr = wt * slip * inv_T
            ra = wt * alpha
            for i in range(6):
                si = sn6[i]
                ni = nn[i]
                u = a_ss * si + a_ns * ni  # (.) (x) sn6
                v = a_sn * si + a_nn * ni  # (.) (x) nn6
                z = a_rr * rn6[i]          # (.) (x) rn6
                rhs[i] -= ra * (s_t * si + dil * ni)
                for j in range(6):
                    J[i, j] += u * sn6[j] + v * nn[j] + z * rn6[j]
        # the plane's flow m and b (kept over the scratch rows for the Newton step and the tangent)
        ws_ = wt * slip
        for i in range(6):
            s_i = s_t * sn6[i]
            m_i = s_i + dil * nn[i]
            R[i] += ws_ * m_i  # (2.9)
            rn6[i] = (s_i + ratio * nn[i]) * inv_st  # b
            sn6[i] = m_i                             # m
    # mean-stress cut-off
    p = (sig[0] + sig[1] + sig[2]) / 3.0
    phi0, (pu0, pv0) = _fb(dl, -p / law.bulk, True)
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
    merit = 0.5 * (rn2 / (pt.r_scale * pt.r_scale) + phi2 + (phi0 / pt.r_scale) ** 2)
    return True, merit, rmax, phimax, abs(phi0)


@njit(cache=True, error_model="numpy")
def _newton(law, opt, pt, sig, dk, dl_in, ws):
    """Semismooth Newton with a backtracking line search on the merit function, from (sig, dk, dl_in).

    Returns (converged, iterations, dl). On convergence ws.J holds the LU factors of the condensed
    Jacobian at the solution, and sig, dk, ws.plane, ws.mvec, ws.bvec the solution."""
    plane, trial_plane, J, rhs, step, piv = ws.plane, ws.trial_plane, ws.J, ws.rhs, ws.step, ws.piv
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
    ok, merit, rmax, phimax, phi0 = evaluate(law, pt, sig, dk, dl, True, plane, ws)
    if not ok:
        return False, 0, dl
    for it in range(opt.maxit + 1):
        if rmax <= opt.tol * pt.r_scale + floor and phimax <= opt.tol and phi0 <= opt.tol * pt.r_scale + floor:
            return _lu_factor(J, piv), it, dl
        if it == opt.maxit or not _lu_factor(J, piv):
            return False, it, dl
        for i in range(7):
            step[i] = rhs[i]
        _lu_solve(J, piv, step)
        for a in range(M):
            if strong[a]:
                acc = 0.0
                for j in range(6):
                    acc += ws.bvec[a, j] * step[j]
                dk_step[a] = plane[a, _P_ALPHA] + plane[a, _P_CB] * acc
        alpha = 1.0
        accepted = False
        for _ls in range(40):
            for i in range(6):
                sig_try[i] = sig[i] + alpha * step[i]
            for a in range(M):
                dk_try[a] = dk[a] + alpha * dk_step[a] if strong[a] else 0.0
            dl_try = dl + alpha * step[6]
            ok2, merit2, rmax2, phimax2, phi02 = evaluate(law, pt, sig_try, dk_try, dl_try, True, trial_plane, ws)
            if ok2 and merit2 <= (1.0 - 1e-4 * alpha) * merit:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            return False, it, dl
        for i in range(6):
            sig[i] = sig_try[i]
        for a in range(M):
            dk[a] = dk_try[a]
            for c in range(8):
                plane[a, c] = trial_plane[a, c]
        dl = dl_try
        merit, rmax, phimax, phi0 = merit2, rmax2, phimax2, phi02
    return False, opt.maxit, dl


@njit(cache=True, error_model="numpy")
def _ratios(law, sig, shift, out):
    """Mobilised ratio etah_a of every plane at ``sig`` into ``out`` (inf where sigma~ <= 0)."""
    for a in range(law.normals.shape[0]):
        sigma_t, tau, T, _, _, _ = plane_stress(sig, law.normals[a], shift[a], law.rounding)
        out[a] = T / sigma_t if sigma_t > 0.0 else np.inf


@njit(cache=True, error_model="numpy")
def _is_elastic(law, trial, kap_n, soft, eta_f, shift):
    """The elastic trial is the solution: no mean tension, no plane above its reached level (stops at the
    first plane that loads)."""
    if trial[0] + trial[1] + trial[2] > 0.0:
        return False
    for a in range(kap_n.shape[0]):
        sigma_t, tau, T, _, _, _ = plane_stress(trial, law.normals[a], shift[a], law.rounding)
        if not (sigma_t > 0.0 and T <= sigma_t * hardening(kap_n[a], eta_f[a], law.zeta, law.A, law.kstar, soft,
                                                              law.residual)[0]):
            return False
    return True


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


@njit(cache=True, error_model="numpy")
def _rate_active_set(law, pt, ws):
    """Choose the branch of every plane on its kink at sigma_n by the rate problem (sets ``pt.select``).

    The planes on their hardening curve at sigma_n load at rates x >= 0 with the rates of their
    overstress g_dot = q - H x <= 0 and x . g_dot = 0, q_a = b_a . C d_eps (the elastic rate of etah_a),
    H_ab = (w_b / t) b_a . C m_b + eta'_a delta_ab. Solved by Lemke's method; where it finds no solution
    the choice stays the loading branch for all. Returns whether a solution was found.
    """
    M = pt.kap_n.shape[0]
    on = np.empty(M, dtype=np.int64)
    n = 0
    sig = pt.sig_n
    hard = ws.dk_try  # eta' of each plane on its curve (scratch)
    for a in range(M):
        sigma_t, tau, T, ts0, ts1, ts2 = plane_stress(sig, law.normals[a], pt.shift[a], law.rounding)
        plane_directions(law.normals[a], ts0, ts1, ts2, tau, ws.mvec[a], ws.bvec[a])
        ratio = T / sigma_t
        eta, deta = hardening(pt.kap_n[a], pt.eta_f[a], law.zeta, law.A, law.kstar, pt.soft, law.residual)
        if sigma_t > 0.0 and ratio >= eta - _ON_CURVE * (1.0 + eta):
            on[n] = a
            n += 1
            hard[a] = deta + pt.floor[a]
            # m and b at sigma_n
            s_t = tau / T
            wc, _ = compaction_weight(sigma_t, law.compaction_stress)
            dil = ratio - law.eta_c_ratio * pt.eta_f[a] * wc
            for i in range(6):
                s_i = s_t * ws.mvec[a, i]
                ws.bvec[a, i] = (s_i + ratio * law.nn6[a, i]) / sigma_t
                ws.mvec[a, i] = s_i + dil * law.nn6[a, i]
        pt.select[a] = False
    if n == 0:
        return True
    tab = ws.tableau
    cm = ws.vecs[_V_COL]  # C m_b
    cde = ws.vecs[_V_S0]  # C d_eps
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += law.stiff[i, j] * pt.de[j]
        cde[i] = acc
    for jb in range(n):
        bpl = on[jb]
        for i in range(6):
            acc = 0.0
            for j in range(6):
                acc += law.stiff[i, j] * ws.mvec[bpl, j]
            cm[i] = acc
        wt = law.weights[bpl] * law.inv_t
        for ia in range(n):
            apl = on[ia]
            acc = 0.0
            for i in range(6):
                acc += ws.bvec[apl, i] * cm[i]
            h = wt * acc + (hard[apl] if ia == jb else 0.0)
            tab[ia, n + jb] = -h  # the tableau holds -M (M = H)
    for ia in range(n):
        apl = on[ia]
        for j in range(n):
            tab[ia, j] = 1.0 if j == ia else 0.0
        tab[ia, 2 * n] = -1.0
        acc = 0.0
        for i in range(6):
            acc += ws.bvec[apl, i] * cde[i]
        tab[ia, 2 * n + 1] = -acc  # q of the LCP is -q
        # (columns beyond 2n + 1 unused)
    # compact the columns: the function expects (n, 2n + 2)
    found = _lemke(tab[:n, :2 * n + 2], ws.basis[:n], n, 4 * n + 10)
    if not found:
        for ia in range(n):
            pt.select[on[ia]] = True
        return False
    for i in range(n):
        v = ws.basis[i]
        if n <= v < 2 * n and tab[i, 2 * n + 1] > 0.0:
            pt.select[on[v - n]] = True
    return True


@njit(cache=True, error_model="numpy")
def point_update(law, opt, sig_n, de, eps_n, kap_n, soft, sig_out, kap_out, D_out, loading, ws):
    """Integrate one Gauss point (Mandel vectors; see the module docstring for the algorithm).

    Outputs: sig_out (6,), kap_out (M,), D_out (6, 6) d sigma / d d_eps (if ``opt.tangent``), loading (M,)
    bool (planes whose slip grows). Returns (status, Newton iterations, continuation halvings, the
    fraction of the increment reached (1 unless failed), opening dlambda of the cut-off, largest
    etah_a / eta_f,a at the end).
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
    for a in range(M):
        shift[a] = law.cohesion[a] / eta_f[a] + law.apex_stress
        strong[a] = kap_n[a] > law.A or (soft > 0.0 and kap_n[a] >= law.kstar)
        ws.select[a] = True
    sig = vecs[_V_SIG]
    for i in range(6):
        acc = sig_n[i]
        for j in range(6):
            acc += law.stiff[i, j] * de[j]
        sig[i] = acc
    if _is_elastic(law, sig, kap_n, soft, eta_f, shift):
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
        return OK, 0, 0, 1.0, 0.0, best
    # the strain scale of the point: the increment, or the elastic strain of its stress
    smax = law.apex_stress
    dmax = 0.0
    for i in range(6):
        smax = max(smax, abs(sig_n[i]))
        dmax = max(dmax, abs(de[i]))
    r_scale = dmax + smax * law.comp[0, 0]
    de_lam = vecs[_V_DE]
    # the step stabilisation's floor of each plane: mu times its elastic self-coupling (w/t) G / sigma~
    g_mod = 0.5 / law.comp[5, 5]  # shear modulus (the Mandel compliance of a shear is 1 / (2 G))
    for a in range(M):
        if opt.stabilisation > 0.0:
            sigma_t = plane_stress(sig_n, law.normals[a], shift[a], law.rounding)[0]
            ws.floor[a] = opt.stabilisation * law.weights[a] * law.inv_t * g_mod / max(sigma_t, law.apex_stress)
        else:
            ws.floor[a] = 0.0
    pt = Point(sig_n, de_lam, kap_n, soft, eta_f, shift, strong, ws.select, ws.floor, r_scale)
    # follow the branch in the fraction lam of the increment, from the solution at lam = 0 (the start of
    # the step); Newton's first step from a solution is the tangent predictor of the next fraction
    sig_done = vecs[_V_SIG_DONE]
    for i in range(6):
        sig_done[i] = sig_n[i]
    for a in range(M):
        dk_done[a] = 0.0
    dl_done = 0.0
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
        converged, its, dl = _newton(law, opt, pt, sig, dk, dl_done, ws)
        total_its += its
        if converged:
            lam_done = lam
            for i in range(6):
                sig_done[i] = sig[i]
            for a in range(M):
                dk_done[a] = dk[a]
            dl_done = dl
            h = min(2.0 * h, 1.0)
        elif lam_done == 0.0 and not rate_solved:
            # the branches at the kinks of sigma_n from the rate problem, then the same fraction again
            _rate_active_set(law, Point(sig_n, de, kap_n, soft, eta_f, shift, strong, ws.select, ws.floor, r_scale),
                             ws)
            rate_solved = True
        else:
            h *= 0.5
            halvings += 1
            if halvings > opt.max_halvings:
                for i in range(6):
                    sig_out[i] = sig_n[i]
                    if opt.tangent:
                        for j in range(6):
                            D_out[i, j] = law.stiff[i, j]
                for a in range(M):
                    kap_out[a] = kap_n[a]
                    loading[a] = False
                return FAILED, total_its, halvings, lam_done, 0.0, np.nan
    # the solution at lam = 1 (sig, dk, plane and the LU factors of J are those of the last Newton solve)
    best = 0.0
    for a in range(M):
        slip = plane[a, _P_SLIP]
        kap_out[a] = kap_n[a] + max(slip, 0.0)
        loading[a] = slip > (0.0 if not strong[a] else 1e-12 * law.A)
        best = max(best, plane[a, _P_RATIO] / eta_f[a])
    for i in range(6):
        sig_out[i] = sig[i]
    if opt.tangent:
        _tangent(law, soft, eps_end, strong, ws, D_out)
    return OK, total_its, halvings, 1.0, dl_done, best


@njit(cache=True, error_model="numpy")
def _tangent(law, soft, eps_end, strong, ws, D_out):
    """Consistent tangent d sigma / d d_eps at the converged solution (ws.J holds its LU factors).

    Differentiating the equations at the solution: J7 [d sigma; d lambda] = [(I - T) d d_eps; 0], where
    J7 is the condensed Newton matrix and T = sum_a t_a (x) l_a collects the dependence of the plane laws
    on the end-of-step strain through eta_f,a (induced anisotropy, 3.14-3.15): l_a = d eta_f,a / d eps and
    t_a = d R / d eta_f,a (with the strong planes' slips condensed).
    """
    M = strong.shape[0]
    T = ws.mats[1]
    for i in range(6):
        for j in range(6):
            T[i, j] = 0.0
    if law.beta != 0.0:
        L = ws.mats[0]
        induced_slope(eps_end, law.beta, law.alpha_hat, law.beta_hat, L, ws.vecs[_V_S0:_V_S2 + 1])
        ell = ws.vecs[_V_ELL]
        for a in range(M):
            slip = ws.plane[a, _P_SLIP]
            cb = ws.plane[a, _P_CB]
            if slip == 0.0 and cb == 0.0:
                continue
            ef = ws.eta_f[a]
            ratio = ws.plane[a, _P_RATIO]
            dst = -law.cohesion[a] / (ef * ef)  # d sigma~ / d eta_f (the cohesion's shift c / eta_f)
            dr = -ratio / ws.plane[a, _P_ST] * dst  # d etah / d eta_f
            nn = law.nn6[a]
            m = ws.mvec[a]
            wt = law.weights[a] * law.inv_t
            if strong[a]:
                dg = dr - ws.plane[a, _P_ETA] / ef  # d g / d eta_f (eta is proportional to eta_f)
                cm = wt * cb * dg
            else:
                # d slip / d eta_f at fixed stress: (d etah / d eta_f - eta / eta_f) / (eta' + h)
                cm = wt * ws.plane[a, _P_KP] * (dr - ws.plane[a, _P_ETA] / ef)
            # d m / d eta_f = (d etah / d eta_f - eta_c_ratio (w + eta_f w' d sigma~ / d eta_f)) nn6
            wc, dwc = compaction_weight(ws.plane[a, _P_ST], law.compaction_stress)
            cn = wt * slip * (dr - law.eta_c_ratio * (wc + ef * dwc * dst))
            for j in range(6):
                acc = 0.0
                for i in range(6):
                    acc += nn[i] * L[i, j]
                ell[j] = ws.deta_f[a] * acc
            for i in range(6):
                ti = cm * m[i] + cn * nn[i]
                for j in range(6):
                    T[i, j] += ti * ell[j]
    col = ws.step
    for j in range(6):
        for i in range(6):
            col[i] = (1.0 if i == j else 0.0) - T[i, j]
        col[6] = 0.0
        _lu_solve(ws.J, ws.piv, col)
        for i in range(6):
            D_out[i, j] = col[i]
