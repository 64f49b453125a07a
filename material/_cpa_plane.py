"""The plane law of the CPA model: strength of a plane, hardening, and a plane's kinematics at a stress.

Pure numba functions on scalars and small arrays (no Python objects), used by the local solver
(:mod:`material._cpa_local`). The equations, with the conventions of ``docs/cpa_law.md``:

Strength (eqs. 2.4, 3.14-3.15)
    x_a = n_a . (Omega + Lambda(eps)) . n_a,  eta_f,a = eta0 (1 + x + a1 x^2 + a2 x^3 + ...),
    Lambda = beta dev(eps) (or the coaxial law 3.8), eps the total strain at the end of the step.
The apex (this package's addition, ``docs/cpa_law.md``)
    sigma~ = sigma_N + c / eta_f + c_a   (the cohesion and the apex stress c_a read as shifts of the
    normal stress), T = sqrt(tau^2 + b^2) with b = c_a / 10: every loading surface T = eta sigma~ is
    a convex hyperbolic cone with its tip in tension, at sigma~ = b / eta, so the surfaces of different
    hardening levels share no point and etah is smooth wherever sigma~ > 0.
Mobilised ratio and hardening (2.16)
    etah = T / sigma~,   eta(kappa) = zeta eta_f kappa / (A + kappa)   (then the optional softening
    branch past kappa* = A / (zeta - 1)); a plane loads while etah = eta(kappa), kappa never decreases.
Flow (2.7, 2.9, 2.17, with the same substitution in the potential)
    m = sym((t_s / T + (etah - eta_c) n) (x) n) per unit slip,  eta_c = eta_c_ratio eta_f w(sigma~),
    w = sigma~^2 / (sigma~^2 + p_c^2): slip along the shear traction, compaction while etah < eta_c,
    dilation above; associated for eta_c = 0. The factor w (this package's addition) lets the
    compaction fade below the normal stress p_c (dilatancy grows as confinement falls, Bolton 1986):
    without it the strain-driven problem of a contractive plane set at low stress has no solution.

Mandel vectors: ``v = (a11, a22, a33, r a23, r a13, r a12)``, r = sqrt 2, so ``a : b = v_a . v_b``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

SQ2 = np.sqrt(2.0)
ISQ2 = 1.0 / np.sqrt(2.0)

#: Compile options of the kernels that make no array and return none: ``njit(..., **NO_REFCOUNT)`` compiles
#: them without numba's reference counting (its runtime, NRT). A numba function increments the count of every
#: array it receives on entry and decrements it on return (atomic operations, calls to NRT_incref and
#: NRT_decref that LLVM does not inline and numba's pruning does not remove in functions of this size), and
#: the per-point kernels take namedtuples of some 50 arrays (Law, Point, Work) at every call: measured with
#: ``perf`` on ``benchmarks/material_update.py``, those calls were 23 % of the update's time. The arguments
#: are owned by the caller for the whole call, so the kernels' views of them (rows, slices) need no count;
#: a kernel that allocates (``np.empty``, ``.copy()``, slice assignment between arrays) must keep the
#: runtime, and so must one that returns an array. (``_nrt`` is numba's own switch for this, used in its tests.)
#: ``_nrt`` is not public API: where a numba version does not declare it, the kernels compile with the runtime,
#: with the same results and the speed of before (``cpa_batch`` 1.39 times the time).
def _refcount_switch(on: bool) -> dict:
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:  # pragma: no cover - a numba that moved its target options
        return {}
    return {"_nrt": on} if hasattr(CPUTargetOptions, "_nrt") else {}


NO_REFCOUNT = _refcount_switch(False)
#: ... and a kernel that allocates and is called from one of those says so: numba compiles a callee that does not
#: set the switch with its caller's setting, and an allocation does not compile without the runtime.
REFCOUNT = _refcount_switch(True)


# ------------------------------------------------------------------------------------------ strength
@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def series_and_slope(x, coeffs):
    """1 + x + a1 x^2 + a2 x^3 + ... and its derivative in x (the bracket of eq. 2.4)."""
    val = 1.0 + x
    der = 1.0
    xp = x  # x^(k+1) for coefficient a_k
    for k in range(coeffs.shape[0]):
        der += (k + 2) * coeffs[k] * xp
        xp *= x
        val += coeffs[k] * xp
    return val, der


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def induced_tensor(eps6, beta, ahat, bhat, out):
    """Induced tensor Lambda (Mandel) of the total strain eps6 (eqs. 3.8, 3.15) into ``out``.

    Lambda = beta |e| n^Omega, n^Omega = alpha_hat n^e + beta_hat dev(n^e n^e) normalised, e = dev(eps);
    with beta_hat = 0 (alpha_hat > 0) exactly beta e.
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


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def induced_slope(eps6, beta, ahat, bhat, L, scratch):
    """L = d Lambda / d eps (6, 6), Mandel: exact (beta P_dev) for the linear law; for the general law
    (3.8) a central difference with step 1e-5 |e| (Lambda is homogeneous of degree one in e, so the
    relative error is ~1e-10), and beta P_dev at e = 0."""
    norm = 0.0
    tr3 = (eps6[0] + eps6[1] + eps6[2]) / 3.0
    for i in range(6):
        e = eps6[i] - tr3 if i < 3 else eps6[i]
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
        induced_tensor(ep, beta, ahat, bhat, lp)
        ep[j] -= 2.0 * h
        induced_tensor(ep, beta, ahat, bhat, lm)
        for i in range(6):
            L[i, j] = (lp[i] - lm[i]) / (2.0 * h)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def plane_strengths(nn6, om6, lam6, coeffs, eta0, eta_f, deta_f):
    """eta_f,a and d eta_f,a / d x_a, x_a = n_a.(Omega + Lambda).n_a (eqs. 2.4, 3.14), into the arrays."""
    for a in range(nn6.shape[0]):
        x = 0.0
        for i in range(6):
            x += nn6[a, i] * (om6[i] + lam6[i])
        val, der = series_and_slope(x, coeffs)
        eta_f[a] = eta0 * val
        deta_f[a] = eta0 * der


