"""
Journal-bearing theory: plain cylindrical bearings as speed-dependent 2x2 stiffness and damping.

* :mod:`.short`     -- closed-form short bearing (Ocvirk, pi film): ``ocvirk(D, L, c, mu, W, speed)``.
* :mod:`.finite`    -- finite-length bearing, Reynolds equation by finite volumes with Reynolds cavitation and the
  perturbation method: ``reynolds(D, L, c, mu, W, speed, n_theta, n_z)`` (the direct solver, 0.1-0.4 s a call).
* :mod:`.finite_table` -- the same bearing from a precomputed dimensionless table vs Sommerfeld number (smooth,
  ~50 us a call; validated against the direct solver, see its docstring).  Model ``'finite'`` below uses the table;
  ``'finite_direct'`` (not a params/rig.yaml choice) the direct solver on its default grid.
* :mod:`.stability` -- onset speed of oil whirl/whip of the rotor on its bearings: ``threshold_speed``.

Both models return a :class:`BearingSolution` (eccentricity, attitude angle, Sommerfeld number, K [N/m] and
C [N s/m] in our (x, y) frame, journal position [m]).  The helpers here apply them to ``params.Bearing`` entries:

* ``coefficients(bearing, speed, load, *, viscosity=None, clearance=None, model=None) -> (K, C)``
* ``solution(...)`` -> the full BearingSolution (for orbit/clearance and Sommerfeld checks)
* ``bearing_fn(rig, model=None, viscosity_factor=None, clearance_factor=None, loads=None)`` -> callable
  ``speed [rad/s] -> {node: (K, C)}`` (cached per speed), with ``.solutions(speed) -> {node: BearingSolution}``.
"""
from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
import math

import numpy as np

from . import finite_table
from .finite import reynolds
from .short import BearingSolution, ocvirk

MODELS = ('short', 'finite')
MODELS_ALL = MODELS + ('finite_direct',)     # 'finite_direct': the direct Reynolds solver (slow, for checks)


def solution(bearing, speed: float, load: float, *, viscosity: float | None = None, clearance: float | None = None,
             model: str | None = None) -> BearingSolution:
    """
    Equilibrium and coefficients of ``bearing`` (params.Bearing) at ``speed`` [rad/s] under ``load`` [N].

    ``viscosity`` [Pa s] and ``clearance`` [m] override the bearing's; ``model`` ('short' | 'finite') overrides
    ``bearing.model``.  Raises ValueError for speed <= 0 (no hydrodynamic film) or a non-positive load.
    """
    model = model or bearing.model
    if model not in MODELS_ALL:
        raise ValueError(f'bearing model must be one of {MODELS}, got {model!r}')
    speed = float(speed)
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f'bearing coefficients need speed > 0 rad/s (no hydrodynamic film at zero speed), '
                         f'got {speed!r} for {bearing.name}')
    mu = float(bearing.viscosity if viscosity is None else viscosity)
    c = float(bearing.clearance if clearance is None else clearance)
    return _solve(model, float(bearing.diameter), float(bearing.length), c, mu, float(load), speed)


@lru_cache(maxsize=8192)
def _solve(model, D, L, c, mu, W, speed) -> BearingSolution:
    """Solve with a cache (identical bearings and repeated calls from the KF/identification cost nothing)."""
    fn = {'short': ocvirk, 'finite': finite_table.solution, 'finite_direct': reynolds}[model]
    s = fn(D, L, c, mu, W, speed)
    s.K.setflags(write=False)      # shared between callers: read-only
    s.C.setflags(write=False)
    return s


