"""
The base of every candidate effect of a diagnosis: a no-op augmentation of the model with its hooks.

:class:`bearing_id.diagnose.predict.Problem` calls the hooks; :mod:`bearing_id.diagnose.effects` holds the effects.
"""
from __future__ import annotations

import numpy as np

DETERMINED_REL = 0.075    # a parameter is reported as a number when its 1-sigma is <= 7.5 % (2 sigma <= 15 %)


def determined(value: float, std) -> bool:
    """Return True when ``value`` is determined: finite 1-sigma at most ``DETERMINED_REL`` of |value|."""
    return std is not None and bool(np.isfinite(std)) and abs(std) <= DETERMINED_REL * abs(value) and value != 0


def pm(value, std) -> str:
    """Return ' ± p %' for ``value`` with 1-sigma ``std`` ('' without one; a note when it is not finite)."""
    if std is None or value == 0:
        return ''
    if not np.isfinite(std):
        return ' (1σ not determined)'
    pct = abs(std / value) * 100
    return f' ± {pct:.0f} %' if pct >= 9.5 else f' ± {pct:.2g} %'


class Effect:
    """Base: a no-op augmentation.  Subclasses set ``name``, ``where`` and override the hooks they need."""

    name = 'none'
    n_lin = 0
    acts_on_1x = True        # False for effects seen only off 1X (2X forcing, a sub-synchronous whirl)
    # True when the effect's whole signature is its 1X response: identify's 1X vectors at the noise floor can then
    # judge it against a rival of that kind (False where it also lives at 2X/3X, DC or sub-synchronous)
    only_1x = True
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

    def missing_signature(self, phys: dict, std: dict) -> str | None:
        """
        Return why this effect's own signature is absent from its fit (None: present, the default).

        An effect that validates but lacks its signature (a crack without its 3X, ...) is not accepted.
        """
        return None

    def undetermined(self, phys: dict, std: dict) -> list:
        """Names of the physical parameters the data do not determine (reported as such, not as numbers)."""
        return []

    @property
    def label(self) -> str:
        return f'{self.name} [{self.where}]' if self.where else self.name
