"""Single-point (element) tests of any material law: a mixed stress/strain path engine and lab tests.

The engine, :func:`run_path`, works like MFront's MTest: a :class:`LoadPath` is a list of segments,
each split into load steps; in every step six linear conditions fix the six independent components
of the symmetric strain increment. Condition k reads

    A_k . eps + B_k . (sigma - u delta) = c_k            (Mandel vectors, tension +)

with ``eps`` the total strain and ``sigma`` the effective stress at the end of the step, ``u`` the pore
pressure (compression +; only for undrained segments) and ``delta`` = (1, 1, 1, 0, 0, 0). A
strain-controlled component has A_k = Q_k, B_k = 0, a stress-controlled one A_k = 0, B_k = Q_k, where Q is
the Mandel rotation to the segment's frame (identity by default): components can be prescribed in a
rotated frame (principal stress rotation) or as a linear combination (the b value of a true triaxial
test). The unknown strain increment is found by Newton on these conditions with the law's consistent
tangent (6x6 Mandel form); the material state is kept at the start of the step and committed on
convergence. An undrained segment adds the constraint tr(d eps) = 0 per step, whose Lagrange
multiplier is the excess pore pressure increment (total stress = effective stress - u I, tension +);
with pore water of bulk modulus K (``pore_bulk_modulus_kPa``, as in the FE's penalty formulation) the
constraint is tr(d eps) + d u / K = 0.
In a drained segment u keeps its last value (no consolidation is modelled; u = 0 unless an undrained
segment came before), and stress conditions are always on the total stress sigma - u delta.

A step that fails (law status FAILED, Newton not converged, singular system) is retried in 2, 4, ...
sub-steps (``max_cuts`` halvings); if it still fails the run stops, and the table of the steps
computed so far is returned with ``completed = False`` and a message naming the step and the cause
(``on_failure="raise"`` raises :class:`PathFailure` instead, carrying the partial table).

Mandel basis (the order of :data:`COMPONENTS`): v = (T_xx, T_yy, T_zz, sqrt2 T_yz, sqrt2 T_xz, sqrt2 T_xy).
Paths and CSV columns use **tensor** components (``eps_xz`` is half the engineering shear strain).

Lab tests built on the engine (all return an :class:`~material.results.ElementResult`):
:func:`triaxial`, :func:`oedometer`, :func:`direct_shear`, :func:`simple_shear`,
:func:`cyclic_simple_shear`, :func:`plane_strain`, :func:`true_triaxial`, :func:`rotation`.
The loading (axial) axis of the triaxial-type tests is the global z axis; the material axes of a CPA
law built here come from :func:`material.anisotropy.axes_from_alpha` (e2 at alpha from z).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path as _FilePath

import numpy as np

from material.base import STATUS_FAILED, check_positive, check_steps, copy_state, step_fraction
from material.results import COMPONENTS, ElementResult, standard_columns
from material.table import TableWriter, read_table
from material.tensors import MANDEL_WEIGHTS, from_mandel, from_mandel_matrix, to_mandel, to_mandel_matrix

__all__ = [
    "COMPONENTS",
    "ElementResult",
    "LoadPath",
    "Segment",
    "PathFailure",
    "run_path",
    "triaxial",
    "oedometer",
    "direct_shear",
    "simple_shear",
    "cyclic_simple_shear",
    "plane_strain",
    "true_triaxial",
    "rotation",
    "mandel_rotation",
]

_IJ = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))  # material.tensors.MANDEL_INDEX
_W = MANDEL_WEIGHTS
_DELTA = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
_BACKTRACKS = 3  # halvings of a Newton correction the law could not integrate


# ---------------------------------------------------------------------------- Mandel algebra
def mandel_rotation(frame) -> np.ndarray:
    """6x6 Q with to_mandel(R^T T R) = Q @ to_mandel(T): components of T in the frame R (columns = axes)."""
    r = np.asarray(frame, dtype=float)
    if r.shape != (3, 3) or not np.allclose(r.T @ r, np.eye(3), atol=1e-10):
        raise ValueError(f"frame: expected a (3, 3) orthonormal matrix (columns = axes), got {np.round(r, 6).tolist()}")
    basis = from_mandel(np.eye(6))  # (6, 3, 3): the Mandel basis tensors
    return to_mandel(np.einsum("ai,kab,bj->kij", r, basis, r)).T


def rotation_about_z(angle_deg: float) -> np.ndarray:
    """Frame (columns = axes) rotated by ``angle_deg`` about the global z axis (x towards y)."""
    a = np.deg2rad(float(angle_deg))
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ---------------------------------------------------------------------------- load path
@dataclass(frozen=True)
class Segment:
    """One segment of a :class:`LoadPath` (data layout of the engine).

    Attributes
    ----------
    steps : int
        Number of load steps the segment is split into (targets interpolated linearly), >= 1.
    A, B : (6, 6) ndarray
        Strain and stress coefficients of the six conditions ``A eps + B (sigma - u delta) = c``
        (Mandel vectors, tension +). Every row has either A or B non-zero.
    target : (6,) ndarray
        End-of-segment value c of each condition (kPa for stress rows, - for strain rows).
    relative : (6,) bool ndarray
        Row k's target is a change from the value at the segment start (else absolute).
    undrained : bool
        Undrained: the excess pore pressure is the multiplier of the volume condition (module docstring).
    name : str
        Stage label recorded in the ``stage`` column (as an index into ``metadata["stages"]``).
    pore_compliance : float
        1 / K of the pore water [1/kPa] in an undrained segment: the volume condition reads
        tr(d eps) + d u / K = 0; 0 (the default) is constant volume, the limit of incompressible water.
    """

    steps: int
    A: np.ndarray
    B: np.ndarray
    target: np.ndarray
    relative: np.ndarray
    undrained: bool = False
    name: str = ""
    pore_compliance: float = 0.0

    @property
    def stress_rows(self) -> np.ndarray:
        """(6,) bool: which conditions are on stress."""
        return np.abs(self.B).sum(axis=1) > 0


@dataclass
class LoadPath:
    """A mixed stress/strain-controlled loading path: a list of :class:`Segment`.

    Build it with :meth:`add` (component-wise control in a frame), :meth:`add_conditions` (raw A, B,
    c rows), :meth:`from_toml` (a path declared as data) or :meth:`from_csv` (lab data), e.g. a drained triaxial compression from -p0 I::

        path = LoadPath(initial_stress=-100.0 * np.eye(3))
        path.add(steps=300, eps_zz=-0.15, sig_xx=-100.0, sig_yy=-100.0,
                 sig_yz=0.0, sig_xz=0.0, sig_xy=0.0, relative_strain=True)

    Keyword names are ``sig_<c>`` (stress [kPa], tension +) or ``eps_<c>`` (strain, tension +,
    tensor shear), ``<c>`` in :data:`COMPONENTS`; each of the six components exactly once.

    Attributes
    ----------
    segments : list of Segment
    initial_stress : (3, 3) ndarray
        Effective stress at the start of the path [kPa], tension +.
    """

    initial_stress: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    segments: list = field(default_factory=list)

    def __post_init__(self):
        s = np.asarray(self.initial_stress, dtype=float)
        if s.shape != (3, 3) or not np.isfinite(s).all() or not np.allclose(s, s.T):
            raise ValueError(f"initial_stress: expected a finite symmetric (3, 3) tensor [kPa], got {s.tolist()}")
        self.initial_stress = s

    @property
    def n_steps(self) -> int:
        """Total number of load steps."""
        return sum(seg.steps for seg in self.segments)

    def add(self, steps: int, *, frame=None, relative_strain: bool = True, relative_stress: bool = False,
            undrained: bool = False, pore_bulk_modulus_kPa: float | None = None, name: str = "",
            **components: float) -> "LoadPath":
        """Append a segment prescribing each component in stress or in strain.

        Parameters
        ----------
        steps : int
            Number of load steps, >= 1.
        frame : (3, 3) array, optional
            Frame (columns = axes) in which the components are given; default the global frame.
        relative_strain : bool
            Strain targets are changes over the segment (default), else absolute total strains.
        relative_stress : bool
            Stress targets are changes over the segment, else absolute values (default).
        undrained : bool
            Undrained: the excess pore pressure is the multiplier of the volume condition (stress targets
            are total).
        pore_bulk_modulus_kPa : float, optional
            Undrained with pore water of this bulk modulus K = K_w / n [kPa] (the penalty of
            :class:`material.undrained.Undrained`, so that an FE run and this test model the same water);
            default: constant volume (K infinite).
        **components
            ``sig_xx=...`` [kPa] or ``eps_zz=...`` [-]; all six components, each once.
        """
        q = mandel_rotation(np.eye(3) if frame is None else frame)
        a, b = np.zeros((6, 6)), np.zeros((6, 6))
        target, rel = np.zeros(6), np.zeros(6, dtype=bool)
        allowed = [f"{kind}_{c}" for kind in ("sig", "eps") for c in COMPONENTS]
        for key in components:
            if key not in allowed:
                raise KeyError(f"unknown component {key!r}; allowed: {allowed}")
        for k, c in enumerate(COMPONENTS):
            has_s, has_e = f"sig_{c}" in components, f"eps_{c}" in components
            if has_s == has_e:
                raise ValueError(
                    f"component {c!r}: prescribe exactly one of sig_{c} or eps_{c} "
                    f"(got {'both' if has_s else 'neither'})"
                )
            value = float(components[f"sig_{c}" if has_s else f"eps_{c}"])
            if not math.isfinite(value):
                raise ValueError(f"component {'sig' if has_s else 'eps'}_{c} = {value!r}: must be finite")
            (b if has_s else a)[k] = q[k]
            target[k] = value * (_W[k] if k >= 3 else 1.0)  # Mandel value of a tensor component
            rel[k] = relative_stress if has_s else relative_strain
        return self.add_conditions(steps, a, b, target, rel, undrained=undrained, name=name,
                                   pore_bulk_modulus_kPa=pore_bulk_modulus_kPa)

    def add_conditions(self, steps: int, A, B, target, relative, *, undrained: bool = False,
                       name: str = "", pore_bulk_modulus_kPa: float | None = None) -> "LoadPath":
        """Append a segment given its raw conditions (see :class:`Segment`)."""
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise ValueError(f"steps = {steps!r}: must be an integer >= 1")
        a, b = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
        c = np.asarray(target, dtype=float)
        rel = np.broadcast_to(np.asarray(relative, dtype=bool), (6,)).copy()
        if a.shape != (6, 6) or b.shape != (6, 6) or c.shape != (6,):
            raise ValueError(f"conditions: expected A (6, 6), B (6, 6), target (6,), got {a.shape}, {b.shape}, {c.shape}")
        if not (np.isfinite(a).all() and np.isfinite(b).all() and np.isfinite(c).all()):
            raise ValueError("conditions: A, B and target must be finite (NaN or inf found)")
        both = (np.abs(a).sum(1) > 0) & (np.abs(b).sum(1) > 0)
        if both.any():
            raise ValueError(f"conditions: row(s) {np.flatnonzero(both).tolist()} mix strain and stress; use one per row")
        if undrained and np.allclose(b @ _DELTA, 0.0):
            raise ValueError(
                "undrained segment: no stress condition involves a normal stress, so the pore pressure "
                "(the multiplier of tr(d eps) = 0) is undetermined; prescribe at least one total normal stress"
            )
        compliance = 0.0
        if pore_bulk_modulus_kPa is not None:
            if not undrained:
                raise ValueError(f"pore_bulk_modulus_kPa = {pore_bulk_modulus_kPa!r}: applies to undrained segments only")
            compliance = 1.0 / check_positive("pore_bulk_modulus_kPa", pore_bulk_modulus_kPa)
        self.segments.append(Segment(int(steps), a, b, c, rel, bool(undrained), str(name), compliance))
        return self

    @classmethod
    def from_toml(cls, path) -> "LoadPath":
        """Read a path declared as data (like an MTest file) from TOML.

        Layout::

            p0_kPa = 100.0                 # initial stress -p0 I; or initial_stress_kPa = [[...], [...], [...]]

            [[segment]]
            name = "compression"           # optional
            steps = 100
            eps_zz = -0.05                 # one of sig_<c> [kPa] / eps_<c> per component, tension +
            sig_xx = -100.0
            sig_yy = -100.0
            sig_yz = 0.0
            sig_xz = 0.0
            sig_xy = 0.0
            # optional: relative_strain = true, relative_stress = false, undrained = false,
            #           frame_z_deg = 0.0 (components given in axes rotated about z by this angle)

        Unknown keys raise ``KeyError`` naming them; values are checked like :meth:`add`.
        """
        import tomllib

        path = _FilePath(path)
        if not path.is_file():
            raise FileNotFoundError(f"path file {str(path)!r} does not exist")
        try:
            doc = tomllib.loads(path.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML: {exc}") from None
        top = set(doc) - {"p0_kPa", "initial_stress_kPa", "segment", "description"}
        if top:
            raise KeyError(f"{path}: unknown key(s) {sorted(top)}; allowed: p0_kPa, initial_stress_kPa, segment, description")
        if "p0_kPa" in doc and "initial_stress_kPa" in doc:
            raise ValueError(f"{path}: give p0_kPa or initial_stress_kPa, not both")
        if "initial_stress_kPa" in doc:
            s0 = np.asarray(doc["initial_stress_kPa"], dtype=float)
        else:
            s0 = -float(doc.get("p0_kPa", 0.0)) * np.eye(3)
        out = cls(initial_stress=s0)
        segments = doc.get("segment", [])
        if not isinstance(segments, list) or not segments:
            raise ValueError(f"{path}: no [[segment]] tables; add at least one")
        options = {"name", "steps", "relative_strain", "relative_stress", "undrained", "frame_z_deg"}
        comps = {f"{k}_{c}" for k in ("sig", "eps") for c in COMPONENTS}
        for i, seg in enumerate(segments):
            unknown = set(seg) - options - comps
            if unknown:
                raise KeyError(f"{path}: segment {i}: unknown key(s) {sorted(unknown)}; allowed: "
                               f"{sorted(options)} and sig_<c> / eps_<c> for <c> in {list(COMPONENTS)}")
            if "steps" not in seg:
                raise ValueError(f"{path}: segment {i}: missing 'steps'")
            frame = rotation_about_z(seg["frame_z_deg"]) if "frame_z_deg" in seg else None
            try:
                out.add(seg["steps"], frame=frame, relative_strain=bool(seg.get("relative_strain", True)),
                        relative_stress=bool(seg.get("relative_stress", False)),
                        undrained=bool(seg.get("undrained", False)), name=str(seg.get("name", f"segment {i}")),
                        **{k: v for k, v in seg.items() if k in comps})
            except ValueError as exc:
                raise ValueError(f"{path}: segment {i}: {exc}") from None
        return out

    @classmethod
    def from_csv(cls, path, substeps: int = 1, initial_stress=None) -> "LoadPath":
        """Read a path from a CSV of lab data (one load step per row after the first).

        Columns: exactly one of ``sig_<c>_kPa`` (stress [kPa], tension +) or ``eps_<c>`` (strain,
        tension +, tensor shear) per component ``<c>`` in :data:`COMPONENTS`; optional ``step``,
        ``time_s`` and ``stage`` columns are ignored; lines starting with ``#`` are comments. Values
        are absolute. The first row is the reference state: strains are measured from it and its stress
        values are the start of the stress-controlled components. ``initial_stress`` (3, 3) [kPa] sets
        the whole initial stress; by default it is the first row's stress where given and, for
        strain-controlled normal components, the mean of the given normal stresses (0 if none).
        Each later row is reached in ``substeps`` steps.
        """
        path = _FilePath(path)
        if not path.is_file():
            raise FileNotFoundError(f"path file {str(path)!r} does not exist")
        table = read_table(path)
        if len(table) < 2:
            raise ValueError(f"{path}: need a header and at least two data rows (start + one step), got {len(table)} rows")
        names = [h.strip() for h in table.columns]
        stress_cols = {f"sig_{c}_kPa": k for k, c in enumerate(COMPONENTS)}
        strain_cols = {f"eps_{c}": k for k, c in enumerate(COMPONENTS)}
        ignored = {"step", "time_s", "time", "stage"}
        unknown = [n for n in names if n not in stress_cols and n not in strain_cols and n not in ignored]
        if unknown:
            raise KeyError(
                f"{path}: unknown column(s) {unknown}; allowed: {list(stress_cols) + list(strain_cols)} "
                f"(+ ignored {sorted(ignored)})"
            )
        data = np.column_stack([table[c] for c in table.columns])
        mode: dict[int, tuple[str, int]] = {}
        for j, n in enumerate(names):
            if n in ignored:
                continue
            k = stress_cols.get(n, strain_cols.get(n))
            if k in mode:
                raise ValueError(f"{path}: component {COMPONENTS[k]!r} is given twice ({names[mode[k][1]]} and {n})")
            mode[k] = ("sig" if n in stress_cols else "eps", j)
            bad = ~np.isfinite(data[:, j])
            if bad.any():
                raise ValueError(f"{path}: column {n!r} has NaN/inf in data row(s) {(np.flatnonzero(bad) + 1).tolist()}")
        missing = [COMPONENTS[k] for k in range(6) if k not in mode]
        if missing:
            raise ValueError(f"{path}: component(s) {missing} are not prescribed; give sig_<c>_kPa or eps_<c> for each")
        if initial_stress is None:
            s0 = np.zeros((3, 3))
            normal_given = [data[0, mode[k][1]] for k in range(3) if mode[k][0] == "sig"]
            mean = float(np.mean(normal_given)) if normal_given else 0.0
            for k, (i, j) in enumerate(_IJ):
                kind, col = mode[k]
                s0[i, j] = s0[j, i] = data[0, col] if kind == "sig" else (mean if k < 3 else 0.0)
        else:
            s0 = initial_stress
        out = cls(initial_stress=s0)
        eye6 = np.eye(6)
        a, b = np.zeros((6, 6)), np.zeros((6, 6))
        for k in range(6):
            (b if mode[k][0] == "sig" else a)[k] = eye6[k]
        for r in range(1, len(data)):
            target = np.array([data[r, mode[k][1]] - (data[0, mode[k][1]] if mode[k][0] == "eps" else 0.0)
                               for k in range(6)]) * _W
            out.add_conditions(int(substeps), a, b, target, np.zeros(6, dtype=bool), name=f"row {r}")
        return out


# ---------------------------------------------------------------------------- engine
class PathFailure(RuntimeError):
    """A load step failed after all cut-backs; ``.result`` holds the table computed so far."""

    def __init__(self, message: str, result: ElementResult):
        super().__init__(message)
        self.result = result


@dataclass
class _Point:
    """Converged state of the single material point (start of the next step)."""

    strain: np.ndarray  # (6,) Mandel, tension +
    stress: np.ndarray  # (6,) Mandel effective stress, tension +
    u: float  # excess pore pressure [kPa], compression +
    state: dict
    tangent: np.ndarray  # (6, 6) Mandel tangent of the last converged update


def _mandel_update(model, d_strain, stress, state, inputs=None):
    """One update of the point with its tangent as a (6, 6) Mandel matrix: a law that computes it in
    Mandel form (``"mandel" in model.TANGENTS``, the CPA law) gives it as it is, without a round trip.
    ``inputs``: the law's other inputs (:func:`_rate_inputs`)."""
    inputs = inputs or {}
    if "mandel" in getattr(model, "TANGENTS", ()):
        stress, state, tangent = model.update(d_strain, stress, state, tangent="mandel", **inputs)
        return stress, state, np.asarray(tangent)[0]
    stress, state, tangent = model.update(d_strain, stress, state, **inputs)
    return stress, state, to_mandel_matrix(np.asarray(tangent)[0])


