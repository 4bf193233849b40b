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
        self.max_readings = int(max_readings)
        self._t = np.empty(1024)       # stamps in time order: the readings are _t[_a:_b], _v[_a:_b]
        self._v = np.empty(1024)
        self._a = self._b = 0
        self._lock = threading.Lock()

    def add(self, stamp: float, T: float) -> str:
        """
        Take a reading ``T`` [K] at ``stamp`` [s]; return why it was refused, or ''.

        In time order the cost is O(1) amortised; a late reading is inserted in place.  Readings older than ``keep``
        before the newest, and beyond ``max_readings``, go first.  Every query is O(log n) in the readings (a solve
        asks one per vector: on a 72-hour stream rebuilding and scanning all of them made a tenth of the identifier's
        work at 50x).
        """
        if not (math.isfinite(stamp) and math.isfinite(T)):
            return f'oil temperature reading not finite ({T} K at {stamp})'
        if not T_RANGE[0] <= T <= T_RANGE[1]:
            return (f'oil temperature {T:.6g} K is outside {T_RANGE[0]:g}-{T_RANGE[1]:g} K (degC expected on '
                    f'sensor_msgs/Temperature)')
        stamp, T = float(stamp), float(T)
        with self._lock:
            if self._b == self._t.size:                     # full: drop what is out of reach, then grow
                n = self._b - self._a
                size = max(1024, 2 * n)
                t, v = np.empty(size), np.empty(size)
                t[:n], v[:n] = self._t[self._a:self._b], self._v[self._a:self._b]
                self._t, self._v, self._a, self._b = t, v, 0, n
            a, b = self._a, self._b
            if b == a or stamp >= self._t[b - 1]:
                self._t[b], self._v[b] = stamp, T
            else:                                           # a late reading: in place, after equal stamps
                k = a + int(np.searchsorted(self._t[a:b], stamp, side='right'))
                self._t[k + 1:b + 1], self._v[k + 1:b + 1] = self._t[k:b].copy(), self._v[k:b].copy()
                self._t[k], self._v[k] = stamp, T
            self._b = b + 1
            newest = self._t[self._b - 1]
            self._a += int(np.searchsorted(self._t[self._a:self._b], newest - self.keep, side='left'))
            self._a = max(self._a, self._b - self.max_readings)
        return ''

    def __len__(self) -> int:
        return self._b - self._a

    def over(self, t0: float, t1: float) -> tuple[float, float, int]:
        with self._lock:
            t = self._t[self._a:self._b]
            i0, i1 = np.searchsorted(t, t0, side='left'), np.searchsorted(t, t1, side='right')
            if i1 <= i0:
                return math.nan, math.nan, 0
            v = self._v[self._a + i0:self._a + i1]
            return float(np.mean(v)), float(np.std(v)), int(i1 - i0)

    def mean_at(self, t0: float, t1: float) -> float:
        """
        Return the inlet temperature [K] over [t0, t1], also between readings.

        The readings' mean there, else the linear interpolation between the readings either side at its middle; NaN
        without a reading on both sides.
        """
        T, _, n = self.over(t0, t1)
        if n:
            return T
        mid = 0.5 * (t0 + t1)
        with self._lock:
            t, v = self._t[self._a:self._b], self._v[self._a:self._b]
            if not t.size or not t[0] <= mid <= t[-1]:
                return math.nan
            if t.size == 1:
                return float(v[0])
            k = int(np.clip(np.searchsorted(t, mid), 1, t.size - 1))
            return float(np.interp(mid, t[k - 1:k + 1], v[k - 1:k + 1]))


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
