"""The CPA law with a gradient back stress X = H_g (eps_p - ebar_p) (CPAModel(back_stress_modulus=...)):
the local law is the law, the step is the law's in shifted variables, and its coupled tangent is exact."""

import dataclasses

import numpy as np
import pytest

from material import CPAModel, load_preset
from material import _cpa_kernel as _k
from material.anisotropy import axes_from_alpha
from material.base import BackStressTangent

H_G = 1.0e4  # kPa, the modulus the localisation diagnostic measured (docs/regularisation.md, section 4)
SOFT = dict(zeta=1.05, softening_slip=0.01, residual_ratio=0.65)  # a softening sand (test_cpa.py)
_BASE = np.array([[0.8e-3, 1e-4, 2e-4], [1e-4, 0.6e-3, -1.5e-4], [2e-4, -1.5e-4, -2e-3]])


def _hardening(stabilisation=0.0, n=4, softening=False, steps=6):
    """The law and the same law with the back stress, both driven locally along a triaxial-like path from
    100 kPa to hardening states (or with ``softening``, past the peak); returns (law, with back stress,
    stresses and states of each, the step)."""
    params = load_preset("ottawa_c109")
    if softening:
        params = dataclasses.replace(params, **SOFT)
    law = CPAModel(params, axes=axes_from_alpha(30.0), stabilisation=stabilisation)
    bs = law.replace(back_stress_modulus=H_G, back_stress_length=0.006)
    sig = np.repeat(-100.0 * np.eye(3)[None], n, axis=0)
    de = _BASE[None] * np.linspace(0.5, 2.0, n)[:, None, None]
    s_law, st_law = sig.copy(), law.initial_state(n, stress=sig)
    s_bs, st_bs = sig.copy(), bs.initial_state(n, stress=sig)
    for _ in range(steps):
        s_law, st_law, t_law = law.update(de, s_law, st_law)
        s_bs, st_bs, t_bs = bs.update(de, s_bs, st_bs)
    return law, bs, (s_law, st_law, t_law), (s_bs, st_bs, t_bs), de


def test_without_the_nonlocal_input_the_law_with_a_back_stress_is_the_law():
    """ebar_p follows eps_p, X = 0: stress, slips and tangent equal to the bit; the state records ebar_p."""
    _, _, (s_law, st_law, t_law), (s_bs, st_bs, t_bs), _ = _hardening()
    assert np.array_equal(s_bs, s_law) and np.array_equal(t_bs, t_law)
    assert np.array_equal(st_bs["kappa"], st_law["kappa"])
    assert np.array_equal(st_bs["nonlocal_plastic_strain"], st_law["plastic_strain"])
    assert not np.any(st_bs["back_stress"])
    assert np.abs(st_law["plastic_strain"]).max() > 1e-3  # (the path is plastic)


def test_the_step_keeps_hooke_and_the_back_stress_is_h_times_the_plastic_strain_ahead_of_its_field():
    law, bs, _, (sig, st, _), de = _hardening()
    rng = np.random.default_rng(3)
    d_bar = rng.normal(size=(4, 3, 3)) * 2e-4
    d_bar = 0.5 * (d_bar + d_bar.transpose(0, 2, 1))
    new, st1, tan = bs.update(0.3 * de, sig, st, d_nonlocal_plastic_strain=d_bar)
    assert isinstance(tan, BackStressTangent)
    d_eps_p = st1["plastic_strain"] - st["plastic_strain"]
    hooke = np.einsum("ij,nj->ni", law._stiff, _k.to_mandel(0.3 * de - d_eps_p))
    assert np.abs(_k.to_mandel(new - sig) - hooke).max() < 1e-10 * np.abs(new).max()
    ebar = st["nonlocal_plastic_strain"] + d_bar
    assert np.allclose(st1["nonlocal_plastic_strain"], ebar, rtol=0, atol=1e-15)
    assert np.allclose(st1["back_stress"], H_G * (st1["plastic_strain"] - ebar), rtol=0, atol=1e-9)
    assert np.allclose(tan.local, st1["plastic_strain"], rtol=0, atol=0)
    assert np.abs(st1["back_stress"]).max() > 1.0  # kPa: the field's increment is felt
    assert np.abs(d_eps_p).max() > 1e-4  # (the step is plastic)