def _rate_inputs(model, seg: Segment, n_sub: int) -> dict:
    """The step's size for a :attr:`rate_dependent` law (:func:`material.base.step_fraction`): a segment's
    time runs from 0 to 1 over its ``steps``, so a step lasts 1 / steps, a nominal step (1 for a law
    without a ``relaxation_time``), and each of its ``n_sub`` sub-steps after a cut-back 1 / n_sub of that."""
    if not getattr(model, "rate_dependent", False):
        return {}
    nominal = 1.0 / seg.steps
    return {"step_fraction": step_fraction(model, nominal / n_sub, nominal)}


def _update(model, point: _Point, d_eps: np.ndarray, inputs=None):
    stress, state, tangent = _mandel_update(model, from_mandel(d_eps)[None], from_mandel(point.stress)[None],
                                            point.state, inputs)
    failed = int(np.asarray(state["status"])[0]) == STATUS_FAILED
    return to_mandel(stress[0]), state, tangent, failed


def _failure_reason(model, point: _Point, d_eps: np.ndarray, failed_state, inputs=None) -> str:
    """The stop message of a step whose increment the law cannot integrate (``failed_state``: the state the
    failed update returned), with the law's own reading of why where it has one (``explain_failure``: the
    CPA law names a point that snaps back at its peak)."""
    reason = "the material returned status FAILED (no converged stress for this increment)"
    explain = getattr(model, "explain_failure", None)
    if explain is None:
        return reason
    extra = dict(inputs or {})
    if "reached" in failed_state:
        extra["reached"] = np.asarray(failed_state["reached"], dtype=float)
    why = explain(from_mandel(d_eps)[None], from_mandel(point.stress)[None], point.state, **extra)[0]
    return reason if why is None else f"{reason}: {why}"


