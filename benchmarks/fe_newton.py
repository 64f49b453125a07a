"""Benchmark: one Newton iteration on the 54k-DOF triaxial specimen in a plastic state.

The specimen of :func:`femgran.cases.triaxial` (50 x 50 x 100 mm, rough platens) meshed with
20 x 20 x 40 trilinear hexahedra (16,000 elements, 128,000 Gauss points, 54,243 DOFs), CPA law
``ottawa_c109`` at alpha = 45. A plastic state is reached by one load step of 1 % axial strain; then
the pieces of one Newton iteration are timed:

* material update (CPA, all Gauss points, with the consistent tangent),
* tangent assembly (numba B^T D B kernel + CSR scatter),
* scikit-fem's own assembly of 3D linear elasticity on the same mesh (the baseline; ratio printed),
* the linear solve of K_ff du = -r with each linear solver (SuperLU, pyamg-preconditioned GMRES,
  ILU-preconditioned GMRES),
* one whole Newton iteration (update + residual + assembly + solve) with the default solver.

Run::

    NUMBA_NUM_THREADS=2 python benchmarks/fe_newton.py [--resolution 20] [--solvers superlu amg-gmres ilu-gmres]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _t(f, *a, repeat=1, **k):
    best = np.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f(*a, **k)
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resolution", type=int, default=20, help="elements across the width (height: 2x)")
    ap.add_argument("--solvers", nargs="+", default=["superlu", "amg-gmres"], help="also: ilu-gmres (slow here)")
    ap.add_argument("--alpha", type=float, default=45.0)
    ap.add_argument("--skip-skfem", action="store_true", help="skip the (slow) scikit-fem baseline")
    args = ap.parse_args(argv)

    import numba
    import skfem
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from femgran.assembly import Discretisation
    from material.factory import make_material
    from femgran.mesh import box
    from femgran.solver import Dirichlet, LinearSolver, NewtonSolver, SolverOptions

    n = args.resolution
    mesh = box(0.05, 0.05, 0.1, n, n, 2 * n)
    t_disc, d = _t(Discretisation, mesh, 1)
    print(f"mesh: {d.nelems} hexahedra, {d.n_points} Gauss points, {d.ndofs} DOFs; numba threads {numba.get_num_threads()}")
    print(f"discretisation (basis data, DOF maps): {t_disc:.2f} s")

    mat = make_material(None, alpha_deg=args.alpha)
    b = mesh.boundaries
    bot, top = d.facet_scalar_dofs(b["bottom"]), d.facet_scalar_dofs(b["top"])
    bcs = [Dirichlet(d.vector_dofs(bot), 0.0), Dirichlet(d.vector_dofs(top, [2]), -0.001, name="top"),
           Dirichlet(d.vector_dofs(top, [0, 1]), 0.0)]
    lateral = np.concatenate([b[k] for k in ("left", "right", "front", "back")])
    solver = NewtonSolver(d, mat, bcs, f_fixed=d.pressure_force(lateral, 100.0), initial_stress=-100.0 * np.eye(3),
                          options=SolverOptions(tol=1e-6, linear_solver="amg-gmres"))
    t0 = time.perf_counter()
    du, iters, res = solver.step(1.0)
    solver.points.commit()
    solver._committed_tangent = solver.points.tangent
    solver.u += du
    solver.t = 1.0
    print(f"plastic state: one step of 1 % axial strain, {iters} iterations, residuals {['%.1e' % r for r in res]}, "
          f"{time.perf_counter() - t0:.1f} s (incl. predictor and JIT)")
    print(f"  points with plastic flow in the step: {np.mean(np.any(solver.points.state['kappa'] > 0, axis=1)):.0%}")

    # a further increment from the plastic state
    du2 = np.zeros(d.ndofs)
    du2[solver.constrained] = solver.prescribed(1.1) - solver.u[solver.constrained]
    du2 = solver._predict(du2, 1.1)
    de = d.strain(du2)
    t_strain, _ = _t(d.strain, du2, repeat=3)
    t_upd, (stress, tangent, failed) = _t(solver.points.evaluate, de, repeat=2)
    print(f"material update (CPA, {d.n_points} points, tangent): {t_upd:.2f} s; failed points {int(failed.sum())}")
    t_fint, r = _t(lambda: d.internal_force(stress) - solver.external(1.1), repeat=3)
    print(f"strain from displacement: {t_strain:.3f} s; internal force: {t_fint:.3f} s")
    t_asm, K = _t(d.stiffness, tangent, repeat=3)
    print(f"tangent assembly (numba kernel + scatter): {t_asm:.2f} s, nnz {K.nnz}")
    t_slice, Kff = _t(lambda: K[solver.free][:, solver.free], repeat=2)
    print(f"free-DOF submatrix: {t_slice:.2f} s")
    if not args.skip_skfem:
        vb = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementHex1()), intorder=3)
        t_sk, K_sk = _t(linear_elasticity(*lame_parameters(3e4, 0.3)).assemble, vb)
        t_el, K_el = _t(d.stiffness, np.broadcast_to(material_stiffness(3e4, 0.3), (d.n_points, 3, 3, 3, 3)))
        err = abs(K_el - K_sk).max() / abs(K_sk).max()
        print(f"scikit-fem asm of 3D linear elasticity (baseline): {t_sk:.2f} s; ours on the same elastic tangent "
              f"{t_el:.2f} s (rel. difference {err:.1e}); speed-up {t_sk / t_el:.1f}x, "
              f"(plastic tangent assembly: {t_sk / t_asm:.1f}x)")
        del vb, K_sk
    rhs = -r[solver.free]
    times = {}
    ns = solver._nullspace()
    for method in args.solvers:
        ls = LinearSolver(method, 1e-8, ns if method == "amg-gmres" else None)
        t_s, x = _t(ls.solve, Kff, rhs)
        rel = np.linalg.norm(Kff @ x - rhs) / np.linalg.norm(rhs)
        msg = f"linear solve {method:>10}: {t_s:.2f} s, relative residual {rel:.1e}"
        if method != "superlu":
            t_r, x = _t(ls.solve, Kff, 0.5 * rhs)  # the next Newton iteration reuses the preconditioner
            msg += f"; {ls.last_iterations} GMRES iterations; with the preconditioner reused: {t_r:.2f} s"
            t_e, x = _t(ls.solve, Kff, 0.25 * rhs, 3, 1e-4)
            msg += f"; reused + inexact Newton forcing 1e-4: {t_e:.2f} s ({ls.last_iterations} iterations)"
            t_s = t_e  # what a Newton iteration of the solver costs (forcing term, reused preconditioner)
        times[method] = t_s
        print(msg)
    print("(the solver's forcing term: eta_k = min(1e-3, 0.1 |r_k|/ref) for Krylov solvers)")
    best = min(times, key=times.get)
    print(f"fastest linear solver here (preconditioner reused across Newton iterations): {best}")
    t_it = t_upd + t_fint + t_asm + t_slice + times[best] + t_strain
    print(f"one Newton iteration (update + residual + assembly + solve with {best}): {t_it:.2f} s "
          f"[update {t_upd / t_it:.0%}, assembly {t_asm / t_it:.0%}, solve {times[best] / t_it:.0%}]")


def material_stiffness(E, nu):
    from material.elastic import isotropic_stiffness

    return isotropic_stiffness(E, nu)


if __name__ == "__main__":
    main()
