"""Reference elastoplastic laws with textbook closed-form answers: von Mises, Drucker-Prager, Mohr-Coulomb.

Both follow the interface of :mod:`material.base` (strain driven, tension positive, kPa) and exist
to verify the FE solver (Prandtl's bearing capacity, cavity expansion, ...) before it meets the CPA
law. Integration: one-step elastic predictor / closest-point (radial) return, which is exact for
these laws with linear hardening; the tangent is the consistent (algorithmic) tangent
d(sigma_{n+1}) / d(d_strain). Vectorised numpy over the N points (no loop over points); the algebra
is closed form, so there is no separate numba kernel.

References: de Souza Neto, Peric & Owen (2008), *Computational Methods for Plasticity*, boxes 7.3-7.4
(von Mises), 8.1-8.4 (Mohr-Coulomb) and 8.5-8.8 (Drucker-Prager), appendix A (derivatives of isotropic
tensor functions); Simo & Hughes (1998), ch. 3.
"""

from __future__ import annotations

import numpy as np

from material.base import STATUS_OK, CoupledTangent, State, as_stress_batch, check_batch, check_state
from material.elastic import _check_elastic, isotropic_compliance, isotropic_stiffness

__all__ = ["VonMises", "GradientVonMises", "DruckerPrager", "MohrCoulomb", "von_mises_stress"]

_I2 = np.eye(3)
_II = np.einsum("ij,kl->ijkl", _I2, _I2)  # 1 (x) 1
_ISYM = 0.5 * (np.einsum("ik,jl->ijkl", _I2, _I2) + np.einsum("il,jk->ijkl", _I2, _I2))
_IDEV = _ISYM - _II / 3.0


def _dev(a: np.ndarray) -> np.ndarray:
    return a - np.trace(a, axis1=-2, axis2=-1)[..., None, None] / 3.0 * _I2


def _norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...ij,...ij->...", a, a))


def von_mises_stress(stress: np.ndarray) -> np.ndarray:
    """q = sqrt(3/2 s:s) of (..., 3, 3) stresses [kPa]."""
    return np.sqrt(1.5) * _norm(_dev(np.asarray(stress, dtype=float)))


def _check_nonneg(name: str, value: float, strict: bool = False) -> float:
    v = float(value)
    ok = np.isfinite(v) and (v > 0 if strict else v >= 0)
    if not ok:
        raise ValueError(f"{name} = {value!r}: must be {'>' if strict else '>='} 0 (finite)")
    return v


class _Base:
    E: float
    nu: float

    def _init_elastic(self, E_kPa: float, nu: float) -> None:
        self.E, self.nu = _check_elastic(E_kPa, nu)
        self.G = self.E / (2.0 * (1.0 + self.nu))
        self.K = self.E / (3.0 * (1.0 - 2.0 * self.nu))
        self.stiffness = isotropic_stiffness(self.E, self.nu)

    def initial_state(self, n_points: int, stress=None, *, element_size=None) -> State:
        """State of ``n_points`` points: zero strain and plastic strain.

        ``stress`` (3, 3) or (N, 3, 3), tension +, is validated but not stored: the stress is passed
        to :meth:`update`; it is assumed admissible (inside the yield surface). ``element_size`` is part
        of the material protocol; a law without a length scale ignores it.
        """
        as_stress_batch(stress, n_points)
        n = int(n_points)
        return {
            "strain": np.zeros((n, 3, 3)),
            "plastic_strain": np.zeros((n, 3, 3)),
            "eq_plastic_strain": np.zeros(n),
            "status": np.zeros(n, dtype=np.int8),
            "step_ratio": np.ones(n),
        }

    def _trial(self, d_strain, stress, state):
        de, s = check_batch(d_strain, stress)
        n = de.shape[0]
        check_state(state, n, ("strain", "plastic_strain", "eq_plastic_strain"))
        trial = s + np.einsum("ijkl,nkl->nij", self.stiffness, de)
        return de, trial, n

    def _new_state(self, state, de, d_plastic, d_eq):
        n = de.shape[0]
        return {
            "strain": state["strain"] + de,
            "plastic_strain": state["plastic_strain"] + d_plastic,
            "eq_plastic_strain": state["eq_plastic_strain"] + d_eq,
            "status": np.full(n, STATUS_OK, dtype=np.int8),
            "step_ratio": np.ones(n),
        }