def _solve_step(model, point: _Point, seg: Segment, c_end: np.ndarray, tol: float, max_iter: int, inputs=None):
    """Newton for one step from ``point`` to the conditions ``c_end`` (``inputs``: :func:`_rate_inputs`).

    Returns (_Point, iterations, stress residual [kPa], None) on convergence, else (None, None, reason).
    """
    a, b, undrained = seg.A, seg.B, seg.undrained
    srows = seg.stress_rows
    n = 7 if undrained else 6
    d_eps, d_u = np.zeros(6), 0.0
    sig, tangent = point.stress, point.tangent
    state = None
    for it in range(max_iter + 1):
        r = a @ (point.strain + d_eps) + b @ (sig - (point.u + d_u) * _DELTA) - c_end
        scale = max(np.abs(sig).max(), np.abs(c_end[srows]).max(initial=0.0), 1e-3)
        conv_s = np.abs(r[srows]).max(initial=0.0) <= tol * scale
        conv_e = np.abs(r[~srows]).max(initial=0.0) <= 1e-12 * max(1.0, np.abs(c_end[~srows]).max(initial=0.0))
        if it > 0 and conv_s and conv_e:
            return _Point(point.strain + d_eps, sig, point.u + d_u, state, tangent), it, np.abs(r[srows]).max(initial=0.0)
        if it == max_iter:
            return None, None, f"Newton did not converge in {max_iter} iterations (stress residual {np.abs(r[srows]).max(initial=0.0):.3g} kPa)"
        jac = np.zeros((n, n))
        jac[:6, :6] = a + b @ tangent
        res = np.zeros(n)
        res[:6] = r
        if undrained:
            jac[:6, 6] = -b @ _DELTA
            jac[6, :6] = _DELTA
            jac[6, 6] = seg.pore_compliance
            res[6] = _DELTA @ d_eps + seg.pore_compliance * d_u
        try:
            dx = np.linalg.solve(jac, -res)
        except np.linalg.LinAlgError:
            return None, None, "singular system (the prescribed stresses cannot be reached: limit state?)"
        if not np.isfinite(dx).all():
            return None, None, "non-finite Newton correction"
        # backtracking: if the law cannot integrate the trial increment, shorten the correction
        for _ in range(_BACKTRACKS + 1):
            trial = d_eps + dx[:6]
            new = _update(model, point, trial, inputs)
            if not new[3] and np.isfinite(new[0]).all():
                break
            dx = 0.5 * dx
        else:
            return None, None, _failure_reason(model, point, trial, new[1], inputs)
        d_eps = trial
        if undrained:
            d_u += dx[6]
        sig, state, tangent, _ = new
    return None, None, "Newton loop exhausted"  # pragma: no cover