def coefficients(bearing, speed: float, load: float, *, viscosity: float | None = None,
                 clearance: float | None = None, model: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(K [N/m], C [N s/m]) 2x2 in our (x, y) frame of ``bearing`` at ``speed`` [rad/s] under ``load`` [N]."""
    s = solution(bearing, speed, load, viscosity=viscosity, clearance=clearance, model=model)
    return s.K, s.C


def _per_bearing(value, nb: int, name: str) -> tuple:
    if value is None:
        return (1.0,) * nb
    if isinstance(value, (int, float, np.floating, np.integer)):
        vals = (float(value),) * nb
    elif isinstance(value, (Sequence, np.ndarray)) and len(value) == nb:
        vals = tuple(float(v) for v in value)
    else:
        raise ValueError(f'{name} must be a number or one factor per bearing ({nb}), got {value!r}')
    if not all(math.isfinite(v) and v > 0 for v in vals):
        raise ValueError(f'{name} factors must be positive and finite, got {vals}')
    return vals


def static_loads(rig) -> dict:
    """
    Return the static load [N] per bearing node.

    ``bearing.load`` where given, else the rotor's weight share (statics).
    """
    loads = {b.node: b.load for b in rig.bearings}
    if any(v is None for v in loads.values()):
        from ..rotor.assembly import RotorModel, static_bearing_loads  # lazy: rotor/ imports nothing from here
        weight = static_bearing_loads(RotorModel.from_params(rig))
        loads = {n: (weight[n] if v is None else v) for n, v in loads.items()}
    for n, v in loads.items():
        if not v > 0:
            raise ValueError(f'bearing at node {n} carries a static load of {v!r} N: a plain journal bearing needs a '
                             'positive load (give bearings[].load)')
    return loads


class BearingFunction:
    """
    ``speed [rad/s] -> {node: (K, C)}`` for all bearings of a rig, cached per speed.

    Attributes: ``loads`` {node: N}, ``viscosity``/``clearance`` {node: value used}, ``model`` {node: name}.
    """

    def __init__(self, rig, model=None, viscosity_factor=None, clearance_factor=None, loads=None):
        nb = len(rig.bearings)
        vf = _per_bearing(viscosity_factor, nb, 'viscosity_factor')
        cf = _per_bearing(clearance_factor, nb, 'clearance_factor')
        if model is not None and model not in MODELS_ALL:
            raise ValueError(f'bearing model must be one of {MODELS}, got {model!r}')
        self.bearings = tuple(rig.bearings)
        self.loads = dict(loads) if loads is not None else static_loads(rig)
        self.viscosity = {b.node: b.viscosity * f for b, f in zip(self.bearings, vf)}
        self.clearance = {b.node: b.clearance * f for b, f in zip(self.bearings, cf)}
        self.model = {b.node: model or b.model for b in self.bearings}
        self._cache: dict = {}

    def solutions(self, speed: float) -> dict:
        """{node: BearingSolution} at ``speed`` [rad/s] (cached)."""
        key = float(speed)
        out = self._cache.get(key)
        if out is None:
            out = {b.node: solution(b, key, self.loads[b.node], viscosity=self.viscosity[b.node],
                                    clearance=self.clearance[b.node], model=self.model[b.node])
                   for b in self.bearings}
            if len(self._cache) > 4096:
                self._cache.clear()
            self._cache[key] = out
        return out

    def __call__(self, speed: float) -> dict:
        return {n: (s.K.copy(), s.C.copy()) for n, s in self.solutions(speed).items()}


def bearing_fn(rig, model=None, viscosity_factor=None, clearance_factor=None, loads=None) -> BearingFunction:
    """
    Speed-dependent coefficients of the rig's bearings: ``fn(speed [rad/s]) -> {node: (K, C)}``.

    ``model`` overrides every bearing's model; ``viscosity_factor`` / ``clearance_factor`` scale the nominal values
    (a number or one per bearing, in ``rig.bearings`` order); ``loads`` {node: N} overrides the static loads
    (default: ``bearing.load`` or the rotor weight share from ``rotor.assembly.static_bearing_loads``).
    """
    return BearingFunction(rig, model=model, viscosity_factor=viscosity_factor, clearance_factor=clearance_factor,
                           loads=loads)


__all__ = ['BearingSolution', 'ocvirk', 'reynolds', 'solution', 'coefficients', 'bearing_fn', 'BearingFunction',
           'static_loads', 'MODELS', 'MODELS_ALL', 'finite_table']
