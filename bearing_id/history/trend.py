"""
A machine's physical bearing parameters over time, and the changes in them with a stated false-alarm rate.

:func:`parameter_series` reads one machine's fitted parameters (clearance, viscosity, a table's scale factors, ...)
from a :class:`~.store.HistoryStore` as time series of independent points: the identifications of one solve (one
per speed, each with its own data span, all carrying the same global fit) are one point spanning their data, at its
end; a solve whose data overlap the previous point's is left out (the identifier re-solves as each window arrives,
re-using the other speeds' data: such points are correlated, and the CUSUM's false-alarm rate assumes independent
ones).  :func:`changes` runs the
two-sided CUSUM of :mod:`bearing_id.monitor.cusum` on each series, standardised by its own 1-sigma, with the
in-control value from the first ``n_reference`` points; the threshold follows from ``arl0``, the average number of
points to a false alarm the user accepts (per series and side combined).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime, timezone
import math

import numpy as np

from .oil_temperature import not_monitored
from ..monitor.cusum import Alarm, design, detect, reference_from, scatter_scale, statistics


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
    scale: float = 1.0        # the fits' 1-sigma was widened by this (the reference points' scatter: scatter_scale)

    def sentence(self) -> str:
        a = self.alarm
        rel = a.size / a.reference if a.reference else math.nan
        word = 'up' if a.direction > 0 else 'down'
        now = a.latest / a.reference if a.reference else math.nan
        wider = f", the fits' sigma x{self.scale:.2f} as the reference points scatter" if self.scale > 1.0 else ''
        return (f'{self.bearing} {self.name}: {word} by {a.size:.3g} ± {a.size_sigma:.2g} on average (x{1 + rel:.3f} '
                f'of the reference {a.reference:.4g}, SI) from {_utc(a.onset_time)}, alarm at {_utc(a.time)} after '
                f'{a.n} point(s), by then {a.latest:+.3g} ± {a.latest_sigma:.2g} (x{1 + now:.3f}) (CUSUM '
                f'{a.statistic:.2f} > h = {a.h:.2f} sigma{wider})')


def _utc(t: float) -> str:
    """Return the UTC time of a UNIX stamp [s], to the minute."""
    return datetime.fromtimestamp(float(t), timezone.utc).strftime('%Y-%m-%d %H:%M UTC')


def parameter_series(store, machine: str, since: float | None = None) -> list[Series]:
    """
    Return the physical parameters of ``machine`` as :class:`Series` (finite sigma only).

    One point per solve (its identifications grouped by their common value and sigma) whose data start at or after
    the end of the previous point's data; the others re-use data and are left out (see the module docstring).
    """
    out = []
    for (b, n), fits in _fits(store.query(machine, since=since)).items():
        kept, _ = _independent(fits, -math.inf)
        arr = np.array(kept, dtype=float).reshape(-1, 3)
        out.append(Series(b, n, arr[:, 0], arr[:, 1], arr[:, 2]))
    return out


def _fits(q: dict) -> dict:
    """Return {(bearing, parameter): {(value, sigma): [first, last] data stamp [s]}} of query rows ``q``."""
    sel = (q['kind'] == 'parameter') & np.isfinite(q['value']) & np.isfinite(q['sigma']) & (q['sigma'] > 0)
    out: dict = {}
    for b, n, t0, t1, v, s in zip(q['bearing'][sel], q['name'][sel], q['t_start'][sel], q['t_end'][sel],
                                  q['value'][sel], q['sigma'][sel]):
        span = out.setdefault((str(b), str(n)), {}).setdefault((float(v), float(s)), [float(t0), float(t1)])
        span[0], span[1] = min(span[0], float(t0)), max(span[1], float(t1))     # the speeds of one solve: one fit
    return out


def _independent(fits: dict, end: float) -> tuple[list, float]:
    """
    Return the points (t_end, value, sigma) of ``fits`` whose data start at or after the previous point's end.

    ``end`` [s]: the data end of the point before these; returns the new one too.
    """
    kept = []
    for t1, t0, v, s in sorted((t1, t0, v, s) for (v, s), (t0, t1) in fits.items()):
        if t0 >= end:                     # data disjoint from the last point kept: an independent point
            kept.append((t1, v, s))
            end = t1
    return kept, end


@dataclass(frozen=True)
class Resume:
    """
    Where a series' change detection goes on (:func:`series_changes`).

    Its points after ``t`` [s, UNIX] are the ones still to look at; ``reference`` (and its 1-sigma) the in-control
    value found so far, None while the next ``n_reference`` points are to give it; ``scale`` the factor the points'
    1-sigma is widened by (:func:`~bearing_id.monitor.cusum.scatter_scale` of the reference points).
    """

    t: float
    reference: float | None = None
    reference_sigma: float = 0.0
    scale: float = 1.0


def series_changes(s: Series, *, arl0: float, delta: float, n_reference: int,
                   resume: Resume | None = None) -> tuple[list[Change], Resume]:
    """
    Return the CUSUM alarms of one series (one per change) and where to resume when it has grown.

    ``s`` holds the points after ``resume.t`` (all of them without ``resume``).  The reference is the weighted mean of
    the first ``n_reference`` points (not monitored themselves); after an alarm the ``n_reference`` points that follow
    it (the new level) are the next one.  The points are standardised by their 1-sigma times the reference points'
    scatter about it (``scatter_scale``, at least 1): a fit's sigma that understates the scatter between solves
    would otherwise shorten the run length to a false alarm many times over.  The returned :class:`Resume` is after
    the last point where both sides of the statistic were zero: a run that restarts there from zero raises the alarms
    one from the first point would (the recursion max(0, S + ...) from a lower start stays at or below the true
    statistic until both meet at its zero), so a machine watched for months is re-read from there, not from its first
    solve.  Alarm indices are within ``s``.
    """
    start = 0
    before = -math.inf if resume is None else resume.t       # the time before the points of the current segment
    ref, ref_sigma, scale = (None, 0.0, 1.0)
    if resume is not None:
        ref, ref_sigma, scale = resume.reference, resume.reference_sigma, resume.scale
    out = []
    while True:
        if ref is None:
            if s.t.size - start <= n_reference:
                return out, Resume(before)                     # the reference is not complete: read it again
            seg = slice(start, start + n_reference)
            ref, ref_sigma = reference_from(s.value[seg], s.sigma[seg])
            scale = scatter_scale(s.value[seg], s.sigma[seg], ref)
            ref_sigma *= scale
            start += n_reference
            before = float(s.t[start - 1])
        seg = slice(start, None)
        found = detect(s.value[seg], scale * s.sigma[seg], arl0=arl0, delta=delta, reference=ref,
                       reference_sigma=ref_sigma, times=s.t[seg])
        if not found:
            break
        a = found[0]
        out.append(Change(s.bearing, s.name, replace(a, index=a.index + start, onset=a.onset + start), scale))
        start += a.index + 1              # the level after the change is the next reference: one alarm per change
        before = float(s.t[start - 1])
        ref = None
    sp, sm = statistics((s.value[start:] - ref) / (scale * s.sigma[start:]), design(arl0, delta).k)
    last = min(int(z[-1]) if z.size else -1 for z in (np.flatnonzero(sp == 0.0), np.flatnonzero(sm == 0.0)))
    if last >= 0:                         # both sides were zero at or after it: resume after the earlier zero
        before = float(s.t[start + last])
    return out, Resume(before, ref, ref_sigma, scale)


def changes(series: list[Series], *, arl0: float, delta: float = 2.0, n_reference: int = 10) -> list[Change]:
    """
    Return the CUSUM alarms of every series with more than ``n_reference`` points: one per change.

    ``arl0`` [points]: average run length to a false alarm per series; ``delta`` [sigma]: the shift to detect
    fastest (:func:`series_changes`).  The oil inlet temperature and a viscosity with its temperature-compensated
    ratio are not monitored (:func:`bearing_id.history.oil_temperature.not_monitored`).
    """
    out = []
    skip = not_monitored((s.bearing, s.name) for s in series)
    for s in series:
        if (s.bearing, s.name) in skip:
            continue
        out += series_changes(s, arl0=arl0, delta=delta, n_reference=n_reference)[0]
    return out


class ChangeWatch:
    """
    The changes of one machine's history as it grows: what :func:`changes` finds, and which of them are new.

    ``update()`` reads the identifications written since the last call, adds their independent points to each series
    and runs :func:`series_changes` from where the last call left it (:class:`Resume`): the work and the memory per
    call are those of the points since the statistic was last zero, not of the whole history.  It returns the changes
    found by this call; ``found`` keeps every change, ``series`` and ``points`` count the series watched and the
    longest one's points.  The first call reads the whole history and returns the changes already in it (a restarted
    node reports them again).  A solve written late whose data start before the last point's end (a backfill of
    older data) is no point here; :func:`changes` on the whole history would place it in time.
    """

    def __init__(self, store, machine: str, *, arl0: float, delta: float, n_reference: int):
        self.store, self.machine = store, machine
        self.arl0, self.delta, self.n_reference = float(arl0), float(delta), int(n_reference)
        self.found: list[Change] = []
        self._last_id = None
        self._state: dict = {}       # (bearing, parameter) -> [Resume, pending points [(t, v, s)], data end, count]
        self._skipped: set = set()   # series not monitored (oil_temperature.not_monitored)

    @property
    def series(self) -> int:
        return len(self._state)

    @property
    def points(self) -> int:
        return max((st[3] for st in self._state.values()), default=0)

    def update(self) -> list[Change]:
        """Return the changes the identifications written since the last call reveal."""
        q = self.store.query(self.machine, after_id=self._last_id)
        if q['identification'].size:
            self._last_id = int(np.max(q['identification']))
        new = []
        fits_by = _fits(q)
        skip = not_monitored(set(fits_by) | set(self._state) | self._skipped)
        self._skipped |= skip
        for key, fits in fits_by.items():
            if key in skip:
                self._state.pop(key, None)
                continue
            st = self._state.setdefault(key, [None, [], -math.inf, 0])
            kept, st[2] = _independent(fits, st[2])
            if not kept:
                continue
            st[1] += kept
            st[3] += len(kept)
            arr = np.array(st[1], dtype=float)
            found, st[0] = series_changes(Series(key[0], key[1], arr[:, 0], arr[:, 1], arr[:, 2]), arl0=self.arl0,
                                          delta=self.delta, n_reference=self.n_reference, resume=st[0])
            st[1] = [p for p in st[1] if p[0] > st[0].t]       # the points the next call still needs
            new += found
        self.found += new
        return new


__all__ = ['Series', 'Change', 'ChangeWatch', 'Resume', 'parameter_series', 'series_changes', 'changes']
