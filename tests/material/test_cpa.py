"""The CPA Gauss-point routine: elasticity, the kernel against the numpy reference, consistent tangent,
continuity through kinks and the apex, objectivity, robustness on hard points, bad input."""

import json
from pathlib import Path

import numpy as np
import pytest

from material import load_preset
from material.anisotropy import axes_from_alpha
from material.base import STATUS_FAILED, STATUS_OK
from material.cpa import CPAModel, replay
from material.cpa_reference import update_point
from material.parameters import parameters_from_dict

DATA = Path(__file__).parent / "data"
# a generic strain increment (no component zero, so no plane sits exactly on tau = 0)
DE = np.array([[0.8e-3, 1e-4, 2e-4], [1e-4, 0.6e-3, -1.5e-4], [2e-4, -1.5e-4, -2e-3]])
DE_SHEAR = np.diag([0.8e-3, -1e-3, 0.0])  # compression along y, strain driven


def _loaded(model, n_steps, de=DE, p0=100.0):
    sig = -p0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0])
    for _ in range(n_steps):
        sig, st, _ = model.update(de[None], sig, st)
        assert st["status"][0] != STATUS_FAILED
    return sig, st


def _fd_tangent(model, sig, st, de, h=1e-8):
    D = np.zeros((3, 3, 3, 3))
    for k in range(3):
        for l in range(k, 3):
            E = np.zeros((3, 3))
            E[k, l] += 0.5
            E[l, k] += 0.5
            sp, _, _ = model.update((de + h * E)[None], sig, st, tangent=False)
            sm, _, _ = model.update((de - h * E)[None], sig, st, tangent=False)
            col = (sp[0] - sm[0]) / (2 * h)
            D[:, :, k, l] = col
            D[:, :, l, k] = col
    return D


def _replay_file(name, **changes):
    d = dict(np.load(DATA / name))
    params = parameters_from_dict(json.loads(str(d["params_json"]))).replace(**changes)
    model = CPAModel(params, rule=str(d["rule"]), axes=d["axes"])
    state = {k[len("state__"):]: v for k, v in d.items() if k.startswith("state__")}
    return model, d, state


def test_isotropic_compression_is_elastic_with_bulk_modulus():
    p = load_preset("ottawa_c109")
    model = CPAModel(p, axes=axes_from_alpha(30.0))
    n = 4
    sig = np.repeat(-10.0 * np.eye(3)[None], n, axis=0)
    st = model.initial_state(n, stress=sig)
    de = np.repeat(-1e-3 * np.eye(3)[None], n, axis=0) * np.arange(1, n + 1)[:, None, None]
    new, st2, D = model.update(de, sig, st)
    K = p.E / (3 * (1 - 2 * p.nu))
    dp = -np.trace(new - sig, axis1=1, axis2=2) / 3
    np.testing.assert_allclose(dp, K * 3e-3 * np.arange(1, n + 1), rtol=1e-13)
    np.testing.assert_array_equal(st2["kappa"], st["kappa"])
    assert np.abs(st2["plastic_strain"]).max() < 1e-15
    assert np.all(st2["status"] == STATUS_OK) and not st2["loading"].any()
    assert D[0, 0, 0, 0, 0] + 2 * D[0, 0, 0, 1, 1] == pytest.approx(3 * K, rel=1e-12)


# every variant of the law, along a strain path, against the plain-numpy reference of the whole update
VARIANTS = {
    "inherent": (dict(), "ottawa_c109", 30.0, DE, 25, None),
    "induced": (dict(beta=5.0), "ottawa_c109_induced", 60.0, DE, 25, None),
    "coaxial": (dict(beta=5.0, alpha_hat=0.8, beta_hat=0.5), "ottawa_c109_induced", 20.0, DE, 20, None),
    "cohesion": (dict(c0=1.0, omega1_c=0.1, b=(0.2,)), "ottawa_c109", 45.0, DE, 25, None),
    "softening": (dict(zeta=1.05, softening_slip=0.01), "ottawa_c109", 0.0, DE_SHEAR, 200, 0.012),
    "compaction": (dict(compaction_stress=20.0), "ottawa_c109", 10.0, DE, 20, None),
    "stabilised": (dict(), "ottawa_c109", 30.0, DE, 25, None),
}
MODEL_OPTIONS = {"stabilised": dict(stabilisation=0.02)}


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_kernel_equals_the_numpy_reference_point_by_point(variant):
    """Stress, slips and tangent of the numba kernel against :mod:`material.cpa_reference` (3x3 algebra,
    complex-step Jacobians, no condensation) at every few steps of a path, from the elastic range to
    near failure (and past the peak for the softening law)."""
    changes, preset, alpha, de, n, h = VARIANTS[variant]
    model = CPAModel(load_preset(preset).replace(**changes), axes=axes_from_alpha(alpha),
                     **MODEL_OPTIONS.get(variant, {}))
    sig = -100.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0], element_size=h)
    checked = 0
    for k in range(n):
        s0, st0 = sig, st
        sig, st, D = model.update(de[None], sig, st)
        assert st["status"][0] == STATUS_OK
        if k % max(1, n // 6) == 0 or k == n - 1:
            s_ref, kappa_ref, _, D_ref = update_point(model, de, s0, st0)
            assert np.abs(sig[0] - s_ref).max() <= 1e-10 * np.abs(s_ref).max()
            assert np.abs(st["kappa"][0] - kappa_ref).max() <= 1e-9 * kappa_ref.max()
            assert np.abs(D[0] - D_ref).max() <= 1e-9 * np.abs(D_ref).max()
            checked += 1
    assert checked >= 6
    assert st["mobilised_ratio"][0] > 0.7  # the path goes well into the plastic range


@pytest.mark.parametrize(
    "preset,beta,alpha,steps",
    [
        ("ottawa_c109", 0.0, 0.0, 1),    # first plastic step from isotropic
        ("ottawa_c109", 0.0, 30.0, 10),  # hardening
        ("ottawa_c109", 0.0, 90.0, 40),  # near failure (mobilised ~0.9)
        ("ottawa_c109_induced", 5.0, 60.0, 30),  # induced anisotropy: eta_f depends on strain
    ],
)
def test_consistent_tangent_matches_finite_differences(preset, beta, alpha, steps):
    model = CPAModel(load_preset(preset).replace(beta=beta), axes=axes_from_alpha(alpha))
    sig, st = _loaded(model, steps - 1)
    _, st1, D = model.update(DE[None], sig, st)
    assert st1["status"][0] == STATUS_OK
    Dfd = _fd_tangent(model, sig, st, DE)
    err = np.abs(D[0] - Dfd).max() / np.abs(Dfd).max()
    assert err < 1e-6, err
    if steps >= 40:
        assert st1["mobilised_ratio"][0] > 0.85


def test_tangent_in_elastic_unloading_is_hooke():
    model = CPAModel("ottawa_c109")
    sig, st = _loaded(model, 10)
    new, st1, D = model.update(-0.05 * DE[None], sig, st)  # small reversal: every plane unloads
    assert np.all(st1["kappa"] == st["kappa"])
    from material.elastic import isotropic_stiffness

    np.testing.assert_allclose(D[0], isotropic_stiffness(6000.0, 0.33), rtol=1e-12, atol=1e-9)


def test_update_is_continuous_through_a_switching_event_and_its_tangent_is_the_derivative():
    """On a line d_eps(s) = d_eps0 + s h through the point where the first plane starts to load, the
    stress is continuous, and the difference quotient on each side matches the returned tangent there
    (the update is a deterministic, piecewise smooth function of its input)."""
    model = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0))
    sig, st = _loaded(model, 8)
    sig, st, _ = model.update(-0.4 * DE[None], sig, st)  # unload: every plane below its curve
    h = DE / np.abs(DE).max()
    s = np.linspace(0.0, 1e-3, 201)
    out = np.array([model.update((si * h)[None], sig, st, tangent=False)[0][0] for si in s])
    loading = np.array([model.update((si * h)[None], sig, st, tangent=False)[1]["loading"][0].any() for si in s])
    k = int(np.argmax(loading))
    assert 10 < k < 190  # the switch is inside the line
    steps = np.abs(np.diff(out, axis=0)).max(axis=(1, 2))
    assert steps.max() <= 1.5 * np.median(steps)  # no jump at the switch
    ds = s[1] - s[0]
    for j in (k - 5, k + 5):  # elastic side, loading side
        _, _, D = model.update((s[j] * h)[None], sig, st)
        slope = (out[j + 1] - out[j - 1]) / (2 * ds)
        np.testing.assert_allclose(np.einsum("ijkl,kl->ij", D[0], h), slope, rtol=1e-5, atol=1e-9 * np.abs(slope).max())


