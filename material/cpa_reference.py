"""Plain-numpy reference of the whole CPA one-point update, for testing the numba kernel point by point.

Slow and simple on purpose, and independent of the kernel's algebra: full 3x3 tensors instead of Mandel
vectors, the residual written once (:func:`residual`) and every derivative taken by the complex step
(d F / d x = Im F(x + i h e) / h, exact to round-off for these analytic expressions) instead of the
kernel's hand-derived Jacobians and its condensation of the slips. It solves the same equations
(``docs/cpa_law.md``, section 3) on the same branch: Newton from the start of the step, a plane on its
kink taking the loading branch, halving the fraction of the increment when Newton fails, and where that
branch folds under the step stabilisation, the floor homotopy at the whole increment. The tangent is
the implicit-function derivative of the converged equations, again by the complex step.

Unknowns x = (sigma (6 components xx yy zz yz xz xy), dkappa of the strong planes, dlambda of the
cut-off); equations F = (strain residual (6), Fischer-Burmeister residuals of the strong planes (their
overstress in the traction form, as in the kernel), of the cut-off). Weak planes (kappa_n <= A, and below
the softening peak) take their slip in closed form.
"""

from __future__ import annotations

import numpy as np

__all__ = ["update_point", "residual", "ReferenceFailure", "follow_past_limits", "loading_tangent"]

_IJ = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
_H = 1e-30  # complex step
_KINK = 1e-12


class ReferenceFailure(RuntimeError):
    """The reference solver found no solution (Newton and its halvings failed)."""


def _sym(v):
    a = np.zeros((3, 3), dtype=v.dtype)
    for k, (i, j) in enumerate(_IJ):
        a[i, j] = a[j, i] = v[k]
    return a


def _six(a):
    return np.array([a[i, j] for i, j in _IJ])


class _Law:
    """The law's constants for one CPAModel (global frame, 3x3 tensors)."""

    def __init__(self, model):
        from material._cpa_plane import APEX_ROUNDING

        p = model.params
        self.p = p
        self.n = model.normals
        self.w = model.weights
        self.c = model._cohesion
        self.omega = model.axes @ np.diag([p.omega1, -2 * p.omega1, p.omega1]) @ model.axes.T
        self.lam = p.E * p.nu / ((1 + p.nu) * (1 - 2 * p.nu))
        self.G = p.E / (2 * (1 + p.nu))
        self.K = p.bulk_modulus
        self.b = APEX_ROUNDING * p.apex_stress

    def stiffness(self):
        """The elastic stiffness C (3, 3, 3, 3)."""
        I = np.eye(3)
        return self.lam * np.einsum("ij,kl->ijkl", I, I) + self.G * (np.einsum("ik,jl->ijkl", I, I)
                                                                    + np.einsum("il,jk->ijkl", I, I))

    def eta_f(self, strain):
        """eta_f of every plane for the total strain (3, 3), complex allowed (eqs. 2.4, 3.8, 3.15)."""
        p = self.p
        dev = strain - np.trace(strain) / 3 * np.eye(3)
        if p.beta_hat == 0.0 and p.alpha_hat > 0.0:
            lam = p.beta * dev
        else:
            nrm = np.sqrt(np.sum(dev * dev))
            if nrm.real == 0.0:
                lam = 0.0 * dev
            else:
                ne = dev / nrm
                sq = ne @ ne
                sq = sq - np.trace(sq) / 3 * np.eye(3)
                d = p.alpha_hat * ne + p.beta_hat * sq
                lam = p.beta * nrm * d / np.sqrt(np.sum(d * d))
        x = np.einsum("ai,ij,aj->a", self.n, self.omega + lam, self.n)
        acc = np.zeros_like(x)
        for coef in reversed(tuple(p.a)):
            acc = (acc + coef) * x
        return p.eta0 * (1 + x + x * acc)

    def hardening(self, kappa, ef, soft):
        """eta(kappa) (2.16), with the softening branch past kappa* where soft > 0."""
        p = self.p
        out = p.zeta * ef * kappa / (p.A + kappa)
        if soft > 0:
            post = kappa.real >= p.kappa_instability
            x = 1 + (kappa - p.kappa_instability) / soft
            out = np.where(post, ef * (p.residual_ratio + (1 - p.residual_ratio) / np.where(post, x, 1.0)), out)
        return out

    def softening(self, kappa, ef, soft):
        """The softening branch of (2.16) past kappa*, continued below kappa* by its tangent at the peak (a
        plane past its peak whose gradient-shifted slip falls below it)."""
        p = self.p
        r, ks = p.residual_ratio, p.kappa_instability
        below = kappa.real < ks
        x = 1 + np.where(below, 0.0, kappa - ks) / soft
        return np.where(below, ef * (1 + (1 - r) * (ks - kappa) / soft), ef * (r + (1 - r) / x))

    def planes(self, sigma, ef):
        """Mobilised ratio, shifted normal stress and flow vectors (M, 3) of every plane at sigma."""
        p = self.p
        t = self.n @ sigma.T
        sN = -np.einsum("ai,ai->a", t, self.n)
        ts = t + sN[:, None] * self.n
        T = np.sqrt(np.sum(ts * ts, axis=1) + self.b ** 2)
        st = sN + self.c / ef + p.apex_stress
        ratio = T / st
        pc = p.compaction_stress
        wc = st * st / (st * st + pc * pc) if pc > 0 else 1.0
        g = ts / T[:, None] + (ratio - p.eta_c_ratio * ef * wc)[:, None] * self.n  # (2.7, 2.17)
        return ratio, st, g


