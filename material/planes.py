"""Integration planes of the microplane model: symmetric quadrature rules on the unit sphere.

A rule is a set of M unit normals ``n_a`` (one per +/- pair, i.e. on a hemisphere) and weights
``w_a`` normalised so that ``sum(w) == 1``. For an **even** function f (f(-n) = f(n)), which is every
plane quantity of the model,

    <f> = (1 / 4 pi) * integral over the sphere of f(n) dS  ~=  sum_a w_a f(n_a)

(``docs/model.md``, "Integration planes"; thesis eq. 2.9 with the 1/(8 pi) of the +/- pairs folded in).

``available_rules()`` gives each rule's **degree** D: the full symmetric 2M-point rule integrates every
polynomial in (n1, n2, n3) of degree <= D exactly. Because the rules are centrally symmetric, odd
polynomials are integrated exactly for free, so D is odd and the folded rule is exact for every even
polynomial up to degree D - 1 and not exact at degree D + 1. All degrees below were verified
numerically (``tests/material/test_planes.py``) against the closed-form sphere averages of monomials,
:func:`monomial_sphere_average`:

============== ======== ====== ============================================================
name           planes M degree source
============== ======== ====== ============================================================
lebedev-26     13       7      Lebedev (1976) 26-point rule, orbits a1, a2, a3
bazant-oh-21   21       9      Bazant & Oh (1986) 2x21 rule
lebedev-50     25       11     Lebedev (1976) 50-point rule
bazant-oh-33   33       11     Bazant & Oh (1986) 2x33 rule, thesis Table 2 (10-digit table:
                               the even moments are exact to ~3e-11)
lebedev-86     43       15     Lebedev (1976) 86-point rule
lebedev-110    55       17     Lebedev (1976) 110-point rule
equator-78     78       13     Gauss-Legendre product rule about n3 (7 nodes in n3, 14 azimuths
                               per ring) whose equator ring has 72 azimuths: 36 normals, 5 deg apart
============== ======== ====== ============================================================

Every rule but ``equator-78`` is invariant under the 48 symmetries of the cube (the octahedral group with
reflections), in the frame in which it is tabulated.

``equator-78`` is for plane strain with the material e3 out of plane (the axes of
:func:`material.factory.plane_strain_axes`, which every plane-strain case uses). There the critical
planes contain the out-of-plane axis, so their normals lie on the ring n3 = 0, at an angle that turns with
the principal axes. A rule with few normals on that ring misses the critical plane by up to half its
spacing, and the critical-plane law with an isotropic eta is then stronger than Mohr-Coulomb by up to 11 %
(``bazant-oh-33``; 6 % with ``lebedev-110``, ``docs/cpa_law.md`` section 5.3). With 36 normals 5 deg apart
on the ring the excess is below 0.7 % at every orientation, at 2.4 times the planes of the default rule
(``tests/material/test_driver_cpa.py``). The ring's spacing also sets how a shear band turns after the
peak: with the default rule's normals 21-24 deg apart on the ring (in a biaxial specimen, slip lines at
45 and 69.05 deg from the horizontal and none between), the arms of a band that form between them turn by
7-10 deg as they soften; with ``equator-78`` they keep the angle they form at
(``docs/regularisation.md``, section 4). With the anisotropic thesis sand the default rule's peak strength
against the deposition angle has bumps of its own (23 % above the continuous failure criterion at
alpha = 30 deg in plane strain, 14 % at 75 deg on the triaxial path too), where ``equator-78`` follows the
criterion within 0.4 %, or 3.4 % where the critical plane leans out of the loading plane
(``docs/model.md``, "Integration planes"; ``tests/material/test_driver_cpa.py``). The extra ring points keep the degree: a ring of k equally
spaced azimuths integrates every trigonometric polynomial of degree below k, and 72 > 14. The model
attaches the planes to the material frame
(n_a = R n_a^ref, see :func:`rotate_normals`).
"""

from __future__ import annotations

import itertools
from math import gamma, pi

import numpy as np

__all__ = [
    "DEFAULT_RULE",
    "available_rules",
    "integration_rule",
    "rule_info",
    "rotate_normals",
    "sphere_average",
    "monomial_sphere_average",
]

