"""Parameter identification of the CPA law from laboratory data, by least squares (``docs/identification.md``).

Two problems, each returning an :class:`Identification` (values, standard errors, 95 % confidence
intervals, residuals, fit quality, the identified :class:`~material.parameters.CPAParameters`, and
tables of the data against the fit), which :meth:`Identification.write` turns into a folder
(``parameters.toml``, ``fit.csv``, ``curve.csv``, ``fit.png``):

* :func:`direct_shear` -- the strength distribution from direct-shear Coulomb envelopes
  tau = slope sigma_n + intercept at several deposition angles alpha (thesis Fig. 8): the friction
  series eta_f(alpha) = eta0 (1 + x + a1 x^2 + ...), x = omega1 (1 - 3 cos^2 alpha) (eqs. 2.19, 2.20)
  is fitted to the slopes, the cohesion series c(alpha) = c0 (1 + x_c + b1 x_c^2 + ...),
  x_c = omega1_c (1 - 3 cos^2 alpha) (eq. 2.4) to the intercepts. A closed-form model: the fit is
  started from the linear least-squares polynomial in u = 1 - 3 cos^2 alpha (to which the series is
  equivalent) and refined with the analytic Jacobian under the bounds eta0 > 0, |omega1| < 0.5,
  c0 >= 0, |omega1_c| < 0.5.
* :func:`triaxial` -- the hardening, elastic and dilatancy constants (A, E, nu, eta_c_ratio, ...)
  from measured stress-strain curves (drained triaxial, direct shear, or any mixed stress/strain path),
  with the element driver :func:`material.driver.run_path` as the forward model and a finite-difference
  Jacobian in scaled variables (log of the positive constants).

Statistics (both problems): with r the residual vector (n values, scaled to a common unit), J its
Jacobian with respect to the p free variables at the optimum, s^2 = SSR / (n - p) and
cov = s^2 (J^T J)^-1 (computed by SVD: a direction the data do not determine gets an infinite error);
the 95 % interval is value +- t_{0.975, n-p} stderr in the optimisation variable (for a parameter
optimised as its logarithm: the exponentiated interval, so it stays positive).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from material.parameters import CPAParameters, load_parameters, load_preset, save_parameters
from material.table import Table, jsonable, read_table

__all__ = [
    "Identification",
    "Curve",
    "FREE_PARAMETERS",
    "direct_shear",
    "triaxial",
    "read_envelopes",
    "read_curve",
    "simulate",
    "softening_detected",
    "SHIPPED_ENVELOPES",
]

#: The literal that names the Fig. 8 envelopes shipped with the package (``material/data``).
SHIPPED_ENVELOPES = "fig8"
_SHIPPED_FILE = "data/ottawa_c109_direct_shear_envelopes.csv"
_ENVELOPE_COLUMNS = ("alpha_deg", "slope", "intercept_kPa")
_OMEGA_BOUND = 0.4999  # |omega1| < 0.5 (CPAParameters), kept strictly inside


# ====================================================================================== result
@dataclass(frozen=True)
class Identification:
    """The result of an identification (:func:`direct_shear`, :func:`triaxial`).

    Attributes
    ----------
    kind : str
        ``"direct_shear"`` or ``"triaxial"``.
    names : tuple of str
        Identified quantities, e.g. ``("eta0", "omega1", "a1", "a2", "c0", "omega1_c")`` or
        ``("A", "E", "nu", "eta_c_ratio")``; ``a1``, ``b1``, ... are the entries of the tuples
        ``CPAParameters.a`` and ``.b``.
    values, stderr : (p,) ndarray
        Estimates and their standard errors (linearised; inf where the data do not determine a
        direction of the parameter space).
    ci95 : (p, 2) ndarray
        95 % confidence intervals (t distribution with ``dof`` degrees of freedom).
    residuals : dict of str to ndarray
        Fitted minus measured value of every data point used, per measured quantity (data units).
    rms, r2 : dict of str to float
        Root-mean-square residual (data units) and coefficient of determination per quantity.
    dof : dict of str to int
        Degrees of freedom n - p of each least-squares problem (``"friction"``, ``"cohesion"``, or
        ``"curves"``).
    parameters : CPAParameters
        The identified values in the base parameter set (the rest unchanged).
    data : Table
        One row per data point: measured, fitted, residual (what ``fit.csv`` holds).
    fit : Table
        The fitted model as a dense curve (eta_f and c over alpha in [0, 90], or the simulated
        curves), what ``curve.csv`` holds.
    info : dict
        Everything else worth recording: sources, base parameter set, bounds hit, correlation
        matrix, optimiser status, number of forward runs, wall time, warnings.
    """

    kind: str
    names: tuple[str, ...]
    values: np.ndarray
    stderr: np.ndarray
    ci95: np.ndarray
    residuals: dict[str, np.ndarray]
    rms: dict[str, float]
    r2: dict[str, float]
    dof: dict[str, int]
    parameters: CPAParameters
    data: Table
    fit: Table
    info: dict = field(default_factory=dict)

    def value(self, name: str) -> float:
        """The estimate of ``name`` (KeyError naming the identified quantities otherwise)."""
        return float(self.values[self._index(name)])

    def interval(self, name: str) -> tuple[float, float]:
        """The 95 % confidence interval of ``name``."""
        lo, hi = self.ci95[self._index(name)]
        return float(lo), float(hi)

    def _index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{name!r} was not identified; identified: {list(self.names)}") from None

    def summary(self) -> str:
        """A short plain-text table: name, value, standard error, 95 % interval; then rms and R^2."""
        lines = [f"{'parameter':<12} {'value':>12} {'std. error':>12}   95 % confidence interval"]
        for n, v, s, (lo, hi) in zip(self.names, self.values, self.stderr, self.ci95):
            flag = "  (at a bound)" if n in self.info.get("at_bounds", ()) else ""
            lines.append(f"{n:<12} {v:>12.5g} {s:>12.3g}   [{lo:.5g}, {hi:.5g}]{flag}")
        for q in self.rms:
            lines.append(f"{q}: rms residual {self.rms[q]:.4g}, R^2 {self.r2[q]:.4f}")
        lines.append("degrees of freedom: " + ", ".join(f"{k} {v}" for k, v in self.dof.items()))
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """The numbers as plain JSON/TOML-able values (what ``parameters.toml`` records under
        ``[metadata.identification]``)."""
        return jsonable({
            "kind": self.kind,
            "names": list(self.names),
            "values": self.values,
            "stderr": self.stderr,
            "ci95_low": self.ci95[:, 0],
            "ci95_high": self.ci95[:, 1],
            "rms": self.rms,
            "r2": self.r2,
            "dof": self.dof,
            **{k: v for k, v in self.info.items() if k != "warnings" or v},
        })

    def write(self, out_dir, command: str | None = None) -> dict[str, Path]:
        """Write ``parameters.toml``, ``fit.csv``, ``curve.csv`` and ``fit.png`` into ``out_dir``.

        ``parameters.toml`` is a :func:`~material.parameters.save_parameters` file (readable by
        :func:`~material.parameters.load_parameters`): the identified values in the base parameter
        set, the fit (values, errors, intervals, rms, R^2, sources) and ``command`` in its
        ``[metadata]`` table, and the same summary as comment lines at the top.

        Returns
        -------
        dict of str to Path
            ``{"parameters": ..., "fit": ..., "curve": ..., "figure": ...}``.
        """
        from material.version import __version__

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        record = self.to_dict()
        if command:
            record["command"] = command
        toml = save_parameters(self.parameters, out / "parameters.toml", femgran_version=__version__,
                               identification=record)
        head = [f"# CPA parameters identified by femgran ({self.kind.replace('_', ' ')} data)"]
        if command:
            head.append(f"# command: {command}")
        head += ["# " + ln for ln in self.summary().splitlines()]
        head.append("# (metadata.identification holds these numbers; load_parameters ignores them)")
        toml.write_text("\n".join(head) + "\n\n" + toml.read_text())
        paths = {"parameters": toml, "fit": self.data.write_csv(out / "fit.csv"),
                 "curve": self.fit.write_csv(out / "curve.csv")}
        paths["figure"] = _plot(self, out / "fit.png")
        return paths


# ====================================================================================== statistics
def _statistics(jac: np.ndarray, resid: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, float]:
    """Covariance of the least-squares estimate: s^2 (J^T J)^-1 by SVD.

    Returns (cov (p, p), stderr (p,), dof, s2). Singular directions (singular value below 1e-10 of the
    largest) get an infinite variance on every parameter they involve.
    """
    n, p = jac.shape
    dof = n - p
    s2 = float(resid @ resid) / dof if dof > 0 else math.nan
    if p == 0:
        return np.zeros((0, 0)), np.zeros(0), dof, s2
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    keep = sv > 1e-10 * sv.max() if sv.size and sv.max() > 0 else np.zeros_like(sv, dtype=bool)
    inv = np.where(keep, 1.0 / np.where(keep, sv, 1.0) ** 2, 0.0)
    cov = s2 * (vt.T * inv) @ vt
    var = np.diag(cov).copy()
    if (~keep).any():
        null = np.abs(vt[~keep]).max(axis=0) > 1e-8
        var[null] = np.inf
    return cov, np.sqrt(np.maximum(var, 0.0)), dof, s2


def _t95(dof: int) -> float:
    from scipy.stats import t

    return float(t.ppf(0.975, dof)) if dof > 0 else math.nan


def _quality(fitted: np.ndarray, measured: np.ndarray) -> tuple[float, float]:
    """(rms of fitted - measured, R^2 = 1 - SSR / SST)."""
    r = fitted - measured
    sst = float(np.sum((measured - measured.mean()) ** 2))
    ssr = float(r @ r)
    return math.sqrt(ssr / len(r)), (1.0 - ssr / sst) if sst > 0 else math.nan


def _correlation(cov: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        return cov / np.outer(d, d)


def _base_parameters(preset) -> CPAParameters:
    """A preset name, a parameter file (.toml / .json) or CPAParameters."""
    if isinstance(preset, CPAParameters):
        return preset
    if isinstance(preset, Path) or (isinstance(preset, str) and preset.lower().endswith((".toml", ".json"))):
        return load_parameters(preset)
    if isinstance(preset, str):
        return load_preset(preset)
    raise ValueError(f"preset = {preset!r}: allowed a preset name, a parameter file (.toml/.json) or CPAParameters")


# ====================================================================================== direct shear
def read_envelopes(envelopes) -> dict[str, np.ndarray]:
    """The direct-shear envelopes as arrays ``alpha_deg``, ``slope``, ``intercept_kPa``, checked.

    Parameters
    ----------
    envelopes : path, mapping or ``"fig8"``
        A CSV with the columns ``alpha_deg`` (angle between the shear-plane normal and the
        deposition axis [deg]), ``slope`` (tan of the friction angle of the Coulomb envelope [-]) and
        ``intercept_kPa`` (its intercept [kPa]); lines starting with ``#`` are comments, other
        columns are ignored. Or a mapping of the same names to sequences. ``"fig8"``: the thesis's
        Fig. 8 envelopes of Ottawa C109 sand shipped with the package.

    Raises
    ------
    ValueError
        A missing column (named), NaN/inf, an angle outside [0, 90], repeated angles, fewer than two
        rows, or columns of different lengths.
    FileNotFoundError
        A path that does not exist.
    """
    if isinstance(envelopes, str) and envelopes == SHIPPED_ENVELOPES:
        from importlib.resources import as_file, files

        with as_file(files("material").joinpath(_SHIPPED_FILE)) as path:
            table = read_table(path)
        cols, source = {k: table[k] for k in table.columns}, f"fig8 (material/{_SHIPPED_FILE})"
    elif isinstance(envelopes, (str, Path)):
        path = Path(envelopes)
        if not path.is_file():
            raise FileNotFoundError(f"envelope file {str(path)!r} does not exist (or give 'fig8' for the shipped "
                                    "Fig. 8 data)")
        table = read_table(path)
        cols, source = {k: table[k] for k in table.columns}, str(path)
    elif isinstance(envelopes, Mapping):
        cols, source = dict(envelopes), "<mapping>"
    else:
        raise ValueError(f"envelopes = {envelopes!r}: allowed a CSV path, a mapping of columns or 'fig8'")
    missing = [c for c in _ENVELOPE_COLUMNS if c not in cols]
    if missing:
        raise ValueError(f"envelopes ({source}): missing column(s) {missing}; required: {list(_ENVELOPE_COLUMNS)} "
                         f"(found {sorted(cols)})")
    out = {}
    for c in _ENVELOPE_COLUMNS:
        try:
            v = np.asarray(cols[c], dtype=float).ravel()
        except (TypeError, ValueError):
            raise ValueError(f"envelopes ({source}): column {c!r} holds values that are not numbers") from None
        bad = ~np.isfinite(v)
        if bad.any():
            rows = np.flatnonzero(bad).tolist()
            raise ValueError(f"envelopes ({source}): column {c!r} has NaN/inf in row(s) {rows}; "
                             "allowed: finite numbers")
        out[c] = v
    lengths = {c: len(v) for c, v in out.items()}
    if len(set(lengths.values())) != 1:
        raise ValueError(f"envelopes ({source}): columns of different lengths {lengths}")
    a = out["alpha_deg"]
    if len(a) < 2:
        raise ValueError(f"envelopes ({source}): {len(a)} row(s); at least 2 deposition angles are needed")
    if ((a < 0) | (a > 90)).any():
        raise ValueError(f"envelopes ({source}): alpha_deg = {a.tolist()}; allowed: 0 <= alpha_deg <= 90")
    if len(np.unique(a)) != len(a):
        raise ValueError(f"envelopes ({source}): alpha_deg = {a.tolist()} repeats an angle; give one envelope per "
                         "angle (fit the Coulomb line to all tests at that angle first)")
    if (out["slope"] <= 0).any():
        raise ValueError(f"envelopes ({source}): slope = {out['slope'].tolist()}; allowed: slope > 0")
    order = np.argsort(a)
    out = {c: v[order] for c, v in out.items()}
    out["source"] = source  # type: ignore[assignment]
    return out


def _u(alpha_deg) -> np.ndarray:
    """u = 1 - 3 cos^2 alpha, so that x = omega1 u (eq. 2.19)."""
    return 1.0 - 3.0 * np.cos(np.deg2rad(np.asarray(alpha_deg, dtype=float))) ** 2


def _series_value(theta: np.ndarray, u: np.ndarray) -> np.ndarray:
    """lead (1 + x + k1 x^2 + ...), x = omega u, theta = (lead, omega, k1, k2, ...) (eqs. 2.4, 2.20)."""
    from material.anisotropy import series

    if len(theta) == 1:  # order 0: the constant lead
        return np.full(len(u), float(theta[0]))
    return theta[0] * series(theta[1] * u, theta[2:])


def _series_jacobian(theta: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(n, p) derivatives of :func:`_series_value` with respect to theta."""
    from material.anisotropy import series

    if len(theta) == 1:
        return np.ones((len(u), 1))
    lead, omega, ks = theta[0], theta[1], theta[2:]
    x = omega * u
    jac = np.empty((len(u), len(theta)))
    jac[:, 0] = series(x, ks)
    dseries_dx = 1.0 + sum((k + 2) * c * x ** (k + 1) for k, c in enumerate(ks))
    jac[:, 1] = lead * dseries_dx * u
    for k in range(len(ks)):
        jac[:, 2 + k] = lead * x ** (k + 2)
    return jac