def rate_coupling(law, sig_n, ef, kap_n, soft, level=None, cutoff=None):
    """The rate problem of one point at sigma_n (``docs/cpa_law.md``, section 4), by the definition: the
    planes ``on`` their hardening curve (within 1e-9 relative), and with b_a = d etah_a / d sigma (complex
    step), m_a = sym(g_a (x) n_a) and C the elastic stiffness, q_a(d_eps) = b_a : C d_eps is returned as the
    (n, 3, 3) tensors C b_a and H_ab = (w_b / t) b_a : C m_b + eta'_a delta_ab. ``level``: (planes, shifts) of
    the planes past their peak under the implicit gradient, whose level is the softening branch at
    kappa_n + shift. ``cutoff``: None, or the point's strain scale r: where -p / K <= 1e-9 r at sigma_n the
    mean-stress cut-off is one more unknown, last, marked M (the number of planes) in ``on``: its opening
    rate x_0 (the plastic volumetric strain rate) with the rate of p / K, q_0 - H_0. x, q_0 = C I : d_eps / (3 K),
    H_00 = C I : I / (9 K), H_0b = (w_b / t) C I : m_b / (3 K), and in the planes' rows H_a0 = b_a : C I / 3.
    Returns (on, Cb, H, sigma~ of every plane); ``law`` is ``_Law(model)``."""
    p = law.p

    def eta_of(kappa):
        eta = law.hardening(kappa, ef, soft)
        if level is not None:
            at, shift = level
            eta = np.asarray(eta).copy()
            eta[at] = law.softening(kappa[at] + shift, ef[at], soft)
        return eta

    ratio, st, g = law.planes(sig_n, ef)
    eta_n = eta_of(kap_n.astype(complex)).real
    on = np.flatnonzero((st > 0) & (ratio >= eta_n - 1e-9 * (1 + eta_n)))
    b = np.zeros((len(ratio), 3, 3))
    for i in range(3):
        for j in range(3):
            E = np.zeros((3, 3), complex)
            E[i, j] += 0.5 * 1j * _H
            E[j, i] += 0.5 * 1j * _H
            b[:, i, j] = law.planes(sig_n + E, ef)[0].imag / _H
    m = 0.5 * (np.einsum("ai,aj->aij", g, law.n) + np.einsum("aj,ai->aij", g, law.n))

    def stiff(e):
        return 2 * law.G * e + law.lam * np.trace(e, axis1=-2, axis2=-1)[..., None, None] * np.eye(3)

    deta = eta_of(kap_n + 1j * _H * p.A).imag / (_H * p.A)
    H = np.einsum("aij,bij->ab", b[on], stiff(m[on])) * (law.w[on] / p.t)[None, :] + np.diag(deta[on])
    Cb = stiff(b[on])
    if cutoff is not None and -np.trace(sig_n) / 3 / law.K <= 1e-9 * cutoff:
        ci = stiff(np.eye(3))  # the stress rate of a unit volumetric strain rate, times 3
        row = np.einsum("ij,bij->b", ci, m[on]) * law.w[on] / p.t / (3 * law.K)
        col = np.einsum("aij,ij->a", b[on], ci) / 3
        H = np.block([[H, col[:, None]], [row[None, :], np.array([[np.trace(ci) / (9 * law.K)]])]])
        Cb = np.concatenate([Cb, ci[None] / (3 * law.K)])
        on = np.append(on, len(ratio))
    return on, Cb, H, st