DEFAULT_RULE = "bazant-oh-33"

_S2 = 0.7071067811  # as printed in Table 2

# Thesis Table 2 (Bazant & Oh 1986), verbatim: direction cosines and weights of the 33 planes
# (weights sum to 1/2 there; they are normalised to 1 below).
_BAZANT_OH_33_TABLE = (
    (1.0, 0.0, 0.0, 0.00985353993),
    (0.0, 1.0, 0.0, 0.00985353993),
    (0.0, 0.0, 1.0, 0.00985353993),
    (_S2, _S2, 0.0, 0.01629696858),
    (_S2, -_S2, 0.0, 0.01629696858),
    (_S2, 0.0, _S2, 0.01629696858),
    (_S2, 0.0, -_S2, 0.01629696858),
    (0.0, _S2, _S2, 0.01629696858),
    (0.0, _S2, -_S2, 0.01629696858),
    (0.9338989563, 0.3575370459, 0.0, 0.01347888440),
    (0.9338989563, -0.3575370459, 0.0, 0.01347888440),
    (0.3575370459, 0.9338989563, 0.0, 0.01347888440),
    (0.3575370459, -0.9338989563, 0.0, 0.01347888440),
    (0.9338989563, 0.0, 0.3575370459, 0.01347888440),
    (0.9338989563, 0.0, -0.3575370459, 0.01347888440),
    (0.3575370459, 0.0, 0.9338989563, 0.01347888440),
    (0.3575370459, 0.0, -0.9338989563, 0.01347888440),
    (0.0, 0.9338989563, 0.3575370459, 0.01347888440),
    (0.0, 0.9338989563, -0.3575370459, 0.01347888440),
    (0.0, 0.3575370459, 0.9338989563, 0.01347888440),
    (0.0, 0.3575370459, -0.9338989563, 0.01347888440),
    (0.4372636760, 0.4372636760, 0.7858759158, 0.01757591298),
    (0.4372636760, 0.4372636760, -0.7858759158, 0.01757591298),
    (0.4372636760, -0.4372636760, 0.7858759158, 0.01757591298),
    (0.4372636760, -0.4372636760, -0.7858759158, 0.01757591298),
    (0.4372636760, 0.7858759158, 0.4372636760, 0.01757591298),
    (0.4372636760, 0.7858759158, -0.4372636760, 0.01757591298),
    (0.4372636760, -0.7858759158, 0.4372636760, 0.01757591298),
    (0.4372636760, -0.7858759158, -0.4372636760, 0.01757591298),
    (0.7858759158, 0.4372636760, 0.4372636760, 0.01757591298),
    (0.7858759158, 0.4372636760, -0.4372636760, 0.01757591298),
    (0.7858759158, -0.4372636760, 0.4372636760, 0.01757591298),
    (0.7858759158, -0.4372636760, -0.4372636760, 0.01757591298),
)

# Octahedral orbits: ("a1", w) axes (6 points); ("a2", w) (1,1,0)/sqrt2 (12); ("a3", w) (1,1,1)/sqrt3 (8);
# ("b", w, l) (l, l, m), m = sqrt(1 - 2 l^2) (24); ("c", w, p) (p, q, 0), q = sqrt(1 - p^2) (24).
# Weights per point of the full sphere rule (sum 1 over all points).
_ORBIT_RULES = {
    # Bazant & Oh (1986) 2x21 rule (their weights sum to 1/2 over 21 planes: doubled here).
    "bazant-oh-21": (
        ("a1", 0.0265214244093 / 2.0),
        ("a2", 0.0199301476312 / 2.0),
        ("b", 0.0250712367487 / 2.0, 0.387907304067),
    ),
    # Lebedev, V.I. (1976), Zh. Vychisl. Mat. Mat. Fiz. 16, 293-306; orbit parameters as tabulated
    # (e.g. in Burkardt's sphere_lebedev_rule). Verified numerically in the tests.
    "lebedev-26": (
        ("a1", 0.04761904761904762),
        ("a2", 0.03809523809523810),
        ("a3", 0.03214285714285714),
    ),
    "lebedev-50": (
        ("a1", 0.0126984126984127),
        ("a2", 0.0225749559082892),
        ("a3", 0.02109375),
        ("b", 0.0201733355379189, 0.301511344577764),
    ),
    "lebedev-86": (
        ("a1", 0.01154401154401154),
        ("a3", 0.01194390908585628),
        ("b", 0.01111055571060340, 0.3696028464541502),
        ("b", 0.01187650129453714, 0.6943540066026664),
        ("c", 0.01181230374690448, 0.3742430390903412),
    ),
    "lebedev-110": (
        ("a1", 0.003828270494937162),
        ("a3", 0.009793737512487512),
        ("b", 0.008211737283191111, 0.1851156353447362),
        ("b", 0.009942814891178103, 0.6904210483822922),
        ("b", 0.009595471336070963, 0.3956894730559419),
        ("c", 0.009694996361663028, 0.4783690288121502),
    ),
}

