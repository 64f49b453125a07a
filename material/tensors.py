"""Converters between full tensors and 6-component (Voigt / Mandel) forms.

Every function accepts any number of leading (batch) axes: (..., 3, 3) second-order tensors,
(..., 3, 3, 3, 3) fourth-order tangents, (..., 6) vectors and (..., 6, 6) matrices.

Mandel (the package's internal form, same as :mod:`material._cpa_kernel`):
    v = (a11, a22, a33, sqrt2 a23, sqrt2 a13, sqrt2 a12) for stresses **and** strains;
    M_IJ = w_I w_J C_{ij kl} with w = (1, 1, 1, sqrt2, sqrt2, sqrt2).
    Then a:b = v_a . v_b, (C:e)_M = M e_M, and compositions / inverses of 4th-order maps on
    symmetric tensors are plain 6x6 matrix products / inverses.

Abaqus UMAT (Voigt) order (11, 22, 33, 12, 13, 23):
    stress  STRESS = (s11, s22, s33, s12, s13, s23),
    strain  STRAN  = (e11, e22, e33, 2 e12, 2 e13, 2 e23)   (engineering shear strains gamma = 2 eps),
    tangent DDSDDE_IJ = d STRESS_I / d STRAN_J = C_{i_I j_I k_J l_J} (no factors).
    Then sigma:eps = STRESS . STRAN, and STRESS = DDSDDE @ STRAN.

Tangents returned by :func:`from_mandel_matrix` and :func:`from_voigt_tangent` have both minor
symmetries (C_ijkl = C_jikl = C_ijlk); a tangent without them is symmetrised on the way to 6x6.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "MANDEL_WEIGHTS",
    "MANDEL_INDEX",
    "VOIGT_INDEX",
    "to_mandel",
    "from_mandel",
    "to_mandel_matrix",
    "from_mandel_matrix",
    "stress_to_voigt",
    "strain_to_voigt",
    "voigt_to_stress",
    "voigt_to_strain",
    "to_voigt_tangent",
    "from_voigt_tangent",
    "identity_projectors",
]

SQRT2 = np.sqrt(2.0)
MANDEL_INDEX = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
VOIGT_INDEX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # Abaqus UMAT
_MI = np.array([p[0] for p in MANDEL_INDEX]), np.array([p[1] for p in MANDEL_INDEX])
_VI = np.array([p[0] for p in VOIGT_INDEX]), np.array([p[1] for p in VOIGT_INDEX])
MANDEL_WEIGHTS = np.array([1.0, 1.0, 1.0, SQRT2, SQRT2, SQRT2])  # Mandel value = weight x tensor component
_MW = MANDEL_WEIGHTS
_VW_STRAIN = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])


def _check(a: np.ndarray, tail: tuple, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.shape[a.ndim - len(tail):] != tail or a.ndim < len(tail):
        raise ValueError(f"{name}: expected shape (..., {', '.join(map(str, tail))}), got {a.shape}")
    return a


def _sym2(a: np.ndarray) -> np.ndarray:
    return 0.5 * (a + np.swapaxes(a, -1, -2))


def _sym4(c: np.ndarray) -> np.ndarray:
    """Minor-symmetric part of (..., 3, 3, 3, 3)."""
    c = 0.5 * (c + np.swapaxes(c, -4, -3))
    return 0.5 * (c + np.swapaxes(c, -2, -1))


def _from_six(v: np.ndarray, index, weights) -> np.ndarray:
    i, j = index
    out = np.zeros(v.shape[:-1] + (3, 3))
    comp = v / weights
    out[..., i, j] = comp
    out[..., j, i] = comp
    return out


# --------------------------------------------------------------------------- Mandel
def to_mandel(a) -> np.ndarray:
    """(..., 3, 3) -> (..., 6) Mandel vector (a11, a22, a33, r a23, r a13, r a12), r = sqrt2 (symmetric part)."""
    a = _sym2(_check(a, (3, 3), "tensor"))
    return a[..., _MI[0], _MI[1]] * _MW


def from_mandel(v) -> np.ndarray:
    """(..., 6) Mandel vector -> (..., 3, 3) symmetric tensor."""
    return _from_six(_check(v, (6,), "Mandel vector"), _MI, _MW)


def to_mandel_matrix(c) -> np.ndarray:
    """(..., 3, 3, 3, 3) fourth-order map on symmetric tensors -> (..., 6, 6), M_IJ = w_I w_J C_{ij kl}."""
    c = _sym4(_check(c, (3, 3, 3, 3), "tangent"))
    i, j = _MI
    m = c[..., i[:, None], j[:, None], i[None, :], j[None, :]]
    return m * np.outer(_MW, _MW)


def from_mandel_matrix(m) -> np.ndarray:
    """(..., 6, 6) Mandel matrix -> (..., 3, 3, 3, 3) with both minor symmetries."""
    m = _check(m, (6, 6), "Mandel matrix") / np.outer(_MW, _MW)
    out = np.zeros(m.shape[:-2] + (3, 3, 3, 3))
    i, j = _MI
    for I in range(6):  # 36 index pairs; vectorised over the batch axes
        for J in range(6):
            val = m[..., I, J]
            a, b, c, d = i[I], j[I], i[J], j[J]
            out[..., a, b, c, d] = val
            out[..., b, a, c, d] = val
            out[..., a, b, d, c] = val
            out[..., b, a, d, c] = val
    return out


# --------------------------------------------------------------------------- Abaqus Voigt
def stress_to_voigt(s) -> np.ndarray:
    """(..., 3, 3) stress -> (..., 6) Abaqus STRESS (s11, s22, s33, s12, s13, s23)."""
    s = _sym2(_check(s, (3, 3), "stress"))
    return s[..., _VI[0], _VI[1]]


def strain_to_voigt(e) -> np.ndarray:
    """(..., 3, 3) strain -> (..., 6) Abaqus STRAN (e11, e22, e33, 2 e12, 2 e13, 2 e23)."""
    e = _sym2(_check(e, (3, 3), "strain"))
    return e[..., _VI[0], _VI[1]] * _VW_STRAIN


def voigt_to_stress(v) -> np.ndarray:
    """(..., 6) Abaqus STRESS -> (..., 3, 3)."""
    return _from_six(_check(v, (6,), "Voigt stress"), _VI, np.ones(6))


def voigt_to_strain(v) -> np.ndarray:
    """(..., 6) Abaqus STRAN (engineering shear) -> (..., 3, 3) tensor strain."""
    return _from_six(_check(v, (6,), "Voigt strain"), _VI, _VW_STRAIN)


def to_voigt_tangent(c) -> np.ndarray:
    """(..., 3, 3, 3, 3) -> (..., 6, 6) Abaqus DDSDDE, DDSDDE_IJ = C_{i_I j_I k_J l_J}."""
    c = _sym4(_check(c, (3, 3, 3, 3), "tangent"))
    i, j = _VI
    return c[..., i[:, None], j[:, None], i[None, :], j[None, :]].copy()


def from_voigt_tangent(d) -> np.ndarray:
    """(..., 6, 6) Abaqus DDSDDE -> (..., 3, 3, 3, 3) with both minor symmetries."""
    d = _check(d, (6, 6), "DDSDDE")
    # DDSDDE_IJ = C_{ij kl} = Mandel_IJ / (w_I w_J) after reordering (11,22,33,12,13,23) -> (11,22,33,23,13,12)
    perm = [0, 1, 2, 5, 4, 3]
    m = d[..., perm, :][..., :, perm] * np.outer(_MW, _MW)
    return from_mandel_matrix(m)


def identity_projectors() -> tuple[np.ndarray, np.ndarray]:
    """(P_vol, P_dev), (3, 3, 3, 3): P_vol = 1(x)1 / 3, P_dev = I_sym - P_vol; C_iso = 3K P_vol + 2G P_dev."""
    d = np.eye(3)
    p_vol = np.einsum("ij,kl->ijkl", d, d) / 3.0
    i_sym = 0.5 * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d))
    return p_vol, i_sym - p_vol
