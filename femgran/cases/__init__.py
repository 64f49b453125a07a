"""Boundary-value cases built on the femgran solver (CASES.md section 2).

* :func:`element` -- one hexahedron under homogeneous conditions (bridge to ``material.driver``);
* :func:`triaxial` -- the 50 x 50 x 100 mm specimen between rough or smooth rigid platens (3D);
* :func:`footing` -- rigid strip footing, plane strain, self weight and surcharge;
* :func:`biaxial` -- plane-strain biaxial test with an imperfection (shear band);
* :func:`run_case` -- a case described by a TOML file (``femgran run case.toml``).

Each returns a :class:`femgran.solver.Solution` (``history``, ``out_dir``, case-specific attributes).
"""

from femgran.cases.biaxial import biaxial
from femgran.cases.casefile import load_case, run_case
from femgran.cases.element import element
from femgran.cases.footing import footing
from femgran.cases.triaxial import triaxial

__all__ = ["element", "triaxial", "footing", "biaxial", "run_case", "load_case"]