def _softening_scale(model, state, point: int, gradient: bool) -> float:
    """The point's softening slip scale: softening_slip, or softening_slip t / h under the crack band (0: none)."""
    p = model.params
    if p.softening_slip == 0:
        return 0.0
    h = np.asarray(state.get("element_size", np.full(len(state["kappa"]), p.t)), float).reshape(-1)[point]
    return p.softening_slip * p.t / h if (model.regularise and not gradient) else p.softening_slip


def loading_tangent(model, stress, state, point: int = 0, *, strengthening: str = "none", modulus: float = 0.0):
    """The rate-independent loading tangent (3, 3, 3, 3) of one committed state, by the definition
    (:meth:`material.CPAModel.loading_tangent`): the planes on their curve (:func:`rate_coupling`) load at
    the rates x of H x = (C b_a) : d_eps, sigma rate = C d_eps - sum_b (w_b / t) C m_b x_b; with the
    implicit gradient the planes past their peak at their shifted level, and H_ab - m eta'_a between them
    (ebar fixed); ``strengthening`` (``"plane"``, ``"sum"``, ``"plastic_strain"``, ``"back_stress"``) adds
    H_g delta_ab, H_g, H_g (w_a / t)(w_b / t) m_a : m_b or H_g (w_b / t) b_a : m_b."""
    law = _Law(model)
    p = law.p
    sig_n = np.asarray(stress, float).reshape(-1, 3, 3)[point]
    eps_n = np.asarray(state["strain"], float).reshape(-1, 3, 3)[point]
    kap_n = np.asarray(state["kappa"], float).reshape(-1, law.n.shape[0])[point]
    gradient = getattr(model, "_nonlocal_length", None) is not None and p.softening_slip > 0
    soft = _softening_scale(model, state, point, gradient)
    ef = law.eta_f(eps_n)
    post = np.flatnonzero(kap_n >= p.kappa_instability) if gradient else np.zeros(0, int)
    level = None
    if post.size:
        shift = np.asarray(state.get("nonlocal_shift", np.zeros((point + 1, kap_n.size))), float)
        level = (post, shift.reshape(-1, kap_n.size)[point][post])
    on, Cb, H, st = rate_coupling(law, sig_n, ef, kap_n, soft, level=level)
    stiff = law.stiffness()
    if on.size == 0:
        return stiff
    _, _, g = law.planes(sig_n, ef)
    m = 0.5 * (np.einsum("ai,aj->aij", g, law.n) + np.einsum("aj,ai->aij", g, law.n))[on]
    wt = law.w[on] / p.t
    # eta' of each plane: H's diagonal less its elastic part
    etap = np.diag(H) - wt * np.einsum("aij,aij->a", Cb, m)
    H = H.copy()
    at = np.isin(on, post)
    H[np.ix_(at, at)] -= model.over_nonlocal * etap[at][:, None]
    if strengthening == "plane":
        H += modulus * np.eye(on.size)
    elif strengthening == "sum":
        H += modulus
    elif strengthening == "plastic_strain":
        Mw = (m * wt[:, None, None]).reshape(on.size, 9)
        H += modulus * Mw @ Mw.T
    elif strengthening == "back_stress":  # b_a = C^-1 (C b_a)
        b = (Cb - law.lam / (3 * law.lam + 2 * law.G) * np.trace(Cb, axis1=1, axis2=2)[:, None, None]
             * np.eye(3)) / (2 * law.G)
        H += modulus * np.einsum("aij,bij->ab", b, m) * wt[None, :]
    X = np.linalg.solve(H, Cb.reshape(on.size, 9)).reshape(on.size, 3, 3)
    Cm = np.einsum("ijkl,akl->aij", stiff, m) * wt[:, None, None]
    return stiff - np.einsum("aij,akl->ijkl", Cm, X)


