"""
Oil inlet temperature beside the identified bearings: a warm day is not wear; a wrong oil is a finding.

An oil that stops following its viscosity law is a change of its own.

The physical method fits each bearing's effective oil viscosity mu [Pa s] (and clearance) from the data.  With the oil
inlet temperature T [K] measured and the oil's viscosity law (:mod:`bearing_id.bearings.viscosity`, Walther / ASTM
D341 through two reference viscosities), the ratio

    r = mu_fitted / mu_law(T_mean)

is the viscosity with the temperature taken out: about constant while the oil is the oil the law describes, whatever
the temperature does; a step in it is a wrong oil, contamination or a film hotter than the inlet (a bearing running
hot).  Its 1-sigma combines the fit's and the temperature's spread over the data behind the fit (the temperature
varied that much while the data were taken): sigma_r^2 = (sigma_mu / mu_law)^2 + (r dln(mu)/dT sigma_T)^2.  The raw
viscosity then follows the temperature and is not itself a change to alarm on (:func:`not_monitored`).

SI throughout: T in kelvin (degC only at the node's edge, :func:`bearing_id.bearings.viscosity.celsius`).
"""
from __future__ import annotations

from collections import deque
import math
import threading

import numpy as np

from ..bearings import viscosity

TEMPERATURE = 'oil.inlet_temperature'      # the parameter name (bearing 'oil') the mean inlet temperature goes under
RATIO = 'viscosity_vs_oil'                 # per bearing: fitted viscosity / the law's at the mean inlet temperature
T_RANGE = (200.0, 500.0)                   # K: a reading outside is not an oil temperature (wrong units, a fault)


def not_monitored(keys) -> set:
    """
    Return the (bearing, parameter) series of ``keys`` the change detection leaves out.

    The inlet temperature (an input, not the machine's state) and the raw viscosity of a bearing that has its
    temperature-compensated ratio (it follows the temperature; the ratio is what changes when the oil does).
    """
    keys = set(keys)
    out = {k for k in keys if f'{k[0]}.{k[1]}' == TEMPERATURE}
    out |= {(b, 'viscosity') for b, n in keys if n == RATIO}
    return out & keys


class TemperatureLog:
    """
    The oil inlet temperature readings of the last ``keep`` seconds: (stamp [s, UNIX], T [K]).

    ``add`` refuses a reading that is not finite or outside :data:`T_RANGE` (returns the reason); ``over(t0, t1)``
    gives (mean [K], std [K], count) of the readings with t0 <= stamp <= t1, count 0 when there are none;
    ``mean_at(t0, t1)`` the temperature over a span also between readings.  Safe to add from one thread while another
    reads.
    """

    def __init__(self, keep: float = 7 * 86400.0, max_readings: int = 200_000):
        self.keep = float(keep)
        self._t: deque = deque(maxlen=int(max_readings))
        self._v: deque = deque(maxlen=int(max_readings))
        self._lock = threading.Lock()
        self._arrays = None            # (t, v) arrays of the readings, until the next add

    def add(self, stamp: float, T: float) -> str:
        if not (math.isfinite(stamp) and math.isfinite(T)):
            return f'oil temperature reading not finite ({T} K at {stamp})'
        if not T_RANGE[0] <= T <= T_RANGE[1]:
            return (f'oil temperature {T:.6g} K is outside {T_RANGE[0]:g}-{T_RANGE[1]:g} K (degC expected on '
                    f'sensor_msgs/Temperature)')
        with self._lock:
            self._t.append(float(stamp))
            self._v.append(float(T))
            while self._t and self._t[0] < stamp - self.keep:
                self._t.popleft()
                self._v.popleft()
            self._arrays = None
        return ''

    def readings(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the readings as arrays (stamps [s], T [K]) in time order, built once per change."""
        with self._lock:
            if self._arrays is None:
                t, v = np.array(self._t, float), np.array(self._v, float)
                order = np.argsort(t, kind='stable')        # a late reading may arrive after a later one
                self._arrays = (t[order], v[order])
            return self._arrays

    def __len__(self) -> int:
        return len(self._t)

    def over(self, t0: float, t1: float) -> tuple[float, float, int]:
        t, v = self.readings()
        sel = (t >= t0) & (t <= t1)
        n = int(np.count_nonzero(sel))
        if not n:
            return math.nan, math.nan, 0
        v = v[sel]
        return float(np.mean(v)), float(np.std(v)), n

    def mean_at(self, t0: float, t1: float) -> float:
        """
        Return the inlet temperature [K] over [t0, t1], also between readings.

        The readings' mean there, else the linear interpolation between the readings either side at its middle; NaN
        without a reading on both sides.
        """
        T, _, n = self.over(t0, t1)
        if n:
            return T
        t, v = self.readings()
        mid = 0.5 * (t0 + t1)
        if not t.size or not t[0] <= mid <= t[-1]:
            return math.nan
        return float(np.interp(mid, t, v))


def viscosity_factors(log: TemperatureLog, spans: list, oil: viscosity.Oil | None):
    """
    Return the known viscosity factor mu_law(T_k) / mu_law(T_ref) [-] of each data span, or None.

    ``spans`` [[(t0, t1) [s]] per speed] per run: the data behind each run's vector at each speed; the result has
    their shape (nr, ns).  T_k is the mean inlet temperature over span k (between two readings: interpolated at its
    middle), T_ref the mean over all of them (what :meth:`TemperatureLog.over` gives for the whole span, so the
    viscosity fitted at factor 1 is the one :func:`compensated` compares with the law).  None without a law, without
    every span, or without a temperature for each.  A fit whose data were taken over a temperature swing then has the
    viscosity each vector saw (``physical``'s ``viscosity_factors``) instead of one value for all: with a minute's
    dwells the vectors are precise enough that a 0.1 K drift between two runs at one speed is a misfit.
    """
    flat = [s for row in spans for s in row]
    if oil is None or not len(log) or not flat or any(s is None for s in flat):
        return None
    T_ref, _, n = log.over(min(s[0] for s in flat), max(s[1] for s in flat))
    T = np.array([[log.mean_at(*s) for s in row] for row in spans], dtype=float)
    if not n or not np.all(np.isfinite(T)):
        return None
    return np.asarray(viscosity.dynamic(oil, T), float) / float(viscosity.dynamic(oil, T_ref))


def compensated(parameters: dict, T: float, T_std: float, oil: viscosity.Oil | None) -> dict:
    """
    Return the derived parameters of one solve: the mean inlet temperature and, with a law, each viscosity's ratio.

    ``parameters``: the fit's {'bearing1.viscosity': {'value' [Pa s], 'std' [Pa s]}, ...}; ``T``, ``T_std`` [K] the
    inlet temperature's mean and spread over the solve's data; ``oil`` the law (None: the temperature only).  Returns
    entries in the same form, {'oil.inlet_temperature': ..., 'bearing1.viscosity_vs_oil': ...}.
    """
    out = {TEMPERATURE: {'value': float(T), 'std': float(T_std)}}
    if oil is None:
        return out
    mu_law = float(viscosity.dynamic(oil, T))
    slope = abs(float(viscosity.dln_mu_dT(oil, T)))
    for name, p in parameters.items():
        bearing, _, what = str(name).rpartition('.')
        if what != 'viscosity' or p.get('value') is None or p.get('std') is None:
            continue
        r = float(p['value']) / mu_law
        sig = math.hypot(float(p['std']) / mu_law, r * slope * float(T_std))
        out[f'{bearing}.{RATIO}'] = {'value': r, 'std': sig}
    return out