def test_update_is_continuous_through_the_apex():
    """A point extended from 20 kPa through zero stress (where the thesis's cone is singular) and back:
    every step integrates, the stress stays within the rounded apex (|sigma| of a few apex stresses) and
    the mean stress never becomes tensile; compression brings the point back onto the cone."""
    p = load_preset("ottawa_c109")
    model = CPAModel(p)
    sig = -20.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0])
    de = np.array([[2e-3, 1e-4, 0.0], [1e-4, 1e-3, 0.0], [0.0, 0.0, 1.5e-3]])
    for _ in range(20):
        sig, st, D = model.update(de[None], sig, st)
        assert st["status"][0] == STATUS_OK and np.isfinite(D).all()
        assert np.trace(sig[0]) <= 1e-9
    assert np.abs(sig[0]).max() < 20 * p.apex_stress and st["near_apex"][0]
    assert st["cutoff_opening"][0] > 1e-2  # the extension has opened the sand
    for _ in range(20):
        sig, st, _ = model.update(-de[None], sig, st)
        assert st["status"][0] == STATUS_OK
    assert np.trace(sig[0]) < -100.0


def test_volumetric_extension_opens_at_the_cutoff():
    model = CPAModel("ottawa_c109")
    sig = -10.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0])
    new, st1, D = model.update(1e-2 * np.eye(3)[None], sig, st)  # volumetric extension beyond p = 0
    assert np.trace(new[0]) == pytest.approx(0.0, abs=1e-9)
    assert np.abs(new[0]).max() < 1e-3  # (a deviator of ~1e-4 kPa held by the anisotropic planes)
    assert st1["status"][0] == STATUS_OK and np.isfinite(D).all()
    K = 6000.0 / (3 * (1 - 2 * 0.33))
    # the opening takes the misfit: eps_p = d_eps + S sigma_n (volumetric)
    assert np.trace(st1["plastic_strain"][0]) == pytest.approx(3e-2 - 30.0 / (3 * K), rel=1e-9)
    # (the planes, mobilised to 0.1 at zero stress, add a little plastic volume change of their own)
    assert 0.98 < st1["cutoff_opening"][0] / np.trace(st1["plastic_strain"][0]) <= 1.0
    back, st2, _ = model.update(-2e-2 * np.eye(3)[None], new, st1)
    assert st2["status"][0] == STATUS_OK and np.trace(back[0]) < 0


def test_apex_stress_changes_the_strength_by_its_ratio_to_the_normal_stress():
    """The apex shift raises the strength of a plane at normal stress sigma_N by about c_a / sigma_N:
    the analytic failure of one plane (the failure surface of the rounded law) against the cone."""
    from material.cpa_reference import _Law

    p = load_preset("ottawa_c109")
    model = CPAModel(p)
    law = _Law(model)
    ef = law.eta_f(np.zeros((3, 3)))
    for sN in (10.0, 100.0):
        # the shear stress at which the plane's ratio reaches eta_f at normal stress sN (b^2 << tau^2)
        tau = ef * (sN + p.apex_stress)
        tau = np.sqrt(tau ** 2 - law.b ** 2)
        np.testing.assert_allclose(tau / (ef * sN) - 1, p.apex_stress / sN, rtol=1e-3)