class VonMises(_Base):
    """J2 plasticity with linear isotropic hardening, q = sqrt(3 J2) <= sigma_y + H eps_bar_p.

    Parameters
    ----------
    E_kPa : float
        Young's modulus [kPa], > 0.
    nu : float
        Poisson's ratio, -1 < nu < 0.5.
    yield_stress_kPa : float
        Initial uniaxial yield stress sigma_y [kPa], > 0 (the shear strength is sigma_y / sqrt(3)).
    hardening_kPa : float, optional
        Linear isotropic hardening modulus H [kPa] (0: perfectly plastic), with respect to the
        equivalent plastic strain eps_bar_p = integral of sqrt(2/3 d_eps_p : d_eps_p). Negative: linear
        softening, H > -3 G (below it the strain-driven update has no unique solution), the yield stress
        floored at 0 (perfectly plastic at zero strength from eps_bar_p = sigma_y / |H| on). Softening
        without a length scale localises in one row of elements: it serves to test path following
        (:class:`femgran.solver.PathControl`), where a snap-back is known in closed form.

    Notes
    -----
    Radial return (de Souza Neto et al. box 7.3): with the trial deviator s* and q* = sqrt(3/2) |s*|,
    dgamma = (q* - sigma_y(eps_bar_p)) / (3 G + H), s = (1 - 3 G dgamma / q*) s*, d eps_p = dgamma 3/2 s*/q*.
    Consistent tangent (box 7.4), N = s*/|s*|:
    D = K 1(x)1 + 2G (1 - 3 G dgamma / q*) I_dev + 6 G^2 (dgamma / q* - 1 / (3 G + H)) N (x) N.
    """

    def __init__(self, E_kPa: float, nu: float, yield_stress_kPa: float, hardening_kPa: float = 0.0):
        self._init_elastic(E_kPa, nu)
        self.yield_stress = _check_nonneg("yield_stress_kPa", yield_stress_kPa, strict=True)
        self.hardening = float(hardening_kPa)
        if not (np.isfinite(self.hardening) and self.hardening > -3.0 * self.G):
            raise ValueError(f"hardening_kPa = {hardening_kPa!r}: must be > -3 G = {-3.0 * self.G:g} (finite; negative "
                             "values soften)")

    def __repr__(self) -> str:
        return (
            f"VonMises(E_kPa={self.E:g}, nu={self.nu:g}, yield_stress_kPa={self.yield_stress:g}, "
            f"hardening_kPa={self.hardening:g})"
        )

    def strength(self, eq_plastic_strain) -> np.ndarray:
        """sigma_y + H eps_bar_p, floored at 0 [kPa]."""
        return np.maximum(self.yield_stress + self.hardening * np.asarray(eq_plastic_strain, dtype=float), 0.0)

    def yield_function(self, stress: np.ndarray, eq_plastic_strain: np.ndarray) -> np.ndarray:
        """f = q - max(sigma_y + H eps_bar_p, 0) [kPa], (N,)."""
        return von_mises_stress(stress) - self.strength(eq_plastic_strain)

    def update(self, d_strain, stress, state: State):
        """(N,3,3) strain increment and stress (tension +) -> stress, new state, tangent (N,3,3,3,3)."""
        de, trial, n = self._trial(d_strain, stress, state)
        G, K, H = self.G, self.K, self.hardening
        s_tr = _dev(trial)
        norm_tr = _norm(s_tr)
        q_tr = np.sqrt(1.5) * norm_tr
        f_tr = q_tr - self.strength(state["eq_plastic_strain"])
        plastic = f_tr > 1e-12 * self.yield_stress
        safe_q = np.where(plastic, q_tr, 1.0)
        dgamma = np.where(plastic, f_tr / (3.0 * G + H), 0.0)
        if H < 0.0:  # softening past zero strength: perfectly plastic at q = 0 (H = 0 there)
            spent = plastic & (self.yield_stress + H * (state["eq_plastic_strain"] + dgamma) < 0.0)
            dgamma = np.where(spent, q_tr / (3.0 * G), dgamma)
            H = np.where(spent, 0.0, H)
        N = s_tr / np.where(plastic, norm_tr, 1.0)[:, None, None]  # unit deviator (used where plastic)
        scale = 1.0 - 3.0 * G * dgamma / safe_q
        new_stress = trial - (1.0 - scale)[:, None, None] * s_tr
        d_plastic = (1.5 * dgamma / safe_q)[:, None, None] * s_tr
        tangent = np.broadcast_to(self.stiffness, (n, 3, 3, 3, 3)).copy()
        if plastic.any():
            p = plastic
            Np = N[p]
            tangent[p] = (
                K * _II
                + 2.0 * G * scale[p][:, None, None, None, None] * _IDEV
                + (6.0 * G**2 * (dgamma[p] / q_tr[p] - 1.0 / (3.0 * G + np.broadcast_to(H, n)[p])))
                [:, None, None, None, None]
                * np.einsum("nij,nkl->nijkl", Np, Np)
            )
        return new_stress, self._new_state(state, de, d_plastic, dgamma), tangent



