"""``femgran figures``: regenerate the figure set from the package's own simulations (PNG + CSV each).

The material figures come from :mod:`material.figures` (element tests: Figs. 14, 20, 21, 45-47 and the
strength envelope). The DEM figures (Figs. 23-34, 38-44) are written by ``femgran dem sweep`` and the
FE field figures by the boundary-value cases (``femgran triaxial|footing|biaxial``), each next to
the data behind it.
"""

from __future__ import annotations

from pathlib import Path

from material.commandline import add_out, add_progress, write_run_record


def register(subparsers) -> None:
    from material.figures import FIGURES

    p = subparsers.add_parser(
        "figures",
        help="regenerate the thesis's model figures (PNG + CSV) from element simulations",
        description=__doc__,
    )
    add_out(p, "out/figures")
    p.add_argument("--only", nargs="+", metavar="NAME", choices=list(FIGURES),
                   help=f"only these figures; choices: {', '.join(FIGURES)}")
    p.add_argument("--full", action="store_true", help="the thesis's resolution (more load steps; slower)")
    add_progress(p)
    p.set_defaults(func=_run)


def _run(args) -> int:
    from material.figures import make_figures

    out = Path(args.out)
    written = make_figures(out, names=args.only, full=args.full, progress=args.progress)
    write_run_record(out, args, figures=args.only or "all", files=[p.name for p in written])
    for path in written:
        print(path)
    return 0
