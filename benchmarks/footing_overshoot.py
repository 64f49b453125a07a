"""Which Gauss points make a full Newton step of the CPA footing miss, and what they do along it.

Runs the isotropic CPA footing (the Mohr-Coulomb solid of ``footing_speed.py``) and, for the first
``--probes`` full Newton steps that the line search rejects from step ``--step`` on, prints the overshoot
of the step (its residual over the iterate's, the force of the stress the tangent did not predict over
the force it predicted) and its worst points (``femgran.diagnostics.full_step_overshoot``): where they
are, their mean stress, their share of the missed stress (times volume), the stress change the tangent
predicted and the one the full step gave, and their loading planes at the iterate and at the full step.
``docs/cpa_law.md``, section 4, "Which points make a full Newton step miss", quotes it.

With ``--trace K`` the worst K points of each probe are followed along the Newton step, d_eps + s * direction
for s = 0 ... 1 from the committed state, as the line search sees them: their mean stress p, deviatoric
stress q, loading planes, and the same of the reference law ``--against`` (Mohr-Coulomb by default) driven
from the same committed stress by the same strains: whether another law with the same friction would
respond to that strain as the CPA law does. ``--soil`` takes any soil of ``footing_speed.py``.

    python benchmarks/footing_overshoot.py [--soil cpa-isotropic] [--E 6000] [--resolution 2] [--surcharge 0]
        [--step 1] [--probes 25] [--trace 0] [--against mohr-coulomb]
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> None:
    import femgran.solver as solver_module
    from femgran.cases import footing
    from femgran.diagnostics import full_step_overshoot
    from footing_speed import SOILS, _material  # the soils of the speed benchmark (this folder is on the path)

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--E", type=float, default=6000.0)
    ap.add_argument("--resolution", type=int, default=2)
    ap.add_argument("--surcharge", type=float, default=0.0)
    ap.add_argument("--step", type=int, default=1, help="probe from this load step on (of 40)")
    ap.add_argument("--probes", type=int, default=25)
    ap.add_argument("--worst", type=int, default=4, help="points printed per probe")
    ap.add_argument("--soil", default="cpa-isotropic", choices=SOILS)
    ap.add_argument("--trace", type=int, default=0, help="follow this many of the worst points along the step")
    ap.add_argument("--against", default="mohr-coulomb", choices=SOILS, help="the law the trace compares with")
    args = ap.parse_args(argv)
    reference = _material(args.against, args.E, 0.0)

    # wrappers around the solver (this script only): remember the iterate, probe a rejected full step
    evaluate_of, line_search, step_of = (solver_module.NewtonSolver._evaluate, solver_module.NewtonSolver._line_search,
                                         solver_module.NewtonSolver.step)
    where = {"step": 0, "probes": 0}

    def step(self, t_new, *, step=0, attempt=0):
        where["step"] = step
        return step_of(self, t_new, step=step, attempt=attempt)

    def evaluate(self, du, t):
        r, tangent = evaluate_of(self, du, t)
        where["iterate"] = (du, self.points.trial_stress, tangent, self.points.trial_state.get("loading"))
        return r, tangent

    def probed(self, evaluate_fn, du, ddu, it, rf):
        _, stress0, tangent0, loading0 = where["iterate"]
        out = line_search(self, evaluate_fn, du, ddu, it, rf)
        if out[0] == 1.0 or where["step"] < args.step or where["probes"] >= args.probes:
            return out
        where["probes"] += 1
        m, P = self.points.material, self.points
        copy = {k: np.array(v, copy=True) for k, v in P.state.items()}
        d_eps, direction = self.disc.strain(du), self.disc.strain(ddu)
        stress1, state1, _ = m.update(d_eps + direction, P.stress, copy)  # the full step, as the line search tried it
        o = full_step_overshoot(self.disc.dx, stress0, tangent0, stress1, direction, loading0, state1.get("loading"))
        o["overshoot"] = next(r["overshoot"] for r in reversed(self.log.rows)
                              if r["iteration"] == it and r["line_search"] == 1.0)
        predicted = np.einsum("nijkl,nkl->nij", tangent0, direction)
        x = self.disc.quadrature_points()
        print(f"step {where['step']}, iteration {it}: |r| {rf:.2e} kN, full step rejected (overshoot "
              f"{o['overshoot']:.2f}; half of it at {o['overshoot_points']} point(s)), line search took "
              f"s = {out[0]:.3g}")
        for p in np.argsort(-o["share"])[:args.worst]:
            print(f"  point {p} at ({x[p, 0]:+.3f}, {x[p, 1]:+.3f}) m: mean stress "
                  f"{-np.trace(stress0[p]) / 3:.2f} kPa, share {o['share'][p]:.2f}, stress change predicted {np.abs(predicted[p]).max():.3f} / full step "
                  f"{np.abs(stress1[p] - stress0[p]).max():.3f} kPa, loading planes "
                  f"{_count(loading0, p)} -> {_count(state1.get('loading'), p)}")
        for p in np.argsort(-o["share"])[:args.trace]:
            _trace(m, reference, P.stress[p], {k: v[p] for k, v in P.state.items()}, d_eps[p], direction[p],
                   tangent0[p], stress0[p], f"point {p}")
        return out

    solver_module.NewtonSolver.step, solver_module.NewtonSolver._evaluate = step, evaluate
    if args.soil == "drucker-prager" or args.soil == "mohr-coulomb":
        print(f"{args.soil}: no loading planes; the columns that count them print -")
    solver_module.NewtonSolver._line_search = probed
    try:
        sol = footing(_material(args.soil, args.E, 0.0), resolution=args.resolution, steps=40,
                      surcharge_kPa=args.surcharge, plots=False)
    finally:
        solver_module.NewtonSolver.step, solver_module.NewtonSolver._evaluate = step_of, evaluate_of
        solver_module.NewtonSolver._line_search = line_search
    log = sol.newton_log.summary()
    print(f"whole run: {len(sol.history) - 1} steps, {int(sol.history['iterations'][1:].sum())} Newton iterations, "
          f"{log['evaluations']} material evaluations; {log['full_steps_rejected']} of {log['full_steps']} full steps "
          f"rejected, half of their overshoot at a median of {log['median_overshoot_points_rejected']:.0f} point(s)")


def _count(loading, p) -> str:
    return "-" if loading is None else str(int(np.sum(loading[p])))


def _invariants(stress) -> tuple[float, float]:
    """Mean stress p (compression +) and q of one (3, 3) stress [kPa]."""
    from material.plasticity import von_mises_stress

    return -np.trace(stress) / 3.0, float(von_mises_stress(stress))


def _trace(material, reference, stress_n, state_n, d_eps, direction, tangent0, stress0, label) -> None:
    """One point along the Newton step from its committed state: the law, the tangent's prediction from the
    iterate, and the reference law from the same committed stress (its own initial state there)."""
    s_grid = np.array([0.0, 1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.2, 0.5, 1.0])
    ref_state = reference.initial_state(1, stress=stress_n[None])
    print(f"    {label} along the step (its strain |direction| = {np.linalg.norm(direction):.2e}): s, p / q [kPa] and "
          f"loading planes of the law; p / q predicted by its tangent at the iterate; p / q of the reference")
    for s in s_grid:
        de = (d_eps + s * direction)[None]
        sig, st, _ = material.update(de, stress_n[None], {k: np.array(v, copy=True)[None] for k, v in state_n.items()})
        ref, _, _ = reference.update(de, stress_n[None], {k: np.array(v, copy=True) for k, v in ref_state.items()})
        pred = stress0 + np.einsum("ijkl,kl->ij", tangent0, s * direction)
        (p, q), (pp, qp), (pr, qr) = _invariants(sig[0]), _invariants(pred), _invariants(ref[0])
        print(f"      s = {s:<6g}: {p:8.3f} / {q:8.3f}  {_count(st.get('loading'), 0):>3}   predicted {pp:8.3f} / "
              f"{qp:8.3f}   reference {pr:8.3f} / {qr:8.3f}")


if __name__ == "__main__":
    main()