def test_surface_points_need_the_compaction_fade():
    """Points of the thesis-sand footing next to the surface, in situ (0.2-2 kPa), with the first
    increment of the footing: with the thesis's flow rule at every stress (compaction_stress = 0) the
    strain-driven problem of these contractive planes has no solution and every point fails; with the
    default fade they integrate in a few iterations and agree with the reference."""
    model0, d, state = _replay_file("footing_surface_points.npz")
    assert model0.params.compaction_stress == 0.0
    idx = np.arange(0, len(d["stress"]), 13)
    _, st0, _ = model0.update(d["d_strain"][idx], d["stress"][idx], {k: v[idx] for k, v in state.items()})
    assert (st0["status"] == STATUS_FAILED).all()
    model, _, _ = _replay_file("footing_surface_points.npz", compaction_stress=2.0)
    s, st, D = model.update(d["d_strain"][idx], d["stress"][idx], {k: v[idx] for k, v in state.items()})
    assert (st["status"] == STATUS_OK).all() and st["iterations"].max() <= 20
    for j in (0, len(idx) // 2, len(idx) - 1):
        s_ref, _, _, D_ref = update_point(model, d["d_strain"][idx], d["stress"][idx],
                                          {k: v[idx] for k, v in state.items()}, point=j)
        assert np.abs(s[j] - s_ref).max() <= 1e-9 * np.abs(s_ref).max()


def test_the_footing_stopped_where_a_point_has_two_branches_from_its_start_and_the_one_followed_folds():
    """Point 881 of ``femgran footing --alpha 0`` (the thesis's law, mu = 0) where it stopped, s = 0.056 B,
    before the update continued past limit points: its strain increment at the global iterate where the
    line search found no decrease, and that iterate's Newton direction at the point (``docs/cpa_law.md``,
    section 4). Here the one-step problem alone (``MAX_LIMIT_POINTS = 0``). Along d_strain + s * direction
    the step follows a branch with 16 loading planes and positive second-order work; it ends at a fold
    between s = 1e-4 and 2e-4, where the one-step update fails. From the same start a second branch, with
    12 loading planes and negative second-order work (a softening response), exists over the whole range:
    the kernel's direct Newton finds it at s = 5e-3, and the reference's Newton follows it back to s = 0,
    where it differs from the kernel's answer by 0.01 kPa. That jump kept the footing's residual near
    1e-5 (the tolerance is 1e-8)."""
    from femgran.diagnostics import kinks_along
    from material import cpa_reference as ref

    model, d, state = _replay_file("footing_fold_point.npz")
    model.MAX_LIMIT_POINTS = 0
    sig, de, dd = d["stress"], d["d_strain"], d["direction"]

    def update(s):
        copy = {k: v.copy() for k, v in state.items()}
        out, st, _ = model.update(de + s * dd, sig, copy)
        return out[0], st, float(np.sum((out[0] - sig[0]) * (de + s * dd)[0]))

    s0, st0, w0 = update(0.0)
    assert st0["status"][0] == STATUS_OK and st0["loading"][0].sum() == 16 and w0 > 0.0
    assert update(1e-4)[1]["loading"][0].sum() == 16
    assert update(5e-4)[1]["status"][0] == STATUS_FAILED
    s_far, st_far, w_far = update(5e-3)
    assert st_far["status"][0] == STATUS_OK and st_far["loading"][0].sum() == 12 and w_far < 0.0
    probe = kinks_along(model, sig, state, de, dd, np.linspace(0.0, 1e-3, 11))
    assert 1e-4 < probe["failed_at"][0] <= 3e-4
    # the 12-plane branch at s = 0, by the reference's equations and Newton, from the kernel's s = 5e-3
    law = ref._Law(model)
    kap_n, eps_n = state["kappa"][0], state["strain"][0]
    strong = np.flatnonzero(kap_n > law.p.A)
    x = np.concatenate([ref._six(s_far), (st_far["kappa"][0] - kap_n)[strong], [0.0]])
    for s in np.linspace(5e-3, 0.0, 6):
        de6 = ref._six((de + s * dd)[0])
        r_scale = np.abs(de6).max() + np.abs(sig).max() / law.p.E
        scale = np.ones(x.size)
        scale[:6] /= r_scale
        scale[-1] /= r_scale
        args = (sig[0], de6, eps_n, kap_n, 0.0, strong, np.zeros(kap_n.size), None)
        ok, x = ref._newton(law, x, args, scale, 1e-11, 40)
        assert ok
    dk = ref.residual(law, x, *args)[1].real
    assert (dk > 1e-14).sum() == 12
    jump = np.abs(ref._sym(x[:6]) - s0).max()
    assert 5e-3 < jump < 2e-2  # 0.0101 kPa
    assert float(np.sum((ref._sym(x[:6]) - sig[0]) * de[0])) < 0.0


def test_a_point_whose_branch_ends_within_the_step_goes_on_from_its_limit_state_continuously():
    """The same point with the update as it is: where the branch followed from the start of the step ends
    at a limit point (a fraction lam* < 1 of the increment), the state there starts the rest of the
    increment. Along d_strain + s * direction the stress is then continuous: through the onset of the limit
    (s ~ 1.7e-4, lam* -> 1), along the stretch where the rest of the step is taken on the 12-plane branch,
    and where lam* -> 0 and the step goes on that branch from its start (s ~ 4.1e-3). The one-step update
    failed on the first part and jumped by 0.0101 kPa at the last (previous test). The response there is
    steep (2.55 kPa per unit s, about 1,000 E along the direction), and the tangent by central
    differences is its derivative."""
    from material import _cpa_kernel as _k

    model, d, state = _replay_file("footing_fold_point.npz")
    sig, de, dd = d["stress"], d["d_strain"], d["direction"]
    grid = np.concatenate([[1.5e-4], np.arange(2e-4, 4.6e-3, 2e-4)])
    stresses, passed = [], []
    for s in grid:
        out, st, _ = model.update(de + s * dd, sig, state, tangent=False)
        assert st["status"][0] == STATUS_OK
        stresses.append(out[0])
        passed.append(int(st["limit_points"][0]))
    assert passed[0] == 0 and passed[-1] == 0 and all(p == 1 for p in passed[1:-3])
    steps = np.abs(np.diff(np.array(stresses), axis=0)).max(axis=(1, 2))
    assert steps.max() < 6e-4  # 2.55 kPa per unit s over 2e-4, against the one-step jump of 0.0101 kPa
    again, st2, D = model.update(de + 1e-3 * dd, sig, state, tangent="mandel")
    assert int(st2["limit_points"][0]) == 1
    assert np.array_equal(again[0], model.update(de + 1e-3 * dd, sig, state, tangent=False)[0][0])
    e = 1e-5
    plus = model.update(de + (1e-3 + e) * dd, sig, state, tangent=False)[0]
    minus = model.update(de + (1e-3 - e) * dd, sig, state, tangent=False)[0]
    fd = (_k.to_mandel(plus) - _k.to_mandel(minus))[0] / (2 * e)
    slope = D[0] @ _k.to_mandel(dd)[0]
    assert 2.4 < fd[0] < 2.7
    assert np.abs(slope - fd).max() <= 2e-3 * np.abs(fd).max()


def test_the_kernel_passes_limit_points_as_the_plain_loop_of_the_reference_does():
    """The kernel's continuation past limit points (numba, per point: bisection between the last fraction its
    solver reached and the one it failed at, warm-started) against the reference's (a loop over arrays of
    points: bisection of the whole fraction, each trial solved from the start of the rest), on the stored fold
    point along its line and on the near-failure point (8 limit points): the same limit points, the same
    stress to 1e-9 of its size (measured: 8e-9 kPa at most, of 24 kPa)."""
    from material.cpa_reference import follow_past_limits

    model, d, state = _replay_file("footing_fold_point.npz")
    s = np.array([1.5e-4, 1e-3, 3e-3, 4.0e-3, 4.4e-3])
    de = d["d_strain"] + s[:, None, None] * d["direction"]
    sig = np.repeat(d["stress"], s.size, axis=0)
    st = {k: np.repeat(v, s.size, axis=0) for k, v in state.items()}
    near, d2, st2 = _replay_file("near_failure_point.npz")
    for m, args in ((model, (de, sig, st)), (near, (d2["d_strain"], d2["stress"], st2))):
        out, new, _ = m.update(*args, tangent=False)
        ref_out, ref_new, ok = follow_past_limits(m, *args)
        assert ok.all() and (new["status"] == STATUS_OK).all()
        assert np.array_equal(new["limit_points"], ref_new["limit_points"])
        assert np.abs(out - ref_out).max() <= 1e-9 * np.abs(ref_out).max()
        # each limit is located to 2^-40 of the rest of the increment, and the slips move by that fraction of
        # their increment (measured: 2.2e-12 m of 1.4e-3 m on one machine, 1.4e-12 m on another)
        assert np.abs(new["kappa"] - ref_new["kappa"]).max() <= 1e-8 * np.abs(ref_new["kappa"]).max()
        assert np.array_equal(new["loading"], ref_new["loading"])
    assert new["limit_points"].tolist() == [8] * d2["stress"].shape[0]


def test_the_tangent_past_a_limit_point_is_the_forward_difference_of_the_update_itself():
    """The tangent past a limit point is the forward difference of the continuation, and its continuations
    skip the solves that failed far beyond the limit in the step's own (material._cpa_point._fails_again). The
    skipping must not change the function: each column equals the difference of two updates without the
    tangent, which skip nothing, to round-off (the fold point at four places along its line, whose limit
    moves by up to 3.5 % of the increment under the perturbation, and the near-failure point with 8 limit
    points). And it is the derivative: within 1 % of the central difference of the same updates."""
    from material import _cpa_kernel as _k

    model, d, state = _replay_file("footing_fold_point.npz")
    s = np.array([1e-3, 2e-3, 3e-3, 4e-3])
    near, d2, st2 = _replay_file("near_failure_point.npz")
    cases = [(model, d["d_strain"] + s[:, None, None] * d["direction"], np.repeat(d["stress"], s.size, axis=0),
              {k: np.repeat(v, s.size, axis=0) for k, v in state.items()}),
             (near, d2["d_strain"], d2["stress"], st2)]
    for m, de, sig, st in cases:
        out, new, D = m.update(de, sig, st, tangent="mandel")
        assert (new["limit_points"] >= 1).all()
        de6, sig6 = _k.to_mandel(de), _k.to_mandel(sig)
        w = np.array([1.0, 1.0, 1.0, 2 ** -0.5, 2 ** -0.5, 2 ** -0.5])
        h = m.LIMIT_FD_STEP * (np.abs(de6 * w).max(axis=1) + np.abs(sig6 * w).max(axis=1) * m._comp[0, 0])
        base = _k.to_mandel(m.update(de, sig, st, tangent=False)[0])
        assert np.array_equal(base, _k.to_mandel(out))
        for j in range(6):
            step = np.zeros_like(de6)
            step[:, j] = h
            plus = _k.to_mandel(m.update(_k.from_mandel(de6 + step), sig, st, tangent=False)[0])
            minus = _k.to_mandel(m.update(_k.from_mandel(de6 - step), sig, st, tangent=False)[0])
            forward = (plus - base) / h[:, None]
            central = (plus - minus) / (2 * h[:, None])
            scale = np.abs(D).max(axis=(1, 2))[:, None]
            assert np.abs(D[:, :, j] - forward).max() <= 1e-9 * scale.max()
            assert (np.abs(D[:, :, j] - central) <= 1e-2 * scale).all()


def _kernel_rate_choice(model, d, state, r_scale):
    """The kernel's rate problem of the stored point: (select (M + 1,), found), select[M] the cut-off's."""
    from material import _cpa_local as L
    from material._cpa_rate import _rate_active_set
    from material._cpa_kernel import to_mandel
    from material._cpa_plane import induced_tensor, plane_strengths

    law = model._law
    sig_n, de, eps_n = (to_mandel(a[:1])[0] for a in (d["stress"], d["d_strain"], state["strain"]))
    kap_n = np.ascontiguousarray(state["kappa"][0])
    M = kap_n.size
    ws = L.make_workspace(M)
    lam6 = np.zeros(6)
    induced_tensor(eps_n + de, law.beta, law.alpha_hat, law.beta_hat, lam6)
    plane_strengths(law.nn6, law.omega6, lam6, law.coeffs, law.eta0, ws.eta_f, ws.deta_f)
    pt = L.Point(sig_n, de, kap_n, 0.0, ws.eta_f, law.cohesion / ws.eta_f + law.apex_stress, kap_n > law.A,
                 ws.select, ws.floor, r_scale, ws.post, False, 0.0, 0.0, np.zeros(M))
    found = _rate_active_set(law, pt, ws)
    return ws.select.copy(), found


def test_rate_problem_of_a_near_failure_point_is_solved_by_complementary_pivoting():
    """A point of the thesis-sand footing at 90 % mobilisation whose planes on their curves couple into
    a rate problem with three solutions (not a P-matrix problem; enumerated here with the reference
    algebra): Lemke's method in the kernel picks one of them."""
    import itertools

    from material.cpa_reference import _Law, rate_coupling

    model, d, state = _replay_file("near_failure_point.npz")
    select, _ = _kernel_rate_choice(model, d, state, 1.0)
    chosen = {int(a) for a in np.flatnonzero(select[:-1])}  # (select[M]: the cut-off, off here)
    kap_n = state["kappa"][0]
    # the rate problem by the reference: b_a = d etah_a / d sigma (complex step), m_a, q and H
    ref = _Law(model)
    ef = ref.eta_f(state["strain"][0] + d["d_strain"][0])
    on, Cb, H, _ = rate_coupling(ref, d["stress"][0], ef, kap_n, 0.0)
    assert 10 < on.size < 20
    q = np.einsum("aij,ij->a", Cb, d["d_strain"][0])
    solutions = []
    for k in range(on.size + 1):
        for c in itertools.combinations(range(on.size), k):
            c = list(c)
            x = np.zeros(on.size)
            if c:
                try:
                    x[c] = np.linalg.solve(H[np.ix_(c, c)], q[c])
                except np.linalg.LinAlgError:
                    continue
            w = q - H @ x
            if (x >= -1e-12).all() and (w <= 1e-9 * np.abs(q).max()).all():
                solutions.append({int(on[j]) for j in c if x[j] > 0})
    assert len(solutions) == 3  # the rate problem of this point is not uniquely solvable
    assert chosen in solutions


def test_step_stabilisation_integrates_the_near_failure_point_and_vanishes_with_the_step():
    """The near-failure point with three rate solutions has no solution along the branch from the start
    of its step (the one-step problem fails; the thesis's law goes on past 8 limit points of its branch);
    with the step stabilisation mu = 0.02 (a hardening of at least mu / A within the step) its step problem
    is uniquely solvable and it integrates in one step. On a regular path the stabilisation's effect on the
    stress is first order in the step: 10x smaller with 10x more steps."""
    model, d, state = _replay_file("near_failure_point.npz")
    model.MAX_LIMIT_POINTS = 0
    _, st0, _ = model.update(d["d_strain"], d["stress"], state)
    assert (st0["status"] == STATUS_FAILED).all()
    del model.MAX_LIMIT_POINTS
    _, st_lp, _ = model.update(d["d_strain"], d["stress"], state, tangent=False)
    assert (st_lp["status"] == STATUS_OK).all() and (st_lp["limit_points"] == 8).all()
    stab = CPAModel(model.params, rule=model.rule, axes=model.axes, stabilisation=0.02)
    s, st, D = stab.update(d["d_strain"], d["stress"], state)
    assert (st["status"] == STATUS_OK).all() and np.isfinite(D).all() and (st["limit_points"] == 0).all()
    assert np.abs(s - d["stress"]).max() < 0.1 * np.abs(d["stress"]).max()  # an ordinary small step

    def path_end(mu, n):
        m = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0), stabilisation=mu)
        sig = -100.0 * np.eye(3)[None]
        st = m.initial_state(1, stress=sig[0])
        for _ in range(n):
            sig, st, _ = m.update((20 * DE / n)[None], sig, st, tangent=False)
        return sig[0]

    e10 = np.abs(path_end(0.02, 10) - path_end(0.0, 10)).max()
    e100 = np.abs(path_end(0.02, 100) - path_end(0.0, 100)).max()
    assert 0 < e100 < 0.2 * e10, (e10, e100)