def minimal_stabilisation(law, sig_n, ef, kap_n, soft, unit, level=None):
    """The ``"minimal"`` stabilisation's mu of one point, by the definition (``docs/cpa_law.md``, section 4):
    the coupling H of :func:`rate_coupling` with its rows scaled by w_a sigma~_a, and 1.1 times the least mu
    for which the symmetric part of the scaled H + mu diag(unit) is positive semi-definite."""
    on, _, H, st = rate_coupling(law, sig_n, ef, kap_n, soft, level)
    if on.size == 0:
        return 0.0
    d = law.w[on] * st[on]
    f = d * unit[on]
    S = d[:, None] * H
    S = 0.5 * (S + S.T) / np.sqrt(f[:, None] * f[None, :])
    return 1.1 * max(0.0, -float(np.linalg.eigvalsh(S)[0]))


def _weak_slip(law, ratio, kap_n, ef, mu):
    """Slip of a weak plane from etah = eta(kappa_n + d) + mu d / A (the positive root when mu > 0)."""
    p = law.p
    zef = p.zeta * ef
    if np.all(mu == 0.0):
        return p.A * ratio / (zef - ratio) - kap_n
    c0 = ratio * (p.A + kap_n) - zef * kap_n
    bq = zef - ratio + mu * (p.A + kap_n) / p.A
    return (-bq + np.sqrt(bq * bq + 4 * (mu / p.A) * c0 + 0j)) / (2 * mu / p.A)


def residual(law: _Law, x, sig_n, de6, eps_n, kap_n, soft, strong, mu=None, grad=None):
    """F(x) and the slips of all planes for the unknowns x (see the module docstring); ``mu`` (M,) the
    step stabilisation's hardening floor of each plane [1/m] (None: none); ``grad`` = (post, c0, m) for
    the implicit gradient: the strong planes ``post`` (indices into ``strong``) past their softening peak
    soften with kappa + c0 - m S on the softening branch (continued below the peak), c0 (per post plane) their
    accumulated shift plus this step's m t d_ebar, S = x[-1] the sum of their slip increments (its equation
    last)."""
    p = law.p
    mu = np.zeros(len(kap_n)) if mu is None else mu
    ns = strong.size
    sig = _sym(x[:6])
    dl = x[6 + ns]
    de = _sym(de6)
    ef = law.eta_f(eps_n + de)
    ratio, st, g = law.planes(sig, ef)
    zef = p.zeta * ef
    barrier = np.where(np.full(ef.shape, soft > 0), ef, zef)
    weak = np.ones(ratio.shape, bool)
    weak[strong] = False
    if np.any(st.real <= 0) or np.any((ratio.real >= barrier.real * (1 - 1e-12)) & weak & (mu == 0.0)):
        return None, None
    kr = _weak_slip(law, ratio, kap_n, ef, mu * p.A)  # (2.16) inverted
    on = kr.real >= -_KINK * (p.A + kap_n)  # loading branch at the kink
    dk = np.where(on, np.where(kr.real > 0, kr, kr - kr.real), 0.0 * kr)
    dk = dk.astype(np.result_type(dk, x))
    dk[strong] = x[6:6 + ns]
    if np.any(kap_n[strong] + dk[strong].real <= -0.5 * p.A):
        return None, None
    ep = np.einsum("a,ai,aj->ij", law.w * dk, g, law.n) * (1 / p.t)
    ep = 0.5 * (ep + ep.T)  # (2.9)
    tr = np.trace(sig - sig_n)
    S = ((1 + p.nu) * (sig - sig_n) - p.nu * tr * np.eye(3)) / p.E
    R = S + ep + dl / 3 * np.eye(3) - de
    u = dk[strong] / p.A
    eta = law.hardening(kap_n[strong] + dk[strong], ef[strong], soft)
    extra = []
    if grad is not None:
        post, c0, m = grad
        S = x[-1]
        eta = eta.astype(np.result_type(eta, x, c0))
        k_hat = kap_n[strong][post] + dk[strong][post] + c0 - m * S
        eta[post] = law.softening(k_hat, ef[strong][post], soft)
        extra = [(S - np.sum(dk[strong][post])) / p.A]
    # the overstress in the traction form (sigma~ (eta + h dkappa) - T) / sigma~_n, sigma~_n at least the apex stress
    st_n = law.planes(sig_n, ef)[1][strong]
    st_n = np.where(st_n.real > p.apex_stress, st_n, p.apex_stress)
    v = (eta + mu[strong] * dk[strong] - ratio[strong]) * st[strong] / st_n / (1 + mu[strong] * p.A)
    phi = _fb(u, v)
    phi0 = _fb(np.array([dl]), np.array([-np.trace(sig) / 3 / law.K]))
    return np.concatenate([_six(R), phi, phi0, np.asarray(extra)]), dk