def run_path(model, path: LoadPath, *, tolerance: float = 1e-10, max_iter: int = 30, max_cuts: int = 6,
             on_failure: str = "return", progress: bool = False, state=None, log=None) -> ElementResult:
    """Drive one material point along a mixed stress/strain path (see the module docstring).

    Parameters
    ----------
    model : material object
        Anything with ``initial_state(n, stress=...)`` and ``update(d_strain, stress, state)``.
    path : LoadPath
        The loading; its ``initial_stress`` is the starting effective stress (tension +, kPa).
    tolerance : float
        Stress conditions hold to ``tolerance * max(|sigma|, |targets|, 1e-3 kPa)``.
    max_iter : int
        Newton iterations per step before the step counts as failed.
    max_cuts : int
        A failed step is retried in 2**k sub-steps, k = 1..max_cuts.
    on_failure : {"return", "raise"}
        After the last cut-back: return the partial table (``completed=False``, with a warning) or
        raise :class:`PathFailure`.
    progress : bool
        Show a tqdm progress bar.
    state : dict, optional
        Initial material state (default ``model.initial_state(1, stress=path.initial_stress)``).
    log : path, optional
        CSV written step by step while the path runs (step, stage, u_kPa, the six stress and six
        strain components, tension +), flushed after every step, so a long or interrupted run keeps
        its converged steps on disk.

    Returns
    -------
    ElementResult
        One row per step (row 0 = start): ``step``, ``stage``, ``iterations``, ``cuts``,
        ``u_kPa`` and the :func:`~material.results.standard_columns`.
    """
    if not isinstance(path, LoadPath):
        raise ValueError(f"path: expected a LoadPath, got {type(path).__name__}")
    if not path.segments:
        raise ValueError("path: has no segments; add some with LoadPath.add(...)")
    if on_failure not in ("return", "raise"):
        raise ValueError(f"on_failure = {on_failure!r}; allowed: 'return', 'raise'")
    if not (0 < tolerance < 1e-2):
        raise ValueError(f"tolerance = {tolerance!r}: allowed 0 < tolerance < 1e-2")
    s0 = path.initial_stress
    state0 = model.initial_state(1, stress=s0) if state is None else copy_state(state)
    _, state_probe, tangent0 = _mandel_update(model, np.zeros((1, 3, 3)), s0[None], state0)
    point = _Point(to_mandel(state0["strain"][0]) if "strain" in state0 else np.zeros(6), to_mandel(s0), 0.0,
                   state0, tangent0)
    strain_ref = point.strain.copy()

    rows_s, rows_e, rows_u = [point.stress], [point.strain - strain_ref], [0.0]
    rows_stage, rows_it, rows_cut, rows_res, rows_t = [0], [0], [0], [0.0], [tangent0]
    stages = [seg.name or f"segment {i}" for i, seg in enumerate(path.segments)]
    message = ""
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=path.n_steps, desc="element", unit="step", leave=False)
    step_no = 0
    log_fh = None
    if log is not None:
        log_path = _FilePath(log)
        log_path.parent.mkdir(parents=True, exist_ok=True)
        log_fh = TableWriter(log_path, title="element path, step by step", convention="tension positive; "
                             "u_kPa excess pore pressure, compression positive")
        _log_row(log_fh, 0, 0, 0.0, point.stress, point.strain - strain_ref)
    try:
        for iseg, seg in enumerate(path.segments):
            c_start = seg.A @ point.strain + seg.B @ (point.stress - point.u * _DELTA)
            c_end = np.where(seg.relative, c_start + seg.target, seg.target)
            if seg.undrained:
                # relative strain rows must keep tr(eps) fixed: checked by the solve (singular otherwise)
                pass
            for k in range(1, seg.steps + 1):
                step_no += 1
                goal = c_start + (c_end - c_start) * (k / seg.steps)
                new, its, cuts, resid, reason = _step_with_cutbacks(model, point, seg, goal, tolerance, max_iter,
                                                                    max_cuts)
                if new is None:
                    message = f"step {step_no} (segment {iseg} '{stages[iseg]}', step {k}/{seg.steps}) failed after {max_cuts} cut-backs: {reason}"
                    break
                point = new
                rows_s.append(point.stress)
                rows_e.append(point.strain - strain_ref)
                rows_u.append(point.u)
                rows_stage.append(iseg)
                rows_it.append(its)
                rows_cut.append(cuts)
                rows_res.append(resid)
                rows_t.append(point.tangent)
                if log_fh is not None:
                    _log_row(log_fh, step_no, iseg, point.u, point.stress, point.strain - strain_ref)
                if bar is not None:
                    bar.update(1)
            if message:
                break
    finally:
        if bar is not None:
            bar.close()
        if log_fh is not None:
            log_fh.close()

    stress, strain = from_mandel(np.array(rows_s)), from_mandel(np.array(rows_e))
    cols = {
        "step": np.arange(len(rows_s)),
        "stage": np.array(rows_stage),
        "iterations": np.array(rows_it),
        "cuts": np.array(rows_cut),
        "stress_residual_kPa": np.array(rows_res),
        "u_kPa": np.array(rows_u),
    }
    desc = {
        "step": "load step (0 = initial state)",
        "stage": "index of the path segment (names in metadata['stages'])",
        "iterations": "Newton iterations of the step (summed over sub-steps)",
        "cuts": "number of halvings the step needed (0 = none)",
        "stress_residual_kPa": "largest misfit of a prescribed stress condition at the end of the step [kPa]",
        "u_kPa": "excess pore pressure [kPa], compression + (0 for drained segments)",
    }
    std_cols, std_desc = standard_columns(stress, strain)
    cols.update(std_cols)
    desc.update(std_desc)
    from material.version import __version__

    meta = {"test": "path", "stages": stages, "material": repr(model), "femgran_version": __version__,
            "strain_origin": "strains measured from the start of the path"}
    params = getattr(model, "params", None)
    if params is not None and hasattr(params, "to_dict"):
        meta["parameters"] = params.to_dict()
    res = ElementResult(cols, desc, stress, strain, meta, completed=not message, message=message,
                        final_state=point.state, tangent=from_mandel_matrix(np.array(rows_t)))
    if message:
        if on_failure == "raise":
            raise PathFailure(message, res)
        warnings.warn(f"element path stopped early: {message}", RuntimeWarning, stacklevel=2)
    return res


def _log_row(writer, step: int, stage: int, u: float, stress_m: np.ndarray, strain_m: np.ndarray) -> None:
    row = {"step": step, "stage": stage, "u_kPa": u}
    row.update({f"sig_{c}_kPa": v for c, v in zip(COMPONENTS, stress_m / _W)})  # tensor components
    row.update({f"eps_{c}": v for c, v in zip(COMPONENTS, strain_m / _W)})
    writer.write(row)


def _step_with_cutbacks(model, point, seg, goal, tol, max_iter, max_cuts):
    """Reach ``goal`` from ``point``; on failure split into 2**k equal sub-steps.

    Returns (point or None, iterations, cuts, largest stress residual [kPa], reason of failure).
    """
    c_start = seg.A @ point.strain + seg.B @ (point.stress - point.u * _DELTA)
    reason = ""
    for cuts in range(max_cuts + 1):
        n_sub = 2**cuts
        p, total_its, worst = point, 0, 0.0
        inputs = _rate_inputs(model, seg, n_sub)
        for j in range(1, n_sub + 1):
            new, its, info = _solve_step(model, p, seg, c_start + (goal - c_start) * (j / n_sub), tol, max_iter,
                                         inputs)
            if new is None:
                reason = info
                break
            p, total_its, worst = new, total_its + its, max(worst, info)
        else:
            return p, total_its, cuts, worst, ""
    return None, 0, max_cuts, 0.0, reason


# ---------------------------------------------------------------------------- model construction
def _make_model(model_or_params, alpha_deg: float, rule: str | None):
    """The material (:func:`material.factory.make_material`, 3D frame) and its parameters (or None)."""
    from material.factory import make_material

    model = make_material(model_or_params, alpha_deg=alpha_deg, rule=rule)
    return model, getattr(model, "params", None)


