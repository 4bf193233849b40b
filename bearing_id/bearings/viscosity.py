"""
Oil viscosity against temperature: the Walther relation of ASTM D341, and the oil's density.

ASTM D341 (Walther): log10(log10(nu + 0.7)) = A - B log10(T), nu the kinematic viscosity in cSt (mm^2/s), T the
absolute temperature in kelvin.  A and B [-] follow from two reference kinematic viscosities, as a datasheet gives them
(e.g. ISO VG 32: 32 cSt at 40 degC and 5.4 cSt at 100 degC).  The constant 0.7 form holds for nu >= 2 cSt (the standard
adds a correction term below that; a bearing oil is far above it at any temperature it runs at).

The dynamic viscosity [Pa s] is the kinematic one times the density; the density falls linearly with temperature,
rho(T) = rho_ref + drho_dT (T - T_ref) (drho_dT < 0, typically -0.6 to -0.7 kg/(m^3 K) for mineral oils).

SI in and out: temperatures in kelvin, kinematic viscosity in m^2/s, density in kg/m^3, dynamic viscosity in Pa s;
cSt only inside the formula, degC only in :func:`celsius`.  Every function takes arrays (any shape, broadcast) and
returns arrays of the broadcast shape (0-d for scalars).  :func:`dln_mu_dT` is the slope a temperature sigma is
propagated with: sigma_mu / mu = |dln_mu_dT| sigma_T.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CST = 1e-6                  # one centistoke (mm^2/s) in m^2/s
ZERO_CELSIUS = 273.15       # K
LN10 = np.log(10.0)
NEWTON_RTOL = 1e-13         # the inverse's Newton iteration stops when the step is below this relative to T
NEWTON_MAX = 60


def celsius(t_celsius):
    """Return the temperature ``t_celsius`` [degC] in kelvin (the one place degC enters; any shape)."""
    return np.asarray(t_celsius, dtype=float) + ZERO_CELSIUS


@dataclass(frozen=True)
class Oil:
    """
    An oil by its two reference kinematic viscosities and its density.

    nu1, nu2: kinematic viscosity [m^2/s] at T1, T2 [K] (T1 != T2; typically 40 and 100 degC);
    rho_ref: density [kg/m^3] at T_ref [K]; drho_dT: its slope [kg/(m^3 K)] (negative; 0 = constant density).
    """

    nu1: float
    T1: float
    nu2: float
    T2: float
    rho_ref: float
    T_ref: float = ZERO_CELSIUS + 15.0
    drho_dT: float = -0.65

    def __post_init__(self):
        """Refuse references the Walther relation cannot pass through (equal temperatures, nu < 2 cSt, ...)."""
        vals = (self.nu1, self.T1, self.nu2, self.T2, self.rho_ref, self.T_ref, self.drho_dT)
        if not all(np.isfinite(v) for v in vals):
            raise ValueError(f'oil parameters must be finite, got {vals}')
        if self.T1 <= 0 or self.T2 <= 0 or self.T1 == self.T2:
            raise ValueError(f'reference temperatures must be two different positive kelvin values, got '
                             f'{self.T1} K and {self.T2} K')
        if min(self.nu1, self.nu2) < 2 * CST:
            raise ValueError(f'reference kinematic viscosities must be >= 2 cSt (2e-6 m^2/s; the Walther relation '
                             f'with 0.7 holds above it), got {self.nu1} and {self.nu2} m^2/s')
        if (self.nu1 - self.nu2) * (self.T1 - self.T2) >= 0:
            raise ValueError('the viscosity must fall as the temperature rises: got '
                             f'{self.nu1} m^2/s at {self.T1} K and {self.nu2} m^2/s at {self.T2} K')
        if self.rho_ref <= 0:
            raise ValueError(f'density must be > 0 kg/m^3, got {self.rho_ref}')

    @property
    def walther(self) -> tuple[float, float]:
        """Return the Walther constants (A, B) [-] through the two references (nu in cSt, T in K)."""
        w1, w2 = _w(self.nu1), _w(self.nu2)
        B = (w1 - w2) / (np.log10(self.T2) - np.log10(self.T1))
        return float(w1 + B * np.log10(self.T1)), float(B)


def _w(nu):
    """Return log10(log10(nu_cSt + 0.7)) of ``nu`` [m^2/s]."""
    return np.log10(np.log10(np.asarray(nu, dtype=float) / CST + 0.7))


def kinematic(oil: Oil, T):
    """Return the kinematic viscosity [m^2/s] of ``oil`` at ``T`` [K] (any shape)."""
    A, B = oil.walther
    T = _kelvin(T)
    return (10.0 ** (10.0 ** (A - B * np.log10(T))) - 0.7) * CST


def density(oil: Oil, T):
    """Return the density [kg/m^3] of ``oil`` at ``T`` [K] (any shape), linear in T."""
    rho = oil.rho_ref + oil.drho_dT * (_kelvin(T) - oil.T_ref)
    if np.any(rho <= 0):
        raise ValueError(f'the linear density law gives rho <= 0 at T = {T} K: outside its range')
    return rho


def dynamic(oil: Oil, T):
    """Return the dynamic viscosity [Pa s] of ``oil`` at ``T`` [K] (any shape)."""
    return kinematic(oil, T) * density(oil, T)


def dln_mu_dT(oil: Oil, T):
    """
    Return d ln(mu) / dT [1/K] of ``oil`` at ``T`` [K] (any shape; negative).

    With Z = nu_cSt + 0.7 and L = log10 Z: W = log10 L = A - B log10 T gives dZ/dT = -B Z L ln(10) / T, so
    d ln(nu)/dT = -B Z L ln(10) / (T nu_cSt); the density adds drho_dT / rho.
    """
    A, B = oil.walther
    T = _kelvin(T)
    L = 10.0 ** (A - B * np.log10(T))
    Z = 10.0 ** L
    nu_cst = Z - 0.7
    return -B * Z * L * LN10 / (T * nu_cst) + oil.drho_dT / density(oil, T)


def temperature_for_kinematic(oil: Oil, nu):
    """Return the temperature [K] at which ``oil`` has the kinematic viscosity ``nu`` [m^2/s] (any shape)."""
    A, B = oil.walther
    nu = np.asarray(nu, dtype=float)
    if np.any(~np.isfinite(nu) | (nu < 2 * CST)):
        raise ValueError(f'kinematic viscosity must be finite and >= 2 cSt (2e-6 m^2/s), got {nu}')
    return 10.0 ** ((A - _w(nu)) / B)


def temperature_for_dynamic(oil: Oil, mu):
    """
    Return the temperature [K] at which ``oil`` has the dynamic viscosity ``mu`` [Pa s] (any shape).

    Newton's iteration on ln mu(T) - ln mu (monotonic and smooth in T), started where the kinematic viscosity
    mu / rho_ref is reached; the density's share of the slope is ~1 % of the viscosity's, so a few steps converge.
    Raises ValueError if it does not converge within NEWTON_MAX steps.
    """
    mu = np.asarray(mu, dtype=float)
    if np.any(~np.isfinite(mu) | (mu <= 0)):
        raise ValueError(f'dynamic viscosity must be finite and > 0 Pa s, got {mu}')
    T = temperature_for_kinematic(oil, np.maximum(mu / oil.rho_ref, 2 * CST))
    target = np.log(mu)
    for _ in range(NEWTON_MAX):
        step = (np.log(dynamic(oil, T)) - target) / dln_mu_dT(oil, T)
        T = T - step
        if np.all(np.abs(step) <= NEWTON_RTOL * T):
            return T
    raise ValueError(f'no temperature found for dynamic viscosity {mu} Pa s (Newton did not converge)')


def _kelvin(T):
    T = np.asarray(T, dtype=float)
    if np.any(~np.isfinite(T) | (T <= 0)):
        raise ValueError(f'temperature must be finite and > 0 K, got {T}')
    return T


__all__ = ['Oil', 'celsius', 'kinematic', 'density', 'dynamic', 'dln_mu_dT', 'temperature_for_kinematic',
           'temperature_for_dynamic', 'CST']
