"""
A rig's supports as speed-dependent coefficients.

Its identified bearings' ``bearing_fn(rig)`` from the bearing element models (:mod:`bearing_id.bearings`) under the
rotor's static loads (:func:`static_loads`).

* ``bearing_fn(rig, model=None, viscosity_factor=None, clearance_factor=None, loads=None, k_factor=None,
  c_factor=None)`` -> callable ``speed [rad/s] -> {node: (K, C)}`` of the identified bearings (cached per speed), with
  ``.solutions(speed) -> {node: BearingSolution}``.  Known elements (seals, ``identify: false`` bearings) are inside
  the rotor model instead (:meth:`bearing_id.rotor.assembly.RotorModel.known_coefficients`).
"""
from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np

from .assembly import RotorModel, static_bearing_loads
from ..bearings import MODELS, MODELS_ALL, solution


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


_LOADS: dict = {}          # id(rig) -> (rig, loads): the statics of one rig object solved once


def static_loads(rig) -> dict:
    """
    Return the static load [N] per bearing node.

    ``bearing.load`` where given, else the rotor's weight share (statics: a rotor model assembled and solved, ~2 ms;
    kept per rig object, as every bearing function of one identification asks for the same loads).
    """
    hit = _LOADS.get(id(rig))
    if hit is not None and hit[0] is rig:
        return dict(hit[1])
    loads = _static_loads(rig)
    if len(_LOADS) > 64:
        _LOADS.clear()
    _LOADS[id(rig)] = (rig, dict(loads))
    return loads


def _static_loads(rig) -> dict:
    loads = {b.node: b.load for b in rig.bearings}
    tables = {b.node for b in rig.bearings if b.model == 'table'}
    if any(v is None for n, v in loads.items() if n not in tables):
        weight = static_bearing_loads(RotorModel.from_params(rig))
        loads = {n: (weight[n] if v is None else v) for n, v in loads.items()}
    for n, v in loads.items():
        if n in tables:
            continue
        if not v > 0:
            raise ValueError(f'bearing at node {n} carries a static load of {v!r} N: a plain journal bearing needs a '
                             'positive load (give bearings[].load)')
    return loads


class BearingFunction:
    """
    ``speed [rad/s] -> {node: (K, C)}`` for all bearings of a rig, cached per speed.

    Attributes: ``loads`` {node: N}, ``viscosity``/``clearance`` {node: value used}, ``model`` {node: name}.
    """

    def __init__(self, rig, model=None, viscosity_factor=None, clearance_factor=None, loads=None, k_factor=None,
                 c_factor=None):
        nb = len(rig.bearings)
        vf = _per_bearing(viscosity_factor, nb, 'viscosity_factor')
        cf = _per_bearing(clearance_factor, nb, 'clearance_factor')
        kf = _per_bearing(k_factor or None, nb, 'k_factor')
        ccf = _per_bearing(c_factor or None, nb, 'c_factor')
        self.k_scale = {b.node: f for b, f in zip(rig.bearings, kf)}
        self.c_scale = {b.node: f for b, f in zip(rig.bearings, ccf)}
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
                                    clearance=self.clearance[b.node], model=self.model[b.node],
                                    k_scale=self.k_scale[b.node], c_scale=self.c_scale[b.node])
                   for b in self.bearings}
            if len(self._cache) > 4096:
                self._cache.clear()
            self._cache[key] = out
        return out

    def __call__(self, speed: float) -> dict:
        return {n: (s.K.copy(), s.C.copy()) for n, s in self.solutions(speed).items()}


def bearing_fn(rig, model=None, viscosity_factor=None, clearance_factor=None, loads=None, k_factor=None,
               c_factor=None) -> BearingFunction:
    """
    Speed-dependent coefficients of the rig's (identified) bearings: ``fn(speed [rad/s]) -> {node: (K, C)}``.

    ``model`` overrides every short/finite bearing's model; ``viscosity_factor`` / ``clearance_factor`` scale the
    nominal values (a number or one per bearing, in ``rig.bearings`` order); ``k_factor`` / ``c_factor`` scale a
    table bearing's K / C; ``loads`` {node: N} overrides the static loads (default: ``bearing.load`` or the rotor
    weight share from ``rotor.assembly.static_bearing_loads``).  Known elements are in the rotor model instead.
    """
    return BearingFunction(rig, model=model, viscosity_factor=viscosity_factor, clearance_factor=clearance_factor,
                           loads=loads, k_factor=k_factor, c_factor=c_factor)


__all__ = ['bearing_fn', 'BearingFunction', 'static_loads']
