"""Virtual experiments: biaxial compression (constant lateral stress) and rotation of the principal
strain axes at constant eps_v and eps_q (eq. 3.10, boundary kinematics of Appendix D).

A run is a list of *segments* (a number of steps with a prescribed boundary-strain rate and an
optional servo on sigma_xx). The driver records the history every ``record_every`` steps (also
written line by line to ``out/history.csv`` when ``out`` is given), keeps position snapshots for the
fabric analysis, writes a checkpoint ``.npz`` every ``checkpoint_every`` steps and can resume from it
with results identical to an uninterrupted run.

Sign conventions: the engine works tension positive; the history columns follow the geotechnical
convention (compression positive) where their names say so: ``eps_a`` (axial = y), ``eps_v``,
``eps_q`` (2D: (eps_1 - eps_3)/2), ``p_kPa`` ((sigma_1 + sigma_3)/2), ``q_kPa`` (sigma_1 - sigma_3).
Angles (deg) are those of the major *compressive* principal direction measured from the vertical (y)
axis, counter-clockwise: ``alpha_eps`` (strain), ``alpha_deps`` (strain increment), ``alpha_sigma``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from material.table import Table, TableWriter, read_table

from . import measures
from .simulation import Simulation
from .state import DEMState, load, save

COLUMNS = ("step", "time_s", "alpha_target_deg", "eps_xx", "eps_yy", "eps_xy", "eps_a", "eps_v", "eps_q",
           "sigma_xx_kPa", "sigma_yy_kPa", "sigma_xy_kPa", "contact_sigma_xx_kPa", "contact_sigma_yy_kPa",
           "contact_sigma_xy_kPa", "p_kPa", "q_kPa", "stress_ratio", "phi_mob_deg", "alpha_eps_deg",
           "alpha_deps_deg", "alpha_sigma_deg", "porosity", "coordination", "inertial_number", "steps_per_s")
# eps_xx, eps_yy, eps_xy, sigma_*: tension positive (the engine's convention)
CONVENTION = ("tensor components eps_ij, sigma_ij_kPa: tension positive (the engine's); eps_a, eps_v, p, q: "
              "compression positive; angles from the y axis")
DESCRIPTIONS = {
    "step": "DEM time step counter", "time_s": "simulated time [s]",
    "alpha_target_deg": "prescribed direction of the principal strain rate [deg]",
    "eps_xx": "boundary strain [-]", "eps_yy": "boundary strain [-]", "eps_xy": "boundary strain [-]",
    "eps_a": "axial strain -eps_yy [-]", "eps_v": "volumetric strain -tr(E) [-]",
    "eps_q": "shear strain: radius of the strain Mohr circle [-]",
    "sigma_xx_kPa": "wall stress [kPa]", "sigma_yy_kPa": "wall stress [kPa]", "sigma_xy_kPa": "wall stress [kPa]",
    "contact_sigma_xx_kPa": "stress from the contact forces [kPa]", "contact_sigma_yy_kPa": "stress from the "
    "contact forces [kPa]", "contact_sigma_xy_kPa": "stress from the contact forces [kPa]",
    "p_kPa": "mean of the principal wall stresses [kPa]", "q_kPa": "difference of the principal wall stresses [kPa]",
    "stress_ratio": "q / (2 p) [-]", "phi_mob_deg": "mobilised friction angle [deg]",
    "alpha_eps_deg": "direction of the major compressive strain [deg]",
    "alpha_deps_deg": "direction of the major compressive strain increment [deg]",
    "alpha_sigma_deg": "direction of the major compressive stress [deg]",
    "porosity": "areal porosity [-]", "coordination": "mean coordination number [-]",
    "inertial_number": "inertial number of the loading [-]", "steps_per_s": "DEM steps per wall-clock second",
}


def principal_angle_deg(tensor) -> float:
    """Angle (deg, in (-90, 90]) from the y axis of the major compressive direction of a symmetric
    tension-positive 2x2 tensor (= angle from x of its major tensile direction)."""
    t = np.asarray(tensor)
    return float(0.5 * np.degrees(np.arctan2(2.0 * t[0, 1], t[0, 0] - t[1, 1])))


@dataclass
class Run:
    """Result of an experiment: ``history`` (:class:`material.table.Table`), ``final`` state, position snapshots."""

    history: Table
    final: DEMState
    snapshots: list = field(default_factory=list)  # (history row index, positions (N,2), E (2,2))
    meta: dict = field(default_factory=dict)

    @property
    def columns(self) -> tuple:
        return tuple(self.history.columns)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.history[column]

    def snapshot_state(self, k: int) -> DEMState:
        """A lightweight state (positions, radii, walls) of snapshot ``k`` for the fabric analysis."""
        row, pos, E = self.snapshots[k]
        return DEMState(positions=pos, radii=self.final.radii, half_size=self.final.half_size,
                        law=self.final.law, boundary_strain=E)

    def to_csv(self, path) -> Path:
        return self.history.write_csv(path)


def _rereference(state: DEMState) -> None:
    """Make the current wall rectangle the reference (E = 0): strains are measured from here."""
    E = state.boundary_strain
    if abs(E[0, 1]) > 1e-12 or abs(E[1, 0]) > 1e-12:
        raise ValueError("the sample's boundary is sheared; re-referencing needs a rectangular box")
    state.half_size = state.half_size * (1.0 + np.diag(E))
    state.boundary_strain = np.zeros((2, 2))
    state.boundary_rate = np.zeros((2, 2))


class _Recorder:
    def __init__(self, state: DEMState, out: Path | None, snapshot_every: int):
        self.rows: list[dict] = []
        self.snapshots: list = []
        self.out = out
        self.snapshot_every = snapshot_every
        self.last_eps = state.boundary_strain.copy()
        self.t_wall = time.perf_counter()
        self.last_steps = state.steps
        self.fh = None

    def record(self, sim: Simulation, alpha_target: float, rate: float):
        st = sim.state
        E = st.boundary_strain
        sw = measures.stress_from_walls(st)
        sc = measures.stress_from_contacts(st)
        ev = np.linalg.eigvalsh(sw)  # ascending: sigma_1 (most compressive) first
        s1, s3 = -ev[0], -ev[1]
        p = 0.5 * (s1 + s3)
        q = s1 - s3
        eps_v = -(E[0, 0] + E[1, 1])
        eps_q = 0.5 * np.sqrt((E[0, 0] - E[1, 1]) ** 2 + 4 * E[0, 1] ** 2)
        deps = E - self.last_eps
        now = time.perf_counter()
        sps = (st.steps - self.last_steps) / max(now - self.t_wall, 1e-9)
        self.t_wall, self.last_steps = now, st.steps
        row = {
            "step": st.steps, "time_s": st.time, "alpha_target_deg": alpha_target,
            "eps_xx": E[0, 0], "eps_yy": E[1, 1], "eps_xy": E[0, 1], "eps_a": -E[1, 1], "eps_v": eps_v,
            "eps_q": eps_q, "sigma_xx_kPa": sw[0, 0], "sigma_yy_kPa": sw[1, 1], "sigma_xy_kPa": 0.5 * (sw[0, 1] + sw[1, 0]),
            "contact_sigma_xx_kPa": sc[0, 0], "contact_sigma_yy_kPa": sc[1, 1], "contact_sigma_xy_kPa": sc[0, 1],
            "p_kPa": p, "q_kPa": q, "stress_ratio": q / (2 * p) if p > 0 else np.nan,
            "phi_mob_deg": float(np.degrees(np.arcsin(np.clip(q / (2 * p), -1, 1)))) if p > 0 else np.nan,
            "alpha_eps_deg": principal_angle_deg(E) if eps_q > 1e-12 else np.nan,
            "alpha_deps_deg": principal_angle_deg(deps) if np.abs(deps).max() > 0 else np.nan,
            "alpha_sigma_deg": principal_angle_deg(0.5 * (sw + sw.T)),
            "porosity": measures.porosity(st), "coordination": measures.coordination_number(st),
            "inertial_number": measures.inertial_number(rate, st, p), "steps_per_s": sps,
        }
        self.last_eps = E.copy()
        self.rows.append(row)
        if (len(self.rows) - 1) % self.snapshot_every == 0:
            self.snapshots.append((len(self.rows) - 1, st.positions.copy(), E.copy()))
        if self.out is not None:
            if self.fh is None:  # appends after a resume (the file was cut back to the checkpoint)
                self.fh = TableWriter(self.out / "history.csv", title="DEM run", descriptions=DESCRIPTIONS,
                                      convention=CONVENTION, append=True)
            self.fh.write({c: row[c] for c in COLUMNS})
        return row

    def history(self) -> Table:
        return Table({c: np.array([r[c] for r in self.rows]) for c in COLUMNS}, DESCRIPTIONS, title="DEM run",
                     convention=CONVENTION)

    def close(self):
        if self.fh is not None:
            self.fh.close()


def _drive(state: DEMState, segments: list, record_every: int, out, checkpoint_every: int, resume,
           progress: bool, snapshot_every: int, label: str, meta: dict) -> Run:
    """Run the segments; each is (n_steps, rate (2,2) 1/s, servo_xx_kPa or None, alpha_target_deg), or
    for a strain increment whose duration follows the pressure (n_steps None, dE (2,2), None, alpha,
    estimated steps, (inertial number, max rate)). ``record_every`` None: one record per segment."""
    out = Path(out) if out is not None else None
    ckpt = out / "checkpoint.npz" if out is not None else None
    first_segment, first_step = 0, 0
    rows_before: list[dict] = []
    snaps_before: list = []
    if resume:
        if ckpt is None or not ckpt.is_file():
            raise FileNotFoundError(f"--resume: no checkpoint {str(ckpt)!r} to resume from")
        state = load(ckpt)
        info = state.meta["checkpoint"]
        first_segment, first_step = info["segment"], info["step"]
        with np.load(out / "checkpoint_history.npz", allow_pickle=False) as h:
            n_rows = len(h["step"])
            rows_before = [{c: h[c][k].item() for c in COLUMNS} for k in range(n_rows)]
            snaps_before = [(int(h["snap_rows"][k]), h["snap_pos"][k], h["snap_E"][k]) for k in range(len(h["snap_rows"]))]
        # drop the history lines written after the checkpoint (the header: comment lines and the names)
        with (out / "history.csv").open() as fh:
            lines = fh.readlines()
        n_head = next(i for i, ln in enumerate(lines) if not ln.startswith("#")) + 1
        (out / "history.csv").write_text("".join(lines[: n_head + n_rows]))
    elif out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "history.csv").unlink(missing_ok=True)
    sim = Simulation(state)
    rec = _Recorder(state, out, snapshot_every)
    rec.rows, rec.snapshots = rows_before, snaps_before
    if rows_before:
        r = rows_before[-1]
        rec.last_eps = np.array([[r["eps_xx"], r["eps_xy"]], [r["eps_xy"], r["eps_yy"]]])
    estimate = [s[0] if s[0] is not None else s[4] for s in segments]
    total = sum(estimate)
    done = sum(estimate[:first_segment]) + first_step
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=total, initial=done, desc=label, unit="step", smoothing=0.1)
    since_ckpt = 0
    if not resume:
        rec.record(sim, segments[0][3], _rate_norm(segments[0]))
    try:
        for k in range(first_segment, len(segments)):
            n_steps, rate, servo_xx, alpha = segments[k][:4]
            if resume and k == first_segment:
                n_steps = state.meta["checkpoint"]["n_steps"]
                rate = np.asarray(state.meta["checkpoint"]["segment_rate"])
            elif n_steps is None:  # an increment: its duration follows the current pressure (I const)
                n_steps, rate = _adaptive_increment(sim, rate, segments[k][5])
            state.boundary_rate[:] = rate
            sim.set_servo((servo_xx, None) if servo_xx is not None else (None, None),
                          max_rate=max(2.0 * float(np.abs(rate).max()), 1e-6))
            if resume and k == first_segment:
                state.boundary_rate[:] = np.asarray(state.meta["checkpoint"]["rate"])
            step = first_step if k == first_segment else 0
            every = record_every or n_steps
            while step < n_steps:
                todo = min(every - (step % every), n_steps - step)
                sim.advance(todo, checkpoint=ckpt if (ckpt and ckpt.is_file()) else None)
                step += todo
                since_ckpt += todo
                if bar is not None:
                    bar.update(todo)
                if step % every == 0 or step == n_steps:
                    row = rec.record(sim, alpha, float(np.abs(rate).max()))
                    if bar is not None:
                        bar.set_postfix(eps_a=f"{row['eps_a']:.4f}", ratio=f"{row['stress_ratio']:.3f}",
                                        sps=f"{row['steps_per_s']:.3g}")
                if ckpt is not None and since_ckpt >= checkpoint_every:
                    since_ckpt = 0
                    _write_checkpoint(state, ckpt, k, step, rec, n_steps, rate)
    finally:
        rec.close()
        if bar is not None:
            bar.close()
    state.meta.update(meta)
    run = Run(history=rec.history(), final=state, snapshots=rec.snapshots, meta=meta)
    if out is not None:
        save(state, out / "final.npz")
        _save_snapshots(out / "snapshots.npz", rec.snapshots, state.n_particles)
        (out / "run.json").write_text(json.dumps(meta, indent=2, default=str))
    return run


def _save_snapshots(path: Path, snapshots: list, n: int) -> None:
    np.savez(path, rows=np.array([s[0] for s in snapshots], int),
             positions=np.array([s[1] for s in snapshots]) if snapshots else np.zeros((0, n, 2)),
             strains=np.array([s[2] for s in snapshots]) if snapshots else np.zeros((0, 2, 2)))


def load_run(folder) -> Run:
    """A :class:`Run` from its output folder (history.csv, final.npz, snapshots.npz, run.json)."""
    folder = Path(folder)
    for name in ("history.csv", "final.npz"):
        if not (folder / name).is_file():
            raise FileNotFoundError(f"{str(folder)!r} is not a DEM run folder: {name} is missing")
    history = read_table(folder / "history.csv")
    snaps = []
    if (folder / "snapshots.npz").is_file():
        with np.load(folder / "snapshots.npz", allow_pickle=False) as z:
            snaps = [(int(r), p, e) for r, p, e in zip(z["rows"], z["positions"], z["strains"])]
    meta = json.loads((folder / "run.json").read_text()) if (folder / "run.json").is_file() else {}
    return Run(history=history, final=load(folder / "final.npz"), snapshots=snaps, meta=meta)


def _rate_norm(segment) -> float:
    return float(np.abs(segment[1]).max()) if segment[0] is not None else float(segment[5][1])


def _adaptive_increment(sim: Simulation, dE: np.ndarray, control: tuple):
    """Steps and rate of a strain increment dE so that the inertial number stays at its target at
    the current pressure: rate = I d / sqrt(rho / p), capped at the initial rate."""
    inertial, max_rate = control
    p = max(-0.5 * float(np.trace(measures.stress_from_walls(sim.state))), 1.0)
    rate = min(_rate_for_inertial_number(sim.state, p, inertial), max_rate)
    n = max(1, int(round(np.abs(dE).max() / rate / sim.dt)))
    return n, dE / (n * sim.dt)


def _write_checkpoint(state: DEMState, ckpt: Path, segment: int, step: int, rec: _Recorder, n_steps: int,
                      segment_rate: np.ndarray) -> None:
    state.meta["checkpoint"] = {"segment": segment, "step": step, "rate": state.boundary_rate.tolist(),
                                "n_steps": int(n_steps), "segment_rate": np.asarray(segment_rate).tolist()}
    h = rec.history()
    snap_rows = np.array([s[0] for s in rec.snapshots], int)
    snap_pos = np.array([s[1] for s in rec.snapshots]) if rec.snapshots else np.zeros((0, state.n_particles, 2))
    snap_E = np.array([s[2] for s in rec.snapshots]) if rec.snapshots else np.zeros((0, 2, 2))
    tmp = ckpt.with_name("checkpoint_history.tmp.npz")
    np.savez(tmp, snap_rows=snap_rows, snap_pos=snap_pos, snap_E=snap_E, **h.to_dict())
    tmp.replace(ckpt.with_name("checkpoint_history.npz"))
    save(state, ckpt)


def _rate_for_inertial_number(state: DEMState, p_kPa: float, inertial_number: float) -> float:
    d = 2.0 * float(np.mean(state.radii))
    return inertial_number / (d * np.sqrt(state.law.density / (p_kPa * 1e3)))


def biaxial(sample: DEMState, sigma_lateral_kPa: float = 100.0, axial_strain: float = 0.05,
            strain_rate: float | None = None, inertial_number: float = 2e-4, n_records: int = 50,
            out=None, checkpoint_every: int = 100_000, resume: bool = False, progress: bool = False,
            snapshot_every: int = 1) -> Run:
    """Biaxial compression: axial (y) strain-controlled, lateral (x) stress servo-controlled.

    Parameters
    ----------
    sample : DEMState after :func:`dem.isotropic_compression` (not modified)
    sigma_lateral_kPa : lateral stress held by the servo [kPa], compression positive
    axial_strain : final axial strain (compression positive) [-]
    strain_rate : axial strain rate [1/s]; None -> from ``inertial_number`` (quasi-static target)
    n_records : number of history records (and fabric snapshots, every ``snapshot_every``)
    out : folder for history.csv, checkpoint.npz, final.npz (optional); resume=True continues from it
    """
    if not (np.isfinite(sigma_lateral_kPa) and sigma_lateral_kPa > 0):
        raise ValueError(f"sigma_lateral_kPa={sigma_lateral_kPa!r}: must be positive (compression positive)")
    if not (0 < axial_strain < 0.5):
        raise ValueError(f"axial_strain={axial_strain!r}: must lie in (0, 0.5)")
    state = sample.copy()
    _rereference(state)
    rate = strain_rate or _rate_for_inertial_number(state, sigma_lateral_kPa, inertial_number)
    sim_dt = Simulation(state).dt
    n_steps = int(round(axial_strain / rate / sim_dt))
    record_every = max(1, n_steps // n_records)
    Edot = np.array([[0.0, 0.0], [0.0, -rate]])
    meta = {"experiment": "biaxial", "sigma_lateral_kPa": sigma_lateral_kPa, "axial_strain": axial_strain,
            "strain_rate": rate, "dt": sim_dt, "seed": sample.meta.get("seed"), "version": _version()}
    return _drive(state, [(n_steps, Edot, -sigma_lateral_kPa, 0.0)], record_every, out, checkpoint_every,
                  resume, progress, snapshot_every, "biaxial", meta)


def strain_at(alpha_deg: float, eps_v: float, eps_q: float) -> np.ndarray:
    """Eq. 3.10 (compression positive eps_v, eps_q) returned tension positive as the boundary map E."""
    a = np.radians(alpha_deg)
    c2, s2 = np.cos(2 * a), np.sin(2 * a)
    return np.array([[-0.5 * eps_v + eps_q * c2, eps_q * s2], [eps_q * s2, -0.5 * eps_v - eps_q * c2]])


def rotate_strain(state: DEMState, eps_q: float | None = None, rotation_deg: float = 90.0,
                  increment_deg: float = 1.0, strain_rate: float | None = None, inertial_number: float = 2e-4,
                  records_per_increment: int = 1, out=None, checkpoint_every: int = 100_000,
                  resume: bool = False, progress: bool = False, snapshot_every: int = 5) -> Run:
    """Rotate the principal strain axes at constant eps_v and eps_q (eq. 3.10; Appendix D kinematics).

    The strain measured from the reference box is driven through ``alpha_eps = 0 .. rotation_deg`` in
    increments ``increment_deg``; each increment prescribes the boundary velocity
    ``(eps(alpha_i+1) - eps(alpha_i)) / t_i`` (D.4: the walls translate and rotate with the affine
    map), with ``t_i`` chosen at the start of the increment so that the inertial number at the
    current pressure equals ``inertial_number`` (the pressure changes a lot at constant volume);
    ``strain_rate`` caps the rate. One history record per increment. ``eps_q`` defaults to the state's current value (then the path starts where the biaxial test
    ended); otherwise the deviator is first ramped to ``eps_q`` at alpha = 0.
    """
    if not (np.isfinite(rotation_deg) and 0 < rotation_deg <= 360):
        raise ValueError(f"rotation_deg={rotation_deg!r}: must lie in (0, 360]")
    state = state.copy()
    E0 = state.boundary_strain
    if abs(E0[0, 1]) > 1e-12:
        raise ValueError("rotate_strain starts from a biaxial state (principal strain axes along x, y)")
    ev0 = -(E0[0, 0] + E0[1, 1])
    eq0 = 0.5 * (E0[0, 0] - E0[1, 1])
    eps_q = eq0 if eps_q is None else float(eps_q)
    if not eps_q > 0:
        raise ValueError(f"eps_q={eps_q!r}: must be positive (run a biaxial compression first)")
    p_kPa = -0.5 * float(np.trace(measures.stress_from_walls(state))) or 100.0
    rate = strain_rate or _rate_for_inertial_number(state, max(p_kPa, 1.0), inertial_number)
    dt = Simulation(state).dt
    segments = []
    if abs(eps_q - eq0) > 1e-9:
        target = strain_at(0.0, ev0, eps_q)
        n = max(1, int(round(np.abs(target - E0).max() / rate / dt)))
        segments.append((n, (target - E0) / (n * dt), None, 0.0))
    alphas = np.arange(0.0, rotation_deg + 1e-9, increment_deg)
    if alphas[-1] < rotation_deg - 1e-9:
        alphas = np.append(alphas, rotation_deg)
    for a0, a1 in zip(alphas[:-1], alphas[1:]):
        dE = strain_at(a1, ev0, eps_q) - strain_at(a0, ev0, eps_q)
        estimate = max(1, int(round(np.abs(dE).max() / rate / dt)))
        segments.append((None, dE, None, float(a1), estimate, (inertial_number, rate)))
    meta = {"experiment": "rotate_strain", "eps_v": ev0, "eps_q": eps_q, "rotation_deg": rotation_deg,
            "increment_deg": increment_deg, "strain_rate": rate, "dt": dt, "seed": state.meta.get("seed"),
            "version": _version()}
    return _drive(state, segments, None, out, checkpoint_every, resume, progress, snapshot_every,
                  "rotation", meta)


def _version() -> str:
    """The installed distribution's version (dem never imports the FE package for it)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("femgran")
    except PackageNotFoundError:  # a source tree that is not installed
        return "0.1.0+src"
