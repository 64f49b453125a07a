"""Material axes, microstructure tensors, eta_f(n) (eqs. 2.4, 2.19-2.20) and the induced part (3.14-3.15)."""

import numpy as np
import pytest

from material import load_preset
from material.anisotropy import (
    axes_from_alpha,
    axes_from_frame,
    coaxial_fabric_direction,
    cohesion,
    default_axes,
    deviator,
    friction_coefficient,
    induced_tensor,
    inherent_tensor,
    series,
)

PRESET = load_preset("ottawa_c109")
rng = np.random.default_rng(11)


def _eq_2_20(p, alpha_deg):
    x = p.omega1 * (1 - 3 * np.cos(np.deg2rad(alpha_deg)) ** 2)
    return p.eta0 * (1 + x + sum(c * x ** (k + 2) for k, c in enumerate(p.a)))


@pytest.mark.parametrize("alpha", [0.0, 17.0, 45.0, 90.0, 133.0, -30.0])
def test_axes_from_alpha_orthonormal_right_handed(alpha):
    R = axes_from_alpha(alpha)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0)
    a = np.deg2rad(alpha)
    assert np.allclose(R[:, 1], [np.sin(a), 0, np.cos(a)])  # e2 in the x-z plane, alpha from z
    assert np.allclose(np.cross(R[:, 0], R[:, 1]), R[:, 2])


def test_default_axes_and_bad_alpha():
    assert np.allclose(default_axes()[:, 1], [0, 0, 1])
    with pytest.raises(ValueError, match="alpha_deg"):
        axes_from_alpha(np.nan)


def test_axes_from_frame_validation():
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    assert np.allclose(axes_from_frame(q), q)
    noisy = q + 1e-6 * rng.normal(size=(3, 3))
    fixed = axes_from_frame(noisy)
    assert np.allclose(fixed.T @ fixed, np.eye(3), atol=1e-14) and np.allclose(fixed, q, atol=1e-5)
    with pytest.raises(ValueError, match="left-handed"):
        axes_from_frame(q @ np.diag([1, 1, -1]))
    with pytest.raises(ValueError, match="not orthonormal"):
        axes_from_frame(2 * q)
    with pytest.raises(ValueError, match="shape"):
        axes_from_frame(np.eye(2))
    with pytest.raises(ValueError, match="NaN"):
        axes_from_frame(np.full((3, 3), np.nan))


def test_inherent_tensor_eq_2_19():
    """Omega traceless, Omega_ij n_i n_j = omega1 (1 - 3 cos^2 theta), theta the angle between n and e2."""
    axes = axes_from_alpha(35.0)
    om = inherent_tensor(0.14, axes)
    assert abs(np.trace(om)) < 1e-15 and np.allclose(om, om.T)
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cos = n @ axes[:, 1]
    assert np.allclose(np.einsum("ai,ij,aj->a", n, om, n), 0.14 * (1 - 3 * cos**2))


@pytest.mark.parametrize("alpha", [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0])
def test_friction_coefficient_reproduces_eq_2_20(alpha):
    """A normal at alpha from e2 (any azimuth, any material frame) has eta_f of eq. (2.20)."""
    expected = _eq_2_20(PRESET, alpha)
    for frame_alpha in (0.0, 50.0):
        axes = axes_from_alpha(frame_alpha)
        e2 = axes[:, 1]
        # normals at angle alpha from e2, several azimuths around e2
        psi = np.linspace(0, 2 * np.pi, 7, endpoint=False)
        a = np.deg2rad(alpha)
        n = (np.cos(a) * e2[None, :] + np.sin(a) * (np.cos(psi)[:, None] * axes[:, 0] + np.sin(psi)[:, None] * axes[:, 2]))
        assert np.allclose(friction_coefficient(PRESET, n, axes), expected, rtol=1e-13)
    # and even in n
    assert np.allclose(friction_coefficient(PRESET, -n, axes), expected, rtol=1e-13)


