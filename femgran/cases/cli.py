"""``femgran triaxial|footing|biaxial|run`` subcommands."""


def register(subparsers) -> None:
    """Add the boundary-value subcommands (filled in with the FE solver)."""