# Gauss-Legendre product rules about n3: name -> (nodes in n3 (odd), azimuths per ring, azimuths on the
# equator ring n3 = 0)
_PRODUCT_RULES = {
    "equator-78": (7, 14, 72),
}

# name -> (degree of exactness D, short source)
_RULES = {
    "lebedev-26": (7, "Lebedev (1976), 26 points"),
    "bazant-oh-21": (9, "Bazant & Oh (1986), 2x21 planes"),
    "lebedev-50": (11, "Lebedev (1976), 50 points"),
    "bazant-oh-33": (11, "Bazant & Oh (1986), 2x33 planes, thesis Table 2"),
    "lebedev-86": (15, "Lebedev (1976), 86 points"),
    "lebedev-110": (17, "Lebedev (1976), 110 points"),
    "equator-78": (13, "Gauss-Legendre product rule about n3 with a 5-degree equator ring (this package)"),
}

_CACHE: dict[str, tuple[np.ndarray, np.ndarray]] = {}


def available_rules() -> dict[str, int]:
    """``{name: degree}``: every rule and the highest polynomial degree its full symmetric rule
    integrates exactly (even polynomials are exact up to ``degree - 1``; see the module docstring)."""
    return {name: deg for name, (deg, _) in _RULES.items()}


def rule_info(name: str) -> dict:
    """``{"name", "n_planes", "degree", "even_degree", "source"}`` of a rule."""
    normals, _ = integration_rule(name)
    degree, source = _RULES[name]
    return {"name": name, "n_planes": len(normals), "degree": degree, "even_degree": degree - 1, "source": source}


def integration_rule(name: str = DEFAULT_RULE) -> tuple[np.ndarray, np.ndarray]:
    """Normals and weights of a named rule, one normal per +/- pair.

    Parameters
    ----------
    name : str
        One of :func:`available_rules` (default ``"bazant-oh-33"``, thesis Table 2).

    Returns
    -------
    normals : (M, 3) float array of unit vectors in the rule's reference frame, each chosen with its
        first non-zero component positive.
    weights : (M,) float array, positive, ``sum == 1``.
    Fresh copies: the caller may modify them.

    Raises
    ------
    KeyError
        Unknown name (the message lists the available rules).
    """
    if not isinstance(name, str) or name not in _RULES:
        raise KeyError(f"unknown integration rule {name!r}; available: {sorted(_RULES)}")
    if name not in _CACHE:
        if name == "bazant-oh-33":
            table = np.array(_BAZANT_OH_33_TABLE)
            normals, weights = table[:, :3], table[:, 3]
        elif name in _PRODUCT_RULES:
            normals, weights = _product_rule(*_PRODUCT_RULES[name])
        else:
            normals, weights = _from_orbits(_ORBIT_RULES[name])
        # the printed direction cosines carry 10 digits: renormalise to unit length
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        weights = weights / weights.sum()
        normals.flags.writeable = False
        weights.flags.writeable = False
        _CACHE[name] = (normals, weights)
    normals, weights = _CACHE[name]
    return normals.copy(), weights.copy()


