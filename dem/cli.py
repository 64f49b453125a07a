"""``femgran dem generate|biaxial|rotate|sweep|fabric`` and ``femgran calibrate``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from material.commandline import add_out, add_progress, write_run_record

def register(subparsers) -> None:
    """Add the DEM subcommands to the ``femgran`` parser."""
    p = subparsers.add_parser("dem", help="2D DEM virtual experiments (thesis chapter 3)",
                              description="Numba 2D DEM: sample generation, biaxial, strain rotation, fabric, Table 4 sweep.")
    sub = p.add_subparsers(dest="dem_command", metavar="DEM_COMMAND")
    sub.required = True

    g = sub.add_parser("generate", help="generate a sample (Appendix A) and compress it to p")
    g.add_argument("--n", type=int, default=400, help="number of disks (thesis: 4000)")
    g.add_argument("--psd", default="ottawa_c109", help="PSD preset or CSV (diameter_mm, percent_finer)")
    g.add_argument("--seed", type=int, default=1)
    g.add_argument("--width-mm", type=float, default=None)
    g.add_argument("--height-mm", type=float, default=None)
    g.add_argument("--test", default="T05", help="Table 4 test whose contact law to use (default T05)")
    g.add_argument("--p-kpa", type=float, default=100.0, help="isotropic pressure; 0 = stop after generation")
    add_out(g, "out/dem/sample.npz", help="sample file (.npz; default out/dem/sample.npz)")
    add_progress(g)
    g.set_defaults(func=_generate)

    b = sub.add_parser("biaxial", help="biaxial compression at constant lateral stress")
    b.add_argument("sample", type=Path, help="state .npz after isotropic compression")
    b.add_argument("--axial-strain", type=float, default=0.05)
    b.add_argument("--lateral-kpa", type=float, default=100.0)
    b.add_argument("--inertial-number", type=float, default=2e-4, help="sets the strain rate (quasi-static < 1e-3)")
    b.add_argument("--records", type=int, default=60)
    _run_options(b, "out/dem/biaxial")
    b.set_defaults(func=_biaxial)

    r = sub.add_parser("rotate", help="rotation of the principal strain axes at constant eps_v, eps_q (eq. 3.10)")
    r.add_argument("state", type=Path, help="final.npz of a biaxial run, or its folder")
    r.add_argument("--rotation-deg", type=float, default=90.0)
    r.add_argument("--increment-deg", type=float, default=1.0)
    r.add_argument("--eps-q", type=float, default=None, help="default: the state's current eps_q")
    r.add_argument("--inertial-number", type=float, default=2e-4)
    _run_options(r, "out/dem/rotation")
    r.set_defaults(func=_rotate)

    f = sub.add_parser("fabric", help="stereological fabric of a state (Section 3.4.1)")
    f.add_argument("state", type=Path, help="state .npz or a run folder (uses final.npz)")
    f.add_argument("--measure", default="areal_porosity", choices=("areal_porosity", "mil"))
    f.add_argument("--spacing-um", type=float, default=5.0, help="test-line spacing d [micrometre]")
    f.add_argument("--out", type=Path, default=None, help="CSV of the directional values")
    f.set_defaults(func=_fabric)

    s = sub.add_parser("sweep", help="Table 4 (N1-N3, T01-T07) on the sweep engine (resumable): runs, CSVs, Figs. 23-34 and "
                                          "38-44, calibration")
    add_out(s, "out/dem/sweep")
    add_progress(s)
    s.add_argument("--tests", default=None, help="comma-separated ids (default: all of Table 4)")
    s.add_argument("--full", action="store_true", help="the thesis's particle numbers (slow)")
    s.add_argument("--scale", type=float, default=0.1, help="fraction of the thesis's N when not --full")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local Dask cluster (default: the machine's cores)")
    s.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler; 'serial' runs in this process")
    s.add_argument("--axial-strain", type=float, default=0.05)
    s.add_argument("--rotation-deg", type=float, default=90.0)
    s.set_defaults(func=_sweep)

    c = subparsers.add_parser("calibrate", help="fit beta (3.15) and alpha_hat, beta_hat (3.8) from DEM runs",
                              description="Calibrate the induced-anisotropy constants from DEM run folders and "
                                          "write a parameter file that material.load_parameters reads.")
    c.add_argument("runs", nargs="+", type=Path, help="run folders (biaxial/, rotation/ or a Table 4 test folder)")
    add_out(c, "out/dem/calibrated.toml", help="parameter file written (default out/dem/calibrated.toml)")
    c.add_argument("--measure", default="mil", choices=("mil", "areal_porosity"))
    c.add_argument("--preset", default="ottawa_c109_induced")
    c.set_defaults(func=_calibrate)


def _run_options(p, default_out):
    add_out(p, default_out)
    p.add_argument("--resume", action="store_true", help="continue from out/checkpoint.npz")
    p.add_argument("--checkpoint-every", type=int, default=100_000, help="steps between checkpoints")
    add_progress(p)


def _state_path(path: Path) -> Path:
    return path / "final.npz" if path.is_dir() else path


def _generate(args) -> int:
    import dem
    from dem.sweep import law_of

    law = law_of(args.test)
    w = args.width_mm * 1e-3 if args.width_mm else None
    h = args.height_mm * 1e-3 if args.height_mm else None
    state = dem.generate(args.n, psd=args.psd, width_m=w, height_m=h, seed=args.seed, law=law, progress=args.progress)
    if args.p_kpa > 0:
        state = dem.isotropic_compression(state, p_kPa=args.p_kpa, law=law)
    dem.save(state, args.out)
    write_run_record(args.out, args, seed=args.seed)
    print(f"{args.out}: {state.n_particles} disks, porosity {dem.porosity(state):.4f}, "
          f"Z {dem.coordination_number(state):.2f}, wall stress {np.diag(dem.stress_from_walls(state)).round(2)} kPa")
    return 0


def _biaxial(args) -> int:
    import dem

    run = dem.biaxial(dem.load(args.sample), sigma_lateral_kPa=args.lateral_kpa, axial_strain=args.axial_strain,
                      inertial_number=args.inertial_number, n_records=args.records, out=args.out,
                      checkpoint_every=args.checkpoint_every, resume=args.resume, progress=args.progress)
    write_run_record(args.out, args)
    print(f"{args.out}: eps_a {run['eps_a'][-1]:.4f}, peak phi_mob {np.nanmax(run['phi_mob_deg']):.1f} deg, "
          f"max inertial number {np.nanmax(run['inertial_number']):.2e}")
    return 0


def _rotate(args) -> int:
    import dem

    run = dem.rotate_strain(dem.load(_state_path(args.state)), eps_q=args.eps_q, rotation_deg=args.rotation_deg,
                            increment_deg=args.increment_deg, inertial_number=args.inertial_number, out=args.out,
                            checkpoint_every=args.checkpoint_every, resume=args.resume, progress=args.progress)
    write_run_record(args.out, args)
    lead = (run["alpha_sigma_deg"] - run["alpha_eps_deg"] + 90) % 180 - 90
    print(f"{args.out}: rotated {args.rotation_deg} deg; mean alpha_sigma - alpha_eps {np.nanmean(lead[1:]):.1f} deg, "
          f"max inertial number {np.nanmax(run['inertial_number']):.2e}")
    return 0


def _fabric(args) -> int:
    import dem
    from material.table import Table

    state = dem.load(_state_path(args.state))
    fab = dem.fabric(state, measure=args.measure, grid_spacing_m=args.spacing_um * 1e-6)
    print(f"{args.measure}: mean {fab.mean:.6g}; porosity from disk areas {dem.porosity(state):.4f}")
    for order in (1, 2, 3):
        fit = fab.fit(order)
        print(f"  order {order}: C {fit.C:.6g}, Omega [[{fit.omega[0, 0]:.4g}, {fit.omega[0, 1]:.4g}], ...], "
              f"a {np.round(fit.a, 4).tolist()}, rms {fit.rms:.3g}, principal direction {fit.principal_angle_deg:.1f} deg")
    e = state.boundary_strain - 0.5 * np.trace(state.boundary_strain) * np.eye(2)
    if np.abs(e).max() > 0:
        print(f"  delta (Omega vs strain deviator) {dem.delta_deg(fab.omega, e):.2f} deg")
    cf = dem.contact_fabric(state)
    print(f"  contact-normal fabric phi = [[{cf[0, 0]:.4f}, {cf[0, 1]:.4f}], [{cf[1, 0]:.4f}, {cf[1, 1]:.4f}]]")
    if args.out:
        Table({"direction_deg": fab.directions_deg, "value": fab.values, "void_length_m": fab.void_length,
               "line_length_m": fab.line_length, "n_intercepts": fab.n_intercepts},
              title=f"DEM fabric ({args.measure}) by test-line direction").write_csv(args.out)
        print(f"wrote {args.out}")
    return 0


def _sweep(args) -> int:
    from dem.sweep import TABLE4, sweep

    tests = args.tests.split(",") if args.tests else None
    summary = sweep(args.out, tests=tests, full=args.full, scale=args.scale, seed=args.seed, workers=args.workers,
                    scheduler=args.scheduler,
                    axial_strain=args.axial_strain, rotation_deg=args.rotation_deg, progress=args.progress)
    for s in summary:
        print(json.dumps(s))
    missing = len(tests or TABLE4) - len(summary)
    if not summary:
        print(f"no Table 4 test completed; see {args.out / 'sweep.json'}")
        return 1
    from dem.calibrate import calibrate
    from dem.experiments import load_run

    runs = []
    for s in summary:
        runs += [load_run(args.out / s["test"] / "biaxial"), load_run(args.out / s["test"] / "rotation")]
    cal = calibrate(runs)
    path = cal.write(args.out / "calibrated.toml", tests=[s["test"] for s in summary], seed=args.seed)
    print(f"calibration: beta {cal.beta:.4g} (95% {cal.beta_ci95[0]:.3g}..{cal.beta_ci95[1]:.3g}), "
          f"alpha_hat {cal.alpha_hat:.3f}, delta {cal.delta_mean_deg:.2f} +- {cal.delta_std_deg:.2f} deg -> {path}")
    write_run_record(args.out, args, seed=args.seed, calibration=str(path))
    print(f"figures in {args.out / 'figures'}")
    return 1 if missing else 0


def _calibrate(args) -> int:
    from dem.calibrate import calibrate
    from dem.experiments import load_run

    runs = []
    for folder in args.runs:
        if (folder / "biaxial").is_dir():
            runs.append(load_run(folder / "biaxial"))
            if (folder / "rotation").is_dir():
                runs.append(load_run(folder / "rotation"))
        else:
            runs.append(load_run(folder))
    cal = calibrate(runs, measure=args.measure)
    path = cal.write(args.out, preset=args.preset, runs=[str(r) for r in args.runs])
    write_run_record(args.out, args)
    print(f"beta = {cal.beta:.4g} (95% {cal.beta_ci95[0]:.3g}..{cal.beta_ci95[1]:.3g}); alpha_hat = {cal.alpha_hat:.3f} "
          f"(signed {cal.alpha_signed:+.3f}); beta_hat = 0 (not identifiable in 2D); delta = "
          f"{cal.delta_mean_deg:.2f} +- {cal.delta_std_deg:.2f} deg over {cal.n_states} states -> {path}")
    return 0
