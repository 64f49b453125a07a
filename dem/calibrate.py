"""Calibration of the induced-anisotropy evolution law from DEM runs (eqs. 3.8, 3.9, 3.15).

Procedure (documented in the parameter file's metadata as well):

1. For every fabric snapshot of the runs (biaxial and rotation), compute the fabric tensor Omega
   (first-order Kanatani fit, eq. 3.6) of the chosen measure and the strain deviator ``e`` (2D,
   tension positive, measured from the start of the biaxial stage). States with ``|e| < e_min`` are
   skipped (their direction is undefined).
2. Coaxial law (3.8): least squares of ``n^Omega = alpha n^e + beta dev(n^e n^e)`` over all states.
   In 2D ``n^e n^e = I / 2`` for a traceless symmetric ``n^e``, so the second term vanishes identically:
   ``beta_hat`` cannot be identified from 2D runs and is written as 0 (the linear form 3.9);
   ``alpha = <n^Omega : n^e>`` measures coaxiality (|alpha| = 1: perfectly coaxial). Its sign says
   whether the fabric's major axis follows the major extension (+) or the major compression (-).
   The parameter file receives ``alpha_hat = |alpha|`` (the model normalises n^Omega, so with
   ``beta_hat = 0`` only the direction matters) and the signed value in the metadata.
3. beta of Lambda = beta e (3.15): the thesis chose it "on a purely intuitive basis"; we measure it as
   the least-squares slope of the *induced* fabric against the strain deviator,
   ``beta = sign(alpha) * sum((Omega - Omega_0) : e) / sum(e : e)`` (Omega_0: the fabric at the start
   of shearing, inherited from the generation), i.e. we identify the bias tensor of the strength
   distribution with the induced fabric bias, measured by the same Kanatani representation (3.6 and
   3.14 have the same form). The 95 % interval of the slope is reported too.

The parameter file starts from ``material.load_preset("ottawa_c109_induced")`` and is written with
``material.parameters.save_parameters``; ``material.load_parameters`` reads it back.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .experiments import Run, _version
from .stereology import delta_deg, fabric


def _dev(t):
    return t - 0.5 * np.trace(t) * np.eye(2)


def fabric_series(run: Run, measure: str = "mil", grid_spacing_m: float = 1e-5) -> dict:
    """Fabric along a run: one row per snapshot (history row, strain, Omega, delta, ...)."""
    rows = {k: [] for k in ("row", "eps_q", "alpha_eps_deg", "C", "omega_xx", "omega_xy", "alpha_omega_deg",
                            "delta_deg", "mean")}
    for k in range(len(run.snapshots)):
        state = run.snapshot_state(k)
        fab = fabric(state, measure=measure, grid_spacing_m=grid_spacing_m)
        fit = fab.fit(1)
        E = state.boundary_strain
        row = run.snapshots[k][0]
        rows["row"].append(row)
        rows["eps_q"].append(float(run["eps_q"][row]))
        rows["alpha_eps_deg"].append(float(run["alpha_eps_deg"][row]))
        rows["C"].append(fit.C)
        rows["omega_xx"].append(fit.omega[0, 0])
        rows["omega_xy"].append(fit.omega[0, 1])
        rows["alpha_omega_deg"].append(fit.principal_angle_deg)
        rows["delta_deg"].append(delta_deg(fit.omega, E) if np.abs(_dev(E)).max() > 1e-9 else np.nan)
        rows["mean"].append(fab.mean)
    return {k: np.asarray(v, float) for k, v in rows.items()}


@dataclass
class Calibration:
    """Result of :func:`calibrate`: the constants and the data they were fitted to."""

    beta: float
    beta_ci95: tuple
    alpha_signed: float
    alpha_hat: float
    beta_hat: float
    delta_mean_deg: float
    delta_std_deg: float
    n_states: int
    measure: str
    omega: np.ndarray = field(repr=False)
    strain_dev: np.ndarray = field(repr=False)

    def parameters(self, preset: str = "ottawa_c109_induced"):
        """The preset with the calibrated beta, alpha_hat, beta_hat (a ``material.CPAParameters``)."""
        from material import load_preset

        return load_preset(preset).replace(beta=self.beta, alpha_hat=self.alpha_hat, beta_hat=self.beta_hat)

    def write(self, path, preset: str = "ottawa_c109_induced", **metadata) -> Path:
        from material.parameters import save_parameters

        meta = {
            "source": "dem.calibrate", "measure": self.measure, "n_states": self.n_states,
            "beta_ci95": list(self.beta_ci95), "alpha_signed": self.alpha_signed,
            "delta_mean_deg": self.delta_mean_deg, "delta_std_deg": self.delta_std_deg,
            "procedure": ("Omega: 1st-order Kanatani fit (3.6) of the fabric measure at each snapshot; "
                          "alpha_hat = |<n^Omega : n^e>| (3.8; beta_hat not identifiable in 2D since "
                          "dev(n^e n^e) = 0); beta = slope of (Omega - Omega_0) against e through the origin "
                          "(3.15), sign from alpha"),
        }
        meta.update(metadata)
        meta.setdefault("version", _version())
        return save_parameters(self.parameters(preset), path, **meta)


def calibrate(runs, measure: str = "mil", grid_spacing_m: float = 1e-5, e_min: float = 1e-3) -> Calibration:
    """Fit alpha_hat, beta_hat (3.8) and beta (3.15) from DEM runs with fabric snapshots.

    Parameters
    ----------
    runs : list of :class:`dem.Run` (a biaxial run first, optionally followed by its rotation run;
        several samples may be given, each biaxial run starting a new group)
    measure : fabric measure "mil" (default; see below) or "areal_porosity"
    grid_spacing_m : test-line spacing [m]
    e_min : smallest strain-deviator norm used [-]

    Notes
    -----
    With a circular domain and a uniform grid of lines, sum I / l in any direction estimates the
    area porosity (Delesse/Rosiwal: L_L = A_A), so the areal-porosity Omega of 2D samples is only
    sampling noise; MIL (3.1) carries the directional information and is the default.
    """
    if not runs:
        raise ValueError("calibrate: no runs given")
    omegas, strains = [], []
    omega0 = None
    for run in runs:
        if not run.snapshots:
            raise ValueError(f"calibrate: run {run.meta.get('experiment', '?')!r} has no fabric snapshots")
        if run.meta.get("experiment") != "rotate_strain" or omega0 is None:
            omega0 = fabric(run.snapshot_state(0), measure=measure, grid_spacing_m=grid_spacing_m).fit(1).omega
        for k in range(len(run.snapshots)):
            state = run.snapshot_state(k)
            e = _dev(state.boundary_strain)
            if np.sqrt(np.sum(e * e)) < e_min:
                continue
            om = fabric(state, measure=measure, grid_spacing_m=grid_spacing_m).fit(1).omega
            omegas.append((om, om - omega0))
            strains.append(e)
    if len(strains) < 2:
        raise ValueError(f"calibrate: only {len(strains)} states with |e| >= {e_min}; run longer experiments")
    om = np.array([o[0] for o in omegas])
    d_om = np.array([o[1] for o in omegas])
    e = np.array(strains)
    norm = lambda t: np.sqrt(np.einsum("kij,kij->k", t, t))[:, None, None]
    n_om, n_e = om / norm(om), e / norm(e)
    alpha = float(np.mean(np.einsum("kij,kij->k", n_om, n_e)))  # least squares of n^Om = alpha n^e (3.9)
    sign = 1.0 if alpha >= 0 else -1.0
    ee = np.einsum("kij,kij->k", e, e)
    de = np.einsum("kij,kij->k", d_om, e)
    slope = float(np.sum(de) / np.sum(ee))  # eq. 3.15: Omega - Omega_0 = beta e
    resid = d_om - slope * e
    dof = max(1, 3 * len(e) - 1)
    s2 = float(np.sum(resid * resid)) / dof
    se = np.sqrt(s2 / np.sum(ee))
    beta = sign * slope
    deltas = np.array([delta_deg(o, s) for o, s in zip(om, e)])
    return Calibration(beta=max(beta, 0.0), beta_ci95=(beta - 1.96 * se, beta + 1.96 * se),
                       alpha_signed=alpha, alpha_hat=abs(alpha), beta_hat=0.0,
                       delta_mean_deg=float(np.mean(deltas)), delta_std_deg=float(np.std(deltas)),
                       n_states=len(e), measure=measure, omega=om, strain_dev=e)