def test_preset_values_of_eta_f():
    """Spot values of the Table 3 fit: x = -2 omega1 and x = omega1 in eq. (2.20): 0.762795, 1.028370."""
    n = np.array([[0, 0, 1.0], [1.0, 0, 0]])
    assert np.allclose(friction_coefficient(PRESET, n), [0.76279518964, 1.02837006579], rtol=1e-10)


def test_series_is_the_bracket_of_eq_2_4():
    x = np.linspace(-0.3, 0.3, 13)
    c = (0.3956, 0.4457, 18.96)
    assert np.allclose(series(x, c), 1 + x + c[0] * x**2 + c[1] * x**3 + c[2] * x**4)
    assert np.allclose(series(x, ()), 1 + x)


def test_induced_tensor_is_beta_dev_strain():
    """Lambda = beta dev(eps) (eq. 3.15), traceless, added to Omega in eta_f (eq. 3.14)."""
    e = rng.normal(size=(3, 3))
    e = e + e.T
    lam = induced_tensor(5.0, e)
    assert np.allclose(lam, 5.0 * (e - np.trace(e) / 3 * np.eye(3)))
    assert abs(np.trace(lam)) < 1e-13
    assert np.allclose(deviator(e[None])[0], e - np.trace(e) / 3 * np.eye(3))
    p = load_preset("ottawa_c109_induced").replace(beta=5.0)
    n = rng.normal(size=(20, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    x = np.einsum("ai,ij,aj->a", n, lam, n)
    assert np.allclose(friction_coefficient(p, n, strain=e), p.eta0 * series(x, p.a))
    assert np.allclose(friction_coefficient(p, n), p.eta0)  # no strain: isotropic preset


def test_vertical_compression_strengthens_vertical_planes():
    """With beta > 0, axial compression along z raises eta_f on planes whose normals are horizontal
    (``docs/model.md``, "Inherent and induced anisotropy")."""
    p = load_preset("ottawa_c109_induced")
    eps = np.diag([0.33e-2, 0.33e-2, -1e-2])  # tension +: compression along z, lateral expansion
    eta = friction_coefficient(p, np.array([[1.0, 0, 0], [0, 0, 1.0]]), strain=eps)
    assert eta[0] > p.eta0 > eta[1]


def test_cohesion_distribution():
    n = np.array([[0, 0, 1.0], [1.0, 0, 0]])
    assert np.all(cohesion(PRESET, n) == 0.0)
    p = PRESET.replace(c0=2.0, omega1_c=0.1, b=(0.5,))
    x = 0.1 * np.array([-2.0, 1.0])
    assert np.allclose(cohesion(p, n), 2.0 * (1 + x + 0.5 * x**2))


def test_normals_validated():
    with pytest.raises(ValueError, match="unit"):
        friction_coefficient(PRESET, np.array([[1.0, 1.0, 0.0]]))
    with pytest.raises(ValueError, match="shape"):
        friction_coefficient(PRESET, np.array([1.0, 0.0, 0.0]))


def test_coaxial_fabric_direction_eq_3_8():
    e = np.diag([1e-3, 2e-3, -4e-3])
    d = coaxial_fabric_direction(e, 1.0, 0.0)
    ne = deviator(e[None])[0]
    assert np.allclose(d, ne / np.linalg.norm(ne))
    g = coaxial_fabric_direction(e, 0.7, 0.4)
    assert abs(np.trace(g)) < 1e-14 and np.linalg.norm(g) == pytest.approx(1.0)
    assert np.all(coaxial_fabric_direction(np.eye(3), 1.0, 0.5) == 0.0)  # no deviator -> zeros
    two_d = coaxial_fabric_direction(np.diag([1.0, -1.0])[None], 1.0, 0.3)
    assert two_d.shape == (1, 2, 2) and abs(np.trace(two_d[0])) < 1e-14