class GradientVonMises(VonMises):
    """Von Mises softening regularised by an implicit gradient of the equivalent plastic strain.

    The strength is driven by the over-nonlocal variable kappa_hat = m ebar + (1 - m) kappa (Vermeer &
    Brinkgreve 1994; Stroemberg & Ristinmaa 1996), sigma_y(kappa_hat) = max(sigma_y0 + H kappa_hat, 0),
    where kappa is the point's equivalent plastic strain (the local measure e) and ebar the nodal field that
    solves ebar - l^2 lap(ebar) = kappa with zero normal gradient on the boundary (Peerlings et al. 1996 for
    damage, Engelen, Geers & Baaijens 2003 for plasticity). In a homogeneous state ebar = kappa and the law
    is :class:`VonMises` with the modulus H; inside a band ebar < kappa, which with m > 1 spreads the
    softening over a width set by l instead of one row of elements. m = 1 (the nonlocal variable alone)
    lets the plastic zone keep shrinking as the softening goes on (Jirasek & Rolshoven 2003); the default
    m = 2 keeps it finite.

    Parameters
    ----------
    E_kPa, nu, yield_stress_kPa, hardening_kPa : as :class:`VonMises`; the local modulus
        H_loc = (1 - m) H must satisfy 3 G + H_loc > 0.
    length_m : float
        The internal length l [m], > 0.
    over_nonlocal : float
        m >= 1.

    Notes
    -----
    With ebar given (the coupled Newton iterates on it), the radial return is that of :class:`VonMises`
    with H replaced by H_loc and sigma_y0 by sigma_y0 + m H ebar: a = 3 G + H_loc,
    dgamma = (q* - sigma_y0 - H (m ebar + (1 - m) kappa_n)) / a, and with N = s*/|s*|

        d sigma / d ebar = sqrt(6) G H m / a N,     d kappa / d eps = sqrt(6) G / a N,
        d kappa / d ebar = -H m / a

    (zero where the point is elastic; where the strength is spent, sigma_y = 0, a = 3 G and the
    derivatives with respect to ebar vanish).
    """

    def __init__(self, E_kPa: float, nu: float, yield_stress_kPa: float, hardening_kPa: float = 0.0, *,
                 length_m: float, over_nonlocal: float = 2.0):
        super().__init__(E_kPa, nu, yield_stress_kPa, hardening_kPa)
        self.nonlocal_length = _check_nonneg("length_m", length_m, strict=True)
        m = float(over_nonlocal)
        if not (np.isfinite(m) and m >= 1.0):
            raise ValueError(f"over_nonlocal = {over_nonlocal!r}: must be >= 1 (finite)")
        self.over_nonlocal = m
        if not 3.0 * self.G + (1.0 - m) * self.hardening > 0.0:
            raise ValueError(f"over_nonlocal = {m:g} with hardening_kPa = {self.hardening:g}: the local modulus "
                             f"(1 - m) H = {(1.0 - m) * self.hardening:g} must be > -3 G = {-3.0 * self.G:g}")

    def __repr__(self) -> str:
        return (f"GradientVonMises(E_kPa={self.E:g}, nu={self.nu:g}, yield_stress_kPa={self.yield_stress:g}, "
                f"hardening_kPa={self.hardening:g}, length_m={self.nonlocal_length:g}, "
                f"over_nonlocal={self.over_nonlocal:g})")

    def initial_state(self, n_points: int, stress=None, *, element_size=None) -> State:
        """As :meth:`VonMises.initial_state`, plus the committed nonlocal variable ``"nonlocal"`` (N,) = 0."""
        state = super().initial_state(n_points, stress, element_size=element_size)
        state["nonlocal"] = np.zeros(int(n_points))
        return state

    def update(self, d_strain, stress, state: State, d_nonlocal=None):
        """The local law (ebar = kappa) without ``d_nonlocal``; with it (N,), the update at the given
        ebar = state["nonlocal"] + d_nonlocal and a :class:`material.base.CoupledTangent`."""
        if d_nonlocal is None:
            new_stress, new_state, tangent = super().update(d_strain, stress, state)
            new_state["nonlocal"] = new_state["eq_plastic_strain"].copy()
            return new_stress, new_state, tangent
        de, trial, n = self._trial(d_strain, stress, state)
        check_state(state, n, ("nonlocal",))
        dnl = np.asarray(d_nonlocal, dtype=float)
        if dnl.shape != (n,) or not np.all(np.isfinite(dnl)):
            raise ValueError(f"d_nonlocal: expected a finite array of shape ({n},), got {dnl.shape}")
        G, K, H, m = self.G, self.K, self.hardening, self.over_nonlocal
        ebar = state["nonlocal"] + dnl
        kappa_n = state["eq_plastic_strain"]
        s_tr = _dev(trial)
        norm_tr = _norm(s_tr)
        q_tr = np.sqrt(1.5) * norm_tr
        driving = self.yield_stress + H * (m * ebar + (1.0 - m) * kappa_n)  # sigma_y at the start of the return
        plastic = q_tr - np.maximum(driving, 0.0) > 1e-12 * self.yield_stress
        a = 3.0 * G + (1.0 - m) * H
        dgamma = np.where(plastic, (q_tr - driving) / a, 0.0)
        spent = plastic & (driving + (1.0 - m) * H * dgamma < 0.0)  # strength reaches 0: perfectly plastic there
        dgamma = np.where(spent, q_tr / (3.0 * G), dgamma)
        a_pt = np.where(spent, 3.0 * G, a)
        h_pt = np.where(spent, 0.0, (1.0 - m) * H)
        safe_q = np.where(plastic, q_tr, 1.0)
        N = s_tr / np.where(plastic, norm_tr, 1.0)[:, None, None]
        scale = 1.0 - 3.0 * G * dgamma / safe_q
        new_stress = trial - (1.0 - scale)[:, None, None] * s_tr
        d_plastic = (1.5 * dgamma / safe_q)[:, None, None] * s_tr
        tangent = np.broadcast_to(self.stiffness, (n, 3, 3, 3, 3)).copy()
        ds_de = np.zeros((n, 3, 3))
        dk_deps = np.zeros((n, 3, 3))
        dk_de = np.zeros(n)
        if plastic.any():
            p = plastic
            Np = N[p]
            tangent[p] = (K * _II + 2.0 * G * scale[p][:, None, None, None, None] * _IDEV
                          + (6.0 * G**2 * (dgamma[p] / q_tr[p] - 1.0 / (3.0 * G + h_pt[p])))[:, None, None, None, None]
                          * np.einsum("nij,nkl->nijkl", Np, Np))
            coupled = p & ~spent
            dk_de[coupled] = -H * m / a_pt[coupled]
            ds_de[coupled] = (np.sqrt(6.0) * G * H * m / a_pt[coupled])[:, None, None] * N[coupled]
            dk_deps[p] = (np.sqrt(6.0) * G / a_pt[p])[:, None, None] * Np
        new_state = self._new_state(state, de, d_plastic, dgamma)
        new_state["nonlocal"] = ebar
        kappa = new_state["eq_plastic_strain"]
        return new_stress, new_state, CoupledTangent(tangent, ds_de, kappa, dk_deps, dk_de)

