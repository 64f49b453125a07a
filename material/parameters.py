"""Parameters of the microplane CPA law: an immutable, validated dataclass, presets, TOML/JSON I/O.

Units throughout: kPa for stresses and moduli, m for lengths (``docs/model.md``, "Units").
Every value is checked when the object is made (also by :meth:`CPAParameters.replace`), and a bad
value raises ``ValueError`` naming the key, the value and the allowed range; an unknown key in a file
raises ``KeyError`` naming it and the keys that are allowed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

__all__ = [
    "CPAParameters",
    "PRESETS",
    "load_preset",
    "load_parameters",
    "save_parameters",
]

_FILE_FORMAT = "femgran-cpa-parameters"
#: Default apex stress of the planes [kPa] (:attr:`CPAParameters.apex_stress`; its choice is measured
#: in ``docs/cpa_law.md``).
APEX_STRESS_KPA = 0.04
#: Default normal stress below which the planes' compaction fades [kPa] (:attr:`CPAParameters.compaction_stress`).
COMPACTION_STRESS_KPA = 2.0
_FILE_VERSION = 1


@dataclass(frozen=True, slots=True)
class CPAParameters:
    """Microplane Critical Plane Approach law (``docs/model.md``; thesis eqs. 2.3-2.4, 2.16-2.17, 3.15).

    Attributes
    ----------
    E : float
        Young's modulus [kPa], > 0.
    nu : float
        Poisson's ratio [-], in (-1, 0.5).
    t : float
        Band thickness of a sliding plane [m], > 0 (eq. 2.8).
    A : float
        Hardening constant of eta(kappa) = zeta eta_f kappa / (A + kappa) [m], > 0 (eq. 2.16).
    eta0 : float
        Mean friction coefficient [-], > 0 (eq. 2.4).
    omega1 : float
        Inherent anisotropy: Omega = diag(omega1, -2 omega1, omega1) in the material frame, e2 the
        deposition axis [-], |omega1| < 0.5 so that Omega_ij n_i n_j stays in (-1, 1) (eq. 2.19).
    a : tuple of float
        Higher-order coefficients a1, a2, ... of eta_f = eta0 (1 + x + a1 x^2 + a2 x^3 + ...) (eq. 2.4).
    eta_c_ratio : float
        eta_c / eta_f, the compaction-dilation transition, in [0, 1] (eq. 2.17; Table 3: 0.65).
    c0 : float
        Mean cohesion [kPa], >= 0 (eq. 2.4).
    omega1_c : float
        Anisotropy of the cohesion, same form as omega1 [-], |omega1_c| < 0.5.
    b : tuple of float
        Higher-order coefficients of the cohesion series (eq. 2.4).
    zeta : float
        Asymptote factor of the hardening law, >= 1; zeta > 1 puts the onset of instability at the
        finite slip kappa* = A / (zeta - 1) (thesis 2.3.4).
    beta : float
        Induced anisotropy Lambda = beta * dev(total strain), tension positive [-], >= 0 (eq. 3.15).
    alpha_hat, beta_hat : float
        Constants of the general coaxial evolution law (eq. 3.8): the induced tensor is
        Lambda = beta |e| n^Omega with n^Omega = alpha_hat n^e + beta_hat dev(n^e n^e), normalised
        (n^e = e / |e|, e the strain deviator). The defaults alpha_hat = 1, beta_hat = 0 give exactly
        Lambda = beta e (eq. 3.15 / the linear form 3.9). alpha_hat >= 0.
    softening_slip : float
        Post-peak softening of a plane [m], >= 0; 0 (the default, the thesis's law) switches it off.
        With zeta > 1 a plane reaches eta_f at kappa* = A / (zeta - 1), the thesis's onset of
        instability; beyond it the mobilised ratio decays hyperbolically (the mirror of 2.16),
        eta = eta_f (r + (1 - r) / (1 + d / softening_slip)),
        with d the slip past kappa* measured across the shear band (= (kappa - kappa*) h / t in a finite
        element of size h: the regularisation by the band thickness t, :mod:`material.cpa`). Requires
        zeta > 1. Without the step stabilisation a steep softening makes the point itself snap back at its
        peak, where no strain-driven solution goes on: on the plane-strain element path at p0 = 100 kPa that
        takes softening_slip below 0.002-0.046 m at E = 60 MPa and 0.01-0.08 m at 6 MPa, by rule and
        bedding (``docs/cpa_law.md``, section 5.2; ``CPAModel.explain_failure`` names such a point).
    residual_ratio : float
        r = eta_residual / eta_f of the softening law, in (0, 1] [-]; default 0.65, the compaction-dilation
        transition eta_c / eta_f of Table 3 (the critical state: no more dilation in the band).
    apex_stress : float
        c_a [kPa], > 0: the normal tension at which every plane's loading cone has its apex. The
        mobilised ratio is sqrt(tau^2 + b^2) / (sigma_N + c / eta_f + c_a), b = c_a / 10, in place of
        (tau - c) / sigma_N: each loading surface is a convex cone with a rounded tip in tension, so the
        law is smooth through zero stress and a stress-free plane is mobilised to 0.1. Shifting every
        normal stress by c_a acts like raising the confinement by c_a: the drained triaxial strength at
        p0 rises by c_a / p0 (``docs/cpa_law.md``; the default 0.04 kPa: 0.4 % at p0 = 10 kPa).
    compaction_stress : float
        p_c [kPa], >= 0: the compaction-dilation transition of a plane is eta_c w with
        w = s^2 / (s^2 + p_c^2), s = sigma_N + c / eta_f + c_a, so a plane compacts as the thesis says at
        working stresses (w = 0.99 at s = 10 p_c) and not at all as its normal stress vanishes, where
        the strain-driven update of a contractive plane set has no solution (``docs/cpa_law.md``).
        0 keeps the thesis's flow rule at every stress.
    """

    E: float
    nu: float
    t: float
    A: float
    eta0: float
    omega1: float = 0.0
    a: tuple[float, ...] = ()
    eta_c_ratio: float = 0.65
    c0: float = 0.0
    omega1_c: float = 0.0
    b: tuple[float, ...] = ()
    zeta: float = 1.0
    beta: float = 0.0
    alpha_hat: float = 1.0
    beta_hat: float = 0.0
    softening_slip: float = 0.0
    residual_ratio: float = 0.65
    apex_stress: float = APEX_STRESS_KPA
    compaction_stress: float = COMPACTION_STRESS_KPA
    name: str = field(default="custom", compare=False)

    def __post_init__(self) -> None:
        for key in ("a", "b"):
            value = getattr(self, key)
            try:
                if isinstance(value, (str, bytes)):
                    raise TypeError(key)  # a string would be split into digits
                coeffs = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                raise ValueError(
                    f"parameter {key!r} = {value!r}: expected a sequence of numbers (a1, a2, ...)"
                ) from None
            object.__setattr__(self, key, coeffs)
        for spec in _FIELD_SPECS:
            value = getattr(self, spec.name)
            if spec.name in ("a", "b"):
                for i, v in enumerate(value):
                    if not math.isfinite(v):
                        raise ValueError(f"parameter {spec.name!r}[{i}] = {v!r}: must be a finite number")
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"parameter {spec.name!r} = {value!r}: must be a number; allowed: {spec.allowed}")
            value = float(value)
            object.__setattr__(self, spec.name, value)
            if not spec.check(value):
                raise ValueError(
                    f"parameter {spec.name!r} = {value!r} is out of range; allowed: {spec.allowed} [{spec.unit}]"
                )
        if self.alpha_hat == 0.0 and self.beta_hat == 0.0 and self.beta != 0.0:
            raise ValueError(
                "parameters 'alpha_hat' = 0 and 'beta_hat' = 0 give no direction to the induced tensor while "
                f"'beta' = {self.beta!r}; allowed: alpha_hat > 0 or beta_hat != 0 (defaults 1, 0: Lambda = beta e)"
            )
        if self.softening_slip > 0.0 and self.zeta == 1.0:
            raise ValueError(
                f"parameter 'softening_slip' = {self.softening_slip!r} needs 'zeta' > 1 (the peak eta = eta_f is "
                "reached at kappa* = A / (zeta - 1), infinite for zeta = 1); allowed: zeta in (1, 2] with "
                "softening, or softening_slip = 0"
            )

    # ------------------------------------------------------------------ derived quantities
    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) [kPa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def bulk_modulus(self) -> float:
        """K = E / (3 (1 - 2 nu)) [kPa]."""
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))

    @property
    def kappa_instability(self) -> float:
        """Slip kappa* = A / (zeta - 1) [m] at which eta reaches eta_f (inf for zeta = 1)."""
        return math.inf if self.zeta == 1.0 else self.A / (self.zeta - 1.0)

    def replace(self, **changes: Any) -> "CPAParameters":
        """A copy with some fields changed; the copy is validated like any new object."""
        unknown = set(changes) - set(FIELD_NAMES)
        if unknown:
            raise KeyError(f"unknown parameter(s) {sorted(unknown)}; allowed: {list(FIELD_NAMES)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of all fields (tuples as lists), keys as in the dataclass."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out


@dataclass(frozen=True)
class _FieldSpec:
    name: str
    unit: str
    allowed: str
    check: Any


_FIELD_SPECS = (
    _FieldSpec("E", "kPa", "E > 0 (finite)", lambda v: math.isfinite(v) and v > 0),
    _FieldSpec("nu", "-", "-1 < nu < 0.5", lambda v: -1.0 < v < 0.5),
    _FieldSpec("t", "m", "t > 0 (finite)", lambda v: math.isfinite(v) and v > 0),
    _FieldSpec("A", "m", "A > 0 (finite)", lambda v: math.isfinite(v) and v > 0),
    _FieldSpec("eta0", "-", "eta0 > 0 (finite)", lambda v: math.isfinite(v) and v > 0),
    _FieldSpec("omega1", "-", "-0.5 < omega1 < 0.5", lambda v: -0.5 < v < 0.5),
    _FieldSpec("a", "-", "finite numbers", None),
    _FieldSpec("eta_c_ratio", "-", "0 <= eta_c_ratio <= 1", lambda v: 0.0 <= v <= 1.0),
    _FieldSpec("c0", "kPa", "c0 >= 0 (finite)", lambda v: math.isfinite(v) and v >= 0),
    _FieldSpec("omega1_c", "-", "-0.5 < omega1_c < 0.5", lambda v: -0.5 < v < 0.5),
    _FieldSpec("b", "-", "finite numbers", None),
    _FieldSpec("zeta", "-", "1 <= zeta <= 2", lambda v: 1.0 <= v <= 2.0),
    _FieldSpec("beta", "-", "0 <= beta (finite)", lambda v: math.isfinite(v) and v >= 0),
    _FieldSpec("alpha_hat", "-", "0 <= alpha_hat (finite)", lambda v: math.isfinite(v) and v >= 0),
    _FieldSpec("beta_hat", "-", "finite", lambda v: math.isfinite(v)),
    _FieldSpec("softening_slip", "m", "softening_slip >= 0 (finite; 0: no softening)",
               lambda v: math.isfinite(v) and v >= 0),
    _FieldSpec("residual_ratio", "-", "0 < residual_ratio <= 1", lambda v: 0.0 < v <= 1.0),
    _FieldSpec("apex_stress", "kPa", "apex_stress > 0 (finite)", lambda v: math.isfinite(v) and v > 0),
    _FieldSpec("compaction_stress", "kPa", "compaction_stress >= 0 (finite; 0: the thesis's flow rule)",
               lambda v: math.isfinite(v) and v >= 0),
)
FIELD_NAMES = tuple(s.name for s in _FIELD_SPECS) + ("name",)
UNITS = {s.name: s.unit for s in _FIELD_SPECS}

PRESETS: dict[str, CPAParameters] = {
    # Table 3 of the thesis, inherent anisotropy of Ottawa C109 sand.
    "ottawa_c109": CPAParameters(
        E=6000.0, nu=0.33, t=0.006, A=1.58e-4, eta0=0.8896, omega1=0.1398,
        a=(0.3956, 0.4457, 18.96), eta_c_ratio=0.65, c0=0.0, zeta=1.0, beta=0.0, name="ottawa_c109",
    ),
    # Section 3.5: initially isotropic, induced anisotropy Lambda = beta e (eq. 3.15).
    "ottawa_c109_induced": CPAParameters(
        E=6000.0, nu=0.33, t=0.006, A=1.0e-4, eta0=0.89, omega1=0.0,
        a=(0.3956, 0.4457, 18.96), eta_c_ratio=0.65, c0=0.0, zeta=1.0, beta=0.1, name="ottawa_c109_induced",
    ),
}


def load_preset(name: str) -> CPAParameters:
    """The named parameter set: one of ``PRESETS`` (``ottawa_c109``, ``ottawa_c109_induced``)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown preset {name!r}; available: {sorted(PRESETS)}") from None


def save_parameters(params: CPAParameters, path: str | Path, **metadata: Any) -> Path:
    """Write ``params`` to a TOML (``.toml``) or JSON (``.json``) file with a units table.

    Extra keyword arguments go into a ``[metadata]`` table (e.g. the seed or the package version of
    the run that produced the parameters); they are ignored by :func:`load_parameters`.
    """
    path = Path(path)
    doc: dict[str, Any] = {
        "format": _FILE_FORMAT,
        "version": _FILE_VERSION,
        "parameters": params.to_dict(),
        "units": dict(UNITS),
    }
    if metadata:
        doc["metadata"] = {k: _plain(v) for k, v in metadata.items()}
    suffix = path.suffix.lower()
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".toml":
        path.write_text(tomli_w.dumps(doc))
    elif suffix == ".json":
        path.write_text(json.dumps(doc, indent=2) + "\n")
    else:
        raise ValueError(f"parameter file {str(path)!r}: suffix {suffix!r} not supported; allowed: '.toml', '.json'")
    return path


def load_parameters(path: str | Path) -> CPAParameters:
    """Read a parameter file written by :func:`save_parameters` (or by hand).

    The file holds a ``[parameters]`` table with the dataclass field names (a flat file with the
    fields at the top level is accepted too), optionally ``preset = "name"`` inside it to start from a
    preset and override some fields. Unknown keys raise ``KeyError``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"parameter file {str(path)!r} does not exist")
    suffix = path.suffix.lower()
    text = path.read_text()
    try:
        if suffix == ".toml":
            doc = tomllib.loads(text)
        elif suffix == ".json":
            doc = json.loads(text)
        else:
            raise ValueError(
                f"parameter file {str(path)!r}: suffix {suffix!r} not supported; allowed: '.toml', '.json'"
            )
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"parameter file {str(path)!r} could not be parsed: {exc}") from None
    return parameters_from_dict(doc, source=str(path))


def parameters_from_dict(doc: dict[str, Any], source: str = "<dict>") -> CPAParameters:
    """Build parameters from a mapping as read from a file (see :func:`load_parameters`)."""
    table = doc.get("parameters", None)
    if table is None:
        table = {k: v for k, v in doc.items() if k not in ("format", "version", "units", "metadata")}
    elif not isinstance(table, dict):
        raise ValueError(f"{source}: 'parameters' must be a table, got {table!r}")
    table = dict(table)
    base = table.pop("preset", None)
    unknown = sorted(set(table) - set(FIELD_NAMES))
    if unknown:
        raise KeyError(f"{source}: unknown parameter key(s) {unknown}; allowed: {list(FIELD_NAMES)}")
    if base is not None:
        return load_preset(base).replace(**table)
    missing = [k for k in ("E", "nu", "t", "A", "eta0") if k not in table]
    if missing:
        raise KeyError(f"{source}: missing required parameter(s) {missing} (or give preset = '...')")
    return CPAParameters(**table)


def _plain(v: Any) -> Any:
    if isinstance(v, (str, int, float, bool)):
        return v
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    return str(v)
