"""The CPA law with the implicit-gradient regularisation of its softening (docs/regularisation.md, section 3):
the kernel's coupled update against the plain-numpy reference, the homogeneous limit, bad input."""

import numpy as np
import pytest

from material import CPAModel, load_preset
from material.anisotropy import axes_from_alpha
from material.base import CoupledTangent
from material.cpa import replay
from material.cpa_reference import update_point

SOFT = dict(E=60000.0, zeta=1.05, softening_slip=0.03, residual_ratio=0.65)


def _past_peak(model, planes=2, alpha_deg=30.0):
    """A drained triaxial compression at p0 = 100 kPa (the lateral strain found by Newton) until ``planes``
    planes are past their peak; returns (stress, state, the step's strain increment)."""
    p = model.params
    sig = -100.0 * np.eye(3)[None]
    state = model.initial_state(1, stress=sig)
    de = np.zeros((1, 3, 3))
    de[0, 2, 2] = -8e-4
    for _ in range(400):
        x = 0.0
        for _ in range(20):
            de[0, 0, 0] = de[0, 1, 1] = x
            new, new_state, D = model.update(de, sig, state)
            r = new[0, 0, 0] + 100.0
            if abs(r) < 1e-9:
                break
            x -= r / (D[0, 0, 0, 0, 0] + D[0, 0, 0, 1, 1])
        if (state["kappa"][0] >= p.kappa_instability).sum() >= planes:
            return sig, state, de
        sig, state = new, new_state
    raise AssertionError("the path did not reach the softening")


@pytest.mark.parametrize("preset, stabilisation", [("ottawa_c109", 0.0), ("ottawa_c109", 0.1),
                                                   ("ottawa_c109_induced", 0.0)])
def test_coupled_update_matches_the_reference(preset, stabilisation):
    """Stress, slips, tangent and the four coupled derivatives of the numba kernel against
    material.cpa_reference (3x3 algebra, complex-step Jacobians), for nonlocal increments that put the
    shifted slip of the planes past their peak on both sides of the peak (induced anisotropy included)."""
    p = load_preset(preset).replace(**SOFT)
    model = CPAModel(p, axes=axes_from_alpha(30.0), stabilisation=stabilisation, nonlocal_length=0.004)
    sig, state, de = _past_peak(model)
    e_n = state["nonlocal"][0]
    loaded = 0
    for dn in (0.0, -0.5 * e_n, 0.02, -e_n):
        s_k, st_k, T = model.update(de, sig, state, d_nonlocal=np.array([dn]))
        s_r, k_r, _, R = update_point(model, de, sig, state, d_nonlocal=np.array([dn]))
        assert st_k["status"][0] == 0 and isinstance(T, CoupledTangent)
        scale = np.abs(s_r).max()
        assert np.abs(s_k[0] - s_r).max() <= 1e-10 * scale
        assert np.abs(st_k["kappa"][0] - k_r).max() <= 1e-10 * max(p.A, k_r.max())  # both solvers' tolerance
        for got, ref, unit in ((T.dstress_dstrain[0], R.dstress_dstrain, p.E), (T.dstress_dnonlocal[0],
                               R.dstress_dnonlocal, p.E), (T.dlocal_dstrain[0], R.dlocal_dstrain, 1.0),
                               (T.dlocal_dnonlocal[0], R.dlocal_dnonlocal, 1.0)):
            assert np.allclose(got, ref, rtol=1e-8, atol=1e-10 * unit)
        assert T.local[0] == pytest.approx(R.local, rel=1e-10)
        loaded += np.abs(R.dstress_dnonlocal).max() > 1.0  # the coupling acts (kPa per unit ebar)
    assert loaded >= 2  # (a large drop of ebar makes the planes past their peak stronger: they unload)


def test_homogeneous_nonlocal_field_gives_the_local_law():
    """With ebar equal to the point's own post-peak slip strain at the end of the step (as in any
    homogeneous test), the coupled update is the local update; the local update's state carries that e."""
    p = load_preset("ottawa_c109").replace(**SOFT)
    model = CPAModel(p, axes=axes_from_alpha(0.0), nonlocal_length=0.004)
    sig, state, de = _past_peak(model, planes=3)
    s_loc, st_loc, D_loc = model.update(de, sig, state)
    dn = st_loc["nonlocal"] - state["nonlocal"]
    assert dn[0] > 0  # the softening planes slipped
    s_c, st_c, T = model.update(de, sig, state, d_nonlocal=dn)
    assert np.abs(s_c - s_loc).max() <= 1e-9 * np.abs(s_loc).max()
    assert np.abs(st_c["kappa"] - st_loc["kappa"]).max() <= 1e-9 * p.A
    assert T.local[0] == pytest.approx(st_loc["nonlocal"][0], rel=1e-9)
    # and the local law of a gradient model is the law without regularisation (no crack band)
    plain = CPAModel(p, axes=axes_from_alpha(0.0), regularise=False)
    s_p, _, _ = plain.update(de, sig, {k: v for k, v in state.items() if k != "nonlocal"})
    assert np.array_equal(s_p, s_loc)


