"""
Finite-length plain journal bearing: Reynolds equation by finite volumes, selectable cavitation, perturbation K, C.

Equation (incompressible, isoviscous, aligned journal), dimensionless with H = h/c, P = p c^2/(mu speed R^2),
zeta = z/R, tau = speed t, theta measured from +x towards +y (the spin direction)::

    d/dtheta(H^3 dP/dtheta) + d/dzeta(H^3 dP/dzeta) = 6 dH/dtheta + 12 dH/dtau,
    H = 1 - X cos(theta) - Y sin(theta),   (X, Y) = journal centre / c in our (x, y) frame.

Discretisation: conservative finite volumes, ``n_theta`` cells around (periodic), ``n_z`` cells over the half length
(symmetry at mid-plane, P = 0 at the bearing end), second order.  Axial supply grooves (optional, e.g. the two
20-degree grooves of a two-axial-groove bearing) are cells held at ambient P = 0.

Cavitation: Reynolds (Swift-Stieber) conditions, P >= 0 with the flow balance holding wherever P > 0, posed as the
linear complementarity problem of the discrete operator (what projected Gauss-Seidel/SOR solves) and solved
exactly by a primal-dual active-set iteration (one sparse LU per iteration, finite convergence for this M-matrix).
This is the default, ``cavitation='swift_stieber'``.

``cavitation='gumbel'``: the Gumbel (half-Sommerfeld) condition -- the full-film (Sommerfeld) equation is solved
over the whole film (one linear solve, negative pressures allowed) and the negative pressures are dropped from the
load (the film force integrates max(p, 0) of the piecewise-linear reconstruction of p along theta,
:meth:`ReynoldsGrid.positive_part`, so the force is smooth in the journal position and K, C do not jump as the
rupture line crosses a cell).  Flow is not conserved at the film's rupture, which is why the Reynolds
condition is the better physics; Gumbel is what the closed-form short (Ocvirk, :mod:`.short`) and long bearings
assume, so the finite Gumbel bearing tends to :func:`bearing_id.bearings.short.ocvirk` as L/D shrinks.

Dynamic coefficients: the perturbation method (Lund 1987): the discrete Reynolds equation is differentiated
analytically with respect to X, Y (stiffness) and dX/dtau, dY/dtau (damping) on the converged full-film region,
with the perturbation pressure held at zero in the cavitated region -- four linear solves with the same matrix.
With Gumbel's condition the perturbation pressure is solved over the whole film and integrated through the
derivative of the positive part (the moving rupture line adds nothing to first order: p = 0 there).
:func:`film_force` with velocities gives the second route (central differences of the nonlinear force); the tests
show the two agree.

Equilibrium: Newton on the journal position with the perturbation Jacobian until |F - W| / W <= ``tol``
(1e-10 by default, relative force error), from the short-bearing position or any start inside the clearance.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .short import BearingSolution, check_inputs, short_attitude_angle, short_eccentricity, sommerfeld_number

DEFAULT_N_THETA = 96
DEFAULT_N_Z = 12
MAX_ECC = 0.995
CAVITATION = ('swift_stieber', 'gumbel')   # Reynolds (Swift-Stieber) | half-Sommerfeld (Gumbel)


def check_cavitation(cavitation: str) -> str:
    """Return ``cavitation`` if it is one of :data:`CAVITATION`, else raise ValueError naming the choices."""
    if cavitation not in CAVITATION:
        raise ValueError(f"cavitation must be one of {CAVITATION} ('swift_stieber' = Reynolds, 'gumbel' = "
                         f'half-Sommerfeld), got {cavitation!r}')
    return cavitation


@dataclass(frozen=True)
class FilmState:
    """
    Solution of the film at one journal position/velocity (dimensionless).

    P : (n_theta, n_z) pressure over the half bearing (the load-carrying one: >= 0).   force : (2,) dimensionless
    film force on the journal, f = -2 sum P (cos, sin) dtheta dzeta over the full length (multiply by
    mu speed R^4 / c^2 for newtons; Gumbel: of the positive part, :meth:`ReynoldsGrid.positive_part`).   free :
    boolean (n_theta*n_z,) full-film cells (Gumbel: cells with P > 0).
    dforce : (2, 4) d force / d(X, Y, X', Y') (perturbation).
    """

    P: np.ndarray
    force: np.ndarray
    free: np.ndarray
    dforce: np.ndarray | None


class ReynoldsGrid:
    """
    Grid, geometry and operators of the Reynolds equation for one L/D, grid size and groove layout.

    ``grooves``: sequence of (centre, width) [rad] of axial grooves at ambient pressure, centre measured from the
    load line in the spin direction (the literature convention; the load is along -y here).
    """

    def __init__(self, L_over_D: float, n_theta: int = DEFAULT_N_THETA, n_z: int = DEFAULT_N_Z, grooves=()):
        if n_theta < 16 or n_z < 2:
            raise ValueError(f'grid too coarse: n_theta={n_theta} (>= 16), n_z={n_z} (>= 2)')
        self.n, self.m = int(n_theta), int(n_z)
        self.L_over_D = float(L_over_D)
        self.dth = 2 * math.pi / self.n
        self.dz = self.L_over_D / self.m          # half length L/2 over R = L/D
        self.th = np.arange(self.n) * self.dth   # cell centres
        self.th_half = self.th + 0.5 * self.dth  # face i+1/2
        self.cos, self.sin = np.cos(self.th), np.sin(self.th)
        self.cos_h, self.sin_h = np.cos(self.th_half), np.sin(self.th_half)
        groove = np.zeros(self.n, dtype=bool)
        for centre, width in grooves:
            theta_c = -0.5 * math.pi + centre     # load line is -y (theta = -pi/2)
            d = np.angle(np.exp(1j * (self.th - theta_c)))
            groove |= np.abs(d) <= 0.5 * width + 1e-12
        self.groove_cells = np.repeat(groove, self.m)
        # axial second-difference (m x m): Neumann at mid-plane, Dirichlet P = 0 at the end face (half cell)
        Tz = sp.diags([np.ones(self.m - 1), -2 * np.ones(self.m), np.ones(self.m - 1)], [-1, 0, 1]).tolil()
        Tz[0, 0] = -1.0
        Tz[self.m - 1, self.m - 1] = -3.0
        self.Tz = sp.csr_matrix(Tz) / self.dz**2
        self.Im = sp.identity(self.m, format='csr')
        n = self.n
        self._Sp = sp.csr_matrix((np.ones(n), (np.arange(n), (np.arange(n) + 1) % n)), shape=(n, n))  # i -> i+1
        self.w_force = 2 * self.dth * self.dz    # both halves

    # ---------------------------------------------------------------------------------------- operators
    def film(self, X: float, Y: float):
        """H at cell centres and at faces i+1/2 for journal position (X, Y)."""
        return 1 - X * self.cos - Y * self.sin, 1 - X * self.cos_h - Y * self.sin_h

    def operator(self, a_half: np.ndarray, a_cell: np.ndarray):
        """Return div(a grad .) as a scipy.sparse CSR matrix: face coefficients ``a_half`` (i+1/2), axial ``a_cell``."""
        ap = a_half                               # face i+1/2
        am = np.roll(a_half, 1)                   # face i-1/2
        Dth = (sp.diags(-(ap + am)) + sp.diags(ap) @ self._Sp + sp.diags(am) @ self._Sp.T) / self.dth**2
        return (sp.kron(Dth, self.Im) + sp.kron(sp.diags(a_cell), self.Tz)).tocsr()

    def rhs(self, H_half, Hdot_cell):
        """6 dH/dtheta + 12 dH/dtau per cell, flattened (n*m,)."""
        dH = (H_half - np.roll(H_half, 1)) / self.dth
        return np.repeat(6 * dH + 12 * Hdot_cell, self.m)

    def force_of(self, P_flat) -> np.ndarray:
        """Dimensionless film force (2,) on the journal from the flattened half-bearing pressure."""
        Pth = P_flat.reshape(self.n, self.m).sum(axis=1)
        return -self.w_force * np.array([Pth @ self.cos, Pth @ self.sin])

    # ---------------------------------------------------------------------------------------- solve
    def solve(self, X: float, Y: float, Xd: float = 0.0, Yd: float = 0.0, *, derivatives: bool = True,
              max_iter: int = 200, cavitation: str = 'swift_stieber') -> FilmState:
        """
        Pressure at position (X, Y) and velocity (Xd, Yd) = d(X, Y)/d tau.

        ``cavitation``: 'swift_stieber' (Reynolds conditions, default) or 'gumbel' (half-Sommerfeld).
        """
        if math.hypot(X, Y) >= 1.0:
            raise ValueError(f'journal position eps = {math.hypot(X, Y):.4f} is outside the clearance circle')
        H, Hh = self.film(X, Y)
        Hdot = -(Xd * self.cos + Yd * self.sin)
        A = self.operator(Hh**3, H**3)
        Lop = (-A).tocsr()
        q = -self.rhs(Hh, Hdot)
        N = self.n * self.m
        fixed = self.groove_cells
        if check_cavitation(cavitation) == 'gumbel':
            return self._solve_gumbel(Lop, q, fixed, H, Hh, derivatives)
        active = fixed.copy()
        P = np.zeros(N)
        for _ in range(max_iter):
            free = ~active
            Lff = Lop[free][:, free]
            P = np.zeros(N)
            P[free] = spla.spsolve(Lff.tocsc(), q[free])
            lam = Lop @ P - q
            new_active = fixed | (P < lam)
            new_active &= ~((~active) & (P > 0))       # keep positive full-film cells free
            if np.array_equal(new_active, active):
                break
            active = new_active
        else:  # pragma: no cover - the active-set iteration is finite for M-matrices
            raise RuntimeError('Reynolds cavitation (active-set) iteration did not converge')
        free = ~active
        P[active] = 0.0
        force = self.force_of(P)
        dforce = None
        if derivatives:
            dforce = self._perturbation(Lop, free, P, H, Hh)
        return FilmState(P=P.reshape(self.n, self.m), force=force, free=free, dforce=dforce)

    def positive_part(self, P_flat: np.ndarray):
        """
        Return the cell averages g (n*m,) of max(p, 0) and the derivative coefficients (c0, cm, cp).

        p is the piecewise-linear reconstruction of the cell pressures along theta (each half cell linear from the
        cell value to the face mean), so g is continuously differentiable in P: dg_i = c0_i dP_i + cm_i dP_(i-1) +
        cp_i dP_(i+1).  A cell whose neighbourhood is all positive gets (P_(i-1) + 6 P_i + P_(i+1)) / 8 (the
        reconstruction's exact mean, second order), all negative 0.  Used by Gumbel's condition, where the discrete
        rupture line moving from cell to cell would otherwise make K, C jump by O(1/n_theta).
        """
        P = P_flat.reshape(self.n, self.m)
        mL = 0.5 * (np.roll(P, 1, axis=0) + P)
        mR = 0.5 * (P + np.roll(P, -1, axis=0))
        hL, hLa, hLb = _half_cell_positive(mL, P)
        hR, hRa, hRb = _half_cell_positive(P, mR)
        g = 0.5 * (hL + hR)
        c0 = 0.5 * (0.5 * hLa + hLb + hRa + 0.5 * hRb)
        cm = 0.25 * hLa
        cp = 0.25 * hRb
        return g.ravel(), (c0, cm, cp)

    def _solve_gumbel(self, Lop, q, fixed, H, Hh, derivatives: bool) -> FilmState:
        """Full-film (Sommerfeld) pressure over every non-groove cell; the load integrates its positive part."""
        film = ~fixed
        P = np.zeros(self.n * self.m)
        P[film] = spla.spsolve(Lop[film][:, film].tocsc(), q[film])
        g, (c0, cm, cp) = self.positive_part(P)
        force = self.force_of(g)
        dforce = None
        if derivatives:
            def dg(dP):
                d = dP.reshape(self.n, self.m)
                return (c0 * d + cm * np.roll(d, 1, axis=0) + cp * np.roll(d, -1, axis=0)).ravel()
            dforce = self._perturbation(Lop, film, P, H, Hh, loaded=dg)
        return FilmState(P=np.maximum(P, 0.0).reshape(self.n, self.m), force=force, free=P > 0, dforce=dforce)

    def _perturbation(self, Lop, free, P, H, Hh, loaded=None) -> np.ndarray:
        """
        Return d force / d(X, Y, X', Y') from the linearised (perturbation) Reynolds equations.

        The equations are those of the full-film cells ``free``; ``loaded`` (Gumbel) maps a perturbation pressure
        to the perturbation of what the force integrates (default: the pressure itself).
        """
        cols = []
        for dh_cell, dh_half in ((-self.cos, -self.cos_h), (-self.sin, -self.sin_h)):
            dA = self.operator(3 * Hh**2 * dh_half, 3 * H**2 * dh_cell)
            drhs = self.rhs(dh_half, np.zeros(self.n))
            cols.append(dA @ P - drhs)                   # L dP = dA P - d rhs
        for dh_cell in (-self.cos, -self.sin):           # velocity: rhs gains 12 dH/dtau
            cols.append(-np.repeat(12 * dh_cell, self.m))
        B = np.stack(cols, axis=1)[free]
        lu = spla.splu(Lop[free][:, free].tocsc())
        dP = np.zeros((P.size, 4))
        dP[free] = lu.solve(B)
        if loaded is not None:
            return np.stack([self.force_of(loaded(dP[:, k])) for k in range(4)], axis=1)
        return np.stack([self.force_of(dP[:, k]) for k in range(4)], axis=1)


def _half_cell_positive(a, b):
    """
    Return int_0^1 max(a + (b - a) s, 0) ds and its derivatives d/da, d/db (elementwise arrays).

    Continuously differentiable except at a = b = 0 (where every value is 0).
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    pos_a, pos_b = a > 0, b > 0
    d = np.where(pos_a == pos_b, 1.0, a - b)            # a - b where the segment crosses zero (never 0 there)
    both = pos_a & pos_b
    ha = np.where(both, 0.5, 0.0)
    hb = np.where(both, 0.5, 0.0)
    h = np.where(both, 0.5 * (a + b), 0.0)
    down = pos_a & ~pos_b                               # a > 0 >= b: zero at s = a / (a - b)
    h = np.where(down, a * a / (2 * d), h)
    ha = np.where(down, a * (a - 2 * b) / (2 * d * d), ha)
    hb = np.where(down, a * a / (2 * d * d), hb)
    up = ~pos_a & pos_b                                 # a <= 0 < b: d = a - b < 0
    h = np.where(up, b * b / (-2 * d), h)
    ha = np.where(up, b * b / (2 * d * d), ha)
    hb = np.where(up, b * (b - 2 * a) / (2 * d * d), hb)
    return h, ha, hb


@lru_cache(maxsize=32)
def grid_for(L_over_D: float, n_theta: int, n_z: int, grooves: tuple = ()) -> ReynoldsGrid:
    """Return the cached :class:`ReynoldsGrid` (grids are reused across speeds and loads)."""
    return ReynoldsGrid(L_over_D, n_theta, n_z, grooves)


def equilibrium(grid: ReynoldsGrid, load_param: float, start=None, tol: float = 1e-10, max_iter: int = 60,
                cavitation: str = 'swift_stieber'):
    """
    Journal position (X, Y) where the dimensionless film force equals (0, load_param); returns (X, Y, state, err).

    ``load_param`` = W c^2 / (mu speed R^4).  Newton with the perturbation Jacobian, step-halving to stay inside
    the clearance and to decrease the residual.  ``err`` = |F - W| / W at the returned position.  ``cavitation``
    as in :meth:`ReynoldsGrid.solve`.
    """
    check_cavitation(cavitation)
    target = np.array([0.0, load_param])
    z = np.array(start if start is not None else (0.0, -0.5), dtype=float)
    if np.hypot(*z) >= MAX_ECC:
        z *= 0.9 * MAX_ECC / np.hypot(*z)
    st = grid.solve(*z, cavitation=cavitation)
    r = st.force - target
    err = np.linalg.norm(r) / load_param
    for _ in range(max_iter):
        if err <= tol:
            return z[0], z[1], st, err
        J = st.dforce[:, :2]
        step = -np.linalg.solve(J, r)
        lam = 1.0
        while True:
            zn = z + lam * step
            if np.hypot(*zn) < MAX_ECC:
                stn = grid.solve(*zn, cavitation=cavitation)
                rn = stn.force - target
                errn = np.linalg.norm(rn) / load_param
                if errn < err or lam < 1e-6:
                    break
            lam *= 0.5
            if lam < 1e-9:
                raise RuntimeError('finite-bearing equilibrium: no descent step inside the clearance')
        z, st, r, err = zn, stn, rn, errn
    if err > tol:
        raise RuntimeError(f'finite-bearing equilibrium did not converge: relative force error {err:.2e} > {tol:.0e}')
    return z[0], z[1], st, err


def reynolds(D: float, L: float, c: float, mu: float, W: float, speed: float, n_theta: int = DEFAULT_N_THETA,
             n_z: int = DEFAULT_N_Z, *, grooves=(), start=None, tol: float = 1e-10,
             cavitation: str = 'swift_stieber') -> BearingSolution:
    """
    Finite-length bearing equilibrium and perturbation K [N/m], C [N s/m] in our (x, y) frame.

    D, L, c [m]; mu [Pa s]; W [N] static load on the journal along -y; speed [rad/s] > 0.  ``grooves``: axial
    grooves at ambient pressure as (centre, width) [rad] from the load line in the spin direction (default: a plain
    360-degree bearing).  ``start``: journal position (x, y) [m] to start Newton from (default: the short-bearing
    equilibrium).  ``tol``: relative force error |F - W|/W of the equilibrium (<= 1e-8 is the contract).
    ``cavitation``: 'swift_stieber' (Reynolds conditions, default) or 'gumbel' (half-Sommerfeld).
    """
    check_inputs(D, L, c, mu, W, speed)
    check_cavitation(cavitation)
    R = 0.5 * D
    scale = mu * speed * R**4 / c**2                  # newtons per unit dimensionless force
    grid = grid_for(float(L / D), int(n_theta), int(n_z), tuple(tuple(map(float, g)) for g in grooves))
    S = sommerfeld_number(D, L, c, mu, W, speed)
    if start is None:
        eps0 = min(short_eccentricity(S, L / D), 0.9)
        phi0 = short_attitude_angle(eps0)
        z0 = (eps0 * math.sin(phi0), -eps0 * math.cos(phi0))
    else:
        z0 = (start[0] / c, start[1] / c)
    X, Y, st, err = equilibrium(grid, W / scale, z0, tol=tol, cavitation=cavitation)
    dF = st.dforce * scale
    K = -dF[:, :2] / c
    C = -dF[:, 2:] / (c * speed)
    eps = math.hypot(X, Y)
    phi = math.atan2(X, -Y)                           # from the load line (-y) towards +x (spin direction)
    return BearingSolution(eccentricity=eps, attitude_angle=phi, sommerfeld=S, K=K, C=C,
                           journal_position=(X * c, Y * c), model='finite', force_error=float(err))


def film_force(D, L, c, mu, speed, x, y, vx=0.0, vy=0.0, n_theta=DEFAULT_N_THETA, n_z=DEFAULT_N_Z, grooves=(), *,
               cavitation='swift_stieber'):
    """
    Nonlinear film force (Fx, Fy) [N] on the journal at (x, y) [m] moving at (vx, vy) [m/s].

    ``cavitation``: 'swift_stieber' (Reynolds conditions, default) or 'gumbel' (half-Sommerfeld).
    """
    R = 0.5 * D
    grid = grid_for(float(L / D), int(n_theta), int(n_z), tuple(tuple(map(float, g)) for g in grooves))
    st = grid.solve(x / c, y / c, vx / (c * speed), vy / (c * speed), derivatives=False, cavitation=cavitation)
    return st.force * mu * speed * R**4 / c**2


__all__ = ['reynolds', 'film_force', 'equilibrium', 'ReynoldsGrid', 'FilmState', 'grid_for', 'check_cavitation',
           'CAVITATION', 'DEFAULT_N_THETA', 'DEFAULT_N_Z']
