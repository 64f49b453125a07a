"""Boundary-value cases built on the femgran solver (the list below).

Every case is a frozen dataclass (geometry, loads, options; validated when made) with ``build`` and
``summarise``; :func:`run` does the rest the same way for all of them (:mod:`femgran.cases.base`):

* :class:`Element` / :func:`element` -- one hexahedron under homogeneous conditions (bridge to ``material.driver``);
* :class:`Triaxial` / :func:`triaxial` -- the 50 x 50 x 100 mm specimen between rough or smooth rigid platens (3D);
* :class:`Footing` / :func:`footing` -- rigid strip footing, plane strain, self weight and surcharge;
* :class:`Biaxial` / :func:`biaxial` -- plane-strain biaxial test with an imperfection (shear band);
* :class:`Cavity` / :func:`cavity` -- cylindrical cavity expansion (the example of a case in one module);
* :func:`run_case` -- a case described by a TOML file (``femgran run case.toml``).

The functions keep their keyword interface: ``footing(material, width_m=..., out=..., solver=...)`` is
``run(Footing(width_m=...), material, solver=..., output=Output(out=...))``. Each returns a
:class:`femgran.solver.Solution` (``history``, ``out_dir``, the case's summary as attributes).
"""

from femgran.cases.base import Output, Problem, run
from femgran.cases.biaxial import Biaxial, biaxial
from femgran.cases.casefile import load_case, run_case
from femgran.cases.cavity import Cavity, cavity
from femgran.cases.element import Element, element
from femgran.cases.footing import Footing, footing
from femgran.cases.triaxial import Triaxial, triaxial

__all__ = ["run", "Output", "Problem", "Element", "Triaxial", "Footing", "Biaxial", "Cavity", "element", "triaxial",
           "footing", "biaxial", "cavity", "run_case", "load_case"]