def _series_start(u: np.ndarray, y: np.ndarray, order: int, lead_min: float) -> np.ndarray:
    """Start values from the linear least-squares polynomial q0 + q1 u + ... + q_N u^N: the series
    lead (1 + x + k1 x^2 + ...), x = omega u, is the same polynomial with q0 = lead, q1 = lead omega,
    q_{k+1} = lead k_k omega^(k+1); mapped back (omega clipped into the bounds)."""
    vander = np.vander(u, order + 1, increasing=True)
    q, *_ = np.linalg.lstsq(vander, y, rcond=None)
    lead = max(float(q[0]), lead_min) if q[0] > 0 else max(float(np.mean(y)), lead_min, 1e-6)
    theta = np.zeros(order + 1)
    theta[0] = lead
    if order >= 1:
        omega = float(q[1]) / lead
        if not abs(omega) > 1e-3:
            omega = 1e-3
        omega = float(np.clip(omega, -0.9 * _OMEGA_BOUND, 0.9 * _OMEGA_BOUND))
        theta[1] = omega
        for k in range(1, order):
            theta[1 + k] = float(q[k + 1]) / (lead * omega ** (k + 1))
    return theta


@dataclass(frozen=True)
class _SeriesFit:
    theta: np.ndarray
    stderr: np.ndarray
    ci95: np.ndarray
    cov: np.ndarray
    dof: int
    fitted: np.ndarray
    at_bounds: tuple[int, ...]
    status: str


def _fit_series(u: np.ndarray, y: np.ndarray, order: int, lead_low: float) -> _SeriesFit:
    """Bounded least squares of ``lead (1 + x + k1 x^2 + ...)``, x = omega u, to y; order N: N + 1
    unknowns (lead, omega, k1 .. k_{N-1}), order 0: the lead only."""
    from scipy.optimize import least_squares

    p = order + 1
    theta0 = _series_start(u, y, order, lead_low)
    lo = np.full(p, -np.inf)
    hi = np.full(p, np.inf)
    lo[0] = lead_low
    if p > 1:
        lo[1], hi[1] = -_OMEGA_BOUND, _OMEGA_BOUND
    with np.errstate(invalid="ignore"):
        inner_lo = np.where(np.isfinite(lo), lo + 1e-9 * (1 + np.abs(lo)), -np.inf)
        inner_hi = np.where(np.isfinite(hi), hi - 1e-9 * (1 + np.abs(hi)), np.inf)
    theta0 = np.clip(theta0, inner_lo, inner_hi)
    res = least_squares(lambda th: _series_value(th, u) - y, theta0, jac=lambda th: _series_jacobian(th, u),
                        bounds=(lo, hi), method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        max_nfev=2000)
    theta = res.x
    resid = _series_value(theta, u) - y
    jac = _series_jacobian(theta, u)
    cov, se, dof, _ = _statistics(jac, resid)
    t = _t95(dof)
    ci = np.clip(np.column_stack([theta - t * se, theta + t * se]), lo[:, None], hi[:, None])  # inside the bounds
    at = tuple(int(i) for i in range(p) if (np.isfinite(lo[i]) and theta[i] - lo[i] <= 1e-7 * (1 + abs(lo[i])))
               or (np.isfinite(hi[i]) and hi[i] - theta[i] <= 1e-7 * (1 + abs(hi[i]))))
    return _SeriesFit(theta, se, ci, cov, dof, _series_value(theta, u), at, str(res.message))


def _series_band(fit: _SeriesFit, u: np.ndarray) -> np.ndarray:
    """Standard error of the fitted curve at u (delta method: sqrt(g^T cov g), g = d value / d theta)."""
    g = _series_jacobian(fit.theta, u)
    var = np.einsum("ni,ij,nj->n", g, fit.cov, g)
    return np.sqrt(np.maximum(var, 0.0))