def _is_p_matrix(H):
    """Every principal minor positive (enumerated: the 10-20 planes on their curves at one point)."""
    import itertools

    k = H.shape[0]
    return all(np.linalg.det(H[np.ix_(c, c)]) > 0 for r in range(1, k + 1) for c in itertools.combinations(range(k), r))


def test_minimal_stabilisation_is_a_floor_just_large_enough_for_a_unique_rate_problem():
    """At the near-failure point (three rate solutions) the "minimal" stabilisation takes mu = 0.082: with
    its floor mu U the coupling of the planes on their curves is a P-matrix (one rate solution for every
    strain rate), with half of it not, so the floor is within a factor 2 of the least that works. The kernel's
    mu, stress and tangent equal the reference's (which computes mu by the definition)."""
    from material.cpa_reference import _Law, minimal_stabilisation, rate_coupling

    model, d, state = _replay_file("near_failure_point.npz")
    mini = model.replace(stabilisation="minimal")
    s, st, D = mini.update(d["d_strain"], d["stress"], state)
    assert (st["status"] == STATUS_OK).all()
    mu = st["stabilisation"][0]
    p = model.params
    ref = _Law(mini)
    ef = ref.eta_f(state["strain"][0] + d["d_strain"][0])
    kap_n = state["kappa"][0]
    on, _, H, sig_t = rate_coupling(ref, d["stress"][0], ef, kap_n, 0.0)
    unit = ref.w / p.t * ref.G / np.maximum(sig_t, p.apex_stress)
    assert mu == pytest.approx(minimal_stabilisation(ref, d["stress"][0], ef, kap_n, 0.0, unit), rel=1e-9)
    assert 0.06 < mu < 0.12, mu
    U = np.diag(unit[on])
    assert not _is_p_matrix(H)
    assert _is_p_matrix(H + mu * U) and not _is_p_matrix(H + 0.5 * mu * U)
    s_ref, _, _, D_ref = update_point(mini, d["d_strain"], d["stress"], state, point=0)
    np.testing.assert_allclose(s[0], s_ref, atol=1e-10 * np.abs(s_ref).max())
    np.testing.assert_allclose(D[0], D_ref, atol=1e-9 * np.abs(D_ref).max())


def test_uniqueness_floor_of_committed_states_is_the_minimal_stabilisation():
    """CPAModel.uniqueness_floor (what `femgran replay` prints for a stopped run) gives each committed state
    the mu the minimal stabilisation takes in its next step: 0.082 at the near-failure point, 0 at an
    in-situ state inside its elastic range; a state of another rule is refused; on 200 points the update's
    parallel batch agrees."""
    model, d, state = _replay_file("near_failure_point.npz")
    mu = model.uniqueness_floor(d["stress"], state)
    _, st, _ = model.replace(stabilisation="minimal").update(d["d_strain"], d["stress"], state)
    np.testing.assert_allclose(mu, st["stabilisation"], rtol=1e-12)  # (beta = 0: eta_f does not move in a step)
    assert 0.06 < mu.min()
    fresh = model.initial_state(3, stress=-100.0 * np.eye(3))
    np.testing.assert_array_equal(model.uniqueness_floor(-100.0 * np.eye(3), fresh), 0.0)
    with pytest.raises(ValueError, match=r"state\['kappa'\]: shape \(2, 33\) does not match \(2, 21\)"):
        CPAModel("ottawa_c109", rule="bazant-oh-21").uniqueness_floor(d["stress"], state)
    # the update's parallel batch takes the same mu as this serial loop, point by point (the same loop under
    # parallel=True once did not: 0.0825 for 0.0822), with increments of 0.2 to 1.5 times the stored one
    reps = 100
    many = {k: np.repeat(v, reps, axis=0) if np.ndim(v) and np.shape(v)[0] == 2 else v for k, v in state.items()}
    sig = np.repeat(d["stress"], reps, axis=0)
    scale = np.linspace(0.2, 1.5, 2 * reps)[:, None, None]
    _, st_many, _ = model.replace(stabilisation="minimal").update(np.repeat(d["d_strain"], reps, axis=0) * scale, sig,
                                                                  many, tangent=False)
    np.testing.assert_allclose(st_many["stabilisation"], model.uniqueness_floor(sig, many), rtol=1e-12)


