"""A shear band measured in a plane field: its inclination, position and thickness, or that there is none.

:func:`measure_band` takes the points of a field (e.g. the Gauss points of a plane-strain run) and a
non-negative intensity at each (e.g. the deviatoric strain increment after the peak) and returns a
:class:`Band`:

1. **Inclination** -- a Radon-type search: for each orientation theta (0.5 deg steps) the intensity is
   summed in strips of one element width parallel to theta (line integrals); the band lies along the
   orientation of the largest. A band collects its whole length in one strip, so an X of two bands is
   found along one of its arms, not across the patch where they cross (strip means, tried first, pick
   the short strips through that patch: 33 deg instead of 57 on the biaxial runs). Orientations
   within ``search`` of the x axis only (strips along the specimen's faces, which the platens and the free
   sides load, are not bands). The line integrals favour long strips (a band off the centre comes out
   1-1.5 deg towards the specimen's diagonal), so the angle is then refined within 2 deg, in 0.1 deg
   steps, to the orientation in which the band is sharpest: the highest mean of a strip half an element
   wide. (Points of equal area are assumed, as on a uniform mesh.)
2. **Profile and thickness** -- across the band (the signed distance d from the band's line through the
   points' centroid, in strips of half an element) the mean intensity is fitted by least squares with
   ``b(d) + amplitude exp(-(d - offset)^2 / (2 s^2))``, a peak on the linear trend b of the diffuse
   deformation around it, within three half-widths of the band's crest (the strip
   of the largest line integral; :func:`_peak_window`), so that another crest of the profile -- the
   crush at an imperfection, a conjugate band -- is not taken for it (measured: on a gradient-regularised
   run the crush next to the band was as high as the band and a fit over the whole profile reported
   18 mm for a band of 11); the thickness is the full width at half maximum of that peak,
   2 sqrt(2 ln 2) s; ``offset`` places the band's centre line. The trend b is given by its values at
   the two ends of the window, each bounded below by 0, so it is nowhere negative there, as the intensity
   is not (unbounded, it tilted from -0.07 to 0.4 across the lopsided profile of a band beside the crush of
   its weak zone).
3. **A band or none** -- ``localised`` when the fitted peak rises at least :data:`CONTRAST` times the
   background under its centre line above it and is narrower than :data:`MAX_WIDTH_FRACTION` of the specimen across the band.
   Measured on the plane-strain biaxial runs (CPA with softening, rough platens, weak corner, crack band;
   ``tests/femgran/test_band.py``; 60 steps to 5 %): on meshes of 4, 6, 8 and 12 elements across,
   contrasts of 2.4, 2.9, 2.9 and 2.2 and widths of 0.17-0.35 of the extent across the band; homogeneous
   runs with smooth platens (no imperfection, with and without softening): 0.0-0.10. The criterion sits
   between them, a factor of 2.2 and 10 from each. A diffuse field gets no thickness (NaN). An X of two conjugate bands is a band: the profile across one of them
   has its peak, the other crosses it as a broad bump that the fit takes as background.
4. **Both arms** -- :func:`measure_arms` measures the band of each family of orientations, rising (the
   band's direction between 0 and 90 deg from the x axis) and falling (90 to 180 deg), the stronger first:
   a diamond or an X of conjugate bands is measured whole. (Measured on the CPA gradient runs of the
   shear-band study, meshes of 24, 27, 36 and 48 elements: the stronger line integral was a rising arm at
   57-58 deg on 24 and 27 elements and at 41-43 deg on 36 and 48, and the falling arm lay at 134-135 deg,
   i.e. 45-46 deg from the x axis, on all four meshes.)
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

__all__ = ["Band", "measure_band", "measure_arms", "FAMILIES", "CONTRAST", "MAX_WIDTH_FRACTION"]

#: The families of band orientations :func:`measure_band` searches: both, or the band's direction rising
#: (0 to 90 deg from the x axis) or falling (90 to 180 deg).
FAMILIES = ("both", "rising", "falling")

#: The fitted peak must rise this many times the background above it (section 3 of the module docstring).
CONTRAST = 1.0
#: ... and be narrower (full width at half maximum) than this fraction of the specimen across the band.
MAX_WIDTH_FRACTION = 0.5


@dataclass(frozen=True)
class Band:
    """A measured band (module docstring).

    ``angle_deg``: between the band and the x axis, folded into 0..90; ``direction``: unit vector along the
    band (as found, not folded); ``centre``: a point of its centre line [m]; ``thickness_m``: full width at
    half maximum of the intensity profile across it; ``contrast``: the peak's rise over the background,
    relative to the background; ``localised``: whether it is a band (else the other numbers describe the
    most band-like feature of a diffuse field); ``profile``: (distance [m], mean intensity, fitted) across
    the band, for plots."""

    angle_deg: float
    direction: tuple[float, float]
    centre: tuple[float, float]
    thickness_m: float
    contrast: float
    localised: bool
    profile: tuple[np.ndarray, np.ndarray, np.ndarray]

    @staticmethod
    def none() -> "Band":
        nan = float("nan")
        empty = np.zeros(0)
        return Band(nan, (nan, nan), (nan, nan), nan, nan, False, (empty, empty, empty))

    def summary(self, prefix: str = "") -> dict:
        """The scalars for a run's summary (their names with ``prefix``, e.g. ``"conjugate_"``)."""
        return {f"{prefix}band_angle_deg": self.angle_deg, f"{prefix}band_thickness_m": self.thickness_m,
                f"{prefix}band_contrast": self.contrast, f"{prefix}localised": bool(self.localised),
                f"{prefix}band_centre_m": [float(c) for c in self.centre]}

    @property
    def rising(self) -> bool:
        """Whether the band's direction rises along x (0 to 90 deg from the x axis; else it falls)."""
        return bool(self.direction[0] * self.direction[1] >= 0.0)


