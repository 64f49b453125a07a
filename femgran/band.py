"""A shear band measured in a plane field: its inclination, position and thickness, or that there is none.

:func:`measure_band` takes the points of a field (e.g. the Gauss points of a plane-strain run) and a
non-negative intensity at each (e.g. the deviatoric strain increment after the peak) and returns a
:class:`Band`:

1. **Inclination** -- a Radon-type search: for each orientation theta (0.5 deg steps) the intensity is
   summed across a strip about one element wide parallel to theta (line integrals, :func:`_smoothed`);
   the band lies along the orientation of the largest. A band collects its whole length in one strip, so
   an X of two bands is found along one of its arms, not across the patch where they cross (strip means,
   tried first, pick the short strips through that patch: 33 deg instead of 57 on the biaxial runs).
   Orientations within ``search`` of the x axis only (strips along the specimen's faces, which the
   platens and the free sides load, are not bands). The line integrals favour long strips (on a clean
   band at 48 deg through a 50 x 100 mm specimen they still grow at 50 deg, toward the specimen's
   diagonal), so the angle is then refined to that of the band's centre line (:func:`_centre_line`): a
   straight line fitted through the centres of the band's intensity in slices along it.
   Measured on a known band (10 mm at 36-58 deg sampled on the quadrature points, element centres and
   nodes of the biaxial meshes of 36 elements across, elements of aspect 0.70, 1 and 1.43): within
   0.11 deg on the quadrature points and 0.3 deg on the centres and nodes. The earlier search, with hard
   strips starting at the smallest distance and a refinement to the highest strip mean within 2 deg,
   read up to 3.0 deg off on the quadrature points and pulled the centres and nodes to their lattice
   directions (48 deg read 54.9 on elements of aspect 1.43, whose diagonals lie at 55 deg); on the X of
   the CPA gradient runs it read 42-45 deg where the centre line lies at 33.5-38.5 deg (its refinement
   window ended at the line integral's bias).
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
3. **A band or none** -- ``localised`` when (a) the fitted peak rises at least :data:`CONTRAST` times the
   background under its centre line above it, (b) its full width at half maximum is at most
   :data:`MAX_WIDTH_FRACTION` of the specimen's **section** across the band (:func:`_section`: the extent
   of the specimen along the band's normal through its centre; a wider peak is a deforming zone, not a
   band: :func:`too_wide`, :attr:`Band.verdict`), and (c) the largest line integral does not lie on an end
   of the orientations searched (there it grows toward a face of the specimen; the centre-line fit is kept
   within them too).
   Measured on the plane-strain biaxial runs (CPA with softening, rough platens, weak corner, crack band;
   ``tests/femgran/test_band.py``; 60 steps to 5 %): on meshes of 4, 6, 8 and 12 elements across,
   contrasts of 2.4, 2.9, 2.9 and 2.2; homogeneous runs with smooth platens (no imperfection, with and
   without softening): 0.0-0.10. The criterion sits between them, a factor of 2.2 and 10 from each.
   Widths in windows of 0.5 % axial strain after the peak (``femgran band``, 320 steps to 8 %, specimens
   3 W tall; the shear-band study of ``docs/regularisation.md``): the crack band on 18 elements 0.16-0.28
   of the section; the gradient back stress at alpha = 30 and 60 deg, thin rising bands, 0.07-0.26; at
   alpha = 0, 0.39-0.47 while the band forms, then 0.51-0.90 as it widens into a zone; at alpha = 90 deg a
   zone of 0.71-0.85 from the peak on, between the platens' rigid cones. Before (b) compared the width with
   the specimen's whole extent across the band, about twice the section for a specimen 3 W tall, and
   called that zone a band; before (c) the other arm's search at alpha = 90 deg, turned to 89.6 deg by the
   centre-line fit, took a column of elements along the free side (0.7 mm wide, contrast 1e12) for a band.
   A diffuse field or a zone gets no thickness (NaN); :attr:`Band.peak_width_m` keeps the fitted width.
   An X of two conjugate bands is a band: the profile across one of them has its peak, the other crosses
   it as a broad bump that the fit takes as background.
4. **Both arms** -- :func:`measure_arms` measures the band of each family of orientations, rising (the
   band's direction between 0 and 90 deg from the x axis) and falling (90 to 180 deg), the stronger first:
   a diamond or an X of conjugate bands is measured whole. (Measured with the earlier search on the CPA
   gradient runs of the shear-band study, meshes of 24, 27, 36 and 48 elements: a rising arm at 57-58 deg
   on 24 and 27 elements and at 41-43 deg on 36 and 48, the falling arm at 45-46 deg from the x axis on
   all four; with this one on the 36-element runs with elements of aspect 0.70 and 1.43, both arms at
   33.5-38.5 deg.)
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Band", "measure_band", "measure_arms", "band_history", "written_steps", "read_cells",
           "deviatoric_intensity", "interior_shear", "law_band_angles", "too_wide", "is_zone", "FAMILIES", "CONTRAST",
           "MAX_WIDTH_FRACTION"]

#: The families of band orientations :func:`measure_band` searches: both, or the band's direction rising
#: (0 to 90 deg from the x axis) or falling (90 to 180 deg).
FAMILIES = ("both", "rising", "falling")

#: The fitted peak must rise this many times the background above it (section 3 of the module docstring).
CONTRAST = 1.0
#: The orientation of the largest line integral is refined to the band's fitted centre line when that
#: turns it by at most this much [deg] (section 1 of the module docstring). Measured turns: up to 9.1 deg
#: on the arms of the X of the CPA gradient runs (36 and 48 elements), 0.1-2 deg on clean bands.
REFINE_DEG = 15.0
#: ... and be no wider (full width at half maximum) than this fraction of the specimen's section across the
#: band (module docstring, section 3; measured widths: 0.07-0.47 for bands, 0.51-1.2 for zones).
MAX_WIDTH_FRACTION = 0.5


@dataclass(frozen=True)
class Band:
    """A measured band (module docstring).

    ``angle_deg``: between the band and the x axis, folded into 0..90; ``direction``: unit vector along the
    band (as found, not folded); ``centre``: a point of its centre line [m]; ``thickness_m``: full width at
    half maximum of the intensity profile across it; ``contrast``: the peak's rise over the background,
    relative to the background; ``localised``: whether it is a band (else the other numbers describe the
    most band-like feature of a diffuse field); ``profile``: (distance [m], mean intensity, fitted) across
    the band, for plots; ``angle_method``: ``"centre line"`` when the angle is that of the fitted centre
    line (module docstring, section 1), else it says why not: ``"line integral (...)"`` when the fit was
    not taken -- a zone too broad for three full slices, a fit that lost its full slices after a turn, or
    one turning more than :data:`REFINE_DEG`, which follows another feature, or one leaving the orientations
    searched; or the largest line integral on an end of those orientations -- and the angle is the 0.5 deg
    search's, with its pull toward long strips; ``"none"`` for :meth:`none`. ``section_m``: the specimen's
    section across the band through its centre; ``peak_width_m``: the fitted peak's full width at half
    maximum, kept when it is no band (a zone wider than :data:`MAX_WIDTH_FRACTION` of the section, or a
    diffuse field)."""

    angle_deg: float
    direction: tuple[float, float]
    centre: tuple[float, float]
    thickness_m: float
    contrast: float
    localised: bool
    profile: tuple[np.ndarray, np.ndarray, np.ndarray]
    angle_method: str = "centre line"
    section_m: float = float("nan")
    peak_width_m: float = float("nan")

    @staticmethod
    def none() -> "Band":
        nan = float("nan")
        empty = np.zeros(0)
        return Band(nan, (nan, nan), (nan, nan), nan, nan, False, (empty, empty, empty), "none", nan, nan)

    def summary(self, prefix: str = "") -> dict:
        """The scalars for a run's summary (their names with ``prefix``, e.g. ``"conjugate_"``)."""
        return {f"{prefix}band_angle_deg": self.angle_deg, f"{prefix}band_thickness_m": self.thickness_m,
                f"{prefix}band_contrast": self.contrast, f"{prefix}localised": bool(self.localised),
                f"{prefix}band_centre_m": [float(c) for c in self.centre],
                f"{prefix}band_angle_method": self.angle_method,
                f"{prefix}band_peak_width_m": self.peak_width_m, f"{prefix}band_section_m": self.section_m}

    @property
    def verdict(self) -> str:
        """Why this is a band or not, in a few words: ``"band"``, ``"none"`` (no intensity), ``"toward a
        face"`` (the largest line integral on an end of the orientations searched), ``"diffuse"`` (contrast
        below :data:`CONTRAST`) or ``"zone"`` (a peak wider than :data:`MAX_WIDTH_FRACTION` of the
        specimen's section across it: a deforming zone, not a band)."""
        if self.localised:
            return "band"
        if self.angle_method == "none":
            return "none"
        if self.angle_method.startswith("line integral (largest on an end"):
            return "toward a face"
        return "zone" if is_zone(self.contrast, self.peak_width_m, self.section_m) else "diffuse"

    @property
    def from_line_integral(self) -> bool:
        """Whether the angle is the 0.5 deg search's, the centre-line fit not taken (:attr:`angle_method`)."""
        return self.angle_method.startswith("line integral")

    def height_at(self, x: float) -> float:
        """The height y [m] at which the band's centre line passes the abscissa ``x`` [m], e.g. where the band
        meets a side of the specimen (NaN for a vertical band or :meth:`none`). A height outside the specimen
        means the band leaves it through a platen instead."""
        dx, dy = self.direction
        if not (np.isfinite(dx) and abs(dx) > 1e-12):
            return float("nan")
        return float(self.centre[1] + (float(x) - self.centre[0]) * dy / dx)

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