def rotate_normals(normals: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Global components ``R n_ref`` of reference-frame normals (M, 3); ``axes`` R (3, 3) has columns e1, e2, e3."""
    return np.asarray(normals, dtype=float) @ np.asarray(axes, dtype=float).T


def sphere_average(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Sphere average of an even plane quantity: ``sum_a w_a values[..., a, ...]``.

    Parameters
    ----------
    values : (M, ...) array, the quantity on each plane (plane index first).
    weights : (M,) weights of the rule (sum 1).

    Returns
    -------
    array of shape ``values.shape[1:]``.
    """
    values = np.asarray(values, dtype=float)
    weights = np.asarray(weights, dtype=float)
    if values.shape[:1] != weights.shape:
        raise ValueError(f"values: leading axis {values.shape[:1]} does not match the {weights.shape[0]} weights")
    return np.tensordot(weights, values, axes=(0, 0))


def monomial_sphere_average(a: int, b: int, c: int) -> float:
    """Exact mean of x^a y^b z^c over the unit sphere (zero if any exponent is odd).

    <x^a y^b z^c> = 2 G((a+1)/2) G((b+1)/2) G((c+1)/2) / G((a+b+c+3)/2) / (4 pi), G the Gamma function.
    """
    if a % 2 or b % 2 or c % 2:
        return 0.0
    return 2.0 * gamma((a + 1) / 2) * gamma((b + 1) / 2) * gamma((c + 1) / 2) / gamma((a + b + c + 3) / 2) / (4.0 * pi)


def _orbit(kind: str, *p: float) -> np.ndarray:
    """All distinct points of an octahedral orbit (permutations and sign changes of a generator)."""
    if kind == "a1":
        gen = (1.0, 0.0, 0.0)
    elif kind == "a2":
        gen = (np.sqrt(0.5), np.sqrt(0.5), 0.0)
    elif kind == "a3":
        gen = (np.sqrt(1.0 / 3.0),) * 3
    elif kind == "b":
        gen = (p[0], p[0], np.sqrt(1.0 - 2.0 * p[0] ** 2))
    elif kind == "c":
        gen = (p[0], np.sqrt(1.0 - p[0] ** 2), 0.0)
    else:  # pragma: no cover - table error
        raise ValueError(f"unknown orbit kind {kind!r}")
    seen: dict[tuple, np.ndarray] = {}
    for perm in itertools.permutations(gen):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            v = np.array(perm) * np.array(signs)
            seen.setdefault(tuple(np.round(v, 12) + 0.0), v)
    return np.array(list(seen.values()))


def _fold(points: np.ndarray) -> np.ndarray:
    """Mask of the representatives of +/- pairs: first non-zero component positive."""
    first = np.array([row[np.flatnonzero(np.abs(row) > 1e-12)[0]] for row in points])
    return first > 0


def _from_orbits(spec) -> tuple[np.ndarray, np.ndarray]:
    pts, wts = [], []
    for kind, w, *p in spec:
        o = _orbit(kind, *p)
        keep = _fold(o)
        pts.append(o[keep])
        wts.append(np.full(int(keep.sum()), 2.0 * w))  # each kept normal stands for +/- n
    return np.vstack(pts), np.concatenate(wts)


def _product_rule(n_z: int, n_phi: int, n_equator: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes z_i (``n_z``, odd) in n3 times ``n_phi`` equally spaced azimuths per ring
    (``n_equator`` on the ring z = 0), folded to one normal per +/- pair. Exact for every polynomial of degree
    <= min(2 n_z - 1, n_phi - 1): the rings integrate the azimuthal part, Gauss-Legendre the rest."""
    z, wz = np.polynomial.legendre.leggauss(n_z)
    pts, wts = [], []
    for zi, wi in zip(z, wz):
        if zi < -1e-14:  # the southern rings are the opposites of the northern ones
            continue
        k = n_equator if abs(zi) <= 1e-14 else n_phi
        phi = 2.0 * pi * np.arange(k) / k
        r = np.sqrt(1.0 - zi * zi)
        ring = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(k, zi)])
        if abs(zi) <= 1e-14:
            ring = ring[_fold(ring)]  # the ring's own opposites: half of it
        else:
            ring[~_fold(ring)] *= -1.0  # each normal with its first non-zero component positive
        pts.append(ring)
        wts.append(np.full(len(ring), 2.0 * wi / k))  # each kept normal stands for +/- n
    return np.vstack(pts), np.concatenate(wts)
