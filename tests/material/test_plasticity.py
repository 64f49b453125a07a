"""Reference laws VonMises, DruckerPrager and MohrCoulomb: closed forms, consistency, consistent tangent by finite
differences."""

import numpy as np
import pytest

from material.plasticity import DruckerPrager, MohrCoulomb, VonMises, von_mises_stress

E, NU = 20000.0, 0.3
G = E / (2 * (1 + NU))
K = E / (3 * (1 - 2 * NU))


def _sym(a):
    return 0.5 * (a + np.swapaxes(a, -1, -2))


def _fd_tangent(model, d_strain, stress, state, h=1e-8):
    """Central differences of stress_{n+1} w.r.t. d_strain, all points and 6 directions in one batched call."""
    n = d_strain.shape[0]
    pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    pert = np.zeros((6, 3, 3))
    for m, (k, l) in enumerate(pairs):
        pert[m, k, l] += 0.5 * h
        pert[m, l, k] += 0.5 * h
    de = np.concatenate([d_strain[:, None] + pert[None], d_strain[:, None] - pert[None]], axis=1).reshape(-1, 3, 3)
    rep = lambda a: np.repeat(a, 12, axis=0)
    st = {k: rep(v) for k, v in state.items()}
    s, _, _ = model.update(de, rep(stress), st)
    s = s.reshape(n, 2, 6, 3, 3)
    fd = (s[:, 0] - s[:, 1]) / (2 * h)  # (n, 6, 3, 3)
    return fd, pairs


def _check_tangent(model, d_strain, stress, state, tol=1e-6):
    _, _, tan = model.update(d_strain, stress, state)
    fd, pairs = _fd_tangent(model, d_strain, stress, state)
    for m, (k, l) in enumerate(pairs):
        col = tan[:, :, :, k, l]
        scale = np.abs(tan).max(axis=(1, 2, 3, 4))[:, None, None]
        err = np.abs(fd[:, m] - col) / scale
        assert err.max() < tol, (k, l, err.max())
    return tan


def _random_steps(n, scale, seed):
    rng = np.random.default_rng(seed)
    return _sym(rng.normal(size=(n, 3, 3))) * scale


def _mixed_axial(model, stress, state, d_axial, lateral_stress, iters=30):
    """One step of an axial-strain-controlled test with sigma_xx = sigma_yy = lateral_stress (Newton on tangent)."""
    de = np.zeros((1, 3, 3))
    de[0, 2, 2] = d_axial
    for _ in range(iters):
        s, st, tan = model.update(de, stress, state)
        r = np.array([s[0, 0, 0] - lateral_stress, s[0, 1, 1] - lateral_stress])
        if np.abs(r).max() < 1e-9 * max(1.0, abs(lateral_stress)):
            return s, st
        J = np.array([[tan[0, 0, 0, 0, 0], tan[0, 0, 0, 1, 1]], [tan[0, 1, 1, 0, 0], tan[0, 1, 1, 1, 1]]])
        dx = np.linalg.solve(J, -r)
        de[0, 0, 0] += dx[0]
        de[0, 1, 1] += dx[1]
    raise AssertionError("mixed control did not converge")


def _plane_strain_limit(model, p0, steps=200):
    """The stress (3, 3) after ``steps`` of 2e-4 axial compression along z in plane strain (y out of plane at zero
    strain) with x held at the stress -p0 (Newton on eps_xx)."""
    st = model.initial_state(1)
    s = -p0 * np.eye(3)[None]
    for _ in range(steps):
        de = np.zeros((1, 3, 3))
        de[0, 2, 2] = -2e-4
        for _ in range(30):
            s1, st1, tan = model.update(de, s, st)
            r = s1[0, 0, 0] + p0
            if abs(r) < 1e-9 * p0:
                break
            de[0, 0, 0] -= r / tan[0, 0, 0, 0, 0]
        s, st = s1, st1
    return s[0].copy()


