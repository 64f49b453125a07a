"""femgran: boundary-value problems on scikit-fem with the anisotropic CPA sand model.

Subpackages: :mod:`femgran.cases` (element, triaxial specimen, strip footing, shear band).
The material laws live in the top-level package :mod:`material`, the 2D DEM in :mod:`dem`.

``import femgran`` is light: the solver, the assembly (scikit-fem) and the cases load on first use
of the names below.
"""

from importlib import import_module

from material.version import __version__

_LAZY = {
    "cases": ("femgran.cases", None),
    "Discretisation": ("femgran.assembly", "Discretisation"),
    "Dirichlet": ("femgran.solver", "Dirichlet"),
    "NewtonSolver": ("femgran.solver", "NewtonSolver"),
    "SolverOptions": ("femgran.solver", "SolverOptions"),
}

__all__ = ["cases", "__version__", "Discretisation", "Dirichlet", "NewtonSolver", "SolverOptions"]


def __getattr__(name: str):
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'femgran' has no attribute {name!r}") from None
    value = import_module(module) if attr is None else getattr(import_module(module), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
