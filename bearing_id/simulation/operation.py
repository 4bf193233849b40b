"""
Hours to days of a machine's operation, compressed: the oil inlet temperature cycling and a bearing that wears.

An :class:`Operation` gives, at any stream time t [s], the oil inlet temperature

    T(t) = T_mean + T_amplitude sin(2 pi t / T_period)                                    [K]

the viscosity it implies through the oil's Walther law (:mod:`bearing_id.bearings.viscosity`), as a factor on the
truth's viscosity at T_mean, mu(T(t)) / mu(T_mean), the same for every bearing (one oil supply), and each bearing's
clearance factor: 1 before ``wear_onset``, growing linearly to ``wear_clearance`` at ``wear_end`` on bearing
``wear_bearing`` (0-based), constant after.  :meth:`Operation.truth_at` is the simulated machine at t
(``simulate_stream``'s ``truth_at``: the bearings of the segment that starts at t), so a stream of any length follows
the profile segment by segment with the state carried over; sensor_driver's sim source publishes T(t) beside it.

SI throughout (kelvin, seconds); degC only on the published message.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .rig import changed_truth
from ..bearings import viscosity


@dataclass(frozen=True)
class Operation:
    """
    The operating profile (see the module docstring).

    oil: the oil's viscosity law and T_mean, T_amplitude [K], T_period [s] its inlet temperature (None: no oil
    temperature, the viscosity constant); wear_bearing: index of the wearing bearing
    (None: no wear); wear_onset, wear_end [s] stream time; wear_clearance: its clearance factor at ``wear_end``.
    """

    oil: viscosity.Oil | None = None
    T_mean: float | None = None
    T_amplitude: float = 0.0
    T_period: float = 86400.0
    wear_bearing: int | None = None
    wear_onset: float = math.inf
    wear_end: float = math.inf
    wear_clearance: float = 1.0

    def __post_init__(self):
        if (self.oil is None) != (self.T_mean is None):
            raise ValueError('an oil temperature needs the oil (its viscosity law) and the mean temperature')
        if self.T_mean is not None and not (self.T_period > 0 and 0 <= self.T_amplitude < self.T_mean):
            raise ValueError(f'oil temperature cycle: period {self.T_period} s must be > 0 and the amplitude '
                             f'{self.T_amplitude} K between 0 and the mean {self.T_mean} K')
        if self.wear_bearing is not None and not (self.wear_onset < self.wear_end and self.wear_clearance > 0):
            raise ValueError(f'wear: onset {self.wear_onset} s must come before its end {self.wear_end} s and the '
                             f'clearance factor {self.wear_clearance} be > 0')

    def temperature(self, t):
        """Return the oil inlet temperature [K] at stream time ``t`` [s] (any shape); ValueError without one."""
        if self.T_mean is None:
            raise ValueError('this operating profile has no oil temperature')
        return self.T_mean + self.T_amplitude * np.sin(2 * np.pi * np.asarray(t, dtype=float) / self.T_period)

    def viscosity_factor(self, t):
        """Return mu(T(t)) / mu(T_mean) [-] (any shape; 1 without an oil temperature)."""
        if self.oil is None:
            return np.ones_like(np.asarray(t, dtype=float))
        return viscosity.dynamic(self.oil, self.temperature(t)) / viscosity.dynamic(self.oil, self.T_mean)

    def clearance_factors(self, t: float, n_bearings: int) -> tuple:
        """Return each bearing's clearance factor [-] at stream time ``t`` [s]."""
        out = [1.0] * int(n_bearings)
        if self.wear_bearing is not None:
            if not 0 <= self.wear_bearing < n_bearings:
                raise ValueError(f'wear_bearing {self.wear_bearing} is not one of the {n_bearings} bearings')
            frac = min(max((float(t) - self.wear_onset) / (self.wear_end - self.wear_onset), 0.0), 1.0)
            out[self.wear_bearing] = 1.0 + (self.wear_clearance - 1.0) * frac
        return tuple(out)

    def truth_at(self, rig, t: float):
        """Return the simulated machine's bearing_fn at stream time ``t`` [s] (``rig``'s truth times the profile)."""
        return changed_truth(rig, clearance=self.clearance_factors(t, len(rig.bearings)),
                             viscosity=float(self.viscosity_factor(t)))
