"""Run folders: ParaView time series (.pvd + one .vtu per step), history CSV, parameters, plots.

Written step by step: after every converged step the ``.vtu`` of that step is written and the
``.pvd`` index is rewritten atomically (temporary file + rename), and the history row is appended to
``history.csv`` and flushed, so an interrupted run leaves a readable series.

Fields (snake_case; units: m, kPa):

* point data (at the mesh vertices): ``displacement`` (3), and L2 projections of the quadrature
  fields: ``stress``, ``strain``, ``plastic_strain`` (9 components each, XX XY XZ YX ... ZZ: the full
  3x3 row-major tensor, so ParaView's component order question does not arise), scalars
  ``mobilised_ratio`` (CPA: mobilised friction tau/sigma_N of the most loaded plane over eta_f),
  ``kappa_max`` (CPA: largest plane hardening variable, m), ``stabilisation`` (CPA: the mu of the step
  stabilisation's floor in the last step, 0 where the thesis's law was uniquely solvable, docs/cpa_law.md
  section 4), ``overstress`` (CPA: the largest share of a loading plane's mobilised ratio the step
  stabilisation carries above the hardening curve in the last step), ``ellipticity`` (Rice's indicator of
  the committed tangent, :mod:`material.localisation`: below 0 where a band can form; normals on a 1 degree
  grid in 2D, 10 degrees in 3D), ``eq_plastic_strain`` (von Mises law),
  ``q_kPa`` (sqrt(3 J2)), ``p_kPa`` (mean stress, compression +);
* cell data: the averages of the same quadrature fields over each element (weighted by dx; for
  ``ellipticity`` the least value of the element's points),
  ``status`` (max material status in the element) and ``deposition_axis`` (material e2, if the
  material has ``axes``).
"""

from __future__ import annotations

import functools
import json
import os
import sys
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla
import skfem

from femgran.solver import DIRECT_ORDERING

__all__ = ["SeriesWriter", "L2Projector", "point_fields", "read_pvd", "write_parameters", "plot_history", "plot_field"]


class L2Projector:
    """L2 projection of quadrature-point fields onto the linear Lagrange space of the mesh vertices.

    Solves M P = b with the (consistent) mass matrix M_ab = int N_a N_b and b_a = sum_q dx N_a f(q), using
    the same quadrature as the solver (so the point values are used directly).
    """

    def __init__(self, disc):
        p1 = {"MeshHex1": skfem.ElementHex1, "MeshTet1": skfem.ElementTetP1,
              "MeshQuad1": skfem.ElementQuad1, "MeshTri1": skfem.ElementTriP1}[type(disc.mesh).__name__]()
        self.basis = skfem.Basis(disc.mesh, p1, intorder=disc.intorder)
        if self.basis.X.shape[1] != disc.nqp:
            raise ValueError("projection basis: quadrature differs from the solver's")
        M = skfem.BilinearForm(lambda u, v, w: u * v).assemble(self.basis)
        self._lu = spla.splu(M.tocsc(), permc_spec=DIRECT_ORDERING)
        nb = self.basis.Nbfun
        self._N = np.stack([np.asarray(self.basis.basis[a][0]) for a in range(nb)])  # (nb, nel, nq)
        self._dofs = self.basis.element_dofs  # (nb, nel)
        self._dx = disc.dx
        self.n = self.basis.N

    def __call__(self, values: np.ndarray) -> np.ndarray:
        """values (N, k) at the points (element-major) -> (n_vertices, k) nodal values."""
        nel, nq = self._dx.shape
        v = np.asarray(values, float).reshape(nel, nq, -1)
        be = np.einsum("aeq,eqk,eq->aek", self._N, v, self._dx)
        k = v.shape[-1]
        b = np.zeros((self.n, k))
        for c in range(k):
            b[:, c] = np.bincount(self._dofs.ravel(), weights=be[..., c].ravel(), minlength=self.n)
        return self._lu.solve(b)


#: Fields whose cell data is the least value over the element's points instead of the average: Rice's
#: indicator, where one point past the onset marks the element (an average hid the 6 points past it among
#: the 630 of a coarse footing: no element below 0).
_CELL_MINIMUM = frozenset({"ellipticity"})


def point_fields(solver) -> dict[str, np.ndarray]:
    """Quadrature-point fields (N, k) of the committed state, flattened (tensors as 9 components)."""
    pts = solver.points
    s = pts.stress
    st = pts.state
    out = {"stress": s.reshape(-1, 9), "strain": np.asarray(st["strain"]).reshape(-1, 9)}
    if "plastic_strain" in st:
        out["plastic_strain"] = np.asarray(st["plastic_strain"]).reshape(-1, 9)
    p = -np.trace(s, axis1=1, axis2=2) / 3.0
    dev = s + p[:, None, None] * np.eye(3)
    out["p_kPa"] = p[:, None]
    out["q_kPa"] = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))[:, None]
    for key in ("mobilised_ratio", "stabilisation", "overstress", "eq_plastic_strain", "pore_pressure_kPa"):
        if key in st:
            out[key] = np.asarray(st[key], float).reshape(-1, 1)
    if "kappa" in st:
        out["kappa_max"] = np.asarray(st["kappa"]).max(axis=1)[:, None]
    from femgran.diagnostics import rice_indicator

    rice = rice_indicator(getattr(solver, "_committed_tangent", None), solver.disc.dim, coarse=True)
    if rice is not None:
        out["ellipticity"] = rice[:, None]
    return out