def _finish(res: ElementResult, test: str, params, extra_meta: dict, plot_pairs) -> ElementResult:
    res.metadata["test"] = test
    res.metadata.update(extra_meta)
    if params is not None and hasattr(params, "to_dict"):
        res.metadata["parameters"] = params.to_dict()
    res.plot_pairs = list(plot_pairs)
    res.metadata["plot_pairs"] = [list(p) for p in res.plot_pairs]  # read back by material.results.read_csv
    return res


_ZERO_SHEAR = {"sig_yz": 0.0, "sig_xz": 0.0, "sig_xy": 0.0}


# ---------------------------------------------------------------------------- lab tests
def triaxial(model_or_params, p0_kPa: float = 100.0, alpha_deg: float = 0.0, axial_strain: float = 0.15,
             steps: int = 300, drained: bool = True, extension: bool = False, *, rule: str | None = None,
             pore_bulk_modulus_kPa: float | None = None, **engine) -> ElementResult:
    """Conventional triaxial test: isotropic p0, then axial strain along z at constant cell pressure.

    The point starts at the isotropic effective stress -p0 I (for the CPA law ``initial_state(1,
    stress=-p0 I)``; strains are zeroed there, like a lab test zeroes them after consolidation). This
    replaces the consolidation stage exactly for the CPA law: an isotropic stress puts no shear on any
    plane (no slip) and the induced anisotropy depends on the deviatoric strain only.
    Shearing prescribes eps_zz (compression, or extension if ``extension``) and keeps the lateral
    normal stresses AND the three shear stresses prescribed (sigma_xx = sigma_yy = -p0 total,
    shear stresses 0), so an inclined sample (alpha not 0 or 90) may develop shear strains.
    Undrained (``drained=False``): constant volume; the excess pore pressure u is the multiplier of
    that constraint, the total lateral stress stays -p0 and the effective stresses are the law's. With
    ``pore_bulk_modulus_kPa`` K the pore water is compressible, tr(d eps) = -d u / K, the same water as
    an FE run's ``drainage = "undrained"`` (:class:`material.undrained.Undrained`).

    Parameters
    ----------
    model_or_params : material object, CPAParameters or preset name
        A CPAParameters (or preset) builds ``CPAModel(params, axes=axes_from_alpha(alpha_deg))``; a
        material object is used as given (a model with an ``axes`` attribute must match ``alpha_deg``,
        else ValueError; for isotropic laws ``alpha_deg`` is only recorded).
    p0_kPa : float
        Confining (cell) effective pressure [kPa], > 0.
    alpha_deg : float
        Deposition angle: between the loading axis z and the material axis e2 [deg].
    axial_strain : float
        Magnitude of the axial strain applied [-], > 0.
    steps : int
        Number of equal axial strain steps.
    drained, extension : bool
    rule : str, optional
        Integration rule of the CPA law (only with parameters).
    **engine
        Passed to :func:`run_path` (tolerance, max_iter, max_cuts, on_failure, progress).

    Returns
    -------
    ElementResult
        Besides the standard columns: ``eps_a`` (axial strain -eps_zz, compression +), ``eps_r``
        (mean lateral strain, compression +), ``q_kPa`` = sigma_a - sigma_r (axial minus lateral
        effective stress, compression +; negative in extension: NOT sqrt(3 J2) here), ``eta`` = q/p,
        ``u_kPa``.
    """
    p0 = check_positive("p0_kPa", p0_kPa)
    ea = check_positive("axial_strain", axial_strain)
    steps = check_steps(steps)
    model, params = _make_model(model_or_params, alpha_deg, rule)
    path = LoadPath(initial_stress=-p0 * np.eye(3))
    sign = 1.0 if extension else -1.0
    if drained and pore_bulk_modulus_kPa is not None:
        raise ValueError(f"pore_bulk_modulus_kPa = {pore_bulk_modulus_kPa!r}: applies to an undrained test "
                         "(drained=False) only")
    path.add(steps, eps_zz=sign * ea, sig_xx=-p0, sig_yy=-p0, **_ZERO_SHEAR, undrained=not drained,
             pore_bulk_modulus_kPa=pore_bulk_modulus_kPa, name="extension" if extension else "compression")
    res = run_path(model, path, **engine)
    eps = res.strain
    q = res["sig_xx_kPa"] * 0.5 + res["sig_yy_kPa"] * 0.5 - res["sig_zz_kPa"]
    res.add_column("eps_a", -eps[:, 2, 2], "axial strain -eps_zz [-], compression +")
    res.add_column("eps_r", -0.5 * (eps[:, 0, 0] + eps[:, 1, 1]), "mean lateral strain -(eps_xx+eps_yy)/2 [-], compression +")
    res.add_column("q_kPa", q, "deviator sigma_a - sigma_r (axial minus mean lateral effective stress) [kPa], "
                   "compression + (sigma1 - sigma3 in compression; negative in extension)")
    res.add_column("eta", q / res["p_kPa"], "stress ratio q/p [-]")
    return _finish(res, "triaxial", params,
                   {"p0_kPa": p0, "alpha_deg": float(alpha_deg), "axial_strain": ea, "steps": steps,
                    "drained": bool(drained), "extension": bool(extension),
                    "pore_bulk_modulus_kPa": pore_bulk_modulus_kPa},
                   [("eps_a", "q_kPa"), ("eps_a", "eps_v")] + ([] if drained else [("eps_a", "u_kPa")]))


def oedometer(model_or_params, p0_kPa: float = 10.0, alpha_deg: float = 0.0, axial_strain: float = 0.02,
              steps: int = 100, *, rule: str | None = None, **engine) -> ElementResult:
    """Oedometric (K0) compression along z: every strain component prescribed (lateral and shear 0).

    Starts at the isotropic effective stress -p0 I. Reports ``eps_a`` (= eps_v), ``K0`` =
    sigma_xx / sigma_zz (secant, total stresses including the start) and ``K0_incremental`` =
    (sigma_xx - sigma_xx,0) / (sigma_zz - sigma_zz,0) (the elastic value nu / (1 - nu)); ``K0_y`` for y.
    """
    p0 = check_positive("p0_kPa", p0_kPa)
    ea = check_positive("axial_strain", axial_strain)
    steps = check_steps(steps)
    model, params = _make_model(model_or_params, alpha_deg, rule)
    path = LoadPath(initial_stress=-p0 * np.eye(3))
    path.add(steps, eps_zz=-ea, eps_xx=0.0, eps_yy=0.0, eps_yz=0.0, eps_xz=0.0, eps_xy=0.0, name="oedometer")
    res = run_path(model, path, **engine)
    sxx, syy, szz = res["sig_xx_kPa"], res["sig_yy_kPa"], res["sig_zz_kPa"]
    with np.errstate(invalid="ignore", divide="ignore"):
        dk = (sxx - sxx[0]) / (szz - szz[0])
        dky = (syy - syy[0]) / (szz - szz[0])
    res.add_column("eps_a", -res.strain[:, 2, 2], "axial strain -eps_zz [-], compression +")
    res.add_column("sigma_v_kPa", -szz, "vertical effective stress -sigma_zz [kPa], compression +")
    res.add_column("K0", sxx / szz, "sigma_xx / sigma_zz (secant, from zero stress) [-]")
    res.add_column("K0_y", syy / szz, "sigma_yy / sigma_zz [-]")
    res.add_column("K0_incremental", dk, "(sigma_xx - sigma_xx0) / (sigma_zz - sigma_zz0) [-] (NaN at step 0)")
    res.add_column("K0_y_incremental", dky, "(sigma_yy - sigma_yy0) / (sigma_zz - sigma_zz0) [-]")
    return _finish(res, "oedometer", params, {"p0_kPa": p0, "alpha_deg": float(alpha_deg),
                                              "axial_strain": ea, "steps": steps},
                   [("eps_a", "sigma_v_kPa"), ("sigma_v_kPa", "K0")])