def test_minimal_stabilisation_leaves_a_uniquely_solvable_path_to_the_thesis_law():
    """Along an element path to 97 % mobilisation every step's rate problem is uniquely solvable: the
    minimal stabilisation's mu is 0 at every step and the stress is the thesis's law's to the bit (the
    uniform mu = 0.02 moves it)."""
    ends = {}
    for mu in ("minimal", 0.0, 0.02):
        m = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0), stabilisation=mu)
        sig = -100.0 * np.eye(3)[None]
        st = m.initial_state(1, stress=sig[0])
        for _ in range(40):
            sig, st, _ = m.update((2 * DE)[None], sig, st, tangent=False)
            assert st["stabilisation"][0] == (0.02 if mu == 0.02 and st["iterations"][0] > 0 else 0.0)
        ends[mu] = (sig[0], st["mobilised_ratio"][0])
    assert ends["minimal"][1] > 0.97
    np.testing.assert_array_equal(ends["minimal"][0], ends[0.0][0])
    assert np.abs(ends[0.02][0] - ends[0.0][0]).max() > 1e-3


def test_step_stabilisation_relaxes_in_proportion_to_the_step_so_the_update_is_continuous_at_zero():
    """The stabilisation is a viscosity with a relaxation time of one nominal step: a point loaded in
    nominal steps carries an overstress; a step with no strain relaxes it by a finite amount over a nominal
    step, and by an amount proportional to the step's size as the step shrinks (continuity at zero: a
    cut-back brings the step back to the committed equilibrium). Kernel and reference agree at any size;
    the size is validated."""
    model = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0), stabilisation=0.1)
    sig, st = _loaded(model, 25)
    assert st["mobilised_ratio"][0] > 0.8
    change = {}
    for f in (1.0, 1e-3, 1e-6):
        s, st2, _ = model.update(np.zeros((1, 3, 3)), sig, st, step_fraction=f)
        assert st2["status"][0] == STATUS_OK
        change[f] = np.abs(s - sig).max()
    assert change[1.0] > 0.01  # kPa: the overstress of a nominal step relaxes
    assert change[1e-6] < 1e-4 * change[1.0]
    assert 0.5e-3 < change[1e-6] / change[1e-3] < 2e-3  # proportional to the step's size
    for f in (0.25, 1.0):
        s, st2, D = model.update(0.5 * DE[None], sig, st, step_fraction=f)
        s_ref, kappa_ref, _, D_ref = update_point(model, 0.5 * DE, sig, st, step_fraction=f)
        assert np.abs(s[0] - s_ref).max() <= 1e-10 * np.abs(s_ref).max()
        assert np.abs(D[0] - D_ref).max() <= 1e-9 * np.abs(D_ref).max()
    # without the stabilisation the step's size changes nothing
    plain = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0))
    sig, st = _loaded(plain, 25)
    a = plain.update(0.5 * DE[None], sig, st, step_fraction=0.01)[0]
    assert np.array_equal(a, plain.update(0.5 * DE[None], sig, st)[0]) and not plain.rate_dependent
    assert model.rate_dependent
    for bad in (0.0, -1.0, np.nan, np.ones(2)):
        with pytest.raises(ValueError, match="step_fraction = .*: allowed a finite number > 0"):
            model.update(DE[None], sig, st, step_fraction=bad)


def test_a_short_step_of_a_strongly_overstressed_point_converges_with_its_large_floor():
    """A shallow point of the stiff sand's footing (E = 60 MPa, stabilisation 0.1 with a relaxation time of
    1/40: 24 planes loading at 15 times their failure ratio, 2.9 kPa mean stress). A short step makes the
    floor h / f huge, and the complementarity's v = eta + h dkappa - etah then has to be scaled by
    1 + h A to be computable to Phi's tolerance: without it the local Newton stalled at Phi ~ 1e-11 and the
    point failed for every f <= 1e-6 (its footing run stopped). Each short step now converges in a few
    iterations (7-10 with the overstress in the ratio form, 12-14 in the traction form of the next test, where
    the ratio rises from 15 to 584 as sigma~ falls; 10-18 since the local Newton tries the active-set phase
    after two cut steps, which here does not converge in its four steps and hands on its last iterate)
    and agrees with the plain-numpy reference."""
    model, d, state = _replay_file("overstressed_shallow_point.npz")
    model = model.replace(stabilisation=0.1)
    assert state["mobilised_ratio"][0] > 14.0 and state["loading"][0].sum() == 24
    for f in (1e-5, 1e-6, 1e-7, 1e-8):
        s, st, _ = model.update(d["d_strain"], d["stress"], state, step_fraction=f)
        assert st["status"][0] == STATUS_OK and st["iterations"][0] <= 20, (f, st["iterations"])
    s, st, D = model.update(d["d_strain"], d["stress"], state, step_fraction=1e-6)
    s_ref, _, _, D_ref = update_point(model, d["d_strain"][0], d["stress"][0], state, step_fraction=1e-6)
    assert np.abs(s[0] - s_ref).max() <= 1e-9 * np.abs(s_ref).max()
    assert np.abs(D[0] - D_ref).max() <= 1e-6 * np.abs(D_ref).max()


def test_a_strongly_overstressed_point_relaxes_over_whole_relaxation_times():
    """The same point over long steps, f = 1e-3 to 3 relaxation times, with its strain increment and with
    none: the overstress relaxes (its largest ratio over eta_f falls from 15 to 2.0, 1.4, 1.06, 0.88 and 0.85).
    The strong planes' equation is in the traction form Phi(dkappa / A, (sigma~ (eta + h dkappa) - T) /
    (sigma~_n (1 + h A))): the ratio T / sigma~ of the former form is a quotient whose linearisation fails when
    sigma~ changes by a large factor within the step, and the local Newton crept (steps of 2^-4 to 2^-13 of
    the Newton step): 185 / 250 / 385 iterations with 5 / 7 / 12 halvings at f = 1e-3 / 1e-2 / 0.1, and at
    f = 1 and 3 the point failed (12 halvings). In the traction form, affine in (sigma~, T) for a given slip,
    7-10 iterations without a halving, and 40-73 with 2-4 halvings at f = 1 and 3; with the active-set phase
    of the local Newton 6-14 iterations, and 11 / 56-65 at f = 1 / 3. Same solutions (the scaling is
    positive), the same tangent (it multiplies v = 0 where a plane loads), and the reference agrees."""
    model, d, state = _replay_file("overstressed_shallow_point.npz")
    model = model.replace(stabilisation=0.1)
    for de in (d["d_strain"], np.zeros_like(d["d_strain"])):
        ratios = []
        for f in (1e-3, 1e-2, 0.1, 1.0, 3.0):
            _, st, _ = model.update(de, d["stress"], state, step_fraction=f)
            assert st["status"][0] == STATUS_OK, f
            if f < 1.0:
                assert st["continuation"][0] == 0 and st["iterations"][0] <= 16, (f, st["iterations"])
            else:
                assert st["continuation"][0] <= 6 and st["iterations"][0] <= 100, (f, st["iterations"])
            ratios.append(st["mobilised_ratio"][0])
        assert np.all(np.diff(ratios) < 0) and 0.8 < ratios[-1] < 0.9 < 1.0 < ratios[2] < 1.1, ratios
    s, _, D = model.update(d["d_strain"], d["stress"], state, step_fraction=1.0)
    s_ref, _, _, D_ref = update_point(model, d["d_strain"][0], d["stress"][0], state, step_fraction=1.0)
    assert np.abs(s[0] - s_ref).max() <= 1e-9 * np.abs(s_ref).max()
    assert np.abs(D[0] - D_ref).max() <= 1e-6 * np.abs(D_ref).max()


