"""
Stability threshold (onset of oil whirl / whip) of a rotor on speed-dependent journal bearings.

The rotor-bearing system x' = A(speed) x (``rotor.assembly.state_space`` with the bearings' K, C at that speed)
is unstable when an eigenvalue has a positive real part.  :func:`threshold_speed` scans a speed grid for the first
sign change of the largest real part and refines it with brentq; :func:`whirl_ratio` gives the frequency of the
least stable mode over the spin speed (about 0.4-0.5 for oil whirl, the first forward mode's frequency for whip).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def _eigs(model, bearing_fn, speed: float) -> np.ndarray:
    from ..rotor.assembly import state_space  # lazy: keeps bearings/ importable without the rotor package
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


def threshold_speed(model, bearing_fn, speed_max: float, speed_min: float | None = None, n_grid: int = 40,
                    xtol: float = 1e-3) -> float:
    """
    Lowest speed [rad/s] in [speed_min, speed_max] at which the system has an eigenvalue with Re > 0.

    The grid is geometric (``n_grid`` points, default speed_min = speed_max / 20); the crossing is refined with
    brentq to ``xtol`` rad/s.  Returns ``math.inf`` when the system is stable over the whole range.  Raises
    ValueError when it is already unstable at ``speed_min`` (lower it: the threshold is below the range).
    """
    speed_max = float(speed_max)
    if not (math.isfinite(speed_max) and speed_max > 0):
        raise ValueError(f'speed_max must be > 0 rad/s, got {speed_max!r}')
    speed_min = speed_max / 20 if speed_min is None else float(speed_min)
    if not 0 < speed_min < speed_max:
        raise ValueError(f'need 0 < speed_min < speed_max, got {speed_min!r}, {speed_max!r} rad/s')
    grid = np.geomspace(speed_min, speed_max, int(n_grid))

    def f(w):
        return max_real_part(model, bearing_fn, w)

    prev_w, prev_f = grid[0], f(grid[0])
    if prev_f > 0:
        raise ValueError(f'the rotor-bearing system is already unstable at speed_min = {speed_min:.4g} rad/s '
                         f'(max Re = {prev_f:.3g} 1/s); the threshold lies below the range')
    for w in grid[1:]:
        fw = f(w)
        if fw > 0:
            return float(brentq(f, prev_w, w, xtol=xtol))
        prev_w, prev_f = w, fw
    return math.inf


__all__ = ['threshold_speed', 'whirl_ratio', 'max_real_part']
