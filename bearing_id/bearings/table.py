"""
Bearings and seals given as tables: K and C (2x2, our (x, y) frame) versus speed, as vendors, seal codes and ROSS give.

Interpolation between the table's speeds, each of the 8 coefficients on its own: linear (the default), or ``cubic``
(scipy's not-a-knot ``CubicSpline`` through the rows; what ``bearing-id import-ross`` writes, sampled from ROSS's
own spline).  Outside the table the first or last row is held -- a table says nothing beyond its ends, so
:func:`outside` tells the callers that must flag it.  A one-row table is constant.  Force on the shaft
f = -K q - C q' (see :mod:`bearing_id.conventions`).

``physical`` parametrises a table bearing by scale factors on its coefficients
(:data:`bearing_id.identify.physical.TABLE_FORMS`): K(speed) = k_scale K_table(speed), C(speed) = c_scale C_table(speed)
in the simplest form.
"""
from __future__ import annotations

from functools import lru_cache
import math

import numpy as np
from scipy.interpolate import CubicSpline


def table_arrays(table) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (speeds (n,) [rad/s], K (n, 2, 2) [N/m], C (n, 2, 2) [N s/m]) of a ``params.BearingTable``."""
    return (np.asarray(table.speeds, dtype=float), np.asarray(table.K, dtype=float).reshape(-1, 2, 2),
            np.asarray(table.C, dtype=float).reshape(-1, 2, 2))


@lru_cache(maxsize=256)
def _spline(table) -> CubicSpline:
    """Return the not-a-knot cubic spline of all 8 coefficients (n, 8) through the rows of a (frozen) table."""
    s, K, C = table_arrays(table)
    return CubicSpline(s, np.concatenate([K.reshape(-1, 4), C.reshape(-1, 4)], axis=1), axis=0)


def outside(table, speed: float) -> bool:
    """Return True when ``speed`` [rad/s] lies outside the table's rows (beyond 1e-9 relative): a held value."""
    s = table.speeds
    return len(s) > 1 and not (s[0] * (1 - 1e-9) <= float(speed) <= s[-1] * (1 + 1e-9))


def interpolate(table, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (K, C) 2x2 of ``table`` at ``speed`` [rad/s]: linear or cubic between the rows, held flat outside.

    Raises ValueError for a non-finite speed.
    """
    speed = float(speed)
    if not math.isfinite(speed):
        raise ValueError(f'table bearing: speed must be finite, got {speed!r}')
    s, K, C = table_arrays(table)
    if speed <= s[0]:
        return K[0].copy(), C[0].copy()
    if speed >= s[-1]:
        return K[-1].copy(), C[-1].copy()
    if getattr(table, 'interpolation', 'linear') == 'cubic' and s.size >= 3:
        v = _spline(table)(speed)
        return v[:4].reshape(2, 2), v[4:].reshape(2, 2)
    i = int(np.searchsorted(s, speed, side='right')) - 1
    t = (speed - s[i]) / (s[i + 1] - s[i])
    return (1.0 - t) * K[i] + t * K[i + 1], (1.0 - t) * C[i] + t * C[i + 1]


def coefficients(table, speed: float, k_scale: float = 1.0, c_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(k_scale K, c_scale C) of ``table`` at ``speed`` [rad/s]."""
    K, C = interpolate(table, speed)
    return k_scale * K, c_scale * C


__all__ = ['interpolate', 'coefficients', 'table_arrays', 'outside']
