"""
A machine's physical bearing parameters over time, and the changes in them with a stated false-alarm rate.

:func:`parameter_series` reads one machine's fitted parameters (clearance, viscosity, a table's scale factors, ...)
from a :class:`~.store.HistoryStore` as time series -- one point per solve: the identifications of one solve (one
per speed, all carrying the same global fit) are one point, at the end of their data span.  :func:`changes` runs the
two-sided CUSUM of :mod:`bearing_id.monitor.cusum` on each series, standardised by its own 1-sigma, with the
in-control value from the first ``n_reference`` points; the threshold follows from ``arl0``, the average number of
points to a false alarm the user accepts (per series and side combined).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime, timezone
import math

import numpy as np

from ..monitor.cusum import Alarm, detect


@dataclass(frozen=True)
class Series:
    """One parameter of one bearing: t [s, UNIX] (end of the data span), value and sigma (n,) [SI]."""

    bearing: str
    name: str
    t: np.ndarray
    value: np.ndarray
    sigma: np.ndarray


@dataclass(frozen=True)
class Change:
    """A CUSUM alarm on one series (:class:`~bearing_id.monitor.cusum.Alarm`: onset, size and sigma in SI)."""

    bearing: str
    name: str
    alarm: Alarm

    def sentence(self) -> str:
        a = self.alarm
        rel = a.size / a.reference if a.reference else math.nan
        word = 'up' if a.direction > 0 else 'down'
        return (f'{self.bearing} {self.name}: {word} by {a.size:.3g} ± {a.size_sigma:.2g} (x{1 + rel:.3f} of the '
                f'reference {a.reference:.4g}, SI) from {_utc(a.onset_time)}, alarm at {_utc(a.time)} after {a.n} '
                f'point(s) (CUSUM {a.statistic:.2f} > h = {a.h:.2f} sigma)')


def _utc(t: float) -> str:
    """Return the UTC time of a UNIX stamp [s], to the minute."""
    return datetime.fromtimestamp(float(t), timezone.utc).strftime('%Y-%m-%d %H:%M UTC')


def parameter_series(store, machine: str, since: float | None = None) -> list[Series]:
    """Return the physical parameters of ``machine`` as :class:`Series` (one point per solve; finite sigma only)."""
    q = store.query(machine, since=since)
    sel = (q['kind'] == 'parameter') & np.isfinite(q['value']) & np.isfinite(q['sigma']) & (q['sigma'] > 0)
    out = []
    keys = sorted({(b, n) for b, n in zip(q['bearing'][sel], q['name'][sel])})
    for b, n in keys:
        m = sel & (q['bearing'] == b) & (q['name'] == n)
        pts: dict = {}
        for t, v, s in zip(q['t_end'][m], q['value'][m], q['sigma'][m]):
            pts.setdefault((float(t), float(v), float(s)), None)      # the speeds of one solve: one point
        arr = np.array(sorted(pts), dtype=float).reshape(-1, 3)
        out.append(Series(str(b), str(n), arr[:, 0], arr[:, 1], arr[:, 2]))
    return out


def changes(series: list[Series], *, arl0: float, delta: float = 2.0, n_reference: int = 10) -> list[Change]:
    """
    Return the CUSUM alarms of every series with more than ``n_reference`` points: one per change.

    ``arl0`` [points]: average run length to a false alarm per series; ``delta`` [sigma]: the shift to detect
    fastest; the reference is the weighted mean of the first ``n_reference`` points (not monitored themselves), and
    after an alarm the ``n_reference`` points that follow it (the new level) are the next one.
    """
    out = []
    for s in series:
        start = 0
        while s.t.size - start > n_reference:
            seg = slice(start, None)
            found = detect(s.value[seg], s.sigma[seg], arl0=arl0, delta=delta, n_reference=n_reference,
                           times=s.t[seg])
            if not found:
                break
            a = found[0]
            out.append(Change(s.bearing, s.name, replace(a, index=a.index + start, onset=a.onset + start)))
            start += a.index + 1          # the level after the change is the next reference: one alarm per change
    return out


__all__ = ['Series', 'Change', 'parameter_series', 'changes']