def _select_cohesion(u: np.ndarray, y: np.ndarray, max_order: int) -> tuple[_SeriesFit, int, list]:
    """The cohesion series of the lowest order the intercepts support: starting from a constant c0, a
    term is added while it reduces the residual significantly (F test of nested least-squares
    models, p < 0.05) and no parameter ends at a bound; ``max_order`` caps it. Returns the fit, its
    order and the steps taken ``[{"order", "ssr", "p_value", "at_bound"}, ...]``."""
    from scipy.stats import f as f_dist

    n = len(u)
    best = _fit_series(u, y, 0, 0.0)
    ssr_prev = float(np.sum((best.fitted - y) ** 2))
    steps = [{"order": 0, "ssr": ssr_prev, "p_value": math.nan, "at_bound": bool(best.at_bounds)}]
    chosen = 0
    for k in range(1, max_order + 1):
        trial = _fit_series(u, y, k, 0.0)
        ssr = float(np.sum((trial.fitted - y) ** 2))
        dof = n - k - 1
        if dof < 1:
            break
        stat = (ssr_prev - ssr) / (ssr / dof) if ssr > 0 else math.inf
        p = float(f_dist.sf(stat, 1, dof)) if math.isfinite(stat) else 0.0
        steps.append({"order": k, "ssr": ssr, "p_value": p, "at_bound": bool(trial.at_bounds)})
        if p >= 0.05 or trial.at_bounds:
            break
        best, chosen, ssr_prev = trial, k, ssr
    return best, chosen, steps


def _series_names(lead: str, omega: str, coeff: str, order: int) -> list[str]:
    return ([lead] + ([omega] if order >= 1 else []) + [f"{coeff}{k}" for k in range(1, order)])


def direct_shear(envelopes, *, preset="ottawa_c109", order: int = 3, cohesion_order: int | None = None,
                 fit_cohesion: bool = True) -> Identification:
    """Identify the friction and cohesion distributions from direct-shear Coulomb envelopes.

    The slopes at the angles alpha are fitted with eta_f(alpha) = eta0 (1 + x + a1 x^2 + ... +
    a_{N-1} x^N), x = omega1 (1 - 3 cos^2 alpha) (eqs. 2.19, 2.20; N = ``order``, N + 1 unknowns
    eta0, omega1, a1 .. a_{N-1}); the intercepts with c(alpha) = c0 (1 + x_c + b1 x_c^2 + ...),
    x_c = omega1_c (1 - 3 cos^2 alpha) (eq. 2.4). Each fit keeps at least one degree of freedom for its
    error estimate. Bounds: eta0 > 0, |omega1| < 0.5, c0 >= 0, |omega1_c| < 0.5 (CPAParameters).

    Parameters
    ----------
    envelopes : path, mapping or ``"fig8"``
        Columns ``alpha_deg``, ``slope``, ``intercept_kPa`` (:func:`read_envelopes`).
    preset : str, path or CPAParameters
        The base parameter set: the constants not identified here (E, nu, t, A, eta_c_ratio, ...) are
        taken from it. Default ``ottawa_c109`` (Table 3).
    order : int
        Highest power N of x in the friction series (the thesis's "order": Table 3 is order 4 with
        a1..a3). Default 3 (eta0, omega1, a1, a2): with the six angles of Fig. 8 that leaves 2 degrees
        of freedom; order 4 leaves 1 and its coefficients are poorly conditioned
        (``docs/identification.md``). Needs at least N + 2 angles.
    cohesion_order : int, optional
        Highest power of x_c in the cohesion series: 0 fits a constant c0 (omega1_c = 0), 1 adds
        omega1_c, 2 adds b1, ... Default (None): chosen from the data, the lowest order beyond which
        a further term does not reduce the residual significantly (F test, 5 %) or ends at a bound,
        at most ``min(order, n_angles - 2)`` (one degree of freedom left). The Fig. 8 intercepts
        (0.02 to 1 kPa, no trend with alpha) give order 0: an isotropic c0.
    fit_cohesion : bool
        False leaves c0, omega1_c and b as in ``preset`` (the thesis takes c = 0 for Ottawa sand: its
        intercepts are within the scatter of the tests).

    Returns
    -------
    Identification
        ``names`` eta0, omega1, a1.., then c0, omega1_c, b1..; ``residuals`` and ``rms``/``r2`` for
        ``slope`` and ``intercept_kPa``; ``fit`` holds eta_f and c (with their standard errors) over
        alpha = 0..90 deg and, for comparison, the base set's eta_f (Table 3 for ``ottawa_c109``).

    Raises
    ------
    ValueError
        Bad envelopes (:func:`read_envelopes`), an order below 1 or one the number of angles cannot
        determine.
    """
    t0 = time.perf_counter()
    env = read_envelopes(envelopes)
    base = _base_parameters(preset)
    alpha, slope, intercept = env["alpha_deg"], env["slope"], env["intercept_kPa"]
    n = len(alpha)
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise ValueError(f"order = {order!r}: allowed an integer >= 1 (highest power of x in eta_f)")
    if n < order + 2:
        unknowns = "eta0, omega1" + (f", a1..a{order - 1}" if order > 1 else "")
        raise ValueError(
            f"order = {order}: the friction series has {order + 1} unknowns ({unknowns}) and needs at least "
            f"{order + 2} deposition angles (one more than unknowns, for the error estimate); got {n} "
            f"(alpha_deg = {alpha.tolist()}); allowed: order <= {max(n - 2, 0)}"
            + ("" if n >= 3 else " (at least 3 angles for order 1)"))
    selection: list = []
    if cohesion_order is None:
        c_order = min(order, n - 2)
    else:
        if isinstance(cohesion_order, bool) or not isinstance(cohesion_order, (int, np.integer)) or cohesion_order < 0:
            raise ValueError(f"cohesion_order = {cohesion_order!r}: allowed an integer >= 0")
        if n < cohesion_order + 2:
            raise ValueError(f"cohesion_order = {cohesion_order}: needs at least {cohesion_order + 2} "
                             "deposition angles; "
                             f"got {n}; allowed: cohesion_order <= {n - 2}")
        c_order = int(cohesion_order)
    if (intercept < 0).any():
        warnings.warn(f"intercepts {intercept.tolist()} include negative values; the cohesion is bounded by c0 >= 0",
                      RuntimeWarning, stacklevel=2)
    u = _u(alpha)
    notes: list[str] = []

    fr = _fit_series(u, slope, order, 1e-9)
    names = _series_names("eta0", "omega1", "a", order)
    values, se, ci = list(fr.theta), list(fr.stderr), list(fr.ci95)
    at_bounds = [names[i] for i in fr.at_bounds]
    dof = {"friction": fr.dof}
    changes: dict[str, Any] = {"eta0": fr.theta[0], "omega1": fr.theta[1], "a": tuple(fr.theta[2:])}
    slope_fit = fr.fitted
    cfit = None
    if fit_cohesion and not np.any(intercept > 0):
        notes.append("all intercepts are 0: c0 = 0 (isotropic), nothing else to fit")
        changes.update(c0=0.0, omega1_c=0.0, b=())
        c_order = 0
        intercept_fit = np.zeros(n)
    elif fit_cohesion:
        if cohesion_order is None:
            cfit, c_order, selection = _select_cohesion(u, intercept, min(order, n - 2))
        else:
            cfit, selection = _fit_series(u, intercept, c_order, 0.0), []
        cnames = _series_names("c0", "omega1_c", "b", c_order)
        names += cnames
        values += list(cfit.theta)
        se += list(cfit.stderr)
        ci += list(cfit.ci95)
        at_bounds += [cnames[i] for i in cfit.at_bounds]
        dof["cohesion"] = cfit.dof
        changes.update(c0=cfit.theta[0], omega1_c=cfit.theta[1] if c_order >= 1 else 0.0, b=tuple(cfit.theta[2:]))
        intercept_fit = cfit.fitted
        if cfit.at_bounds:
            notes.append(f"cohesion parameter(s) {[cnames[i] for i in cfit.at_bounds]} at a bound: the intercepts "
                         "are not described by the series within the bounds; their intervals are not meaningful")
    else:
        intercept_fit = base.c0 * _series_value(np.r_[1.0, base.omega1_c, base.b], u)
    params = base.replace(**changes, name=f"{base.name}+direct_shear")

    resid = {"slope": slope_fit - slope}
    rms, r2 = {}, {}
    rms["slope"], r2["slope"] = _quality(slope_fit, slope)
    if fit_cohesion:
        resid["intercept_kPa"] = intercept_fit - intercept
        rms["intercept_kPa"], r2["intercept_kPa"] = _quality(intercept_fit, intercept)

    # tables: the data against the fit, and the dense curves
    base_eta = _series_value(np.r_[base.eta0, base.omega1, base.a], u)
    data = Table({"alpha_deg": alpha, "slope": slope, "eta_f_fit": slope_fit, "slope_residual": resid["slope"],
                  "eta_f_base": base_eta, "intercept_kPa": intercept, "cohesion_fit_kPa": intercept_fit,
                  "intercept_residual_kPa": intercept_fit - intercept},
                 {"alpha_deg": "angle between the shear-plane normal and the deposition axis e2 [deg]",
                  "slope": "measured slope of the Coulomb envelope tau = slope sigma_n + intercept [-]",
                  "eta_f_fit": "fitted eta_f(alpha) (eq. 2.20) [-]",
                  "slope_residual": "eta_f_fit - slope [-]",
                  "eta_f_base": f"eta_f(alpha) of the base parameter set {base.name!r} [-]",
                  "intercept_kPa": "measured intercept of the Coulomb envelope [kPa]",
                  "cohesion_fit_kPa": "fitted c(alpha) (eq. 2.4) [kPa]"
                  + ("" if fit_cohesion else " (base set, not fitted)"),
                  "intercept_residual_kPa": "cohesion_fit_kPa - intercept_kPa [kPa]"},
                 {"source": env["source"]}, title="direct-shear envelopes against the identified eta_f and c")
    grid = np.linspace(0.0, 90.0, 181)
    ug = _u(grid)
    curve_cols = {"alpha_deg": grid, "eta_f": _series_value(fr.theta, ug), "eta_f_stderr": _series_band(fr, ug),
                  "eta_f_base": _series_value(np.r_[base.eta0, base.omega1, base.a], ug)}
    if cfit is not None:
        curve_cols["cohesion_kPa"] = _series_value(cfit.theta, ug)
        curve_cols["cohesion_stderr_kPa"] = _series_band(cfit, ug)
    else:
        curve_cols["cohesion_kPa"] = params.c0 * _series_value(np.r_[1.0, params.omega1_c, params.b], ug)
    fit_table = Table(curve_cols, {
        "alpha_deg": "deposition angle [deg]", "eta_f": "identified eta_f(alpha) [-]",
        "eta_f_stderr": "standard error of the fitted eta_f (delta method) [-]",
        "eta_f_base": f"eta_f(alpha) of the base set {base.name!r} [-]",
        "cohesion_kPa": "identified c(alpha) [kPa]", "cohesion_stderr_kPa": "standard error of c(alpha) [kPa]"},
        title="identified friction and cohesion distributions over alpha")
    if (curve_cols["eta_f"] <= 0).any():
        notes.append("the fitted eta_f(alpha) is not positive everywhere on [0, 90] deg: lower the order")
    if (curve_cols["cohesion_kPa"] < 0).any():
        notes.append("the fitted c(alpha) is negative somewhere on [0, 90] deg: lower cohesion_order")
    for msg in notes:
        warnings.warn(msg, RuntimeWarning, stacklevel=2)
    cov_f = _correlation(fr.cov)
    info = {"source": env["source"], "base": base.name, "order": int(order),
            "cohesion_order": int(c_order) if fit_cohesion else None, "cohesion_order_selection": selection,
            "at_bounds": at_bounds,
            "max_relative_difference_to_base_eta_f": float(np.max(np.abs(slope_fit - base_eta) / base_eta)),
            "correlation_friction": cov_f, "optimiser": fr.status, "wall_time_s": time.perf_counter() - t0,
            "warnings": notes}
    if info["cohesion_order"] is None:
        info.pop("cohesion_order")
    return Identification("direct_shear", tuple(names), np.array(values), np.array(se), np.array(ci).reshape(-1, 2),
                          resid, rms, r2, dof, params, data, fit_table, info)