def test_a_plane_that_loaded_to_the_solvers_tolerance_takes_part_in_the_rate_problem():
    """An edge point of the isotropic footing (equator-78 rule, E = 60 MPa, resolution 5, 80 steps; 0.1 kPa,
    27 loading planes, three of them nearly perfectly plastic). The loading plane 10 ended the last step
    1.6e-12 below its hardening curve: within the local solver's tolerance (a loading plane ends a step with
    |sigma~ (eta - etah) / sigma~_n| <= tol), outside a rate problem whose test of "on its curve" was 1e-12.
    With that test it kept its elastic branch, the first Newton step overstressed it and the local Newton
    stalled with Phi in proportion to the fraction of the increment (1.6e-5 at lambda = 1, 3.9e-9 at 2^-12):
    the point failed for its increment and for every cut-back down to 7e-7, and that footing stopped at
    s = 0.0036 B. With the test at 1e-9 (``_RATE_ON_CURVE``) it converges without a halving at every multiple
    of its increment (10-13 iterations with the active-set phase of the local Newton, 41-48 without it), and
    agrees with the reference."""
    from material.cpa_reference import update_point

    model, d, state = _replay_file("footing_edge_vertex_point.npz")
    eta_f = model.friction_coefficients(state["strain"])[0]
    etah = model.mobilised_ratios(d["stress"], state["strain"])[0]
    kap, A = state["kappa"][0], model.params.A
    gap = eta_f * kap / (A + kap) - etah
    loading = state["loading"][0]
    assert loading.sum() == 27 and loading[10] and 1.5e-12 < gap[10] < 1.7e-12
    for scale in (1e-6, 1e-3, 1.0, 10.0):
        s, st, _ = model.update(d["d_strain"] * scale, d["stress"], state)
        assert st["status"][0] == STATUS_OK and st["continuation"][0] == 0, (scale, st["continuation"])
        assert st["iterations"][0] <= 16, (scale, st["iterations"])  # 41-48 before the active-set phase
    s_ref = update_point(model, d["d_strain"][0], d["stress"][0], state)[0]
    s = model.update(d["d_strain"], d["stress"], state)[0][0]
    assert np.abs(s - s_ref).max() <= 1e-9 * np.abs(s_ref).max()


def test_the_rate_problem_of_a_point_on_the_tension_cut_off_includes_the_cut_off():
    """A point of the isotropic footing (equator-78 rule, E = 60 MPa, resolution 2) at p = 0 on the mean-stress
    cut-off, 28 planes on their hardening curves, under an increment with a volumetric opening. The kernel's
    rate problem takes the cut-off's opening rate as one more unknown: its choice (17 planes and the cut-off
    loading) solves the complementarity problem of the reference algebra with the cut-off, and not the one
    without it (there the planes of that set would need a negative slip rate). So chosen, the update
    converges without a halving for every multiple 1e-8 ... 10 of the increment, its opening the reference's
    rate x_0 times the increment (to 1e-4 for 1e-4 ... 1 of it), and agrees with the reference. (Without the
    cut-off in the rate problem the point failed for its increment: 12 planes took the elastic branch and the
    first Newton step overstressed them. And before q of the rate problem was made free of units, Lemke's
    absolute tolerances chose another set at 1e-5 of the increment than at 1, and the point failed there.)"""
    from material.cpa_reference import _Law, rate_coupling, update_point

    model, d, state = _replay_file("footing_cutoff_point.npz")
    assert abs(np.trace(d["stress"][0])) < 1e-15 and np.trace(d["d_strain"][0]) > 0
    de = np.abs(d["d_strain"][0])
    r_scale = max(de.max(), np.sqrt(2.0) * (de - np.diag(np.diag(de))).max()) + max(
        np.abs(d["stress"][0]).max(), model._law.apex_stress) / model.params.E  # (Mandel components)
    select, found = _kernel_rate_choice(model, d, state, r_scale)
    kap_n = state["kappa"][0]
    M = kap_n.size
    chosen = set(np.flatnonzero(select[:M]).tolist())
    assert found and select[M] and len(chosen) == 17
    ref = _Law(model)
    ef = ref.eta_f(state["strain"][0] + d["d_strain"][0])
    rates = {}
    for cut in (r_scale, None):
        on, Cb, H, _ = rate_coupling(ref, d["stress"][0], ef, kap_n, 0.0, cutoff=cut)
        q = np.einsum("aij,ij->a", Cb, d["d_strain"][0])
        act = [j for j, a in enumerate(on) if a in chosen or a == M]
        x = np.zeros(on.size)
        x[act] = np.linalg.solve(H[np.ix_(act, act)], q[act])
        rates[cut is None] = (on.size, x[act].min(), (q - H @ x).max() / np.abs(q).max(), x[-1])
    size, xmin, wmax, x0 = rates[False]
    assert size == 29 and xmin > 0 and wmax <= 1e-12  # a solution with the cut-off (x0, its opening rate, > 0)
    size, xmin, _, _ = rates[True]
    assert size == 28 and xmin < 0  # not one without it
    for scale in (1e-8, 1e-6, 1e-4, 1e-2, 1.0, 10.0):
        _, st, _ = model.update(d["d_strain"] * scale, d["stress"], state)
        assert st["status"][0] == STATUS_OK and st["continuation"][0] == 0, (scale, st["continuation"])
        assert st["iterations"][0] <= 16, (scale, st["iterations"])  # 35-50 before the active-set phase
        opening = st["cutoff_opening"][0] - state["cutoff_opening"][0]
        if 1e-4 <= scale <= 1.0:  # (below, the increment nears the solver's tolerance: -0.2 % at 1e-6)
            assert abs(opening / (scale * x0) - 1.0) < 1e-4, (scale, opening)
    s, st, _ = model.update(d["d_strain"], d["stress"], state)
    s_ref, _, dl_ref, _ = update_point(model, d["d_strain"][0], d["stress"][0], state)
    assert np.abs(s[0] - s_ref).max() <= 1e-9 * np.abs(s_ref).max()
    assert st["cutoff_opening"][0] - state["cutoff_opening"][0] == pytest.approx(dl_ref, rel=1e-9)


def test_a_point_at_the_apex_with_planes_whose_slip_and_overstress_both_vanish_converges_by_active_set_steps():
    """A point of the isotropic footing (equator-78 rule, E = 60 MPa, resolution 2) at the apex: p = 0 to
    round-off, |sigma| = 0.02 kPa, 55 planes loading in the last step, nearly perfectly plastic (kappa up to
    590 A). Its solution loads 48 planes and opens the cut-off, and some of the planes on their curves end with
    both their slip and their overstress at 0: there Fischer-Burmeister's Newton creeps (each step carries such
    a plane's slip past 0 and the line search cuts it; measured: Phi stalled at 2e-8 after 25 iterations and
    the point failed for 1e-6, 1e-2 ... 10 times its increment, 250-350 local iterations with 13 halvings; the
    reference's Newton needs 37 iterations). The active-set phase (``_cpa_local._active_set_phase``) takes
    full Newton steps on the minimum function after two cut steps in a row: the point converges without a
    halving in at most 9 iterations at every multiple of its increment, and agrees with the reference."""
    from material.cpa_reference import update_point

    model, d, state = _replay_file("footing_apex_point.npz")
    assert abs(np.trace(d["stress"][0])) < 1e-13 and np.abs(d["stress"][0]).max() < 0.03
    assert state["loading"][0].sum() == 55 and state["kappa"][0].max() > 500 * model.params.A
    for scale in (1e-6, 1e-4, 1e-2, 1.0, 10.0):
        _, st, _ = model.update(d["d_strain"] * scale, d["stress"], state)
        assert st["status"][0] == STATUS_OK and st["continuation"][0] == 0, (scale, st["continuation"])
        assert st["iterations"][0] <= 12, (scale, st["iterations"])
    s, st, _ = model.update(d["d_strain"], d["stress"], state)
    assert st["loading"][0].sum() == 48
    s_ref, _, dl_ref, _ = update_point(model, d["d_strain"][0], d["stress"][0], state, maxit=60)
    assert np.abs(s[0] - s_ref).max() <= 1e-9 * np.abs(s_ref).max()
    assert st["cutoff_opening"][0] - state["cutoff_opening"][0] == pytest.approx(dl_ref, rel=1e-9)


