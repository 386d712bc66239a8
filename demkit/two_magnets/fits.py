"""Least-squares fits of the rigid-barbell laws of the seed paper (and a power law).

Angular momentum m v b = beta m R^2 omega_f gives the spin  omega_f = v b / (beta R^2)  and the
kinetic-energy ratio  K_f / K_i = (b/R)^2 / (2 beta)  (K_i = m v^2 for two spheres of speed v).
Both are straight lines through the origin, y = g / beta, fitted for the slope s = 1/beta:

    s = sum(w g y) / sum(w g^2),   sigma_s^2 = sum(w (y - s g)^2) / ((n - 1) sum(w g^2)),

weights w = 1/sigma_y^2 (or 1), and beta = 1/s, sigma_beta = sigma_s / s^2. sigma_s is scaled by
the scatter of the points about the line (as scipy's curve_fit with absolute_sigma=False), so it
reflects how well the law fits rather than only the stated per-point uncertainties.
"""
from __future__ import annotations

import numpy as np


def proportional_fit(g, y, sigma=None):
    """(s, sigma_s) of y = s g by weighted least squares (weights 1/sigma^2 when all sigma > 0)."""
    g, y = np.asarray(g, dtype=float), np.asarray(y, dtype=float)
    if g.shape != y.shape or g.ndim != 1 or len(g) < 2:
        raise ValueError("need two 1-d arrays of equal length >= 2")
    w = np.ones_like(g)
    if sigma is not None:
        sigma = np.asarray(sigma, dtype=float)
        if sigma.shape != g.shape:
            raise ValueError("sigma must have the shape of the data")
        if np.all(sigma > 0) and np.all(np.isfinite(sigma)):
            w = 1.0 / sigma ** 2
    sgg = float(np.sum(w * g * g))
    s = float(np.sum(w * g * y)) / sgg
    residual = float(np.sum(w * (y - s * g) ** 2))
    return s, float(np.sqrt(residual / ((len(g) - 1) * sgg)))


def _beta(s, ds):
    return 1.0 / s, ds / s ** 2


def fit_beta(b_over_R, omega, speed, radius, sigma=None):
    """(beta, sigma_beta) from omega_f = v (b/R) / (beta R); omega in rad per time unit, speed v of
    each sphere and radius R in the same units, sigma the per-point uncertainties of omega."""
    g = speed * np.asarray(b_over_R, dtype=float) / radius
    return _beta(*proportional_fit(g, omega, sigma))


def fit_energy_ratio(b_over_R, ratio, sigma=None):
    """(beta, sigma_beta) from K_f / K_i = (b/R)^2 / (2 beta)."""
    g = 0.5 * np.asarray(b_over_R, dtype=float) ** 2
    return _beta(*proportional_fit(g, ratio, sigma))


def crossing(x, y, level=1.0):
    """First x at which y reaches ``level`` (linear interpolation between points; x ascending).
    None if y never reaches it."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float) - level
    above = np.flatnonzero(y >= 0)
    if len(above) == 0:
        return None
    k = int(above[0])
    if k == 0:
        return float(x[0])
    return float(x[k - 1] - y[k - 1] * (x[k] - x[k - 1]) / (y[k] - y[k - 1]))


def fit_power_law(x, y):
    """(p, sigma_p, c) of y = c x^p by least squares on log y against log x."""
    lx, ly = np.log(np.asarray(x, dtype=float)), np.log(np.asarray(y, dtype=float))
    if len(lx) < 3:
        raise ValueError("need at least three points")
    (p, lc), cov = np.polyfit(lx, ly, 1, cov=True)
    return float(p), float(np.sqrt(cov[0, 0])), float(np.exp(lc))
