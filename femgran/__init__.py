"""femgran: boundary-value problems on scikit-fem with the anisotropic CPA sand model.

Subpackages: :mod:`femgran.cases` (element, triaxial specimen, strip footing, shear band).
The material laws live in the top-level package :mod:`material`, the 2D DEM in :mod:`dem`.
"""

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("femgran")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.1.0+src"

from femgran import cases  # noqa: E402
from femgran.assembly import Discretisation  # noqa: E402
from femgran.solver import Dirichlet, NewtonSolver, SolverOptions  # noqa: E402

__all__ = ["cases", "__version__", "Discretisation", "Dirichlet", "NewtonSolver", "SolverOptions"]
