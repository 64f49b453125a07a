"""The version of the installed ``femgran`` distribution, read from its metadata.

Import-free on purpose: ``material`` and ``dem`` record the version next to their results without
importing the FE package (``femgran``), which would load scikit-fem and every case.
"""

from importlib.metadata import PackageNotFoundError, version as _distribution_version

try:
    __version__ = _distribution_version("femgran")
except PackageNotFoundError:  # a source tree that is not installed
    __version__ = "0.1.0+src"

__all__ = ["__version__"]
