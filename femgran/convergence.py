"""Mesh convergence of a softening study: how far apart the runs of one setting on several meshes are.

A regularised softening law should give the same post-peak response and the same shear band on every
mesh fine enough for its length. Two measures of that, both over runs of one setting that differ only in
the mesh (e.g. the biaxial study of ``examples/fe_04_biaxial_meshes.py``):

* :func:`q_spread` -- the spread of the deviator q over the runs at every axial strain from the latest of
  their peaks to the earliest of their ends, as a fraction of the largest peak (the study's "< 2 % of the
  peak at every strain after the peak").
* :func:`band_spread` -- the band's thickness in consecutive windows of axial strain after the peak
  (:func:`femgran.band.band_history`), each coarser mesh's against the finest mesh's, in units of the
  finest mesh's element (the study's "the same thickness within one element of the finest mesh").

Both return a :class:`material.table.Table`; :func:`describe` puts them in one line of words.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The strain step of the common grid on which :func:`q_spread` compares the runs (the study's step of
#: 0.025 % axial strain; the runs are interpolated linearly between their own steps).
GRID_STEP = 2.5e-4


def q_spread(histories, *, grid_step: float = GRID_STEP):
    """The spread of q over runs at every axial strain after the peak.

    ``histories``: a sequence of at least two run histories, each with the columns ``eps_a`` (axial strain,
    compression positive, increasing) and ``q_kPa`` (:class:`femgran.solver.History` or a
    :class:`material.table.Table` read from a run's ``history.csv``). The grid runs in steps of ``grid_step``
    from the latest of the runs' peaks (the strain of each run's largest q) to the earliest of their ends,
    so that every run is past its peak and none is extrapolated.

    Returns a Table with one row per grid strain: ``eps_a``, ``q_min_kPa``, ``q_max_kPa``, ``spread_kPa`` and
    ``spread_of_peak`` (the spread over the largest peak q, a fraction); its metadata hold the peak, the
    start and the end. Empty when the runs end before the latest peak.
    """
    from material.table import Table

    if len(histories) < 2:
        raise ValueError(f"q_spread needs at least two runs, got {len(histories)}")
    if not (np.isfinite(grid_step) and grid_step > 0.0):
        raise ValueError(f"grid_step = {grid_step!r}: must be an axial strain > 0 (e.g. 2.5e-4)")
    curves = []
    for k, h in enumerate(histories):
        e, q = np.asarray(h["eps_a"], float), np.asarray(h["q_kPa"], float)
        if len(e) < 2 or np.any(np.diff(e) < 0.0) or not np.all(np.isfinite(q)):
            raise ValueError(f"history {k}: eps_a must increase and q_kPa be finite over at least two steps")
        curves.append((e, q))
    peaks = [(float(q.max()), float(e[np.argmax(q)])) for e, q in curves]
    q_peak = max(p for p, _ in peaks)
    start, end = max(e for _, e in peaks), min(e[-1] for e, _ in curves)
    grid = np.arange(np.ceil(start / grid_step - 1e-9) * grid_step, end + 1e-12, grid_step)
    table = Table(metadata={"peak_q_kPa": q_peak, "from_eps_a": start, "to_eps_a": end,
                            "peaks_kPa": [p for p, _ in peaks], "grid_step": grid_step})
    if len(grid):
        qs = np.array([np.interp(grid, e, q) for e, q in curves])
        lo, hi = qs.min(axis=0), qs.max(axis=0)
        for x, a, b in zip(grid, lo, hi):
            table.append({"eps_a": x, "q_min_kPa": a, "q_max_kPa": b, "spread_kPa": b - a,
                          "spread_of_peak": (b - a) / q_peak})
    return table


def band_spread(run_folders, element_sizes_m, *, window: float = 0.005, name: str = "biaxial"):
    """The band's thickness in windows of axial strain after the peak on each mesh, against the finest mesh.

    ``run_folders``: the runs of one setting on at least two meshes (each with its VTK series ``NAME.pvd``
    and ``history.csv``); ``element_sizes_m``: the element size of each, in the same order. Each run's
    windows are those of :func:`femgran.band.band_history` (``window`` of axial strain each, the first
    from its peak), compared window by window up to the shortest run.

    Which band: of the two arms :func:`femgran.band.measure_arms` finds in a window, the one of the
    direction (rising or falling from left to right) that the finest mesh's stronger arm has in most of its
    windows, on every mesh, so that the same band is compared where the two arms are close in strength
    and their order swaps from mesh to mesh. A window where that arm is not a band (a zone or diffuse
    field) has thickness NaN, and its difference counts as not within.

    Returns a Table with one row per window and coarser mesh: ``window`` (1, 2, ...), ``eps_from``,
    ``eps_to`` (the finest mesh's), ``element_size_mm`` (the coarser mesh's), ``thickness_mm``,
    ``angle_deg``, ``finest_thickness_mm``, ``finest_angle_deg``, ``difference_mm`` (signed: the coarser
    minus the finest) and ``within_one_element`` (1 / 0: ``|difference|`` at most the finest element);
    its metadata hold the finest mesh's element size, the arm's direction and the number of windows.
    """
    from femgran.band import band_history
    from material.table import Table

    folders = [Path(f) for f in run_folders]
    sizes = [float(h) for h in element_sizes_m]
    if len(folders) < 2 or len(sizes) != len(folders):
        raise ValueError(f"band_spread needs at least two runs with an element size each, got {len(folders)} "
                         f"run folders and {len(sizes)} element sizes")
    if not all(np.isfinite(h) and h > 0.0 for h in sizes):
        raise ValueError(f"element_sizes_m = {sizes}: each must be > 0 [m]")
    order = np.argsort(sizes)
    finest = int(order[0])
    histories = [band_history(f, window, name=name) for f in folders]
    fine = histories[finest]
    votes = [fine["rising"][i] if fine["localised"][i] else fine["conjugate_rising"][i]
             for i in range(len(fine)) if fine["localised"][i] or fine["conjugate_localised"][i]]
    rising = bool(np.mean(votes) >= 0.5) if votes else True

    def arm(table, i):  # (thickness [mm], angle [deg]) of the chosen direction's arm in window i
        for prefix in ("", "conjugate_"):
            if bool(table[prefix + "rising"][i]) == rising:
                if table[prefix + "localised"][i]:
                    return 1e3 * float(table[prefix + "thickness_m"][i]), float(table[prefix + "angle_deg"][i])
                return float("nan"), float("nan")
        return float("nan"), float("nan")

    n_windows = min(len(t) for t in histories)
    h_fine = 1e3 * sizes[finest]
    result = Table(metadata={"finest_element_size_mm": h_fine, "arm": "rising" if rising else "falling",
                             "windows": n_windows, "window": window,
                             "run_folders": [f.name for f in folders]})
    for i in range(n_windows):
        t_fine, a_fine = arm(fine, i)
        for k in order[1:]:
            t, a = arm(histories[k], i)
            diff = t - t_fine
            result.append({"window": i + 1, "eps_from": float(fine["eps_from"][i]), "eps_to": float(fine["eps_to"][i]),
                           "element_size_mm": 1e3 * sizes[k], "thickness_mm": t, "angle_deg": a,
                           "finest_thickness_mm": t_fine, "finest_angle_deg": a_fine, "difference_mm": diff,
                           "within_one_element": float(bool(abs(diff) <= h_fine))})
    return result


def describe(q: "Table | None" = None, band: "Table | None" = None) -> str:
    """The two measures in words: the largest spread of q and where, and the windows in which the band is
    within one element of the finest mesh (all of them, or up to which strain)."""
    parts = []
    if q is not None:
        if len(q):
            k = int(np.argmax(q["spread_of_peak"]))
            parts.append(f"q spreads by at most {100 * q['spread_of_peak'][k]:.2f} % of the peak "
                         f"({q['spread_kPa'][k]:.1f} kPa at {100 * q['eps_a'][k]:.2f} %) from "
                         f"{100 * q.metadata['from_eps_a']:.2f} to {100 * q.metadata['to_eps_a']:.2f} %")
        else:
            parts.append("no strain after the latest peak to compare q at")
    if band is not None:
        n, h = band.metadata["windows"], band.metadata["finest_element_size_mm"]
        if not n:
            parts.append("no window after the peak to compare the band in")
        else:
            ok = np.array([np.all(band["within_one_element"][band["window"] == w] > 0) for w in range(1, n + 1)])
            largest = np.nanmax(np.abs(band["difference_mm"])) if np.any(np.isfinite(band["difference_mm"])) \
                else float("nan")
            head = f"the {band.metadata['arm']} band within one element of the finest mesh ({h:.2f} mm)"
            if ok.all():
                which = "its one window" if n == 1 else "both windows" if n == 2 else f"all {n} windows"
                parts.append(f"{head} in {which} (largest difference {largest:.2f} mm)")
            else:
                first = int(np.argmin(ok))  # the first window where it is not
                upto = f"every one up to {100 * band['eps_to'][band['window'] == first][0]:.2f} %; " if first else ""
                parts.append(f"{head} in {int(ok.sum())} of {n} windows ({upto}first miss: window {first + 1}; "
                             f"largest difference {largest:.2f} mm)")
    return "; ".join(parts)