def test_a_plane_that_passes_its_peak_in_a_step_leaves_the_update_continuous_at_a_zero_step():
    """The gradient's shift is accumulated per plane from the step after the plane passed its peak, and the
    local measure e grows by the slip of the planes already past it: a zero strain and nonlocal increment
    returns the committed stress (round-off) right after planes passed their peak with the nonlocal field
    ahead of e. (With the shift m t (ebar - e) applied at once, as before, that zero step moved the stress
    by 0.29 %: the planes that had just passed their peak became weaker between two steps.)"""
    p = load_preset("ottawa_c109").replace(**SOFT)
    model = CPAModel(p, axes=axes_from_alpha(30.0), nonlocal_length=0.004)
    sig, state, de = _past_peak(model, planes=1)
    for _ in range(40):
        before = (state["kappa"][0] >= p.kappa_instability).sum()
        sig, state, _ = model.update(de, sig, state, d_nonlocal=np.full(1, 0.04))  # ebar runs ahead of e
        assert state["status"][0] == 0
        if (state["kappa"][0] >= p.kappa_instability).sum() > before:
            break
    assert state["nonlocal"][0] > state["post_peak_strain"][0]  # the planes past their peak are weakened
    assert np.abs(state["nonlocal_shift"]).max() > p.A
    s0, st0, _ = model.update(np.zeros((1, 3, 3)), sig, state, d_nonlocal=np.zeros(1))
    assert np.abs(s0 - sig).max() <= 1e-10 * np.abs(sig).max()
    assert np.abs(st0["kappa"] - state["kappa"]).max() <= 1e-10 * state["kappa"].max()


def test_a_state_of_an_older_version_resumes_with_e_from_the_slips_and_no_shift():
    """A checkpoint written before e ("post_peak_strain") and the per-plane shifts were state variables
    resumes: e is the post-peak slip strain read from the committed slips, the shifts start at zero (the
    rule of docs/regularisation.md, section 3), and the update is that rule's to the bit."""
    p = load_preset("ottawa_c109").replace(**SOFT)
    model = CPAModel(p, axes=axes_from_alpha(30.0), nonlocal_length=0.004)
    sig, state, de = _past_peak(model, planes=2)
    for _ in range(5):  # the nonlocal field runs behind e: the planes past their peak get shifts
        sig, state, _ = model.update(de, sig, state, d_nonlocal=np.full(1, 0.01))
    assert np.abs(state["nonlocal_shift"]).max() > p.A
    old = {k: v for k, v in state.items() if k not in ("post_peak_strain", "nonlocal_shift")}
    s_old, st_old, _ = model.update(de, sig, old, d_nonlocal=np.full(1, 0.01))
    kstar = p.kappa_instability  # e: the slip past the peak of the planes past it, over t
    e_rule = np.where(state["kappa"] >= kstar, state["kappa"] - kstar, 0.0).sum(axis=1) / p.t
    rule = dict(old, post_peak_strain=e_rule, nonlocal_shift=np.zeros_like(state["nonlocal_shift"]))
    s_rule, st_rule, _ = model.update(de, sig, rule, d_nonlocal=np.full(1, 0.01))
    assert st_old["status"][0] == 0 and {"post_peak_strain", "nonlocal_shift"} <= set(st_old)
    assert np.array_equal(s_old, s_rule) and np.array_equal(st_old["post_peak_strain"], st_rule["post_peak_strain"])
    s_new, _, _ = model.update(de, sig, state, d_nonlocal=np.full(1, 0.01))
    assert 0 < np.abs(s_old - s_new).max() <= 0.02 * np.abs(s_new).max()  # a slightly different state: 0.9 %


