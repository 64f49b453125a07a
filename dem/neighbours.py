"""Neighbour search: a Verlet half list in CSR form built from a uniform bin grid with a skin.

The list holds every pair i < j whose gap is below ``skin``; it stays valid until some particle has
moved more than ``skin / 2`` since the build (the engine checks this every step and rebuilds).
Pairs are sorted by i (``istart[i]:istart[i+1]`` are the pairs of i, partner ``pj``); the transpose
(``jstart``, ``jorder``) lists for each particle the pairs where it is the second member, so that the
per-particle force gather needs no atomic scatter. The tangential history is an array parallel to
``pj`` and is carried across rebuilds by :func:`_transfer_history`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _build_half_list(pos, radius, skin):
    """Half list of pairs (i < j) with ``|x_i - x_j| < r_i + r_j + skin`` from a uniform bin grid.

    Returns ``istart`` (N+1,) int64 and ``pj`` (P,) int32 (pairs sorted by i, then by j).
    """
    n = pos.shape[0]
    xmin, ymin = pos[0, 0], pos[0, 1]
    xmax, ymax = xmin, ymin
    rmax = 0.0
    for i in range(n):
        xmin = min(xmin, pos[i, 0]); xmax = max(xmax, pos[i, 0])
        ymin = min(ymin, pos[i, 1]); ymax = max(ymax, pos[i, 1])
        rmax = max(rmax, radius[i])
    cell = 2.0 * rmax + skin
    nx = int((xmax - xmin) / cell) + 1
    ny = int((ymax - ymin) / cell) + 1
    cell_of = np.empty(n, np.int64)
    count = np.zeros(nx * ny + 1, np.int64)
    for i in range(n):
        cx = min(int((pos[i, 0] - xmin) / cell), nx - 1)
        cy = min(int((pos[i, 1] - ymin) / cell), ny - 1)
        c = cy * nx + cx
        cell_of[i] = c
        count[c + 1] += 1
    for c in range(nx * ny):
        count[c + 1] += count[c]
    members = np.empty(n, np.int64)
    fill = count[:-1].copy()
    for i in range(n):
        c = cell_of[i]
        members[fill[c]] = i
        fill[c] += 1
    # two passes: count the pairs of each i, then fill (ascending j inside each row)
    istart = np.zeros(n + 1, np.int64)
    buf = np.empty(64, np.int64)
    for sweep in range(2):
        if sweep == 1:
            for i in range(n):
                istart[i + 1] += istart[i]
            pj = np.empty(istart[n], np.int32)
        for i in range(n):
            c = cell_of[i]
            cx = c % nx
            cy = c // nx
            m = 0
            for dy in range(-1, 2):
                yy = cy + dy
                if yy < 0 or yy >= ny:
                    continue
                for dx in range(-1, 2):
                    xx = cx + dx
                    if xx < 0 or xx >= nx:
                        continue
                    cc = yy * nx + xx
                    for k in range(count[cc], count[cc + 1]):
                        j = members[k]
                        if j <= i:
                            continue
                        ddx = pos[j, 0] - pos[i, 0]
                        ddy = pos[j, 1] - pos[i, 1]
                        cut = radius[i] + radius[j] + skin
                        if ddx * ddx + ddy * ddy < cut * cut:
                            if m == buf.shape[0]:
                                nb = np.empty(2 * m, np.int64)
                                nb[:m] = buf
                                buf = nb
                            buf[m] = j
                            m += 1
            if sweep == 0:
                istart[i + 1] = m
            else:
                row = np.sort(buf[:m])
                for k in range(m):
                    pj[istart[i] + k] = row[k]
    return istart, pj


@njit(cache=True)
def _transpose(istart, pj, n):
    """For each particle the indices of the pairs where it is j: ``jstart`` (N+1,), ``jorder`` (P,)."""
    npairs = pj.shape[0]
    jstart = np.zeros(n + 1, np.int64)
    for p in range(npairs):
        jstart[pj[p] + 1] += 1
    for k in range(n):
        jstart[k + 1] += jstart[k]
    fill = jstart[:-1].copy()
    jorder = np.empty(npairs, np.int64)
    for i in range(n):
        for p in range(istart[i], istart[i + 1]):
            j = pj[p]
            jorder[fill[j]] = p
            fill[j] += 1
    return jstart, jorder


@njit(cache=True)
def _transfer_history(old_istart, old_pj, old_zeta, new_istart, new_pj):
    """Tangential history of the new list: the old value where the pair existed, else 0."""
    n = new_istart.shape[0] - 1
    zeta = np.zeros(new_pj.shape[0])
    for i in range(n):
        a, b = old_istart[i], old_istart[i + 1]
        for p in range(new_istart[i], new_istart[i + 1]):
            j = new_pj[p]
            for q in range(a, b):  # rows are sorted and short (a few partners)
                if old_pj[q] == j:
                    zeta[p] = old_zeta[q]
                    break
                if old_pj[q] > j:
                    break
    return zeta


def naive_pairs(pos: np.ndarray, radius: np.ndarray, skin: float) -> set[tuple[int, int]]:
    """O(N^2) reference: the set of pairs (i < j) with gap below ``skin``."""
    i_idx, j_idx = np.triu_indices(len(radius), 1)
    d = np.hypot(*(pos[j_idx] - pos[i_idx]).T)
    close = d < radius[i_idx] + radius[j_idx] + skin
    return set(zip(i_idx[close].tolist(), j_idx[close].tolist()))
