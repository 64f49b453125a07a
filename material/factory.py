"""One way to turn what a user gives into a material object, for the element drivers, the cases and the CLI.

What may be given (``spec``):

* ``None``: the CPA law with the ``ottawa_c109`` preset;
* a preset name (``"ottawa_c109"``, see :func:`material.parameters.preset_names`) or the path of a
  parameter file (``.toml`` / ``.json``, :func:`material.load_parameters`);
* :class:`material.CPAParameters`;
* a material object (anything with ``initial_state`` and ``update``), used as it is;
* a mapping, the ``[material]`` table of a case file: ``law`` (``"cpa"``, the default, ``"von_mises"``,
  ``"drucker_prager"``, ``"mohr_coulomb"``, ``"linear_elastic"``) and that law's keys (:data:`LAWS`), e.g.
  ``{"preset": "ottawa_c109", "stabilisation": 0.1, "set": {"beta": 5.0}}``; a ``von_mises`` law with
  ``length_m`` (and optionally ``over_nonlocal``) is the gradient-enhanced :class:`material.GradientVonMises`.

The one rule for the deposition angle: a CPA law built here gets the material axes of ``alpha_deg``
(default 0); a material object keeps its own axes, and an ``alpha_deg`` given with it must agree with
them (the deposition axis e2, up to its sign), so the angle recorded next to a result is the angle the
law used. An object without axes (an isotropic law) accepts any ``alpha_deg``. The CPA options
``rule``, ``stabilisation`` / ``relaxation_time`` (the step stabilisation), ``nonlocal_length`` /
``over_nonlocal`` (the implicit gradient), ``back_stress_modulus`` / ``back_stress_length`` (the gradient back
stress) and ``regularise`` (the crack-band scaling of the softening by the
element size, :class:`material.cpa.CPAModel`) apply only to a law built here.

Frames: ``plane_strain=False`` has the vertical along z (e2 = (sin a, 0, cos a),
:func:`material.anisotropy.axes_from_alpha`), ``plane_strain=True`` along y with z out of plane
(e2 = (sin a, cos a, 0), :func:`plane_strain_axes`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

__all__ = ["make_material", "plane_strain_axes", "deposition_axes", "LAWS", "LENGTH_KEYS"]

#: Keys of each law in a mapping spec (the ``[material]`` table of a case file).
LAWS = {
    "cpa": ("preset", "parameters", "rule", "set", "stabilisation", "relaxation_time", "regularise", "nonlocal_length",
            "over_nonlocal", "back_stress_modulus", "back_stress_length"),
    "von_mises": ("E_kPa", "nu", "yield_stress_kPa", "hardening_kPa", "length_m", "over_nonlocal"),
    "drucker_prager": ("E_kPa", "nu", "cohesion_kPa", "friction_deg", "dilation_deg", "match", "hardening_kPa"),
    "mohr_coulomb": ("E_kPa", "nu", "cohesion_kPa", "friction_deg", "dilation_deg"),
    "linear_elastic": ("E_kPa", "nu"),
}

#: Keys of a CPA spec that give the law a length of the boundary-value problem (crack band, implicit gradient,
#: gradient back stress): a material point on an element path has none, so its drivers drop them.
LENGTH_KEYS = ("regularise", "nonlocal_length", "over_nonlocal", "back_stress_modulus", "back_stress_length")

DEFAULT_PRESET = "ottawa_c109"
_PARAMETER_SUFFIXES = (".toml", ".json")


def plane_strain_axes(alpha_deg: float) -> np.ndarray:
    """Material axes of a plane-strain problem whose vertical is global y.

    e2 (deposition axis) = (sin a, cos a, 0) at ``alpha_deg`` from y in the x-y plane,
    e1 = (cos a, -sin a, 0), e3 = z (out of plane); columns e1, e2, e3, right-handed.
    """
    a = np.radians(float(alpha_deg))
    if not np.isfinite(a):
        raise ValueError(f"alpha_deg = {alpha_deg!r}: must be finite")
    e1 = np.array([np.cos(a), -np.sin(a), 0.0])
    e2 = np.array([np.sin(a), np.cos(a), 0.0])
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def deposition_axes(alpha_deg: float, *, plane_strain: bool = False) -> np.ndarray:
    """The material axes for ``alpha_deg`` in the 3D frame (z vertical) or the plane-strain frame (y vertical)."""
    from material.anisotropy import axes_from_alpha

    return plane_strain_axes(alpha_deg) if plane_strain else axes_from_alpha(alpha_deg)


def _parameters(spec):
    from material.parameters import CPAParameters, load_parameters, load_preset

    if spec is None:
        return load_preset(DEFAULT_PRESET)
    if isinstance(spec, CPAParameters):
        return spec
    if isinstance(spec, Path) or (isinstance(spec, str) and spec.lower().endswith(_PARAMETER_SUFFIXES)):
        return load_parameters(spec)
    if isinstance(spec, str):
        return load_preset(spec)
    return None


def _from_mapping(spec, alpha_deg, plane_strain: bool, base: Path):
    """The material of a mapping spec (module docstring), checked key by key."""
    import material as mlib

    spec = dict(spec)
    law = spec.pop("law", "cpa")
    if law not in LAWS:
        raise ValueError(f"[material] law = {law!r}: allowed {sorted(LAWS)}")
    unknown = sorted(set(spec) - set(LAWS[law]))
    if unknown:
        raise ValueError(f"[material] (law {law!r}): unknown key(s) {unknown}; allowed {sorted(LAWS[law])}")
    if law == "cpa":
        from material.commandline import with_changes

        if "parameters" in spec and "preset" in spec:
            raise ValueError("[material]: give either preset or parameters, not both")
        params = mlib.load_parameters(base / spec["parameters"]) if "parameters" in spec else \
            mlib.load_preset(spec.get("preset", DEFAULT_PRESET))
        return make_material(with_changes(params, spec.get("set") or {}), alpha_deg=alpha_deg,
                             plane_strain=plane_strain, rule=spec.get("rule"), stabilisation=spec.get("stabilisation"),
                             relaxation_time=spec.get("relaxation_time"), regularise=spec.get("regularise"),
                             nonlocal_length=spec.get("nonlocal_length"), over_nonlocal=spec.get("over_nonlocal"),
                             back_stress_modulus=spec.get("back_stress_modulus"),
                             back_stress_length=spec.get("back_stress_length"))
    cls = {"von_mises": mlib.VonMises, "drucker_prager": mlib.DruckerPrager, "mohr_coulomb": mlib.MohrCoulomb,
           "linear_elastic": mlib.LinearElastic}[law]
    if law == "von_mises" and ("length_m" in spec or "over_nonlocal" in spec):
        cls = mlib.GradientVonMises  # softening regularised by an implicit gradient of length length_m
    try:
        return cls(**spec)
    except TypeError as exc:
        raise ValueError(f"[material] law {law!r}: {exc}") from None


def make_material(spec=None, *, alpha_deg: float | None = None, plane_strain: bool = False,
                  rule: str | None = None, stabilisation: float | None = None,
                  relaxation_time: float | None = None, regularise: bool | None = None,
                  nonlocal_length: float | None = None, over_nonlocal: float | None = None,
                  back_stress_modulus: float | None = None, back_stress_length: float | None = None,
                  base: Path = Path(".")):
    """The material object for ``spec`` (module docstring: what may be given, and the rule for ``alpha_deg``).
    ``base``: the folder a parameter file named in a mapping spec is relative to."""
    if isinstance(spec, Mapping):
        return _from_mapping(spec, alpha_deg, plane_strain, Path(base))
    params = _parameters(spec)
    if params is not None:
        from material.cpa import CPAModel  # the CPA kernel is the heavy import

        options = {k: v for k, v in (("rule", rule), ("stabilisation", stabilisation),
                                     ("relaxation_time", relaxation_time), ("regularise", regularise),
                                     ("nonlocal_length", nonlocal_length), ("over_nonlocal", over_nonlocal),
                                     ("back_stress_modulus", back_stress_modulus),
                                     ("back_stress_length", back_stress_length))
                   if v is not None}
        axes = deposition_axes(0.0 if alpha_deg is None else alpha_deg, plane_strain=plane_strain)
        return CPAModel(params, axes=axes, **options)
    missing = [m for m in ("initial_state", "update") if not callable(getattr(spec, m, None))]
    if missing:
        raise ValueError(f"material = {spec!r} ({type(spec).__name__}) lacks the method(s) {missing} of a material "
                         "object; allowed: None, a preset name, a parameter file (.toml/.json), CPAParameters or an "
                         "object with initial_state and update")
    for name, value in (("rule", rule), ("stabilisation", stabilisation), ("relaxation_time", relaxation_time),
                        ("regularise", regularise), ("nonlocal_length", nonlocal_length),
                        ("over_nonlocal", over_nonlocal)):
        if value is not None:
            raise ValueError(f"{name} = {value!r}: applies to a CPA law built from a preset or parameters; the "
                             f"given {type(spec).__name__} has its own")
    axes = getattr(spec, "axes", None)
    if alpha_deg is not None and axes is not None:
        e2 = np.asarray(axes, dtype=float)[:, 1]
        expected = deposition_axes(alpha_deg, plane_strain=plane_strain)[:, 1]
        if abs(float(e2 @ expected)) < 1.0 - 1e-9:
            frame = "plane strain, y vertical" if plane_strain else "3D, z vertical"
            raise ValueError(
                f"alpha_deg = {alpha_deg!r} does not match the material's own axes (e2 = "
                f"{np.round(e2, 6).tolist()}; alpha_deg = {alpha_deg!r} means e2 = {np.round(expected, 6).tolist()} "
                f"in this problem's frame, {frame}): build the material with axes for that angle, pass a preset "
                "or CPAParameters instead of the object, or leave alpha_deg out")
    return spec