def write_parameters(path, params: dict) -> Path:
    """Write the run parameters (and the package version) as JSON."""
    from material.version import __version__

    path = Path(path)
    data = {"femgran_version": __version__, **params}
    path.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")
    return path


def _jsonable(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return repr(obj)


class SeriesWriter:
    """Writes a run folder step by step (see the module docstring).

    Parameters
    ----------
    out_dir : path
        Created if missing. Files: ``<name>.pvd``, ``<name>_NNNN.vtu``, ``history.csv``.
    disc : femgran.assembly.Discretisation
    name : str
        Base name of the series.
    every : int
        Write the fields every ``every`` converged steps (the history gets every step; the last step
        is always written on close).
    resume : the writer's :meth:`state` saved in a checkpoint: the series and ``history.csv`` continue
        from there (the rows and frames written after it are dropped).
    """

    def __init__(self, out_dir, disc, name: str = "solution", every: int = 1, resume: dict | None = None):
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.disc = disc
        self.name = name
        self.every = max(int(every), 1)
        self.project = L2Projector(disc)
        self.datasets: list[tuple[float, str]] = []
        self._csv = None  # the history.csv TableWriter, made at the first row (it takes the solver's descriptions)
        self._count = 0
        self._last_written = None
        if resume is not None:
            from material.table import TableWriter, truncate_rows

            self.datasets = [(float(t), str(f)) for t, f in resume["datasets"]]
            self._count, self._last_written = int(resume["count"]), resume["last_written"]
            truncate_rows(self.out_dir / "history.csv", self._count)
            self._csv = TableWriter(self.out_dir / "history.csv", title="FE history", append=True)
            self._write_pvd()

    def state(self) -> dict:
        """What a checkpoint needs to continue this series (JSON-able)."""
        return {"datasets": [[t, f] for t, f in self.datasets], "count": self._count, "last_written": self._last_written}

    def write(self, t: float, solver, row: dict) -> None:
        if self._csv is None:
            from material.table import TableWriter

            self._csv = TableWriter(self.out_dir / "history.csv", title="FE history",
                                    descriptions=getattr(solver, "history_descriptions", None))
        self._csv.write(row)
        if self._count % self.every == 0:
            self._write_fields(t, solver)
        self._count += 1

    def _write_fields(self, t: float, solver) -> None:
        import meshio

        disc = self.disc
        mesh = disc.mesh
        nv = mesh.p.shape[1]
        d = disc.dim
        u = solver.u[: disc.n_displacement_dofs].reshape(-1, d)[:nv]
        points = np.zeros((nv, 3))
        points[:, :d] = mesh.p.T
        disp = np.zeros((nv, 3))
        disp[:, :d] = u
        fields = point_fields(solver)
        point_data = {"displacement": disp}
        if hasattr(disc, "nonlocal_field"):
            point_data[getattr(disc, "nonlocal_name", "nonlocal")] = disc.nonlocal_field(solver.u)
        cell_data = {}
        w = disc.dx / disc.dx.sum(axis=1, keepdims=True)
        for key, val in fields.items():
            nodal = self.project(val)
            per_element = val.reshape(disc.nelems, disc.nqp, -1)
            cell = per_element.min(axis=1) if key in _CELL_MINIMUM else np.einsum("eqk,eq->ek", per_element, w)
            point_data[key] = nodal if nodal.shape[1] > 1 else nodal[:, 0]
            cell_data[key] = [cell if cell.shape[1] > 1 else cell[:, 0]]
        status = np.asarray(solver.points.state["status"]).reshape(disc.nelems, disc.nqp).max(axis=1)
        cell_data["status"] = [status.astype(np.int32)]
        axes = getattr(solver.material, "axes", None)
        if axes is not None and np.shape(axes) == (3, 3):
            cell_data["deposition_axis"] = [np.tile(np.asarray(axes)[:, 1], (disc.nelems, 1))]
        cells = _meshio_cells(mesh)
        fname = f"{self.name}_{len(self.datasets):04d}.vtu"
        meshio.Mesh(points, cells, point_data=point_data, cell_data=cell_data).write(self.out_dir / fname)
        self.datasets.append((float(t), fname))
        self._last_written = _series_time(solver)
        self._write_pvd()

    def _write_pvd(self) -> None:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
        for t, f in self.datasets:
            lines.append(f'    <DataSet timestep="{t:.10g}" group="" part="0" file="{f}"/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.out_dir / f".{self.name}.pvd.tmp"
        tmp.write_text("\n".join(lines))
        os.replace(tmp, self.out_dir / f"{self.name}.pvd")

    @property
    def pvd_path(self) -> Path:
        return self.out_dir / f"{self.name}.pvd"

    def close(self, solver, completed: bool, reason: str) -> None:
        if self._last_written != _series_time(solver):
            self._write_fields(_series_time(solver), solver)
        if self._csv is not None:
            self._csv.close()
        (self.out_dir / "status.json").write_text(json.dumps({"completed": completed, "reason": reason}, indent=2))


def _series_time(solver) -> float:
    """The time of the series: the load factor, plus the stage index in a staged run."""
    return getattr(solver, "time_offset", 0.0) + solver.t


def _meshio_cells(mesh):
    t = mesh.t
    name = {"MeshHex1": "hexahedron", "MeshTet1": "tetra", "MeshQuad1": "quad", "MeshTri1": "triangle"}[type(mesh).__name__]
    if name == "hexahedron":
        from skfem.io.meshio import HEX_MAPPING

        t = t[HEX_MAPPING[:8]]
    return [(name, np.ascontiguousarray(t.T))]


def read_pvd(path) -> list[tuple[float, Path]]:
    """(timestep, file) entries of a .pvd collection."""
    import xml.etree.ElementTree as ET

    path = Path(path)
    root = ET.parse(path).getroot()
    return [(float(ds.get("timestep")), path.parent / ds.get("file")) for ds in root.iter("DataSet")]


def plot_history(history, x: str, y: str, path, *, xlabel=None, ylabel=None, title=None, reference=None) -> Path:
    """Matplotlib curve y(x) from a history table, saved as PNG. ``reference``: (label, x, y) or list of them."""
    refs = [] if reference is None else (reference if isinstance(reference, list) else [reference])
    curves = [("FE", history[x], history[y], "o-")] + [(lab, rx, ry, "--") for lab, rx, ry in refs]
    return plot_curves(curves, path, xlabel=xlabel or x, ylabel=ylabel or y, title=title)


def plot_curves(curves, path, *, xlabel: str, ylabel: str, title=None) -> Path:
    """Several curves ``(label, x, y, style)`` on one set of axes, saved as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.6))
    for label, cx, cy, style in curves:
        ax.plot(cx, cy, style, ms=3, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_field(vtu_path, field: str, path, *, component: int | str | None = None, warp: float = 0.0) -> Path | None:
    """PNG of a nodal field of a .vtu, rendered off screen with pyvista (None if rendering is unavailable).

    ``component``: an index of a multi-component field, or ``"norm"`` (Euclidean norm of the components).
    """
    try:
        pv = _offscreen_pyvista()
        if pv is None:
            return None
        grid = pv.read(str(vtu_path))
        name = field
        values = np.asarray(grid.point_data[field])
        if component is not None:
            name = f"{field}_{component}"
            grid.point_data[name] = np.linalg.norm(values, axis=1) if component == "norm" else values[:, component]
        if warp:
            grid = grid.warp_by_vector("displacement", factor=warp)
        pl = pv.Plotter(off_screen=True, window_size=(800, 600))
        pl.add_mesh(grid, scalars=name, preference="point", show_edges=False, cmap="viridis")
        if grid.bounds[5] - grid.bounds[4] == 0:
            pl.view_xy()
        else:
            pl.view_isometric()
        pl.screenshot(str(path))
        pl.close()
        return Path(path)
    except Exception:  # noqa: BLE001 - no display / no OSMesa: plots are optional
        return None


# Headless OpenGL libraries VTK can render with, in VTK's own order of preference (EGL, then OSMesa);
# the names are the ones VTK's loaders dlopen.
_HEADLESS_GL = (("vtkEGLRenderWindow", ("libEGL.so.1", "libEGL.so")),
                ("vtkOSOpenGLRenderWindow", ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so")))


@functools.cache
def _offscreen_pyvista():
    """pyvista, set up once for off-screen rendering; None if this machine cannot render at all.

    Without an X display VTK (>= 9.4 wheels) first tries an X window, prints "bad X server connection"
    and only then falls back to EGL or OSMesa. Naming the headless window class in
    ``VTK_DEFAULT_OPENGL_WINDOW`` (read when a render window is created, so it may be set after
    ``import vtk``) skips that probe: the picture is still rendered (EGL: Mesa or GPU), and no warning
    is hidden. Done on Linux when DISPLAY is unset, or when PYVISTA_OFF_SCREEN=true asks for off-screen
    rendering; otherwise a display is left alone, and so is a window class the user chose. Headless
    with neither EGL nor OSMesa loadable, VTK would kill the process (segfault, not an exception):
    hence None.
    """
    import pyvista as pv

    linux = sys.platform.startswith("linux")
    headless = linux and not os.environ.get("DISPLAY")
    wanted = os.environ.get("PYVISTA_OFF_SCREEN", "false").lower() == "true"  # pyvista's own test
    if linux and (headless or wanted) and not os.environ.get("VTK_DEFAULT_OPENGL_WINDOW"):
        import ctypes

        window = next((w for w, libs in _HEADLESS_GL if any(_loadable(ctypes, lib) for lib in libs)), None)
        if window is not None:
            os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = window
        elif headless:
            return None
    if headless:
        pv.OFF_SCREEN = True
    return pv


def _loadable(ctypes, lib: str) -> bool:
    try:
        ctypes.CDLL(lib)
    except OSError:
        return False
    return True