# ====================================================================================== element curves
#: Constants :func:`triaxial` can identify, with the variable it optimises: ``log`` (positive
#: constants: log of the value), ``zeta`` (log(zeta - 1)), or ``linear`` (value / scale) with bounds.
FREE_PARAMETERS: dict[str, tuple[str, float, float, float]] = {
    # name: (transform, scale, lower bound, upper bound)
    "E": ("log", 1.0, 0.0, math.inf),
    "A": ("log", 1.0, 0.0, math.inf),
    "t": ("log", 1.0, 0.0, math.inf),
    "eta0": ("log", 1.0, 0.0, math.inf),
    "zeta": ("zeta", 1.0, 1.0, 2.0),
    "nu": ("linear", 0.1, -0.99, 0.495),
    "eta_c_ratio": ("linear", 0.1, 0.0, 1.0),
    "omega1": ("linear", 0.05, -_OMEGA_BOUND, _OMEGA_BOUND),
    "beta": ("linear", 0.1, 0.0, math.inf),
    "c0": ("linear", 1.0, 0.0, math.inf),
}
_LOG_RANGE = math.log(1e3)  # log variables stay within a factor 1000 of the start
_ZETA_START = 1.02  # the thesis's 1 < zeta <= 1.05


@dataclass(frozen=True)
class Curve:
    """One measured curve and how to simulate it.

    Attributes
    ----------
    kind : str
        ``"triaxial"`` (drained compression at constant cell pressure, measured ``q_kPa`` and/or
        ``eps_v`` against ``eps_a``, compression +), ``"direct_shear"`` (constant normal stress,
        measured ``tau_kPa`` and/or ``normal_displacement_m`` (dilation +) against
        ``shear_displacement_m``) or ``"path"`` (a mixed stress/strain path: the prescribed tensor
        components drive the simulation, the measured ones are compared).
    label : str
        Name used in tables and plots (the file stem by default).
    x_name : str
        The control variable: ``eps_a``, ``shear_displacement_m`` or ``row`` (path).
    x : (n,) ndarray
        Its values at the data rows.
    measured : dict of str to (n,) ndarray
        The measured quantities compared with the simulation.
    conditions : dict
        ``p0_kPa`` and ``alpha_deg`` (triaxial), ``sigma_n_kPa`` and ``alpha_deg`` (direct shear),
        ``alpha_deg`` (path).
    control : dict
        For a path: ``initial_stress`` (3, 3) [kPa], ``A``, ``B`` (6, 6) condition rows and
        ``targets`` (n, 6) (Mandel, tension +, strains relative to the first row), see
        :class:`material.driver.Segment`.
    source : str
        The file the curve was read from ("" for tables and mappings).
    """

    kind: str
    label: str
    x_name: str
    x: np.ndarray
    measured: dict
    conditions: dict
    control: dict = field(default_factory=dict)
    source: str = ""

    @property
    def primary(self) -> str | None:
        """The measured stress quantity whose peak decides softening (None for a path)."""
        name = {"triaxial": "q_kPa", "direct_shear": "tau_kPa"}.get(self.kind)
        return name if name in self.measured else None


_TRIAXIAL = ("eps_a", ("q_kPa", "eps_v"), ("p0_kPa", "alpha_deg"))
_DIRECT = ("shear_displacement_m", ("tau_kPa", "normal_displacement_m"), ("sigma_n_kPa", "alpha_deg"))


def _meta_value(meta: dict, key: str):
    """A condition from a table's metadata: ``# metadata: {json}`` or a ``# key: value`` line."""
    if key in meta:
        return meta[key]
    head = meta.get("header", {})
    return head.get(key)


def read_curve(source, *, p0_kPa: float | None = None, alpha_deg: float | None = None,
               sigma_n_kPa: float | None = None, label: str | None = None, control: str | None = None) -> Curve:
    """Read one measured curve (``docs/identification.md``, "Curve files").

    Parameters
    ----------
    source : path, Table or mapping of columns
        Formats, recognised by the columns:

        * triaxial: ``eps_a`` with ``q_kPa`` and/or ``eps_v`` (compression +; q = axial minus
          lateral stress), drained, constant cell pressure; conditions ``p0_kPa`` and ``alpha_deg``.
        * direct shear: ``shear_displacement_m`` with ``tau_kPa`` and/or ``normal_displacement_m``
          (dilation +); conditions ``sigma_n_kPa`` and ``alpha_deg``.
        * path: ``sig_<c>_kPa`` / ``eps_<c>`` columns (tension +, tensor shear, as ``femgran element
          path`` reads); a component with one column is prescribed by it, a component with both is
          prescribed by the one ``control`` names and compared on the other; condition ``alpha_deg``.

        A file's conditions may be in its header, as ``# p0_kPa: 100`` lines or in a femgran table's
        ``# metadata: {...}`` line (the CSVs ``femgran element`` writes read directly); keyword
        arguments override them. Lines starting with ``#`` are comments.
    p0_kPa, alpha_deg, sigma_n_kPa : float, optional
        Conditions of the test (see above).
    label : str, optional
        Default: the file stem.
    control : str, optional
        Path format only: comma-separated prescribed columns for components given both ways, e.g.
        ``"eps_zz,sig_xx_kPa,sig_yy_kPa"``; default: ``eps_zz`` and every other component's stress
        (a drained triaxial compression along z).

    Raises
    ------
    ValueError
        No recognised columns, a missing condition, NaN in a used column, a control variable that
        does not increase.
    """
    if isinstance(source, Table):
        table, name = source, label
    elif isinstance(source, Mapping):
        cols = {k: v for k, v in source.items() if not np.isscalar(v) and not isinstance(v, (str, dict))}
        meta = {k: v for k, v in source.items() if k not in cols}
        table, name = Table(cols, metadata=meta), label
    elif isinstance(source, (str, Path)):
        path = Path(source)
        if not path.is_file():
            raise FileNotFoundError(f"curve file {str(path)!r} does not exist")
        table, name = read_table(path), label or path.stem
    else:
        raise ValueError(f"curve {source!r}: allowed a CSV path, a material.table.Table or a mapping of columns")
    meta = dict(table.metadata)
    given = {"p0_kPa": p0_kPa, "alpha_deg": alpha_deg, "sigma_n_kPa": sigma_n_kPa}
    curve = _read_curve(table, name or "curve", given, meta, control)
    if name is None:  # a table or mapping without a label: name it by its conditions
        tag = "_".join(f"{k.split('_')[0]}{v:g}" for k, v in curve.conditions.items())
        curve = dataclasses.replace(curve, label=f"{curve.kind}_{tag}")
    if isinstance(source, (str, Path)):
        curve = dataclasses.replace(curve, source=str(source))
    return curve


