"""The result table of the element drivers (:mod:`material.driver`): columns, CSV, plots.

A table holds one row per recorded load step (row 0 is the state before the first step). Columns are
plain 1-D numpy arrays addressed by name (``res["q_kPa"]``); the full tensors are kept as
``res.stress`` and ``res.strain``, (n, 3, 3), **tension positive** (the convention of every public
tensor in the package), while the named scalar columns follow the **geotechnical convention**
(compression positive) and say so in :attr:`ElementResult.descriptions`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable

import numpy as np

__all__ = ["ElementResult", "COMPONENTS", "standard_columns", "read_csv"]

#: Order of the six independent components of a symmetric tensor in every table and path.
COMPONENTS = ("xx", "yy", "zz", "yz", "xz", "xy")
_IJ = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))


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


class ElementResult:
    """Table of an element test: one row per recorded step (row 0 = initial state).

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
    """

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
    ):
        self._data = {k: np.asarray(v) for k, v in columns.items()}
        n = len(np.asarray(stress))
        for k, v in self._data.items():
            if v.shape != (n,):
                raise ValueError(f"column {k!r}: expected shape ({n},), got {v.shape}")
        self.descriptions = {k: descriptions.get(k, "") for k in self._data}
        self.stress = np.asarray(stress, dtype=float)
        self.strain = np.asarray(strain, dtype=float)
        self.metadata = dict(metadata or {})
        self.completed = bool(completed)
        self.message = str(message)
        self.final_state = final_state
        self.plot_pairs = list(plot_pairs)

    # ------------------------------------------------------------------ table access
    @property
    def columns(self) -> list[str]:
        """Column names in table order."""
        return list(self._data)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._data[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; available: {self.columns}") from None

    def __contains__(self, name: str) -> bool:
        return name in self._data

    def __len__(self) -> int:
        return len(self.stress)

    def __repr__(self) -> str:
        status = "completed" if self.completed else f"STOPPED: {self.message}"
        return f"ElementResult({self.metadata.get('test', '?')}, {len(self)} rows, {status})"

    def add_column(self, name: str, values, description: str) -> None:
        """Add (or replace) a column of length ``len(self)``."""
        v = np.asarray(values)
        if v.shape != (len(self),):
            raise ValueError(f"column {name!r}: expected shape ({len(self)},), got {v.shape}")
        self._data[name] = v
        self.descriptions[name] = description

    def to_dict(self) -> dict[str, np.ndarray]:
        """Column name -> array (copies)."""
        return {k: np.array(v) for k, v in self._data.items()}

    # ------------------------------------------------------------------ output
    def to_csv(self, path) -> Path:
        """Write the table as CSV with a commented header (``#`` lines): units, convention, metadata.

        The header holds ``# metadata: {json}``, ``# completed: ...``, then one ``# column: meaning``
        line per column; :func:`read_csv` reads the file back.
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        header = [
            "# femgran element test result",
            "# Tensor components sig_ij_kPa, eps_ij: tension positive; p, q, eps_v, eps_a, sig1..3: compression positive.",
            f"# completed: {self.completed}" + (f" ({self.message})" if self.message else ""),
            "# metadata: " + json.dumps(_jsonable(self.metadata), sort_keys=True),
        ]
        header += [f"# {k}: {d}" for k, d in self.descriptions.items()]
        names = self.columns
        data = np.column_stack([np.asarray(self._data[k], dtype=float) for k in names])
        with path.open("w", encoding="utf-8") as fh:
            fh.write("\n".join(header) + "\n")
            fh.write(",".join(names) + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.12g")
        return path

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
    """Read a table written by :meth:`ElementResult.to_csv` (columns, descriptions, metadata)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"result file {str(path)!r} does not exist")
    meta: dict[str, Any] = {}
    desc: dict[str, str] = {}
    completed, message = True, ""
    lines = path.read_text(encoding="utf-8").splitlines()
    body = [ln for ln in lines if not ln.startswith("#")]
    for ln in lines:
        if not ln.startswith("# ") or ": " not in ln:
            continue
        key, value = ln[2:].split(": ", 1)
        if key == "metadata":
            meta = json.loads(value)
        elif key == "completed":
            completed = value.startswith("True")
            message = value[value.find("(") + 1 : -1] if "(" in value else ""
        else:
            desc[key] = value
    names = body[0].split(",")
    data = np.loadtxt(body[1:], delimiter=",", ndmin=2)
    cols = {k: data[:, i] for i, k in enumerate(names)}
    n = data.shape[0]
    stress = np.zeros((n, 3, 3))
    strain = np.zeros((n, 3, 3))
    for comp, (i, j) in zip(COMPONENTS, _IJ):
        if f"sig_{comp}_kPa" in cols:
            stress[:, i, j] = stress[:, j, i] = cols[f"sig_{comp}_kPa"]
        if f"eps_{comp}" in cols:
            strain[:, i, j] = strain[:, j, i] = cols[f"eps_{comp}"]
    return ElementResult(cols, desc, stress, strain, meta, completed, message)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return repr(obj)
