"""Example fe_06: the CPA law's implicit gradient in one dimension, where no inclined band can form.

The biaxial shear-band study (``fe_04``) found that with the scalar gradient the band is about a quarter of
the specimen's width, W f(l / W), and hardly follows the length l (``docs/regularisation.md``, section 4).
This example takes the specimen's geometry away: a plane-strain column, one element across and H = 100 mm
tall, confined laterally by p0 = 100 kPa, smooth ends, compressed along its axis, with a layer 2 mm thick
at mid-height whose eta0 is 10 % lower. Every field depends on the height only, so the softening zone is a
horizontal layer whose width only the law and l can set. The law is the study's (``ottawa_c109``,
E = 60 MPa, zeta 1.05, softening slip 0.03 m, residual ratio 0.65, step stabilisation 0.1) with associated
flow (``eta_c_ratio = 0``), as in the study's converging runs. The shortening of the column's middle half
drives the test (:class:`femgran.solver.PathControl`), so the softening branch is followed whatever the
zone's width; its strain is that shortening over H / 2.

The zone is measured in windows of 0.5 % of that strain from the peak: the growth of the post-peak slip
strain e (state ``post_peak_strain``) over each window, averaged per row of elements, gives a profile over
the height, and its width is 2 sqrt(3) times the profile's standard deviation (the width of a uniform
profile; the over-nonlocal von Mises closed form, :func:`femgran.gradient.one_dimensional_band`, has
3.38 l by this measure and an FWHM of 2.85 l). The second moment is used rather than the FWHM because the
weak layer adds a spike of its own at the zone's centre, which flips an FWHM between the spike and the
zone from one mesh to the next.

Writes ``zones.csv`` (one row per run and window: mu, l, h, strain past the peak, q, the zone's width;
each run's rows as it completes, the settings and the package version in its header) and
``gradient_column.png`` (q, and the width over l against the strain past the peak; its data in
``gradient_column.csv``), and prints one line per run.

    python examples/fe_06_gradient_column.py [--lengths 0.003 0.006] [--per-length 12] [--strain 0.08]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from material.table import TableWriter
from material.version import __version__

HEIGHT_M = 0.1
P0_KPA = 100.0
STEP_STRAIN = 0.08 / 300  #: the middle half's strain per step (the stabilisation's relaxation time is one step)
WINDOW = 0.005  #: the strain past the peak over which each zone width is measured
MATERIAL = {"preset": "ottawa_c109", "stabilisation": 0.1,
            "set": {"E": 60000.0, "zeta": 1.05, "softening_slip": 0.03, "residual_ratio": 0.65, "eta_c_ratio": 0.0}}


def column(length_m: float, rows: int, *, strain: float = 0.08, stabilisation: float = 0.1,
           weak_half_m: float = 0.001, weakening: float = 0.1) -> dict:
    """One column run: ``rows`` elements over the height, the gradient's length ``length_m``, the middle
    half shortened to ``strain``, the law's step stabilisation mu = ``stabilisation`` (relaxation time one
    step of :data:`STEP_STRAIN`). Returns the history (strain, q) and the zones (:func:`zone_widths`)."""
    from femgran.gradient import discretisation_for
    from femgran.mesh import name_box_boundaries, rectangle
    from femgran.solver import Dirichlet, NewtonSolver, PathControl
    from material.composite import Composite
    from material.factory import make_material

    if rows < 8:
        raise ValueError(f"rows = {rows!r}: allowed 8 or more (elements over the height)")
    H, h = HEIGHT_M, HEIGHT_M / rows
    mat = make_material({**MATERIAL, "stabilisation": float(stabilisation), "nonlocal_length": float(length_m)},
                        alpha_deg=0.0, plane_strain=True)
    mesh = name_box_boundaries(rectangle(np.linspace(0, h, 2), np.linspace(0, H, rows + 1)))
    d = discretisation_for(mat, mesh, 1)
    y = d.quadrature_points()[:, 1]
    weak = np.abs(y - 0.5 * H) < weak_half_m
    if not weak.any():
        raise ValueError(f"weak_half_m = {weak_half_m!r}: the weak layer holds no quadrature point of {rows} rows")
    mat = Composite([mat, mat.replace(params=mat.params.replace(eta0=mat.params.eta0 * (1 - weakening)))],
                    weak.astype(np.int64))
    b, x = mesh.boundaries, d.dof_coordinates()
    corner = np.flatnonzero(np.hypot(x[:, 0], x[:, 1]) < 1e-12 * H)
    top = Dirichlet(d.vector_dofs(d.facet_scalar_dofs(b["top"]), [1]), -0.5 * H, name="top")
    bcs = [Dirichlet(d.vector_dofs(d.facet_scalar_dofs(b["bottom"]), [1]), 0.0, ramp=False, name="bottom"),
           Dirichlet(d.vector_dofs(corner, [0]), 0.0, ramp=False), top]
    lower, upper = (np.flatnonzero(np.isclose(x[:, 1], f * H, atol=1e-9 * H)) for f in (0.25, 0.75))
    if lower.size == 0 or upper.size == 0:
        raise ValueError(f"rows = {rows!r}: must be a multiple of 4 (the middle half's ends are node rows)")
    control = PathControl(np.concatenate([d.vector_dofs(lower, [1]), d.vector_dofs(upper, [1])]),
                          np.concatenate([np.full(lower.size, 1 / lower.size), np.full(upper.size, -1 / upper.size)]),
                          name="middle_shortening_m")
    solver = NewtonSolver(d, mat, bcs, f_fixed=d.pressure_force(np.concatenate([b["left"], b["right"]]), P0_KPA),
                          initial_stress=-P0_KPA * np.eye(3))
    slips = []

    def observe(s):
        state = s.points.state
        slips.append(sum(state[f"{k}:post_peak_strain"] for k in (0, 1)))  # each law's points, zero elsewhere
        return {"q_kPa": -float(np.sum(s.reaction[top.dofs])) / h - P0_KPA}

    steps = max(1, round(strain / STEP_STRAIN))
    sol = solver.run(steps=steps, control=control, control_end=strain * 0.5 * H, observers=[observe])
    eps = np.asarray(sol.history["middle_shortening_m"]) / (0.5 * H)
    q = np.asarray(sol.history["q_kPa"])
    return {"length_m": float(length_m), "h_m": h, "stabilisation": float(stabilisation),
            "completed": bool(sol.completed), "stop_reason": sol.stop_reason, "strain": eps, "q_kPa": q,
            "iterations": float(np.mean(sol.history["iterations"][1:])), **zone_widths(y, eps, q, np.array(slips))}


def zone_widths(y: np.ndarray, strain: np.ndarray, q: np.ndarray, slip: np.ndarray) -> dict:
    """The zone's width in each window of :data:`WINDOW` from the peak: 2 sqrt(3) times the standard
    deviation over the height of the growth of ``slip`` (steps x points) in the window, averaged per row."""
    rows, inverse = np.unique(np.round(y, 12), return_inverse=True)
    peak = int(np.argmax(q))
    past, widths, at = [], [], []
    for k in range(1, int((strain[-1] - strain[peak]) / WINDOW + 1e-9) + 1):
        i, j = (int(np.searchsorted(strain, strain[peak] + WINDOW * m - 1e-12)) for m in (k - 1, k))
        growth = np.maximum(np.bincount(inverse, slip[j] - slip[i]) / np.bincount(inverse), 0.0)
        if growth.sum() <= 0:
            continue
        w = growth / growth.sum()
        centre = float(w @ rows)
        past.append(float(strain[j] - strain[peak]))
        widths.append(float(2 * np.sqrt(3 * (w @ (rows - centre) ** 2))))
        at.append(float(q[j]))
    return {"peak_q_kPa": float(q[peak]), "peak_strain": float(strain[peak]), "past_peak": np.array(past),
            "zone_width_m": np.array(widths), "zone_q_kPa": np.array(at)}


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/fe_06_gradient_column")
    ap.add_argument("--lengths", type=float, nargs="+", default=[0.003, 0.006], help="gradient lengths l [m]")
    ap.add_argument("--per-length", type=int, nargs="+", default=[12], help="element rows per l (h = l / this)")
    ap.add_argument("--strain", type=float, default=0.08, help="the middle half's final strain (compression +)")
    ap.add_argument("--stabilisation", type=float, nargs="+", default=[0.1, 0.01],
                    help="step stabilisations mu of the law (the shear-band study's is 0.1)")
    args = ap.parse_args(argv)
    if any(not (np.isfinite(x) and 0 < x <= 0.02) for x in args.lengths):
        ap.error(f"--lengths must be in (0, 0.02] m (the column is 0.1 m tall), got {args.lengths}")
    if any(n < 2 for n in args.per_length):
        ap.error(f"--per-length must be at least 2, got {args.per_length}")
    if any(not (np.isfinite(mu) and 0 < mu <= 1) for mu in args.stabilisation):
        ap.error(f"--stabilisation must be in (0, 1] (without it the law stops at the peak), got {args.stabilisation}")
    if not 0.03 <= args.strain <= 0.2:
        ap.error(f"--strain must be in [0.03, 0.2] (the peak is near 2.2 %), got {args.strain}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = []
    law = {k: v for k, v in MATERIAL.items() if k != "stabilisation"}  # mu: each row's own
    metadata = {"femgran_version": __version__, "material": law, "height_m": HEIGHT_M, "p0_kPa": P0_KPA,
                "step_strain": STEP_STRAIN, "window": WINDOW, "weak_layer": "2 mm at mid-height, eta0 10 % lower",
                "strain": args.strain, "lengths_m": args.lengths, "per_length": args.per_length,
                "stabilisations": args.stabilisation}
    table = TableWriter(out / "zones.csv", title="fe_06: the CPA gradient's softening zone in a one-dimensional "
                        "column", metadata=metadata)  # each run's rows as it completes
    for mu, ell, per in ((mu, ell, per) for mu in args.stabilisation for ell in args.lengths
                         for per in args.per_length):
        rows = 4 * max(2, round(HEIGHT_M / ell * per / 4))
        r = column(ell, rows, strain=args.strain, stabilisation=mu)
        runs.append(r)
        for s, w, q in zip(r["past_peak"], r["zone_width_m"], r["zone_q_kPa"]):
            table.write({"stabilisation": mu, "length_mm": 1e3 * ell, "element_size_mm": 1e3 * r["h_m"],
                          "past_peak": s, "q_kPa": q, "zone_width_mm": 1e3 * w, "zone_width_over_length": w / ell,
                          "completed": int(r["completed"])})
        print(f"mu = {mu:g}, l = {1e3 * ell:g} mm, h = {1e3 * r['h_m']:.3g} mm: peak {r['peak_q_kPa']:.1f} kPa at "
              f"{100 * r['peak_strain']:.2f} %, {r['iterations']:.2f} Newton iterations per step; zone / l in "
              "the windows from the peak: " + ", ".join(f"{w / ell:.2f}" for w in r["zone_width_m"])
              + ("" if r["completed"] else f" (stopped early: {r['stop_reason']})"), flush=True)
    table.close()
    _plot(runs, out / "gradient_column.png")
    return runs


def _plot(runs, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from material.plotting import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for r in runs:
        label = f"mu = {r['stabilisation']:g}, l = {1e3 * r['length_m']:g} mm, h = {1e3 * r['h_m']:.2g} mm"
        axes[0].plot(100 * r["strain"], r["q_kPa"], label=label)
        axes[1].plot(100 * r["past_peak"], r["zone_width_m"] / r["length_m"], "o-", label=label)
    axes[0].set_xlabel("strain of the middle half [%] (compression +)")
    axes[0].set_ylabel("q = s1 - s3 [kPa]")
    axes[1].axhline(3.38, color="k", lw=0.8, ls="--", label="over-nonlocal von Mises, closed form")
    axes[1].set_xlabel("strain past the peak [%]")
    axes[1].set_ylabel("zone width / l (2 sqrt(3) std)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)  # and the curves it draws as a CSV of the same stem


if __name__ == "__main__":
    main()
