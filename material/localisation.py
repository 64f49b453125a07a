"""Rice's localisation condition: where a tangent admits a band.

A material point whose incremental response is d sigma = D : d eps (``D`` its tangent, d sigma_ij / d eps_kl)
can develop a band with unit normal n, across which the velocity gradient jumps by g (x) n, when the
acoustic tensor

    Q_ik(n) = n_j D_ijkl n_l

is singular: det Q(n) = 0 for some n (Hill 1962; Rudnicki & Rice 1975; Rice 1976). While det Q(n) > 0 for
every n the incremental boundary-value problem is elliptic at the point. Once det Q(n) <= 0 for some n
it is not: a band is an admissible rate solution, the rate problem of the body loses uniqueness whatever
the local law's integration, and a rate-independent local continuum has no mesh-objective solution
past it. Non-associated flow (the CPA law's dilatancy differs from its friction) makes this happen before
the peak of the stress-strain curve (Rudnicki & Rice 1975); softening makes it happen at the latest
at the peak. A regularisation with a length (``docs/regularisation.md``) restores a well-posed problem.

:func:`ellipticity` searches the normals on a grid and returns, per point, the scale-free indicator

    min over n of det Q(n) / (|Q(n)| / sqrt(d))^d

(``d`` = 2 for the jump g in a plane, 3 in space; |Q| the Frobenius norm), which lies in [-1, 1], is 1
for Q = identity, positive while the point is elliptic and <= 0 once a band can form, with the
inclination of the band (the direction normal to n) at the minimum. For an isotropic elastic solid it is
4 (1 - 2 nu)(1 - nu) / ((1 - 2 nu)^2 + (2 - 2 nu)^2) in the plane: 0.8 for nu = 0, 0.53 for nu = 0.3.

In plane strain (``plane=(0, 1)``, the x-y plane of the FE cases) n and the jump g lie in the plane: the
out-of-plane mode, kinematically excluded there, is left out. The functions are numpy, vectorised over
points and normals.
"""

from __future__ import annotations

import numpy as np

__all__ = ["acoustic_tensor", "ellipticity", "band_normals", "ONSET"]

#: An indicator within this of 0 is the onset of localisation, not its loss: an associated perfectly plastic
#: point at its limit sits there to round-off (measured: exactly 0.0 on a Drucker-Prager footing, 1.6e-10 on
#: the isotropic CPA footing), as slip lines are admissible in a limit state. The indicator is scale-free.
ONSET = 1e-12


def band_normals(plane=(0, 1), resolution_deg: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit normals of candidate bands on a grid of ``resolution_deg``.

    ``plane`` = (i, j) two distinct axes: normals in that plane, n = cos(theta) e_i + sin(theta) e_j,
    theta in [0, 180) deg; ``plane=None``: over a hemisphere (elevation 0..90 deg from the x-y plane).
    Returns (normals (K, 3), the band's inclination from e_i [deg] in [0, 180) (the band runs normal to n;
    for a hemisphere, that of the projection on the x-y plane), the elevation of n [deg] (0 in a plane)).
    """
    if not 0.0 < float(resolution_deg) <= 45.0:
        raise ValueError(f"resolution_deg = {resolution_deg!r}; allowed: 0 < resolution_deg <= 45")
    step = np.deg2rad(resolution_deg)
    if plane is None:
        theta, phi = np.meshgrid(np.arange(0.0, np.pi, step), np.arange(0.0, 0.5 * np.pi + 0.5 * step, step))
        theta, phi = theta.ravel(), phi.ravel()
        n = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], axis=1)
        return n, np.rad2deg(theta + 0.5 * np.pi) % 180.0, np.rad2deg(phi)
    i, j = _check_plane(plane)
    theta = np.arange(0.0, np.pi, step)
    n = np.zeros((theta.size, 3))
    n[:, i], n[:, j] = np.cos(theta), np.sin(theta)
    return n, np.rad2deg(theta + 0.5 * np.pi) % 180.0, np.zeros_like(theta)


def _check_plane(plane) -> tuple[int, int]:
    try:
        i, j = (int(k) for k in plane)
    except (TypeError, ValueError):
        raise ValueError(f"plane = {plane!r}; allowed: two distinct axes (i, j) out of 0, 1, 2, or None") from None
    if i == j or not {i, j} <= {0, 1, 2}:
        raise ValueError(f"plane = {plane!r}; allowed: two distinct axes (i, j) out of 0, 1, 2, or None")
    return i, j


def _check_tangent(tangent) -> np.ndarray:
    D = np.asarray(tangent, dtype=float)
    if D.ndim == 4:
        D = D[None]
    if D.ndim != 5 or D.shape[1:] != (3, 3, 3, 3):
        raise ValueError(f"tangent has shape {np.shape(tangent)}; allowed: (3, 3, 3, 3) or (N, 3, 3, 3, 3)")
    if not np.all(np.isfinite(D)):
        raise ValueError(f"tangent: {int(np.sum(~np.isfinite(D).all(axis=(1, 2, 3, 4))))} point(s) have entries "
                         "that are not finite")
    return D


def acoustic_tensor(tangent, normals) -> np.ndarray:
    """Q_ik(n) = n_j D_ijkl n_l of each point (N) and normal (K, 3): (N, K, 3, 3)."""
    D = _check_tangent(tangent)
    return _acoustic(D, np.asarray(normals, dtype=float).reshape(-1, 3))


def _acoustic(D: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(N, K, 3, 3) as one matrix product: D as (N, (i, k), (j, l)) times n_j n_l as ((j, l), K)."""
    N, K = D.shape[0], n.shape[0]
    Dr = D.transpose(0, 1, 3, 2, 4).reshape(N, 9, 9)
    nn = (n[:, :, None] * n[:, None, :]).reshape(K, 9)
    return (Dr @ nn.T).reshape(N, 3, 3, K).transpose(0, 3, 1, 2)