def simple_shear(model_or_params, sigma_n_kPa: float = 50.0, alpha_deg: float = 0.0, shear_strain: float = 0.2,
                 steps: int = 300, constant_height: bool = False, k0: float | None = None, *,
                 lateral: str = "band", rule: str | None = None, **engine) -> ElementResult:
    """Simple shear in the x-z plane of a layer with normal z: engineering shear strain gamma = 2 eps_xz.

    Initial effective stress: sigma_zz = -sigma_n and lateral sigma_xx = sigma_yy = -k0 sigma_n
    (``k0=None``: isotropic, k0 = 1). During shear: eps_xz prescribed (gamma from 0 to
    ``shear_strain``); the normal stress is held (``constant_height=False``) or the normal strain
    (``constant_height=True``: eps_zz fixed, the normal stress changes — the constant-volume,
    "undrained-like" variant of laboratory simple shear). Lateral conditions:

    * ``lateral="band"`` (default): the kinematics of a shear band with normal z, eps = sym(g x n)/t,
      i.e. eps_xx = eps_yy = eps_xy = 0 (rigid box walls / ring) and sigma_yz = 0 (eps_yz free, non-zero
      only for asymmetric fabrics); sigma_xx, sigma_yy evolve. With this choice the peak ratio
      tau/sigma_n approaches eta_f of the planes parallel to the layer, i.e. the direct-shear friction
      coefficient eta_f(alpha) (``docs/model.md``, "Inherent and induced anisotropy").
    * ``lateral="stress"``: sigma_xx, sigma_yy held at their initial values and sigma_xy = sigma_yz = 0
      (all lateral strains free). The Mohr circle then grows about a fixed centre and the peak
      tau/sigma_n stays well below eta_f (about 0.6 for ottawa_c109).

    alpha: angle between the layer normal z and e2.

    Columns: ``gamma`` (2 eps_xz), ``tau_kPa`` = sigma_xz (shear stress on the layer, + with gamma),
    ``sigma_n_kPa`` = -sigma_zz (compression +), ``tau_over_sigma_n``, ``eps_n`` = eps_zz (dilation +).
    """
    sn = check_positive("sigma_n_kPa", sigma_n_kPa)
    gamma = float(shear_strain)
    if not math.isfinite(gamma) or gamma == 0:
        raise ValueError(f"shear_strain = {shear_strain!r}: must be a finite non-zero engineering shear strain")
    steps = check_steps(steps)
    if lateral not in ("band", "stress"):
        raise ValueError(f"lateral = {lateral!r}; allowed: 'band', 'stress'")
    kk = 1.0 if k0 is None else check_positive("k0", k0)
    model, params = _make_model(model_or_params, alpha_deg, rule)
    path = LoadPath(initial_stress=-sn * np.diag([kk, kk, 1.0]))
    comps = {"eps_xz": gamma / 2.0}
    comps.update({"eps_zz": 0.0} if constant_height else {"sig_zz": -sn})
    if lateral == "stress":
        comps.update(sig_xx=-kk * sn, sig_yy=-kk * sn, sig_xy=0.0, sig_yz=0.0)
    else:
        comps.update(eps_xx=0.0, eps_yy=0.0, eps_xy=0.0, sig_yz=0.0)
    path.add(steps, name="simple shear", **comps)
    res = run_path(model, path, **engine)
    res.add_column("gamma", 2.0 * res.strain[:, 0, 2], "engineering shear strain 2 eps_xz [-]")
    res.add_column("tau_kPa", res.stress[:, 0, 2], "shear stress sigma_xz on the layer [kPa] (same sign as gamma)")
    res.add_column("sigma_n_kPa", -res.stress[:, 2, 2], "normal effective stress -sigma_zz [kPa], compression +")
    res.add_column("tau_over_sigma_n", res["tau_kPa"] / res["sigma_n_kPa"], "mobilised ratio tau / sigma_n [-]")
    res.add_column("eps_n", res.strain[:, 2, 2], "normal strain eps_zz of the layer [-], dilation +")
    return _finish(res, "simple_shear", params,
                   {"sigma_n_kPa": sn, "alpha_deg": float(alpha_deg), "shear_strain": gamma, "steps": steps,
                    "constant_height": bool(constant_height), "k0": kk, "lateral": lateral},
                   [("gamma", "tau_kPa"), ("gamma", "eps_n" if not constant_height else "sigma_n_kPa")])


def direct_shear(model_or_params, sigma_n_kPa: float = 50.0, alpha_deg: float = 0.0,
                 shear_displacement: float = 0.006, steps: int = 300, *, band_thickness_m: float | None = None,
                 k0: float | None = None, lateral: str = "band", rule: str | None = None,
                 **engine) -> ElementResult:
    """Direct shear as simple shear of a band of thickness t under constant normal stress.

    gamma = shear_displacement / t with t = params.t for the CPA law (or ``band_thickness_m``,
    default 0.006 m, for other laws). The band normal is z, the shear direction x; alpha is the angle
    between the shear-plane normal and e2 (``axes_from_alpha(alpha_deg)``). Initial state and the
    lateral conditions as in :func:`simple_shear` (default: isotropic start -sigma_n I, then the band
    kinematics eps_xx = eps_yy = eps_xy = 0, sigma_yz = 0, sigma_zz = -sigma_n held).

    Columns (besides those of :func:`simple_shear`): ``shear_displacement_m`` = gamma t,
    ``normal_displacement_m`` = eps_zz t (dilation +).
    """
    d = float(shear_displacement)
    if not math.isfinite(d) or d == 0:
        raise ValueError(f"shear_displacement = {shear_displacement!r}: must be a finite non-zero length [m]")
    from material.parameters import CPAParameters, load_preset

    if isinstance(model_or_params, str):
        model_or_params = load_preset(model_or_params)
    if isinstance(model_or_params, CPAParameters):
        if band_thickness_m is not None and not math.isclose(band_thickness_m, model_or_params.t):
            raise ValueError(f"band_thickness_m = {band_thickness_m!r}: the CPA band thickness is params.t = "
                             f"{model_or_params.t}; change it with params.replace(t=...)")
        t = model_or_params.t
    else:
        t = check_positive("band_thickness_m", 0.006 if band_thickness_m is None else band_thickness_m)
    res = simple_shear(model_or_params, sigma_n_kPa, alpha_deg, shear_strain=d / t, steps=steps, k0=k0,
                       lateral=lateral, rule=rule, **engine)
    res.add_column("shear_displacement_m", res["gamma"] * t, "shear displacement gamma t [m]")
    res.add_column("normal_displacement_m", res.strain[:, 2, 2] * t, "normal displacement eps_zz t [m], dilation +")
    res.metadata.update(test="direct_shear", shear_displacement=d, band_thickness_m=t)
    res.plot_pairs = [("shear_displacement_m", "tau_kPa"), ("shear_displacement_m", "normal_displacement_m")]
    return res


def cyclic_simple_shear(model_or_params, sigma_n_kPa: float = 50.0, alpha_deg: float = 0.0,
                        gamma_amplitude: float = 0.005, cycles: int = 3, steps_per_quarter: int = 25,
                        constant_height: bool = False, *, rule: str | None = None, **engine) -> ElementResult:
    """Strain-controlled cyclic simple shear, gamma: 0 -> +a -> -a -> ... -> 0, ``cycles`` full cycles.

    Same boundary conditions as :func:`simple_shear` (isotropic start, band kinematics);
    ``constant_height=True`` holds eps_zz (the normal stress then evolves, e.g. decreases).
    """
    sn = check_positive("sigma_n_kPa", sigma_n_kPa)
    amp = check_positive("gamma_amplitude", gamma_amplitude)
    if isinstance(cycles, bool) or not isinstance(cycles, (int, np.integer)) or cycles < 1:
        raise ValueError(f"cycles = {cycles!r}: must be an integer >= 1")
    nq = check_steps(steps_per_quarter)
    model, params = _make_model(model_or_params, alpha_deg, rule)
    path = LoadPath(initial_stress=-sn * np.eye(3))
    base = {"eps_xx": 0.0, "eps_yy": 0.0, "eps_xy": 0.0, "sig_yz": 0.0}
    base.update({"eps_zz": 0.0} if constant_height else {"sig_zz": -sn})
    targets = [amp] + [-amp, amp] * cycles
    targets[-1] = 0.0
    for i, g in enumerate(targets):
        last = targets[i - 1] if i else 0.0
        path.add(nq * max(1, int(round(abs(g - last) / amp))), eps_xz=g / 2.0, relative_strain=False,
                 name=f"to gamma={g:g}", **base)
    res = run_path(model, path, **engine)
    res.add_column("gamma", 2.0 * res.strain[:, 0, 2], "engineering shear strain 2 eps_xz [-]")
    res.add_column("tau_kPa", res.stress[:, 0, 2], "shear stress sigma_xz [kPa]")
    res.add_column("sigma_n_kPa", -res.stress[:, 2, 2], "normal effective stress -sigma_zz [kPa], compression +")
    res.add_column("eps_n", res.strain[:, 2, 2], "normal strain eps_zz [-], dilation +")
    return _finish(res, "cyclic_simple_shear", params,
                   {"sigma_n_kPa": sn, "alpha_deg": float(alpha_deg), "gamma_amplitude": amp, "cycles": int(cycles),
                    "constant_height": bool(constant_height)},
                   [("gamma", "tau_kPa"), ("gamma", "eps_n" if not constant_height else "sigma_n_kPa")])


