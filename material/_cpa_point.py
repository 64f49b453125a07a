"""The update of one Gauss point of the CPA law: the branch from sigma_n, its tangent, and the continuation
past limit points.

The local problem and its semismooth Newton solver are :mod:`material._cpa_local`; the rate problem that chooses
the branch at the kinks is :mod:`material._cpa_rate`.

Following the branch
--------------------
Newton starts at the solution for no increment, so its first step is the tangent predictor. A plane
that loaded in the last step sits exactly on its kink there, and the generalised derivative must pick a
branch for it (:data:`material._cpa_local._ON_CURVE`): the loading branch by default. When that Newton
does not converge, the branch of each plane on its kink (and of the cut-off, where it is on) is chosen by
solving the rate problem at sigma_n, a linear complementarity problem
(:func:`material._cpa_rate._rate_active_set`, Lemke's method: the coupling of non-associated planes near
failure or at low stress need not be a P-matrix, and then the all-loading guess can keep Newton away from
the one active set that solves it; measured on a point of a footing at 97 % mobilisation). If Newton still
fails, the equations are solved for the fraction lambda = 1/2, 1/4, ... of the increment,
each from the solution at the last fraction reached, and lambda is doubled again after each success, up
to 1. The answer is the solution at lambda = 1 of the one-step problem: the fractions only supply
starting points, they are not sub-steps. When the branch ends before lambda = 1 (a limit point of the
strain-driven response) :func:`point_update` reports ``FAILED`` with the fraction it reached, and
:func:`update_past_limits` goes on from the limit state (next section).

Where the branch in lam folds: the floor homotopy
-------------------------------------------------
With the step stabilisation (a floor h_a > 0) the branch in lam can fold before lam = 1 although the
one-step problem at lam = 1 has a solution: over lam the floor is h_a / lam, so lam moves the strain and
the viscosity together, and past a softening peak their path can turn back. Then the equations at lam = 1
are solved along the floor instead: with the floor k h_a, from k = :data:`_FLOOR_START` (where Newton from
sigma_n converges: the viscosity dominates the softening) down to k = 1, each solve from the solution at
the last k reached, the ratio of successive k shrinking towards 1 after a failure
(:func:`_floor_homotopy`). The answer is again the solution at lam = 1 of the one-step problem, a
deterministic function of the step's inputs. Measured on the biaxial shear-band study (quadratic elements,
l = 3 mm, mu = 0.01, to 8 %): 101 of the 117 rejected global attempts on 24 elements had a point that
failed this way, and the failed attempts took 36 % of the run's evaluations. On 12 stored failures drawn
from them the branch in lam ended at 0.90-0.97 of the increment and the floor homotopy reached k = 1; of
all the stored failures of the 24- and 48-element runs, 230 of 267 and 118 of 162 now integrate. On the
rest the floor homotopy folds too, and the point fails as before (``docs/cpa_law.md``, section 3).

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

import numpy as np
from numba import njit

from material._cpa_local import (
    FAILED,
    LIMIT,
    OK,
    Options,
    Point,
    _NSYS,
    _P_CB,
    _P_ETA,
    _P_GAMMA,
    _P_INV_ST0,
    _P_KP,
    _P_RATIO,
    _P_SLIP,
    _P_ST,
    _V_COL,
    _V_DE,
    _V_ELL,
    _V_EPS,
    _V_LAM,
    _V_S0,
    _V_S2,
    _V_SIG,
    _V_SIG_DONE,
    _is_elastic,
    _lu_solve,
    _newton,
    _ratios,
    evaluate,
    inverse_shifted_normal_stress,
    take_iterate,
)
from material._cpa_plane import (
    ISQ2, NO_REFCOUNT, REFCOUNT, compaction_weight, induced_slope, induced_tensor, plane_strengths,
)
from material._cpa_rate import _rate_active_set, _uniqueness_floor, floor_units

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
#: The floor homotopy (:func:`_floor_homotopy`) starts at this multiple of the step stabilisation's floor and
#: multiplies it by 4 while Newton from sigma_n fails there (at most :data:`_FLOOR_TRIES` times). On 12
#: stored failures of the shear-band study the reference's Newton converged at 10 times the floor (mu = 0.1
#: for the study's 0.01).
_FLOOR_START = 16.0
_FLOOR_TRIES = 4

@njit(cache=True, error_model="numpy")
def make_path():
    """The recorded path of one thread (:data:`_PATH_MODE` ...), off."""
    return np.zeros(_PATH_SIZE)


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
def _slips_out(law, plane, kap_n, strong, eta_f, kap_out, loading):
    """The outputs of the planes at a solution whose per-plane rows ``plane`` hold: kap_out, loading (a slip
    that grows), and the largest mobilisation etah_a / eta_f,a, which it returns."""
    best = 0.0
    for a in range(kap_n.shape[0]):
        slip = plane[_P_SLIP, a]
        kap_out[a] = kap_n[a] + max(slip, 0.0)
        loading[a] = slip > (0.0 if not strong[a] else 1e-12 * law.A)
        best = max(best, plane[_P_RATIO, a] / eta_f[a])
    return best


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def point_update(law, pd, opt, sig_n, de, eps_n, kap_n, soft, c0, m_over, nl_shift, sig_out, kap_out, D_out,
                 loading, grad_out, ws, path):
    """Integrate one Gauss point (Mandel vectors; see the module docstring for the algorithm).

    ``pd`` is :func:`material._cpa_local.plane_data` of ``law``, ``ws`` the thread's
    :func:`material._cpa_local.make_workspace`, ``path`` its :func:`make_path` (off, except in
    :func:`update_past_limits`). ``c0``, ``m_over`` and
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
            take_iterate(sig, dk, sig_done, dk_done)
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
                    take_iterate(sig, dk, sig_done, dk_done)
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
                best = _slips_out(law, plane, kap_n, strong, eta_f, kap_out, loading)
                return LIMIT, total_its, halvings, lo, dl_done, best, mu, 0.0
            if halvings > opt.max_halvings:
                if mu > 0.0:  # the branch in lam folded: the equations at lam = 1 along the floor instead
                    converged, its, dl, S = _floor_homotopy(law, pd, opt, pt, sig_n, de, ws)
                    total_its += its
                    if converged:
                        dl_done = dl
                        s_done = S
                        break
                _keep_start(law, opt.tangent, sig_n, kap_n, sig_out, kap_out, D_out, loading)
                return FAILED, total_its, halvings, lam_done, 0.0, np.nan, mu, 0.0
    _part_ends(1.0, path)
    # the solution at lam = 1 (sig, dk, plane and the LU factors of J are those of the last Newton solve)
    best = _slips_out(law, plane, kap_n, strong, eta_f, kap_out, loading)
    over = 0.0
    for a in range(M):
        slip = plane[_P_SLIP, a]
        if slip > 0.0:  # the floor's share of the plane's ratio: etah = eta(kappa) + h dkappa (ws.floor: lam = 1)
            over = max(over, ws.floor[a] * slip / plane[_P_RATIO, a])
    for i in range(6):
        sig_out[i] = sig[i]
    grad_out[0] = s_done
    if opt.tangent:
        _tangent(law, soft, eps_end, strong, pt, ws, D_out, grad_out)
    return OK, total_its, halvings, 1.0, dl_done, best, mu, over


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _floor_homotopy(law, pd, opt, pt, sig_n, de, ws):
    """The one-step equations at lam = 1 solved along the step stabilisation's floor (module docstring): the
    floor k ws.floor0 / opt.step from k = :data:`_FLOOR_START` (times 4 while Newton from sigma_n fails
    there) down to k = 1, each Newton solve from the solution at the last k reached; after a failed solve
    the ratio of the next k to the last shrinks to its square root, and the homotopy gives up after
    opt.max_halvings such failures. Returns (converged, Newton iterations, dl, S); on convergence sig
    (``ws.vecs[_V_SIG]``), dk, ``ws.plane`` and the LU factors are those of the solution at k = 1 and
    ``ws.floor`` the floor at lam = 1, as :func:`point_update` leaves them after its last fraction."""
    M = pt.kap_n.shape[0]
    sig, sig_done, de_lam = ws.vecs[_V_SIG], ws.vecs[_V_SIG_DONE], ws.vecs[_V_DE]
    dk, dk_done = ws.dk, ws.dk_done
    for i in range(6):
        de_lam[i] = de[i]
        sig_done[i] = sig_n[i]
    for a in range(M):
        dk_done[a] = 0.0
    dl_done, s_done, total_its = 0.0, 0.0, 0
    k_done = 0.0
    k = _FLOOR_START
    for _ in range(_FLOOR_TRIES + 1):
        converged, its, dl, S = _floor_solve(law, pd, opt, pt, k, sig, dk, sig_done, dk_done, 0.0, 0.0, ws)
        total_its += its
        if converged:
            k_done = k
            take_iterate(sig, dk, sig_done, dk_done)
            dl_done, s_done = dl, S
            break
        k *= 4.0
    if k_done == 0.0:
        return False, total_its, 0.0, 0.0
    ratio = 0.25
    failures = 0
    while k_done > 1.0:
        k = max(1.0, k_done * ratio)
        converged, its, dl, S = _floor_solve(law, pd, opt, pt, k, sig, dk, sig_done, dk_done, dl_done, s_done, ws)
        total_its += its
        if converged:
            k_done = k
            take_iterate(sig, dk, sig_done, dk_done)
            dl_done, s_done = dl, S
        else:
            failures += 1
            if failures > opt.max_halvings:
                break
            ratio = np.sqrt(ratio)
    for a in range(M):
        ws.floor[a] = ws.floor0[a] / opt.step
    return k_done == 1.0, total_its, dl_done, s_done


@njit(cache=True, inline="always", error_model="numpy", **NO_REFCOUNT)
def _floor_solve(law, pd, opt, pt, k, sig, dk, sig_done, dk_done, dl_done, s_done, ws):
    """One Newton solve of the one-step equations at lam = 1 with the floor k ws.floor0 / opt.step, from the
    solution (sig_done, dk_done, dl_done, s_done)."""
    for i in range(6):
        sig[i] = sig_done[i]
    for a in range(pt.kap_n.shape[0]):
        dk[a] = dk_done[a] if pt.strong[a] else 0.0
        ws.floor[a] = k * ws.floor0[a] / opt.step
    return _newton(law, pd, opt, pt, sig, dk, dl_done, s_done, ws)


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