# ------------------------------------------------------------------------------------------ hardening
@njit(cache=True, inline="always", error_model="numpy")
def hardening(kappa, eta_f, zeta, A, kstar, soft, residual):
    """eta(kappa) and d eta / d kappa of a plane (eq. 2.16), both proportional to eta_f.

    The hyperbola zeta eta_f kappa / (A + kappa) up to kappa* = A / (zeta - 1); past it, when the point
    has a softening slip scale ``soft`` > 0, the decay eta_f (r + (1 - r) / (1 + (kappa - kappa*) / soft))
    to r = ``residual`` (continuous, with a kink at the peak eta = eta_f)."""
    if soft > 0.0 and kappa >= kstar:
        return softening_branch(kappa, eta_f, kstar, soft, residual)
    zef = zeta * eta_f
    apk = A + kappa
    return zef * kappa / apk, zef * A / (apk * apk)


@njit(cache=True, inline="always", error_model="numpy")
def softening_branch(kappa, eta_f, kstar, soft, residual):
    """eta and d eta / d kappa on the softening branch: past the peak (kappa >= kappa*) the decay
    eta_f (r + (1 - r) / x), x = 1 + (kappa - kappa*) / soft, of :func:`hardening`; below it the branch's
    tangent at the peak, eta_f (1 + (1 - r) (kappa* - kappa) / soft) (continuous with its slope).

    The implicit gradient (:mod:`material._cpa_local`) evaluates a plane past its peak at its slip shifted
    by the nonlocal field, which can fall below kappa* where the plane's neighbours slip less: the plane is
    then stronger than its peak, linearly, as the over-nonlocal von Mises law is (the decay itself continued
    below the peak would have a pole at kappa* - soft; measured on a biaxial band: shifts of -1.07 soft
    reached it)."""
    if kappa >= kstar:
        x = 1.0 + (kappa - kstar) / soft
        return eta_f * (residual + (1.0 - residual) / x), -eta_f * (1.0 - residual) / (soft * x * x)
    slope = -eta_f * (1.0 - residual) / soft
    return eta_f + slope * (kappa - kstar), slope