def _overstress_of_committed_state(model, stress, state):
    """The share of each loading plane's mobilised ratio above its hardening curve, from the committed
    stress and slips alone (the public ratios and strengths, the hyperbola 2.16): max_a (etah_a - eta_a) / etah_a."""
    p = model.params
    eta_f = model.friction_coefficients(state["strain"])
    etah = model.mobilised_ratios(stress, state["strain"])
    kap = state["kappa"]
    level = p.zeta * eta_f * kap / (p.A + kap)
    return np.where(state["loading"], (etah - level) / etah, 0.0).max(axis=1)


def test_step_stabilisation_reports_its_overstress_and_it_shrinks_with_mu():
    """state["overstress"] is what the floor changes: at the end of every step of a loading path it is the
    largest share of a loading plane's mobilised ratio above the plane's hardening curve, as the committed
    stress and slips give it independently of the kernel; 0 for the thesis's law (where etah = eta(kappa)
    on every loading plane); about proportional to mu; 0 at an elastic (unloading) step."""
    seen = {}
    for mu in (0.0, 0.01, 0.1):
        model = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0), stabilisation=mu)
        sig = -100.0 * np.eye(3)[None]
        st = model.initial_state(1, stress=sig[0])
        assert st["overstress"][0] == 0.0
        over = []
        for _ in range(25):
            sig, st, _ = model.update(DE[None], sig, st, tangent=False)
            assert st["status"][0] == STATUS_OK and st["loading"].any()
            direct = _overstress_of_committed_state(model, sig, st)[0]
            assert abs(st["overstress"][0] - direct) <= 1e-9, (mu, st["overstress"][0], direct)
            over.append(st["overstress"][0])
        seen[mu] = np.array(over)
        sig, st, _ = model.update(-0.05 * DE[None], sig, st, tangent=False)  # unloading: elastic
        assert not st["loading"].any() and st["overstress"][0] == 0.0
    assert np.abs(seen[0.0]).max() <= 1e-10
    assert seen[0.1].max() > 1e-3  # a finite share of the ratio along this path (0.28 % at the first step)
    ratio = seen[0.1] / seen[0.01]
    assert np.all((ratio > 5.0) & (ratio < 12.0)), ratio  # about proportional to mu


def _rotation(theta, axis):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


@pytest.mark.parametrize("beta", [0.0, 5.0])
def test_objectivity_rotating_axes_stress_and_strain_together(beta):
    p = load_preset("ottawa_c109").replace(beta=beta)
    R0 = axes_from_alpha(35.0)
    Q = _rotation(0.7, [0.3, -1.0, 0.5])
    m1 = CPAModel(p, axes=R0)
    m2 = CPAModel(p, axes=Q @ R0)
    sig1 = -100.0 * np.eye(3)[None]
    sig2 = sig1.copy()
    st1 = m1.initial_state(1, stress=sig1[0])
    st2 = m2.initial_state(1, stress=sig2[0])
    de2 = Q @ DE @ Q.T
    for _ in range(15):
        sig1, st1, D1 = m1.update(DE[None], sig1, st1)
        sig2, st2, D2 = m2.update(de2[None], sig2, st2)
    np.testing.assert_allclose(sig2[0], Q @ sig1[0] @ Q.T, atol=1e-10 * np.abs(sig1).max())
    np.testing.assert_allclose(st2["kappa"], st1["kappa"], rtol=1e-9, atol=1e-16)
    D1r = np.einsum("ia,jb,kc,ld,abcd->ijkl", Q, Q, Q, Q, D1[0])
    np.testing.assert_allclose(D2[0], D1r, atol=1e-9 * np.abs(D1).max())


def test_batch_equals_points_one_by_one(rng):
    model = CPAModel("ottawa_c109", axes=axes_from_alpha(60.0))
    n = 7
    sig = np.repeat(-80.0 * np.eye(3)[None], n, axis=0)
    st = model.initial_state(n, stress=sig)
    de = rng.normal(scale=1e-3, size=(n, 3, 3))
    de = 0.5 * (de + de.transpose(0, 2, 1)) - 1e-3 * np.eye(3)
    for _ in range(3):
        new, st_new, D = model.update(de, sig, st)
        for i in (0, 3, 6):
            s_i, _, D_i = model.update(de[i:i + 1], sig[i:i + 1], {k: v[i:i + 1] for k, v in st.items()})
            np.testing.assert_array_equal(s_i[0], new[i])
            np.testing.assert_array_equal(D_i[0], D[i])
        sig, st = new, st_new


def test_update_does_not_modify_its_inputs():
    model = CPAModel("ottawa_c109")
    sig, st = _loaded(model, 3)
    sig0 = sig.copy()
    st0 = {k: v.copy() for k, v in st.items()}
    model.update(DE[None], sig, st)
    np.testing.assert_array_equal(sig, sig0)
    for k in st:
        np.testing.assert_array_equal(st[k], st0[k])


def test_failed_point_returns_start_stress_and_a_replay_file(tmp_path):
    model = CPAModel("ottawa_c109", maxit=1, max_halvings=0, replay_dir=tmp_path)
    sig, st = _loaded(CPAModel("ottawa_c109"), 5)
    new, st1, D = model.update(DE[None], sig, st)
    assert st1["status"][0] == STATUS_FAILED
    assert 0 < st1["step_ratio"][0] < 1
    np.testing.assert_array_equal(new, sig)
    assert np.isfinite(D).all()
    files = list(tmp_path.glob("cpa-failure-*.npz"))
    assert len(files) == 1
    # replay with the default options converges and agrees with a fresh model
    _, stress_r, state_r, _ = replay(files[0], maxit=25, max_halvings=12)
    ref, _, _ = CPAModel("ottawa_c109").update(DE[None], sig, st)
    assert state_r["status"][0] == STATUS_OK
    np.testing.assert_allclose(stress_r, ref, rtol=1e-12)
    # the same failure again within the same second keeps a file of its own
    model.update(DE[None], sig, st)
    model.update(DE[None], sig, st)
    assert len(list(tmp_path.glob("cpa-failure-*.npz"))) == 3


def test_initial_anisotropic_stress_releases_no_slip_burst():
    model = CPAModel("ottawa_c109")
    k0 = np.diag([-50.0, -50.0, -100.0])
    st = model.initial_state(1, stress=k0)
    assert st["kappa"].max() > 0
    tiny = 1e-8 * DE
    new, st1, _ = model.update(tiny[None], k0[None], st)
    assert np.abs(new[0] - k0).max() < 1e-3  # ~ E |tiny|, not a jump
    assert not st1["loading"].any()  # inside the 5 % elastic margin
    with pytest.raises(ValueError, match="failure surface"):
        model.initial_state(1, stress=np.diag([-1.0, -1.0, -100.0]))
    with pytest.raises(ValueError, match="mean tension"):
        model.initial_state(1, stress=np.diag([1.0, 1.0, 1.0]))


def test_large_increments_converge_at_first_order_to_many_small_ones():
    """Backward Euler: a fully strain-driven path (4 % axial) in 10 steps is within 5 % of 1000
    steps, and 100 steps are ~10x closer (first-order convergence of the flow direction)."""
    model = CPAModel("ottawa_c109")
    total = 20 * DE
    ends = {}
    for n in (10, 100, 1000):
        sig = -100.0 * np.eye(3)[None]
        st = model.initial_state(1, stress=sig[0])
        for _ in range(n):
            sig, st, _ = model.update((total / n)[None], sig, st, tangent=False)
        assert st["status"][0] != STATUS_FAILED
        ends[n] = sig[0]
    scale = np.abs(ends[1000]).max()
    e10 = np.abs(ends[10] - ends[1000]).max() / scale
    e100 = np.abs(ends[100] - ends[1000]).max() / scale
    assert e10 < 0.05, e10
    assert 5 < e10 / e100 < 20, (e10, e100)


