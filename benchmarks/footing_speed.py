"""CPA footing against the Drucker-Prager footing on the same mesh: wall time, steps, Newton iterations.

The strip footing of ``femgran.cases.footing`` (rough, B = 1 m, gamma = 18 kN/m^3, no surcharge unless asked, to
s = 0.1 B in 40 nominal steps) on the default mesh, four soils:

* ``drucker-prager``: the plane-strain-matched cone, c = 0, phi = 30 deg, associated (the baseline);
* ``mohr-coulomb``: the same friction angle with the edges and apex of Mohr-Coulomb (a reference with corners);
* ``cpa-isotropic``: the CPA law as the same Mohr-Coulomb solid (isotropic eta = tan 30 deg,
  associated at failure: eta_c = 0, fast hardening A = 1e-5 m);
* ``cpa-thesis``: the thesis sand ``ottawa_c109`` at alpha = 0, with every option at its default;
* ``cpa-thesis-stabilised``: the same with the local step stabilisation of ``CPAModel``;
* ``cpa-thesis-wide-fade``: the same without the stabilisation, its compaction fading below
  ``--compaction-stress`` (default 20 kPa) instead of 2 kPa: a change of the law (``docs/cpa_law.md``,
  section 4).

Each run is timed in this process, after a warm-up that compiles the kernels; the ratio to the
Drucker-Prager time is printed (target <= 5), and the material evaluations a law needs beyond the cone's:
for the CPA law that excess hardly changes with ``--steps`` (the events of the run: a point's loading planes
changing while the mechanism forms), where the iterations per step do. Runs that share the cores disturb each other: run it on an
idle machine, one numba thread (``NUMBA_NUM_THREADS=1``) for a per-core figure.

``--profile`` runs each footing under ``cProfile`` and splits its time between the material update (every
point, every global iterate and line-search trial), the linear solves, the assembly (stiffness, internal
force, strains), the Newton log with its diagnostics, and the rest (these runs write no files). The ratio
to the cone is the product of two factors, the material evaluations and the cost of each; the split says
which one a change should aim at. The profiler slows the Python parts: take the split, not the times, from
such a run.

    python benchmarks/footing_speed.py [--E 6000] [--resolution 3] [--surcharge 0] [--soils cpa-isotropic ...]
                                       [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

import numpy as np


def _material(name: str, E: float, stabilisation: float, compaction_stress: float = 20.0):
    from material import CPAModel, DruckerPrager, MohrCoulomb, load_preset
    from material.factory import plane_strain_axes

    if name == "drucker-prager":
        return DruckerPrager(E, 0.3, cohesion_kPa=0.0, friction_deg=30.0)
    if name == "mohr-coulomb":
        return MohrCoulomb(E, 0.3, cohesion_kPa=0.0, friction_deg=30.0)
    if name == "cpa-isotropic":
        p = load_preset("ottawa_c109").replace(omega1=0.0, eta0=float(np.tan(np.radians(30.0))), eta_c_ratio=0.0,
                                               A=1e-5, E=E)
        return CPAModel(p, axes=plane_strain_axes(0.0))
    p = load_preset("ottawa_c109").replace(E=E)
    if name == "cpa-thesis-wide-fade":
        p = p.replace(compaction_stress=compaction_stress)
    mu = stabilisation if name == "cpa-thesis-stabilised" else 0.0
    return CPAModel(p, axes=plane_strain_axes(0.0), stabilisation=mu)


#: Where a footing's time goes (``--profile``): each part is the cumulative time of these functions, named by
#: (path suffix, function name); they do not call one another.
PARTS = {
    "material update": [("femgran/state.py", "evaluate")],
    "linear solves": [("femgran/solver.py", "_solve_free")],
    "assembly": [("femgran/assembly.py", "stiffness"), ("femgran/assembly.py", "internal_force"),
                 ("femgran/assembly.py", "strain")],
    "Newton log": [("femgran/diagnostics.py", "record"), ("femgran/diagnostics.py", "full_step_overshoot")],
}


def time_split(profile: cProfile.Profile, total: float) -> dict:
    """The seconds of each of :data:`PARTS` in a profiled run, and the rest of ``total``."""
    stats = pstats.Stats(profile).stats  # {(file, line, name): (calls, primitive calls, tottime, cumtime, callers)}
    split = {}
    for part, functions in PARTS.items():
        split[part] = sum(entry[3] for (path, _line, name), entry in stats.items()
                          if any(path.replace("\\", "/").endswith(suffix) and name == fn for suffix, fn in functions))
    split["rest"] = total - sum(split.values())
    return split


def timed_footing(material, profile: bool = False, **kwargs):
    """``femgran.cases.footing(material, plots=False, **kwargs)`` timed: (solution, wall time [s], split), the
    split of :func:`time_split` with ``profile`` (the run under ``cProfile``), else None."""
    from femgran.cases import footing

    profiler = cProfile.Profile() if profile else None
    t0 = time.perf_counter()
    if profiler is not None:
        profiler.enable()
    sol = footing(material, plots=False, **kwargs)
    wall = time.perf_counter() - t0
    if profiler is None:
        return sol, wall, None
    profiler.disable()
    return sol, wall, time_split(profiler, wall)


SOILS = ("drucker-prager", "mohr-coulomb", "cpa-isotropic", "cpa-thesis", "cpa-thesis-stabilised",
         "cpa-thesis-wide-fade")


def main(argv=None) -> None:
    from femgran.cases import footing

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--E", type=float, default=6000.0, help="Young's modulus of every soil [kPa]")
    ap.add_argument("--resolution", type=int, default=3)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--stabilisation", type=float, default=0.1, help="mu of cpa-thesis-stabilised")
    ap.add_argument("--compaction-stress", type=float, default=20.0,
                    help="p_c of cpa-thesis-wide-fade [kPa] (the law's default is 2)")
    ap.add_argument("--soils", nargs="+", default=list(SOILS), choices=SOILS)
    ap.add_argument("--surcharge", type=float, default=0.0, help="on the surface beside the footing [kPa]")
    ap.add_argument("--profile", action="store_true", help="split each run's time by part (cProfile)")
    args = ap.parse_args(argv)
    footing(_material("cpa-thesis", args.E, 0.0), resolution=1, steps=2, settlement_m=0.002, plots=False)  # compile
    rows = {}
    for soil in args.soils:
        sol, wall, split = timed_footing(_material(soil, args.E, args.stabilisation, args.compaction_stress),
                                         args.profile, resolution=args.resolution, steps=args.steps,
                                         surcharge_kPa=args.surcharge)
        h = sol.history
        its = h["iterations"][1:]
        log = sol.newton_log.summary()
        rows[soil] = (wall, sol, log["evaluations"])
        print(f"{soil:<24} {'done' if sol.completed else 'STOPPED':<8} s = {h['settlement_m'][-1]:.4f} m  "
              f"p = {h['pressure_kPa'][-1]:7.1f} kPa  steps {len(h) - 1:4d}  iterations/step {its.mean():5.2f}  "
              f"{wall:7.1f} s", flush=True)
        print(f"{'':<24} material evaluations {log['evaluations']}; a point's loading planes changed "
              f"{log['points_switched_total']} times over the run; full Newton steps {log['full_steps']}, "
              f"{log['full_steps_rejected']} rejected by the line search (half of their overshoot at a median of "
              f"{log['median_overshoot_points_rejected']:.0f} point(s): femgran.diagnostics.full_step_overshoot)")
        if split is not None:
            print(f"{'':<24} time by part (profiled): " + ", ".join(
                f"{part} {t:.1f} s ({100 * t / wall:.0f} %)" for part, t in split.items()))
            per = 1e3 / log["evaluations"]
            print(f"{'':<24} material update per evaluation {per * split['material update']:.1f} ms, "
                  f"everything else {per * (wall - split['material update']):.1f} ms")
        if not sol.completed:
            print(f"{'':<24} {sol.stop_reason}")
    if "drucker-prager" in rows:
        base, _, base_evals = rows["drucker-prager"]
        for soil, (wall, sol, evals) in rows.items():
            if soil != "drucker-prager":
                print(f"time {soil} / drucker-prager: {wall / base:.1f}"
                      f"{'' if sol.completed else ' (stopped early)'}{'  (target <= 5)' if soil.startswith('cpa') else ''}; "
                      f"material evaluations {evals} - {base_evals} = {evals - base_evals} more than the cone's "
                      f"(a number per run, not per step: docs/cpa_law.md, section 4)")


if __name__ == "__main__":
    main()
