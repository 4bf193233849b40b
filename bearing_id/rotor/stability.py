"""
Stability threshold (onset of oil whirl / whip) of a rotor on speed-dependent journal bearings.

The rotor-bearing system x' = A(speed) x (``rotor.assembly.state_space`` with the bearings' K, C at that speed)
is unstable when an eigenvalue has a positive real part.  :func:`threshold_speed` scans a speed grid for the first
sign change of the largest real part and refines it with brentq; :func:`whirl_ratio` gives the frequency of the
least stable mode over the spin speed (about 0.4-0.5 for oil whirl, the first forward mode's frequency for whip).

Large models (more than ``FAST_NDOF`` DOFs) take :class:`FastStability`: only the least stable modes decide the
onset, so at each speed the ``n_refine`` least stable eigenvalues of a Craig-Bampton reduction (fixed-interface modes
up to ``cutoff_factor`` x the top speed of the search) are refined on the full model
(:class:`bearing_id.rotor.eigen.ReducedEigen`, whose docstring states the method and its assumption: the mode that
goes unstable first is among them, i.e. below the cutoff: the interior modes above it are the shaft's high bending
modes, stiffness-damped and far from the films' cross-coupling).  The refined eigenvalues are the full model's within
LAPACK's error bound of the dense ones (test/test_stability_fast.py).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from .assembly import state_space
from .eigen import least_stable, ReducedEigen


def _eigs(model, bearing_fn, speed: float) -> np.ndarray:
    A, _ = state_space(model, speed, bearing_fn(speed))
    return np.linalg.eigvals(A)


def max_real_part(model, bearing_fn, speed: float) -> float:
    """Largest real part [1/s] of the rotor-bearing eigenvalues at ``speed`` [rad/s] (> 0: unstable)."""
    return float(np.max(_eigs(model, bearing_fn, speed).real))


def whirl_ratio(model, bearing_fn, speed: float) -> float:
    """|Im| / speed of the least stable eigenvalue at ``speed`` [rad/s] (whirl frequency ratio)."""
    lam = _eigs(model, bearing_fn, speed)
    k = int(np.argmax(lam.real))
    return float(abs(lam[k].imag) / speed)


FAST_NDOF = 200            # models with more DOFs take :class:`FastStability` (:func:`max_real_part_fn`)


class FastStability:
    """
    Least stable eigenvalues of a large rotor-bearing model: reduced-model screen, full-model shift-invert refinement.

    ``model`` a RotorModel, ``bearing_fn(speed) -> coeffs``, ``speed_top`` [rad/s] the top of the speeds to be asked
    (sets the reduction's cutoff, ``cutoff_factor`` x speed_top / 2 pi Hz), ``n_refine`` reduced eigenvalues refined
    per speed (upper half plane and real ones; conjugates follow).  The machinery is
    :class:`bearing_id.rotor.eigen.ReducedEigen`; see the module docstring.
    """

    def __init__(self, model, bearing_fn, speed_top: float, *, cutoff_factor: float = 10.0, n_refine: int = 4):
        self.model, self.bearing_fn = model, bearing_fn
        self.n_refine = int(n_refine)
        self.eig = ReducedEigen(model, cutoff_hz=float(cutoff_factor) * float(speed_top) / (2 * math.pi))

    def least_stable(self, speed: float) -> np.ndarray:
        """
        Return the full model's eigenvalues [1/s] nearest the ``n_refine`` least stable reduced ones (Im >= 0).

        At ``speed`` [rad/s].

        Sorted by real part, largest first.
        """
        coeffs = self.bearing_fn(speed)
        lr, V = self.eig.reduced(speed, coeffs, vectors=True)
        cand = least_stable(lr, self.n_refine)
        A = self.eig.pencil(speed, coeffs)
        out = np.array([self.eig.refine(A, lr[j], self.eig.lift(V[:, j]))[0] for j in cand])
        return out[np.argsort(-out.real)]

    def max_real_part(self, speed: float) -> float:
        """Return the largest real part [1/s] of the full model's eigenvalues at ``speed`` [rad/s]."""
        return float(np.max(self.least_stable(speed).real))


def threshold_speed(model, bearing_fn, speed_max: float, speed_min: float | None = None, n_grid: int = 40,
                    xtol: float = 1e-3, scan=None, stop_above: float | None = None) -> float:
    """
    Lowest speed [rad/s] in [speed_min, speed_max] at which the system has an eigenvalue with Re > 0.

    The grid is geometric (``n_grid`` points, default speed_min = speed_max / 20); the crossing is refined with
    brentq to ``xtol`` rad/s.  Returns ``math.inf`` when the system is stable over the whole range.  Raises
    ValueError when it is already unstable at ``speed_min`` (lower it: the threshold is below the range).  The
    largest real part by :func:`max_real_part_fn` (dense below ``FAST_NDOF`` DOFs, :class:`FastStability` above).
    ``scan``: (speeds (n,) increasing [rad/s], largest real part at each (n,) [1/s]) already computed on this model
    and bearings (e.g. :attr:`bearing_id.rotor.modal.Campbell.max_real`): the grid is then those speeds
    (``speed_min``, ``n_grid`` ignored; ``speed_max`` must be the last) and only the bracketing crossing is refined.
    ``stop_above`` [rad/s]: the scan stops at the first stable grid point at or above it and returns ``math.inf``
    (the threshold, if any, lies above that point): what a caller needs who only compares speeds up to it.
    """
    speed_max = float(speed_max)
    if not (math.isfinite(speed_max) and speed_max > 0):
        raise ValueError(f'speed_max must be > 0 rad/s, got {speed_max!r}')
    if scan is not None:
        grid, values = (np.asarray(v, dtype=float) for v in scan)
        if grid.ndim != 1 or grid.shape != values.shape or grid.size < 2 or not np.all(np.diff(grid) > 0) \
                or not grid[0] > 0 or not math.isclose(grid[-1], speed_max, rel_tol=1e-12):
            raise ValueError('scan must be (increasing speeds > 0 ending at speed_max, values) of equal length')
        speed_min = float(grid[0])
    else:
        speed_min = speed_max / 20 if speed_min is None else float(speed_min)
        if not 0 < speed_min < speed_max:
            raise ValueError(f'need 0 < speed_min < speed_max, got {speed_min!r}, {speed_max!r} rad/s')
        grid, values = np.geomspace(speed_min, speed_max, int(n_grid)), None
    f = max_real_part_fn(model, bearing_fn, speed_max)

    def at(i):
        return float(values[i]) if values is not None else f(grid[i])

    prev_f = at(0)
    if prev_f > 0:
        raise ValueError(f'the rotor-bearing system is already unstable at speed_min = {speed_min:.4g} rad/s '
                         f'(max Re = {prev_f:.3g} 1/s); the threshold lies below the range')
    for i in range(1, grid.size):
        if at(i) > 0:
            return float(brentq(f, grid[i - 1], grid[i], xtol=xtol))
        if stop_above is not None and grid[i] >= stop_above:
            break
    return math.inf


def max_real_part_fn(model, bearing_fn, speed_top: float):
    """
    Return f(speed) -> largest real part [1/s] of the rotor-bearing eigenvalues.

    The dense eigenvalues (:func:`max_real_part`) for models up to ``FAST_NDOF`` DOFs, :class:`FastStability` above
    (``speed_top`` [rad/s]: the highest speed f will be asked, its reduction's cutoff).
    """
    if model.ndof > FAST_NDOF:
        return FastStability(model, bearing_fn, speed_top).max_real_part
    return lambda w: max_real_part(model, bearing_fn, w)


__all__ = ['threshold_speed', 'whirl_ratio', 'max_real_part', 'max_real_part_fn', 'FastStability', 'FAST_NDOF']
