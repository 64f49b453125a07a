"""Case files: a boundary-value run described as data (TOML), for ``femgran run case.toml``.

Format::

    case = "footing"              # element | triaxial | footing | biaxial
    out = "out/footing"           # run folder (optional; relative to the current directory)

    [material]                    # optional; default: CPA ottawa_c109 with axes from alpha_deg
    law = "cpa"                   # cpa | von_mises | drucker_prager | linear_elastic
    preset = "ottawa_c109"        # cpa: a preset name, or parameters = "my_sand.toml"
    rule = "bazant-oh-33"         # cpa: integration rule of the planes
    set = { beta = 5.0 }          # cpa: parameters to change (CPAParameters.replace)
    stabilisation = 0.1           # cpa: the step stabilisation of CPAModel (default 0: the thesis's law)
    # von_mises: E_kPa, nu, yield_stress_kPa, hardening_kPa
    # drucker_prager: E_kPa, nu, cohesion_kPa, friction_deg, dilation_deg, match, hardening_kPa
    # linear_elastic: E_kPa, nu

    [parameters]                  # keyword arguments of femgran.cases.<case>
    width_m = 1.0
    alpha_deg = 30.0

    [solver]                      # optional: fields of femgran.solver.SolverOptions
    tol = 1e-8
    max_iter = 25

Every key is checked before any computation: an unknown key raises ``ValueError`` naming it and the
allowed keys.
"""

from __future__ import annotations

import inspect
import tomllib
from pathlib import Path

__all__ = ["load_case", "run_case", "CASES", "LAWS"]

CASES = ("element", "triaxial", "footing", "biaxial")
LAWS = {
    "cpa": ("preset", "parameters", "rule", "set", "stabilisation"),
    "von_mises": ("E_kPa", "nu", "yield_stress_kPa", "hardening_kPa"),
    "drucker_prager": ("E_kPa", "nu", "cohesion_kPa", "friction_deg", "dilation_deg", "match", "hardening_kPa"),
    "linear_elastic": ("E_kPa", "nu"),
}
_TOP = ("case", "out", "material", "parameters", "solver")


def _case_function(name):
    import femgran.cases as c

    return getattr(c, name)


def _check_keys(where: str, given, allowed) -> None:
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed {sorted(allowed)}")


def _table(doc: dict, name: str) -> dict:
    value = doc[name]
    if not isinstance(value, dict):
        raise ValueError(f"{name} = {value!r}: must be a table [{name}]")
    return value


def build_material(spec: dict | None, alpha_deg: float, plane_strain: bool, base: Path = Path(".")):
    """The material object of a ``[material]`` table (None: the case default)."""
    import material as mlib

    if spec is None:
        return None
    spec = dict(spec)
    law = spec.pop("law", "cpa")
    if law not in LAWS:
        raise ValueError(f"[material] law = {law!r}: allowed {sorted(LAWS)}")
    _check_keys(f"[material] (law {law!r})", spec, LAWS[law])
    if law == "cpa":
        from material.factory import make_material

        if "parameters" in spec and "preset" in spec:
            raise ValueError("[material]: give either preset or parameters, not both")
        if "parameters" in spec:
            params = mlib.load_parameters(base / spec["parameters"])
        else:
            params = mlib.load_preset(spec.get("preset", "ottawa_c109"))
        if spec.get("set"):
            params = params.replace(**spec["set"])
        return make_material(params, alpha_deg=alpha_deg, plane_strain=plane_strain, rule=spec.get("rule"),
                             stabilisation=spec.get("stabilisation"))
    cls = {"von_mises": mlib.VonMises, "drucker_prager": mlib.DruckerPrager, "linear_elastic": mlib.LinearElastic}[law]
    try:
        return cls(**spec)
    except TypeError as exc:
        raise ValueError(f"[material] law {law!r}: {exc}") from None


def load_case(path) -> tuple[str, dict]:
    """Read and validate a case file. Returns (case name, keyword arguments incl. ``material``)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"case file {str(p)!r}: not found")
    try:
        doc = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"case file {str(p)!r}: not valid TOML ({exc})") from None
    _check_keys(f"case file {p.name}", doc, _TOP)
    case = doc.get("case")
    if case not in CASES:
        raise ValueError(f"case file {p.name}: case = {case!r}; allowed {list(CASES)}")
    func = _case_function(case)
    params = dict(doc.get("parameters", {}))
    allowed = [k for k in inspect.signature(func).parameters if k not in ("material", "solver")]
    _check_keys(f"[parameters] of case {case!r}", params, allowed)
    if "mesh" in params:
        mp = Path(params["mesh"])
        params["mesh"] = str(mp if mp.is_absolute() or mp.exists() else p.parent / mp)
        if not Path(params["mesh"]).is_file():
            raise FileNotFoundError(f"[parameters] mesh = {str(mp)!r}: file not found")
    alpha = float(params.get("alpha_deg", 0.0))
    kwargs = dict(params)
    kwargs["material"] = build_material(doc.get("material"), alpha, plane_strain=case in ("footing", "biaxial"),
                                        base=p.parent)
    if "out" in doc and "out" in allowed:
        kwargs["out"] = doc["out"]
    if "solver" in doc:
        from femgran.cases.common import solver_options

        kwargs["solver"] = solver_options(_table(doc, "solver"), where=f"[solver] of {p.name}")
    return case, kwargs


def run_case(path, **overrides):
    """Run the case of a case file (``overrides`` replace its parameters)."""
    case, kwargs = load_case(path)
    func = _case_function(case)
    accepted = inspect.signature(func).parameters
    kwargs.update({k: v for k, v in overrides.items() if k in accepted})
    sol = func(**kwargs)
    out = kwargs.get("out")
    if out is not None:
        import shutil

        shutil.copyfile(path, Path(out) / "case.toml")
    return sol
