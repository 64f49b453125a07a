"""``femgran dem ...`` and ``femgran calibrate ...`` subcommands."""


def register(subparsers) -> None:
    """Add the DEM subcommands (filled in with the DEM engine)."""