def plane_strain(model_or_params, p0_kPa: float = 100.0, alpha_deg: float = 0.0, axial_strain: float = 0.1,
                 steps: int = 300, *, rule: str | None = None, **engine) -> ElementResult:
    """Plane-strain (biaxial) compression: axial strain along z, sigma3 = sigma_xx = -p0 held, eps_yy = 0.

    Shear stresses are held at zero. Columns: ``eps_a`` (-eps_zz), ``q13_kPa`` = sigma_a - sigma_xx
    (compression +), ``q_kPa`` = sqrt(3 J2), ``sigma2_kPa`` = -sigma_yy (the out-of-plane stress),
    ``b`` = (sigma2 - sigma3)/(sigma1 - sigma3) on the principal values, and Rice's localisation condition
    on each step's tangent: ``rice_indicator`` (< 0: a band can form), ``rice_band_deg``, and
    ``metadata["bifurcation"]``, the onset (:func:`_bifurcation`; ``docs/regularisation.md``, section 4).

    Where the bedding is mirror-symmetric about the axes (alpha = 0 or 90 deg) and the law softens with the
    step stabilisation, the path branches after the peak: the two planes of a mirror pair stop loading
    together, one unloads, and the point shears, eps_xz growing from round-off to about 1e-2 by 8 % axial
    strain. The sense of that shear
    is not set by the loading (it changes with the number of steps); the mirror image of the path is the
    path sheared the other way, with the rising and falling columns exchanged (``docs/regularisation.md``,
    section 4, "The element path shears after the peak"). ``metadata["shear_onset"]`` says where
    (:func:`_shear_onset`; None where the path keeps its symmetry or the bedding has none). The
    rate-independent law keeps the symmetric path (measured at alpha = 0 and 90 deg).
    """
    p0 = check_positive("p0_kPa", p0_kPa)
    ea = check_positive("axial_strain", axial_strain)
    steps = check_steps(steps)
    model, params = _make_model(model_or_params, alpha_deg, rule)
    path = LoadPath(initial_stress=-p0 * np.eye(3))
    path.add(steps, eps_zz=-ea, sig_xx=-p0, eps_yy=0.0, **_ZERO_SHEAR, name="plane strain")
    res = run_path(model, path, **engine)
    res.add_column("eps_a", -res.strain[:, 2, 2], "axial strain -eps_zz [-], compression +")
    res.add_column("q13_kPa", res["sig_xx_kPa"] - res["sig_zz_kPa"], "sigma_zz - sigma_xx deviator, compression + [kPa]")
    res.add_column("sigma2_kPa", -res["sig_yy_kPa"], "out-of-plane effective stress -sigma_yy [kPa], compression +")
    with np.errstate(invalid="ignore", divide="ignore"):
        b = (res["sig2_kPa"] - res["sig3_kPa"]) / (res["sig1_kPa"] - res["sig3_kPa"])
    res.add_column("b", b, "(sigma2 - sigma3)/(sigma1 - sigma3) [-] (NaN at isotropic states)")
    onset = _bifurcation(res)
    return _finish(res, "plane_strain", params,
                   {"p0_kPa": p0, "alpha_deg": float(alpha_deg), "axial_strain": ea, "steps": steps,
                    "bifurcation": onset, "shear_onset": _shear_onset(res, alpha_deg)},
                   [("eps_a", "q13_kPa"), ("eps_a", "eps_v"), ("eps_a", "rice_indicator")])


#: The shear strain at which a mirror-symmetric path counts as sheared (:func:`_shear_onset`), as a fraction of
#: the axial strain: nine to ten orders of magnitude above the round-off the shear grows from (1e-17),
#: four to five below what it grows to (3e-3 to 2e-2 by 5-8 %). Measured on the shear-band study's sand
#: (mu = 0.01, alpha = 0, to 5 %), fractions of 1e-9 / 1e-6 / 1e-4 give the rows 649 / 651 / 651 of 1000 with
#: ``equator-78``, whose symmetric branch ends in a fold, and 200 / 209 / 214 of 400 and 700 / 717 / 727 of
#: 1600 with the default rule, whose shear grows by 2.15 times a step (``docs/regularisation.md``,
#: section 4): the row moves by 0.01-0.18 % of axial strain over five orders of the fraction.
SHEAR_ONSET = 1e-6


def _shear_onset(res: ElementResult, alpha_deg: float) -> dict | None:
    """Where a plane-strain path on a mirror-symmetric bedding (alpha = 0 or 90 deg), which by symmetry keeps
    eps_xz = 0, shears: the first row where |eps_xz| exceeds :data:`SHEAR_ONSET` of the axial strain, its
    axial strain, q13 and the sign of the shear (the sense, which round-off decides). None where the path
    keeps its symmetry, or where the bedding has none (it shears from the start)."""
    if float(alpha_deg) % 90.0 != 0.0:
        return None
    shear, ea = res["eps_xz"], res["eps_a"]
    rows = np.flatnonzero(np.abs(shear) > SHEAR_ONSET * np.abs(ea))
    if rows.size == 0:
        return None
    i = int(rows[0])
    return {"row": i, "eps_a": float(ea[i]), "q13_kPa": float(res["q13_kPa"][i]), "sense": float(np.sign(shear[-1]))}


def _bifurcation(res: ElementResult) -> dict | None:
    """Rice's condition along a plane-strain path in the x-z plane (:mod:`material.localisation`): the
    columns ``rice_indicator`` and ``rice_band_deg`` (inclination from x, the sigma3 axis, of the band whose
    acoustic tensor is nearest to singular), and the onset: the first row past it (indicator below
    -:data:`material.localisation.ONSET`), its axial strain and q13, and the band's inclination at the last
    elliptic row folded into 0..90 deg (the two mirror bands of a symmetric specimen are one). ``None``
    where the path stays elliptic.

    Each family of bands also has its own columns, ``rice_rising_indicator`` / ``rice_rising_deg`` (bands
    rising toward +x, toward which the driver tilts the deposition axis) and ``rice_falling_...``, and the
    onset names both at the last elliptic row (``rising_deg``, ``falling_deg``) and the ``family`` that
    forms first (``"both"`` where the two are mirror images, as at alpha = 0 and 90 deg): with a tilted
    bedding the two arms of an X are not symmetric, and a boundary-value problem's arms are compared each
    with its own (docs/regularisation.md, section 4)."""
    from material.localisation import ONSET, ellipticity

    loc = ellipticity(res.tangent, plane=(0, 2), resolution_deg=0.25, families=True)
    res.add_column("rice_indicator", loc["indicator"], "Rice's localisation indicator of the step's tangent, "
                   "min over band normals in the x-z plane of det Q / (|Q|/sqrt 2)^2 [-] (< 0: a band can form)")
    res.add_column("rice_band_deg", loc["band_deg"], "inclination from x (the sigma3 axis) of the band nearest to "
                   "forming [deg]")
    folded = {"rising": loc["rising_band_deg"], "falling": 180.0 - loc["falling_band_deg"]}
    for family, sense in (("rising", "rising toward +x"), ("falling", "falling toward +x")):
        res.add_column(f"rice_{family}_indicator", loc[f"{family}_indicator"],
                       f"Rice's indicator over the {family} bands only ({sense}) [-]")
        res.add_column(f"rice_{family}_deg", np.round(np.where(folded[family] == 180.0, 0.0, folded[family]), 9),
                       f"inclination from x of the {family} band nearest to forming, folded into 0..90 [deg]")
    lost = np.flatnonzero(loc["indicator"][1:] < -ONSET)
    if lost.size == 0:
        return None
    i = int(lost[0]) + 1
    band = float(loc["band_deg"][i - 1])
    rising, falling = float(loc["rising_indicator"][i - 1]), float(loc["falling_indicator"][i - 1])
    # mirror images up to round-off (measured at alpha = 0 and 90: 4e-12 and 3e-14 of the indicator)
    mirror = abs(rising - falling) <= 1e-9 * max(abs(rising), abs(falling), 1e-300)
    return {"row": i, "eps_a": float(res["eps_a"][i]), "q13_kPa": float(res["q13_kPa"][i]),
            "band_deg": round(min(band, 180.0 - band), 9),
            "family": "both" if mirror else ("rising" if rising < falling else "falling"),
            "rising_deg": float(res["rice_rising_deg"][i - 1]), "falling_deg": float(res["rice_falling_deg"][i - 1])}