# ----------------------------------------------------------------------------- von Mises
def test_von_mises_elastic_step_is_hooke():
    m = VonMises(E, NU, 100.0)
    st = m.initial_state(2)
    de = _random_steps(2, 1e-5, 0)
    s, st2, tan = m.update(de, np.zeros((2, 3, 3)), st)
    assert np.allclose(tan, m.stiffness)
    assert np.allclose(s, np.einsum("ijkl,nkl->nij", m.stiffness, de))
    assert np.all(st2["eq_plastic_strain"] == 0) and np.all(st["strain"] == 0)  # input state untouched
    assert set(st2) >= {"strain", "status", "step_ratio", "plastic_strain", "eq_plastic_strain"}


@pytest.mark.parametrize("H", [0.0, 1500.0])
def test_von_mises_simple_shear_closed_form(H):
    """tau(gamma) = (sigma_y/sqrt3 + H gamma/3) / (1 + H/(3G)) after yield, gamma = 2 eps_12."""
    sy = 100.0
    m = VonMises(E, NU, sy, hardening_kPa=H)
    st = m.initial_state(1)
    s = np.zeros((1, 3, 3))
    gammas = np.linspace(0, 0.02, 41)[1:]
    dg = gammas[0]
    de = np.zeros((1, 3, 3))
    de[0, 0, 1] = de[0, 1, 0] = dg / 2
    taus = []
    for _ in gammas:
        s, st, _ = m.update(de, s, st)
        taus.append(s[0, 0, 1])
    exact = np.where(G * gammas < sy / np.sqrt(3), G * gammas, (sy / np.sqrt(3) + H * gammas / 3) / (1 + H / (3 * G)))
    assert np.allclose(taus, exact, rtol=1e-10, atol=1e-9)
    assert abs(np.trace(s[0])) < 1e-9  # J2 flow is isochoric: no pressure in simple shear


@pytest.mark.parametrize("H", [0.0, 2000.0])
def test_von_mises_uniaxial_stress_closed_form(H):
    """sigma = (sigma_y + H eps) / (1 + H/E) after yield; eps_lat = -nu sigma/E - eps_p/2."""
    sy = 120.0
    m = VonMises(E, NU, sy, hardening_kPa=H)
    st = m.initial_state(1)
    s = np.zeros((1, 3, 3))
    d = -1e-3 / 4  # compression
    for _ in range(60):  # to eps = 1.5e-2 > sigma_y / E = 6e-3
        s, st = _mixed_axial(m, s, st, d, 0.0)
    eps = st["strain"][0, 2, 2]
    sig_exact = -(sy + H * abs(eps)) / (1 + H / E)
    assert s[0, 2, 2] == pytest.approx(sig_exact, rel=1e-9)
    eps_p = abs(eps) - abs(sig_exact) / E
    assert st["eq_plastic_strain"][0] == pytest.approx(eps_p, rel=1e-8)
    assert st["strain"][0, 0, 0] == pytest.approx(nu_lat := NU * abs(sig_exact) / E + eps_p / 2, rel=1e-8)
    assert nu_lat > 0


@pytest.mark.parametrize("H", [0.0, 3000.0])
def test_von_mises_on_yield_surface_after_return(H):
    m = VonMises(E, NU, 100.0, hardening_kPa=H)
    n = 50
    st = m.initial_state(n)
    de = _random_steps(n, 4e-3, 1)
    s, st2, _ = m.update(de, np.zeros((n, 3, 3)), st)
    f = m.yield_function(s, st2["eq_plastic_strain"])
    plastic = st2["eq_plastic_strain"] > 0
    assert plastic.sum() > 40
    assert np.abs(f[plastic]).max() < 1e-9 * 100
    assert np.all(f[~plastic] <= 1e-9)
    # plastic strain is deviatoric and eq. plastic strain = sqrt(2/3 eps_p:eps_p) for a single step
    ep = st2["plastic_strain"]
    assert np.abs(np.trace(ep, axis1=1, axis2=2)).max() < 1e-15
    assert np.allclose(np.sqrt(2 / 3 * np.einsum("nij,nij->n", ep, ep)), st2["eq_plastic_strain"])


