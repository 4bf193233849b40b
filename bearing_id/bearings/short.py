"""
Closed-form short-bearing (Ocvirk) solution of a plain cylindrical journal bearing.

Physics (Ocvirk & DuBois 1953; coefficients as in Lund 1987, Childs 1993 section 3, Friswell et al. 2010 section 5.5):
the circumferential pressure flow is neglected against the axial one, so Reynolds' equation integrates in z,
and the film is the half-Sommerfeld (Gumbel, "pi film") one: negative pressures are set to zero.  Valid for
L/D <~ 0.5; for L/D = 1 it over-predicts the load capacity (use :mod:`.finite`).

Definitions (SI)
    R = D/2, radial clearance c, eccentricity ratio eps = e/c, spin speed ``speed`` [rad/s], static load W [N].
    Sommerfeld number S = mu N L D / W (R/c)^2 with N = speed/(2 pi) [rev/s]  (Raimondi-Boyd / Someya / Lund).
    Short-bearing load equation:  pi S (L/D)^2 = (1 - eps^2)^2 / (eps sqrt(16 eps^2 + pi^2 (1 - eps^2))).
    Attitude angle phi (from the load line, in the spin direction):  tan phi = pi sqrt(1 - eps^2) / (4 eps).

Frames: the dimensionless coefficients below are in the bearing-literature frame of
:mod:`bearing_id.conventions` (X along the load, Y 90 deg ahead in the spin direction) and are mapped to our
(x horizontal, y up; load along -y, spin +x -> +y) frame with :func:`conventions.lit_to_xy`.  Force on the shaft
f = -K q - C q'.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..conventions import lit_to_xy


@dataclass(frozen=True)
class BearingSolution:
    """
    Static equilibrium and linearised coefficients of one journal bearing at one speed.

    eccentricity : eps = e/c [-].   attitude_angle : phi [rad], journal position measured from the load line in the
    spin direction.   sommerfeld : S = mu N L D / W (R/c)^2 [-].   K (2,2) [N/m], C (2,2) [N s/m] in our (x, y) frame.
    journal_position : (x, y) [m] of the journal centre relative to the bearing centre (load along -y -> y < 0).
    model : 'short' | 'finite'.   force_error : |F_film - F_required| / W at the equilibrium found (0 = closed form).
    """

    eccentricity: float
    attitude_angle: float
    sommerfeld: float
    K: np.ndarray
    C: np.ndarray
    journal_position: tuple
    model: str = 'short'
    force_error: float = 0.0


def check_inputs(D, L, c, mu, W, speed) -> None:
    """Raise ValueError with a clear message for non-physical bearing inputs (numbers or arrays of them)."""
    for name, v in (('diameter D', D), ('length L', L), ('radial clearance c', c), ('viscosity mu', mu),
                    ('static load W', W), ('speed', speed)):
        if not _positive(v):
            if name == 'speed':
                raise ValueError(f'journal bearing speed must be > 0 rad/s (no hydrodynamic film at zero speed), '
                                 f'got {speed!r}')
            raise ValueError(f'bearing {name} must be a positive finite number (SI), got {v!r}')


def _positive(v) -> bool:
    """Return True when every entry of ``v`` (a number or an array) is finite and > 0."""
    if isinstance(v, float):
        return 0.0 < v < math.inf
    v = np.asarray(v, dtype=float)
    return bool(v.min() > 0 and v.max() < math.inf) if v.size else True


def sommerfeld_number(D, L, c, mu, W, speed):
    """S = mu N L D / W (R/c)^2, N = speed / 2 pi [rev/s] (numbers or arrays)."""
    return mu * speed / (2 * math.pi) * L * D / W * (D / 2 / c) ** 2


def short_load_parameter(eps):
    """Return pi S (L/D)^2 of the short bearing as a function of eps (decreasing from inf at 0 to 0 at 1)."""
    eps = np.asarray(eps, dtype=float)
    return (1 - eps**2) ** 2 / (eps * np.sqrt(16 * eps**2 + math.pi**2 * (1 - eps**2)))


def short_eccentricity(sommerfeld, L_over_D: float):
    """
    Eccentricity ratio of the short bearing from its Sommerfeld number (a number, or an array: the same shape out).

    The load equation sigma = pi S (L/D)^2 = F(eps) (:func:`short_load_parameter`) solved as G(v) = ln sigma -
    ln F(eps) = 0 in v = ln(eps / (1 - eps)) by Newton's method, every entry at once.  G rises from -inf to +inf
    with a slope between 0.94 and 2 (1 as eps -> 0, 2 as eps -> 1): Newton starts at the smaller of the two
    asymptotes (eps = 1 / (pi sigma) at small eps, 1 - eps = sqrt(sigma) near 1) and takes at most 4 steps for S
    from 1e-13 to 1e13 (RuntimeError after 50).  An entry stops after its first step below 1e-10 in v (the next
    would be below 1e-19): eps to ~1e-14 relative, the rounding of G.
    """
    S = np.asarray(sommerfeld, dtype=float)
    sigma = math.pi * S * L_over_D**2
    if not _positive(sigma):
        raise ValueError(f'Sommerfeld number must be positive and finite, got {S}')
    pi2 = math.pi**2
    ln_sigma = np.log(sigma)
    v = np.minimum(-np.log(math.pi * sigma), -0.5 * ln_sigma)
    live = np.ones_like(v)                                      # 1 while an entry iterates, 0 once it stopped
    for _ in range(50):
        t = np.exp(-v)
        e = 1 / (1 + t)
        em = t * e                                              # 1 - eps
        q = 16 * e * e + pi2 * em * (1 + e)                     # 16 eps^2 + pi^2 (1 - eps^2)
        G = ln_sigma + np.log1p(t) + 2 * v - 2 * np.log1p(e) + 0.5 * np.log(q)   # ln eps = -ln(1 + t)
        dG = em + 4 * e * e / (1 + e) + (16 - pi2) * e * e * em / q            # dG/dv
        dv = live * (G / dG)
        v = v - dv
        live = live * (np.abs(dv) > 1e-10)
        if not live.any():
            e = 1 / (1 + np.exp(-v))
            return float(e) if np.ndim(e) == 0 else e
    raise RuntimeError(f'short_eccentricity: Newton did not converge for S = {S}')


def short_attitude_angle(eps):
    """Attitude angle [rad] of the short bearing (pi/2 at eps -> 0, 0 at eps -> 1); numbers or arrays."""
    eps = np.asarray(eps, dtype=float)
    phi = np.arctan2(math.pi * np.sqrt(1 - eps * eps), 4 * eps)
    return float(phi) if phi.ndim == 0 else phi


def short_coefficients_lit(eps) -> tuple[np.ndarray, np.ndarray]:
    """
    Dimensionless (k = K c / W, b = C c speed / W) short-bearing coefficients in the literature frame.

    ``eps`` a number (k, b (2, 2)) or an array (k, b (..., 2, 2)).  Closed forms of the linearised Ocvirk pi-film
    forces (Lund 1987; Childs 1993 ch. 3; Friswell et al. 2010 eq. 5.80, which states the same numbers directly in a
    horizontal/vertical frame equal to our (x, y): its a_uu is our k_YY, a_vv our k_XX, a_uv = -k_YX, a_vu = -k_XY,
    b_uv = -b_XY), here written in the X = load, Y = 90 deg ahead (spin direction) frame.  Checked against
    quadrature of the short-bearing pressure in the tests (test/film_oracle.py).
    """
    eps = np.asarray(eps, dtype=float)
    e2 = eps * eps
    pi2 = math.pi**2
    s = np.sqrt(1 - e2)
    h0 = 1.0 / (pi2 * (1 - e2) + 16 * e2) ** 1.5
    k = np.empty(eps.shape + (2, 2))
    k[..., 0, 0] = 4 * (pi2 * (1 + 2 * e2) + 32 * e2 * (1 + e2) / (1 - e2))
    k[..., 0, 1] = math.pi * (pi2 * (1 - e2) * (1 + 2 * e2) + 32 * e2 * (1 + e2)) / (eps * s)
    k[..., 1, 0] = -math.pi * (pi2 * (1 - e2) ** 2 - 16 * e2 * e2) / (eps * s)
    k[..., 1, 1] = 4 * (pi2 * (2 - e2) + 16 * e2)
    b = np.empty(eps.shape + (2, 2))
    b[..., 0, 0] = 2 * math.pi * (pi2 * (1 - e2) ** 2 + 48 * e2) / (eps * s)
    b[..., 0, 1] = b[..., 1, 0] = 8 * (pi2 * (1 + 2 * e2) - 16 * e2)
    b[..., 1, 1] = 2 * math.pi * s * (pi2 * (1 + 2 * e2) - 16 * e2) / eps
    h0 = h0[..., None, None]
    return h0 * k, h0 * b


def journal_position(eps: float, phi: float, c: float) -> tuple[float, float]:
    """(x, y) [m] of the journal centre: eccentricity e = eps c at phi from the load line (-y) towards +x."""
    return (eps * c * math.sin(phi), -eps * c * math.cos(phi))


def ocvirk_batch(D: float, L: float, c, mu, W, speed) -> tuple[np.ndarray, np.ndarray]:
    """
    Short-bearing K [N/m], C [N s/m] in our frame, (..., 2, 2), for arrays of clearance, viscosity, load and speed.

    One bearing geometry (D, L [m]); c [m], mu [Pa s], W [N] (acting on the journal along -y) and speed [rad/s] > 0
    broadcast to a common shape (...).  The computation of :func:`ocvirk` (which is this for one entry), for
    :func:`bearing_id.bearings.coefficients_at` (a bearing's coefficients at every speed of a prediction).
    """
    c, mu, W, speed = (np.asarray(v, dtype=float) for v in np.broadcast_arrays(c, mu, W, speed))
    check_inputs(D, L, c, mu, W, speed)
    _, eps, K, C = _solve(D, L, c, mu, W, speed)
    return K, C


def _solve(D, L, c, mu, W, speed):
    """Return (S, eps, K, C) of the short bearing for (broadcast) arrays c, mu, W, speed; K, C (..., 2, 2)."""
    S = sommerfeld_number(D, L, c, mu, W, speed)
    eps = np.asarray(short_eccentricity(S, L / D))
    k, b = short_coefficients_lit(eps)
    K = lit_to_xy(k * (W / c)[..., None, None])
    C = lit_to_xy(b * (W / (c * speed))[..., None, None])
    return S, eps, K, C


def ocvirk(D: float, L: float, c: float, mu: float, W: float, speed: float) -> BearingSolution:
    """
    Short-bearing equilibrium and K [N/m], C [N s/m] (our frame) of a plain journal bearing.

    D, L, c [m]; mu [Pa s]; W [N] static load (acting on the journal along -y); speed [rad/s] > 0.
    """
    check_inputs(D, L, c, mu, W, speed)
    S, eps, K, C = _solve(D, L, *(np.asarray(v, dtype=float) for v in (c, mu, W, speed)))
    eps = float(eps)
    phi = short_attitude_angle(eps)
    return BearingSolution(eccentricity=eps, attitude_angle=phi, sommerfeld=float(S), K=K, C=C,
                           journal_position=journal_position(eps, phi, float(c)), model='short', force_error=0.0)


__all__ = ['BearingSolution', 'ocvirk', 'ocvirk_batch', 'sommerfeld_number', 'short_eccentricity',
           'short_attitude_angle', 'short_load_parameter', 'short_coefficients_lit', 'journal_position',
           'check_inputs']