def test_a_failed_coupled_point_replays_with_its_nonlocal_input(tmp_path):
    p = load_preset("ottawa_c109").replace(**SOFT)
    model = CPAModel(p, axes=axes_from_alpha(0.0), nonlocal_length=0.004, max_halvings=0, maxit=1)
    sig, state, de = _past_peak(model.replace(max_halvings=12, maxit=25))
    _, st, _ = model.update(de * 50, sig, state, d_nonlocal=np.array([0.3]))
    assert st["status"][0] == 2
    path = model.dump_failure(tmp_path / "point.npz")
    stored = np.load(path)
    assert stored["d_nonlocal"][0] == 0.3
    again, _, st2, T = replay(path, max_halvings=12, maxit=25)
    assert again.nonlocal_length == 0.004 and isinstance(T, CoupledTangent) and st2["status"][0] == 0


def test_where_the_branch_in_the_fraction_folds_the_floor_homotopy_carries_the_step():
    """A point of the shear-band study (quadratic elements, l = 3 mm, mu = 0.01: the corner of the band at the
    bottom platen, 30 % strain, two planes past their peak) whose branch in the fraction of the increment
    folds at 0.93 of it: the step failed there and the global step was cut. Along the step stabilisation's
    floor the whole increment has a solution (the reference's floor homotopy finds the same stress to 1e-9,
    and the same coupled tangent). It
    continues the branch: for 0.90 and 0.91 of the increment the branch in the fraction reaches the end
    (6-8 local iterations), for 0.92 and 0.93 the homotopy gives the answer (429-442 iterations, most in the
    fractions that fail first), and the stress moves by the same amount over each 0.01 (0.082, 0.079, 0.077,
    0.074 kPa at most: no jump where the homotopy takes over)."""
    from pathlib import Path

    path = Path(__file__).parent / "data" / "shear_band_fold_point.npz"
    model, stress, state, T = replay(path)
    stored = dict(np.load(path))
    assert state["status"][0] == 0
    kw = dict(d_nonlocal=stored["d_nonlocal"], step_fraction=float(stored["step_fraction"]))
    st0 = {k[len("state__"):]: v for k, v in stored.items() if k.startswith("state__")}
    s_ref, _, _, T_ref = update_point(model, stored["d_strain"][0], stored["stress"][0], st0, **kw)
    assert np.abs(stress[0] - s_ref).max() <= 1e-9 * np.abs(s_ref).max()
    for field in T._fields:  # the coupled tangent of the solution the homotopy reached (measured: 5e-14)
        mine, ref = np.asarray(getattr(T, field))[0], np.asarray(getattr(T_ref, field))
        assert np.abs(mine - ref).max() <= 1e-8 * max(np.abs(ref).max(), 1e-30), field
    answers = []
    for scale in (0.90, 0.91, 0.92, 0.93):
        s, st, _ = model.update(stored["d_strain"] * scale, stored["stress"], {k: v.copy() for k, v in st0.items()},
                                **dict(kw, d_nonlocal=stored["d_nonlocal"] * scale))
        assert st["status"][0] == 0
        answers.append(s[0])
    steps = np.diff(answers, axis=0)
    for a, b in zip(steps[:-1], steps[1:]):
        assert np.abs(b - a).max() <= 0.1 * np.abs(a).max()


def test_bad_gradient_input_is_named():
    p = load_preset("ottawa_c109").replace(**SOFT)
    with pytest.raises(ValueError, match="nonlocal_length = 0"):
        CPAModel(p, nonlocal_length=0.0)
    with pytest.raises(ValueError, match="softening_slip = 0"):
        CPAModel("ottawa_c109", nonlocal_length=0.004)
    with pytest.raises(ValueError, match="over_nonlocal = 1"):
        CPAModel(p, nonlocal_length=0.004, over_nonlocal=1.0)
    local = CPAModel(p)
    state = local.initial_state(2, stress=-100 * np.eye(3))
    with pytest.raises(ValueError, match="no nonlocal_length"):
        local.update(np.zeros((2, 3, 3)), -100 * np.eye(3)[None].repeat(2, 0), state, d_nonlocal=np.zeros(2))
    with pytest.raises(AttributeError):
        local.nonlocal_length
    grad = CPAModel(p, nonlocal_length=0.004)
    state = grad.initial_state(2, stress=-100 * np.eye(3))
    with pytest.raises(ValueError, match="d_nonlocal: expected a finite array of shape"):
        grad.update(np.zeros((2, 3, 3)), -100 * np.eye(3)[None].repeat(2, 0), state, d_nonlocal=np.zeros(3))
    assert grad.replace(stabilisation=0.1).nonlocal_length == 0.004