@pytest.mark.parametrize("H", [0.0, 3000.0])
def test_von_mises_consistent_tangent_fd(H):
    m = VonMises(E, NU, 100.0, hardening_kPa=H)
    n = 6
    # start from a prestressed, hardened state, then a plastic step
    st = m.initial_state(n)
    first = _random_steps(n, 1e-2, 2)
    s0, st, _ = m.update(first, np.zeros((n, 3, 3)), st)
    assert np.all(st["eq_plastic_strain"] > 0)
    de = 0.5 * first + _random_steps(n, 2e-3, 3)  # keep loading, direction changes
    _, st_chk, _ = m.update(de, s0, st)
    assert np.all(st_chk["eq_plastic_strain"] > st["eq_plastic_strain"])
    tan = _check_tangent(m, de, s0, st)
    # associated flow: major symmetry
    assert np.allclose(tan, np.transpose(tan, (0, 3, 4, 1, 2)), atol=1e-8 * np.abs(tan).max())


def test_von_mises_vectorised_matches_pointwise():
    m = VonMises(E, NU, 80.0, hardening_kPa=500.0)
    n = 7
    de = _random_steps(n, 2e-3, 5)
    s0 = _random_steps(n, 20.0, 6)
    st = m.initial_state(n)
    s, st2, tan = m.update(de, s0, st)
    for i in range(n):
        si, sti, ti = m.update(de[i : i + 1], s0[i : i + 1], m.initial_state(1))
        assert np.allclose(si[0], s[i]) and np.allclose(ti[0], tan[i])


def test_von_mises_bad_input():
    with pytest.raises(ValueError, match="yield_stress_kPa"):
        VonMises(E, NU, -1.0)
    with pytest.raises(ValueError, match="hardening_kPa = .*must be > -3 G"):
        VonMises(E, NU, 10.0, hardening_kPa=-2.0 * E / (1 + NU))
    with pytest.raises(ValueError, match="nu"):
        VonMises(E, 0.5, 10.0)
    m = VonMises(E, NU, 10.0)
    with pytest.raises(ValueError, match="d_strain"):
        m.update(np.zeros((2, 3)), np.zeros((2, 3)), m.initial_state(2))
    with pytest.raises(ValueError, match="eq_plastic_strain"):
        m.update(np.zeros((1, 3, 3)), np.zeros((1, 3, 3)), {"strain": np.zeros((1, 3, 3)), "plastic_strain": np.zeros((1, 3, 3))})


def test_von_mises_stress_invariant():
    s = np.diag([-100.0, -100.0, -250.0])
    assert von_mises_stress(s) == pytest.approx(150.0)


# ----------------------------------------------------------------------------- Drucker-Prager
def test_drucker_prager_triaxial_strength_compression_match():
    """Outer cone: drained triaxial compression peaks at q_f = 2 (c cos phi + p0 sin phi) / (1 - sin phi)."""
    c, phi, p0 = 5.0, 30.0, 100.0
    m = DruckerPrager(E, NU, c, phi, match="compression")
    st = m.initial_state(1)
    s = -p0 * np.eye(3)[None]
    for _ in range(60):
        s, st = _mixed_axial(m, s, st, -2e-4, -p0)
    q = s[0, 0, 0] - s[0, 2, 2]
    sphi = np.sin(np.deg2rad(phi))
    q_exact = 2 * (c * np.cos(np.deg2rad(phi)) + p0 * sphi) / (1 - sphi)
    assert q == pytest.approx(q_exact, rel=1e-9)
    assert st["eq_plastic_strain"][0] > 0


def test_drucker_prager_plane_strain_limit_is_mohr_coulomb():
    """Plane-strain match + associated flow: the steady plane-strain limit state satisfies Mohr-Coulomb."""
    c, phi, p0 = 10.0, 25.0, 50.0
    s = _plane_strain_limit(DruckerPrager(E, NU, c, phi, match="plane_strain"), p0)[None]
    sig1, sig3 = -s[0, 2, 2], -s[0, 0, 0]  # compression positive, major and minor
    phir = np.deg2rad(phi)
    mc = (sig1 - sig3) / 2 - ((sig1 + sig3) / 2 * np.sin(phir) + c * np.cos(phir))
    assert abs(mc) < 1e-6 * sig1
    assert -s[0, 1, 1] > sig3 and -s[0, 1, 1] < sig1  # intermediate stress between the two