def _frictional(cohesion_kPa, friction_deg, dilation_deg) -> tuple[float, float, float]:
    """Validated (c, phi, psi) of a Mohr-Coulomb-type law: c >= 0, 0 <= phi < 90, 0 <= psi <= phi (default
    phi), and some strength (c > 0 or phi > 0)."""
    c = _check_nonneg("cohesion_kPa", cohesion_kPa)
    phi = float(friction_deg)
    if not (np.isfinite(phi) and 0.0 <= phi < 90.0):
        raise ValueError(f"friction_deg = {friction_deg!r}: allowed 0 <= friction_deg < 90")
    psi = phi if dilation_deg is None else float(dilation_deg)
    if not (np.isfinite(psi) and 0.0 <= psi <= phi):
        raise ValueError(f"dilation_deg = {dilation_deg!r}: allowed 0 <= dilation_deg <= friction_deg = {phi:g}")
    if c == 0.0 and phi == 0.0:
        raise ValueError("cohesion_kPa = 0 and friction_deg = 0: the material would have no strength")
    return c, phi, psi


_MATCH = ("compression", "extension", "plane_strain")


def _dp_coefficients(angle_deg: float, match: str) -> tuple[float, float]:
    """(eta, xi) of sqrt(J2) + eta p - xi c matched to Mohr-Coulomb with angle phi (de Souza Neto 6.121-6.123)."""
    a = np.deg2rad(angle_deg)
    if match == "compression":  # outer cone: triaxial compression meridian
        d = np.sqrt(3.0) * (3.0 - np.sin(a))
        return 6.0 * np.sin(a) / d, 6.0 * np.cos(a) / d
    if match == "extension":  # inner cone: triaxial extension meridian
        d = np.sqrt(3.0) * (3.0 + np.sin(a))
        return 6.0 * np.sin(a) / d, 6.0 * np.cos(a) / d
    d = np.sqrt(9.0 + 12.0 * np.tan(a) ** 2)  # plane strain (exact collapse loads with associated flow)
    return 3.0 * np.tan(a) / d, 3.0 / d


