"""
Journal-bearing theory: plain cylindrical bearings as speed-dependent 2x2 stiffness and damping.

* :mod:`.short`     -- closed-form short bearing (Ocvirk, pi film): ``ocvirk(D, L, c, mu, W, speed)``.
* :mod:`.finite`    -- finite-length bearing, Reynolds equation by finite volumes with Reynolds cavitation and the
  perturbation method: ``reynolds(D, L, c, mu, W, speed, n_theta, n_z)`` (the direct solver, 0.1-0.4 s a call).
* :mod:`.finite_table` -- the same bearing from a precomputed dimensionless table vs Sommerfeld number (smooth,
  ~50 us a call; validated against the direct solver, see its docstring).  Model ``'finite'`` below uses the table;
  ``'finite_direct'`` (not a params/rig.yaml choice) the direct solver on its default grid.
* :mod:`.table`     -- bearings and seals given as K, C tables vs speed (kind 'table'), linear in speed.

Both models return a :class:`BearingSolution` (eccentricity, attitude angle, Sommerfeld number, K [N/m] and
C [N s/m] in our (x, y) frame, journal position [m]).  The helpers here apply them to one ``params.Bearing``:

* ``coefficients(bearing, speed, load, *, viscosity=None, clearance=None, model=None) -> (K, C)``;
  ``coefficients_at(bearing, speeds, load, ...)`` the same at many speeds (K, C (n, 2, 2))
* ``solution(...)`` -> the full BearingSolution (for orbit/clearance and Sommerfeld checks)

A rig's bearings under the rotor's static loads: :func:`bearing_id.rotor.supports.bearing_fn`; the onset of oil
whirl: :mod:`bearing_id.rotor.stability`.

A bearing of kind 'table' is interpolated (``k_scale``/``c_scale`` scale it; the model override and the
viscosity/clearance factors do not apply to it); a short/finite bearing whose static load is not along -y
(``bearing.load_direction``: a load vector, or gravity not along -y) has the coefficients for a load along -y rotated
by :func:`bearing_id.conventions.load_rotation` (the plain journal bearing is axisymmetric); a finite bearing with
``cavitation: gumbel`` uses the tabulated half-Sommerfeld solution like the Swift-Stieber one (``finite_direct``: the
direct Reynolds solver with that condition).
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
import math

import numpy as np

from . import finite_table, table as table_model
from .finite import reynolds
from .short import BearingSolution, ocvirk, ocvirk_batch
from ..conventions import load_rotation

MODELS = ('short', 'finite')
KINDS = ('short', 'finite', 'table')
MODELS_ALL = MODELS + ('finite_direct',)     # 'finite_direct': the direct Reynolds solver (slow, for checks)
CAVITATION = {'short': (None,), 'finite': ('swift_stieber', 'gumbel')}   # the film conditions each model offers


def solution(bearing, speed: float, load: float, *, viscosity: float | None = None, clearance: float | None = None,
             model: str | None = None, k_scale: float = 1.0, c_scale: float = 1.0) -> BearingSolution:
    """
    Equilibrium and coefficients of ``bearing`` (params.Bearing) at ``speed`` [rad/s] under ``load`` [N].

    ``viscosity`` [Pa s] and ``clearance`` [m] override the bearing's; ``model`` ('short' | 'finite') overrides
    ``bearing.model`` (not for a table bearing).  A table bearing gives its interpolated K, C times ``k_scale``,
    ``c_scale`` (eccentricity etc. NaN).  Raises ValueError for speed <= 0 (no hydrodynamic film) or a non-positive
    load of a short/finite bearing.
    """
    if getattr(bearing, 'model', None) == 'table':
        K, C = table_model.coefficients(bearing.table, speed, k_scale, c_scale)
        K.setflags(write=False)
        C.setflags(write=False)
        nan = float('nan')
        return BearingSolution(nan, nan, nan, K, C, (nan, nan), model='table')
    model = model or bearing.model
    if model not in MODELS_ALL:
        raise ValueError(f'bearing model must be one of {MODELS}, got {model!r}')
    speed = float(speed)
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f'bearing coefficients need speed > 0 rad/s (no hydrodynamic film at zero speed), '
                         f'got {speed!r} for {bearing.name}')
    mu = float(bearing.viscosity if viscosity is None else viscosity)
    c = float(bearing.clearance if clearance is None else clearance)
    cav = getattr(bearing, 'cavitation', 'swift_stieber')
    if model in ('finite', 'finite_direct') and cav == 'gumbel':     # the table, or the direct solver
        model = 'finite_gumbel' if model == 'finite' else 'finite_direct_gumbel'
    s = _solve(model, float(bearing.diameter), float(bearing.length), c, mu, float(load), speed)
    if not _load_along_y(bearing):
        s = _rotated(s, tuple(float(v) for v in bearing.load_direction))
    return s


def _rotated(s: BearingSolution, direction: tuple) -> BearingSolution:
    """Return the solution for a film force along ``direction`` (unit vector) from the one along +y."""
    R = load_rotation(direction)
    K, C = R @ s.K @ R.T, R @ s.C @ R.T
    K.setflags(write=False)
    C.setflags(write=False)
    pos = tuple(float(v) for v in R @ np.asarray(s.journal_position, float))
    return dataclasses.replace(s, K=K, C=C, journal_position=pos)


def _load_along_y(bearing) -> bool:
    direction = getattr(bearing, 'load_direction', None)
    return direction is None or tuple(direction) == (0.0, 1.0)


def _gumbel_direct(D, L, c, mu, W, speed) -> BearingSolution:
    return reynolds(D, L, c, mu, W, speed, cavitation='gumbel')


def _gumbel_table(D, L, c, mu, W, speed) -> BearingSolution:
    return finite_table.solution(D, L, c, mu, W, speed, cavitation='gumbel')


@lru_cache(maxsize=8192)
def _solve(model, D, L, c, mu, W, speed) -> BearingSolution:
    """Solve with a cache (identical bearings and repeated calls from the KF/identification cost nothing)."""
    fn = {'short': ocvirk, 'finite': finite_table.solution, 'finite_direct': reynolds, 'finite_gumbel': _gumbel_table,
          'finite_direct_gumbel': _gumbel_direct}[model]
    s = fn(D, L, c, mu, W, speed)
    s.K.setflags(write=False)      # shared between callers: read-only
    s.C.setflags(write=False)
    return s


def coefficients(bearing, speed: float, load: float, *, viscosity: float | None = None,
                 clearance: float | None = None, model: str | None = None, k_scale: float = 1.0,
                 c_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(K [N/m], C [N s/m]) 2x2 in our (x, y) frame of ``bearing`` at ``speed`` [rad/s] under ``load`` [N]."""
    s = solution(bearing, speed, load, viscosity=viscosity, clearance=clearance, model=model, k_scale=k_scale,
                 c_scale=c_scale)
    return s.K, s.C