def _read_curve(table: Table, name: str, given: dict, meta: dict, control: str | None) -> Curve:
    """The format dispatch of :func:`read_curve`."""
    test = meta.get("test")
    cols = table.columns
    if "eps_a" in cols and ("q_kPa" in cols or "eps_v" in cols) and test in (None, "triaxial"):
        if meta.get("extension") or meta.get("drained") is False:
            raise ValueError(f"curve {name!r}: only drained triaxial compression is supported "
                             f"(metadata: drained = {meta.get('drained')}, extension = {meta.get('extension')})")
        return _simple_curve(table, name, "triaxial", _TRIAXIAL, given, meta)
    if "shear_displacement_m" in cols and ("tau_kPa" in cols or "normal_displacement_m" in cols):
        return _simple_curve(table, name, "direct_shear", _DIRECT, given, meta)
    if any(c.startswith(("sig_", "eps_")) for c in cols):
        return _path_curve(table, name, given, meta, control)
    raise ValueError(
        f"curve {name!r}: columns {cols} match no format; allowed: eps_a with q_kPa/eps_v (triaxial), "
        "shear_displacement_m with tau_kPa/normal_displacement_m (direct shear), or sig_<c>_kPa/eps_<c> (path)")


def _condition(name: str, key: str, given: dict, meta: dict) -> float:
    v = given.get(key)
    if v is None:
        v = _meta_value(meta, key)
    if v is None:
        flag = {"p0_kPa": "--p0", "alpha_deg": "--alpha", "sigma_n_kPa": "--sigma-n"}[key]
        raise ValueError(f"curve {name!r}: {key} is not given; pass it as an argument ({key}=..., or {flag} on the "
                         f"command line) or add a line '# {key}: VALUE' to the file")
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"curve {name!r}: {key} = {v!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"curve {name!r}: {key} = {v!r}: must be finite")
    return v


def _simple_curve(table: Table, name: str, kind: str, spec, given: dict, meta: dict) -> Curve:
    x_name, quantities, conds = spec
    conditions = {k: _condition(name, k, given, meta) for k in conds}
    for k in conds:
        if k != "alpha_deg" and conditions[k] <= 0:
            raise ValueError(f"curve {name!r}: {k} = {conditions[k]!r}; allowed: > 0")
    x = table[x_name]
    measured = {q: table[q] for q in quantities if q in table}
    for q, v in [(x_name, x), *measured.items()]:
        bad = ~np.isfinite(v)
        if bad.any():
            rows = (np.flatnonzero(bad) + 1).tolist()
            raise ValueError(f"curve {name!r}: column {q!r} has NaN/inf in data row(s) {rows}")
    keep = x > 0  # the start (x = 0) is the simulation's initial state, not a data point to fit
    if keep.sum() < 2:
        raise ValueError(f"curve {name!r}: fewer than 2 data rows with {x_name} > 0")
    x = x[keep]
    if np.any(np.diff(x) <= 0):
        i = int(np.flatnonzero(np.diff(x) <= 0)[0])
        raise ValueError(f"curve {name!r}: {x_name} must increase from row to row (monotonic loading); it does not "
                         f"after {x_name} = {x[i]!r}")
    return Curve(kind, name, x_name, x, {q: v[keep] for q, v in measured.items()}, conditions)


def _path_curve(table: Table, name: str, given: dict, meta: dict, control: str | None) -> Curve:
    from material.results import COMPONENTS
    from material.tensors import MANDEL_WEIGHTS

    cols = table.columns
    stress = {c: f"sig_{c}_kPa" for c in COMPONENTS}
    strain = {c: f"eps_{c}" for c in COMPONENTS}
    chosen = set()
    if control:
        chosen = {s.strip() for s in control.split(",") if s.strip()}
        allowed = set(stress.values()) | set(strain.values())
        unknown = sorted(chosen - allowed)
        if unknown:
            raise ValueError(f"curve {name!r}: control {sorted(unknown)} unknown; allowed: {sorted(allowed)}")
    default = {c: (strain[c] if c == "zz" else stress[c]) for c in COMPONENTS}
    prescribed, compared = {}, []
    for c in COMPONENTS:
        has = [col for col in (stress[c], strain[c]) if col in cols]
        if not has:
            raise ValueError(f"curve {name!r}: component {c!r} has neither {stress[c]} nor {strain[c]}; "
                             "give at least one")
        if len(has) == 1:
            prescribed[c] = has[0]
            continue
        pick = [col for col in has if col in chosen]
        if len(pick) == 2:
            raise ValueError(f"curve {name!r}: control names both {has}; prescribe one of them")
        prescribed[c] = pick[0] if pick else default[c]
        compared.append(next(col for col in has if col != prescribed[c]))
    if not compared:
        raise ValueError(f"curve {name!r}: every component has only its prescribed column, nothing to compare; add the "
                         "measured ones (e.g. sig_zz_kPa of a strain-controlled axial component, eps_xx of a "
                         "stress-controlled lateral one)")
    data = {col: table[col] for col in set(prescribed.values()) | set(compared)}
    for col, v in data.items():
        bad = ~np.isfinite(v)
        if bad.any():
            rows = (np.flatnonzero(bad) + 1).tolist()
            raise ValueError(f"curve {name!r}: column {col!r} has NaN/inf in data row(s) {rows}")
    n = len(table)
    if n < 3:
        raise ValueError(f"curve {name!r}: need the start row and at least 2 more rows, got {n}")
    s0 = np.zeros((3, 3))
    ij = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
    normal_given = [data[stress[c]][0] for c in COMPONENTS[:3] if stress[c] in cols]
    mean = float(np.mean(normal_given)) if normal_given else 0.0
    for k, (c, (i, j)) in enumerate(zip(COMPONENTS, ij)):
        v = table[stress[c]][0] if stress[c] in cols else (mean if k < 3 else 0.0)
        s0[i, j] = s0[j, i] = v
    a, b = np.zeros((6, 6)), np.zeros((6, 6))
    targets = np.zeros((n - 1, 6))
    for k, c in enumerate(COMPONENTS):
        col = prescribed[c]
        v = data[col]
        if col.startswith("sig_"):
            b[k, k] = 1.0
            targets[:, k] = v[1:] * MANDEL_WEIGHTS[k]
        else:
            a[k, k] = 1.0
            targets[:, k] = (v[1:] - v[0]) * MANDEL_WEIGHTS[k]
    measured = {col: (data[col][1:] - data[col][0]) if col.startswith("eps_") else data[col][1:] for col in compared}
    strains = [prescribed[c] for c in COMPONENTS if prescribed[c].startswith("eps_")]
    if len(strains) == 1:
        x_name, x = strains[0], data[strains[0]][1:] - data[strains[0]][0]
    else:
        x_name, x = "row", np.arange(1.0, n)
    conditions = {"alpha_deg": _condition(name, "alpha_deg", given, meta)}
    return Curve("path", name, x_name, x, measured, conditions,
                 {"initial_stress": s0, "A": a, "B": b, "targets": targets, "prescribed": dict(prescribed)})


def softening_detected(curve: Curve, drop: float = 0.05) -> int | None:
    """Row of the peak of a curve that softens, else None.

    Criterion: the measured stress (``q_kPa`` of a triaxial, ``tau_kPa`` of a direct-shear curve)
    reaches its maximum before the last row and falls by more than ``drop`` (a fraction of the peak)
    at some later row. Paths are never classed as softening.
    """
    q = curve.primary
    if q is None:
        return None
    y = curve.measured[q]
    i = int(np.argmax(y))
    if i >= len(y) - 1 or y[i] <= 0:
        return None
    return i if (y[i] - y[i + 1:].min()) > drop * y[i] else None


