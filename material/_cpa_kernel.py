"""Batch kernels of the CPA law: the update of N Gauss points in parallel, strengths, Mandel conversions.

Pure functions over arrays: :mod:`material.cpa` validates the input, prepares the constants
(:class:`material._cpa_local.Law`) and calls :func:`cpa_batch`. The law is in five parts:
:mod:`material._cpa_plane` (one plane: strength, hardening, kinematics), :mod:`material._cpa_local` (the
local problem of one point and its semismooth Newton solver), :mod:`material._cpa_rate` (the rate problem at
the start of a step), :mod:`material._cpa_point` (the update of one point: the branch from the start of the
step, the consistent tangent, the continuation past limit points) and this module (the loop over points).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from material._cpa_local import Point, _ratios, inverse_shifted_normal_stress, make_workspace, plane_data
from material._cpa_plane import ISQ2, NO_REFCOUNT, SQ2, induced_tensor, plane_strengths
from material._cpa_point import make_path, update_past_limits
from material._cpa_rate import _rate_coupling, _uniqueness_floor, floor_units


@njit(cache=True, parallel=True, error_model="numpy")
def cpa_batch(law, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, D_out, loading,
              grad_out, status, iterations, halvings, reached, opening, mobilised, floor_mu, overstress, limits):
    """Update N Gauss points (Mandel vectors), in parallel over chunks of points.

    Inputs: ``law`` (:class:`material._cpa_local.Law`), ``opt`` (:class:`material._cpa_local.Options`),
    ``lim`` (:class:`material._cpa_local.Limits`: the continuation past limit points; ``max_points = 0``: none),
    sig_n, de, eps_n (N, 6) stress, strain increment, total strain at the start; kap_n (N, M) slips;
    soft (N,) softening slip scale of each point (0: none); c0 (N,), m_over and nl_shift (N, M): the implicit
    gradient's shift of the slip of the planes past their peak in this step, its m (0: no gradient) and the
    shift each plane has accumulated.
    Outputs: sig_out (N, 6), kap_out (N, M), D_out (N, 6, 6) (untouched without ``opt.tangent``),
    loading (N, M) bool, grad_out (N, 14) the gradient's S and derivatives
    (:func:`material._cpa_point.point_update`), status (N,) int8, iterations and halvings (N,) int32,
    reached (N,) the fraction of the increment a failed point reached (1 otherwise), opening (N,) plastic
    volumetric opening of the cut-off, mobilised (N,) the largest etah_a / eta_f,a, floor_mu (N,) the mu of the
    step stabilisation's floor at each point, overstress (N,) the stabilisation's overstress (the largest part
    h_a dkappa_a / etah_a of a loading plane's mobilised ratio that the floor carries), limits (N,) int32 the
    limit points each point's step passed (:func:`material._cpa_point.update_past_limits`).
    """
    N = sig_n.shape[0]
    M = kap_n.shape[1]
    nchunk = min(N, 64)
    block = (N + nchunk - 1) // max(nchunk, 1)
    for c in prange(nchunk):
        ws = make_workspace(M)
        path = make_path()
        pd = plane_data(law)
        _update_points(law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out,
                       D_out, loading, grad_out, status, iterations, halvings, reached, opening, mobilised, floor_mu,
                       overstress, limits, c * block, min(N, (c + 1) * block), ws, path)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _update_points(law, pd, opt, lim, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, D_out,
                   loading, grad_out, status, iterations, halvings, reached, opening, mobilised, floor_mu, overstress,
                   limits, start, stop, ws, path):
    """The points start..stop-1 of :func:`cpa_batch` with the workspace ``ws`` and the recorded path ``path``
    of one thread. (A function of its own, without reference counting, so that the rows of the point arrays
    it passes on cost no atomic count updates: :data:`material._cpa_plane.NO_REFCOUNT`.)"""
    for p in range(start, stop):
        st, its, hv, lam, dl, best, mu, over, nlim = update_past_limits(
            law, pd, opt, lim, sig_n[p], de[p], eps_n[p], kap_n[p], soft[p], c0[p], m_over, nl_shift[p], sig_out[p],
            kap_out[p], D_out[p], loading[p], grad_out[p], ws, path)
        status[p] = st
        iterations[p] = its
        halvings[p] = hv
        reached[p] = lam
        opening[p] = dl
        mobilised[p] = best
        floor_mu[p] = mu
        overstress[p] = over
        limits[p] = nlim


@njit(cache=True, error_model="numpy")
def uniqueness_floors(law, sig_n, eps_n, kap_n, soft, out):
    """The least mu of the step stabilisation for which the rate problem of each of N committed states is
    uniquely solvable by the sufficient condition of :func:`material._cpa_rate._uniqueness_floor` (0 where
    the thesis's law is), into ``out`` (N,). sig_n, eps_n (N, 6) Mandel, kap_n (N, M), soft (N,).
    (The implicit gradient's shifts are left out: the planes past their peak take their local level.)
    Serial: a diagnostic, and the same loop under ``parallel=True`` returned 0.0825 instead of 0.0822 at the
    near-failure point of the tests (the serial loop, the Python execution of it and the update agree)."""
    N = sig_n.shape[0]
    M = kap_n.shape[1]
    ws = make_workspace(M)
    pd = plane_data(law)
    lam6 = np.empty(6)
    inv_st = np.empty(M)
    unit = np.empty(M)
    zero6 = np.zeros(6)
    no_shift = np.zeros(M)
    for p in range(N):
        induced_tensor(eps_n[p], law.beta, law.alpha_hat, law.beta_hat, lam6)
        plane_strengths(law.nn6, law.omega6, lam6, law.coeffs, law.eta0, ws.eta_f, ws.deta_f)
        for a in range(M):
            ws.shift[a] = law.cohesion[a] / ws.eta_f[a] + law.apex_stress
            ws.strong[a] = kap_n[p, a] > law.A or (soft[p] > 0.0 and kap_n[p, a] >= law.kstar)
            ws.post[a] = False
            ws.floor[a] = 0.0
        inverse_shifted_normal_stress(sig_n[p], pd, ws.shift, law.apex_stress, inv_st, M)
        floor_units(law, inv_st, unit, M)
        pt = Point(sig_n[p], zero6, kap_n[p], soft[p], ws.eta_f, ws.shift, ws.strong, ws.select, ws.floor, 1.0,
                   ws.post, False, 0.0, 0.0, no_shift)
        out[p] = _uniqueness_floor(law, pt, ws, unit)


#: The strengthening kinds of :func:`loading_tangents` (``CPAModel.loading_tangent``).
STRENGTHENINGS = ("none", "plane", "sum", "plastic_strain", "back_stress")


@njit(cache=True, error_model="numpy")
def loading_tangents(law, sig_n, eps_n, kap_n, soft, nl_shift, m_over, kind, modulus, out):
    """The rate-independent loading tangent of each of N committed states, into ``out`` (N, 6, 6) Mandel.

    Every plane at or above its curve at sigma_n loads (:func:`material._cpa_rate._rate_coupling`: its
    eta' at the committed slip, the step stabilisation left out), at the rates x that solve H x = q,
    q_a = b_a . C d_eps; the stress rate is C d_eps - sum_b (w_b / t) C m_b x_b. With the implicit gradient
    (``m_over`` > 0) the planes past their peak take the gradient's shifted level ``nl_shift`` and, ebar
    held fixed, their coupling through S: H_ab -= m eta'_a for a and b past their peak. ``kind`` adds a
    strengthening of modulus ``modulus`` that a disturbance shorter than a nonlocal length would meet
    (:data:`STRENGTHENINGS`): 1 ``plane``, H_g delta_ab on each plane's own slip [1/m]; 2 ``sum``, H_g on
    the sum of the slips (one scalar field) [1/m]; 3 ``plastic_strain``, H_g (w_a / t)(w_b / t) m_a . m_b,
    on the plastic strain rate the slips make together [m]; 4 ``back_stress``, H_g (w_b / t) b_a . m_b, a
    back stress H_g (eps_p - ebar_p) [kPa] that every plane sees (its ratio taken at sigma - X): with
    associated flow (m_b = sigma~_b b_b) it keeps the rate problem symmetric after the row scaling
    w_a sigma~_a, where ``plastic_strain`` does not. (The mean-stress cut-off is left out.) A point
    whose H is singular gets NaN."""
    N = sig_n.shape[0]
    M = kap_n.shape[1]
    ws = make_workspace(M)
    lam6 = np.empty(6)
    zero6 = np.zeros(6)
    on = ws.basis
    H = np.empty((M, M))
    Q = np.empty((M, 6))
    cm = np.empty((M, 6))
    for p in range(N):
        induced_tensor(eps_n[p], law.beta, law.alpha_hat, law.beta_hat, lam6)
        plane_strengths(law.nn6, law.omega6, lam6, law.coeffs, law.eta0, ws.eta_f, ws.deta_f)
        coupled = False
        for a in range(M):
            ws.shift[a] = law.cohesion[a] / ws.eta_f[a] + law.apex_stress
            ws.strong[a] = kap_n[p, a] > law.A or (soft[p] > 0.0 and kap_n[p, a] >= law.kstar)
            ws.post[a] = m_over > 0.0 and soft[p] > 0.0 and kap_n[p, a] >= law.kstar
            coupled = coupled or ws.post[a]
            ws.floor[a] = 0.0
        pt = Point(sig_n[p], zero6, kap_n[p], soft[p], ws.eta_f, ws.shift, ws.strong, ws.select, ws.floor, 1.0,
                   ws.post, coupled, 0.0, m_over, nl_shift[p])
        n = _rate_coupling(law, pt, ws, on, False, False)
        for i in range(6):
            for j in range(6):
                out[p, i, j] = law.stiff[i, j]
        if n == 0:
            continue
        for ia in range(n):
            a = on[ia]
            wa = law.weights[a] * law.inv_t
            for jb in range(n):
                b = on[jb]
                h = -ws.tableau[ia, n + jb]
                if ws.post[a] and ws.post[b]:
                    h -= m_over * ws.dk_try[a]  # (eta' of plane a, _rate_coupling's scratch)
                if kind == 1 and ia == jb:
                    h += modulus
                elif kind == 2:
                    h += modulus
                elif kind == 3:
                    acc = 0.0
                    for i in range(6):
                        acc += ws.mvec[i, a] * ws.mvec[i, b]
                    h += modulus * wa * law.weights[b] * law.inv_t * acc
                elif kind == 4:
                    acc = 0.0
                    for i in range(6):
                        acc += ws.bvec[i, a] * ws.mvec[i, b]
                    h += modulus * law.weights[b] * law.inv_t * acc
                H[ia, jb] = h
            for i in range(6):
                qa = 0.0
                ca = 0.0
                for j in range(6):
                    qa += law.stiff[i, j] * ws.bvec[j, a]
                    ca += law.stiff[i, j] * ws.mvec[j, a]
                Q[ia, i] = qa
                cm[ia, i] = wa * ca
        try:
            Y = np.linalg.solve(H[:n, :n], Q[:n])
        except Exception:  # a singular rate problem: no loading tangent at this point
            out[p, :, :] = np.nan
            continue
        for ib in range(n):
            for i in range(6):
                for j in range(6):
                    out[p, i, j] -= cm[ib, i] * Y[ib, j]


@njit(cache=True, error_model="numpy")
def strengths(nn6, om6, coeffs, eta0, beta, ahat, bhat, eps6):
    """eta_f of every plane (N, M) for N total strains (N, 6) (eqs. 2.4, 3.14-3.15)."""
    N = eps6.shape[0]
    M = nn6.shape[0]
    out = np.empty((N, M))
    slope = np.empty(M)
    lam6 = np.empty(6)
    for p in range(N):
        induced_tensor(eps6[p], beta, ahat, bhat, lam6)
        plane_strengths(nn6, om6, lam6, coeffs, eta0, out[p], slope)
    return out


@njit(cache=True, error_model="numpy")
def ratios(law, sig6, eta_f):
    """Mobilised ratio etah_a of every plane (N, M) at N stresses (N, 6), with the strengths eta_f (N, M)."""
    N = sig6.shape[0]
    M = law.normals.shape[0]
    out = np.empty((N, M))
    shift = np.empty(M)
    for p in range(N):
        for a in range(M):
            shift[a] = law.cohesion[a] / eta_f[p, a] + law.apex_stress
        _ratios(law, sig6[p], shift, out[p])
    return out


# ---------------------------------------------------------------------------------------- Mandel


@njit(cache=True, error_model="numpy")
def to_mandel(a):
    """(N, 3, 3) symmetric -> (N, 6) Mandel (11, 22, 33, r 23, r 13, r 12)."""
    N = a.shape[0]
    out = np.empty((N, 6))
    for p in range(N):
        out[p, 0] = a[p, 0, 0]
        out[p, 1] = a[p, 1, 1]
        out[p, 2] = a[p, 2, 2]
        out[p, 3] = 0.5 * (a[p, 1, 2] + a[p, 2, 1]) * SQ2
        out[p, 4] = 0.5 * (a[p, 0, 2] + a[p, 2, 0]) * SQ2
        out[p, 5] = 0.5 * (a[p, 0, 1] + a[p, 1, 0]) * SQ2
    return out


@njit(cache=True, error_model="numpy")
def from_mandel(v):
    """(N, 6) Mandel -> (N, 3, 3) symmetric."""
    N = v.shape[0]
    out = np.empty((N, 3, 3))
    for p in range(N):
        out[p, 0, 0] = v[p, 0]
        out[p, 1, 1] = v[p, 1]
        out[p, 2, 2] = v[p, 2]
        out[p, 1, 2] = out[p, 2, 1] = v[p, 3] * ISQ2
        out[p, 0, 2] = out[p, 2, 0] = v[p, 4] * ISQ2
        out[p, 0, 1] = out[p, 1, 0] = v[p, 5] * ISQ2
    return out


@njit(cache=True, error_model="numpy")
def plastic_increment(de, sig, sig_n, comp):
    """The plastic strain increments (N, 3, 3) d_eps - S (sigma - sigma_n) of N points, from the Mandel vectors
    de, sig, sig_n (N, 6) and the elastic compliance ``comp`` (6, 6): one pass, where the array expression
    (a matrix product and three temporaries) took a quarter of the update's wrapper and woke BLAS's threads."""
    N = de.shape[0]
    out = np.empty((N, 3, 3))
    v = np.empty(6)
    for p in range(N):
        for i in range(6):
            acc = 0.0
            for j in range(6):
                acc += (sig[p, j] - sig_n[p, j]) * comp[i, j]
            v[i] = de[p, i] - acc
        out[p, 0, 0] = v[0]
        out[p, 1, 1] = v[1]
        out[p, 2, 2] = v[2]
        out[p, 1, 2] = out[p, 2, 1] = v[3] * ISQ2
        out[p, 0, 2] = out[p, 2, 0] = v[4] * ISQ2
        out[p, 0, 1] = out[p, 1, 0] = v[5] * ISQ2
    return out


@njit(cache=True, error_model="numpy")
def tangent_from_mandel(D):
    """(N, 6, 6) Mandel tangent -> (N, 3, 3, 3, 3) with both minor symmetries."""
    N = D.shape[0]
    out = np.empty((N, 3, 3, 3, 3))
    idx_i = (0, 1, 2, 1, 0, 0)
    idx_j = (0, 1, 2, 2, 2, 1)
    for p in range(N):
        for I in range(6):
            wi = 1.0 if I < 3 else ISQ2
            i, j = idx_i[I], idx_j[I]
            for K in range(6):
                wk = 1.0 if K < 3 else ISQ2
                k, l = idx_i[K], idx_j[K]
                v = D[p, I, K] * wi * wk
                out[p, i, j, k, l] = v
                out[p, j, i, k, l] = v
                out[p, i, j, l, k] = v
                out[p, j, i, l, k] = v
    return out
