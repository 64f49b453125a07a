"""``femgran figures``: regenerate the figure set from the package's own simulations (PNG + CSV each).

The material figures come from :mod:`material.figures` (element tests: Figs. 14, 20, 21, 45-47 and the
strength envelope). The DEM figures (Figs. 23-34, 38-44) are written by ``femgran dem sweep`` and the
FE field figures by the boundary-value cases (``femgran triaxial|footing|biaxial``), each next to
the data behind it.
"""

from __future__ import annotations

import json
from pathlib import Path


def register(subparsers) -> None:
    from material.figures import FIGURES

    p = subparsers.add_parser(
        "figures",
        help="regenerate the thesis's model figures (PNG + CSV) from element simulations",
        description=__doc__,
    )
    p.add_argument("--out", default="out/figures", help="output folder (default: out/figures)")
    p.add_argument("--only", nargs="+", metavar="NAME", choices=list(FIGURES),
                   help=f"only these figures; choices: {', '.join(FIGURES)}")
    p.add_argument("--full", action="store_true", help="the thesis's resolution (more load steps; slower)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from material.figures import make_figures
    from material.version import __version__

    out = Path(args.out)
    written = make_figures(out, names=args.only, full=args.full, progress=not args.no_progress)
    (out / "run.json").write_text(json.dumps(
        {"command": "figures", "figures": args.only or "all", "full": bool(args.full),
         "femgran_version": __version__, "files": [p.name for p in written]}, indent=2) + "\n")
    for path in written:
        print(path)
    return 0
