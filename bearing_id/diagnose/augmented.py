"""
The augmented model of a diagnosis, in the form identification consumes (``bearing-id diagnose --identify``).

An augmented params file (``extra: {effects: [...]}``, written by :func:`report.write_params`) holds three kinds of
physics the nominal model left out, and each enters identification at a different place:

* measurement effects (``probe_runout``, ``probe_orientation``) -> :meth:`AugmentedModel.correct_data` removes them
  from the measured 1X phasors (runout vector subtracted; a turned/gained probe re-projected with its perpendicular
  partner at the same node);
* force effects (``residual_unbalance``, ``shaft_bow``; ``misalignment`` is 2X and does not enter a 1X fit) ->
  :meth:`AugmentedModel.extra_forces` adds them to the known excitation of every run;
* model effects (``support_flexibility``, ``disc_mass_error``) -> :meth:`AugmentedModel.dynamic_stiffness`, the
  hook the ``physical`` and ``direct`` methods call instead of the rotor's dynamic stiffness with the bearings
  inserted directly (``options={'augment': AugmentedModel}``).

Units SI; phasors as in :mod:`bearing_id.conventions`.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import effects as fx


class AugmentedModel:
    """
    Hook object for identification on the augmented model.

    Parameters
    ----------
    model : rotor.assembly.RotorModel (no bearings) of the *nominal* rig.
    rig : RigParams whose ``extra['effects']`` holds the augmentations (an augmented params file).

    Protocol used by :mod:`bearing_id.identify.physical` / :mod:`bearing_id.identify.direct`:
    ``dynamic_stiffness(speed, omega, coeffs) -> Z (ndof, ndof)`` and ``extra_forces(speed) -> {ratio: F (ndof,)}``.

    """

    def __init__(self, model, rig):
        self.model, self.rig = model, rig
        self._effects = fx.effects_from_extra(rig)
        self._corrections = fx.measurement_corrections(rig)

    @property
    def names(self) -> list:
        return [e.name for e, _, _ in self._effects] + [d['effect'] for d in self._corrections]

    def dynamic_stiffness(self, speed: float, omega: float, coeffs: dict) -> np.ndarray:
        """
        Return Z (ndof, ndof) of the rotor on ``coeffs`` ({node: (K, C)}) with the model effects.

        At spin ``speed`` and frequency ``omega`` [rad/s].
        """
        return fx.augmented_dynamic_stiffness(self.model, self.rig, speed, omega, coeffs, effects=self._effects)

    def extra_forces(self, speed: float) -> dict:
        """{ratio: F (ndof,) complex [N]} of the force effects at ``speed`` [rad/s]."""
        return fx.augmented_forces(self.model, self.rig, speed, effects=self._effects)

    def correct_phasors(self, X: np.ndarray, probes) -> np.ndarray:
        """
        Measured 1X phasors X (..., nch) [m] with the measurement effects removed (a corrected copy).

        Runout vectors are subtracted first.  Turned/gained probes are undone per x/y pair: the pair's readings are
        r = T u with T's row for a turned probe g (cos a e_self + sin a e_perp) (its axis turned by a towards +90 deg,
        e_perp = +y for an x probe, -x for a y probe) and the unit row for an untouched one; u = T^-1 r.  This undoes a
        single turned probe and a pair turned together alike (each reading is re-projected with the partner's
        *displacement*, not its reading).
        """
        X = np.array(X, dtype=complex, copy=True)
        names = [p.name for p in probes]
        for d in self._corrections:
            if d['effect'] == 'probe_runout' and d['probe'] in names:
                X[..., names.index(d['probe'])] -= d['runout'] * np.exp(1j * math.radians(d.get('phase_deg', 0.0)))
        by_node: dict = {}
        for d in self._corrections:
            if d['effect'] == 'probe_orientation' and d['probe'] in names:
                by_node.setdefault(probes[names.index(d['probe'])].node, []).append(d)
        for node, ds in by_node.items():
            ix = next((k for k, q in enumerate(probes) if q.node == node and q.direction == 'x'), None)
            iy = next((k for k, q in enumerate(probes) if q.node == node and q.direction == 'y'), None)
            if ix is None or iy is None:
                continue            # no partner to re-project with: left as measured
            T = np.eye(2)
            for d in ds:
                a, g = math.radians(d['angle_deg']), float(d.get('gain', 1.0))
                if probes[names.index(d['probe'])].direction == 'x':
                    T[0] = g * np.array([math.cos(a), math.sin(a)])
                else:
                    T[1] = g * np.array([-math.sin(a), math.cos(a)])
            Ti = np.linalg.inv(T)
            rx, ry = X[..., ix].copy(), X[..., iy].copy()
            X[..., ix] = Ti[0, 0] * rx + Ti[0, 1] * ry
            X[..., iy] = Ti[1, 0] * rx + Ti[1, 1] * ry
        return X

    def correct_data(self, data):
        """Return a copy of harmonic data (``identify.harmonics.HarmonicData``) with the measurement effects removed."""
        plain = getattr(data, 'plain', None)        # the paper method's plain fits: their phasors corrected alike
        if plain is not None:
            plain = dataclasses.replace(plain, X=self.correct_phasors(plain.X, data.probes))
        return dataclasses.replace(data, X=self.correct_phasors(data.X, data.probes), plain=plain)


__all__ = ['AugmentedModel']