def _fb(u, v):
    """Fischer-Burmeister function, complex-step safe; at the kink (0, 0) its loading branch (Phi ~ v)."""
    r = np.sqrt(u * u + v * v + 0j) if np.iscomplexobj(u) or np.iscomplexobj(v) else np.sqrt(u * u + v * v)
    out = u + v - r
    kink = (np.abs(np.real(u)) <= _KINK) & (np.abs(np.real(v)) <= _KINK)
    if np.any(kink):
        out = np.where(kink, np.real(out) + 1j * np.imag(v) if np.iscomplexobj(out) else np.real(out), out)
    return out


def _jacobian(law, x, args, scale):
    n = x.size
    J = np.empty((n, n))
    for j in range(n):
        xc = x.astype(complex)
        h = _H * max(abs(x[j]), 1e-8 if j >= 6 else 1e-3)
        xc[j] += 1j * h
        J[:, j] = residual(law, xc, *args)[0].imag / h * scale
    return J


def _newton(law, x, args, scale, tol, maxit):
    f, _ = residual(law, x, *args)
    if f is None:
        return False, x
    f = f * scale
    merit = 0.5 * f @ f
    for _ in range(maxit + 1):
        if np.abs(f).max() <= tol:
            return True, x
        try:
            dx = np.linalg.solve(_jacobian(law, x, args, scale), -f)
        except np.linalg.LinAlgError:
            return False, x
        a = 1.0
        for _ls in range(40):
            ft, _ = residual(law, x + a * dx, *args)
            if ft is not None:
                ft = ft * scale
                if 0.5 * ft @ ft <= (1 - 1e-4 * a) * merit:
                    break
            a *= 0.5
        else:
            return False, x
        x, f, merit = x + a * dx, ft, 0.5 * ft @ ft
    return False, x


def _floor_homotopy(law, n, args, floor, grad, scale, tol, maxit, max_halvings):
    """Where the branch in the fraction of the increment folds (the step stabilisation's floor over the
    fraction lam is floor / lam): the equations of the whole increment along the floor k ``floor``, from k = 16
    (times 4 while Newton from the start fails, at most 4 times) down to 1, the ratio of successive k from
    1/4 to its square root after each failed solve. The solution at k = 1, or None."""
    x0 = np.concatenate([_six(args[0]), np.zeros(n - 6)])
    k_done, x_done = 0.0, None
    for k in 16.0 * 4.0 ** np.arange(5):
        ok, x = _newton(law, x0.copy(), (*args, k * floor, grad), scale, tol, maxit)
        if ok:
            k_done, x_done = k, x
            break
    if x_done is None:
        return None
    ratio, failures = 0.25, 0
    while k_done > 1.0:
        k = max(1.0, k_done * ratio)
        ok, x = _newton(law, x_done.copy(), (*args, k * floor, grad), scale, tol, maxit)
        if ok:
            k_done, x_done = k, x
        else:
            failures += 1
            if failures > max_halvings:
                return None
            ratio = np.sqrt(ratio)
    return x_done