@pytest.mark.parametrize("psi", [None, 10.0, 0.0])
@pytest.mark.parametrize("H", [0.0, 800.0])
def test_drucker_prager_consistent_tangent_fd_cone(psi, H):
    m = DruckerPrager(E, NU, 20.0, 32.0, dilation_deg=psi, hardening_kPa=H)
    n = 6
    s0 = -100.0 * np.eye(3) + _random_steps(n, 10.0, 7)
    st = m.initial_state(n)
    de = _random_steps(n, 2e-2, 8)
    de -= np.trace(de, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)  # deviatoric: stays off the apex
    s1, st1, _ = m.update(de, s0, st)
    # all points on the smooth cone
    assert np.all(st1["eq_plastic_strain"] > 0)
    assert np.all(np.linalg.norm(s1 - np.trace(s1, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3), axis=(1, 2)) > 1e-6)
    assert np.abs(m.yield_function(s1, st1["eq_plastic_strain"])).max() < 1e-9
    tan = _check_tangent(m, de, s0, st)
    sym = np.allclose(tan, np.transpose(tan, (0, 3, 4, 1, 2)), atol=1e-8 * np.abs(tan).max())
    assert sym == (psi is None)  # major symmetry only for associated flow


def test_drucker_prager_apex_return():
    """Strong volumetric extension: the stress returns to the apex p = xi c / eta (hydrostatic)."""
    c, phi = 10.0, 30.0
    for H, psi in ((0.0, 20.0), (500.0, 20.0), (0.0, 0.0), (500.0, 0.0)):
        m = DruckerPrager(E, NU, c, phi, dilation_deg=psi, hardening_kPa=H)
        n = 3
        de = np.eye(3)[None] * 1e-2 + _random_steps(n, 1e-4, 9)
        s, st, tan = m.update(de, np.zeros((n, 3, 3)), m.initial_state(n))
        dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
        assert np.abs(dev).max() < 1e-9
        c_new = c + H * st["eq_plastic_strain"]
        assert np.allclose(np.trace(s, axis1=1, axis2=2) / 3, m.xi * c_new / m.eta, rtol=1e-12)
        assert np.abs(m.yield_function(s, st["eq_plastic_strain"])).max() < 1e-9
        assert np.all(np.isfinite(st["eq_plastic_strain"]))
        if H == 0.0 or psi == 0.0:
            assert np.abs(tan).max() == 0.0
        else:
            _check_tangent(m, de, np.zeros((n, 3, 3)), m.initial_state(n))
        # plastic strain = total - elastic
        eps_e = (1 + NU) / E * s - NU / E * np.trace(s, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        assert np.allclose(st["plastic_strain"], de - eps_e, atol=1e-14)


def test_drucker_prager_dilatancy_ratio():
    """Cone return: d eps_v_p = eta_bar dgamma, d eps_bar_p = xi dgamma."""
    m = DruckerPrager(E, NU, 0.0, 35.0, dilation_deg=5.0)
    n = 4
    s0 = -80.0 * np.eye(3)[None].repeat(n, axis=0)
    de = _random_steps(n, 3e-3, 11)
    s, st, _ = m.update(de, s0, m.initial_state(n))
    ev = np.trace(st["plastic_strain"], axis1=1, axis2=2)
    plastic = st["eq_plastic_strain"] > 0
    assert plastic.any()
    assert np.allclose(ev[plastic], m.eta_bar / m.xi * st["eq_plastic_strain"][plastic])


@pytest.mark.parametrize("law", [DruckerPrager, MohrCoulomb])
@pytest.mark.parametrize("args, kwargs, key", [
    ((1.0, 95.0), {}, "friction_deg"), ((1.0, 90.0), {}, "friction_deg"),
    ((1.0, 30.0), {"dilation_deg": 40.0}, "dilation_deg"), ((1.0, 30.0), {"dilation_deg": 35.0}, "dilation_deg"),
    ((-1.0, 30.0), {}, "cohesion_kPa"), ((0.0, 0.0), {}, "no strength")])
def test_frictional_laws_bad_input(law, args, kwargs, key):
    """The checks Drucker-Prager and Mohr-Coulomb share (material.plasticity._frictional): the message names
    the key."""
    with pytest.raises(ValueError, match=key):
        law(E, NU, *args, **kwargs)


def test_drucker_prager_bad_input():
    with pytest.raises(ValueError, match="match"):
        DruckerPrager(E, NU, 1.0, 30.0, match="outer")


def test_von_mises_softening_is_linear_then_floored_at_zero_with_a_consistent_tangent():
    """H < 0: uniaxial (plane-strain-free) shear softens q = sigma_y + H eps_bar_p down to 0, then stays there;
    the tangent is the derivative of the update on the softening branch."""
    G = E / (2 * (1 + NU))
    law = VonMises(E, NU, 10.0, hardening_kPa=-0.1 * G)
    st, sig = law.initial_state(1), np.zeros((1, 3, 3))
    gam = np.zeros((1, 3, 3))
    gam[0, 0, 1] = gam[0, 1, 0] = 4e-5  # simple shear increments
    qs, eps = [], []
    for _ in range(1000):
        sig, st, D = law.update(gam, sig, st)
        qs.append(float(np.sqrt(1.5) * np.linalg.norm(sig[0] - np.trace(sig[0]) / 3 * np.eye(3))))
        eps.append(float(st["eq_plastic_strain"][0]))
    qs, eps = np.array(qs), np.array(eps)
    soft = (eps > 0) & (eps < 10.0 / (0.1 * G) * 0.9)
    assert np.allclose(qs[soft], 10.0 - 0.1 * G * eps[soft], rtol=1e-10, atol=1e-9)
    assert qs[-1] == pytest.approx(0.0, abs=1e-9) and eps[-1] > 10.0 / (0.1 * G)  # spent: zero strength
    # tangent on the softening branch against central differences
    st2, sig2 = law.initial_state(1), np.zeros((1, 3, 3))
    for _ in range(60):
        sig2, st2, _ = law.update(gam, sig2, st2)
    de = gam + np.array([[[1e-6, 0, 0], [0, -2e-6, 0], [0, 0, 0.5e-6]]])
    s0, _, D = law.update(de, sig2, st2)
    h = 1e-10
    for k, l in ((0, 0), (0, 1), (2, 2)):
        e = np.zeros((1, 3, 3))
        e[0, k, l] = e[0, l, k] = h
        fd = (law.update(de + e, sig2, st2)[0] - law.update(de - e, sig2, st2)[0]) / (2 * h)
        np.testing.assert_allclose(np.einsum("nijkl,nkl->nij", D, e) / h, fd, rtol=1e-6, atol=1e-3)


# ----------------------------------------------------------------------------- Mohr-Coulomb
def _mc_branches(model, stress):
    """Which return each point took, from its principal stresses: 'apex', 'edge' (two equal, not the apex) or
    'plane' (all distinct), and the principal stresses (descending)."""
    sig = np.linalg.eigvalsh(stress)[:, ::-1]
    scale = np.abs(sig).max(axis=1) + 1.0
    apex = np.abs(sig - model.apex_stress).max(axis=1) <= 1e-9 * scale
    edge = ~apex & ((sig[:, 0] - sig[:, 1] <= 1e-9 * scale) | (sig[:, 1] - sig[:, 2] <= 1e-9 * scale))
    return np.where(apex, "apex", np.where(edge, "edge", "plane")), sig


@pytest.mark.parametrize("extension", [False, True])
def test_mohr_coulomb_triaxial_strengths_are_the_closed_forms(extension):
    """Drained triaxial compression ends on the edge sigma_1 = sigma_2, extension on sigma_2 = sigma_3, at
    q_f = 2 (c cos phi + p0 sin phi) / (1 -+ sin phi): the two meridians that Drucker-Prager matches one at a time."""
    c, phi, p0 = 5.0, 30.0, 100.0
    m = MohrCoulomb(E, NU, c, phi)
    st = m.initial_state(1)
    s = -p0 * np.eye(3)[None]
    for _ in range(60):  # axisymmetric: on an edge the split of the lateral strains between x and y is free
        de = np.diag([0.0, 0.0, 2e-4 if extension else -2e-4])[None]
        for _ in range(30):
            s1, st1, tan = m.update(de, s, st)
            r = 0.5 * (s1[0, 0, 0] + s1[0, 1, 1]) + p0
            if abs(r) < 1e-10 * p0:
                break
            slope = 0.5 * (tan[0, 0, 0, 0, 0] + tan[0, 0, 0, 1, 1] + tan[0, 1, 1, 0, 0] + tan[0, 1, 1, 1, 1])
            de = de - r / slope * np.diag([1.0, 1.0, 0.0])[None]
        s, st = s1, st1
    q = abs(s[0, 0, 0] - s[0, 2, 2])
    sphi = np.sin(np.deg2rad(phi))
    q_exact = 2 * (c * np.cos(np.deg2rad(phi)) + p0 * sphi) / ((1 + sphi) if extension else (1 - sphi))
    assert q == pytest.approx(q_exact, rel=1e-9)
    assert _mc_branches(m, s)[0][0] == "edge"
    assert st["eq_plastic_strain"][0] > 0
    if not extension:  # the outer Drucker-Prager cone goes through the same compression strength
        dp = DruckerPrager(E, NU, c, phi, match="compression")
        assert dp.yield_function(s, np.zeros(1))[0] == pytest.approx(0.0, abs=1e-8 * p0)


def test_mohr_coulomb_plane_strain_limit_is_the_plane_strain_drucker_prager_limit():
    """Plane strain with associated flow: Mohr-Coulomb and the plane-strain-matched cone reach the same limit
    state (the match is built for it), with the out-of-plane stress strictly between the other two."""
    c, phi, p0 = 10.0, 25.0, 50.0
    mc, dp = (_plane_strain_limit(m, p0) for m in (MohrCoulomb(E, NU, c, phi),
                                                   DruckerPrager(E, NU, c, phi, match="plane_strain")))
    assert mc[2, 2] == pytest.approx(dp[2, 2], rel=1e-6)  # the major stress at the limit
    assert -mc[0, 0] < -mc[1, 1] < -mc[2, 2]
    assert _mc_branches(MohrCoulomb(E, NU, c, phi), mc[None])[0][0] == "plane"


@pytest.mark.parametrize("c, psi", [(0.0, None), (10.0, None), (10.0, 10.0), (0.0, 0.0)])
def test_mohr_coulomb_returns_onto_its_planes_edges_and_apex_with_the_consistent_tangent(c, psi):
    """Random strain steps from a confined state reach every branch of the return; each ends on the surface
    (and no stress beyond the apex), the plastic strain is the total minus the elastic one, and the tangent is
    the central difference of the update on every branch (non-symmetric only for non-associated flow)."""
    m = MohrCoulomb(E, NU, c, 30.0, dilation_deg=psi)
    n = 400
    s0 = -60.0 * np.eye(3) + _random_steps(n, 8.0, 21)
    de = _random_steps(n, 4e-3, 22) + np.eye(3) * np.random.default_rng(23).uniform(-2e-3, 3e-3, n)[:, None, None]
    st = m.initial_state(n)
    s1, st1, tan = m.update(de, s0, st)
    kind, sig = _mc_branches(m, s1)
    plastic = st1["eq_plastic_strain"] > 0
    for branch in ("plane", "edge", "apex"):
        assert np.count_nonzero(plastic & (kind == branch)) >= 5, branch
    scale = np.abs(sig).max(axis=1) + c + 1.0
    f = m.yield_function(s1)
    assert np.all(f <= 1e-10 * scale)
    assert np.all(np.abs(f[plastic]) <= 1e-10 * scale[plastic])
    assert np.all(sig.mean(axis=1) <= m.apex_stress + 1e-10 * scale)
    eps_e = (1 + NU) / E * (s1 - s0) - NU / E * np.trace(s1 - s0, axis1=1, axis2=2)[:, None, None] * np.eye(3)
    assert np.allclose(st1["plastic_strain"], de - eps_e, atol=1e-13)
    not_apex = kind != "apex"
    _check_tangent(m, de[not_apex], s0[not_apex], {k: v[not_apex] for k, v in st.items()})
    assert np.abs(tan[kind == "apex"]).max() == 0.0  # perfectly plastic apex: no stiffness left
    on_plane = plastic & (kind == "plane")
    sym = np.allclose(tan[on_plane], np.transpose(tan[on_plane], (0, 3, 4, 1, 2)), atol=1e-8 * np.abs(tan).max())
    assert sym == (psi is None)


def test_mohr_coulomb_bad_input():
    with pytest.raises(ValueError, match="nu"):
        MohrCoulomb(E, 0.5, 1.0, 30.0)
