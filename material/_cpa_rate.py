"""The rate problem of the CPA law at the start of a step, and the least step stabilisation that makes it unique.

At sigma_n the planes on their hardening curve may load or unload at the start of the step. Their slip rates
x >= 0 and overstress rates q - H x <= 0 are complementary, a linear complementarity problem in the coupling
matrix H of those planes (and of the mean-stress cut-off where it is on); :func:`_rate_active_set` solves it
by Lemke's method (:func:`_lemke`) to choose the branch of every plane on its kink, which the local Newton of
:mod:`material._cpa_local` then follows (:func:`material._cpa_point.point_update`). The problem has one
solution for every strain rate when H is a P-matrix; :func:`_uniqueness_floor` gives the least mu of the step
stabilisation that makes it one by a sufficient condition (the ``"minimal"`` stabilisation; ``docs/cpa_law.md``,
section 4).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from material._cpa_local import _V_COL, _V_S0, _V_S1, _V_S2, _level
from material._cpa_plane import NO_REFCOUNT, REFCOUNT, compaction_weight, plane_directions, plane_stress


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
#: plane on its kink (:data:`material._cpa_local._ON_CURVE`), and the equations are those of the plane.
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
    (:func:`material._cpa_local.inverse_shifted_normal_stress`; ``docs/cpa_law.md``, section 3)."""
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