def _det(Q: np.ndarray) -> np.ndarray:
    """Determinants of the trailing 2 x 2 or 3 x 3 matrices, in closed form."""
    if Q.shape[-1] == 2:
        return Q[..., 0, 0] * Q[..., 1, 1] - Q[..., 0, 1] * Q[..., 1, 0]
    return (Q[..., 0, 0] * (Q[..., 1, 1] * Q[..., 2, 2] - Q[..., 1, 2] * Q[..., 2, 1])
            - Q[..., 0, 1] * (Q[..., 1, 0] * Q[..., 2, 2] - Q[..., 1, 2] * Q[..., 2, 0])
            + Q[..., 0, 2] * (Q[..., 1, 0] * Q[..., 2, 1] - Q[..., 1, 1] * Q[..., 2, 0]))


def ellipticity(tangent, plane=(0, 1), resolution_deg: float = 0.5, *,
                families: bool = False) -> dict[str, np.ndarray]:
    """Rice's condition on N tangents (N, 3, 3, 3, 3) (see the module docstring).

    ``plane`` = (i, j): normals and jumps in the plane of axes i, j (plane strain); ``None``: normals over a
    hemisphere and jumps in space. Returns ``indicator`` (N,), the least det Q / (|Q| / sqrt d)^d over the
    normals (<= 0: a band can form), ``band_deg`` (N,), the band's inclination from e_i at that normal
    (:func:`band_normals`), and for ``plane=None`` ``normal_elevation_deg`` (N,). Points are taken in blocks
    of about 2^17 / (number of normals), so memory stays near 2^17 acoustic tensors (10 MB) whatever N.
    A point has lost ellipticity where its indicator is below -:data:`ONSET`.

    ``families=True`` (a plane only) also returns the least indicator and its band over each family of
    orientations: ``rising_indicator`` and ``rising_band_deg`` over bands inclined 0..90 deg from e_i
    (rising toward +e_i), ``falling_indicator`` and ``falling_band_deg`` over 90..180 deg (the horizontal
    and the vertical band belong to both). A law with mirror symmetry about the e_j axis gives both families
    the same indicator at mirror angles; a tilted bedding does not, and then the two arms of an X in a
    boundary-value problem can be compared each with its own family.
    """
    D = _check_tangent(tangent)
    if families and plane is None:
        raise ValueError("families = True needs a plane (i, j): over a hemisphere the bands have no rising and "
                         "falling families")
    normals, band, elevation = band_normals(plane, resolution_deg)
    axes = list(_check_plane(plane)) if plane is not None else [0, 1, 2]
    d = len(axes)
    subsets = {"": None}  # all normals: no copy of the ratios
    if families:
        subsets["rising_"] = np.flatnonzero(band <= 90.0)
        subsets["falling_"] = np.flatnonzero((band >= 90.0) | (band == 0.0))
    k_min = {name: np.empty(D.shape[0], dtype=int) for name in subsets}
    value = {name: np.empty(D.shape[0]) for name in subsets}
    step = max(2**17 // normals.shape[0], 1)
    for start in range(0, D.shape[0], step):
        Q = _acoustic(D[start:start + step], normals)[:, :, axes][:, :, :, axes]
        size = np.sqrt(np.einsum("pkim,pkim->pk", Q, Q) / d)
        ratio = _det(Q) / np.where(size > 0.0, size, np.inf) ** d
        for name, subset in subsets.items():
            k = np.argmin(ratio, axis=1) if subset is None else subset[np.argmin(ratio[:, subset], axis=1)]
            k_min[name][start:start + step] = k
            value[name][start:start + step] = ratio[np.arange(k.size), k]
    out = {}
    for name in subsets:
        out.update({f"{name}indicator": value[name], f"{name}band_deg": band[k_min[name]]})
    if plane is None:
        out["normal_elevation_deg"] = elevation[k_min[""]]
    return out