def update_point(model, d_strain, stress, state, point: int = 0, *, d_nonlocal=None, step_fraction: float = 1.0,
                 tol: float = 1e-11, maxit: int = 40, max_halvings: int = 12):
    """One point's update by the reference algorithm.

    Parameters
    ----------
    model : material.CPAModel
    d_strain, stress : (3, 3) or (N, 3, 3) tension positive (``point`` picks one of a batch).
    state : the state dict of ``model`` (batch), read at ``point``.
    d_nonlocal : None or (N,) the increment of the nonlocal field ebar (a model with a ``nonlocal_length``):
        the gradient-enhanced update (``docs/regularisation.md``, section 3).
    step_fraction : the step's size in nominal steps: the step stabilisation's floor is mu_a / step_fraction,
        and over the fraction lam of the increment mu_a / (lam step_fraction).

    Returns
    -------
    stress (3, 3), kappa (M,), opening dlambda of the cut-off, tangent (3, 3, 3, 3), or with ``d_nonlocal``
    a :class:`material.base.CoupledTangent` of this point (unbatched: (3, 3, 3, 3), (3, 3), e, (3, 3), ()).
    Raises :class:`ReferenceFailure` when no solution is found.
    """
    law = _Law(model)
    p = law.p
    de = np.asarray(d_strain, float).reshape(-1, 3, 3)[point]
    sig_n = np.asarray(stress, float).reshape(-1, 3, 3)[point]
    eps_n = np.asarray(state["strain"], float)[point]
    kap_n = np.asarray(state["kappa"], float)[point]
    gradient = d_nonlocal is not None
    soft = _softening_scale(model, state, point, gradient)
    strong = np.flatnonzero((kap_n > p.A) | ((soft > 0) & (kap_n >= p.kappa_instability)))
    grad, e_n = None, 0.0
    if gradient:
        post = np.flatnonzero((soft > 0) & (kap_n[strong] >= p.kappa_instability))
        e_n = float(np.asarray(state["post_peak_strain"], float)[point]) if "post_peak_strain" in state else \
            float(np.sum(kap_n[strong][post] - p.kappa_instability)) / p.t
        d_ebar = float(np.asarray(d_nonlocal, float).reshape(-1)[point])
        shift_n = np.asarray(state.get("nonlocal_shift", np.zeros_like(state["kappa"])), float)[point]
        m = model.over_nonlocal
        # kappa_hat - kappa of each plane past its peak: its accumulated shift plus m t d_ebar - m S
        grad = (post, shift_n[strong][post] + m * p.t * d_ebar, m) if post.size else None
    # the step stabilisation's floor of each plane over a nominal step: mu (w/t) G / sigma~ at sigma_n
    ef_end = law.eta_f(eps_n + _sym(_six(de)))
    st_n = law.planes(sig_n, ef_end)[1]
    unit = law.w / p.t * law.G / np.maximum(st_n, p.apex_stress)
    if model.options.stabilisation == "minimal":
        level = None if grad is None else (strong[grad[0]], grad[1])
        mu = minimal_stabilisation(law, sig_n, ef_end, kap_n, soft, unit, level) * unit
    else:
        mu = model.options.stabilisation * unit
    ns = strong.size
    ng = 0 if grad is None else 1
    de6 = _six(de)
    r_scale = np.abs(de6).max() + max(np.abs(sig_n).max(), p.apex_stress) / p.E
    scale = np.ones(6 + ns + 1 + ng)
    scale[:6] /= r_scale
    scale[6 + ns] /= r_scale
    # elastic trial
    trial = sig_n + 2 * law.G * de + law.lam * np.trace(de) * np.eye(3)
    ef = law.eta_f(eps_n + de)
    ratio, st, _ = law.planes(trial, ef)
    eta_n = law.hardening(kap_n, ef, soft)
    stiff = law.stiffness()
    if grad is not None:  # the planes past their peak at the nonlocal field's level
        at = strong[grad[0]]
        eta_n[at] = law.softening(kap_n[at] + grad[1], ef[at], soft)
    if np.trace(trial) <= 0 and np.all(st > 0) and np.all(ratio <= eta_n):
        if not gradient:
            return trial, kap_n.copy(), 0.0, stiff
        from material.base import CoupledTangent

        return trial, kap_n.copy(), 0.0, CoupledTangent(stiff, np.zeros((3, 3)), e_n, np.zeros((3, 3)), 0.0)
    x_done = np.concatenate([_six(sig_n), np.zeros(ns), [0.0], np.zeros(ng)])
    lam_done, h, halvings = 0.0, 1.0, 0
    while lam_done < 1.0:
        lam = min(1.0, lam_done + h)
        ok, x = _newton(law, x_done.copy(), (sig_n, lam * de6, eps_n, kap_n, soft, strong,
                                             mu / (lam * step_fraction), grad), scale, tol, maxit)
        if ok:
            lam_done, x_done, h = lam, x, min(2 * h, 1.0)
        else:
            h *= 0.5
            halvings += 1
            if halvings > max_halvings:
                x_done = _floor_homotopy(law, x_done.size, (sig_n, de6, eps_n, kap_n, soft, strong), mu / step_fraction,
                                         grad, scale, tol, maxit, max_halvings) if np.any(mu > 0) else None
                if x_done is None:
                    raise ReferenceFailure(f"no solution beyond the fraction {lam_done} of the increment")
                break
    args = (sig_n, de6, eps_n, kap_n, soft, strong, mu / step_fraction, grad)
    F, dk = residual(law, x_done, *args)
    J = _jacobian(law, x_done, args, scale)
    # d F / d d_eps by the complex step on the increment (tensor components, shear counted once)
    Fe = np.empty((x_done.size, 6))
    for j in range(6):
        dc = de6.astype(complex)
        dc[j] += 1j * _H
        Fe[:, j] = residual(law, x_done.astype(complex), sig_n, dc, *args[2:])[0].imag / _H * scale
    dxde = -np.linalg.solve(J, Fe)  # d x / d d_eps_kl with d_eps_kl and d_eps_lk moved together
    tangent = _tensor4(dxde[:6])
    stress, kappa, dl = _sym(x_done[:6]), kap_n + np.maximum(dk.real, 0.0), x_done[6 + ns]
    if not gradient:
        return stress, kappa, dl, tangent
    from material.base import CoupledTangent

    if grad is None:  # no plane past its peak: nothing depends on ebar, and e stays e_n
        return stress, kappa, dl, CoupledTangent(tangent, np.zeros((3, 3)), e_n, np.zeros((3, 3)), 0.0)
    post, c0, m = grad
    fz = residual(law, x_done.astype(complex), *args[:-1], (post, c0 + 1j * _H * m * p.t, m))[0].imag / _H * scale
    dx_ebar = -np.linalg.solve(J, fz)
    de_local = np.array([dxde[-1, b] * (1.0 if k == l else 0.5) for b, (k, l) in enumerate(_IJ)]) / p.t
    return stress, kappa, dl, CoupledTangent(tangent, _sym(dx_ebar[:6]), e_n + x_done[-1] / p.t, _sym(de_local),
                                             dx_ebar[-1] / p.t)