def _smoothed(d: np.ndarray, w: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """The weights ``w`` of points at distances ``d`` summed across a strip of about ``width``: on a grid
    of width / 8, sum_i w_i exp(-(g - d_i)^2 / (2 s^2)) with s = width / sqrt(2 pi) (the Gaussian's area is
    that of a strip of ``width``). Returns (grid, sums).

    Why not strips: a histogram's strips start at the smallest distance, which moves with the orientation,
    so a band's line integral rose and fell with how its centre line met the strips' edges, and the
    orientation search picked up lattice directions of the points: a clean band at 40 deg sampled at the
    quadrature points of 36 square elements across read 43.0 deg, bands at 36-40 deg on elements 1.43
    times as tall read 1.5-2 deg steep. The points are linearly binned on the fine grid (each between its two nearest nodes),
    then convolved, so the sums move continuously with the orientation."""
    s = width / np.sqrt(2.0 * np.pi)
    step = width / 8.0
    reach = int(np.ceil(4.0 * s / step))
    origin = d.min() - (reach + 1) * step
    u = (d - origin) / step
    i = np.floor(u).astype(np.int64)
    f = u - i
    n = int(i.max()) + reach + 3
    binned = np.bincount(i, w * (1.0 - f), minlength=n) + np.bincount(i + 1, w * f, minlength=n)
    kernel = np.exp(-0.5 * (np.arange(-reach, reach + 1) * step / s) ** 2)
    return origin + step * np.arange(n), np.convolve(binned, kernel, mode="same")


def _centre_line(x, w, t: float, c, element_size: float, reach_deg: float) -> tuple[float, str]:
    """The orientation of the band's centre line, from the orientation t of its largest line integral
    (module docstring, section 1): across slices two elements long along the band, the centres of the
    intensity above the band's half height within its half width (slices that the specimen's edge cuts
    lopsided left out), and the straight line fitted through them (weighted by each slice's intensity)
    turns t; repeated until it turns by less than 0.01 deg. A slice is kept when its halves on either side
    of the crest hold point counts within a factor 0.75: with every slice kept, the known band of
    ``tests/femgran/test_band.py`` read 0.4-1.0 deg steep on every mesh, with this rule 0.11 deg at worst.
    A turn of more than ``reach_deg`` in all leaves t (the line would belong to another feature), and so
    does a fit that loses its full slices after a turn: it wanders with the slices it keeps (measured on
    the diffuse X of the reduced figure set's alpha = 90 deg run, 6 elements across: from 52 deg it turned
    to 42.9 and lost its slices; from 47 deg it turned by -7.6 and then -10.6; the 42.9 deg was once
    reported as the band's angle). A fit that still turns after 20 fits keeps its last angle: measured on
    the known band of 40 deg sampled at the element centres of elements of aspect 0.70, it converged to a
    cycle of turns of +-0.012 deg as a slice left and rejoined the fit, 0.18 deg from the band where the
    line integral is 2.5 deg off.
    Returns the orientation and how it was found (:attr:`Band.angle_method`)."""
    t0, tol = t, np.radians(0.01)
    for _ in range(20):
        along, normal = np.array([np.cos(t), np.sin(t)]), np.array([-np.sin(t), np.cos(t)])
        d, s = (x - c) @ normal, (x - c) @ along
        grid, sums = _smoothed(d, w, element_size)
        centres, means = _strip_means(d, w, 0.5 * element_size)
        k = _crest_strip(float(grid[np.argmax(sums)]), centres, means, element_size)
        half, reach = _half_height(centres, means, k)
        inside = np.abs(d - centres[k]) <= max(min(reach, 3.0 * element_size), element_size)
        excess = np.clip(w[inside] - half, 0.0, None)
        piece = ((s[inside] - s[inside].min()) // (2.0 * element_size)).astype(np.int64)
        mass = np.bincount(piece, excess)
        side = d[inside] > centres[k]  # a slice the specimen's edge cuts across the band is lopsided: left out
        above, below = np.bincount(piece, side, len(mass)), np.bincount(piece, ~side, len(mass))
        full = (mass > 0) & (np.minimum(above, below) >= 0.75 * np.maximum(above, below))
        if full.sum() < 3:  # an unfinished fit is no centre line: its last turn is not known to be the band's
            how = ("line integral (the centre line lost its full slices, fewer than 3, after a turn of "
                   f"{np.degrees(t - t0):+.1f} deg)" if t != t0 else
                   "line integral (fewer than 3 full slices for a centre line)")
            return t0, how
        s_mid = np.bincount(piece, excess * s[inside])[full] / mass[full]
        d_mid = np.bincount(piece, excess * d[inside])[full] / mass[full]
        turn = float(np.arctan(np.polyfit(s_mid, d_mid, 1, w=np.sqrt(mass[full]))[0]))
        t += turn
        if abs(t - t0) > np.radians(reach_deg):
            return t0, (f"line integral (the centre line turned more than {reach_deg:g} deg from it: "
                        f"{np.degrees(t - t0):+.1f})")
        if abs(turn) < tol:
            return t, "centre line"
    return t, f"centre line (not converged: its last turn {np.degrees(turn):+.3f} deg after 20 fits)"


def _crest_strip(crest: float, centres, means, element_size: float) -> int:
    """The strip of highest mean within an element of the distance ``crest``."""
    near = np.flatnonzero(np.abs(centres - crest) <= element_size)
    return int(near[np.argmax(means[near])])


def _half_height(centres, means, k: int) -> tuple[float, float]:
    """(half height, reach): half the height of strip k above the lowest strip, and the distance from k at
    which the profile first falls below it on the nearer side (inf when it does not on either)."""
    half = 0.5 * (means[k] + means.min())
    below = np.flatnonzero(means < half)
    left, right = below[below < k], below[below > k]
    reach = min(centres[k] - centres[left[-1]] if left.size else np.inf,
                centres[right[0]] - centres[k] if right.size else np.inf)
    return float(half), float(reach)


def _peak_window(crest, centres, means, element_size) -> tuple[int, int, int]:
    """(first, peak, last) strip of the band's peak in the profile. The peak is the strip of highest mean
    within an element of ``crest``, the distance of the largest line integral (the band's own line, which
    the orientation search found); from it the profile first falls below half its height above the lowest
    strip at a distance a on one side and b on the other (:func:`_half_height`); the window is the peak
    +- 3 min(a, b), so that another crest of the profile (the crush at an imperfection, a
    conjugate band) does not pull the fit, while the band's own flanks and the trend around it are in."""
    k = _crest_strip(crest, centres, means, element_size)
    _, reach = _half_height(centres, means, k)
    if not np.isfinite(reach):
        return 0, k, len(means) - 1
    inside = np.flatnonzero(np.abs(centres - centres[k]) <= 3.0 * reach)
    return int(inside[0]), k, int(inside[-1])


def too_wide(peak_width: float, section: float) -> bool:
    """Whether a peak of full width at half maximum ``peak_width`` is too wide to be a band in a section of
    ``section`` across it (:data:`MAX_WIDTH_FRACTION`; module docstring, section 3)."""
    return bool(peak_width > MAX_WIDTH_FRACTION * section)


def is_zone(contrast: float, peak_width: float, section: float) -> bool:
    """Whether a fitted peak is a deforming zone (:attr:`Band.verdict` ``"zone"``): it rises above its
    background (``contrast`` >= :data:`CONTRAST`) but is :func:`too_wide` for its ``section``. Takes the
    numbers a run's summary or ``band_history.csv`` keeps."""
    return bool(contrast >= CONTRAST and too_wide(peak_width, section))


def _section(x, centre, t: float, element_size: float) -> float:
    """The specimen's section across the band: the extent, along the band's normal, of the points within
    half an element of the normal through the band's ``centre`` (``t``: the band's orientation), plus one
    element, since the points sit inside the boundary (element centres half an element, the 2 x 2 Gauss
    points of a quadrilateral 0.21 of one)."""
    along, normal = np.array([np.cos(t), np.sin(t)]), np.array([-np.sin(t), np.cos(t)])
    near = np.abs((x - centre) @ along) <= 0.5 * element_size
    if near.sum() < 2:
        return float(np.ptp(x @ normal)) + element_size
    return float(np.ptp(x[near] @ normal)) + element_size


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

    def distance(t):  # signed distance of the points from the line through c along t
        return -np.sin(t) * (x[:, 0] - c[0]) + np.cos(t) * (x[:, 1] - c[1])

    def score(t):  # the largest line integral: the intensity summed across a strip about one element wide
        return _smoothed(distance(t), w, element_size)[1].max()

    wanted = {"both": np.ones_like(deg, dtype=bool), "rising": deg <= 90.0, "falling": deg >= 90.0}[family]
    coarse = np.radians(deg[(fold >= search[0]) & (fold <= search[1]) & wanted])
    scores = np.array([score(t) for t in coarse])
    best = int(np.argmax(scores))
    best_t = line_t = coarse[best]
    # the largest line integral on an end of the range searched (the family's ends, not where "both" wraps
    # round through 90 deg): it grows toward a face of the specimen, along which no band is measured
    ends = np.flatnonzero(np.abs(np.diff(coarse)) > np.radians(0.75))
    at_end = best in (0, len(coarse) - 1) or best in ends or best in ends + 1
    best_t, method = _centre_line(x, w, best_t, c, element_size, REFINE_DEG)
    best_t = float(best_t % np.pi)
    folded = min(np.degrees(best_t), 180.0 - np.degrees(best_t))
    if not search[0] <= folded <= search[1]:  # the fit left the orientations searched: a face, not a band
        best_t, method = float(line_t), (f"line integral (the centre line turned to {folded:.1f} deg, outside "
                                         f"the search's {search[0]:g}-{search[1]:g} deg)")
    normal = np.array([-np.sin(best_t), np.cos(best_t)])
    d = (x - c) @ normal
    centres, means = _strip_means(d, w, 0.5 * element_size)
    grid, sums = _smoothed(d, w, element_size)
    lo, k, hi = _peak_window(float(grid[np.argmax(sums)]), centres, means, element_size)
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
    section = _section(x, c + off * normal, best_t, element_size)
    localised = bool(contrast >= CONTRAST and not too_wide(fwhm, section) and not at_end)
    if at_end:
        method = (f"line integral (largest on an end of the orientations searched, {search[0]:g}-{search[1]:g} deg "
                  "from the x axis: it grows toward a face)")
    peak_width = float(fwhm)
    if not localised:
        fwhm = float("nan")
    angle = float(np.degrees(best_t))
    angle = angle if angle <= 90.0 else 180.0 - angle
    return Band(angle, (float(np.cos(best_t)), float(np.sin(best_t))), tuple(float(v) for v in c + off * normal),
                float(fwhm), float(contrast), localised,
                (centres, means, np.where((centres >= d_lo) & (centres <= d_hi), model(centres, b_lo, b_hi, amp, off, s),
                                          np.nan)), method, section, peak_width)


def band_history(run_folder, window: float = 0.005, *, name: str = "biaxial", law: bool = False):
    """The band active in each window of axial strain after the peak, from a run folder's VTK series.

    The summary's band is that of the whole post-peak strain increment; a band that forms, narrows or hands
    over to another one shows only here. Each window starts where the last ended, the first at the first
    written step within 1 % of the peak deviator (as the summary's band does), and spans ``window`` of axial
    strain (to the nearest written step; the last window is what remains when that is half a window or more,
and a window longer than the whole post-peak path is that path). In each, the intensity is the deviatoric strain increment of the
    element averages (the VTK cell field ``strain``) and both arms are measured (:func:`measure_arms`).

    Returns a :class:`material.table.Table`, one row per window: ``eps_from``, ``eps_to``, ``q_from_kPa``,
    ``q_to_kPa``, and for the stronger arm and the other one (``conjugate_``) ``angle_deg``, ``thickness_m``,
    ``contrast``, ``localised`` (1 / 0), ``rising`` (1 / 0), ``peak_width_m`` and ``section_m`` (:class:`Band`),
    the centre line's point ``centre_x_m``, ``centre_y_m`` and the heights ``left_y_m``, ``right_y_m`` at which it
    meets the specimen's left and right sides (:meth:`Band.height_at` at the extreme abscissae of the cells'
    corners: a height below 0 or above the specimen's top means the arm runs into a platen), and the
    mobilised friction and the dilatancy inside the arm, ``friction_deg`` (the stress at the window's end;
    NaN for a series without the cell field ``stress``) and ``dilatancy_deg`` (the strain increment over the
    window), of :func:`in_band_state`: the arm's own
    Coulomb (45 + phi / 2) and Roscoe (45 + psi / 2) angles as it runs, where the run's peak gives them once.
    ``interior_shear``: the shear strain increment inside the arm away from the other (:func:`interior_shear`).
    ``law=True`` adds ``law_angle_deg`` and ``law_indicator`` (and ``conjugate_``): the band the law itself forms
    at the friction inside each arm, in the arm's sense, on the element sheared as the inside of the arm is
    (:func:`law_band_angles`, the run's material from its ``case.toml``, :func:`run_material`; a biaxial run
    only), and ``law_other_angle_deg``, ``law_other_indicator`` on the element sheared the other way (the
    two differ only on a mirror-symmetric bedding).
    ``femgran band RUN_FOLDER [--law]`` writes it as ``band_history.csv``.
    """
    from material.table import Table

    w = float(window)
    if not (np.isfinite(w) and w > 0.0):
        raise ValueError(f"window = {window!r}: must be an axial strain > 0 (e.g. 0.005)")
    folder = Path(run_folder)
    w_eps, w_q, paths, start = written_steps(folder, name)
    of_law = run_material(folder) if law else None  # before the windows: a folder without it fails at once
    cache = {}
    sides = [0.0, 0.0]  # the abscissae of the specimen's left and right sides [m], from the cells read

    def cells(i):
        if i not in cache:
            corners, (strain, stress) = read_cell_fields(paths[i], ("strain",), optional=("stress",))
            cache.clear()  # windows are consecutive: keep the last step only
            cache[i] = (corners.mean(axis=1), strain, float(np.ptp(corners, axis=1).max()), stress)
            sides[:] = float(corners[..., 0].min()), float(corners[..., 0].max())
        return cache[i]

    table = Table(metadata={"run_folder": folder.name, "window": w, "intensity":
                            "deviatoric strain increment over the window, VTK element averages"})
    i0 = start
    while True:
        target = w_eps[i0] + w
        if target > w_eps[-1] + 0.5 * w and len(table):  # less than half a window left
            break
        i1 = int(np.argmin(np.abs(w_eps - min(target, w_eps[-1]))))
        if i1 <= i0:
            break
        x, e0, _, _ = cells(i0)
        _, e1, size, stress = cells(i1)
        band, other = measure_arms(x, deviatoric_intensity(e1 - e0), element_size=size)
        row = {"eps_from": w_eps[i0], "eps_to": w_eps[i1], "q_from_kPa": w_q[i0], "q_to_kPa": w_q[i1]}
        for prefix, b, o in (("", band, other), ("conjugate_", other, band)):
            friction, dilatancy, _ = in_band_state(x, b, stress, e1 - e0, tuple(sides))
            row.update({f"{prefix}friction_deg": friction, f"{prefix}dilatancy_deg": dilatancy,
                        f"{prefix}interior_shear": interior_shear(x, b, o, e1 - e0)})
            row.update({f"{prefix}angle_deg": b.angle_deg, f"{prefix}thickness_m": b.thickness_m,
                        f"{prefix}contrast": b.contrast, f"{prefix}localised": float(b.localised),
                        f"{prefix}rising": float(b.rising), f"{prefix}peak_width_m": b.peak_width_m,
                        f"{prefix}section_m": b.section_m, f"{prefix}centre_x_m": float(b.centre[0]),
                        f"{prefix}centre_y_m": float(b.centre[1]), f"{prefix}left_y_m": b.height_at(sides[0]),
                        f"{prefix}right_y_m": b.height_at(sides[1])})
        table.append(row)
        i0 = i1
    if of_law is not None and len(table):
        law_path = _law_path(*of_law, axial_strain=0.08, steps=1600)
        for prefix in ("", "conjugate_"):
            arms = (table[f"{prefix}friction_deg"], table[f"{prefix}rising"] > 0.5)
            for tag, shear, sheared in (("", table[f"{prefix}interior_shear"], "as the inside of the arm"),
                                        ("other_", -table[f"{prefix}interior_shear"], "the other way")):
                angle, indicator = _read_law(law_path, *arms, shear)
                table.add_column(f"{prefix}law_{tag}angle_deg", angle,
                                 "the band of the law at the friction inside the arm, in its sense, on the element "
                                 f"sheared {sheared} (Rice's condition, femgran.band.law_band_angles) [deg]")
                table.add_column(f"{prefix}law_{tag}indicator", indicator,
                                 "Rice's indicator of that family there (about 0: a band forms; near -1: no band "
                                 "to compare with) [-]")
    return table


def written_steps(run_folder, name: str = "biaxial"):
    """The steps of a run folder's VTK series ``NAME.pvd`` matched to its ``history.csv``: (axial strain (K,),
    q [kPa] (K,), the VTU paths (K,), the index of the first written step within 1 % of the peak deviator
    (where :func:`band_history` and the summary's band start)). A missing file, a history without
    ``load_factor`` / ``eps_a`` / ``q_kPa`` or fewer than two written steps raise an error naming the folder."""
    from femgran.output import read_pvd
    from material.table import read_table

    folder = Path(run_folder)
    pvd, hist_path = folder / f"{name}.pvd", folder / "history.csv"
    for path in (pvd, hist_path):
        if not path.is_file():
            raise FileNotFoundError(f"run_folder = {str(folder)!r}: no {path.name} (a run folder of a case with "
                                    f"VTK output, name {name!r}, is needed)")
    hist = read_table(hist_path)
    for col in ("load_factor", "eps_a", "q_kPa"):
        if col not in hist:
            raise ValueError(f"run_folder = {str(folder)!r}: its history has no column {col!r} (a biaxial or "
                             f"triaxial run is needed)")
    t, eps, q = hist["load_factor"], hist["eps_a"], hist["q_kPa"]
    written = []  # (history row, vtu file) of each written step
    for step_t, path in read_pvd(pvd):
        rows = np.flatnonzero(np.isclose(t, step_t, rtol=0.0, atol=1e-9 * max(1.0, abs(step_t))))
        if rows.size:
            written.append((int(rows[-1]), path))
    if len(written) < 2:
        raise ValueError(f"run_folder = {str(folder)!r}: fewer than two written steps")
    w_rows = np.array([r for r, _ in written])
    w_eps, w_q = eps[w_rows], q[w_rows]
    start = int(np.flatnonzero(w_q >= 0.99 * np.nanmax(q))[0])
    return w_eps, w_q, [path for _, path in written], start


def read_cells(vtu_path):
    """(the corners' in-plane coordinates (n_cells, n_corners, 2), the cell strain (n_cells, 3, 3)) of one
    VTU file of a plane run (its cell field ``strain``, element averages)."""
    corners, (strain,) = read_cell_fields(vtu_path, ("strain",))
    return corners, strain


def read_cell_fields(vtu_path, names=("strain", "stress"), optional=()):
    """(the corners' in-plane coordinates (n_cells, n_corners, 2), [each cell tensor field of ``names``, then
    of ``optional``, (n_cells, 3, 3)]) of one VTU file of a plane run (element averages). A missing field of
    ``names`` raises an error naming the file and the fields it has; a missing one of ``optional`` is None."""
    import meshio

    m = meshio.read(vtu_path)
    missing = [n for n in names if n not in m.cell_data]
    if missing:
        raise ValueError(f"{vtu_path}: no cell field(s) {missing}; it has {sorted(m.cell_data)}")
    corners = m.points[m.cells[0].data][:, :, :2]
    return corners, [np.asarray(m.cell_data[n][0], dtype=float).reshape(-1, 3, 3) if n in m.cell_data else None
                     for n in (*names, *optional)]


def mobilised_angles(sigma_1: float, sigma_3: float, d_eps_1: float, d_eps_3: float) -> tuple[float, float]:
    """(friction, dilatancy) [deg] of a plane state, geotechnical convention (compression positive):
    sin(phi) = (sigma_1 - sigma_3) / (sigma_1 + sigma_3) from the major and minor principal stresses, and
    sin(psi) = -(d_eps_1 + d_eps_3) / (d_eps_1 - d_eps_3) from the principal strain increments along them
    (dilation makes psi positive). NaN where a ratio is undefined (sigma_1 + sigma_3 <= 0, d_eps_1 = d_eps_3)."""
    nan = float("nan")
    phi = float(np.degrees(np.arcsin(np.clip((sigma_1 - sigma_3) / (sigma_1 + sigma_3), -1, 1)))) \
        if sigma_1 + sigma_3 > 0.0 else nan
    psi = float(np.degrees(np.arcsin(np.clip(-(d_eps_1 + d_eps_3) / (d_eps_1 - d_eps_3), -1, 1)))) \
        if d_eps_1 != d_eps_3 else nan
    return phi, psi


def in_band_state(centres, band: "Band", stress, d_strain, sides: tuple[float, float]) -> tuple[float, float, int]:
    """The mobilised friction and the dilatancy inside a band: (friction [deg], dilatancy [deg], cells).

    The cells whose centre lies within half the band's thickness of its centre line and in the middle half
    of the specimen's width (``sides``: the abscissae of its left and right faces), away from a trigger on
    a face and from the faces themselves. The friction from their mean stress (in the plane) and the
    dilatancy from their mean strain increment ``d_strain`` over the window (the elastic part included), by
    :func:`mobilised_angles` (``stress`` and ``d_strain`` tension positive, as the VTK fields). NaN and 0
    cells where the band is :meth:`Band.none` or no cell qualifies; the friction NaN where ``stress`` is None
    (a series written without it)."""
    nan = float("nan")
    if not np.isfinite(band.thickness_m):
        return nan, nan, 0
    c = np.asarray(centres, dtype=float)
    d = np.asarray(band.direction, dtype=float)
    across = (c - np.asarray(band.centre)) @ np.array([-d[1], d[0]])
    x0, x1 = sides
    sel = (np.abs(across) <= 0.5 * band.thickness_m) & (np.abs(c[:, 0] - 0.5 * (x0 + x1)) <= 0.25 * (x1 - x0))
    if not sel.any():
        return nan, nan, 0
    d1, d3 = np.linalg.eigvalsh(np.asarray(d_strain)[sel][:, :2, :2].mean(axis=0))  # d1: most compressive
    s1, s3 = np.linalg.eigvalsh(np.asarray(stress)[sel][:, :2, :2].mean(axis=0)) if stress is not None else (nan, nan)
    friction, dilatancy = mobilised_angles(-s1, -s3, -d1, -d3)
    return friction, dilatancy, int(sel.sum())


def interior_shear(centres, band: "Band", other: "Band", d_strain) -> float:
    """The mean shear strain increment d eps_xy inside a band, away from the other arm of its X: the cells
    whose centre lies within half the band's thickness of its centre line and not within half the other
    arm's of the other's (where both arms shear the cells are neither's), over the whole specimen
    (``d_strain`` tension positive, x to the right, y up). NaN where the band is :meth:`Band.none` or no cell
    qualifies.

    Its sign is the sense in which the inside of the band shears, which is not the band's own: a jump of
    slip c at the dilatancy angle psi across a band at theta from x makes d eps_xy = -c cos(2 theta - psi) / 2
    inside it, so a rising band steeper than 45 + psi / 2 (its Roscoe angle) shears its inside positively,
    a flatter one negatively (:func:`law_band_angles` reads the law's band on an element sheared that way)."""
    if not np.isfinite(band.thickness_m):
        return float("nan")
    c = np.asarray(centres, dtype=float)
    d = np.asarray(band.direction, dtype=float)
    across = (c - np.asarray(band.centre)) @ np.array([-d[1], d[0]])
    sel = np.abs(across) <= 0.5 * band.thickness_m
    if np.isfinite(other.thickness_m):
        e = np.asarray(other.direction, dtype=float)
        sel &= np.abs((c - np.asarray(other.centre)) @ np.array([-e[1], e[0]])) > 0.5 * other.thickness_m
    return float(np.asarray(d_strain)[sel][:, 0, 1].mean()) if sel.any() else float("nan")


def deviatoric_intensity(d_strain) -> np.ndarray:
    """sqrt(2 e : e) of the deviatoric part e of strain increments (N, 3, 3): the band's intensity."""
    d = np.asarray(d_strain, dtype=float)
    dev = d - np.trace(d, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
    return np.sqrt(2.0 * np.einsum("nij,nij->n", dev, dev))


def law_band_angles(material, alpha_deg: float, p0_kPa: float, friction_deg, rising, *, interior_shear=None,
                    axial_strain: float = 0.08, steps: int = 1600) -> tuple[np.ndarray, np.ndarray]:
    """The band the law itself would form at a given mobilised friction after the peak: Rice's condition on
    the plane-strain element path of the same material (:func:`material.driver.plane_strain`, the lateral
    stress ``p0_kPa`` held, the deposition angle ``alpha_deg``), read at the first row past the peak whose
    mobilised friction, sin(phi) = q13 / (q13 + 2 p0), has fallen to ``friction_deg``, in the family of each
    ``rising`` (True: the driver's ``rice_rising_deg``, bands rising toward +x, as a biaxial run's rising arm;
    False: ``rice_falling_deg``). A friction at or above the path's peak reads the peak row; one the path
    never falls to, or a NaN, gives NaN. Returns (angles [deg], the family's indicator there): the scale-free
    least det Q of :func:`material.localisation.ellipticity`, about 0 where a band forms; near -1 the acoustic
    tensor is far from singular in the other sense (strongly indefinite: measured on the element path at
    alpha = 90 with ``equator-78`` and at alpha = 0 with the default rule, just past the peak) and the
    direction of its least det is no band to compare with.

    ``interior_shear`` (one per friction, or one for all) is the shear strain inside each arm, or its sign
    (d eps_xy, tension positive, x to the right, y up: :func:`interior_shear`). Where the bedding is
    mirror-symmetric (alpha = 0 or 90 deg) the element shears after the peak, in a sense its loading does not
    set (the driver's docstring); the family of bands in the sense of its shear keeps its angle, the other
    turns. Each arm is then read on the element sheared as the inside of the arm is (the path, or its mirror
    image, which exchanges the rising and the falling family). None: as the inside of a band steeper than its
    Roscoe angle shears (positive for a rising band, negative for a falling one). On a bedding that is not
    mirror-symmetric it changes nothing.

    This is how to tell a band the law selects from one the boundary-value problem adds: the arms of the
    biaxial runs with ``equator-78`` follow it within about 1 deg as they soften, at the friction measured
    inside them (:func:`band_history`; ``docs/regularisation.md``, section 4). ``material`` is a material
    specification as a case file writes it (preset, set, rule, stabilisation, ...); its lengths (gradient,
    crack band, back stress) are dropped, its step stabilisation is kept (the runs' algorithmic tangent).
    The path runs ``steps`` steps to ``axial_strain`` (0.005 % each by default: the angles are those of 1600
    steps to 0.25 deg)."""
    shape = np.atleast_1d(np.asarray(friction_deg, dtype=float)).shape  # the inputs checked before the path runs
    _per_friction("rising", rising, shape, bool)
    if interior_shear is not None:
        _per_friction("interior_shear", interior_shear, shape, float)
    return _read_law(_law_path(material, alpha_deg, p0_kPa, axial_strain, steps), friction_deg, rising, interior_shear)


def _law_path(material, alpha_deg, p0_kPa, axial_strain, steps):
    """The element path of :func:`law_band_angles`: (its result, the mobilised friction [deg] per row, its peak
    row, the sense of its shear where the path on a mirror-symmetric bedding shears (the driver's
    ``metadata["shear_onset"]``), else 0: a path with no mirror image to read, or one that keeps its
    symmetry, whose two families are one)."""
    from material import driver
    from material.factory import LENGTH_KEYS, make_material

    if not isinstance(material, Mapping):
        raise ValueError(f"material = {material!r}: a specification mapping is needed (a case file's [material])")
    p0 = float(p0_kPa)
    if not (np.isfinite(p0) and p0 > 0.0):
        raise ValueError(f"p0_kPa = {p0_kPa!r}: must be > 0 (the lateral stress of the biaxial run)")
    alpha = float(alpha_deg)
    spec = {k: v for k, v in dict(material).items() if k not in LENGTH_KEYS}
    res = driver.plane_strain(make_material(spec, alpha_deg=alpha), p0_kPa=p0, alpha_deg=alpha,
                              axial_strain=axial_strain, steps=steps)
    q = np.asarray(res["q13_kPa"], dtype=float)
    peak = int(np.nanargmax(q))
    with np.errstate(invalid="ignore"):
        mobilised = np.degrees(np.arcsin(np.clip(q / (q + 2.0 * p0), -1.0, 1.0)))
    branch = res.metadata["shear_onset"]  # where a mirror-symmetric path shears, and in which sense
    return res, mobilised, peak, 0.0 if branch is None else branch["sense"]


def _read_law(path, friction_deg, rising, interior_shear=None):
    """(angles, indicators) of :func:`law_band_angles` on its path: each arm in its own family, on the path
    where the path shears as the arm's inside does (or where the path has no mirror image), else in the
    other family, which is the arm's own on the mirror image of the path."""
    res, mobilised, peak, sense = path
    friction = np.atleast_1d(np.asarray(friction_deg, dtype=float))
    arms = _per_friction("rising", rising, friction.shape, bool)
    inside = np.where(arms, 1.0, -1.0) if interior_shear is None else \
        _per_friction("interior_shear", interior_shear, friction.shape, float)
    angle, indicator = np.full(friction.shape, np.nan), np.full(friction.shape, np.nan)
    after = np.arange(len(mobilised)) >= peak
    for k, (phi, up, shear) in enumerate(zip(friction, arms, inside)):
        if not (np.isfinite(phi) and np.isfinite(shear)):
            continue
        rows = np.flatnonzero(after & (mobilised <= phi)) if phi < mobilised[peak] else np.array([peak])
        if rows.size:
            if sense * shear < 0.0:  # the arm's family on the mirror image: the other family here
                up = not up
            family = "rice_rising_" if up else "rice_falling_"
            angle[k], indicator[k] = res[family + "deg"][rows[0]], res[family + "indicator"][rows[0]]
    return angle, indicator


def _per_friction(key: str, value, shape, dtype) -> np.ndarray:
    """``value`` as one entry per friction: one value for all, or an array of the frictions' shape."""
    v = np.asarray(value, dtype=dtype)
    if v.size == 1:
        return np.full(shape, v.reshape(-1)[0], dtype=dtype)
    if v.shape != shape:
        raise ValueError(f"{key}: shape {v.shape}; allowed one value or one per friction, {shape}")
    return v


def run_material(run_folder) -> tuple[dict, float, float]:
    """(the material specification, alpha_deg, p0_kPa) of a biaxial run folder, from its ``case.toml``; an
    error naming the folder where the file, the case or the material is not there (a run given a material
    object has no specification on disk)."""
    import tomllib

    path = Path(run_folder) / "case.toml"
    if not path.is_file():
        raise FileNotFoundError(f"run_folder = {str(run_folder)!r}: no case.toml (the law's band needs the run's "
                                f"material as a case file writes it)")
    doc = tomllib.loads(path.read_text())
    case, material = doc.get("case", {}), doc.get("material")
    if case.get("name") != "biaxial" or not isinstance(material, dict):
        raise ValueError(f"run_folder = {str(run_folder)!r}: the law's band needs a biaxial run with a material "
                         f"specification in case.toml (found case {case.get('name')!r}, material "
                         f"{'a specification' if isinstance(material, dict) else 'none'})")
    missing = [key for key in ("alpha_deg", "p0_kPa") if key not in case]
    if missing:
        raise ValueError(f"run_folder = {str(run_folder)!r}: its case.toml has no {missing} under [case]")
    return material, float(case["alpha_deg"]), float(case["p0_kPa"])