@pytest.mark.parametrize(
    "bad,match",
    [
        (lambda de, s, st: (de[:, :2], s, st), "shape"),
        (lambda de, s, st: (de + np.triu(np.ones((3, 3)), 1) * 1e-3, s, st), "not symmetric"),
        (lambda de, s, st: (de * np.nan, s, st), "NaN"),
        (lambda de, s, st: (de, np.full_like(s, np.inf), st), "NaN or inf"),
        (lambda de, s, st: (de, s, {k: v for k, v in st.items() if k != "kappa"}), "missing key 'kappa'"),
        (lambda de, s, st: (np.repeat(de, 2, 0), np.repeat(s, 2, 0), st), "leading axis"),
    ],
)
def test_bad_input_is_named(bad, match):
    model = CPAModel("ottawa_c109")
    sig = -100.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0])
    args = bad(DE[None].copy(), sig.copy(), st)
    with pytest.raises(ValueError, match=match):
        model.update(*args)


def test_bad_construction_is_named():
    with pytest.raises(KeyError, match="unknown preset"):
        CPAModel("no_such_sand")
    with pytest.raises(KeyError, match="bazant-oh-33"):
        CPAModel("ottawa_c109", rule="nope")
    with pytest.raises(ValueError, match="left-handed"):
        CPAModel("ottawa_c109", axes=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="maxit"):
        CPAModel("ottawa_c109", maxit=0)
    with pytest.raises(ValueError, match="max_halvings = 31"):
        CPAModel("ottawa_c109", max_halvings=31)
    with pytest.raises(ValueError, match="tol"):
        CPAModel("ottawa_c109", tol=0.1)
    for bad in (-0.1, "maximal", float("nan"), None):
        with pytest.raises(ValueError, match=f"stabilisation = {bad!r}: allowed a number 0 <= mu <= 1 or 'minimal'"):
            CPAModel("ottawa_c109", stabilisation=bad)
    assert CPAModel("ottawa_c109", stabilisation=" Minimal").options.stabilisation == "minimal"
    for bad in (0.0, -0.5, float("nan"), float("inf"), "soon", True):
        with pytest.raises(ValueError, match=f"relaxation_time = {bad!r}: allowed a finite number > 0"):
            CPAModel("ottawa_c109", stabilisation=0.1, relaxation_time=bad)
    with pytest.raises(ValueError, match="relaxation_time = 0.1: the relaxation time of the step stabilisation, but "
                                         "stabilisation = 0"):
        CPAModel("ottawa_c109", relaxation_time=0.1)
    model = CPAModel("ottawa_c109", stabilisation="minimal", relaxation_time=0.05)
    assert model.relaxation_time == 0.05 and model.replace(tol=1e-11).relaxation_time == 0.05
    assert CPAModel("ottawa_c109", stabilisation=0.1).relaxation_time is None


def test_general_coaxial_law_changes_the_response_and_reduces_to_the_linear_one():
    base = load_preset("ottawa_c109_induced").replace(beta=5.0)
    ends = {}
    for key, params in {"linear": base, "same": base.replace(alpha_hat=2.0),
                        "coaxial": base.replace(alpha_hat=0.5, beta_hat=1.0)}.items():
        sig, st = _loaded(CPAModel(params), 15)
        ends[key] = sig[0]
    # alpha_hat only scales the direction, which is normalised: identical to Lambda = beta e
    np.testing.assert_allclose(ends["same"], ends["linear"], rtol=1e-9)
    assert np.abs(ends["coaxial"] - ends["linear"]).max() > 0.1


# ------------------------------------------------------------------ post-peak softening (zeta > 1)
SOFT = dict(zeta=1.05, softening_slip=0.01, residual_ratio=0.65)


def _soft_path(h, n_steps=240, de=DE_SHEAR):
    """Strain-driven shear path of one point of element size h; per step: the most active plane's
    slip and mobilised ratio etah / eta_f."""
    p = load_preset("ottawa_c109").replace(**SOFT)
    model = CPAModel(p)
    sig = -100.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0], element_size=h)
    ef = model.friction_coefficients()
    rows = []
    for _ in range(n_steps):
        sig, st, _ = model.update(de[None], sig, st)
        assert st["status"][0] != STATUS_FAILED
        a = int(np.argmax(st["kappa"][0]))
        rows.append((st["kappa"][0, a], model.mobilised_ratios(sig)[0, a] / ef[a], st["mobilised_ratio"][0]))
    return p, np.array(rows)


def test_softening_past_the_peak_follows_the_law_scaled_by_the_element_size():
    """eta of the most active plane: the hyperbola (2.16) up to kappa* (eta = eta_f), then
    eta_f (r + (1 - r) / (1 + (kappa - kappa*) h / (t s))): the slip read as a jump across a band of
    thickness t smeared over an element of size h (crack band)."""
    for h in (0.006, 0.012):
        p, rows = _soft_path(h)
        kap, ratio, mob = rows.T
        ks = p.kappa_instability
        post = kap > ks * 1.05
        assert post.sum() > 20  # well into the softening branch
        law = p.residual_ratio + (1 - p.residual_ratio) / (1 + (kap[post] - ks) * h / (p.t * p.softening_slip))
        np.testing.assert_allclose(ratio[post], law, rtol=1e-9)
        assert 0.98 <= mob.max() <= 1.0 + 1e-9  # the peak is eta_f: no plane overshoots it
        assert mob[-1] < 0.85  # and it softens towards the residual 0.65
    assert _soft_path(0.012)[1][-1, 1] < _soft_path(0.006)[1][-1, 1]


def test_softening_tangent_matches_finite_differences():
    p = load_preset("ottawa_c109").replace(**SOFT)
    model = CPAModel(p)
    sig = -100.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0])
    for _ in range(150):  # past the peak of the most active plane
        sig, st, _ = model.update(DE_SHEAR[None], sig, st)
    assert st["kappa"][0].max() > 1.2 * p.kappa_instability
    de = DE_SHEAR + np.array([[0, 1e-5, 2e-5], [1e-5, 0, -1e-5], [2e-5, -1e-5, 0]])
    _, st1, D = model.update(de[None], sig, st)
    assert st1["status"][0] == STATUS_OK
    Dfd = _fd_tangent(model, sig, st, de)
    err = np.abs(D[0] - Dfd).max() / np.abs(Dfd).max()
    assert err < 1e-5, err


def test_without_softening_the_mobilised_ratio_keeps_rising_past_eta_f():
    p = load_preset("ottawa_c109").replace(zeta=1.05)
    model = CPAModel(p)
    sig = -100.0 * np.eye(3)[None]
    st = model.initial_state(1, stress=sig[0])
    for _ in range(240):
        sig, st, _ = model.update(DE_SHEAR[None], sig, st)
    assert 1.0 < st["mobilised_ratio"][0] < 1.05


def test_the_mandel_tangent_is_the_tensor_tangent_in_mandel_form():
    from material.tensors import to_mandel_matrix

    model = CPAModel("ottawa_c109", axes=axes_from_alpha(30.0))
    state = model.initial_state(2, stress=-100.0 * np.eye(3))
    d_strain = np.array([np.diag([1e-3, 5e-4, -3e-3]), np.diag([-2e-3, 1e-3, 1e-3])])
    s_t, _, tensor = model.update(d_strain, np.broadcast_to(-100.0 * np.eye(3), (2, 3, 3)), state)
    s_m, _, mandel = model.update(d_strain, np.broadcast_to(-100.0 * np.eye(3), (2, 3, 3)), state, tangent="mandel")
    np.testing.assert_array_equal(s_t, s_m)
    np.testing.assert_allclose(mandel, to_mandel_matrix(tensor), rtol=1e-13, atol=1e-10)
