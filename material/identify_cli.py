"""``femgran identify ...``: identify CPA parameters from laboratory data (:mod:`material.identify`).

Examples::

    femgran identify direct-shear fig8 --out out/identify_ds            # the shipped Fig. 8 envelopes
    femgran identify direct-shear envelopes.csv --order 2 --no-cohesion
    femgran identify triaxial p50.csv p100.csv --p0 50 100 --alpha 0 --out out/identify_tx
    femgran identify triaxial lab.csv --alpha 90 --free A,E,nu,eta_c_ratio --params out/identify_ds/parameters.toml

Every run writes into ``--out`` (default ``out/identify``): ``parameters.toml`` (the identified
values in the base set, with the fit recorded in its metadata), ``fit.csv`` (data, fitted values,
residuals), ``curve.csv`` (the fitted curves), ``fit.png`` and ``run.json``; the identified values
with their 95 % confidence intervals are printed. File formats: ``docs/identification.md``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from material.commandline import (add_out, add_parameters, add_progress, parameters_from_args, parse_set,
                                  write_run_record)

__all__ = ["register"]


def register(subparsers) -> None:
    """Add ``femgran identify direct-shear|triaxial ...`` to the top-level parser."""
    ident = subparsers.add_parser(
        "identify",
        help="identify CPA parameters from laboratory data (material.identify)",
        description="Least-squares identification of CPA parameters; writes parameters.toml, fit.csv, "
                    "curve.csv, fit.png and run.json into --out.",
    )
    kinds = ident.add_subparsers(dest="kind", metavar="DATA")
    kinds.required = True

    ds = kinds.add_parser("direct-shear", help="friction and cohesion series from direct-shear Coulomb envelopes",
                          description="Fit eta_f(alpha) (eq. 2.20) to the envelope slopes and c(alpha) (eq. 2.4) "
                                      "to the intercepts.")
    ds.add_argument("envelopes", metavar="ENVELOPES",
                    help="CSV with columns alpha_deg, slope, intercept_kPa ('#' lines are comments), or 'fig8' for "
                         "the thesis's Fig. 8 envelopes shipped with the package")
    ds.add_argument("--order", type=int, default=3,
                    help="highest power of x in eta_f = eta0 (1 + x + a1 x^2 + ...) (default 3: eta0, omega1, a1, a2; "
                         "Table 3 is order 4)")
    ds.add_argument("--cohesion-order", type=int, default=None,
                    help="highest power in the cohesion series (default: chosen by an F test, at most --order)")
    ds.add_argument("--no-cohesion", dest="cohesion", action="store_false",
                    help="keep c0, omega1_c, b of the base set (the thesis takes c = 0)")
    _common(ds)
    ds.set_defaults(func=_run_direct_shear)

    tx = kinds.add_parser("triaxial", help="hardening/elastic/dilatancy constants from measured curves",
                          description="Least squares over element simulations of drained triaxial, direct-shear or "
                                      "mixed-path curves, all fitted jointly.")
    tx.add_argument("curves", metavar="CURVES", nargs="+",
                    help="CSV files: eps_a,q_kPa,eps_v (triaxial, compression +), shear_displacement_m,tau_kPa,"
                         "normal_displacement_m (direct shear), or sig_<c>_kPa/eps_<c> columns (path, tension +)")
    tx.add_argument("--p0", type=float, nargs="+", default=None,
                    help="cell pressure(s) [kPa] of triaxial curves: one for all or one per file (else '# p0_kPa: ...' "
                         "in the file)")
    tx.add_argument("--alpha", type=float, nargs="+", default=None,
                    help="deposition angle(s) [deg]: one for all or one per file (else '# alpha_deg: ...')")
    tx.add_argument("--sigma-n", dest="sigma_n", type=float, nargs="+", default=None,
                    help="normal stress(es) [kPa] of direct-shear curves (else '# sigma_n_kPa: ...')")
    tx.add_argument("--free", default="A,E,nu,eta_c_ratio",
                    help="comma-separated constants to identify (default A,E,nu,eta_c_ratio; zeta joins when a curve "
                         "softens)")
    tx.add_argument("--start", metavar="KEY=VALUE", action="append", default=[],
                    help="start value of a free constant (repeatable; default the base set's)")
    tx.add_argument("--control", default=None,
                    help="path curves: comma-separated prescribed columns where a component has both (default eps_zz "
                         "and the other stresses)")
    tx.add_argument("--steps", type=int, default=40,
                    help="simulation resolution: steps to the largest strain (default 40)")
    tx.add_argument("--softening-drop", type=float, default=0.05,
                    help="drop after the peak (fraction) that counts as softening (default 0.05)")
    tx.add_argument("--no-auto-zeta", dest="auto_zeta", action="store_false",
                    help="do not add zeta to the free constants when a curve softens")
    tx.add_argument("--max-nfev", type=int, default=60, help="optimiser iterations (default 60)")
    _common(tx)
    tx.set_defaults(func=_run_triaxial)


def _common(p) -> None:
    g = p.add_argument_group("base parameters and output")
    add_parameters(g, preset_default="ottawa_c109")
    add_out(g, "out/identify")
    add_progress(g)


def _command(args) -> str:
    argv = getattr(args, "_argv", None)
    return "femgran " + " ".join(sys.argv[1:] if argv is None else argv)


def _finish(args, ident, t0: float, **extra) -> int:
    out = Path(args.out)
    paths = ident.write(out, command=_command(args))
    write_run_record(out, args, identification=ident.kind, seed=None, deterministic=True,
                     wall_time_s=round(time.perf_counter() - t0, 3), files=[p.name for p in paths.values()],
                     names=list(ident.names), values=ident.values.tolist(), rms=ident.rms, r2=ident.r2, **extra)
    print(f"femgran identify {args.kind}: -> {out}/ ({', '.join(p.name for p in paths.values())}, run.json)")
    print(ident.summary())
    for msg in ident.info.get("warnings", []):
        print(f"  note: {msg}")
    return 0


def _run_direct_shear(args) -> int:
    from material.identify import direct_shear

    t0 = time.perf_counter()
    base = parameters_from_args(args)
    ident = direct_shear(args.envelopes, preset=base, order=args.order, cohesion_order=args.cohesion_order,
                         fit_cohesion=args.cohesion)
    return _finish(args, ident, t0)


def _run_triaxial(args) -> int:
    from material.identify import triaxial

    t0 = time.perf_counter()
    base = parameters_from_args(args)
    start = parse_set(args.start)
    bad = {k: v for k, v in start.items() if isinstance(v, list)}
    if bad:
        raise ValueError(f"--start {bad}: give one number per constant")
    ident = triaxial(args.curves, preset=base, free=args.free, start=start, p0_kPa=args.p0, alpha_deg=args.alpha,
                     sigma_n_kPa=args.sigma_n, control=args.control, steps=args.steps,
                     softening_drop=args.softening_drop, auto_zeta=args.auto_zeta, max_nfev=args.max_nfev,
                     progress=args.progress)
    return _finish(args, ident, t0, simulations=ident.info["simulations"])
