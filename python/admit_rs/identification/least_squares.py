"""The sensor's filter as identify models it, and least squares whose intervals account for
the residuals' autocorrelation."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

Array = npt.NDArray[np.float64]


def low_pass_delay(u: Array, alpha: float, latency: int) -> Array:
    """The sensor's low-pass (y_0 = u_0) and latency (holding y_0), along axis 0."""
    if alpha >= 1.0:
        y = np.array(u, dtype=float)
    else:
        # y_k − (1 − α) y_{k−1} = α u_k, started at y_0 = u_0: the filter's state before
        # sample 0 is (1 − α) u_0.
        zi = (1 - alpha) * np.asarray(u[:1], dtype=float)
        y = lfilter([alpha], [1.0, -(1 - alpha)], u, axis=0, zi=zi)[0]
    if latency > 0:
        y = np.concatenate([np.repeat(y[:1], latency, axis=0), y[:-latency]], axis=0)
    return y


def alpha_of(cutoff: float | None, period: float) -> float:
    return 1.0 if cutoff is None else 1.0 - math.exp(-2 * math.pi * cutoff * period)


def ar1_inflation(residuals: Array, columns: int = 1) -> tuple[float, float]:
    """(variance inflation, lag-one autocorrelation ρ ≥ 0) of an AR(1) residual; a residual
    raveled from ``columns`` series sampled together is taken apart first (neighbours in
    the raveled order are different axes, not neighbouring times)."""
    series = residuals.reshape(-1, columns)
    r = series - series.mean(axis=0)
    denom = float(np.sum(r * r))
    rho = float(np.sum(r[1:] * r[:-1])) / denom if denom > 0 else 0.0
    rho = min(max(rho, 0.0), 0.995)
    return (1 + rho) / (1 - rho), rho


@dataclass
class LinearFit:
    coef: Array
    cov: Array
    rss: float
    dof: float
    residuals: Array


def least_squares(design: Array, target: Array, columns: int = 1) -> LinearFit:
    """Ordinary least squares with an AR(1)-corrected covariance (``columns``: the target
    is that many series raveled sample by sample)."""
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    res = target - design @ coef
    n, p = design.shape
    inflation, _ = ar1_inflation(res, columns)
    n_eff = max(n / inflation, p + 2.0)
    rss = float(res @ res)
    s2 = rss / max(n - p, 1)
    cov = np.linalg.pinv(design.T @ design) * s2 * inflation
    return LinearFit(np.asarray(coef, dtype=float), cov, rss, n_eff - p, res)


@dataclass
class ResidualFit:
    """Least squares' coefficients and residual sum of squares alone."""

    coef: Array
    rss: float


def residual_fit(design: Array, target: Array) -> ResidualFit:
    """The coefficients and residual sum of squares of ``target`` ≈ ``design`` · coef by the
    normal equations on unit-norm columns (no covariance: what a profile search over the
    sensor's latency and cut-off needs, without :func:`least_squares`' SVD and covariance).
    Columns scaled to unit norm keep the normal matrix's condition near the square of the
    design's (a contact law's δ and offset columns: about 1e6, far from float64's limit)."""
    gram = design.T @ design
    scale = np.sqrt(np.diag(gram))
    scale[scale == 0] = 1.0
    try:
        solved = np.linalg.solve(gram / np.outer(scale, scale), (design.T @ target) / scale)
        coef = np.asarray(solved / scale, dtype=float)
    except np.linalg.LinAlgError:
        coef = np.asarray(np.linalg.lstsq(design, target, rcond=None)[0], dtype=float)
    res = target - design @ coef
    return ResidualFit(coef, float(res @ res))
