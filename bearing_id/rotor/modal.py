"""
Modal analysis of the rotor: damped modes with whirl direction, free-free modes, Campbell data, critical speeds.

All frequencies in rad/s.  A mode with eigenvalue lambda = sigma + j wd (wd > 0) has damped frequency wd, natural
frequency |lambda|, damping ratio zeta = -sigma / |lambda| and logarithmic decrement delta = -2 pi sigma / wd
(negative = unstable).  Whirl direction from :func:`bearing_id.conventions.whirl_direction` of the node orbits
(x, y phasors of the mode shape), voted with each node's orbit size.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh
from scipy.optimize import brentq

from .assembly import RotorModel, state_space
from .eigen import least_stable, ReducedEigen
from ..conventions import DOF_PER_NODE, LOCAL_DOF, orbit_semi_axes, whirl_direction


@dataclass(frozen=True)
class DampedModes:
    """
    The lowest ``n`` underdamped modes at one speed, sorted by damped frequency.

    frequency : (n,) damped natural frequency wd [rad/s].   natural_frequency : (n,) |lambda| [rad/s].
    damping_ratio : (n,) [-].   log_dec : (n,) [-].   whirl : tuple of 'forward' | 'backward'.
    eigenvalues : (n,) complex [1/s].   shapes : (4 n_nodes, n) complex displacement part of the eigenvectors on
    the rotor's DOFs (pedestal DOFs, if any, left out).   max_real : the largest real part of ALL the system's
    eigenvalues [1/s] (> 0: unstable; over- and highly damped ones included).
    """

    frequency: np.ndarray
    natural_frequency: np.ndarray
    damping_ratio: np.ndarray
    log_dec: np.ndarray
    whirl: tuple
    eigenvalues: np.ndarray
    shapes: np.ndarray
    max_real: float = float('nan')


def mode_whirl(model: RotorModel, shape: np.ndarray) -> str:
    """'forward' or 'backward' for a complex mode shape (ndof,), voting the node orbits by their size."""
    n = DOF_PER_NODE * model.n_nodes             # rotor DOFs only (pedestal DOFs follow them)
    X = shape[LOCAL_DOF['x']:n:DOF_PER_NODE]
    Y = shape[LOCAL_DOF['y']:n:DOF_PER_NODE]
    score = 0.0
    for xi, yi in zip(X, Y):
        major, _ = orbit_semi_axes(xi, yi)
        score += major if whirl_direction(xi, yi) == 'forward' else -major
    return 'forward' if score >= 0 else 'backward'


def damped_modes(model: RotorModel, speed: float, coeffs: dict, n: int = 8) -> DampedModes:
    """
    Damped modes of the rotor on bearings ``coeffs`` at spin ``speed`` [rad/s]; the lowest ``n`` by wd.

    Overdamped (real) eigenvalues and nearly so (zeta > 0.99995: :func:`underdamped`) are not modes of vibration
    and are left out.
    """
    A, _ = state_space(model, speed, coeffs)
    lam, V = np.linalg.eig(A)
    return _modes(model, lam, V, float(np.max(lam.real)), n)


def underdamped(lam: np.ndarray) -> np.ndarray:
    """
    Return which eigenvalues ``lam`` [1/s] are modes of vibration: Im > ``UNDERDAMPED_RTOL`` |lambda| (bool mask).

    Im / |lambda| = sqrt(1 - zeta^2): 1e-2 leaves out zeta > 0.99995 (log dec > 630).  Such eigenvalues do not
    vibrate; a large stiff model has many of them (a 160-element rotor with seals, dense eigenvalues at 4000 rpm: 148
    x/y pairs of heavily damped element modes with Im / |lambda| ~ 1e-5 ... 1.2e-3 -- genuinely complex, Im 2e7 x
    LAPACK's error bound or more -- listed as "modes" at 0.06 ... 150 Hz with log dec 5e3 ... 1e7 under the former
    1e-9 threshold, and invisible to the reduced screen).
    """
    lam = np.asarray(lam)
    return lam.imag > UNDERDAMPED_RTOL * np.maximum(1.0, np.abs(lam))


def _modes(model: RotorModel, lam: np.ndarray, V: np.ndarray, max_real: float, n: int) -> DampedModes:
    """Return the DampedModes of the lowest ``n`` underdamped eigenpairs (lam (k,), state vectors (2 ndof, k))."""
    keep = underdamped(lam)
    lam, V = lam[keep], V[:, keep]
    order = np.argsort(lam.imag)[:n]
    lam, V = lam[order], V[:DOF_PER_NODE * model.n_nodes, order]
    wn = np.abs(lam)
    zeta = -lam.real / wn
    logdec = -2.0 * np.pi * lam.real / lam.imag
    whirl = tuple(mode_whirl(model, V[:, k]) for k in range(V.shape[1]))
    return DampedModes(frequency=lam.imag.copy(), natural_frequency=wn, damping_ratio=zeta, log_dec=logdec,
                       whirl=whirl, eigenvalues=lam, shapes=V, max_real=max_real)


UNDERDAMPED_RTOL = 1e-2   # Im / |lambda| below this (zeta > 0.99995) is no mode of vibration: see underdamped()
FAST_NDOF = 100           # models with more DOFs take :class:`FastModes` (:func:`modes_solver`)
N_LEAST_STABLE = 4        # reduced eigenvalues refined for the largest real part (as rotor.stability.FastStability)
CROSSING_RTOL = 1e-3      # a critical speed: some forward mode's frequency within this of the speed (relative)
CRITICAL_XTOL = 1e-7      # relative precision of a critical speed (0.001 rpm at 10,000 rpm; its model is not better)
CUTOFF_WIDENINGS = 2      # times a FastModes doubles its reduction's cutoff in all (then speeds are solved densely)


class FastModes:
    """
    The lowest damped modes of a large model without its dense eigen-decomposition.

    :class:`bearing_id.rotor.eigen.ReducedEigen` with the cutoff at ``cutoff_factor`` x the larger of ``speed_top``
    [rad/s] and the n-th mode's frequency at ``speed_top`` on ``coeffs_top`` (from the reduced screen, re-reduced
    until it is below the cutoff's third; no dense solve; without ``coeffs_top``, ``cutoff_factor`` x
    ``speed_top``): the reduced model's lowest ``n`` underdamped modes and its
    ``N_LEAST_STABLE`` least stable eigenvalues are refined on the full model, so the frequencies, damping, shapes
    and the largest real part are the full model's (within the dense eigenvalues' error bound).  The n-th reduced
    mode above half the cutoff at a speed, fewer than ``n`` reduced modes, or two refinements landing on one full
    eigenvalue: the cutoff is doubled (up to ``CUTOFF_WIDENINGS`` times in all, kept for later speeds); a speed where
    it still fails is solved densely (counted in ``fallbacks``).
    """

    def __init__(self, model: RotorModel, speed_top: float, coeffs_top: dict | None = None, n: int = 8,
                 cutoff_factor: float = 3.0):
        self.model = model
        top = float(speed_top)
        cut = float(cutoff_factor) * top
        self.eig = ReducedEigen(model, cutoff_hz=cut / (2 * np.pi))
        for _ in range(CUTOFF_WIDENINGS if coeffs_top is not None else 0):
            # the n-th mode at the top speed from the reduced screen itself (it errs high: a Ritz value)
            lr = self.eig.reduced(top, coeffs_top)
            f = np.sort(lr.imag[underdamped(lr)])
            need = float(cutoff_factor) * max(top, float(f[n - 1]) if f.size >= n else 2.0 * cut / cutoff_factor)
            if need <= cut:
                break
            cut = need
            self.eig = ReducedEigen(model, cutoff_hz=cut / (2 * np.pi))
        self.fallbacks, self.widenings = 0, 0

    def damped_modes(self, speed: float, coeffs: dict, n: int = 8) -> DampedModes:
        """As :func:`damped_modes` (the same numbers to refinement precision)."""
        while True:
            got = self._refined(speed, coeffs, n)
            if got is not None:
                return got
            if self.widenings >= CUTOFF_WIDENINGS:
                return self._dense(speed, coeffs, n)
            # the n-th mode lies above half the cutoff here (e.g. a speed where the bearings are softer), or two
            # reduced estimates were too coarse to refine apart (close x / y pairs): widen the reduction once for
            # all later speeds rather than solve every such speed densely
            self.eig = ReducedEigen(self.model, cutoff_hz=2.0 * self.eig.cutoff / (2 * np.pi))
            self.widenings += 1

    def _refined(self, speed, coeffs, n):
        """
        Return the lowest ``n`` modes from the current reduction, refined; None when it is too coarse for them here.

        The reduced modes are refined in order of frequency; one that lands on an eigenvalue that is no mode of
        vibration (a mode becoming overdamped at this speed: :func:`underdamped`) is left out, as the dense
        solution leaves it out, and the next one taken.
        """
        eig = self.eig
        lr, Vr = eig.reduced(speed, coeffs, vectors=True)
        under = np.flatnonzero(underdamped(lr))
        A = eig.pencil(speed, coeffs)
        got, low = {}, []
        for j in under[np.argsort(lr[under].imag)].tolist():
            if len(low) == n:
                break
            got[j] = eig.refine(A, lr[j], eig.lift(Vr[:, j]))
            if underdamped(got[j][0]):
                low.append(j)
        if len(low) < n or lr[low[-1]].imag > 0.5 * eig.cutoff:
            return None
        least = least_stable(lr, N_LEAST_STABLE)
        for j in least.tolist():
            if j not in got:
                got[j] = eig.refine(A, lr[j], eig.lift(Vr[:, j]))
        lam = np.array([got[j][0] for j in low])
        gap = np.abs(lam[:, None] - lam[None, :])
        np.fill_diagonal(gap, np.inf)
        if np.min(gap) <= 1e-8 * np.max(np.abs(lam)):
            return None
        V = np.column_stack([got[j][1] for j in low])
        max_real = max(float(np.max(lam.real)), max(float(got[j][0].real) for j in least))
        return _modes(self.model, lam, V, max_real, n)

    def _dense(self, speed, coeffs, n):
        self.fallbacks += 1
        return damped_modes(self.model, speed, coeffs, n)


def modes_solver(model: RotorModel, speed_top: float, bearing_fn=None, n: int = 8):
    """
    Return f(speed, coeffs, n) -> DampedModes for ``model``.

    :func:`damped_modes` (dense) for models up to ``FAST_NDOF`` DOFs, :class:`FastModes` above.  ``speed_top``
    [rad/s]: the highest speed to be asked; with ``bearing_fn`` and ``n`` (the most modes to be asked) the fast
    path's reduction keeps modes up to 3 x the n-th one there.
    """
    if model.ndof > FAST_NDOF:
        top = float(speed_top)
        return FastModes(model, top, bearing_fn(top) if bearing_fn is not None else None, n).damped_modes
    return lambda speed, coeffs, n: damped_modes(model, speed, coeffs, n)


def modes_below(model: RotorModel, bearing_fn, speed: float, frequency: float) -> int:
    """
    Return how many modes of vibration ``model`` has below ``frequency`` [rad/s] at ``speed`` [rad/s].

    Dense eigenvalues up to ``FAST_NDOF`` DOFs; above, those of the Craig-Bampton screen with its cutoff at 3 x
    ``frequency`` (Ritz values: each mode lies a little below its screen value, so a count at the margin may be one
    pair short).
    """
    coeffs = bearing_fn(speed)
    if model.ndof > FAST_NDOF:
        lam = ReducedEigen(model, cutoff_hz=3.0 * frequency / (2 * np.pi)).reduced(speed, coeffs)
    else:
        lam = np.linalg.eigvals(state_space(model, speed, coeffs)[0])
    return int(np.sum(underdamped(lam) & (lam.imag <= frequency)))


def free_free_frequencies(model: RotorModel, n: int = 4, return_shapes: bool = False):
    """
    Lowest ``n`` elastic free-free bending frequencies [rad/s] at zero speed (no bearings).

    Solved in the x-z plane (x, ty DOFs; the y-z plane gives the same frequencies); the two rigid-body modes
    (translation, tilt) are excluded.  With ``return_shapes`` also the (n_nodes,) lateral shapes (n_nodes, n).
    """
    idx = np.sort(np.concatenate([np.arange(model.n_nodes) * DOF_PER_NODE + LOCAL_DOF['x'],
                                  np.arange(model.n_nodes) * DOF_PER_NODE + LOCAL_DOF['ty']]))
    K = model.K[np.ix_(idx, idx)]
    M = model.M[np.ix_(idx, idx)]
    w2, V = eigh(K, M)
    w2, V = w2[2:2 + n], V[:, 2:2 + n]
    w = np.sqrt(np.clip(w2, 0.0, None))
    if return_shapes:
        return w, V[0::2]
    return w


@dataclass(frozen=True)
class Campbell:
    """
    Campbell data.

    ``speeds`` (ns,) [rad/s]; ``frequency``, ``log_dec``, ``damping_ratio`` (ns, n); ``whirl`` (ns, n) array of
    'forward'/'backward'; ``max_real`` (ns,) the largest real part of all the eigenvalues at each speed [1/s] (the
    stability scan of :func:`bearing_id.rotor.stability.threshold_speed`, for free with the modes).
    """

    speeds: np.ndarray
    frequency: np.ndarray
    damping_ratio: np.ndarray
    log_dec: np.ndarray
    whirl: np.ndarray
    max_real: np.ndarray | None = None


def campbell(model: RotorModel, speeds, bearing_fn, n: int = 8, solver=None) -> Campbell:
    """
    Damped modes over ``speeds`` [rad/s] with speed-dependent bearings ``bearing_fn(speed) -> coeffs``.

    Modes are ordered by frequency at each speed (no mode tracking); NaN where fewer than ``n`` modes exist.
    The modes by :func:`modes_solver` (or a ``solver`` from it).
    """
    speeds = np.asarray(speeds, dtype=float)
    modes = solver or modes_solver(model, float(np.max(speeds)), bearing_fn, n)
    F = np.full((speeds.size, n), np.nan)
    Z = np.full_like(F, np.nan)
    D = np.full_like(F, np.nan)
    Wh = np.full(F.shape, '', dtype=object)
    mr = np.full(speeds.size, np.nan)
    for i, s in enumerate(speeds):
        m = modes(s, bearing_fn(s), n)
        k = m.frequency.size
        F[i, :k], Z[i, :k], D[i, :k] = m.frequency, m.damping_ratio, m.log_dec
        Wh[i, :k] = m.whirl
        mr[i] = m.max_real
    return Campbell(speeds=speeds, frequency=F, damping_ratio=Z, log_dec=D, whirl=Wh, max_real=mr)


def _forward_frequencies(modes, speed, bearing_fn, n):
    m = modes(speed, bearing_fn(speed), n)
    return np.array([f for f, w in zip(m.frequency, m.whirl) if w == 'forward'])


def forward_frequencies(cb: Campbell) -> list:
    """Return, per speed of a :class:`Campbell`, its forward-whirl damped frequencies [rad/s] in ascending order."""
    return [np.array([f for f, w in zip(cb.frequency[i], cb.whirl[i]) if w == 'forward' and np.isfinite(f)])
            for i in range(cb.speeds.size)]


def critical_speeds(model: RotorModel, bearing_fn, speed_range, n_grid: int = 60, n_modes: int = 8, *,
                    campbell_grid: Campbell | None = None, solver=None) -> np.ndarray:
    """
    Return the synchronous critical speeds [rad/s]: where a forward-whirl damped frequency crosses the 1X line.

    ``speed_range`` = (lo, hi) [rad/s], lo > 0.  The k-th forward mode's wd(Omega) - Omega is sampled on ``n_grid``
    speeds, each sign change refined with Brent's method and kept only where a forward mode's frequency is within
    ``CROSSING_RTOL`` of the speed (a sign change from two modes swapping order is no crossing).  Returns the sorted
    crossings inside the range.
    ``campbell_grid``: a :func:`campbell` of the same model and bearings with ``n_modes`` modes on exactly that grid
    (``linspace(lo, hi, n_grid)``), whose modes are then reused instead of recomputed (the same numbers).
    The modes by :func:`modes_solver` (or a ``solver`` from it).
    """
    lo, hi = map(float, speed_range)
    if not 0 < lo < hi:
        raise ValueError('speed_range must be (lo, hi) with 0 < lo < hi [rad/s]')
    modes = solver or modes_solver(model, hi, bearing_fn, n_modes)
    grid = np.linspace(lo, hi, n_grid)
    if campbell_grid is not None and campbell_grid.speeds.shape == grid.shape \
            and np.array_equal(campbell_grid.speeds, grid) and campbell_grid.frequency.shape[1] == n_modes:
        fw = forward_frequencies(campbell_grid)
    else:
        fw = [_forward_frequencies(modes, s, bearing_fn, n_modes) for s in grid]
    kmax = min(len(f) for f in fw)
    known = dict(zip(grid.tolist(), fw))          # forward frequencies by speed: the grid's, then every one solved

    def forward(s):
        if s not in known:
            known[s] = _forward_frequencies(modes, s, bearing_fn, n_modes)
        return known[s]

    out = []
    for k in range(kmax):
        g = np.array([f[k] for f in fw]) - grid
        for i in np.nonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)[0]:
            def h(s, k=k):
                f = forward(float(s))
                return (f[k] if k < len(f) else np.nan) - s
            try:
                s = brentq(h, grid[i], grid[i + 1], xtol=CRITICAL_XTOL * grid[i + 1], rtol=CRITICAL_XTOL)
            except ValueError:  # mode order changed inside the bracket: the linear estimate, checked below
                s = grid[i] - g[i] * (grid[i + 1] - grid[i]) / (g[i + 1] - g[i])
            # a crossing is a forward mode at the 1X line; a sign change from modes swapping order is none
            f = forward(float(s))
            if f.size and np.min(np.abs(f - s)) <= CROSSING_RTOL * s:
                out.append(s)
    return np.array(sorted(out))


__all__ = ['DampedModes', 'damped_modes', 'modes_below', 'mode_whirl', 'free_free_frequencies', 'Campbell', 'campbell',
           'critical_speeds', 'forward_frequencies', 'FastModes', 'modes_solver', 'FAST_NDOF']
