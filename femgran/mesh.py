"""Meshes for the cases: structured generators, reading a user's mesh file, validity checks.

Generators return scikit-fem meshes with named boundaries (``mesh.boundaries``): 3D boxes have
``left/right`` (x), ``front/back`` (y), ``bottom/top`` (z); 2D rectangles have ``left/right`` (x) and
``bottom/top`` (y). Any mesh file meshio reads can be loaded with :func:`load_mesh` (it is checked for
inverted elements before any computation).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import skfem

__all__ = ["box", "rectangle", "graded", "load_mesh", "check_mesh", "name_box_boundaries"]


def graded(length: float, n: int, ratio: float = 1.0, start: float = 0.0) -> np.ndarray:
    """``n + 1`` coordinates from ``start`` to ``start + length``; successive sizes grow by ``ratio``."""
    n = int(n)
    if n < 1:
        raise ValueError(f"number of elements n = {n}: must be >= 1")
    if not (length > 0 and ratio > 0):
        raise ValueError(f"length = {length}, ratio = {ratio}: both must be > 0")
    h = ratio ** np.arange(n)
    return start + length * np.concatenate([[0.0], np.cumsum(h) / h.sum()])


def name_box_boundaries(mesh, tol: float = 1e-9):
    """Attach the named boundaries of the bounding box to ``mesh`` (returns a new mesh)."""
    lo, hi = mesh.p.min(axis=1), mesh.p.max(axis=1)
    span = hi - lo
    names = [("left", "right"), ("bottom", "top")] if mesh.dim() == 2 else [("left", "right"), ("front", "back"), ("bottom", "top")]
    tests = {}
    for axis, (a, b) in enumerate(names):
        tests[a] = (lambda x, axis=axis: np.abs(x[axis] - lo[axis]) <= tol * span[axis])
        tests[b] = (lambda x, axis=axis: np.abs(x[axis] - hi[axis]) <= tol * span[axis])
    return mesh.with_boundaries(tests)


def box(lx: float, ly: float, lz: float, nx: int, ny: int, nz: int, *, kind: str = "hex", origin=(0.0, 0.0, 0.0)):
    """Structured box [m] of ``nx * ny * nz`` hexahedra (``kind="hex"``) or 6 x as many tetrahedra."""
    xs = [origin[i] + np.linspace(0.0, L, int(n) + 1) for i, (L, n) in enumerate(((lx, nx), (ly, ny), (lz, nz)))]
    if kind == "hex":
        m = skfem.MeshHex.init_tensor(*xs)
    elif kind == "tet":
        m = skfem.MeshTet.init_tensor(*xs)
    else:
        raise ValueError(f"kind = {kind!r}: allowed 'hex' or 'tet'")
    return name_box_boundaries(m)


def rectangle(x, y, *, kind: str = "quad"):
    """Structured rectangle from coordinate vectors ``x``, ``y`` [m]: quads or (``kind="tri"``) triangles."""
    if kind == "quad":
        m = skfem.MeshQuad.init_tensor(np.asarray(x, float), np.asarray(y, float))
    elif kind == "tri":
        m = skfem.MeshTri.init_tensor(np.asarray(x, float), np.asarray(y, float))
    else:
        raise ValueError(f"kind = {kind!r}: allowed 'quad' or 'tri'")
    return name_box_boundaries(m)


def check_mesh(mesh, basis=None) -> None:
    """Raise ``ValueError`` if an element is inverted or degenerate (Jacobian determinant <= 0)."""
    if mesh.t.shape[1] == 0:
        raise ValueError("mesh: has no elements")
    if basis is None:
        e = {"MeshHex1": skfem.ElementHex1, "MeshTet1": skfem.ElementTetP1,
             "MeshQuad1": skfem.ElementQuad1, "MeshTri1": skfem.ElementTriP1}.get(type(mesh).__name__)
        if e is None:
            raise ValueError(f"mesh type {type(mesh).__name__}: not supported; allowed hex, tet, quad, tri")
        basis = skfem.Basis(mesh, e(), intorder=2)
    det = basis.mapping.detDF(basis.X)  # (nelems, nqp)
    scale = np.abs(det).max()
    positive = (det > 1e-12 * scale).all(axis=1)
    negative = (det < -1e-12 * scale).all(axis=1)
    # an inverted element: Jacobian ~0 or changing sign inside, or oriented against the rest of the mesh
    # (simplices: scikit-fem integrates with |det J|, so only degenerate ones are invalid)
    bad = ~(positive | negative)
    if type(mesh).__name__ in ("MeshHex1", "MeshQuad1"):
        bad |= negative if positive.sum() >= negative.sum() else positive
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"mesh: {int(bad.sum())} inverted or degenerate element(s) (Jacobian determinant ~0, changing sign, or opposite to the other elements; first: element {i}); "
            "allowed: positively oriented elements"
        )


def load_mesh(path):
    """Read any mesh file meshio reads (hexahedra, tetrahedra, quads, triangles) as a scikit-fem mesh.

    The mesh is checked for inverted elements; 2D meshes stored with a z coordinate are flattened.
    Named boundaries of the bounding box are attached (see the module docstring).
    """
    import meshio

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"mesh file {str(p)!r}: not found")
    try:
        m = meshio.read(p)
    except (Exception, SystemExit) as exc:  # meshio raises many types (even SystemExit) for unreadable files
        raise ValueError(f"mesh file {str(p)!r}: unreadable by meshio ({exc})") from None
    kinds = {"hexahedron": skfem.MeshHex, "tetra": skfem.MeshTet, "quad": skfem.MeshQuad, "triangle": skfem.MeshTri}
    for k, cls in kinds.items():
        if k in m.cells_dict:
            cells = m.cells_dict[k]
            pts = np.asarray(m.points, float)
            if cls in (skfem.MeshQuad, skfem.MeshTri):
                if pts.shape[1] == 3 and np.ptp(pts[:, 2]) > 0:
                    raise ValueError(f"mesh file {str(p)!r}: 2D cells ({k}) with a non-planar z coordinate")
                pts = pts[:, :2]
            if k == "hexahedron":
                from skfem.io.meshio import HEX_MAPPING

                cells = cells[:, np.argsort(HEX_MAPPING[:8])]
            used = np.unique(cells)
            remap = np.full(pts.shape[0], -1)
            remap[used] = np.arange(used.size)
            mesh = cls(pts[used].T, remap[cells].T, validate=False)
            check_mesh(mesh)
            return name_box_boundaries(mesh)
    raise ValueError(f"mesh file {str(p)!r}: no supported cells; found {sorted(m.cells_dict)}, "
                     f"allowed {sorted(kinds)}")
