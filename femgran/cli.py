"""The ``femgran`` command line: one entry point, one subcommand per job.

Each area of the package registers its own subcommands (``register(subparsers)``), so this module
only assembles them:

* :mod:`material.cli` -- ``femgran element ...`` (single-point element tests);
* :mod:`femgran.cases.cli` -- ``femgran triaxial|footing|biaxial|run ...`` (boundary-value problems);
* :mod:`dem.cli` -- ``femgran dem ...`` and ``femgran calibrate ...`` (virtual experiments);
* :mod:`femgran.figures` -- ``femgran figures`` (every figure, from the package's own simulations);
* :mod:`femgran.sweep` -- ``femgran sweep`` (any run over a grid or a list, on Dask);
* :mod:`material.identify_cli` -- ``femgran identify direct-shear|triaxial`` (parameters from lab data).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from material.commandline import resolve_progress

_REGISTRARS = ("material.cli", "femgran.cases.cli", "dem.cli", "femgran.figures", "femgran.sweep", "material.identify_cli")


def build_parser() -> argparse.ArgumentParser:
    from material.version import __version__

    parser = argparse.ArgumentParser(
        prog="femgran",
        description="Anisotropic sand: CPA material model, scikit-fem boundary-value problems, 2D DEM.",
    )
    parser.add_argument("--version", action="version", version=f"femgran {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _REGISTRARS:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args._argv = list(sys.argv[1:] if argv is None else argv)  # for the run records (material.commandline)
    resolve_progress(args)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: the run wrote its checkpoint and said where
        print(f"femgran {args.command}: {exc or 'interrupted'}", file=sys.stderr)
        return 130
    except (ValueError, KeyError, FileNotFoundError) as exc:
        # Bad input: one clear line, no traceback from deep inside numpy.
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"femgran {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