class DruckerPrager(_Base):
    """Drucker-Prager cone sqrt(J2) + eta p - xi c <= 0 matched to Mohr-Coulomb (c, phi), perfectly plastic
    unless ``hardening_kPa`` (on the cohesion) is given.

    Parameters
    ----------
    E_kPa, nu : float
        Isotropic elasticity [kPa], [-].
    cohesion_kPa : float
        Mohr-Coulomb cohesion c [kPa], >= 0 (c = 0 with phi > 0 is a cohesionless cone).
    friction_deg : float
        Mohr-Coulomb friction angle phi [deg], 0 <= phi < 90 (phi = 0 with c > 0: a von Mises-type cylinder).
    dilation_deg : float, optional
        Dilation angle psi [deg], 0 <= psi <= phi; default psi = phi (associated flow).
    match : {"plane_strain", "compression", "extension"}
        Which Mohr-Coulomb meridian the cone goes through (de Souza Neto et al. eqs. 6.121-6.123).
        ``"plane_strain"`` (default) reproduces the Mohr-Coulomb plane-strain collapse loads
        (Prandtl) for associated flow; ``"compression"`` the triaxial-compression strength
        q_f = 2 (c cos phi + p0 sin phi) / (1 - sin phi) (compression positive).
    hardening_kPa : float, optional
        Linear hardening of the cohesion, c = c0 + H eps_bar_p, H >= 0.

    Notes
    -----
    p = tr(sigma) / 3 (tension positive), J2 = s:s / 2. Return mapping (de Souza Neto et al. box 8.5):
    to the smooth cone, dgamma = Phi* / (G + K eta eta_bar + xi^2 H), s = (1 - G dgamma / sqrt(J2*)) s*,
    p = p* - K eta_bar dgamma, d eps_bar_p = xi dgamma; if that overshoots the apex
    (sqrt(J2*) - G dgamma < 0), return to the apex: s = 0, p = p* - K d eps_v_p with
    d eps_v_p = (p* - xi c_n / eta) / (K + xi^2 H / (eta eta_bar)), d eps_bar_p = xi d eps_v_p / eta_bar.
    eta_bar is eta with psi in place of phi. The consistent tangent (box 8.6) is non-symmetric when
    psi != phi; at the apex of a perfectly plastic cone it is zero (the solver must cope: cut back).
    """

    def __init__(
        self,
        E_kPa: float,
        nu: float,
        cohesion_kPa: float,
        friction_deg: float,
        dilation_deg: float | None = None,
        match: str = "plane_strain",
        hardening_kPa: float = 0.0,
    ):
        self._init_elastic(E_kPa, nu)
        self.cohesion, phi, psi = _frictional(cohesion_kPa, friction_deg, dilation_deg)
        if match not in _MATCH:
            raise ValueError(f"match = {match!r}: allowed {list(_MATCH)}")
        self.friction_deg, self.dilation_deg, self.match = phi, psi, match
        self.hardening = _check_nonneg("hardening_kPa", hardening_kPa)
        self.eta, self.xi = _dp_coefficients(phi, match)
        self.eta_bar, _ = _dp_coefficients(psi, match)

    def __repr__(self) -> str:
        return (
            f"DruckerPrager(E_kPa={self.E:g}, nu={self.nu:g}, cohesion_kPa={self.cohesion:g}, "
            f"friction_deg={self.friction_deg:g}, dilation_deg={self.dilation_deg:g}, match={self.match!r})"
        )

    def yield_function(self, stress: np.ndarray, eq_plastic_strain: np.ndarray) -> np.ndarray:
        """Phi = sqrt(J2) + eta p - xi c(eps_bar_p) [kPa], (N,)."""
        stress = np.asarray(stress, dtype=float)
        sqrt_j2 = _norm(_dev(stress)) / np.sqrt(2.0)
        p = np.trace(stress, axis1=-2, axis2=-1) / 3.0
        c = self.cohesion + self.hardening * np.asarray(eq_plastic_strain)
        return sqrt_j2 + self.eta * p - self.xi * c

    def update(self, d_strain, stress, state: State):
        """(N,3,3) strain increment and stress (tension +) -> stress, new state, tangent (N,3,3,3,3)."""
        de, trial, n = self._trial(d_strain, stress, state)
        G, K, H = self.G, self.K, self.hardening
        eta, eta_b, xi = self.eta, self.eta_bar, self.xi
        s_tr = _dev(trial)
        norm_tr = _norm(s_tr)
        sqrt_j2 = norm_tr / np.sqrt(2.0)
        p_tr = np.trace(trial, axis1=1, axis2=2) / 3.0
        c_n = self.cohesion + H * state["eq_plastic_strain"]
        phi_tr = sqrt_j2 + eta * p_tr - xi * c_n
        plastic = phi_tr > 1e-12 * (sqrt_j2 + eta * np.abs(p_tr) + xi * c_n) + 1e-300

        dgamma = np.where(plastic, phi_tr / (G + K * eta * eta_b + xi**2 * H), 0.0)
        apex = plastic & (sqrt_j2 - G * dgamma < 0.0)
        cone = plastic & ~apex

        new_stress = trial.copy()
        d_plastic = np.zeros_like(trial)
        d_eq = np.zeros(n)
        tangent = np.broadcast_to(self.stiffness, (n, 3, 3, 3, 3)).copy()

        if cone.any():
            c = cone
            sj = sqrt_j2[c]
            dg = dgamma[c]
            N = s_tr[c] / norm_tr[c][:, None, None]
            fac = 1.0 - G * dg / sj
            p_new = p_tr[c] - K * eta_b * dg
            new_stress[c] = fac[:, None, None] * s_tr[c] + p_new[:, None, None] * _I2
            # d eps_p = dgamma dPsi/dsigma, Psi = sqrt(J2) + eta_bar p: dPsi/dsigma = N / sqrt2 + eta_bar / 3 I
            d_plastic[c] = dg[:, None, None] * (N / np.sqrt(2.0) + eta_b / 3.0 * _I2)
            d_eq[c] = xi * dg
            A = 1.0 / (G + K * eta * eta_b + xi**2 * H)
            a1 = (2.0 * G * fac)[:, None, None, None, None]
            a2 = (2.0 * G * (G * dg / sj) - 2.0 * G * G * A)[:, None, None, None, None]
            NN = np.einsum("nij,nkl->nijkl", N, N)
            NI = np.einsum("nij,kl->nijkl", N, _I2)
            IN = np.einsum("ij,nkl->nijkl", _I2, N)
            # box 8.6 (de Souza Neto et al.), with N = s*/|s*| and sqrt(J2*) = |s*|/sqrt2
            tangent[c] = (
                a1 * _IDEV
                + a2 * NN
                - np.sqrt(2.0) * G * A * K * (eta * NI + eta_b * IN)
                + K * (1.0 - K * eta * eta_b * A) * _II
            )
        if apex.any():
            a = apex
            # psi = 0 (eta_bar = 0): no volumetric flow on the cone; the apex then acts as a tension
            # cut-off that does not harden the cohesion (alpha = 0)
            alpha = xi / eta_b if eta_b > 0.0 else 0.0
            beta = xi / eta if eta > 0.0 else np.inf
            dev_v = (p_tr[a] - beta * c_n[a]) / (K + alpha * beta * H)
            p_new = p_tr[a] - K * dev_v
            new_stress[a] = p_new[:, None, None] * _I2
            d_plastic[a] = (s_tr[a] / (2.0 * G)) + (dev_v / 3.0)[:, None, None] * _I2
            d_eq[a] = alpha * dev_v
            tangent[a] = (K * (1.0 - K / (K + alpha * beta * H)) * _II)[None]
        return new_stress, self._new_state(state, de, d_plastic, d_eq), tangent


