"""Case files: a boundary-value run described as data (TOML), for ``femgran run case.toml``.

Format (four tables, each checked against the dataclass it fills)::

    [case]                        # femgran.cases.<Case> fields
    name = "footing"              # element | triaxial | footing | biaxial | cavity
    width_m = 1.0
    alpha_deg = 30.0

    [material]                    # optional; default: CPA ottawa_c109 with axes from alpha_deg
    law = "cpa"                   # cpa | von_mises | drucker_prager | mohr_coulomb | linear_elastic
    preset = "ottawa_c109"        # cpa: a preset name, or parameters = "my_sand.toml"
    rule = "bazant-oh-33"         # cpa: integration rule of the planes
    set = { beta = 5.0 }          # cpa: parameters to change (CPAParameters.replace)
    stabilisation = 0.1           # cpa: the step stabilisation of CPAModel (default 0: the thesis's law)
    relaxation_time = 0.025       # cpa: its relaxation time in load factor (default: one nominal step)
    nonlocal_length = 0.006       # cpa with softening: the implicit gradient's length l [m] (not the crack band)
    # von_mises: E_kPa, nu, yield_stress_kPa, hardening_kPa (and length_m, over_nonlocal: the gradient law)
    # drucker_prager: E_kPa, nu, cohesion_kPa, friction_deg, dilation_deg, match, hardening_kPa
    # mohr_coulomb: E_kPa, nu, cohesion_kPa, friction_deg, dilation_deg
    # linear_elastic: E_kPa, nu

    [solver]                      # optional: femgran.solver.SolverOptions fields
    tol = 1e-8
    max_iter = 25

    [output]                      # optional: femgran.cases.base.Output fields
    out = "out/footing"           # run folder, relative to the current directory
    write_every = 1

Every key is checked before any computation: an unknown key raises ``ValueError`` naming it, its table
and the allowed keys. Paths in the file (a mesh, a parameter file) are relative to the file.

The earlier layout (``case = "footing"``, ``out = ...`` and a ``[parameters]`` table of the case
function's keywords) is still read.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

__all__ = ["load_case", "run_case", "CASES"]

CASES = ("element", "triaxial", "footing", "biaxial", "cavity")
_TABLES = ("case", "material", "solver", "output")
_LEGACY_TOP = ("case", "out", "material", "parameters", "solver")


def case_types() -> dict:
    """name -> case dataclass."""
    from femgran.cases.biaxial import Biaxial
    from femgran.cases.cavity import Cavity
    from femgran.cases.element import Element
    from femgran.cases.footing import Footing
    from femgran.cases.triaxial import Triaxial

    return {c.name: c for c in (Element, Triaxial, Footing, Biaxial, Cavity)}


def _check_keys(where: str, given, allowed) -> None:
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed {sorted(allowed)}")


def _table(doc: dict, name: str, where: str) -> dict:
    value = doc.get(name, {})
    if not isinstance(value, dict):
        raise ValueError(f"{where}: {name} = {value!r} must be a table [{name}]")
    return dict(value)


def _fields(cls) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def build_material(spec: dict | None, alpha_deg: float, plane_strain: bool, base: Path = Path(".")):
    """The material object of a ``[material]`` table (None: the case default), :func:`material.factory.make_material`."""
    from material.factory import make_material

    return None if spec is None else make_material(spec, alpha_deg=alpha_deg, plane_strain=plane_strain, base=base)


def _legacy(doc: dict, where: str) -> dict:
    """The earlier layout (``case = "name"``, ``out``, ``[parameters]``) as the four tables."""
    from femgran.cases.base import Output

    _check_keys(where, doc, _LEGACY_TOP)
    params = _table(doc, "parameters", where)
    output = {k: params.pop(k) for k in [f for f in _fields(Output) if f in params]}
    if "out" in doc:
        output.setdefault("out", doc["out"])
    solver = _table(doc, "solver", where)
    for key in ("tol", "linear_solver"):
        if key in params:
            solver[key] = params.pop(key)
    tables = {"case": {"name": doc["case"], **params}, "solver": solver, "output": output}
    if "material" in doc:
        tables["material"] = doc["material"]
    return tables


def load_case(path):
    """Read and validate a case file. Returns (case, material, solver options, output)."""
    from femgran.cases.base import Output
    from femgran.cases.common import solver_options

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"case file {str(p)!r}: not found")
    try:
        doc = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"case file {str(p)!r}: not valid TOML ({exc})") from None
    where = f"case file {p.name}"
    if isinstance(doc.get("case"), str):
        doc = _legacy(doc, where)
    _check_keys(where, doc, _TABLES)
    fields = _table(doc, "case", where)
    name = fields.pop("name", None)
    types = case_types()
    if name is None:
        others = f" (it has {sorted(fields)})" if fields else ""
        raise ValueError(f"{where}: [case] needs a name{others}; allowed {sorted(types)}")
    if name not in types:
        raise ValueError(f"{where}: [case] name = {name!r}; allowed {sorted(types)}")
    cls = types[name]
    _check_keys(f"[case] of {p.name} (case {name!r})", fields, _fields(cls))
    if fields.get("mesh") is not None:
        mp = Path(fields["mesh"])
        fields["mesh"] = str(mp if mp.is_absolute() or mp.exists() else p.parent / mp)
        if not Path(fields["mesh"]).is_file():
            raise FileNotFoundError(f"[case] mesh = {str(mp)!r}: file not found")
    case = cls(**fields)
    material = build_material(doc.get("material"), getattr(case, "alpha_deg", 0.0), cls.plane_strain, base=p.parent)
    solver = solver_options(_table(doc, "solver", where), where=f"[solver] of {p.name}")
    output_fields = _table(doc, "output", where)
    _check_keys(f"[output] of {p.name}", output_fields, _fields(Output))
    return case, material, solver, Output(**output_fields)


def run_case(path, *, solver=None, resume: bool = False, **output_overrides):
    """Run the case of a case file. ``solver``: fields of :class:`femgran.solver.SolverOptions` that replace
    the file's ``[solver]`` values; ``output_overrides``: fields of :class:`femgran.cases.base.Output`, e.g.
    ``progress=True``. The file is copied into the run folder as ``case.toml`` first (``femgran run --resume``
    reads it); ``resume``: continue the run in the output folder from its last checkpoint."""
    from femgran.cases.base import run
    from femgran.cases.common import solver_options

    case, material, file_solver, output = load_case(path)
    if solver:
        file_solver = solver_options({**file_solver.to_dict(), **dict(solver)}, where="solver")
    solver = file_solver
    if output_overrides:
        output = dataclasses.replace(output, **output_overrides)
    if output.out is not None and not resume:
        import shutil

        Path(output.out).mkdir(parents=True, exist_ok=True)
        if Path(path).resolve() != (Path(output.out) / "case.toml").resolve():
            shutil.copyfile(path, Path(output.out) / "case.toml")
    sol = run(case, material, solver=solver, output=output, resume=resume)
    return sol
