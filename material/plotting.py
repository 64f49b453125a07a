"""A figure and the data it draws, saved together: ``name.png`` and ``name.csv``.

:func:`save_figure` writes a matplotlib figure as a PNG and, next to it, every curve and every set of
points it draws as columns of a :class:`material.table.Table` CSV (``<panel>_<label>_x`` and ``..._y``, and
``..._value`` for points coloured by a value; shorter curves padded with NaN; the panel's axis labels
in the column descriptions). So each figure of
the package can be re-plotted, or compared with a user's data, from numbers, not from pixels; the CSV
holds exactly what was drawn, whatever function drew it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from material.table import Table

__all__ = ["figure_data", "save_figure"]


def _name(text: str) -> str:
    return re.sub(r"[^0-9A-Za-z.+-]+", "_", text).strip("_") or "curve"


def figure_data(fig, title: str = "figure data") -> Table:
    """Every line (``Line2D``) and point set (``PathCollection``) of ``fig`` as columns of a Table."""
    columns: dict[str, np.ndarray] = {}
    descriptions: dict[str, str] = {}
    for a, ax in enumerate(fig.get_axes()):
        panel = f"p{a}"
        xlabel, ylabel = ax.get_xlabel(), ax.get_ylabel()
        items = [(line.get_label(), line.get_xdata(), line.get_ydata(), None) for line in ax.get_lines()]
        for c in ax.collections:  # point sets (scatter): their positions, and their colour values if mapped
            offsets = np.asarray(c.get_offsets()) if hasattr(c, "get_offsets") else np.empty((0, 2))
            if type(c).__name__ == "PathCollection" and len(offsets):
                values = c.get_array()
                items.append((c.get_label(), offsets[:, 0], offsets[:, 1],
                              None if values is None or len(values) != len(offsets) else values))
        for i, (label, x, y, values) in enumerate(items):
            label = f"curve{i}" if not label or label.startswith("_") else label
            stem = f"{panel}_{_name(label)}"
            while f"{stem}_x" in columns:
                stem += "_"
            columns[f"{stem}_x"] = np.asarray(x, dtype=float).ravel()
            columns[f"{stem}_y"] = np.asarray(y, dtype=float).ravel()
            descriptions[f"{stem}_x"] = f"panel {a} ({ax.get_title() or 'untitled'}), {label}: x = {xlabel}"
            descriptions[f"{stem}_y"] = f"panel {a}, {label}: y = {ylabel}"
            if values is not None:
                columns[f"{stem}_value"] = np.asarray(values, dtype=float).ravel()
                descriptions[f"{stem}_value"] = f"panel {a}, {label}: the value shown by the colour"
    n = max((len(v) for v in columns.values()), default=0)
    padded = {k: np.concatenate([v, np.full(n - len(v), np.nan)]) for k, v in columns.items()}
    return Table(padded, descriptions, title=title)


def save_figure(fig, path, title: str | None = None, dpi: int = 120) -> list[Path]:
    """Write ``fig`` to ``path`` (.png) and its data to the same stem with .csv; close it; return both paths."""
    import matplotlib.pyplot as plt

    png = Path(path).with_suffix(".png")
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=dpi)
    csv = figure_data(fig, title or png.stem).write_csv(png.with_suffix(".csv"))
    plt.close(fig)
    return [png, Path(csv)]
