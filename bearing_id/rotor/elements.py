"""
Finite elements of the rotor: the Nelson (1980) Timoshenko shaft element and the rigid disc.

DOFs per node ``[x, y, tx, ty]`` with tx = -dy/dz and ty = +dx/dz (see :mod:`bearing_id.conventions`); the element
matrices are 8x8 on ``[x1, y1, tx1, ty1, x2, y2, tx2, ty2]``.  Equation of motion
``M q'' + (C + Omega G) q' + K q = f`` (G skew-symmetric; forward-whirl frequencies rise with speed).

Construction
    Each matrix is the classical planar Timoshenko matrix on ``(w1, w1', w2, w2')`` (Nelson 1980; Przemieniecki),
    mapped into the two bending planes: x-z uses ``(x1, ty1, x2, ty2)``, y-z uses ``(y1, -tx1, y2, -tx2)``.
    The gyroscopic matrix couples the planes through the rotary-inertia integral R = int Psi^T Psi dz of the
    rotation shape functions: ``G = rho Ip_area (Tx^T R Ty - Ty^T R Tx)`` with Ip_area = 2 I (polar second moment).

Shear deformation
    phi = 12 E I / (kappa G A L^2).  kappa is Hutchinson's (2001) shear coefficient for a hollow circular section,
    kappa = 6 (1 + r^2)^2 (1 + nu)^2 / [(1 + r^2)^2 (7 + 12 nu + 4 nu^2) + 4 r^2 (5 + 6 nu + 2 nu^2)], r = d_i / d_o
    (solid: 6 (1 + nu)^2 / (7 + 12 nu + 4 nu^2) = 0.9252 for nu = 0.3).  Cowper's (1966) value
    6 (1 + nu)(1 + r^2)^2 / [(7 + 6 nu)(1 + r^2)^2 + (20 + 12 nu) r^2] (0.8864) is available with
    ``shear_method='cowper'``; a number as ``shear_method`` is kappa itself.

Added mass
    ``added_mass`` = ((rho A, rho I) per unit length, ...) of mass-only layers (sleeves, impeller hubs): they add
    translational and rotary inertia and gyroscopics with the element's own shape functions (same phi), no stiffness.

Layers (``shaft.elements[i].layers``)
    ``layers`` = concentric full ShaftElements of the same length on the same two nodes (ROSS's several elements on
    one station, e.g. the impeller hubs of its compressor example): each with its own section, E, G, density and shear
    coefficient, hence its own shear parameter phi; their M, K and G are added to the host's (exactly as ROSS sums
    them).  ``mass`` counts them.

    Note: ROSS 2.3.0's 'hutchinson' option drops the square on (1 + nu) (kappa = 0.7117 for solid steel), so the ROSS
    comparison (scripts/ross_reference.py, test/test_rotor_ross.py) uses Cowper's coefficient on both sides.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

# index maps from the 8 element DOFs [x1, y1, tx1, ty1, x2, y2, tx2, ty2] to the planar (w1, w1', w2, w2')
_T_XZ = np.zeros((4, 8))
_T_XZ[[0, 1, 2, 3], [0, 3, 4, 7]] = 1.0            # (x1, ty1, x2, ty2): ty = +dx/dz
_T_YZ = np.zeros((4, 8))
_T_YZ[[0, 1, 2, 3], [1, 2, 5, 6]] = [1.0, -1.0, 1.0, -1.0]   # (y1, -tx1, y2, -tx2): tx = -dy/dz


def shear_coefficient(outer_d: float, inner_d: float, nu: float, method='hutchinson') -> float:
    """Timoshenko shear coefficient kappa [-] of a (hollow) circular section; a number ``method`` is kappa."""
    if not isinstance(method, str):
        k = float(method)
        if not (0.0 < k <= 2.0):
            raise ValueError(f'a shear coefficient must be in (0, 2], got {method!r}')
        return k
    r2 = (inner_d / outer_d) ** 2
    r12 = (1.0 + r2) ** 2
    if method == 'hutchinson':
        return 6.0 * r12 * (1.0 + nu) ** 2 / (r12 * (7.0 + 12.0 * nu + 4.0 * nu**2)
                                              + 4.0 * r2 * (5.0 + 6.0 * nu + 2.0 * nu**2))
    if method == 'cowper':
        return 6.0 * r12 * (1.0 + nu) / (r12 * (7.0 + 6.0 * nu) + r2 * (20.0 + 12.0 * nu))
    raise ValueError(f"shear coefficient method must be 'hutchinson' or 'cowper', got {method!r}")


def _planar(T: np.ndarray, P: np.ndarray) -> np.ndarray:
    return T.T @ P @ T


class ShaftElement:
    """
    Uniform Timoshenko shaft element (Nelson 1980).

    Parameters
    ----------
    length : m.   outer_d, inner_d : m.   E, G : Pa (Young's and shear modulus).   rho : kg/m^3.
    shear : include shear deformation (phi).   rotary_inertia : include rotary inertia (and gyroscopics).
    shear_method : 'hutchinson' (default), 'cowper' or kappa as a number.
    added_mass : sequence of (rho A [kg/m], rho I [kg m]) of mass-only layers (no stiffness).
    layers : sequence of ShaftElement of the same length: concentric full elements whose M, K, G are added.

    """

    def __init__(self, length, outer_d, inner_d, E, G, rho, *, shear=True, rotary_inertia=True,
                 shear_method='hutchinson', added_mass=(), layers=()):
        if not (length > 0 and outer_d > inner_d >= 0 and E > 0 and G > 0 and rho > 0):
            raise ValueError('shaft element needs length > 0, outer_d > inner_d >= 0, E, G, rho > 0')
        self.length, self.outer_d, self.inner_d = float(length), float(outer_d), float(inner_d)
        self.E, self.G_mod, self.rho = float(E), float(G), float(rho)
        self.shear, self.rotary_inertia, self.shear_method = bool(shear), bool(rotary_inertia), shear_method
        shear_coefficient(1.0, 0.0, 0.3, shear_method)  # validates the method name
        self.added_mass = tuple((float(a), float(b)) for a, b in added_mass)
        if any(not (a >= 0 and b >= 0) for a, b in self.added_mass):
            raise ValueError('added mass layers need rho A >= 0 and rho I >= 0')
        self.layers = tuple(layers)
        for lay in self.layers:
            if not isinstance(lay, ShaftElement) or lay.layers or abs(lay.length - self.length) > 1e-12 * self.length:
                raise ValueError('a layer must be a ShaftElement of the same length, without layers of its own')

    def __repr__(self):
        return (f'ShaftElement(length={self.length}, outer_d={self.outer_d}, inner_d={self.inner_d}, E={self.E}, '
                f'G={self.G_mod}, rho={self.rho})')

    # section properties
    @property
    def area(self) -> float:
        """Cross-section area [m^2]."""
        return math.pi / 4 * (self.outer_d**2 - self.inner_d**2)

    @property
    def inertia(self) -> float:
        """Diametral second moment of area I [m^4]."""
        return math.pi / 64 * (self.outer_d**4 - self.inner_d**4)

    @property
    def kappa(self) -> float:
        nu = self.E / (2.0 * self.G_mod) - 1.0
        return shear_coefficient(self.outer_d, self.inner_d, nu, self.shear_method)

    @property
    def phi(self) -> float:
        """Shear parameter 12 E I / (kappa G A L^2) [-] (0 without shear)."""
        if not self.shear:
            return 0.0
        return 12.0 * self.E * self.inertia / (self.kappa * self.G_mod * self.area * self.length**2)

    # planar 4x4 matrices on (w1, w1', w2, w2')
    @property
    def mass_per_length(self) -> float:
        """Return the translational mass per length [kg/m]: rho A plus the added layers."""
        m = self.rho * self.area
        for a, _ in self.added_mass:
            m = m + a
        return m

    @property
    def rotary_per_length(self) -> float:
        """Return the rotary inertia per length [kg m]: rho I plus the added layers."""
        r = self.rho * self.inertia
        for _, b in self.added_mass:
            r = r + b
        return r

    def _planar_mass(self) -> np.ndarray:
        p, L = self.phi, self.length
        m1 = 312 + 588 * p + 280 * p**2
        m2 = (44 + 77 * p + 35 * p**2) * L
        m3 = 108 + 252 * p + 140 * p**2
        m4 = -(26 + 63 * p + 35 * p**2) * L
        m5 = (8 + 14 * p + 7 * p**2) * L**2
        m6 = -(6 + 14 * p + 7 * p**2) * L**2
        Mt = np.array([[m1, m2, m3, m4], [m2, m5, -m4, m6], [m3, -m4, m1, -m2], [m4, m6, -m2, m5]])
        return self.mass_per_length * L / (840.0 * (1 + p) ** 2) * Mt

    def _rotation_integral(self) -> np.ndarray:
        """R = int Psi^T Psi dz [m] of the rotation shape functions (planar, 4x4)."""
        p, L = self.phi, self.length
        s2 = (3 - 15 * p) * L
        s3 = (4 + 5 * p + 10 * p**2) * L**2
        s4 = (-1 - 5 * p + 5 * p**2) * L**2
        R = np.array([[36, s2, -36, s2], [s2, s3, -s2, s4], [-36, -s2, 36, -s2], [s2, s4, -s2, s3]])
        return R / (30.0 * L * (1 + p) ** 2)

    def _planar_stiffness(self) -> np.ndarray:
        p, L = self.phi, self.length
        Kp = np.array([[12, 6 * L, -12, 6 * L], [6 * L, (4 + p) * L**2, -6 * L, (2 - p) * L**2],
                       [-12, -6 * L, 12, -6 * L], [6 * L, (2 - p) * L**2, -6 * L, (4 + p) * L**2]])
        return self.E * self.inertia / ((1 + p) * L**3) * Kp

    # 8x8 matrices
    def M(self) -> np.ndarray:
        """Mass matrix [kg, kg m, kg m^2] (translational + rotary inertia), 8x8."""
        Mp = self._planar_mass()
        if self.rotary_inertia:
            Mp = Mp + self.rotary_per_length * self._rotation_integral()
        out = _planar(_T_XZ, Mp) + _planar(_T_YZ, Mp)
        for lay in self.layers:
            out = out + lay.M()
        return out

    def K(self) -> np.ndarray:
        """Stiffness matrix [N/m, N, N m] (bending + shear), 8x8."""
        Kp = self._planar_stiffness()
        out = _planar(_T_XZ, Kp) + _planar(_T_YZ, Kp)
        for lay in self.layers:
            out = out + lay.K()
        return out

    def G(self) -> np.ndarray:
        """Gyroscopic matrix per unit spin speed [kg m^2 ...], 8x8, skew-symmetric (multiply by Omega [rad/s])."""
        out = self._own_G() if self.rotary_inertia else np.zeros((8, 8))
        for lay in self.layers:
            out = out + lay.G()
        return out

    def _own_G(self) -> np.ndarray:
        """Return the host's gyroscopic matrix (without the layers), 8x8."""
        R = 2.0 * self.rotary_per_length * self._rotation_integral()
        # ty = Psi . (x-z planar dofs); tx = -Psi . (y-z planar dofs); disc-like coupling +Ip on [tx, ty]
        return _T_XZ.T @ R @ _T_YZ - _T_YZ.T @ R @ _T_XZ

    @property
    def mass(self) -> float:
        """Return the element's mass [kg] (added mass and layers included)."""
        return self.mass_per_length * self.length + sum(lay.mass for lay in self.layers)


@dataclass(frozen=True)
class DiscElement:
    """Rigid disc at one node: mass ``m`` [kg], diametral inertia ``Id`` and polar inertia ``Ip`` [kg m^2]."""

    m: float
    Id: float
    Ip: float

    def M(self) -> np.ndarray:
        """4x4 mass matrix on [x, y, tx, ty]."""
        return np.diag([self.m, self.m, self.Id, self.Id])

    def G(self) -> np.ndarray:
        """4x4 gyroscopic matrix per unit spin speed: +Ip at [tx, ty], -Ip at [ty, tx]."""
        g = np.zeros((4, 4))
        g[2, 3] = self.Ip
        g[3, 2] = -self.Ip
        return g


__all__ = ['ShaftElement', 'DiscElement', 'shear_coefficient']
