"""
The base of every candidate effect of a diagnosis: a no-op augmentation of the model with its hooks.

:class:`bearing_id.diagnose.predict.Problem` calls the hooks; :mod:`bearing_id.diagnose.effects` holds the effects.
"""
from __future__ import annotations

import numpy as np


class Effect:
    """Base: a no-op augmentation.  Subclasses set ``name``, ``where`` and override the hooks they need."""

    name = 'none'
    n_lin = 0
    acts_on_1x = True        # False for effects seen only off 1X (2X forcing, a sub-synchronous whirl)
    nl_names: tuple = ()
    nl_lo: tuple = ()
    nl_hi: tuple = ()
    key = ''

    def __init__(self):
        self.where = ''

    @property
    def starts(self) -> list:
        """Return the starting points for the nonlinear parameters (several for multi-start)."""
        return [np.zeros(0)]

    # hooks (see predict.Problem) ------------------------------------------------------------------
    def bearing_impedance(self, prob, node, Zb, speed, omega, nl):
        return Zb

    def bearing_factors(self, nl):
        """(viscosity factors, clearance factors) per bearing applied to the bearing theory, or None."""
        return None

    def add_dZ(self, prob, Z, speed, omega, nl):
        return None

    def force_columns(self, prob, k, ratio, nl):
        return None

    def measure_columns(self, prob, k, o, ratio, y_nom, y_perp):
        return None

    # reporting --------------------------------------------------------------------------------------
    def physical(self, nl, lin) -> dict:
        return {}

    def sentence(self, phys: dict, std: dict) -> str:
        return self.name

    def to_extra(self, phys: dict) -> dict:
        return {'effect': self.name, **{k: float(v) for k, v in phys.items()}}

    def conflicts(self, other) -> bool:
        """Return True when this variant cannot be fitted together with ``other`` (besides being the same variant)."""
        return False

    def undetermined(self, phys: dict, std: dict) -> list:
        """Names of the physical parameters the data do not determine (reported as such, not as numbers)."""
        return []

    @property
    def label(self) -> str:
        return f'{self.name} [{self.where}]' if self.where else self.name
