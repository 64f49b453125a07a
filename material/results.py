"""The result table of the element drivers (:mod:`material.driver`): columns, CSV, plots.

A table holds one row per recorded load step (row 0 is the state before the first step). Columns are
plain 1-D numpy arrays addressed by name (``res["q_kPa"]``); the full tensors are kept as
``res.stress`` and ``res.strain``, (n, 3, 3), **tension positive** (the convention of every public
tensor in the package), while the named scalar columns follow the **geotechnical convention**
(compression positive) and say so in :attr:`ElementResult.descriptions`.
"""

from __future__ import annotations

from typing import Any, Iterable

import numpy as np

from material.table import Table, read_table

__all__ = ["ElementResult", "COMPONENTS", "standard_columns", "read_csv"]

#: Order of the six independent components of a symmetric tensor in every table and path.
COMPONENTS = ("xx", "yy", "zz", "yz", "xz", "xy")
_IJ = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
CONVENTION = ("tensor components sig_ij_kPa, eps_ij: tension positive; p, q, eps_v, eps_a, sig1..3: "
              "compression positive")


def standard_columns(stress: np.ndarray, strain: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Columns every driver reports, from (n, 3, 3) effective stress and strain (tension +).

    Returns ``(columns, descriptions)``: ``p_kPa`` = -tr(sigma)/3, ``q_kPa`` = sqrt(3 J2),
    ``sig1_kPa >= sig2_kPa >= sig3_kPa`` principal stresses (compression +), ``eps_v`` = -tr(eps),
    ``eps_q`` = sqrt(2/3 e:e), and the 12 tensor components ``sig_ij_kPa``, ``eps_ij`` (tension +,
    tensor shear strains, not engineering gamma).
    """
    s = np.asarray(stress, dtype=float)
    e = np.asarray(strain, dtype=float)
    eye = np.eye(3)
    tr_s = np.trace(s, axis1=1, axis2=2)
    dev_s = s - tr_s[:, None, None] / 3.0 * eye
    tr_e = np.trace(e, axis1=1, axis2=2)
    dev_e = e - tr_e[:, None, None] / 3.0 * eye
    principal = -np.linalg.eigvalsh(s)  # ascending tension + -> descending compression +
    cols: dict[str, np.ndarray] = {
        "p_kPa": -tr_s / 3.0,
        "q_kPa": np.sqrt(1.5 * np.einsum("nij,nij->n", dev_s, dev_s)),
        "sig1_kPa": principal[:, 0],
        "sig2_kPa": principal[:, 1],
        "sig3_kPa": principal[:, 2],
        "eps_v": -tr_e,
        "eps_q": np.sqrt(2.0 / 3.0 * np.einsum("nij,nij->n", dev_e, dev_e)),
    }
    desc = {
        "p_kPa": "mean effective stress -tr(sigma)/3 [kPa], compression +",
        "q_kPa": "deviator sqrt(3 J2) of the effective stress [kPa] (>= 0)",
        "sig1_kPa": "major principal effective stress [kPa], compression +",
        "sig2_kPa": "intermediate principal effective stress [kPa], compression +",
        "sig3_kPa": "minor principal effective stress [kPa], compression +",
        "eps_v": "volumetric strain -tr(eps) [-], compression +",
        "eps_q": "deviatoric strain invariant sqrt(2/3 e:e) [-]",
    }
    for name, (i, j) in zip(COMPONENTS, _IJ):
        cols[f"sig_{name}_kPa"] = s[:, i, j]
        desc[f"sig_{name}_kPa"] = f"effective stress component sigma_{name} [kPa], tension +"
    for name, (i, j) in zip(COMPONENTS, _IJ):
        cols[f"eps_{name}"] = e[:, i, j]
        desc[f"eps_{name}"] = f"strain component eps_{name} [-], tension +, tensor (not engineering) shear"
    return cols, desc


class ElementResult(Table):
    """Table of an element test: one row per recorded step (row 0 = initial state).

    A :class:`material.table.Table` (columns, descriptions, metadata, one CSV format) with the tensors.

    Attributes
    ----------
    columns : list of str
        Column names, units and sign convention in the name (``p_kPa``, ``eps_a``, ...); the full
        description of each is in :attr:`descriptions`.
    descriptions : dict[str, str]
        Column name -> meaning, unit and sign convention.
    stress, strain : (n, 3, 3) ndarray
        Effective Cauchy stress [kPa] and total small strain [-], **tension positive**, global frame.
    metadata : dict
        Test name, options, material description, parameters, package version.
    completed : bool
        False when the path stopped early (a step failed after all cut-backs); ``message`` says why.
    message : str
        Empty for a completed run, otherwise the reason of the stop.
    final_state : dict or None
        Material state after the last converged step (the dict of the material interface).
    tangent : (n, 3, 3, 3, 3) ndarray or None
        The material's tangent d sigma / d eps of each step's last update (row 0: of a zero step from the
        start), in the global frame; what :mod:`material.localisation` tests for a band. Kept in memory
        only (None for a table read from a file).
    """

    title = "femgran element test result"

    def __init__(
        self,
        columns: dict[str, np.ndarray],
        descriptions: dict[str, str],
        stress: np.ndarray,
        strain: np.ndarray,
        metadata: dict[str, Any] | None = None,
        completed: bool = True,
        message: str = "",
        final_state: dict | None = None,
        plot_pairs: Iterable[tuple[str, str]] = (),
        tangent: np.ndarray | None = None,
    ):
        n = len(np.asarray(stress))
        for k, v in columns.items():
            if np.shape(v) != (n,):
                raise ValueError(f"column {k!r}: expected shape ({n},), got {np.shape(v)}")
        super().__init__(columns, {k: descriptions.get(k, "") for k in columns}, metadata, convention=CONVENTION)
        self._n = n
        self.stress = np.asarray(stress, dtype=float)
        self.strain = np.asarray(strain, dtype=float)
        self.completed = bool(completed)
        self.message = str(message)
        self.final_state = final_state
        self.plot_pairs = list(plot_pairs)
        self.tangent = None if tangent is None else np.asarray(tangent, dtype=float)

    def __repr__(self) -> str:
        status = "completed" if self.completed else f"STOPPED: {self.message}"
        return f"ElementResult({self.metadata.get('test', '?')}, {len(self)} rows, {status})"

    def header(self, names=None) -> list[str]:
        lines = super().header(names)
        return lines[:1] + [f"# completed: {self.completed}" + (f" ({self.message})" if self.message else "")] + lines[1:]

    def plot(self, pairs: Iterable[tuple[str, str]] | None = None, title: str | None = None):
        """A matplotlib Figure with one panel per (x, y) column pair (default: the driver's choice).

        Uses :class:`matplotlib.figure.Figure` directly (no pyplot state, any backend); save it with
        ``fig.savefig("file.png")``.
        """
        from matplotlib.figure import Figure

        pairs = list(pairs) if pairs is not None else (self.plot_pairs or [("eps_q", "q_kPa"), ("eps_q", "eps_v")])
        for x, y in pairs:
            self[x], self[y]  # KeyError naming the column
        fig = Figure(figsize=(5.0 * len(pairs), 4.0), layout="constrained")
        axes = fig.subplots(1, len(pairs), squeeze=False)[0]
        for ax, (x, y) in zip(axes, pairs):
            ax.plot(self[x], self[y], "-", lw=1.5)
            ax.set_xlabel(x)
            ax.set_ylabel(y)
            ax.grid(True, alpha=0.3)
        fig.suptitle(title or self._title())
        return fig

    def _title(self) -> str:
        md = self.metadata
        bits = [str(md.get("test", "element test"))]
        for key in ("p0_kPa", "sigma_n_kPa", "alpha_deg", "delta_psi_deg", "b"):
            if key in md:
                bits.append(f"{key}={md[key]:g}")
        if not self.completed:
            bits.append("(stopped early)")
        return ", ".join(bits)


def read_csv(path) -> ElementResult:
    """Read a table written by :meth:`ElementResult.to_csv` (columns, descriptions, metadata, tensors)."""
    t = read_table(path)
    completed_line = t.metadata.pop("header", {}).get("completed", "True")
    completed = completed_line.startswith("True")
    message = completed_line[completed_line.find("(") + 1: -1] if "(" in completed_line else ""
    cols = t.to_dict()
    n = len(t)
    stress = np.zeros((n, 3, 3))
    strain = np.zeros((n, 3, 3))
    for comp, (i, j) in zip(COMPONENTS, _IJ):
        if f"sig_{comp}_kPa" in cols:
            stress[:, i, j] = stress[:, j, i] = cols[f"sig_{comp}_kPa"]
        if f"eps_{comp}" in cols:
            strain[:, i, j] = strain[:, j, i] = cols[f"eps_{comp}"]
    pairs = [tuple(p) for p in t.metadata.get("plot_pairs", ())]
    return ElementResult(cols, t.descriptions, stress, strain, t.metadata, completed, message, plot_pairs=pairs)
