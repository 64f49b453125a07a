"""One table type and one CSV format for every result: element tests, FE histories, DEM runs, sweep summaries.

A :class:`Table` holds named columns of numbers, what each column means (unit and sign convention) and
the run's metadata. Its CSV file is plain comma-separated numbers under a commented header::

    # femgran table: <title>
    # convention: <sign convention of the columns>
    # metadata: {"test": "triaxial", ...}
    # q_kPa: deviator stress [kPa], compression +
    # ...
    step,q_kPa,...
    0,0,...

Any CSV reader that skips ``#`` lines reads the numbers; :func:`read_table` reads everything back.
Values are written with 17 significant digits, so a table read back is the table written, to the bit.
:class:`TableWriter` writes the same format row by row (flushed), so a run that stops leaves a
readable file.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Table", "TableWriter", "read_table", "truncate_rows", "jsonable"]

_FMT = "%.17g"


def jsonable(obj):
    """``obj`` with numpy values, tuples and unknown objects made JSON-able (unknown objects by repr)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return repr(obj) if not isinstance(obj, Path) else str(obj)


class Table:
    """Named columns of numbers with their descriptions and the run's metadata.

    Rows can be appended one at a time (:meth:`append`; a column missing from a row is NaN there) or
    whole columns given at once (``Table({"x": [...], ...})``, :meth:`add_column`).
    """

    title = "table"

    def __init__(self, columns: dict | None = None, descriptions: dict | None = None, metadata: dict | None = None,
                 *, title: str | None = None, convention: str = ""):
        self._data: dict[str, list] = {}
        self._n = 0
        if columns:
            lengths = {k: len(np.atleast_1d(v)) for k, v in columns.items()}
            if len(set(lengths.values())) > 1:
                raise ValueError(f"columns of different lengths: {lengths}")
            self._n = next(iter(lengths.values()))
            self._data = {k: list(np.asarray(v)) for k, v in columns.items()}
        self.descriptions = dict(descriptions or {})
        self.metadata = dict(metadata or {})
        if title is not None:
            self.title = title
        self.convention = convention

    # ------------------------------------------------------------------ access
    @property
    def columns(self) -> list[str]:
        """Column names in table order."""
        return list(self._data)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return np.asarray(self._data[name], dtype=float)
        except KeyError:
            raise KeyError(f"no column {name!r}; available: {self.columns}") from None

    def __contains__(self, name: str) -> bool:
        return name in self._data

    def __len__(self) -> int:
        return self._n

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.title!r}, {len(self)} rows, columns={self.columns})"

    def rows(self) -> list[dict]:
        """The rows as dicts (column -> value)."""
        return [{k: v[i] for k, v in self._data.items()} for i in range(self._n)]

    def to_dict(self) -> dict[str, np.ndarray]:
        """Column name -> array (copies)."""
        return {k: np.array(v, dtype=float) for k, v in self._data.items()}

    # ------------------------------------------------------------------ building
    def append(self, row: dict) -> None:
        """Add one row; a new column gets NaN in the earlier rows, a column missing from ``row`` NaN here."""
        for key in row:
            if key not in self._data:
                self._data[key] = [np.nan] * self._n
        for key, values in self._data.items():
            values.append(row.get(key, np.nan))
        self._n += 1

    def add_column(self, name: str, values, description: str = "") -> None:
        """Add (or replace) a column of length ``len(self)``."""
        v = np.asarray(values)
        if v.shape != (len(self),):
            raise ValueError(f"column {name!r}: expected shape ({len(self)},), got {v.shape}")
        self._data[name] = list(v)
        if description:
            self.descriptions[name] = description

    # ------------------------------------------------------------------ files
    def header(self, names=None) -> list[str]:
        """The commented header lines (without the column-name line) for the columns ``names`` (default all)."""
        names = self.columns if names is None else names
        lines = [f"# femgran table: {self.title}"]
        if self.convention:
            lines.append(f"# convention: {self.convention}")
        lines.append("# metadata: " + json.dumps(jsonable(self.metadata), sort_keys=True))
        lines += [f"# {k}: {self.descriptions[k]}" for k in names if self.descriptions.get(k)]
        return lines

    def write_csv(self, path) -> Path:
        """Write the table (module docstring: the format); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        names = self.columns
        with path.open("w", encoding="utf-8") as fh:
            fh.write("\n".join(self.header()) + "\n" + ",".join(names) + "\n")
            if names and len(self):
                data = np.column_stack([np.asarray(self._data[k], dtype=float) for k in names])
                np.savetxt(fh, data, delimiter=",", fmt=_FMT)
        return path

    to_csv = write_csv


class TableWriter:
    """Writes a table row by row in the format of :meth:`Table.write_csv` (each row flushed): the header
    and the column names with the first row, whose keys fix the columns."""

    def __init__(self, path, *, title: str, descriptions: dict | None = None, metadata: dict | None = None,
                 convention: str = "", append: bool = False):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._table = Table(descriptions=descriptions, metadata=metadata, title=title, convention=convention)
        self._cols: list[str] | None = None
        if append and self.path.is_file() and self.path.stat().st_size:
            self._cols = read_table(self.path).columns
        self._fh = self.path.open("a" if append else "w", encoding="utf-8")

    def write(self, row: dict) -> None:
        if self._cols is None:
            self._cols = list(row)
            self._fh.write("\n".join(self._table.header(self._cols)) + "\n" + ",".join(self._cols) + "\n")
        self._fh.write(",".join(_FMT % float(row.get(c, np.nan)) for c in self._cols) + "\n")
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()

    def __del__(self):  # a log nobody closes (the Newton log of a run) is closed with its writer
        fh = getattr(self, "_fh", None)
        if fh is not None and not fh.closed:
            fh.close()


def truncate_rows(path, n_rows: int) -> None:
    """Keep the header and the first ``n_rows`` data rows of a table file (a run resumed from a checkpoint
    drops the rows written after it)."""
    path = Path(path)
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    head = next((i for i, ln in enumerate(lines) if not ln.startswith("#")), len(lines)) + 1
    tmp = path.with_name(".tmp_" + path.name)
    tmp.write_text("".join(lines[: head + int(n_rows)]), encoding="utf-8")
    tmp.replace(path)


def read_table(path, cls=Table) -> Table:
    """Read a CSV written by :meth:`Table.write_csv` or :class:`TableWriter` (or any CSV of numbers with
    one header line, ``#`` lines skipped); returns an instance of ``cls``."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"table file {str(path)!r} does not exist")
    lines = path.read_text(encoding="utf-8").splitlines()
    comments = [ln[2:] for ln in lines if ln.startswith("# ")]
    body = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    if not body:
        raise ValueError(f"table file {str(path)!r}: no header line")
    names = body[0].split(",")
    rows = []
    for i, ln in enumerate(body[1:], start=1):
        values = ln.split(",")
        if len(values) != len(names):
            raise ValueError(f"table file {str(path)!r}: data row {i} has {len(values)} values for {len(names)} "
                             "columns")
        try:
            rows.append([float(v) for v in values])
        except ValueError:
            raise ValueError(f"table file {str(path)!r}: data row {i} holds a value that is not a number: "
                             f"{ln!r}") from None
    data = np.array(rows, dtype=float).reshape(len(rows), len(names))
    meta: dict[str, Any] = {}
    desc: dict[str, str] = {}
    title, convention = None, ""
    for c in comments:
        key, _, value = c.partition(": ")
        if key == "femgran table":
            title = value
        elif key == "convention":
            convention = value
        elif key == "metadata":
            meta = json.loads(value)
        elif key in names:
            desc[key] = value
        else:
            meta.setdefault("header", {})[key] = value  # e.g. the "completed" line of older element results
    table = cls.__new__(cls)
    Table.__init__(table, {k: data[:, i] for i, k in enumerate(names)}, desc, meta, title=title,
                   convention=convention)
    if not names or not rows:
        table._data = {k: [] for k in names}
        table._n = 0
    return table
