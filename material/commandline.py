"""The flags every ``femgran`` subcommand speaks, defined once.

``material``, ``femgran`` and ``dem`` register their subcommands with these helpers, so the same flag
means the same thing everywhere (``material`` and ``dem`` do not import the FE package for it):

* ``--out`` the output folder (or file), and ``run.json`` written there: the command line, the options,
  the package version (:func:`write_run_record`);
* ``--preset``, ``--params FILE`` (``--parameters`` is the same flag) and ``--set KEY=VALUE`` (repeatable;
  a comma-separated VALUE is a list, e.g. ``--set a=0.4,0.45,19``) for the CPA parameters;
* a progress bar where stderr is a terminal, none where it is not (a batch job's log file or a pipe, into
  which the bar's carriage-return updates wrote one line of 20 kB for ``femgran footing --alpha 0``);
  ``--progress`` draws it there too, ``--no-progress`` nowhere (:func:`resolve_progress`). The Python API's
  ``progress=True`` draws it wherever it is asked for (a notebook's stderr is no terminal).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

__all__ = ["add_out", "add_progress", "resolve_progress", "add_parameters", "parse_set", "parameters_from_args",
           "with_changes", "write_run_record"]


def add_out(parser, default: str, help: str | None = None) -> None:
    parser.add_argument("--out", type=Path, default=Path(default),
                        help=help or f"output folder (default {default}); run.json is written there")


def add_progress(parser) -> None:
    parser.add_argument("--no-progress", dest="progress", action="store_false", default=None, help="no progress bar")
    parser.add_argument("--progress", dest="progress", action="store_true", default=None,
                        help="a progress bar even where stderr is not a terminal (default: on a terminal only)")


def resolve_progress(args, stream=None) -> None:
    """``args.progress`` as the subcommands read it: the flag given, or without one (None) whether ``stream``
    (default ``sys.stderr``) is a terminal."""
    if getattr(args, "progress", False) is None:
        stream = sys.stderr if stream is None else stream
        args.progress = bool(getattr(stream, "isatty", lambda: False)())


def add_parameters(parser, preset_default: str | None = "ottawa_c109") -> None:
    shown = preset_default or "the test's"
    parser.add_argument("--preset", default=preset_default, help=f"CPA parameter preset (default {shown})")
    parser.add_argument("--params", "--parameters", dest="params", metavar="FILE", default=None,
                        help="CPA parameter file (TOML/JSON) instead of a preset")
    parser.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                        help="change a CPA parameter (repeatable; a comma-separated VALUE is a list, e.g. a=0.4,0.45,19)")


def parse_set(items) -> dict:
    """``["beta=5", "a=0.4,0.45,19"]`` -> ``{"beta": 5.0, "a": [0.4, 0.45, 19.0]}``; a clear error otherwise."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE, e.g. beta=5")
        key, value = (s.strip() for s in item.split("=", 1))
        try:
            numbers = [float(v) for v in value.split(",")]
        except ValueError:
            raise ValueError(f"--set {item!r}: VALUE must be a number or comma-separated numbers") from None
        out[key] = numbers if "," in value else numbers[0]
    return out


def parameters_from_args(args, default_preset: str = "ottawa_c109"):
    """The CPAParameters of ``--preset`` / ``--params`` with the ``--set`` changes (a scalar given for a
    list-valued parameter, e.g. ``b=0.1``, becomes a one-element list)."""
    from material.parameters import load_parameters, load_preset

    params = load_parameters(args.params) if args.params else load_preset(args.preset or default_preset)
    return with_changes(params, parse_set(args.set))


def with_changes(params, changes: dict):
    """``params.replace(**changes)``, a scalar given for a list-valued parameter (``b=0.1``) made a list."""
    if not changes:
        return params
    lists = {k: [v] for k, v in changes.items() if isinstance(getattr(params, k, None), tuple)
             and not isinstance(v, (list, tuple))}
    return params.replace(**{**changes, **lists})


def write_run_record(out, args, **extra) -> Path:
    """``run.json`` in the folder ``out`` (next to it, as ``<name>.run.json``, when ``out`` is a file):
    the command line, every option, the package version and ``extra``, added to what the run itself
    recorded there (a DEM experiment writes its own ``run.json`` first)."""
    from material.version import __version__

    out = Path(out)
    path = out.with_name(out.stem + ".run.json") if out.suffix else out / "run.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    argv = getattr(args, "_argv", None)
    before = json.loads(path.read_text()) if path.is_file() else {}
    record = {**before, "command": "femgran " + " ".join(sys.argv[1:] if argv is None else argv),
              "options": {k: v for k, v in vars(args).items() if k != "func" and not k.startswith("_")},
              "femgran_version": __version__, **extra}
    path.write_text(json.dumps(record, indent=2, default=str) + "\n")
    return path
