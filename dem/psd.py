"""Particle-size distribution: the mass-based sieve curve, its number-based form, and sampling.

Appendix A: a sieve curve gives the mass fraction per grading segment [D_i, D_i+1]; a DEM sample
needs the number fraction. With disks of equal density (2D, unit thickness) a particle's mass is
proportional to d^2, and with diameters uniform inside each segment the mean of d^2 over the segment
is (D_i^2 + D_i D_i+1 + D_i+1^2) / 3, so the number fraction of segment i is proportional to
dP_i / <d^2>_i. Diameters are drawn by inverse-transform sampling (A.3) of this piecewise-linear
number CDF.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

PRESETS = {"ottawa_c109": "ottawa_c109_psd.csv"}


class PSD:
    """A sieve curve (diameters [m], mass fraction finer [0..1]) with its number-based CDF."""

    def __init__(self, diameters_m, mass_finer, name: str = "psd"):
        d = np.asarray(diameters_m, float)
        p = np.asarray(mass_finer, float)
        if d.ndim != 1 or d.shape != p.shape or len(d) < 2:
            raise ValueError(f"PSD {name!r}: need two equal-length columns with at least 2 points")
        if not (np.all(np.isfinite(d)) and np.all(d > 0) and np.all(np.diff(d) > 0)):
            raise ValueError(f"PSD {name!r}: diameters must be positive and strictly increasing, got {d.tolist()}")
        if not (np.all(np.diff(p) >= 0)):
            raise ValueError(f"PSD {name!r}: percent finer must be non-decreasing (monotone), got {(100 * p).tolist()}")
        if not (abs(p[0]) < 1e-12 and abs(p[-1] - 1.0) < 1e-9):
            raise ValueError(f"PSD {name!r}: percent finer must start at 0 and end at 100, got {100 * p[0]:g} .. {100 * p[-1]:g}")
        self.name = name
        self.diameters = d
        self.mass_finer = p
        dp = np.diff(p)
        mean_d2 = (d[:-1] ** 2 + d[:-1] * d[1:] + d[1:] ** 2) / 3.0
        count = dp / mean_d2
        self.number_finer = np.concatenate([[0.0], np.cumsum(count) / count.sum()])

    @classmethod
    def from_csv(cls, path) -> "PSD":
        """Read ``diameter_mm,percent_finer`` (comment lines start with #)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"PSD file {str(path)!r} does not exist")
        lines = [ln.strip() for ln in path.read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
        header = [h.strip() for h in lines[0].split(",")] if lines else []
        if "diameter_mm" not in header or "percent_finer" not in header:
            raise KeyError(f"PSD file {str(path)!r}: needs columns 'diameter_mm' and 'percent_finer', got {header}")
        try:
            rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
        except ValueError as exc:
            raise ValueError(f"PSD file {str(path)!r}: not numeric ({exc})") from None
        d = rows[:, header.index("diameter_mm")]
        p = rows[:, header.index("percent_finer")]
        return cls(1e-3 * d, 0.01 * p, name=path.stem)

    def number_cdf(self, d_m) -> np.ndarray:
        """Number fraction of particles finer than ``d_m`` [m]."""
        return np.interp(d_m, self.diameters, self.number_finer)

    def mass_cdf(self, d_m) -> np.ndarray:
        return np.interp(d_m, self.diameters, self.mass_finer)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` diameters [m] by inverse-transform sampling (A.1-A.3) of the number CDF."""
        u = rng.random(n)
        keep = np.diff(self.number_finer) > 0  # drop empty segments so the inverse is single-valued
        x = np.concatenate([[self.number_finer[0]], self.number_finer[1:][keep]])
        y = np.concatenate([[self.diameters[0]], self.diameters[1:][keep]])
        return np.interp(u, x, y)


def load_psd(psd) -> PSD:
    """A :class:`PSD` from a preset name ("ottawa_c109"), a CSV path or a PSD."""
    if isinstance(psd, PSD):
        return psd
    if isinstance(psd, str) and psd in PRESETS:
        with resources.as_file(resources.files("dem") / "data" / PRESETS[psd]) as path:
            out = PSD.from_csv(path)
        out.name = psd
        return out
    if isinstance(psd, (str, Path)) and (Path(psd).suffix == ".csv" or Path(psd).exists()):
        return PSD.from_csv(psd)
    raise KeyError(f"unknown PSD {psd!r}; allowed: a preset {sorted(PRESETS)} or a CSV path")


def ks_distance(diameters_m: np.ndarray, psd: PSD) -> float:
    """Kolmogorov-Smirnov distance between the sample's number ECDF and the PSD's number CDF."""
    d = np.sort(np.asarray(diameters_m))
    n = len(d)
    cdf = psd.number_cdf(d)
    return float(max(np.max(np.arange(1, n + 1) / n - cdf), np.max(cdf - np.arange(n) / n)))