def _grid(x: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Simulation points: the data x merged with a uniform grid of ``steps`` intervals on [0, max x]
    (uniform points closer than a quarter interval to a data point dropped). Returns (grid without
    0, index of each data point in it)."""
    h = x.max() / steps
    uni = np.linspace(0.0, x.max(), steps + 1)[1:]
    near = np.min(np.abs(uni[:, None] - x[None, :]), axis=1) < 0.25 * h
    g = np.union1d(x, uni[~near])
    return g, np.searchsorted(g, x)


def simulate(curve: Curve, params: CPAParameters, *, steps: int = 40, rule: str | None = None) -> tuple[dict, bool]:
    """Simulate ``curve`` with ``params``: the values of its measured quantities at its data rows.

    The element driver (:func:`material.driver.run_path`) follows the test from its initial state
    (isotropic p0 or sigma_n; the path's first row) through every data row, with at most
    ``max(x) / steps`` between simulation points (``steps`` sets the resolution; data points are
    always simulation points). A run that stops early (a step the law cannot integrate) holds its
    last values for the remaining rows.

    Returns
    -------
    (dict of str to (n,) ndarray, bool)
        The simulated quantities (same names as ``curve.measured``) and whether the run completed.
    """
    from material import driver
    from material.anisotropy import axes_from_alpha
    from material.cpa import CPAModel
    from material.results import COMPONENTS

    # one point: a single numba thread (a parallel launch per update costs more than the update)
    model = CPAModel(params, axes=axes_from_alpha(curve.conditions["alpha_deg"]), threads=1,
                     **({} if rule is None else {"rule": rule}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        if curve.kind == "triaxial":
            p0 = curve.conditions["p0_kPa"]
            g, idx = _grid(curve.x, steps)
            path = driver.LoadPath(initial_stress=-p0 * np.eye(3))
            for e in g:
                path.add(1, eps_zz=-e, sig_xx=-p0, sig_yy=-p0, sig_yz=0.0, sig_xz=0.0, sig_xy=0.0,
                         relative_strain=False)
            res = driver.run_path(model, path, max_cuts=4)
            s, e = res.stress, res.strain
            values = {"q_kPa": 0.5 * (s[:, 0, 0] + s[:, 1, 1]) - s[:, 2, 2], "eps_v": -np.trace(e, axis1=1, axis2=2)}
        elif curve.kind == "direct_shear":
            sn, t = curve.conditions["sigma_n_kPa"], params.t
            g, idx = _grid(curve.x, steps)
            path = driver.LoadPath(initial_stress=-sn * np.eye(3))
            for d in g:
                path.add(1, eps_xz=d / (2.0 * t), sig_zz=-sn, eps_xx=0.0, eps_yy=0.0, eps_xy=0.0, sig_yz=0.0,
                         relative_strain=False)
            res = driver.run_path(model, path, max_cuts=4)
            values = {"tau_kPa": res.stress[:, 0, 2], "normal_displacement_m": res.strain[:, 2, 2] * t}
        else:
            ctl = curve.control
            n = len(curve.x)
            sub = max(1, int(math.ceil(steps / n)))
            path = driver.LoadPath(initial_stress=ctl["initial_stress"])
            for target in ctl["targets"]:
                path.add_conditions(sub, ctl["A"], ctl["B"], target, np.zeros(6, dtype=bool))
            res = driver.run_path(model, path, max_cuts=4)
            idx = np.arange(1, n + 1) * sub - 1
            values = {}
            for q in curve.measured:
                k = COMPONENTS.index(q.split("_")[1])
                i, j = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))[k]
                values[q] = (res.stress if q.startswith("sig_") else res.strain)[:, i, j]
    rows = idx + 1  # row 0 of the result is the initial state
    last = len(res) - 1
    out = {q: values[q][np.minimum(rows, last)] for q in curve.measured}
    return out, bool(res.completed)


@dataclass
class _Space:
    """The optimisation variables z of the free constants: z = log(theta / theta0), z = log((zeta - 1) /
    (zeta0 - 1)) or z = (theta - theta0) / scale."""

    names: tuple[str, ...]
    start: dict

    def to_params(self, z: np.ndarray) -> dict[str, float]:
        """The constants of the scaled variables z."""
        return {name: self._value(name, float(zi)) for name, zi in zip(self.names, z)}

    def _value(self, name: str, zi: float) -> float:
        kind, scale, _, _ = FREE_PARAMETERS[name]
        s = self.start[name]
        if kind == "log":
            return s * math.exp(zi)
        if kind == "zeta":
            return 1.0 + (s - 1.0) * math.exp(zi)
        return s + scale * zi

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = [], []
        for name in self.names:
            kind, scale, low, high = FREE_PARAMETERS[name]
            s = self.start[name]
            if kind == "log":
                lo.append(-_LOG_RANGE)
                hi.append(_LOG_RANGE)
            elif kind == "zeta":
                lo.append(-_LOG_RANGE)
                hi.append(math.log((high - 1.0) / (s - 1.0)))
            else:
                lo.append((low - s) / scale)
                hi.append((high - s) / scale)
        return np.array(lo), np.array(hi)

    def interval(self, z: np.ndarray, se_z: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Values, standard errors and 95 % intervals in parameter units (delta method for the
        errors; the interval mapped through the transform, so positive constants stay positive)."""
        values = np.array([self._value(n, float(zi)) for n, zi in zip(self.names, z)])
        se, ci = np.empty(len(z)), np.empty((len(z), 2))
        for k, name in enumerate(self.names):
            kind, scale, low, high = FREE_PARAMETERS[name]
            ends = np.clip([z[k] - t * se_z[k], z[k] + t * se_z[k]], -700.0, 700.0)
            with np.errstate(invalid="ignore"):  # inf * 0 of an undetermined constant
                ci[k] = np.clip([self._value(name, e) for e in ends], low, high)
            # delta method: d theta / d z = theta (log), zeta - 1 (zeta), scale (linear)
            slope = {"log": values[k], "zeta": values[k] - 1.0}.get(kind, scale)
            se[k] = slope * se_z[k]
        return values, se, ci


def _scale_group(quantity: str) -> str:
    """Quantities that share a residual scale: the tensor components of path curves share one for the
    stresses (``sig``) and one for the strains (``eps``); any other quantity has its own."""
    if quantity.startswith("sig_"):
        return "sig"
    if quantity.startswith("eps_") and quantity != "eps_v":
        return "eps"
    return quantity


def _check_free(free: Sequence[str]) -> tuple[str, ...]:
    if isinstance(free, str):
        free = [s.strip() for s in free.split(",") if s.strip()]
    names = tuple(free)
    unknown = [n for n in names if n not in FREE_PARAMETERS]
    if unknown:
        raise ValueError(f"free = {list(names)}: unknown or not identifiable from curves {unknown}; allowed: "
                         f"{sorted(FREE_PARAMETERS)}")
    if len(set(names)) != len(names):
        raise ValueError(f"free = {list(names)}: a name is repeated")
    if not names:
        raise ValueError("free: no parameter to identify; allowed names: " + ", ".join(sorted(FREE_PARAMETERS)))
    return names


def _as_curves(curves, p0_kPa, alpha_deg, sigma_n_kPa, control) -> list[Curve]:
    if isinstance(curves, (str, Path, Table, Curve)) or isinstance(curves, Mapping):
        curves = [curves]
    curves = list(curves)
    if not curves:
        raise ValueError("curves: none given; pass at least one curve (file, Table, mapping or Curve)")

    def per_curve(value, key):
        if value is None or np.isscalar(value):
            return [value] * len(curves)
        value = list(value)
        if len(value) == 1:
            return value * len(curves)
        if len(value) != len(curves):
            raise ValueError(f"{key} = {value}: give one value for all curves or one per curve ({len(curves)})")
        return value

    p0s, alphas, sns = (per_curve(p0_kPa, "p0_kPa"), per_curve(alpha_deg, "alpha_deg"),
                        per_curve(sigma_n_kPa, "sigma_n_kPa"))
    out = []
    for i, c in enumerate(curves):
        if isinstance(c, Curve):
            out.append(c)
        else:
            out.append(read_curve(c, p0_kPa=p0s[i], alpha_deg=alphas[i], sigma_n_kPa=sns[i], control=control))
    labels = [c.label for c in out]
    if len(set(labels)) != len(labels):  # make labels unique for the tables
        out = [dataclasses.replace(c, label=f"{i}:{c.label}") for i, c in enumerate(out)]
    return out


def triaxial(curves, *, preset="ottawa_c109", free: Sequence[str] | str = ("A", "E", "nu", "eta_c_ratio"),
             start: Mapping[str, float] | None = None, p0_kPa=None, alpha_deg=None, sigma_n_kPa=None,
             control: str | None = None, steps: int = 40, softening_drop: float = 0.05, auto_zeta: bool = True,
             scales: Mapping[str, float] | None = None, diff_step: float = 1e-3, max_nfev: int = 60,
             rule: str | None = None, progress: bool = False) -> Identification:
    """Identify constants of the law from measured element-test curves with the element driver.

    Least squares over simulations (:func:`simulate`) of every curve with the trial constants,
    all curves jointly (e.g. several confining pressures or deposition angles). The residual of a
    measured quantity (q_kPa, eps_v, tau_kPa, a tensor component, ...) at a data row is
    (simulated - measured) / scale, with one scale per quantity: its largest magnitude over all
    curves (``scales`` overrides), so stresses and strains weigh alike. The optimiser
    (:func:`scipy.optimize.least_squares`, trust region reflective) works in scaled variables: the
    log of positive constants (E, A, t, ...), log(zeta - 1), and (value - start) / scale for the
    bounded ones (nu, eta_c_ratio, ...), see :data:`FREE_PARAMETERS`; its Jacobian is a forward
    difference with the step ``diff_step`` in these variables (a 0.1 % change of a positive constant
    by default).

    Softening (criterion of :func:`softening_detected`): the rows after the peak of a softening curve
    are not fitted (the element driver follows the hardening branch only; the thesis identifies the
    hardening regime and puts the onset of instability, eta = eta_f, at the peak), and ``zeta``
    joins the free constants (``auto_zeta``), started at 1.02 if the base set has zeta = 1.

    Identifiability: in a triaxial test A and t enter only as A / t (the plastic strain is the slip,
    proportional to A, over the band thickness t), in a direct-shear test E and t only as t / E; a
    free set the curves cannot separate is refused before the fit, naming the combination
    (fix t, the band thickness, at a multiple of the grain size as the thesis does).

    Parameters
    ----------
    curves : path, Table, mapping, Curve or a sequence of them
        :func:`read_curve` formats.
    preset : str, path or CPAParameters
        The base set: start values of the free constants and the values of all others.
    free : sequence of str or comma-separated str
        Constants to identify (names of :class:`CPAParameters` fields, :data:`FREE_PARAMETERS`).
    start : mapping, optional
        Start values overriding the base set's for some free constants.
    p0_kPa, alpha_deg, sigma_n_kPa : float or sequence, optional
        Test conditions for all curves or one per curve (else from the files' headers).
    control : str, optional
        Prescribed columns of path-format curves (:func:`read_curve`).
    steps : int
        Simulation resolution: at most max(x) / steps between simulation points (default 40).
    softening_drop : float
        Fractional drop after the peak that counts as softening (default 0.05).
    auto_zeta : bool
        Add ``zeta`` to the free constants when a curve softens.
    scales : mapping, optional
        Residual scale per quantity (data units), e.g. ``{"q_kPa": 5.0, "eps_v": 1e-3}``.
    diff_step : float
        Finite-difference step in the scaled variables.
    max_nfev : int
        Iterations of the optimiser (each costs one simulation of every curve, plus one per free
        constant for the Jacobian).
    rule : str, optional
        Integration rule of the planes (default the law's).
    progress : bool
        Show the simulations as a tqdm bar.

    Returns
    -------
    Identification
        ``residuals``, ``rms`` and ``r2`` per measured quantity; ``data`` the measured and fitted
        values row by row (``used`` = 0 for rows after a softening peak); ``fit`` the simulated
        curves on a finer grid.

    Raises
    ------
    ValueError
        Bad curves (:func:`read_curve`), unknown free names, fewer data points than free constants,
        or a free set the curves cannot identify.
    """
    t0 = time.perf_counter()
    base = _base_parameters(preset)
    names = list(_check_free(free))
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 2:
        raise ValueError(f"steps = {steps!r}: allowed an integer >= 2")
    if not (0.0 < softening_drop < 1.0):
        raise ValueError(f"softening_drop = {softening_drop!r}: allowed 0 < softening_drop < 1")
    if not (0.0 < diff_step < 0.5):
        raise ValueError(f"diff_step = {diff_step!r}: allowed 0 < diff_step < 0.5")
    curve_list = _as_curves(curves, p0_kPa, alpha_deg, sigma_n_kPa, control)
    notes: list[str] = []

    # rows used: everything up to the peak of a softening curve
    used, softening = [], {}
    for c in curve_list:
        peak = softening_detected(c, softening_drop)
        mask = np.ones(len(c.x), dtype=bool)
        if peak is not None:
            mask[peak + 1:] = False
            softening[c.label] = {"peak_row": peak + 1, c.x_name: float(c.x[peak])}
        used.append(mask)
    if softening and auto_zeta and "zeta" not in names:
        names.append("zeta")
        notes.append(f"softening seen in {sorted(softening)} (drop > {softening_drop:.0%} after the peak): post-peak "
                     "rows not fitted, zeta added to the free constants")
    names = tuple(names)

    start_values = {n: float(getattr(base, n)) for n in names}
    for k, v in (start or {}).items():
        if k not in names:
            raise ValueError(f"start: {k!r} is not a free constant; free: {list(names)}")
        start_values[k] = float(v)
    if "zeta" in names and start_values["zeta"] <= 1.0:
        start_values["zeta"] = _ZETA_START
    for k, v in start_values.items():
        kind, _, low, high = FREE_PARAMETERS[k]
        if kind in ("log",) and not v > 0:
            raise ValueError(f"start: {k} = {v!r}; allowed: > 0 (it is optimised as its logarithm)")
        if not (low <= v <= high):
            raise ValueError(f"start: {k} = {v!r}; allowed: {low} <= {k} <= {high}")
    space = _Space(names, start_values)
    try:
        base.replace(**space.to_params(np.zeros(len(names))))
    except ValueError as exc:
        raise ValueError(f"start values: {exc}") from None

    quantities = sorted({q for c in curve_list for q in c.measured})
    scale = _residual_scales(curve_list, used, quantities, scales)
    n_data = sum(int(m.sum()) * len(c.measured) for c, m in zip(curve_list, used))
    if n_data <= len(names):
        raise ValueError(f"{n_data} data values for {len(names)} free constants {list(names)}: at least "
                         f"{len(names) + 1} are needed")

    from scipy.optimize import least_squares

    problem = _CurveProblem(curve_list, used, scale, base, space, steps, rule, diff_step)
    z0 = np.zeros(len(names))
    try:
        if progress:
            from tqdm import tqdm

            problem.bar = tqdm(desc="identify: simulations", unit="run", leave=False)
        problem.check_identifiable(z0)
        res = least_squares(problem, z0, jac=problem.jacobian, bounds=(problem.lo, problem.hi), method="trf",
                            x_scale=1.0, max_nfev=max_nfev, xtol=1e-8, ftol=1e-10, gtol=1e-10)
    finally:
        if problem.bar is not None:
            problem.bar.close()
    z = res.x
    sims = problem.simulate(z)
    cov, se_z, dof, s2 = _statistics(problem.jacobian_central(z), problem.residual(sims))
    values, se, ci = space.interval(z, se_z, _t95(dof))
    params = base.replace(**dict(zip(names, values)), name=f"{base.name}+curves")
    at_bounds = [n for k, n in enumerate(names) if z[k] - problem.lo[k] < 1e-6 or problem.hi[k] - z[k] < 1e-6]
    if at_bounds:
        notes.append(f"parameter(s) {at_bounds} at a bound of the search range: their intervals are not meaningful")
    if problem.incomplete:
        notes.append(f"{problem.incomplete} of {problem.runs} simulations stopped early (values held after the "
                     "last converged step)")
    if not res.success:
        notes.append(f"optimiser: {res.message}")

    # quality per quantity, tables
    resid, rms, r2 = {}, {}, {}
    for q in quantities:
        fitted = np.concatenate([sim[q][m] for c, m, sim in zip(curve_list, used, sims) if q in c.measured])
        meas = np.concatenate([c.measured[q][m] for c, m in zip(curve_list, used) if q in c.measured])
        resid[q] = fitted - meas
        rms[q], r2[q] = _quality(fitted, meas)
    data, fit_table = _curve_tables(curve_list, used, sims, params, steps, rule, quantities)
    for msg in notes:
        warnings.warn(msg, RuntimeWarning, stacklevel=2)
    info = {
        "sources": [c.source or c.label for c in curve_list],
        "curves": [{"label": c.label, "kind": c.kind, "source": c.source, **c.conditions, "rows": len(c.x),
                    "rows_fitted": int(m.sum()),
                    "measured": sorted(c.measured)} for c, m in zip(curve_list, used)],
        "base": base.name,
        "start": start_values,
        "free": list(names),
        "scales": scale,
        "softening": softening,
        "steps": int(steps),
        "diff_step": float(diff_step),
        "at_bounds": at_bounds,
        "residual_variance_scaled": s2,
        "correlation": _correlation(cov),
        "optimiser": str(res.message),
        "iterations": int(res.nfev),
        "simulations": problem.runs,
        "incomplete_simulations": problem.incomplete,
        "wall_time_s": time.perf_counter() - t0,
        "warnings": notes,
    }
    return Identification("triaxial", names, values, se, ci, resid, rms, r2, {"curves": dof}, params, data,
                           fit_table, info)


def _residual_scales(curves: list[Curve], used: list[np.ndarray], quantities: list[str],
                     scales: Mapping[str, float] | None) -> dict[str, float]:
    """The scale s of each quantity's residuals (simulated - measured) / s: ``scales[q]`` (or of its
    group, :func:`_scale_group`) if given, else the largest measured magnitude in the group over
    the fitted rows of all curves."""
    out = {}
    for q in quantities:
        group = _scale_group(q)
        if scales and q in scales:
            out[q] = float(scales[q])
        elif scales and group in scales:
            out[q] = float(scales[group])
        else:
            out[q] = max(float(np.max(np.abs(c.measured[k][m]))) for c, m in zip(curves, used)
                         for k in c.measured if _scale_group(k) == group)
        if not (math.isfinite(out[q]) and out[q] > 0):
            raise ValueError(f"quantity {q!r}: residual scale {out[q]!r} (every measured value 0?); allowed: a "
                             f"positive scale, give scales={{{q!r}: ...}}")
    return out


class _CurveProblem:
    """The least-squares problem of :func:`triaxial` in the scaled variables z: residuals (one
    simulation of every curve per evaluation, the last one cached) and their finite-difference
    Jacobians."""

    def __init__(self, curves, used, scale, base, space: _Space, steps, rule, diff_step):
        self.curves, self.used, self.scale, self.base, self.space = curves, used, scale, base, space
        self.steps, self.rule, self.h = steps, rule, diff_step
        self.lo, self.hi = space.bounds()
        self.runs = self.incomplete = 0
        self.bar = None
        self._cache: tuple[bytes, np.ndarray] | None = None

    def simulate(self, z: np.ndarray) -> list[dict]:
        """Every curve simulated with the constants of z."""
        params = self.base.replace(**self.space.to_params(z))
        sims = []
        for c in self.curves:
            sim, done = simulate(c, params, steps=self.steps, rule=self.rule)
            self.runs += 1
            self.incomplete += not done
            if self.bar is not None:
                self.bar.update(1)
            sims.append(sim)
        return sims

    def residual(self, sims: list[dict]) -> np.ndarray:
        """(simulated - measured) / scale over the fitted rows, curve by curve, quantity by quantity."""
        return np.concatenate([(sim[q][m] - c.measured[q][m]) / self.scale[q]
                               for c, m, sim in zip(self.curves, self.used, sims) for q in sorted(c.measured)])

    def __call__(self, z: np.ndarray) -> np.ndarray:
        key = np.asarray(z, dtype=float).tobytes()
        if self._cache is None or self._cache[0] != key:
            self._cache = (key, self.residual(self.simulate(z)))
        return self._cache[1]

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        """Forward differences with step h (inwards at an upper bound): the optimiser's Jacobian."""
        r0 = self(z)
        cols = []
        for k in range(len(z)):
            h = self.h if z[k] + self.h <= self.hi[k] else -self.h
            zk = z.copy()
            zk[k] += h
            cols.append((self.residual(self.simulate(zk)) - r0) / h)
        return np.column_stack(cols)

    def jacobian_central(self, z: np.ndarray) -> np.ndarray:
        """Central differences (error O(h^2)): the identifiability check and the covariance."""
        cols = []
        for k in range(len(z)):
            h = min(self.h, max(0.5 * (self.hi[k] - z[k]), 1e-12), max(0.5 * (z[k] - self.lo[k]), 1e-12))
            zp, zm = z.copy(), z.copy()
            zp[k] += h
            zm[k] -= h
            cols.append((self.residual(self.simulate(zp)) - self.residual(self.simulate(zm))) / (2.0 * h))
        return np.column_stack(cols)

    def check_identifiable(self, z: np.ndarray) -> None:
        """ValueError naming the combination of free constants the curves cannot separate (a singular
        value of the central-difference Jacobian below 1e-6 of the largest)."""
        _, sv, vt = np.linalg.svd(self.jacobian_central(z), full_matrices=False)
        if sv.min() > 1e-6 * sv.max():
            return
        names = self.space.names
        # a singular vector is defined up to its sign, which the SVD leaves to round-off (it flipped between
        # machines on the same curves): print it with its largest component positive
        direction = vt[-1] * np.sign(vt[-1, np.argmax(np.abs(vt[-1]))])
        combo = ", ".join(f"{n} {direction[k]:+.2f}" for k, n in enumerate(names) if abs(direction[k]) > 0.05)
        raise ValueError(
            f"free = {list(names)}: these curves do not determine them separately; the response does not change "
            f"along the direction ({combo}) of the scaled variables (log of positive constants). Fix one of "
            "them: in element tests A and t act only through A/t (triaxial) and t through t/E (direct shear); "
            "fix t (the band thickness) and fit A")


def _curve_tables(curves: list[Curve], used: list[np.ndarray], sims: list[dict], params: CPAParameters,
                  steps: int, rule, quantities: list[str]) -> tuple[Table, Table]:
    """``data``: every data row with measured, fitted, residual; ``fit``: each curve simulated on a
    grid of 4 * steps points up to its last x."""
    x_names = sorted({c.x_name for c in curves})
    xcol = x_names[0] if len(x_names) == 1 else "x"
    cols: dict[str, list] = {"curve": [], xcol: [], "used": []}
    for q in quantities:
        cols[q], cols[f"{q}_fit"], cols[f"{q}_residual"] = [], [], []
    for i, (c, m, sim) in enumerate(zip(curves, used, sims)):
        cols["curve"] += [i] * len(c.x)
        cols[xcol] += list(c.x)
        cols["used"] += list(m.astype(float))
        for q in quantities:
            if q in c.measured:
                cols[q] += list(c.measured[q])
                cols[f"{q}_fit"] += list(sim[q])
                cols[f"{q}_residual"] += list(sim[q] - c.measured[q])
            else:
                for k in (q, f"{q}_fit", f"{q}_residual"):
                    cols[k] += [np.nan] * len(c.x)
    desc = {"curve": "index of the curve (metadata 'curves')", "used": "1 if the row was fitted (0: after a "
            "softening peak)", xcol: ", ".join(sorted({c.x_name for c in curves})) + " of the curve"}
    for q in quantities:
        desc[q] = f"measured {q}"
        desc[f"{q}_fit"] = f"simulated {q} with the identified constants"
        desc[f"{q}_residual"] = f"{q}_fit - {q}"
    meta = {"curves": [{"label": c.label, "kind": c.kind, "x": c.x_name, **c.conditions} for c in curves]}
    data = Table({k: np.asarray(v, dtype=float) for k, v in cols.items()}, desc, meta,
                 title="measured curves against the simulations with the identified constants",
                 convention="as the curve files: eps_a, eps_v, q_kPa compression +; tau_kPa, shear displacement "
                            "with the shear; normal displacement dilation +; tensor components tension +")
    dense: dict[str, list] = {"curve": [], xcol: []}
    for q in quantities:
        dense[f"{q}_fit"] = []
    for i, c in enumerate(curves):
        if c.kind == "path":
            xs, sim = c.x, sims[i]
        else:
            xs = np.linspace(0.0, float(c.x.max()), 4 * steps + 1)[1:]
            fine = Curve(c.kind, c.label, c.x_name, xs, {q: xs for q in c.measured}, c.conditions)
            sim, _ = simulate(fine, params, steps=4 * steps, rule=rule)
        dense["curve"] += [i] * len(xs)
        dense[xcol] += list(xs)
        for q in quantities:
            dense[f"{q}_fit"] += list(sim[q]) if q in sim else [np.nan] * len(xs)
    fit = Table({k: np.asarray(v, dtype=float) for k, v in dense.items()},
                {f"{q}_fit": f"simulated {q}" for q in quantities}, meta,
                title="simulated curves, identified constants")
    return data, fit


# ====================================================================================== figure
def _plot(ident: Identification, path: Path) -> Path:
    """Data points and fitted curves (top), residuals (bottom)."""
    from matplotlib.figure import Figure

    if ident.kind == "direct_shear":
        d, f = ident.data, ident.fit
        fig = Figure(figsize=(10, 6.5), layout="constrained")
        axes = fig.subplots(2, 2, sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
        ax = axes[0, 0]
        band = f["eta_f_stderr"]
        ax.fill_between(f["alpha_deg"], f["eta_f"] - 2 * band, f["eta_f"] + 2 * band, alpha=0.2, label="fit +- 2 s.e.")
        ax.plot(f["alpha_deg"], f["eta_f"], "-", label="identified eta_f (eq. 2.20)")
        ax.plot(f["alpha_deg"], f["eta_f_base"], "--", label=f"base set ({ident.info.get('base')})")
        ax.plot(d["alpha_deg"], d["slope"], "ko", label="envelope slopes")
        ax.set_ylabel("friction coefficient eta_f [-]")
        ax.legend(fontsize=8)
        ax = axes[0, 1]
        if "cohesion_stderr_kPa" in f:
            cb = f["cohesion_stderr_kPa"]
            ax.fill_between(f["alpha_deg"], f["cohesion_kPa"] - 2 * cb, f["cohesion_kPa"] + 2 * cb, alpha=0.2)
        ax.plot(f["alpha_deg"], f["cohesion_kPa"], "-", label="identified c (eq. 2.4)")
        ax.plot(d["alpha_deg"], d["intercept_kPa"], "ko", label="envelope intercepts")
        ax.set_ylabel("cohesion c [kPa]")
        ax.legend(fontsize=8)
        axes[1, 0].axhline(0.0, color="0.5", lw=0.8)
        axes[1, 0].plot(d["alpha_deg"], d["slope_residual"], "ko")
        axes[1, 0].set_ylabel("residual [-]")
        axes[1, 1].axhline(0.0, color="0.5", lw=0.8)
        axes[1, 1].plot(d["alpha_deg"], d["intercept_residual_kPa"], "ko")
        axes[1, 1].set_ylabel("residual [kPa]")
        for ax in axes[1]:
            ax.set_xlabel("deposition angle alpha [deg]")
        for ax in axes.ravel():
            ax.grid(alpha=0.3)
        fig.suptitle("Direct-shear envelopes: identified strength distribution")
    else:
        d, f = ident.data, ident.fit
        quantities = list(ident.residuals)
        xcol = [c for c in d.columns if c not in ("curve", "used")][0]
        fig = Figure(figsize=(5.0 * len(quantities), 6.5), layout="constrained")
        axes = fig.subplots(2, len(quantities), squeeze=False, sharex="col",
                            gridspec_kw={"height_ratios": [3, 1.3]})
        labels = [c["label"] for c in ident.info["curves"]]
        for j, q in enumerate(quantities):
            top, bottom = axes[0, j], axes[1, j]
            for i, lab in enumerate(labels):
                m = d["curve"] == i
                mf = f["curve"] == i
                if not np.isfinite(d[q][m]).any():
                    continue
                line, = top.plot(f[xcol][mf], f[f"{q}_fit"][mf], "-", label=f"{lab} fit")
                use = d["used"][m] > 0
                top.plot(d[xcol][m][use], d[q][m][use], "o", ms=3, color=line.get_color(), label=f"{lab} data")
                if (~use).any():
                    top.plot(d[xcol][m][~use], d[q][m][~use], "x", ms=4, color=line.get_color())
                bottom.plot(d[xcol][m][use], d[f"{q}_residual"][m][use], "o", ms=3, color=line.get_color())
                if (~use).any():
                    bottom.plot(d[xcol][m][~use], d[f"{q}_residual"][m][~use], "x", ms=4, color=line.get_color())
            bottom.axhline(0.0, color="0.5", lw=0.8)
            top.set_ylabel(q)
            bottom.set_ylabel(f"residual {q}")
            bottom.set_xlabel(xcol)
            top.legend(fontsize=7)
            for ax in (top, bottom):
                ax.grid(alpha=0.3)
        fig.suptitle("Element curves: data (o; x not fitted) and simulations with the identified constants")
    fig.savefig(path, dpi=110)
    return path


def sweep_target(out, method: str = "direct-shear", data="fig8", **options) -> dict:
    """Sweep target (:mod:`material.sweep`): one identification into the folder ``out``.

    ``method`` ``"direct-shear"`` (``data``: an envelope CSV or ``"fig8"``) or ``"triaxial"`` (``data``: a
    curve CSV or a list of them); ``options`` go to :func:`direct_shear` or :func:`triaxial`. Writes what
    :meth:`Identification.write` writes; returns each identified value with its standard error and the
    fit quality (``rms_<quantity>``, ``r2_<quantity>``)."""
    if method not in ("direct-shear", "triaxial"):
        raise ValueError(f"identification method = {method!r}: allowed 'direct-shear' or 'triaxial'")
    fn = direct_shear if method == "direct-shear" else triaxial
    result = fn(data, **options)
    result.write(out, command=f"material.identify.sweep_target(method={method!r}, data={data!r}, **{options!r})")
    summary: dict[str, Any] = {}
    for name, value, se in zip(result.names, result.values, result.stderr):
        summary[name] = float(value)
        summary[f"{name}_stderr"] = float(se)
    summary.update({f"rms_{q}": float(v) for q, v in result.rms.items()})
    summary.update({f"r2_{q}": float(v) for q, v in result.r2.items()})
    return summary