def _tensor4(d6):
    """(3, 3, 3, 3) from the (6, 6) derivative of the six stress components by the six strain components
    (an off-diagonal strain component moved with its transpose)."""
    tangent = np.zeros((3, 3, 3, 3))
    for a, (i, j) in enumerate(_IJ):
        for b, (k, l) in enumerate(_IJ):
            v = d6[a, b] * (1.0 if k == l else 0.5)
            tangent[i, j, k, l] = tangent[j, i, k, l] = tangent[i, j, l, k] = tangent[j, i, l, k] = v
    return tangent


def _rows(state, idx, n: int):
    """The rows ``idx`` of every per-point array of ``state`` (first dimension ``n``), copied."""
    return {k: (np.asarray(v)[idx].copy() if np.ndim(v) and np.shape(v)[0] == n else v) for k, v in state.items()}


def _put(dst, rows, src, mask) -> None:
    """dst[key][rows] = src[key][mask] for every per-point key the two states share (in place)."""
    for key, arr in src.items():
        if key in dst and np.ndim(arr) and np.ndim(dst[key]):
            dst[key][rows] = np.asarray(arr)[mask]


#: Continuation halvings of the one-step solves while the bisection of :func:`follow_past_limits` looks for a
#: limit: a trial beyond the limit fails after them, and the limit found is the same to 1e-11 with 4 as with
#: 12 halvings (measured on the footing's fold point of the tests).
_SEARCH_HALVINGS = 4