@pytest.mark.parametrize("stabilisation", [0.0, 0.1])
def test_with_the_field_on_the_plastic_strain_the_step_is_the_law_s(stabilisation):
    """ebar_p's increment equal to the law's plastic strain increment: X = 0 at the end, and the step gives
    the law's stress and slips (measured 4e-11 kPa, also with the step stabilisation, whose floor the
    back stress's variables keep)."""
    law, bs, (s_law, st_law, _), (s_bs, st_bs, _), de = _hardening(stabilisation)
    s1, st1, _ = law.update(0.3 * de, s_law, st_law)
    s2, st2, _ = bs.update(0.3 * de, s_bs, st_bs,
                           d_nonlocal_plastic_strain=st1["plastic_strain"] - st_law["plastic_strain"])
    assert np.abs(s2 - s1).max() < 1e-9 * np.abs(s1).max()
    assert np.abs(st2["kappa"] - st1["kappa"]).max() < 1e-10 * st1["kappa"].max()
    assert np.abs(st2["back_stress"]).max() < 1e-8


def test_the_tangent_at_a_fixed_field_is_the_back_stress_loading_tangent_of_the_localisation_diagnostic():
    """Two independent derivations: the kernel in shifted variables (update) and the rate problem with the
    back stress's coupling (loading_tangent, strengthening="back_stress"), which differs from the law's by
    a quarter."""
    law, bs, _, (sig, st, _), de = _hardening()
    _, _, tan = bs.update(1e-5 * de, sig, st, d_nonlocal_plastic_strain=np.zeros_like(de))
    diag = law.loading_tangent(sig, st, strengthening="back_stress", modulus=H_G)
    plain = law.loading_tangent(sig, st)
    size = np.abs(diag).max()
    assert np.abs(tan.dstress_dstrain - diag).max() < 1e-5 * size  # (measured 3.3e-7: the step's curvature)
    assert np.abs(plain - diag).max() > 0.1 * size  # (measured 0.25)


def _central_differences(bs, sig, st, d_eps, d_bar, which, h=1e-8):
    """Columns (0, 0), (1, 2), (2, 2) of d sigma and d eps_p over the increment of strain (which = 0) or of
    ebar_p (1), by central differences; and the tangent's prediction of them."""
    _, _, tan = bs.update(d_eps, sig, st, d_nonlocal_plastic_strain=d_bar)
    t_sig = (tan.dstress_dstrain, tan.dstress_dnonlocal)[which]
    t_eps = (tan.dlocal_dstrain, tan.dlocal_dnonlocal)[which]
    errors = []
    for i, j in ((0, 0), (1, 2), (2, 2)):
        E = np.zeros((3, 3))
        E[i, j] += 0.5 * h
        E[j, i] += 0.5 * h
        out = []
        for sign in (1.0, -1.0):
            args = (d_eps + sign * E, d_bar) if which == 0 else (d_eps, d_bar + sign * E)
            s, st1, _ = bs.update(args[0], sig, st, d_nonlocal_plastic_strain=args[1], tangent=False)
            out.append((s, st1["plastic_strain"]))
        fd_sig = (out[0][0] - out[1][0]) / (2 * h)
        fd_eps = (out[0][1] - out[1][1]) / (2 * h)
        errors.append(max(np.abs(fd_sig - np.einsum("nijkl,kl->nij", t_sig, E / h)).max() / np.abs(t_sig).max(),
                          np.abs(fd_eps - np.einsum("nijkl,kl->nij", t_eps, E / h)).max() / np.abs(t_eps).max()))
    return max(errors)


