"""
The local flexibility of a transverse crack in a solid round shaft: open-crack compliance <-> crack depth.

A straight-front crack of depth ``a`` in a shaft of radius ``R`` adds, while open, a rotational compliance to the
shaft for the bending moment that opens it (the moment vector along the crack front; ``c55`` of Dimarogonas &
Papadopoulos 1983, Papadopoulos & Dimarogonas 1987).  Castigliano on the strain energy released by the crack,
integrated over the crack face in strips of width dx (each strip an edge-cracked strip of height h(x))::

    c55 = 2 (1 - nu^2) / E  int_{-b}^{b} int_0^{alpha(x)} k(alpha, x)^2 d(alpha) dx

    k = sigma(x) sqrt(pi alpha) F(alpha / h),     sigma(x) = 4 sqrt(R^2 - x^2) / (pi R^4)   (per N m of moment)
    h(x) = 2 sqrt(R^2 - x^2),   alpha(x) = sqrt(R^2 - x^2) - (R - a),   b = sqrt(R^2 - (R - a)^2)
    F(s) = sqrt(tan(l) / l) (0.923 + 0.199 (1 - sin l)^4) / cos(l),   l = pi s / 2

``F`` is the stress-intensity factor of an edge-cracked strip in bending (Tada, Paris & Irwin, The Stress Analysis
of Cracks Handbook).  In units of (1 - nu^2) / (E R^3) the compliance depends on a / R alone
(:func:`dimensionless_c55`).  The integral is evaluated by Gauss-Legendre quadrature after x = b sin(t) (the strip
depth has a square-root edge at x = b when a = R); the law holds up to a = R (half the diameter), where the strip
formula's s = alpha / h stays <= 1/2.  For a hollow shaft it does not apply (:func:`crack_depth_ratio` says so with
NaN).  SI units: m, Pa, rad/(N m).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

_GL_X, _GL_W = np.polynomial.legendre.leggauss(48)
MAX_DEPTH_RATIO = 0.5          # a / D: the law's range (a crack reaching the shaft's centre)


def strip_factor(s: np.ndarray) -> np.ndarray:
    """Return F(s) (dimensionless) of an edge-cracked strip in bending at relative depth ``s`` = alpha / h (< 1)."""
    lam = 0.5 * math.pi * np.asarray(s, float)
    lam = np.where(lam > 0, lam, 1e-300)
    return np.sqrt(np.tan(lam) / lam) * (0.923 + 0.199 * (1.0 - np.sin(lam)) ** 4) / np.cos(lam)


def dimensionless_c55(a_over_r: float) -> float:
    """
    Return c55 E R^3 / (1 - nu^2) for a crack of depth ``a_over_r`` = a / R in (0, 1] (0 for no crack).

    Quadrature on the crack face (module docstring), 48 x 48 Gauss-Legendre points on the quarter x >= 0 (the face
    is symmetric in x); R = 1.
    """
    q = float(a_over_r)
    if not 0.0 <= q <= 1.0:
        raise ValueError(f'crack depth a/R = {q:g} is outside the law (0 ... 1: up to the shaft centre)')
    if q == 0.0:
        return 0.0
    b = math.sqrt(1.0 - (1.0 - q) ** 2)
    t = 0.25 * math.pi * (_GL_X + 1.0)                       # x = b sin(t), t in (0, pi/2)
    x = b * np.sin(t)
    dx = 0.25 * math.pi * _GL_W * b * np.cos(t)
    half = np.sqrt(1.0 - x * x)                               # h / 2 (R = 1)
    depth = half - (1.0 - q)                                  # alpha(x), the strip's crack depth
    u = 0.5 * (_GL_X + 1.0)                                   # alpha = depth u, u in (0, 1)
    alpha = depth[:, None] * u[None, :]
    dalpha = depth[:, None] * 0.5 * _GL_W[None, :]
    sigma = 4.0 * half / math.pi
    k2 = (sigma[:, None] ** 2) * math.pi * alpha * strip_factor(alpha / (2.0 * half[:, None])) ** 2
    return float(2.0 * 2.0 * np.sum(dx[:, None] * dalpha * k2))      # 2 (Castigliano) x 2 (both halves in x)


def open_crack_compliance(depth_ratio: float, diameter: float, E: float, nu: float) -> float:
    """Return the open crack's rotational compliance c55 [rad/(N m)] for depth ``depth_ratio`` = a / D (<= 0.5)."""
    R = 0.5 * diameter
    return dimensionless_c55(2.0 * depth_ratio) * (1.0 - nu ** 2) / (E * R ** 3)


def crack_depth_ratio(compliance: float, diameter: float, inner_diameter: float, E: float, nu: float) -> float:
    """
    Return the crack depth a / D whose open-crack compliance c55 is ``compliance`` [rad/(N m)].

    0 for a compliance <= 0; NaN when the law does not apply: a hollow shaft, or a compliance beyond that of a crack
    to the shaft's centre (a / D = 0.5).
    """
    if inner_diameter > 0 or not math.isfinite(compliance):
        return math.nan
    if compliance <= 0:
        return 0.0
    R = 0.5 * diameter
    target = compliance * E * R ** 3 / (1.0 - nu ** 2)
    if target >= dimensionless_c55(2.0 * MAX_DEPTH_RATIO):
        return math.nan
    q = brentq(lambda q: dimensionless_c55(q) - target, 0.0, 2.0 * MAX_DEPTH_RATIO, xtol=1e-14, rtol=1e-14)
    return 0.5 * q


__all__ = ['strip_factor', 'dimensionless_c55', 'open_crack_compliance', 'crack_depth_ratio', 'MAX_DEPTH_RATIO']
