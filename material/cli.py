"""``femgran element ...`` subcommand."""


def register(subparsers) -> None:
    """Add the element-test subcommand (filled in with the element drivers)."""