# Mohr-Coulomb planes in principal space (sigma_1 >= sigma_2 >= sigma_3, tension positive): the plane
# f_ij = (sigma_i - sigma_j) + (sigma_i + sigma_j) sin(phi) - 2 c cos(phi) between the principal stresses i, j
_MAIN, _EDGE_12, _EDGE_23 = (0, 2), (0, 1), (1, 2)


def _mc_normal(pair, sin_angle) -> np.ndarray:
    """d f_ij / d sigma in principal space, (3,), for the friction (or dilation) angle's sine."""
    v = np.zeros(3)
    v[pair[0]] = 1.0 + sin_angle
    v[pair[1]] = -(1.0 - sin_angle)
    return v


class MohrCoulomb(_Base):
    """Perfectly plastic Mohr-Coulomb, (sigma_1 - sigma_3) + (sigma_1 + sigma_3) sin phi <= 2 c cos phi, with
    its edges and apex (multi-surface return in principal stresses).

    The reference law with corners: a microplane CPA law with an isotropic friction ratio eta = tan phi on
    every plane approaches this surface as the planes become dense, and :class:`DruckerPrager` is its smooth
    neighbour. On the same mesh the three show what the corners of a criterion cost the global Newton.

    Parameters
    ----------
    E_kPa, nu : float
        Isotropic elasticity [kPa], [-].
    cohesion_kPa : float
        Cohesion c [kPa], >= 0.
    friction_deg : float
        Friction angle phi [deg], 0 <= phi < 90 (phi = 0 with c > 0: Tresca, which has no apex).
    dilation_deg : float, optional
        Dilation angle psi [deg], 0 <= psi <= phi; default psi = phi (associated flow).

    Notes
    -----
    Tension positive, sigma_1 >= sigma_2 >= sigma_3 the principal stresses (sigma_3 the most compressive).
    With the elastic matrix of principal space De = K 1 1^T + 2 G (I - 1 1^T / 3), the normal n_ij and flow
    direction m_ij (n with psi for phi) of the plane f_ij, and the trial stress sigma* (box 8.1-8.4 of de
    Souza Neto et al.):

    * main plane f_13: dgamma = f*/(n^T De m), sigma = sigma* - dgamma De m, if the order of the principal
      stresses survives the return;
    * otherwise an edge: sigma_1 = sigma_2 (planes f_13 and f_23) if sigma_2 > sigma_1 after the main return,
      sigma_2 = sigma_3 (f_13 and f_12) if sigma_3 > sigma_2; the two multipliers solve the 2 x 2 system
      (N^T De M) dgamma = f*;
    * the apex sigma = c cot(phi) 1 where an edge return gives a negative multiplier or a stress beyond it.

    The consistent tangent is the principal tangent of the active planes, Dp = De - De M (N^T De M)^-1 N^T De
    (0 at the apex), carried to the full tensor with the spin terms of an isotropic tensor function,
    (sigma_a - sigma_b)/(eps*_a - eps*_b) for each pair of principal directions (their limit
    Dp_aa - Dp_ab where the trial stresses coincide). The law is perfectly plastic: ``eq_plastic_strain``
    accumulates sqrt(2/3 d_eps_p : d_eps_p) for output only.

    At an edge the plastic flow is any non-negative combination of its two planes' flows. A single point whose
    two lateral stresses are both prescribed (the triaxial element test of :func:`material.driver.triaxial`)
    therefore has no unique lateral strains at its limit: the driver reaches the limit (q_f exactly) and stops
    there with "singular system". In a body, or with an axisymmetric constraint, the path goes on.
    """

    def __init__(self, E_kPa: float, nu: float, cohesion_kPa: float, friction_deg: float,
                 dilation_deg: float | None = None):
        self._init_elastic(E_kPa, nu)
        self.cohesion, phi, psi = _frictional(cohesion_kPa, friction_deg, dilation_deg)
        self.friction_deg, self.dilation_deg = phi, psi
        self._sphi, self._spsi = np.sin(np.radians(phi)), np.sin(np.radians(psi))
        self._two_c_cos = 2.0 * self.cohesion * np.cos(np.radians(phi))
        K, G = self.K, self.G
        self._De = K * np.ones((3, 3)) + 2.0 * G * (np.eye(3) - np.ones((3, 3)) / 3.0)
        self._C_inv = isotropic_compliance(self.E, self.nu)

    def __repr__(self) -> str:
        return (f"MohrCoulomb(E_kPa={self.E:g}, nu={self.nu:g}, cohesion_kPa={self.cohesion:g}, "
                f"friction_deg={self.friction_deg:g}, dilation_deg={self.dilation_deg:g})")

    @property
    def apex_stress(self) -> float:
        """c cot(phi): the mean stress of the apex [kPa] (tension positive; inf for phi = 0)."""
        return self.cohesion / np.tan(np.radians(self.friction_deg)) if self.friction_deg > 0.0 else np.inf

    def yield_function(self, stress: np.ndarray, eq_plastic_strain=None) -> np.ndarray:
        """f = (sigma_1 - sigma_3) + (sigma_1 + sigma_3) sin phi - 2 c cos phi [kPa], (N,)."""
        sig = np.linalg.eigvalsh(np.asarray(stress, dtype=float))
        return (sig[..., 2] - sig[..., 0]) + (sig[..., 2] + sig[..., 0]) * self._sphi - self._two_c_cos

    def _f(self, pair, sig):
        return sig[:, pair[0]] - sig[:, pair[1]] + (sig[:, pair[0]] + sig[:, pair[1]]) * self._sphi - self._two_c_cos

    def _return_edge(self, trial_p, edge):
        """Principal stresses, multipliers (n, 2) and principal tangent (n, 3, 3) of the return to the edge
        of the main plane and ``edge``."""
        De = self._De
        N = np.stack([_mc_normal(_MAIN, self._sphi), _mc_normal(edge, self._sphi)], axis=1)  # (3, 2)
        M = np.stack([_mc_normal(_MAIN, self._spsi), _mc_normal(edge, self._spsi)], axis=1)
        A = N.T @ De @ M
        f = np.stack([self._f(_MAIN, trial_p), self._f(edge, trial_p)], axis=1)
        dgamma = f @ np.linalg.inv(A).T
        sig = trial_p - dgamma @ (De @ M).T
        Dp = De - De @ M @ np.linalg.solve(A, N.T @ De)
        return sig, dgamma, Dp

    def _principal_return(self, trial_p):
        """Principal stresses (n, 3) after the return, the principal tangent (n, 3, 3) and the plastic points
        (n,), of the principal trial stresses in descending order (n, 3)."""
        n = trial_p.shape[0]
        De, tol = self._De, 1e-12
        scale = np.abs(trial_p).max(axis=1) + self._two_c_cos + 1e-300
        sig = trial_p.copy()
        Dp = np.broadcast_to(De, (n, 3, 3)).copy()
        plastic = self._f(_MAIN, trial_p) > tol * scale
        if not plastic.any():
            return sig, Dp, plastic
        n_main, m_main = _mc_normal(_MAIN, self._sphi), _mc_normal(_MAIN, self._spsi)
        a = n_main @ De @ m_main
        dgamma = np.where(plastic, self._f(_MAIN, trial_p) / a, 0.0)
        main = trial_p - dgamma[:, None] * (De @ m_main)[None]
        ordered = (main[:, 0] >= main[:, 1] - tol * scale) & (main[:, 1] >= main[:, 2] - tol * scale)
        on_main = plastic & ordered
        sig[on_main] = main[on_main]
        Dp[on_main] = De - np.outer(De @ m_main, n_main @ De) / a
        apex = np.zeros(n, dtype=bool)
        above = main[:, 1] > main[:, 0]  # sigma_2 above sigma_1 after the return: the edge sigma_1 = sigma_2
        for edge, wrong in ((_EDGE_23, above), (_EDGE_12, ~above)):  # else sigma_3 above sigma_2
            take = plastic & ~ordered & wrong
            if not take.any():
                continue
            s_e, g_e, Dp_e = self._return_edge(trial_p[take], edge)
            beyond = (g_e < -tol).any(axis=1) | (s_e.mean(axis=1) > self.apex_stress)
            idx = np.flatnonzero(take)
            ok = idx[~beyond]
            sig[ok] = s_e[~beyond]
            Dp[ok] = Dp_e
            apex[idx[beyond]] = True
        if apex.any():
            if not np.isfinite(self.apex_stress):  # Tresca has no apex: an edge return always exists
                raise RuntimeError("Mohr-Coulomb return: no admissible edge with phi = 0 (please report)")
            sig[apex] = self.apex_stress
            Dp[apex] = 0.0
        return sig, Dp, plastic

    def update(self, d_strain, stress, state: State):
        """(N,3,3) strain increment and stress (tension +) -> stress, new state, tangent (N,3,3,3,3)."""
        de, trial, n = self._trial(d_strain, stress, state)
        w, V = np.linalg.eigh(trial)  # ascending: w[:, 0] the most compressive
        # principal space in descending order, as the docstring writes it: sigma_1 = w[:, 2]
        trial_p = w[:, ::-1]
        V = V[:, :, ::-1]
        sig_p, Dp, plastic = self._principal_return(trial_p)
        new_stress = trial.copy()
        d_plastic = np.zeros_like(trial)
        tangent = np.broadcast_to(self.stiffness, (n, 3, 3, 3, 3)).copy()
        if plastic.any():
            p = plastic
            new_stress[p] = np.einsum("nia,na,nja->nij", V[p], sig_p[p], V[p])
            d_plastic[p] = np.einsum("ijkl,nkl->nij", self._C_inv, trial[p] - new_stress[p])
            tangent[p] = self._tangent(V[p], trial_p[p], sig_p[p], Dp[p])
        d_eq = np.sqrt(2.0 / 3.0 * np.einsum("nij,nij->n", d_plastic, d_plastic))
        return new_stress, self._new_state(state, de, d_plastic, d_eq), tangent

    def _tangent(self, V, trial_p, sig_p, Dp) -> np.ndarray:
        """d sigma / d eps (N,3,3,3,3) of the isotropic tensor function from its principal parts."""
        e = [V[:, :, a] for a in range(3)]  # (n, 3) principal directions
        D = np.einsum("nab,nia,nja,nkb,nlb->nijkl", Dp, V, V, V, V)
        scale = np.abs(trial_p).max(axis=1) + 1e-300
        for a in range(3):
            for b in range(3):
                if a == b:
                    continue
                gap = trial_p[:, a] - trial_p[:, b]
                close = np.abs(gap) <= 1e-9 * scale
                theta = np.where(close, Dp[:, a, a] - Dp[:, a, b],
                                 2.0 * self.G * (sig_p[:, a] - sig_p[:, b]) / np.where(close, 1.0, gap))
                Eab = 0.5 * (np.einsum("ni,nj->nij", e[a], e[b]) + np.einsum("ni,nj->nij", e[b], e[a]))
                D += theta[:, None, None, None, None] * np.einsum("nij,nk,nl->nijkl", Eab, e[a], e[b])
        return 0.5 * (D + D.transpose(0, 1, 2, 4, 3))
