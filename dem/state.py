"""The state of a DEM sample (particles, walls, contact history) and its .npz file (no pickle)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .contacts import ContactLaw

_FORMAT = "femgran-dem-state"


@dataclass
class DEMState:
    """A 2D disk assembly inside four rigid walls.

    Attributes
    ----------
    positions : (N, 2) float, particle centres [m] (sample centre at the origin)
    radii : (N,) float [m]
    velocities : (N, 2) [m/s]; angular_velocities : (N,) [rad/s]
    forces : (N, 2) [N/m]; torques : (N,) [N] -- the forces of the current configuration (kept so that
        a resumed run continues bit for bit)
    half_size : (2,) reference half width and half height of the wall rectangle [m]
    boundary_strain : (2, 2) E with the boundary map x = (I + E) X, tension positive (Appendix D)
    boundary_rate : (2, 2) dE/dt [1/s]
    pair_i, pair_j : (P,) int, pair_zeta : (P,) float -- tangential contact history [m]
    law : ContactLaw
    time : float [s]; steps : int; dt : float [s] (0 = not yet chosen)
    meta : dict of JSON-serialisable run information (seed, version, stage, ...)
    """

    positions: np.ndarray
    radii: np.ndarray
    half_size: np.ndarray
    law: ContactLaw = field(default_factory=ContactLaw)
    velocities: np.ndarray | None = None
    angular_velocities: np.ndarray | None = None
    forces: np.ndarray | None = None
    torques: np.ndarray | None = None
    boundary_strain: np.ndarray | None = None
    boundary_rate: np.ndarray | None = None
    pair_i: np.ndarray | None = None
    pair_j: np.ndarray | None = None
    pair_zeta: np.ndarray | None = None
    time: float = 0.0
    steps: int = 0
    dt: float = 0.0
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, dtype=float)
        self.radii = np.ascontiguousarray(self.radii, dtype=float)
        n = len(self.radii)
        if self.positions.shape != (n, 2):
            raise ValueError(f"positions must have shape ({n}, 2), got {self.positions.shape}")
        self.half_size = np.asarray(self.half_size, dtype=float).reshape(2)
        zeros2 = lambda: np.zeros((n, 2))
        self.velocities = zeros2() if self.velocities is None else np.ascontiguousarray(self.velocities, float)
        self.forces = zeros2() if self.forces is None else np.ascontiguousarray(self.forces, float)
        self.angular_velocities = np.zeros(n) if self.angular_velocities is None else np.ascontiguousarray(self.angular_velocities, float)
        self.torques = np.zeros(n) if self.torques is None else np.ascontiguousarray(self.torques, float)
        self.boundary_strain = np.zeros((2, 2)) if self.boundary_strain is None else np.array(self.boundary_strain, float)
        self.boundary_rate = np.zeros((2, 2)) if self.boundary_rate is None else np.array(self.boundary_rate, float)
        if self.pair_i is None:
            self.pair_i = np.zeros(0, np.int64)
            self.pair_j = np.zeros(0, np.int64)
            self.pair_zeta = np.zeros(0)

    @property
    def n_particles(self) -> int:
        return len(self.radii)

    @property
    def masses(self) -> np.ndarray:
        """(N,) masses per metre of thickness [kg/m]."""
        return self.law.density * np.pi * self.radii**2

    @property
    def deformation_gradient(self) -> np.ndarray:
        return np.eye(2) + self.boundary_strain

    @property
    def area(self) -> float:
        """Area inside the walls [m^2] (per metre of thickness: volume V of Appendix C)."""
        return float(4.0 * self.half_size[0] * self.half_size[1] * np.linalg.det(self.deformation_gradient))

    def corners(self) -> np.ndarray:
        """(4, 2) current wall corners [m], counter-clockwise from bottom-left."""
        a, b = self.half_size
        ref = np.array([[-a, -b], [a, -b], [a, b], [-a, b]])
        return ref @ self.deformation_gradient.T

    def copy(self) -> "DEMState":
        return DEMState(**{k: (v.copy() if isinstance(v, (np.ndarray, dict)) else v) for k, v in self.__dict__.items()})


def save(state: DEMState, path) -> Path:
    """Write ``state`` to a plain ``.npz`` (arrays + a JSON string; readable without pickle)."""
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"DEM state file {str(path)!r}: suffix must be '.npz'")
    path.parent.mkdir(parents=True, exist_ok=True)
    header = {"format": _FORMAT, "version": 1, "law": state.law.to_dict(), "time": state.time,
              "steps": state.steps, "dt": state.dt, "meta": state.meta}
    arrays = {k: getattr(state, k) for k in ("positions", "radii", "half_size", "velocities",
                                             "angular_velocities", "forces", "torques", "boundary_strain",
                                             "boundary_rate", "pair_i", "pair_j", "pair_zeta")}
    tmp = path.with_name(path.stem + ".tmp.npz")
    np.savez(tmp, header=np.array(json.dumps(header)), **arrays)
    tmp.replace(path)  # atomic: an interrupted write never corrupts the previous checkpoint
    return path


def load(path) -> DEMState:
    """Read a state written by :func:`save`."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"DEM state file {str(path)!r} does not exist")
    with np.load(path, allow_pickle=False) as data:
        header = json.loads(str(data["header"]))
        if header.get("format") != _FORMAT:
            raise ValueError(f"{str(path)!r} is not a DEM state file (format {header.get('format')!r})")
        arrays = {k: data[k] for k in data.files if k != "header"}
    return DEMState(law=ContactLaw(**header["law"]), time=header["time"], steps=header["steps"],
                    dt=header["dt"], meta=header["meta"], **arrays)