@njit(cache=True, inline="always", error_model="numpy")
def ratio_barrier(eta_f, zeta, soft):
    """The largest mobilised ratio the hardening branch reaches: zeta eta_f (asymptotically), or the
    peak eta_f when the plane can soften."""
    return eta_f if soft > 0.0 else zeta * eta_f


@njit(cache=True, inline="always", error_model="numpy")
def slip_of_ratio(etah, kappa_n, eta_f, zeta, A, mu):
    """Slip increment d >= 0 of a weakly mobilised plane at the ratio etah, and dd / d etah.

    The plane's step equation on the hardening branch of (2.16): etah = eta(kappa_n + d) + mu d / A (mu / A
    the step stabilisation's hardening floor of the plane, :mod:`material._cpa_local`), solved in closed
    form: for mu = 0 the
    inverted hyperbola d = A etah / (zeta eta_f - etah) - kappa_n, which needs etah < zeta eta_f; for
    mu > 0 the positive root of (mu/A) d^2 + [zeta eta_f - etah + mu (A + kappa_n)/A] d
    - [etah (A + kappa_n) - zeta eta_f kappa_n] = 0, finite at any etah. Returns (d, dd/d etah, eta) with
    d <= 0 meaning no loading (then the derivative is that of the loading branch, for the kink).
    """
    zef = zeta * eta_f
    apk = A + kappa_n
    c0 = etah * apk - zef * kappa_n  # > 0 iff the plane is above its reached level
    if mu == 0.0:
        inv = 1.0 / (zef - etah)
        d = c0 * inv
        # (on the branch eta(kappa_n + d) = etah; below the reached level the value is not used)
        return d, A * zef * inv * inv, etah
    bq = zef - etah + mu * apk / A
    disc = np.sqrt(bq * bq + 4.0 * (mu / A) * c0) if bq * bq + 4.0 * (mu / A) * c0 > 0.0 else 0.0
    if c0 >= 0.0:
        d = 2.0 * c0 / (bq + disc)
    else:
        d = c0 / bq  # (below the level: the sign is all that matters)
    k = kappa_n + d
    eta = zef * k / (A + k)
    deta = zef * A / ((A + k) * (A + k))
    return d, 1.0 / (deta + mu / A), eta


@njit(cache=True, inline="always", error_model="numpy")
def compaction_weight(sigma_t, p_c):
    """w = sigma~^2 / (sigma~^2 + p_c^2) and dw / d sigma~: the factor on eta_c in the flow rule, so a plane
    compacts as the thesis says at working stresses and not at all as its normal stress vanishes."""
    if p_c == 0.0:
        return 1.0, 0.0
    s2 = sigma_t * sigma_t
    inv = 1.0 / (s2 + p_c * p_c)
    return s2 * inv, 2.0 * sigma_t * p_c * p_c * inv * inv


# ------------------------------------------------------------------------------------------ kinematics
@njit(cache=True, inline="always", error_model="numpy")
def tensor_parts(sig):
    """The tensor components (s11, s22, s33, s23, s13, s12) of a Mandel stress vector."""
    return sig[0], sig[1], sig[2], sig[3] * ISQ2, sig[4] * ISQ2, sig[5] * ISQ2


@njit(cache=True, inline="always", error_model="numpy")
def traction(sig, n0, n1, n2):
    """t = sigma n for a Mandel stress vector."""
    return traction_of_parts(tensor_parts(sig), n0, n1, n2)


@njit(cache=True, inline="always", error_model="numpy")
def traction_of_parts(parts, n0, n1, n2):
    """t = sigma n for the stress given by :func:`tensor_parts`."""
    s11, s22, s33, s23, s13, s12 = parts
    return (s11 * n0 + s12 * n1 + s13 * n2, s12 * n0 + s22 * n1 + s23 * n2, s13 * n0 + s23 * n1 + s33 * n2)


@njit(cache=True, inline="always", error_model="numpy")
def sym_parts(a0, a1, a2, n0, n1, n2):
    """The six Mandel components of sym(a (x) n)."""
    return (a0 * n0, a1 * n1, a2 * n2, (a1 * n2 + a2 * n1) * ISQ2, (a0 * n2 + a2 * n0) * ISQ2,
            (a0 * n1 + a1 * n0) * ISQ2)