def true_triaxial(model_or_params, p0_kPa: float = 100.0, alpha_deg: float = 0.0, b: float = 0.5,
                  axial_strain: float = 0.1, steps: int = 300, *, rule: str | None = None, **engine) -> ElementResult:
    """True triaxial compression at constant b = (sigma2 - sigma3) / (sigma1 - sigma3).

    sigma1 on z (eps_zz prescribed, compression), sigma3 = sigma_xx = -p0 held, and sigma2 on y tied to
    them by the linear condition sigma_yy - b sigma_zz - (1 - b) sigma_xx = 0 (all tension +); shear
    stresses 0. b = 0 is triaxial compression, b = 1 triaxial extension (in stress space).
    """
    p0 = check_positive("p0_kPa", p0_kPa)
    ea = check_positive("axial_strain", axial_strain)
    steps = check_steps(steps)
    bb = float(b)
    if not (0.0 <= bb <= 1.0):
        raise ValueError(f"b = {b!r}: allowed 0 <= b <= 1")
    model, params = _make_model(model_or_params, alpha_deg, rule)
    a_mat, b_mat = np.zeros((6, 6)), np.zeros((6, 6))
    a_mat[2, 2] = 1.0
    b_mat[0, 0] = 1.0
    b_mat[1, [1, 2, 0]] = [1.0, -bb, -(1.0 - bb)]
    b_mat[3, 3] = b_mat[4, 4] = b_mat[5, 5] = 1.0
    target = np.array([-p0, 0.0, -ea, 0.0, 0.0, 0.0])
    rel = np.array([False, False, True, False, False, False])
    path = LoadPath(initial_stress=-p0 * np.eye(3))
    path.add_conditions(steps, a_mat, b_mat, target, rel, name=f"true triaxial b={bb:g}")
    res = run_path(model, path, **engine)
    res.add_column("eps_a", -res.strain[:, 2, 2], "axial strain -eps_zz [-], compression +")
    res.add_column("eta", res["q_kPa"] / res["p_kPa"], "stress ratio sqrt(3 J2) / p [-]")
    return _finish(res, "true_triaxial", params,
                   {"p0_kPa": p0, "alpha_deg": float(alpha_deg), "b": bb, "axial_strain": ea, "steps": steps},
                   [("eps_a", "q_kPa"), ("eps_a", "eps_v")])


def rotation(model_or_params="ottawa_c109_induced", p0_kPa: float = 14.0, delta_psi_deg: float = 90.0, *,
             preshear_strain: float = 0.02, axial_strain: float = 0.05, steps: int = 200,
             preshear_steps: int | None = None, unload_steps: int = 50, alpha_deg: float = 0.0,
             rule: str | None = None, **engine) -> ElementResult:
    """Principal stress rotation in plane strain (directional shear cell, thesis Figs. 45-47).

    The loading plane is x-y; z is the out-of-plane direction (eps_zz = 0, sigma_xz = sigma_yz = 0)
    and, with the default ``alpha_deg = 0``, also the deposition axis e2 (sand poured normal to the
    loading plane, as in the directional shear cell: initially isotropic in that plane).

    Stages, all drained, from the hydrostatic -p0 I:

    1. pre-shear: sigma1 along x, eps_xx prescribed to ``-preshear_strain`` (compression), sigma_yy =
       -p0 and sigma_xy = 0 held;
    2. unload to hydrostatic: sigma_xx back to -p0 by stress control (sigma_yy = -p0, sigma_xy = 0);
    3. reshear with sigma1 along the direction at ``delta_psi_deg`` from x in the x-y plane: in that
       rotated frame (x', y') eps_x'x' is prescribed to ``-axial_strain`` (relative), sigma_y'y' = -p0
       and sigma_x'y' = 0, so the principal stress directions are fixed at the rotated axes.

    Columns (besides the standard ones): ``eps_1r`` (compression strain along x' since the start of
    the reshear), ``q_kPa`` = sqrt(3 J2), ``t_kPa`` = (sigma_x'x' - sigma_y'y')/2 in the rotated frame
    (compression +), ``eps_x'x'`` etc. in the columns ``eps_11r``, ``eps_22r``, ``eps_12r`` (tension +,
    rotated frame, measured from the start of the path).
    """
    p0 = check_positive("p0_kPa", p0_kPa)
    pre = check_positive("preshear_strain", preshear_strain, allow_zero=True)
    ea = check_positive("axial_strain", axial_strain)
    steps = check_steps(steps)
    psteps = check_steps(preshear_steps if preshear_steps is not None else steps)
    usteps = check_steps(unload_steps)
    dpsi = float(delta_psi_deg)
    if not math.isfinite(dpsi):
        raise ValueError(f"delta_psi_deg = {delta_psi_deg!r}: must be a finite angle in degrees")
    model, params = _make_model(model_or_params, alpha_deg, rule)
    path = LoadPath(initial_stress=-p0 * np.eye(3))
    out_of_plane = {"eps_zz": 0.0, "sig_xz": 0.0, "sig_yz": 0.0}
    if pre > 0:
        path.add(psteps, eps_xx=-pre, sig_yy=-p0, sig_xy=0.0, name="pre-shear", **out_of_plane)
        path.add(usteps, sig_xx=-p0, sig_yy=-p0, sig_xy=0.0, name="unload", **out_of_plane)
    frame = rotation_about_z(dpsi)
    path.add(steps, frame=frame, eps_xx=-ea, sig_yy=-p0, sig_xy=0.0, name=f"reshear dpsi={dpsi:g}", **out_of_plane)
    res = run_path(model, path, **engine)
    r = frame
    e_rot = np.einsum("ai,nab,bj->nij", r, res.strain, r)
    s_rot = np.einsum("ai,nab,bj->nij", r, res.stress, r)
    reshear = res["stage"] == len(path.segments) - 1
    start = int(np.argmax(reshear)) - 1 if reshear.any() else len(res) - 1
    e1r = -(e_rot[:, 0, 0] - e_rot[start, 0, 0])
    e1r[:start] = np.nan
    res.add_column("eps_1r", e1r, "compression strain along x' since the start of the reshear [-] (NaN before)")
    res.add_column("t_kPa", 0.5 * (s_rot[:, 1, 1] - s_rot[:, 0, 0]), "(sigma_x'x' - sigma_y'y')/2, rotated frame, compression + [kPa]")
    res.add_column("eps_11r", e_rot[:, 0, 0], "eps_x'x' in the rotated frame [-], tension +")
    res.add_column("eps_22r", e_rot[:, 1, 1], "eps_y'y' in the rotated frame [-], tension +")
    res.add_column("eps_12r", e_rot[:, 0, 1], "eps_x'y' in the rotated frame [-], tension +")
    return _finish(res, "rotation", params,
                   {"p0_kPa": p0, "delta_psi_deg": dpsi, "preshear_strain": pre, "axial_strain": ea,
                    "steps": steps, "alpha_deg": float(alpha_deg), "reshear_start_row": start},
                   [("eps_1r", "q_kPa"), ("eps_1r", "eps_v")])