def _strip_means(d: np.ndarray, w: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Centres and mean intensities of the strips of ``width`` along d that hold points."""
    edges = np.arange(d.min(), d.max() + width, width)
    counts = np.histogram(d, bins=edges)[0]
    sums = np.histogram(d, bins=edges, weights=w)[0]
    full = counts > 0
    return 0.5 * (edges[:-1] + edges[1:])[full], sums[full] / counts[full]


def _peak_window(d, w, centres, means, element_size) -> tuple[int, int, int]:
    """(first, peak, last) strip of the band's peak in the profile. The peak is the strip of the largest
    line integral (the band's own strip, which the orientation search found); from it the profile first
    falls below half its height above the lowest strip at a distance a on one side and b on the other; the
    window is the peak +- 3 min(a, b), so that another crest of the profile (the crush at an imperfection, a
    conjugate band) does not pull the fit, while the band's own flanks and the trend around it are in."""
    sums = np.histogram(d, bins=np.arange(d.min(), d.max() + element_size, element_size), weights=w)[0]
    crest = d.min() + (int(np.argmax(sums)) + 0.5) * element_size
    near = np.flatnonzero(np.abs(centres - crest) <= element_size)
    k = int(near[np.argmax(means[near])])
    half = 0.5 * (means[k] + means.min())
    below = np.flatnonzero(means < half)
    left, right = below[below < k], below[below > k]
    reach = min(centres[k] - centres[left[-1]] if left.size else np.inf,
                centres[right[0]] - centres[k] if right.size else np.inf)
    if not np.isfinite(reach):
        return 0, k, len(means) - 1
    inside = np.flatnonzero(np.abs(centres - centres[k]) <= 3.0 * reach)
    return int(inside[0]), k, int(inside[-1])


def _peak_on_background(d_lo: float, d_hi: float):
    """A Gaussian peak on a linear background (the diffuse deformation of the rest of the specimen) over
    the window [d_lo, d_hi], the background given by its values at the window's ends: bounded below by
    0 there, it is nowhere negative in the window (the intensity is not)."""
    span = max(d_hi - d_lo, 1e-300)

    def model(d, b_lo, b_hi, amplitude, offset, s):
        return b_lo + (b_hi - b_lo) * (d - d_lo) / span + amplitude * np.exp(-0.5 * ((d - offset) / s) ** 2)

    return model


def measure_arms(points, intensity, *, element_size: float, exclude: tuple[float, float, float] | None = None,
                 search: tuple[float, float] = (15.0, 80.0)) -> tuple[Band, Band]:
    """The band of each family of orientations (module docstring, section 4): (the stronger, the conjugate
    arm). The stronger is :func:`measure_band` over both families; the conjugate its best in the other."""
    first = measure_band(points, intensity, element_size=element_size, exclude=exclude, search=search)
    if not np.isfinite(first.angle_deg):
        return first, Band.none()
    other = "falling" if first.rising else "rising"
    return first, measure_band(points, intensity, element_size=element_size, exclude=exclude, search=search,
                               family=other)


def measure_band(points, intensity, *, element_size: float, exclude: tuple[float, float, float] | None = None,
                 search: tuple[float, float] = (15.0, 80.0), family: str = "both") -> Band:
    """The band of ``intensity`` (N,) >= 0 at ``points`` (N, 2) [m] (module docstring).

    ``element_size`` [m]: the field's resolution (strip width of the search; half of it for the profile).
    ``exclude`` = (x, y, r): leave out the points within r of (x, y) (an imperfection's own crush).
    ``family``: the orientations searched (:data:`FAMILIES`)."""
    from scipy.optimize import OptimizeWarning, curve_fit

    x = np.asarray(points, dtype=float)[:, :2]
    w = np.asarray(intensity, dtype=float)
    if x.shape[0] != w.shape[0]:
        raise ValueError(f"points ({x.shape[0]}) and intensity ({w.shape[0]}) differ in length")
    if not (np.isfinite(element_size) and element_size > 0):
        raise ValueError(f"element_size = {element_size!r}: must be > 0")
    if family not in FAMILIES:
        raise ValueError(f"family = {family!r}: allowed {list(FAMILIES)}")
    keep = np.isfinite(w)
    if exclude is not None:
        keep &= np.hypot(x[:, 0] - exclude[0], x[:, 1] - exclude[1]) >= exclude[2]
    x, w = x[keep], np.clip(w[keep], 0.0, None)
    if len(w) < 10 or not np.any(w > 0):
        return Band.none()
    c = x.mean(axis=0)
    deg = np.arange(0.0, 180.0, 0.5)
    fold = np.where(deg <= 90.0, deg, 180.0 - deg)

    def score(t, width):  # the largest line integral: the intensity summed in a strip along t
        d = -np.sin(t) * (x[:, 0] - c[0]) + np.cos(t) * (x[:, 1] - c[1])  # signed distance from the line
        return np.histogram(d, bins=np.arange(d.min(), d.max() + width, width), weights=w)[0].max()

    def sharpness(t):  # the highest mean of a half-element strip (strips of at least half the usual points)
        d = -np.sin(t) * (x[:, 0] - c[0]) + np.cos(t) * (x[:, 1] - c[1])
        edges = np.arange(d.min(), d.max() + 0.5 * element_size, 0.5 * element_size)
        counts = np.histogram(d, bins=edges)[0]
        sums = np.histogram(d, bins=edges, weights=w)[0]
        full = counts >= 0.5 * np.median(counts[counts > 0])
        return (sums[full] / counts[full]).max()

    wanted = {"both": np.ones_like(deg, dtype=bool), "rising": deg <= 90.0, "falling": deg >= 90.0}[family]
    coarse = np.radians(deg[(fold >= search[0]) & (fold <= search[1]) & wanted])
    best_t = max(coarse, key=lambda t: score(t, element_size))
    fine = best_t + np.radians(np.arange(-2.0, 2.01, 0.1))  # near it, the orientation the band is sharpest in
    best_t = float(max(fine, key=sharpness) % np.pi)
    normal = np.array([-np.sin(best_t), np.cos(best_t)])
    d = (x - c) @ normal
    centres, means = _strip_means(d, w, 0.5 * element_size)
    lo, k, hi = _peak_window(d, w, centres, means, element_size)
    window = slice(lo, hi + 1)
    d_lo, d_hi = float(centres[lo]), float(centres[hi])
    model = _peak_on_background(d_lo, d_hi)
    guess = (means[lo], means[hi], max(means[k] - min(means[lo], means[hi]), 1e-300),
             float(np.clip(centres[k], d.min(), d.max())), element_size)
    across = float(np.ptp(d))
    try:
        with warnings.catch_warnings():  # the parameters' covariance is not used: no warning when it is singular
            warnings.simplefilter("ignore", OptimizeWarning)
            (b_lo, b_hi, amp, off, s), _ = curve_fit(
                model, centres[window], means[window], p0=guess, maxfev=4000,
                bounds=([0.0, 0.0, 0.0, d.min(), 0.1 * element_size], [np.inf, np.inf, np.inf, d.max(), across]))
    except (RuntimeError, ValueError):  # no peak to fit: a flat profile (or too few strips in the window)
        b_lo = b_hi = float(min(means[lo], means[hi]))
        amp, off, s = 0.0, centres[k], across
    fwhm = 2.0 * np.sqrt(2.0 * np.log(2.0)) * s
    bg_at_peak = float(model(off, b_lo, b_hi, 0.0, off, s))  # the background under the band's centre line
    contrast = amp / max(bg_at_peak, 1e-12 * max(amp, 1e-300))
    localised = bool(contrast >= CONTRAST and fwhm <= MAX_WIDTH_FRACTION * across)
    if not localised:
        fwhm = float("nan")
    angle = float(np.degrees(best_t))
    angle = angle if angle <= 90.0 else 180.0 - angle
    return Band(angle, (float(np.cos(best_t)), float(np.sin(best_t))), tuple(float(v) for v in c + off * normal),
                float(fwhm), float(contrast), localised,
                (centres, means, np.where((centres >= d_lo) & (centres <= d_hi), model(centres, b_lo, b_hi, amp, off, s),
                                          np.nan)))