def coefficients_at(bearing, speeds, load: float, *, viscosity: float | None = None, clearance: float | None = None,
                    model: str | None = None, k_scale: float = 1.0,
                    c_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return :func:`coefficients` at every speed of ``speeds`` (n,) [rad/s]: K [N/m], C [N s/m] (n, 2, 2).

    A short bearing loaded along -y in one :func:`.short.ocvirk_batch` (the same computation as :func:`.short.ocvirk`,
    without a call per speed), any other one speed by speed; ``k_scale``, ``c_scale`` scale a table bearing.
    """
    speeds = np.asarray(speeds, dtype=float).reshape(-1)
    if (model or bearing.model) == 'short' and bearing.model != 'table' and _load_along_y(bearing):
        c = float(bearing.clearance if clearance is None else clearance)
        mu = float(bearing.viscosity if viscosity is None else viscosity)
        if not np.all(np.isfinite(speeds) & (speeds > 0)):
            raise ValueError(f'bearing coefficients need speed > 0 rad/s (no hydrodynamic film at zero speed), '
                             f'got {speeds!r} for {bearing.name}')
        return ocvirk_batch(float(bearing.diameter), float(bearing.length), c, mu, float(load), speeds)
    pairs = [coefficients(bearing, w, load, viscosity=viscosity, clearance=clearance, model=model, k_scale=k_scale,
                          c_scale=c_scale) for w in speeds]
    return np.array([k for k, _ in pairs]).reshape(-1, 2, 2), np.array([c for _, c in pairs]).reshape(-1, 2, 2)


__all__ = ['BearingSolution', 'ocvirk', 'reynolds', 'solution', 'coefficients', 'coefficients_at', 'MODELS',
           'MODELS_ALL', 'KINDS', 'finite_table', 'table_model']