@njit(cache=True, inline="always", error_model="numpy")
def sym_mandel(out, a0, a1, a2, n0, n1, n2):
    """out = Mandel(sym(a (x) n))."""
    out[0], out[1], out[2], out[3], out[4], out[5] = sym_parts(a0, a1, a2, n0, n1, n2)


#: b / c_a: the rounding of a plane's tip relative to the apex stress (a stress-free plane is mobilised
#: to etah = b / c_a = 0.1 when it has no cohesion).
APEX_ROUNDING = 0.1


@njit(cache=True, inline="always", error_model="numpy")
def plane_measures(sig, n0, n1, n2, shift, rounding):
    """The stress measures of the plane with normal n at the Mandel stress ``sig``: (sigma~, tau, T, t_s),
    with ``shift`` = c / eta_f + c_a, ``rounding`` = b and t_s = (ts0, ts1, ts2) the shear traction."""
    return measures_of_parts(tensor_parts(sig), n0, n1, n2, shift, rounding)


@njit(cache=True, inline="always", error_model="numpy")
def measures_of_parts(parts, n0, n1, n2, shift, rounding):
    """:func:`plane_measures` for the stress given by :func:`tensor_parts` (read once before a loop over the
    planes: a loop that reads the stress array itself, and writes other arrays, does not vectorise)."""
    t0, t1, t2 = traction_of_parts(parts, n0, n1, n2)
    tn = t0 * n0 + t1 * n1 + t2 * n2
    ts0, ts1, ts2 = t0 - tn * n0, t1 - tn * n1, t2 - tn * n2
    tau = np.sqrt(ts0 * ts0 + ts1 * ts1 + ts2 * ts2)
    return -tn + shift, tau, np.sqrt(tau * tau + rounding * rounding), ts0, ts1, ts2


@njit(cache=True, inline="always", error_model="numpy")
def plane_stress(sig, normal, shift, rounding):
    """:func:`plane_measures` for the normal given as an array (3,)."""
    return plane_measures(sig, normal[0], normal[1], normal[2], shift, rounding)


@njit(cache=True, inline="always", error_model="numpy")
def fallback_shear(n0, n1, n2):
    """A unit shear direction of the plane with normal n, used where it carries no shear: the one
    orthogonal to the smallest normal component (nothing that follows depends on which)."""
    if abs(n0) <= abs(n1) and abs(n0) <= abs(n2):
        s0, s1, s2 = 0.0, -n2, n1
    elif abs(n1) <= abs(n2):
        s0, s1, s2 = n2, 0.0, -n0
    else:
        s0, s1, s2 = -n1, n0, 0.0
    ns = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    return s0 / ns, s1 / ns, s2 / ns


@njit(cache=True, inline="always", error_model="numpy")
def shear_pair(n0, n1, n2, ts0, ts1, ts2, tau, f0, f1, f2):
    """An orthonormal pair (s, r = n x s) of shear directions of the plane: s along the shear traction
    t_s, or the fallback direction f (:func:`fallback_shear`, precomputed per plane) where tau = 0."""
    if tau > 0.0:
        inv = 1.0 / tau
        s0, s1, s2 = ts0 * inv, ts1 * inv, ts2 * inv
    else:
        s0, s1, s2 = f0, f1, f2
    return s0, s1, s2, n1 * s2 - n2 * s1, n2 * s0 - n0 * s2, n0 * s1 - n1 * s0


@njit(cache=True, inline="always", error_model="numpy")
def plane_directions(normal, ts0, ts1, ts2, tau, sn6, rn6):
    """sn6 = Mandel(sym(s (x) n)) and rn6 = Mandel(sym(r (x) n)) for the pair (s, r) of
    :func:`shear_pair` (d tau / d sigma = sn6)."""
    n0, n1, n2 = normal[0], normal[1], normal[2]
    f0, f1, f2 = fallback_shear(n0, n1, n2)
    s0, s1, s2, r0, r1, r2 = shear_pair(n0, n1, n2, ts0, ts1, ts2, tau, f0, f1, f2)
    sym_mandel(sn6, s0, s1, s2, n0, n1, n2)
    sym_mandel(rn6, r0, r1, r2, n0, n1, n2)