@pytest.mark.parametrize("stabilisation, softening", [(0.0, False), (0.1, False), (0.0, True), (0.1, True)])
def test_the_coupled_tangent_against_central_differences(stabilisation, softening):
    """All four derivatives at hardening points, or past the peak (measured: 3e-10 to 7e-10 of their size,
    1e-9 to 5e-9 past the peak, with the step stabilisation as without it)."""
    law, bs, _, (sig, st, _), de = _hardening(stabilisation, softening=softening, steps=60 if softening else 6)
    if softening:  # (three of the four points have a plane past its peak)
        assert (st["kappa"] >= law.params.kappa_instability).any(axis=1).sum() == 3
    rng = np.random.default_rng(1)
    d_bar = rng.normal(size=(4, 3, 3)) * 2e-4
    d_bar = 0.5 * (d_bar + d_bar.transpose(0, 2, 1))
    assert _central_differences(bs, sig, st, 0.3 * de, d_bar, 0) < 1e-7
    assert _central_differences(bs, sig, st, 0.3 * de, d_bar, 1) < 1e-7


def test_bad_input_names_the_key_the_value_and_what_is_allowed():
    with pytest.raises(ValueError, match=r"back_stress_modulus = -1.0: allowed a finite number >= 0"):
        CPAModel(back_stress_modulus=-1.0, back_stress_length=0.01)
    with pytest.raises(ValueError, match=r"back_stress_length = None: allowed a finite number > 0"):
        CPAModel(back_stress_modulus=1e4)
    with pytest.raises(ValueError, match=r"back_stress_length = 0.01: needs back_stress_modulus > 0"):
        CPAModel(back_stress_length=0.01)
    with pytest.raises(ValueError, match=r"allowed one of the two regularisations"):
        CPAModel(dataclasses.replace(load_preset("ottawa_c109"), **SOFT), back_stress_modulus=1e4,
                 back_stress_length=0.01, nonlocal_length=0.006)
    induced = dataclasses.replace(load_preset("ottawa_c109"), beta=0.3)
    with pytest.raises(ValueError,
                       match=r"induced anisotropy \(beta = 0.3\): not supported yet; allowed with beta = 0"):
        CPAModel(induced, back_stress_modulus=1e4, back_stress_length=0.01)
    law = CPAModel()
    sig = np.repeat(-100.0 * np.eye(3)[None], 2, axis=0)
    st = law.initial_state(2, stress=sig)
    with pytest.raises(ValueError, match=r"d_nonlocal_plastic_strain: this CPA law has no back stress"):
        law.update(np.zeros((2, 3, 3)), sig, st, d_nonlocal_plastic_strain=np.zeros((2, 3, 3)))
    bs = law.replace(back_stress_modulus=1e4, back_stress_length=0.01)
    st = bs.initial_state(2, stress=sig)
    with pytest.raises(ValueError, match=r"expected a finite array of shape \(2, 3, 3\), got shape \(2,\)"):
        bs.update(np.zeros((2, 3, 3)), sig, st, d_nonlocal_plastic_strain=np.zeros(2))
    bad = np.zeros((2, 3, 3))
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"with non-finite values"):
        bs.update(np.zeros((2, 3, 3)), sig, st, d_nonlocal_plastic_strain=bad)
    bad[0, 0, 0], bad[0, 0, 1] = 0.0, 1e-3
    with pytest.raises(ValueError, match=r"not symmetric"):
        bs.update(np.zeros((2, 3, 3)), sig, st, d_nonlocal_plastic_strain=bad)
    with pytest.raises(ValueError, match=r"tangent = 'mandel'"):
        bs.update(np.zeros((2, 3, 3)), sig, st, d_nonlocal_plastic_strain=np.zeros((2, 3, 3)), tangent="mandel")
