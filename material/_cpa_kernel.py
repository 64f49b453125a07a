"""Numba kernels of the microplane CPA law: implicit stress update and consistent tangent.

Pure functions over arrays (STYLE.md): no Python objects, no I/O. :mod:`material.cpa` validates the
input, prepares the plane data and calls :func:`cpa_batch`.

Notation inside the kernel (MODEL.md, "Integration at a Gauss point")
-----------------------------------------------------------------------
Symmetric tensors are Mandel 6-vectors ``v = (a11, a22, a33, r a23, r a13, r a12)``, ``r = sqrt(2)``,
so that ``a : b = v_a . v_b`` and a symmetric 4th-order map is a 6x6 matrix. Stress is tension
positive; on a plane with unit normal ``n`` the normal traction is compression positive,
``sigma_N = -n.sigma.n``.

The implicit (backward Euler) step solves for the end-of-step stress. With the hardening law (2.16)
inverted, the slip of a loading plane is an explicit function of the stress, and the step is the
strain residual (strain units)::

    R(sigma) = S : (sigma - sigma_n) + d_eps_p(sigma) - d_eps = 0
    d_eps_p  = (1/t) sum_a w_a sym(dg_a (x) n_a)                           (2.9)
    dg_a     = dkappa_a [ s_a - (eta_c,a - tau_a / (sigma_N,a + sigma0_a)) n_a ]   (2.7, 2.17)
    dkappa_a = max(0, A etah_a / (zeta eta_f,a - etah_a) - kappa_n,a)       (2.16 inverted)
    etah_a   = (tau_a - c_a) / sigma_N,a                                    (mobilised ratio)

``S`` the elastic compliance (isotropic Hooke, 2.11-2.15 normalised to it), ``w_a`` the plane weights
(sum 1, +-n folded), ``t`` the band thickness. Solving R(sigma) = 0 directly meets the barrier
etah_a -> zeta eta_f,a where kappa -> inf, and Newton stalls near failure. So Newton runs on the
stress AND the slips of the loading planes, with the hardening law as an equation per plane,
``g_a = etah_a(sigma) - zeta eta_f kappa_a / (A + kappa_a) = 0``; each d kappa_a is eliminated from the
linearised system plane by plane, leaving a 6x6 system (:func:`_assemble`). An active-set update
(planes start or stop loading) runs at every iteration, and a backtracking line search on
``|R|^2/|d_eps|^2 + sum g^2`` keeps the iterates admissible. At the solution the condensed matrix is
the Jacobian dR/dsigma, so the consistent tangent is dsigma/d(d_eps) = J^-1 (I - dR/d eps |_sigma),
the second term from the strain dependence of eta_f through the induced tensor Lambda = beta dev(eps)
(3.14-3.15). When a step does not converge it is split into 2, 4, ... equal sub-steps; the tangent
is then carried through the sub-steps by the chain rule (sensitivities of sigma and of every kappa_a
with respect to the total increment), so it stays consistent with the algorithm actually used.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

SQ2 = np.sqrt(2.0)
ISQ2 = 1.0 / np.sqrt(2.0)

# status codes (material.base)
_OK = 0
_SUBSTEPPED = 1
_FAILED = 2

# integer options, packed in one array: see cpa_batch
_I_MAXIT = 0
_I_MAX_LEVEL = 1
_I_TANGENT = 2
# float options
_F_TOL = 0
_F_TOL_G = 1
_F_CUTOFF_STIFFNESS = 2


@njit(cache=True, inline="always")
def _traction(sig, n0, n1, n2):
    """t = sigma n for a Mandel stress vector."""
    s11, s22, s33 = sig[0], sig[1], sig[2]
    s23, s13, s12 = sig[3] * ISQ2, sig[4] * ISQ2, sig[5] * ISQ2
    return (s11 * n0 + s12 * n1 + s13 * n2, s12 * n0 + s22 * n1 + s23 * n2, s13 * n0 + s23 * n1 + s33 * n2)


@njit(cache=True, inline="always")
def _sym_mandel(out, a0, a1, a2, n0, n1, n2):
    """out = Mandel(sym(a (x) n))."""
    out[0] = a0 * n0
    out[1] = a1 * n1
    out[2] = a2 * n2
    out[3] = (a1 * n2 + a2 * n1) * ISQ2
    out[4] = (a0 * n2 + a2 * n0) * ISQ2
    out[5] = (a0 * n1 + a1 * n0) * ISQ2


@njit(cache=True)
def _series_and_slope(x, coeffs):
    """1 + x + a1 x^2 + a2 x^3 + ... and its derivative in x (eq. 2.4)."""
    val = 1.0 + x
    der = 1.0
    xp = x  # x^(k+1) for coefficient a_k
    for k in range(coeffs.shape[0]):
        der += (k + 2) * coeffs[k] * xp
        xp *= x
        val += coeffs[k] * xp
    return val, der


@njit(cache=True)
def _lambda6(eps6, beta, ahat, bhat, out):
    """Induced tensor Lambda (Mandel) for the total strain eps6 (eqs. 3.8, 3.15).

    Lambda = beta |e| n^Omega, n^Omega = alpha_hat n^e + beta_hat dev(n^e n^e) normalised; with
    beta_hat = 0 (alpha_hat > 0) exactly beta e.
    """
    tr3 = (eps6[0] + eps6[1] + eps6[2]) / 3.0
    norm = 0.0
    for i in range(6):
        e = eps6[i] - tr3 if i < 3 else eps6[i]
        out[i] = e
        norm += e * e
    norm = np.sqrt(norm)
    if bhat == 0.0 and ahat > 0.0:
        for i in range(6):
            out[i] *= beta
        return
    if norm == 0.0:
        for i in range(6):
            out[i] = 0.0
        return
    # n^e as a 3x3 matrix, its square, the deviator of the square
    a11, a22, a33 = out[0] / norm, out[1] / norm, out[2] / norm
    a23, a13, a12 = out[3] / norm * ISQ2, out[4] / norm * ISQ2, out[5] / norm * ISQ2
    q11 = a11 * a11 + a12 * a12 + a13 * a13
    q22 = a12 * a12 + a22 * a22 + a23 * a23
    q33 = a13 * a13 + a23 * a23 + a33 * a33
    q23 = a12 * a13 + a22 * a23 + a23 * a33
    q13 = a11 * a13 + a12 * a23 + a13 * a33
    q12 = a11 * a12 + a12 * a22 + a13 * a23
    qt = (q11 + q22 + q33) / 3.0
    d0 = ahat * a11 + bhat * (q11 - qt)
    d1 = ahat * a22 + bhat * (q22 - qt)
    d2 = ahat * a33 + bhat * (q33 - qt)
    d3 = (ahat * a23 + bhat * q23) * SQ2
    d4 = (ahat * a13 + bhat * q13) * SQ2
    d5 = (ahat * a12 + bhat * q12) * SQ2
    dn = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3 + d4 * d4 + d5 * d5)
    if dn == 0.0:
        for i in range(6):
            out[i] = 0.0
        return
    f = beta * norm / dn
    out[0], out[1], out[2], out[3], out[4], out[5] = f * d0, f * d1, f * d2, f * d3, f * d4, f * d5


@njit(cache=True)
def _lambda_and_slope(eps6, beta, ahat, bhat, lam6, L, scratch):
    """Lambda (6,) and L = d Lambda / d eps (6, 6), Mandel. L is exact for the linear law (beta P_dev);
    for the general law (3.8) it is a central difference with step 1e-5 |e| (Lambda is homogeneous of
    degree one in e, so the relative error is ~1e-10), and beta P_dev at e = 0."""
    _lambda6(eps6, beta, ahat, bhat, lam6)
    tr = 0.0
    norm = 0.0
    for i in range(6):
        e = eps6[i] - (eps6[0] + eps6[1] + eps6[2]) / 3.0 if i < 3 else eps6[i]
        norm += e * e
    norm = np.sqrt(norm)
    if (bhat == 0.0 and ahat > 0.0) or norm == 0.0:
        for i in range(6):
            for j in range(6):
                L[i, j] = beta * ((1.0 if i == j else 0.0) - (1.0 / 3.0 if (i < 3 and j < 3) else 0.0))
        return
    h = 1e-5 * norm
    ep = scratch[0]
    lp = scratch[1]
    lm = scratch[2]
    for j in range(6):
        for i in range(6):
            ep[i] = eps6[i]
        ep[j] += h
        _lambda6(ep, beta, ahat, bhat, lp)
        ep[j] -= 2.0 * h
        _lambda6(ep, beta, ahat, bhat, lm)
        for i in range(6):
            L[i, j] = (lp[i] - lm[i]) / (2.0 * h)


@njit(cache=True)
def _plane_strengths(normals6, om6, lam6, coeffs, eta0, eta_f, deta_f):
    """eta_f,a and d eta_f,a / d x_a with x_a = n_a.(Omega + Lambda).n_a (eqs. 2.4, 3.14)."""
    for a in range(normals6.shape[0]):
        x = 0.0
        for i in range(6):
            x += normals6[a, i] * (om6[i] + lam6[i])
        val, der = _series_and_slope(x, coeffs)
        eta_f[a] = eta0 * val
        deta_f[a] = eta0 * der


@njit(cache=True)
def _assemble(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion, eta_f, zeta, A, inv_t, eta_c_ratio,
              comp, update_active, want_jac, active, r, J, rhs, work, bvec, tmp, de_norm, k_explicit, h_on, sp):
    """Residuals and the condensed Newton system at the iterate (sig, kap).

    Two kinds of loading planes. A weakly mobilised plane (kappa_n <= A, i.e. eta(kappa_n) <= zeta
    eta_f / 2) takes its slip from the inverted hardening law, kappa_a = A etah_a / (zeta eta_f - etah_a):
    smooth where the shear traction vanishes (the slip vector dkappa s is then ~ t_s), which matters for
    tiny increments from states with unsheared planes; it must stay inside the barrier etah < zeta
    eta_f. A strongly mobilised plane (kappa_n > A) keeps kappa_a as an unknown with the hardening law
    as its equation, so nothing is singular as it approaches failure:

    Unknowns: the stress and the slip kappa_a of every such plane. Residuals: the strain residual
    ``r = S (sigma - sigma_n) + (1/t) sum_a w_a (kappa_a - kappa_n,a) m_a - d_eps`` with
    ``m_a = sym((s_a - dil_a n_a) (x) n_a)`` (2.7, 2.9), and on each loading plane the hardening law
    (2.16) ``g_a = etah_a(sigma) - zeta eta_f kappa_a / (A + kappa_a) = 0``. Linearising g_a gives
    ``d kappa_a = (g_a + b_a . d sigma) / eta'_a`` (b_a = d etah_a / d sigma), which condenses the system
    to ``J d sigma = rhs`` with ``J = S + sum_a (w_a/t) [dkappa_a dm_a/dsigma + m_a (x) b_a / eta'_a]``
    and ``rhs = -r - sum_a (w_a/t) m_a g_a / eta'_a`` (for an explicit plane g = 0 and 1/eta' is
    d kappa / d etah, the same terms). At a solution J is the Jacobian of the stress-only residual, so
    its inverse is the consistent tangent.

    ``update_active`` (strongly mobilised planes; explicit planes switch by themselves) 1: an elastic
    plane whose etah exceeds eta(kappa_n) starts loading (kappa from kappa_n), a loading plane whose kappa
    fell below kappa_n unloads; 2: only report (``changed``) whether such a switch is due; 0: frozen. Returns (admissible, merit,
    changed, |r|, max |g|); merit = |r|^2 / |d_eps|^2 + sum g^2. ``work[a]`` receives sigma_N, tau, etah,
    q, dil, 1/eta', g; ``bvec[a]`` receives b_a.
    """
    M = normals.shape[0]
    for i in range(6):
        acc = -de[i]
        for j in range(6):
            acc += comp[i, j] * (sig[j] - sig_n[j])
        r[i] = acc
        rhs[i] = 0.0
    if want_jac:
        for i in range(6):
            for j in range(6):
                J[i, j] = comp[i, j]
    smax = 0.0
    for i in range(6):
        smax = max(smax, abs(sig[i]))
    tau_tiny = 1e-13 * (smax + 1e-300)
    merit_g = 0.0
    gmax = 0.0
    changed = False
    for a in range(M):
        n0, n1, n2 = normals[a, 0], normals[a, 1], normals[a, 2]
        t0, t1, t2 = _traction(sig, n0, n1, n2)
        tn = t0 * n0 + t1 * n1 + t2 * n2
        sigma_N = -tn  # compression positive
        ts0, ts1, ts2 = t0 - tn * n0, t1 - tn * n1, t2 - tn * n2
        tau = np.sqrt(ts0 * ts0 + ts1 * ts1 + ts2 * ts2)
        c = cohesion[a]
        ef = eta_f[a]
        zef = zeta * ef
        kn = kap_n[a]
        # explicit (inverted law) plane: weakly mobilised, and before its peak when it can soften
        explicit = kn <= k_explicit and not (sp[1] > 0.0 and kn >= sp[0])
        if sigma_N <= 0.0 or tau <= tau_tiny:
            if active[a] and not explicit:
                if update_active != 1:
                    return False, np.inf, changed, np.inf, np.inf
                changed = True  # a loading plane that lost its compression or its shear unloads
            active[a] = False
            kap[a] = kn
            if sigma_N <= 0.0 and (tau > c + tau_tiny or sigma_N < -c / ef - tau_tiny):
                # tension side: no normal tension beyond the apex sigma0 = c / eta_f, and no shear above
                # the cohesion on a plane that is not compressed (MODEL.md, tension cut-off)
                return False, np.inf, changed, np.inf, np.inf
            continue
        etah = (tau - c) / sigma_N  # mobilised ratio
        if explicit:
            # weakly mobilised plane (eta(kappa_n) <= zeta eta_f / 2): explicit inverse law, kappa(etah),
            # smooth even where tau -> 0 (dkappa s ~ t_s), admissible only inside the barrier (below the
            # peak eta_f, where the inverse holds, when the plane can soften)
            if etah >= (ef if sp[1] > 0.0 else zef) * (1.0 - 1e-9):
                return False, np.inf, changed, np.inf, np.inf
            # in the last-resort attempt (wide hysteresis, _solve_substep) the law is shifted by the same
            # band, kappa(etah - h_on zeta eta_f): continuous, and a plane that starts on its kink stays
            # elastic under an increment too small to load it by more than the band
            e = etah - (zef * h_on if h_on >= _H_ON_WIDE else 0.0)  # (the band of the last resort)
            if tau <= tau_tiny or e < zef * kn / (A + kn):
                active[a] = False
                kap[a] = kn
                continue
            active[a] = True
            kap[a] = A * e / (zef - e)
            dk = kap[a] - kn
            if dk < 0.0:
                dk = 0.0
            kprime = A * zef / ((zef - e) * (zef - e))  # d kappa / d etah
            g = 0.0
        else:
            dk, kprime, g = _implicit_plane(a, update_active, active, kap, kn, etah, ef, zef, A, h_on, sp)
            if dk == _INADMISSIBLE:
                return False, np.inf, changed, np.inf, np.inf
            if dk == _SWITCHED:
                changed = True
                continue
            if dk == _SWITCH_DUE:
                changed = True
            if not active[a]:
                continue
            dk = kap[a] - kn
        _plane_terms(a, dk, kprime, g, sigma_N, tau, etah, ts0, ts1, ts2, c, ef, n0, n1, n2, nn6, weights, inv_t,
                     eta_c_ratio, want_jac, r, J, rhs, work, bvec, tmp)
        merit_g += g * g
        gmax = max(gmax, abs(g))
    rn = 0.0
    for i in range(6):
        rn += r[i] * r[i]
        rhs[i] = -r[i] - rhs[i]
    merit = rn / (de_norm * de_norm + 1e-300) + merit_g
    return True, merit, changed, np.sqrt(rn), gmax


_INADMISSIBLE = -1e300
_SWITCHED = -2e300
_SWITCH_DUE = -3e300


@njit(cache=True, inline="always")
def _implicit_plane(a, update_active, active, kap, kn, etah, ef, zef, A, h_on, sp):
    """Active-set logic and hardening residual of a strongly mobilised plane (kappa an unknown).

    Returns (code or 0, 1/eta'(kappa), g); the code is _SWITCHED when the plane was switched on or off
    here (mode 1; a plane switched on starts at kappa_n), _SWITCH_DUE when a switch is due (mode 2),
    _INADMISSIBLE when kappa left the range A + kappa > 0.
    """
    code = 0.0
    if update_active != 0:
        # switches with a small hysteresis (1e-12 in kappa/A to switch off, h_on zeta eta_f of overstress
        # to switch on, h_on = _H_ON = 1e-7 normally), so that a plane that sits on its loading/unloading
        # kink under a tiny increment cannot flip at every iteration (the classical cycling of
        # multi-surface return mappings); the overstress it may keep is physically negligible
        if active[a]:
            if kap[a] < kn - 1e-12 * (A + kn):
                if update_active == 1:
                    active[a] = False
                    kap[a] = kn
                    return _SWITCHED, 0.0, 0.0
                code = _SWITCH_DUE
        elif etah > _hardening(kn, ef, zef, A, sp)[0] + zef * h_on:  # loading beyond the level reached (2.16)
            if update_active == 1:
                active[a] = True
                kap[a] = kn
            else:
                return _SWITCH_DUE, 0.0, 0.0
            code = _SWITCH_DUE
    if not active[a]:
        return code, 0.0, 0.0
    k = kap[a]
    if k <= -0.5 * A:
        # an iterate may take kappa below kappa_n (the plane is about to unload; the next active-set
        # update switches it off) but must keep A + kappa > 0 for the hardening curve to make sense
        return _INADMISSIBLE, 0.0, 0.0
    eta, deta = _hardening(k, ef, zef, A, sp)
    if deta == 0.0:
        return _INADMISSIBLE, 0.0, 0.0
    return code, 1.0 / deta, etah - eta  # hardening law (2.16) residual


@njit(cache=True, inline="always")
def _hardening(k, ef, zef, A, sp):
    """eta(kappa) and d eta / d kappa of a plane: the hyperbola (2.16) up to kappa* = sp[0], then
    (sp[1] = softening slip scale of this point > 0) the hyperbolic decay to sp[2] eta_f,
    eta = eta_f (r + (1 - r) / (1 + (kappa - kappa*) / s)). Both are proportional to eta_f.

    The law is continuous with a kink at its peak kappa*; :func:`_newton` stops an iterate that would
    carry a plane across kappa* exactly there, so that Newton never linearises across the kink."""
    if sp[1] > 0.0 and k >= sp[0]:
        x = 1.0 + (k - sp[0]) / sp[1]
        if x <= 1e-3:
            return 0.0, 0.0  # far below the start of the softening branch: not admissible
        r = sp[2]
        return ef * (r + (1.0 - r) / x), -ef * (1.0 - r) / (sp[1] * x * x)
    apk = A + k
    return zef * k / apk, zef * A / (apk * apk)


@njit(cache=True, inline="always")
def _plane_terms(a, dk, kprime, g, sigma_N, tau, etah, ts0, ts1, ts2, c, ef, n0, n1, n2, nn6, weights, inv_t,
                 eta_c_ratio, want_jac, r, J, rhs, work, bvec, tmp):
    """Add a loading plane's flow (2.7, 2.9) to the residual and its terms to the condensed system."""
    sn6 = tmp[0]
    mn6 = tmp[1]
    v1 = tmp[2]
    v2 = tmp[3]
    s0, s1, s2 = ts0 / tau, ts1 / tau, ts2 / tau
    sig0 = c / ef
    q = tau / (sigma_N + sig0)
    dil = eta_c_ratio * ef - q  # d psi / d sigma_N (2.17): > 0 compaction, < 0 dilation
    work[a, 0] = sigma_N
    work[a, 1] = tau
    work[a, 2] = etah
    work[a, 3] = q
    work[a, 4] = dil
    work[a, 5] = kprime
    work[a, 6] = g
    wt = weights[a] * inv_t
    _sym_mandel(sn6, s0, s1, s2, n0, n1, n2)
    for i in range(6):
        r[i] += wt * dk * (sn6[i] - dil * nn6[a, i])
    if want_jac:
        m0 = n1 * s2 - n2 * s1
        m1 = n2 * s0 - n0 * s2
        m2 = n0 * s1 - n1 * s0
        _sym_mandel(mn6, m0, m1, m2, n0, n1, n2)
        inv_sn = 1.0 / sigma_N
        for j in range(6):
            v1[j] = sn6[j] + etah * nn6[a, j]  # sigma_N d etah / d sigma
            v2[j] = sn6[j] + q * nn6[a, j]     # (sigma_N + sigma0) dq / d sigma
            bvec[a, j] = v1[j] * inv_sn
        cg = wt * kprime * inv_sn
        ch = wt * dk / (sigma_N + sig0)
        cm = wt * dk / tau
        for i in range(6):
            mi_ = sn6[i] - dil * nn6[a, i]
            rhs[i] += wt * mi_ * g * kprime
            gi = cg * mi_
            hi = ch * nn6[a, i]
            mi = cm * mn6[i]
            for j in range(6):
                J[i, j] += gi * v1[j] + hi * v2[j] + mi * mn6[j]


@njit(cache=True)
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


@njit(cache=True)
def _lu_solve(LU, piv, b):
    """Solve in place for one right-hand side b (6,)."""
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


@njit(cache=True)
def _is_strictly_compressive(sig, normals):
    smax = 0.0
    for i in range(6):
        smax = max(smax, abs(sig[i]))
    if smax == 0.0:
        return False
    for a in range(normals.shape[0]):
        n0, n1, n2 = normals[a, 0], normals[a, 1], normals[a, 2]
        t0, t1, t2 = _traction(sig, n0, n1, n2)
        if -(t0 * n0 + t1 * n1 + t2 * n2) <= 1e-10 * smax:
            return False
    return True


@njit(cache=True)
def _newton(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion, eta_f, zeta, A, inv_t, eta_c_ratio,
            comp, tol, tol_g, maxit, de_norm, active, r, J, rhs, work, bvec, tmp, piv, dk_step, sig_try, kap_try,
            k_explicit, h_on, sp):
    """Newton on (sigma, kappa) from the given iterate, with an active-set update at each iteration and a
    backtracking line search on the merit function (active set frozen). Returns (ok, iterations);
    on success J holds the LU factors of the condensed Jacobian at the solution."""
    M = normals.shape[0]
    ok, merit, changed, rn, gmax = _assemble(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion, eta_f,
                                             zeta, A, inv_t, eta_c_ratio, comp, 1, True, active, r, J, rhs, work,
                                             bvec, tmp, de_norm, k_explicit, h_on, sp)
    dsig = tmp[4]
    # round-off floor of |r|: S (sigma - sigma_n) is computed from stresses of size |sigma|, so |r| cannot
    # go below ~1e-16 |S| |sigma|; a tiny increment would otherwise ask for less than round-off
    smax = 0.0
    for i in range(6):
        smax = max(smax, abs(sig_n[i]), abs(sig[i]))
    cmax = 0.0
    for i in range(6):
        cmax = max(cmax, abs(comp[i, i]))
    r_floor = 1e-13 * smax * cmax
    for it in range(maxit + 1):
        if not ok:
            return False, it
        if not changed and rn <= tol * de_norm + r_floor and gmax <= tol_g:
            return _lu_factor(J, piv), it
        if it == maxit or not _lu_factor(J, piv):
            return False, it
        for i in range(6):
            dsig[i] = rhs[i]
        _lu_solve(J, piv, dsig)
        for a in range(M):
            if active[a]:
                acc = work[a, 6]
                for j in range(6):
                    acc += bvec[a, j] * dsig[j]
                dk_step[a] = acc * work[a, 5]
            else:
                dk_step[a] = 0.0
        # a plane about to pass the peak of a softening law (kappa*) stops exactly on it: the step is
        # shortened to the first such breakpoint, taken without the descent test (the merit function
        # has a kink there), and the next iteration linearises the softening branch
        alpha = 1.0
        brk = -1
        if sp[1] > 0.0:
            for a in range(M):
                if active[a] and kap[a] < sp[0] and kap[a] + dk_step[a] > sp[0]:
                    f = (sp[0] - kap[a]) / dk_step[a]
                    if f < alpha:
                        alpha = f
                        brk = a
        # line search with the active set frozen; the evaluation that is accepted also provides the
        # residuals and the Jacobian of the next iteration unless a plane is due to switch
        accepted = False
        for _ls in range(40):
            for i in range(6):
                sig_try[i] = sig[i] + alpha * dsig[i]
            for a in range(M):
                kap_try[a] = kap[a] + alpha * dk_step[a]
            if brk >= 0:
                kap_try[brk] = sp[0]
            ok2, merit2, due, rn2, gmax2 = _assemble(sig_try, kap_try, sig_n, de, kap_n, normals, nn6, weights,
                                                     cohesion, eta_f, zeta, A, inv_t, eta_c_ratio, comp, 2, True,
                                                     active, r, J, rhs, work, bvec, tmp, de_norm, k_explicit, h_on, sp)
            if ok2 and (brk >= 0 or merit2 <= (1.0 - 1e-4 * alpha) * merit):
                accepted = True
                break
            alpha *= 0.5
            brk = -1
        if not accepted:
            return False, it
        for i in range(6):
            sig[i] = sig_try[i]
        for a in range(M):
            kap[a] = kap_try[a]
        if due:
            ok, merit, changed, rn, gmax = _assemble(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion,
                                                     eta_f, zeta, A, inv_t, eta_c_ratio, comp, 1, True, active, r,
                                                     J, rhs, work, bvec, tmp, de_norm, k_explicit, h_on, sp)
        else:
            ok, merit, changed, rn, gmax = True, merit2, False, rn2, gmax2
    return False, maxit


@njit(cache=True)
def _solve_substep(sig_n, de, kap_n, eta_f, normals, nn6, weights, cohesion, zeta, A, inv_t, eta_c_ratio,
                   comp, stiff, tol, tol_g, maxit, sig, J, active, dkap, work, r, piv, delta, trial, tmp, pred,
                   kap, bvec, dk_step, kap_try, last_resort, sp):
    """One (sub)step with the hybrid local Newton (planes with kappa_n > A keep kappa as an unknown);
    if that fails, once more with every plane explicit (the stress-only form, kappa = kappa(etah)),
    which resolves the active-set cycling of planes that sit exactly on their loading/unloading kink
    under a tiny increment. Returns (ok, iterations).

    ``last_resort`` (after the normal adaptive sub-stepping failed, with uniform sub-steps from the
    finest size up): if both fail, a third attempt with a wider switch-on hysteresis, h_wide zeta eta_f
    instead of _H_ON (h_wide below). It resolves the case where the local problem of non-associated multi-plane
    flow has no consistent active set for the increment (a plane loads when it is elastic and unloads
    when it is loading: the active-set loop cycles for ever); the plane then stays elastic for this
    sub-step with an overstress below h_wide zeta eta_f sigma_N (the change of the ratio one sub-step
    makes: a first-order error, at most 1 %), which the next increment removes as soon as it loads the
    plane by more.
    """
    ok, its = _solve_substep_k(sig_n, de, kap_n, eta_f, normals, nn6, weights, cohesion, zeta, A, inv_t,
                               eta_c_ratio, comp, stiff, tol, tol_g, maxit, sig, J, active, dkap, work, r, piv,
                               delta, trial, tmp, pred, kap, bvec, dk_step, kap_try, A, _H_ON, sp)
    if ok:
        return ok, its
    ok, its2 = _solve_substep_k(sig_n, de, kap_n, eta_f, normals, nn6, weights, cohesion, zeta, A, inv_t,
                                eta_c_ratio, comp, stiff, tol, tol_g, maxit, sig, J, active, dkap, work, r, piv,
                                delta, trial, tmp, pred, kap, bvec, dk_step, kap_try, np.inf, _H_ON, sp)
    its += its2
    if ok or not last_resort:
        return ok, its
    # the band: _H_ON_WIDE, or 1.5 x the largest change of a mobilised ratio the elastic trial makes, or
    # just above the overstress a plane already carries from an earlier last resort, at most _H_ON_CAP
    # (1 % of the strength: no plane overstressed by more stays elastic). At low stress the plastic
    # compliance of a plane, ~ (w/t)(A/eta_f)/sigma_N, dwarfs the elastic one and a tiny increment moves
    # etah across the kink by more than _H_ON_WIDE.
    h_wide = max(_H_ON_WIDE, min(_last_resort_band(sig_n, de, stiff, normals, cohesion, eta_f, zeta, trial, kap_n, A,
                                                   sp), _H_ON_CAP))
    ok, its2 = _solve_substep_k(sig_n, de, kap_n, eta_f, normals, nn6, weights, cohesion, zeta, A, inv_t,
                                eta_c_ratio, comp, stiff, tol, tol_g, maxit, sig, J, active, dkap, work, r, piv,
                                delta, trial, tmp, pred, kap, bvec, dk_step, kap_try, A, h_wide, sp)
    return ok, its + its2


@njit(cache=True, inline="always")
def _ratio(sig, n0, n1, n2, c):
    """Mobilised ratio (tau - c) / sigma_N of the plane n at the stress sig; NaN unless compressed."""
    t0, t1, t2 = _traction(sig, n0, n1, n2)
    tn = t0 * n0 + t1 * n1 + t2 * n2
    if -tn <= 0.0:
        return np.nan
    ts0, ts1, ts2 = t0 - tn * n0, t1 - tn * n1, t2 - tn * n2
    return (np.sqrt(ts0 * ts0 + ts1 * ts1 + ts2 * ts2) - c) / (-tn)


@njit(cache=True)
def _last_resort_band(sig_n, de, stiff, normals, cohesion, eta_f, zeta, trial, kap_n, A, sp):
    """max over the compressed planes of 1.5 |etah_a(elastic trial) - etah_a(sigma_n)| and
    1.01 (etah_a(sigma_n) - eta(kappa_n,a)), both over zeta eta_f,a."""
    for i in range(6):
        acc = sig_n[i]
        for j in range(6):
            acc += stiff[i, j] * de[j]
        trial[i] = acc
    big = 0.0
    for a in range(normals.shape[0]):
        n0, n1, n2 = normals[a, 0], normals[a, 1], normals[a, 2]
        zef = zeta * eta_f[a]
        e_n = _ratio(sig_n, n0, n1, n2, cohesion[a])
        d = 1.5 * abs(_ratio(trial, n0, n1, n2, cohesion[a]) - e_n) / zef
        over = 1.01 * (e_n - _hardening(kap_n[a], eta_f[a], zef, A, sp)[0]) / zef
        # (NaN, a plane in tension at either end, compares false)
        if d > big:
            big = d
        if over > big:
            big = over
    return big


# switch-on hysteresis of a strongly mobilised plane (overstress in units of zeta eta_f), see
# _implicit_plane and _solve_substep
_H_ON = 1e-7
_H_ON_WIDE = 1e-4
_H_ON_CAP = 1e-2
# a point that fails to integrate with a stress below _APEX_FLOOR x its elastic stiffness goes to the apex
_APEX_FLOOR = 1e-4


@njit(cache=True)
def _solve_substep_k(sig_n, de, kap_n, eta_f, normals, nn6, weights, cohesion, zeta, A, inv_t, eta_c_ratio,
                     comp, stiff, tol, tol_g, maxit, sig, J, active, dkap, work, r, piv, delta, trial, tmp, pred,
                     kap, bvec, dk_step, kap_try, k_explicit, h_on, sp):
    """One (sub)step: elastic trial, else Newton on (sigma, kappa). Returns (ok, iterations).

    ``pred`` (6, 6) is the consistent tangent of the point's previous plastic step (pred[0, 0] == 0 when
    there is none). A point that was plastic in its last step most likely goes on loading, so Newton
    first starts from the predictor sigma_n + pred : d_eps with every loading plane put on its hardening
    curve; otherwise (or if that fails) the elastic trial decides, and Newton starts from it with kappa_n
    (the classical return from the trial state), or from sigma_n when the trial is not admissible.
    On success sig holds the stress, J the LU factors of the Jacobian, active/dkap/work the planes.
    """
    M = normals.shape[0]
    de_norm = 0.0
    for i in range(6):
        de_norm += de[i] * de[i]
    de_norm = np.sqrt(de_norm)
    sig_try = tmp[5]
    its = 0
    if pred[0, 0] != 0.0:
        for i in range(6):
            acc = sig_n[i]
            for j in range(6):
                acc += pred[i, j] * de[j]
            sig[i] = acc
        admissible = True
        for a in range(M):
            kap[a] = kap_n[a]
            active[a] = False
            etah = _ratio(sig, normals[a, 0], normals[a, 1], normals[a, 2], cohesion[a])
            if not etah == etah:  # NaN: a plane in tension
                admissible = False
                break
            zef = zeta * eta_f[a]
            if etah > _hardening(kap_n[a], eta_f[a], zef, A, sp)[0]:
                if sp[1] > 0.0 and kap_n[a] >= sp[0]:
                    kap[a] = kap_n[a]  # past its peak: loading, from kappa_n
                else:
                    e = min(etah, (eta_f[a] if sp[1] > 0.0 else zef) * (1.0 - 1e-6))
                    kap[a] = max(kap_n[a], A * e / (zef - e))  # on the hardening curve (2.16)
                active[a] = True
        if admissible:
            ok, its = _newton(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion, eta_f, zeta, A, inv_t,
                              eta_c_ratio, comp, tol, tol_g, maxit, de_norm, active, r, J, delta, work, bvec, tmp,
                              piv, dk_step, sig_try, kap_try, k_explicit, h_on, sp)
            if ok:
                _finish_substep(kap, kap_n, active, dkap)
                return True, its
    # elastic trial
    for i in range(6):
        acc = sig_n[i]
        for j in range(6):
            acc += stiff[i, j] * de[j]
        trial[i] = acc
        sig[i] = acc
    for a in range(M):
        kap[a] = kap_n[a]
        active[a] = False
    ok, merit, changed, rn, gmax = _assemble(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion, eta_f,
                                             zeta, A, inv_t, eta_c_ratio, comp, 1, False, active, r, J, delta,
                                             work, bvec, tmp, de_norm, k_explicit, h_on, sp)
    any_active = False
    for a in range(M):
        any_active = any_active or active[a]
    if ok and not any_active:
        for i in range(6):
            for j in range(6):
                J[i, j] = comp[i, j]
        for a in range(M):
            dkap[a] = 0.0
        return _lu_factor(J, piv), its
    if not ok:
        # the trial stress puts some plane in tension: return from sigma_n (admissible by construction),
        # or from the isotropic part of the trial stress when sigma_n sits on the apex
        for a in range(M):
            kap[a] = kap_n[a]
            active[a] = False
        if _is_strictly_compressive(sig_n, normals):
            for i in range(6):
                sig[i] = sig_n[i]
        else:
            p = (trial[0] + trial[1] + trial[2]) / 3.0
            if p >= 0.0:
                return False, its
            for i in range(6):
                sig[i] = p if i < 3 else 0.0
    ok, its2 = _newton(sig, kap, sig_n, de, kap_n, normals, nn6, weights, cohesion, eta_f, zeta, A, inv_t,
                       eta_c_ratio, comp, tol, tol_g, maxit, de_norm, active, r, J, delta, work, bvec, tmp, piv,
                       dk_step, sig_try, kap_try, k_explicit, h_on, sp)
    if ok:
        _finish_substep(kap, kap_n, active, dkap)
    return ok, its + its2


@njit(cache=True)
def _finish_substep(kap, kap_n, active, dkap):
    for a in range(kap.shape[0]):
        dkap[a] = kap[a] - kap_n[a] if active[a] else 0.0


@njit(cache=True, inline="always")
def _mean_trial(sig, de, stiff):
    """Mean stress of the elastic trial sig + stiff : de (Mandel)."""
    p = 0.0
    for i in range(3):
        acc = sig[i]
        for j in range(6):
            acc += stiff[i, j] * de[j]
        p += acc / 3.0
    return p


@njit(cache=True)
def _point_update(sig_n, de, eps_n, kap_n, normals, nn6, weights, cohesion, om6, coeffs, eta0, beta, ahat, bhat,
                  zeta, A, inv_t, eta_c_ratio, comp, stiff, iopt, fopt,
                  sig_out, kap_out, D_out, bufs_f, bufs_b, piv, Dk, Dk_new, vecs, mats, pred, sp):
    """One Gauss point: adaptive sub-stepping around :func:`_solve_substep`, chain-rule tangent.

    Returns (status, substeps, iterations, cutoff).
    """
    M = normals.shape[0]
    maxit = iopt[_I_MAXIT]
    max_level = iopt[_I_MAX_LEVEL]
    want_tangent = iopt[_I_TANGENT] != 0
    tol = fopt[_F_TOL]
    tol_g = fopt[_F_TOL_G]
    eta_f = bufs_f[0, :M]
    deta_f = bufs_f[1, :M]
    dkap = bufs_f[2, :M]
    kap = bufs_f[3, :M]
    work = bufs_f[4:12, :M].T  # (M, 8) view
    kap_it = bufs_f[12, :M]
    dk_step = bufs_f[13, :M]
    kap_try = bufs_f[14, :M]
    bvec = bufs_f[15:21, :M].T  # (M, 6) view
    active = bufs_b[:M]
    sig = vecs[0]
    sig_prev = vecs[1]
    de_k = vecs[2]
    eps_k = vecs[3]
    r = vecs[4]
    delta = vecs[5]
    trial = vecs[6]
    col = vecs[7]
    sn6 = vecs[8]
    dx_de = vecs[9]
    lam6 = vecs[16]
    lam_scratch = vecs[17:20]
    Lam = mats[3]  # d Lambda / d eps (Mandel)
    tmp = vecs[10:16]
    J = mats[0]
    B = mats[1]
    Dsig = mats[2]
    total_it = 0
    s_last = np.inf
    # tension cut-off (MODEL.md "Tension"), first case: when the elastic trial stress has no compression
    # left (mean stress >= 0) no stress state of the cone can follow the increment
    if _mean_trial(sig_n, de, stiff) >= 0.0:
        _apex(sig_out, kap_out, D_out, kap_n, stiff, fopt[_F_CUTOFF_STIFFNESS], want_tangent)
        return _OK, 1, 0, True
    # Sub-steps are counted in units of the finest one, 2**-max_level of the increment. Attempt 0, the
    # normal active-set logic: the whole increment first; a sub-step that fails is halved (down to one
    # unit) and retried from the last converged state, and the rest of the increment goes on with the
    # size that worked (a point that meets a hard stretch late in its increment, e.g. on its way to the
    # apex, keeps the part it has done). If that fails, the last resort (_solve_substep's band) with
    # uniform sub-steps from the finest size up, where the band's error, the ratio change of one
    # sub-step, is as small as it can be.
    total = 1 << max_level
    for attempt in range(max_level + 2):
        last_resort = attempt > 0
        h = total if attempt == 0 else 1 << (attempt - 1)
        pos = 0
        nsub = 0
        p_before = 0.0  # mean stress before the last converged sub-step, and that sub-step's size
        h_last = 1
        for i in range(6):
            sig_prev[i] = sig_n[i]
        for a in range(M):
            kap[a] = kap_n[a]
        if want_tangent:
            for i in range(6):
                for j in range(6):
                    Dsig[i, j] = 0.0
            for a in range(M):
                for j in range(6):
                    Dk[a, j] = 0.0
        failed = False
        while pos < total:
            h = min(h, total - pos)
            frac = (pos + h) / total  # the fraction of the increment done at the end of this sub-step
            hf = h / total  # and the fraction this sub-step makes
            for i in range(6):
                eps_k[i] = eps_n[i] + frac * de[i]
                de_k[i] = hf * de[i]
            if nsub > 0 and _mean_trial(sig_prev, de_k, stiff) >= 0.0:
                # the cut-off's first case met on the way: this sub-step opens the material past the apex
                _apex(sig_out, kap_out, D_out, kap_n, stiff, fopt[_F_CUTOFF_STIFFNESS], want_tangent)
                return _OK, nsub + 1, total_it, True
            _lambda_and_slope(eps_k, beta, ahat, bhat, lam6, Lam, lam_scratch)
            _plane_strengths(nn6, om6, lam6, coeffs, eta0, eta_f, deta_f)
            ok, its = _solve_substep(sig_prev, de_k, kap, eta_f, normals, nn6, weights, cohesion, zeta, A, inv_t,
                                     eta_c_ratio, comp, stiff, tol, tol_g, maxit, sig, J, active, dkap, work,
                                     r, piv, delta, trial, tmp, pred, kap_it, bvec, dk_step, kap_try,
                                     last_resort, sp)
            total_it += its
            if not ok:
                if not last_resort and h > 1:
                    h //= 2
                    continue
                failed = True
                # The point was on its way to the apex, where the plastic compliance of the low-stress
                # planes stops the local Newton, if the rest of the increment takes its mean stress past
                # zero: the elastic trial of the rest from the last converged stress (the cut-off's first
                # case), or the mean stress's change in the last converged sub-step carried on linearly
                # (dilation unloads the point faster than the elastic trial says).
                rest = total - pos
                for i in range(6):
                    de_k[i] = rest / total * de[i]
                p_now = (sig_prev[0] + sig_prev[1] + sig_prev[2]) / 3.0
                if _mean_trial(sig_prev, de_k, stiff) >= 0.0 or (
                        nsub > 0 and p_now + (p_now - p_before) * rest / h_last >= 0.0):
                    _apex(sig_out, kap_out, D_out, kap_n, stiff, fopt[_F_CUTOFF_STIFFNESS], want_tangent)
                    return _OK, nsub + 1, total_it, True
                # how close to the apex any sub-stepping got before it stopped
                s_fail = 0.0
                for i in range(6):
                    s_fail = max(s_fail, abs(sig_prev[i]))
                s_last = min(s_last, s_fail)
                break
            more = pos + h < total  # another sub-step follows
            if want_tangent:
                # B = S Dsig_{k-1} + I hf + sum_active (w/t)(SN - dil NN) (x) Dkap_{k-1,a}
                #     - sum_active dG_a/d eta_f * d eta_f/d eps * frac
                for i in range(6):
                    for j in range(6):
                        acc = 0.0
                        if nsub > 0:
                            for l in range(6):
                                acc += comp[i, l] * Dsig[l, j]
                        B[i, j] = acc + (hf if i == j else 0.0)
                for a in range(M):
                    if not active[a] or (nsub == 0 and beta == 0.0):
                        continue  # (Dkap_0 = 0: nothing to add in the first sub-step without induced terms)
                    n0, n1, n2 = normals[a, 0], normals[a, 1], normals[a, 2]
                    t0, t1, t2 = _traction(sig, n0, n1, n2)
                    tn = t0 * n0 + t1 * n1 + t2 * n2
                    tau = work[a, 1]
                    s0, s1, s2 = (t0 - tn * n0) / tau, (t1 - tn * n1) / tau, (t2 - tn * n2) / tau
                    _sym_mandel(sn6, s0, s1, s2, n0, n1, n2)
                    wt = weights[a] * inv_t
                    dil = work[a, 4]
                    if nsub > 0:
                        for i in range(6):
                            g = wt * (sn6[i] - dil * nn6[a, i])
                            for j in range(6):
                                B[i, j] += g * Dk[a, j]
                    if beta != 0.0:
                        sigma_N = work[a, 0]
                        etah = work[a, 2]
                        q = work[a, 3]
                        ef = eta_f[a]
                        zef = zeta * ef
                        c = cohesion[a]
                        sig0 = c / ef
                        # d kappa / d eta_f at fixed stress, from g = etah - zeta eta_f kappa/(A+kappa) = 0
                        dkap_def = -(etah / ef) * work[a, 5]
                        ddil_def = eta_c_ratio - tau * c / (ef * ef * (sigma_N + sig0) * (sigma_N + sig0))
                        for j in range(6):  # d x_a / d eps = n_a n_a : d Lambda / d eps
                            acc = 0.0
                            for i in range(6):
                                acc += nn6[a, i] * Lam[i, j]
                            dx_de[j] = acc
                        scale = deta_f[a] * frac
                        for i in range(6):
                            dGi = wt * ((sn6[i] - dil * nn6[a, i]) * dkap_def - dkap[a] * ddil_def * nn6[a, i])
                            for j in range(6):
                                B[i, j] -= dGi * scale * dx_de[j]
                # Dsig_k = J^-1 B
                for j in range(6):
                    for i in range(6):
                        col[i] = B[i, j]
                    _lu_solve(J, piv, col)
                    for i in range(6):
                        Dsig[i, j] = col[i]
                # Dkap_k = kappa' d etah/d sigma . Dsig_k + d kappa/d eta_f d eta_f/d eps frac  (active);
                # needed only by a following sub-step
                for a in range(M if more else 0):
                    if not active[a]:
                        for j in range(6):
                            Dk_new[a, j] = Dk[a, j]
                        continue
                    n0, n1, n2 = normals[a, 0], normals[a, 1], normals[a, 2]
                    t0, t1, t2 = _traction(sig, n0, n1, n2)
                    tn = t0 * n0 + t1 * n1 + t2 * n2
                    tau = work[a, 1]
                    s0, s1, s2 = (t0 - tn * n0) / tau, (t1 - tn * n1) / tau, (t2 - tn * n2) / tau
                    _sym_mandel(sn6, s0, s1, s2, n0, n1, n2)
                    sigma_N = work[a, 0]
                    etah = work[a, 2]
                    kprime = work[a, 5]
                    for j in range(6):
                        acc = 0.0
                        for i in range(6):
                            acc += (sn6[i] + etah * nn6[a, i]) * Dsig[i, j]
                        Dk_new[a, j] = kprime * acc / sigma_N
                    if beta != 0.0:
                        ef = eta_f[a]
                        zef = zeta * ef
                        dkap_def = -(etah / ef) * kprime
                        scale = dkap_def * deta_f[a] * frac
                        for j in range(6):
                            acc = 0.0
                            for i in range(6):
                                acc += nn6[a, i] * Lam[i, j]
                            Dk_new[a, j] += scale * acc
                for a in range(M if more else 0):
                    for j in range(6):
                        Dk[a, j] = Dk_new[a, j]
            for a in range(M):
                if active[a]:
                    kap[a] = kap[a] + dkap[a]
            p_before = (sig_prev[0] + sig_prev[1] + sig_prev[2]) / 3.0
            h_last = h
            for i in range(6):
                sig_prev[i] = sig[i]
            pos += h
            nsub += 1
        if not failed:
            _write_result(sig_out, kap_out, D_out, sig_prev, kap, Dsig, want_tangent)
            return (_OK if nsub == 1 else _SUBSTEPPED), nsub, total_it, False
    # second case: no sub-step sequence converged, and either one ran into the apex (its last converged
    # stress is under 5 % of the start stress, or the point started on the apex) or the trial stress
    # pulls some plane apart: the increment opens the material faster than plastic dilation can follow,
    # and the point goes to the apex
    s_start = 0.0
    s_inc = 0.0  # the elastic stress of the whole increment
    for i in range(6):
        s_start = max(s_start, abs(sig_n[i]))
        acc = 0.0
        for j in range(6):
            acc += stiff[i, j] * de[j]
        s_inc = max(s_inc, abs(acc))
    # (or the point starts within one increment's elastic stress of the apex, or below _APEX_FLOOR of
    # the elastic modulus, the only stress scale of a cohesionless law: 0.9 kPa for E = 6000 kPa, the
    # weight of 5 cm of sand; such a point is practically stress free, and a local problem that no
    # sub-stepping solves there is not worth stopping a boundary-value problem for)
    if s_last <= 0.05 * s_start or s_start <= max(s_inc, _APEX_FLOOR * stiff[0, 0]):
        _apex(sig_out, kap_out, D_out, kap_n, stiff, fopt[_F_CUTOFF_STIFFNESS], want_tangent)
        return _OK, 1 << max_level, total_it, True
    for i in range(6):
        trial[i] = sig_n[i]
        for j in range(6):
            trial[i] += stiff[i, j] * de[j]
    for a in range(M):
        t0, t1, t2 = _traction(trial, normals[a, 0], normals[a, 1], normals[a, 2])
        if t0 * normals[a, 0] + t1 * normals[a, 1] + t2 * normals[a, 2] > 0.0:
            _apex(sig_out, kap_out, D_out, kap_n, stiff, fopt[_F_CUTOFF_STIFFNESS], want_tangent)
            return _OK, 1 << max_level, total_it, True
    _write_result(sig_out, kap_out, D_out, sig_n, kap_n, stiff, want_tangent)  # failed: start of step
    return _FAILED, 1 << max_level, total_it, False


@njit(cache=True, inline="always")
def _write_result(sig_out, kap_out, D_out, sig, kap, D, want_tangent):
    for i in range(6):
        sig_out[i] = sig[i]
    for a in range(kap.shape[0]):
        kap_out[a] = kap[a]
    if want_tangent:
        for i in range(6):
            for j in range(6):
                D_out[i, j] = D[i, j]


@njit(cache=True)
def _apex(sig_out, kap_out, D_out, kap_n, stiff, rho, want_tangent):
    """Tension cut-off: stress free, kappa unchanged, tangent rho * elastic (MODEL.md "Tension")."""
    for i in range(6):
        sig_out[i] = 0.0
    for a in range(kap_n.shape[0]):
        kap_out[a] = kap_n[a]
    if want_tangent:
        for i in range(6):
            for j in range(6):
                D_out[i, j] = rho * stiff[i, j]


@njit(cache=True, parallel=True)
def cpa_batch(sig_n, de, eps_n, kap_n, normals, nn6, weights, cohesion, om6, coeffs, eta0, beta, ahat, bhat, zeta, A,
              inv_t,
              eta_c_ratio, comp, stiff, iopt, fopt, sig_out, kap_out, D_out, status, substeps, iterations, cutoff,
              mobilised, pred, kstar, soft, residual):
    """Update N Gauss points (Mandel vectors). Arrays:

    sig_n, de, eps_n (N, 6); kap_n (N, M); normals (M, 3) global; nn6 (M, 6) Mandel(n n);
    weights, cohesion (M,); om6 (6,) Mandel(Omega) global; coeffs (K,) a1..aK;
    comp, stiff (6, 6) elastic compliance / stiffness (Mandel); iopt = (maxit, max_level, want_tangent);
    fopt = (tol, tol_g, cutoff_stiffness): |R| <= tol |d_eps| and max_a |g_a| <= tol_g.
    pred (N, 6, 6) the tangent of each point's last plastic step (zeros where none) for the predictor.
    Softening (:func:`_hardening`): kstar the peak slip A / (zeta - 1), soft (N,) the slip scale of each
    point (0: none), residual the ratio eta_residual / eta_f.
    Outputs: sig_out (N, 6), kap_out (N, M), D_out (N, 6, 6), status, substeps, iterations (N,) int,
    cutoff (N,) bool, mobilised (N,) = max_a etah_a / eta_f,a at the end of the step.
    """
    N = sig_n.shape[0]
    M = normals.shape[0]
    nchunk = min(N, 64)
    block = (N + nchunk - 1) // max(nchunk, 1)
    for c in prange(nchunk):
        bufs_f = np.empty((21, M))
        bufs_b = np.zeros(M, dtype=np.bool_)
        piv = np.empty(6, dtype=np.int64)
        Dk = np.empty((M, 6))
        Dk_new = np.empty((M, 6))
        eps_end = np.empty(6)
        vecs = np.empty((20, 6))
        mats = np.empty((4, 6, 6))
        sp = np.empty(3)
        sp[0] = kstar
        sp[2] = residual
        for p in range(c * block, min(N, (c + 1) * block)):
            sp[1] = soft[p]
            st, m, its, cut = _point_update(sig_n[p], de[p], eps_n[p], kap_n[p], normals, nn6, weights, cohesion,
                                            om6, coeffs, eta0, beta, ahat, bhat, zeta, A, inv_t, eta_c_ratio, comp,
                                            stiff,
                                            iopt, fopt, sig_out[p], kap_out[p], D_out[p], bufs_f, bufs_b, piv,
                                            Dk, Dk_new, vecs, mats, pred[p], sp)
            status[p] = st
            substeps[p] = m
            iterations[p] = its
            cutoff[p] = cut
            # mobilised ratio at the end of the step (output only)
            for i in range(6):
                eps_end[i] = eps_n[p, i] + de[p, i]
            _lambda6(eps_end, beta, ahat, bhat, vecs[16])
            _plane_strengths(nn6, om6, vecs[16], coeffs, eta0, bufs_f[0, :M], bufs_f[1, :M])
            best = 0.0
            for a in range(M):
                v = _ratio(sig_out[p], normals[a, 0], normals[a, 1], normals[a, 2], cohesion[a]) / bufs_f[0, a]
                if v > best:  # (NaN, a plane in tension, compares false)
                    best = v
            mobilised[p] = best


# ---------------------------------------------------------------------------------------- Mandel


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
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