def follow_past_limits(model, d_strain, stress, state):
    """The continuation past limit points (``material._cpa_point``, "Past a limit point") as a plain loop
    over arrays of points, built on the kernel's one-step update (``model._integrate(..., limits=False)``):
    the reference of :func:`material._cpa_point.update_past_limits`, which does the same per point in numba.
    Returns (stress (N, 3, 3), state, ok (N,) bool); no tangent. It locates each limit point otherwise than
    the kernel: by ``model.LIMIT_BISECTIONS`` halvings of the whole fraction [0, 1] of the rest of the
    increment, each trial a one-step solve from the start of the rest (with at most ``_SEARCH_HALVINGS``
    continuation halvings), where the kernel bisects between the last fraction its solver reached and the
    one it failed at, each trial a Newton solve from the solution at the last fraction reached. The state at
    the last fraction that integrates starts the rest, up to ``model.MAX_LIMIT_POINTS`` times. (This was the
    package's update for one version, at about 2 s per point in a footing.)"""
    from material.base import STATUS_FAILED

    de = np.asarray(d_strain, dtype=float)
    sig = np.asarray(stress, dtype=float)
    m = de.shape[0]

    def one_step(d, s, st, halvings=None):
        return model._integrate(d, s, st, False, None, 1.0, halvings, limits=False)

    out_sig, out_state, _ = one_step(de, sig, state)
    ok = out_state["status"] != STATUS_FAILED
    cur_sig, cur_state, rest = sig.copy(), _rows(state, np.arange(m), m), de.copy()
    cur_state.setdefault("cutoff_opening", np.zeros(m))  # accumulated over the parts of the step
    count = np.zeros(m, dtype=np.int32)
    spent = {k: np.zeros(m, dtype=np.int32) for k in ("iterations", "continuation")}
    loading = np.zeros((m, model.n_planes), dtype=bool)
    todo = np.flatnonzero(~ok & (out_state["reached"] > 0.0))
    search = min(model.options.max_halvings, _SEARCH_HALVINGS)
    for _level in range(model.MAX_LIMIT_POINTS):
        if todo.size == 0:
            break
        k = todo.size
        lo, hi = np.zeros(k), np.ones(k)
        lo_sig, lo_state = cur_sig[todo].copy(), None  # the state at the last fraction reached
        t_sig, t_state, t_rest = cur_sig[todo], _rows(cur_state, todo, m), rest[todo]
        for _ in range(model.LIMIT_BISECTIONS):
            mid = 0.5 * (lo + hi)
            s_mid, st_mid, _ = one_step(mid[:, None, None] * t_rest, t_sig, t_state, search)
            good = st_mid["status"] != STATUS_FAILED
            lo, hi = np.where(good, mid, lo), np.where(good, hi, mid)
            lo_sig[good] = s_mid[good]
            if lo_state is None:  # rows that never integrate are dropped below (lo = 0)
                lo_state = {key: np.array(v, copy=True) for key, v in st_mid.items()}
            _put(lo_state, np.flatnonzero(good), st_mid, good)
        moved = lo > 0.0
        todo, lo, lo_sig = todo[moved], lo[moved], lo_sig[moved]
        lo_state = _rows(lo_state, np.flatnonzero(moved), k)
        if todo.size == 0:
            break
        count[todo] += 1
        for key in spent:
            spent[key][todo] += lo_state[key]
        loading[todo] |= lo_state["loading"]
        cur_sig[todo] = lo_sig
        _put(cur_state, todo, lo_state, np.ones(todo.size, dtype=bool))
        rest[todo] *= (1.0 - lo)[:, None, None]
        s1, st1, _ = one_step(rest[todo], cur_sig[todo], _rows(cur_state, todo, m))
        good = st1["status"] != STATUS_FAILED
        done = todo[good]
        out_sig[done] = s1[good]
        _put(out_state, done, st1, good)
        ok[done] = True
        todo = todo[~good & (st1["reached"] > 0.0)]
    for key in spent:
        out_state[key] = np.where(count > 0, out_state[key] + spent[key], out_state[key]).astype(np.int32)
    out_state["loading"] = out_state["loading"] | loading
    out_state["limit_points"] = count
    return out_sig, out_state, ok
