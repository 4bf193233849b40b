"""
Locate where recordings and the model disagree: measured harmonic vectors per window, residuals, significance.

Measured side (:func:`observe`)
    Each recording is cut into steady-speed windows (:func:`bearing_id.signals.windows.steady_windows`); the first
    ``settle`` seconds + 20 % of each window are dropped (the transient after a speed step: this rig has a lightly
    damped mode near 33 Hz, zeta < 1 %, whose free vibration lasts seconds), the rest is fitted with
    :func:`bearing_id.signals.harmonics.harmonic_vectors` for the orders 1X, 2X, 3X.  The strongest sub-synchronous
    component (:func:`bearing_id.signals.subsync.subsynchronous`) is searched in every window and, when above
    ``sub_snr``, fitted in the same regression as the nX vectors (so that it does not leak into them).  It counts as a
    *whirl* only when its ratio lies in ``whirl_band`` (0.3-0.6X), it whirls forward and it does not decay within the
    window; otherwise it is the free vibration left by a speed change (a lightly damped mode at a fixed frequency) and
    is noted.  When any window holds a whirl, every other window gets a sub-synchronous vector at the median whirl ratio
    of the windows a fit may learn from (:meth:`Observations.assign_sub`: all windows in-sample, the training windows
    for held-out validation), so that nothing about a whirl is learnt from a held-out window.

Noise floor
    The 1-sigma std of each harmonic vector comes from the fit residual (white-noise least squares).  The
    *model tolerance* ``rel_tol`` (default 2 % of the measured amplitude) is added in quadrature: a model never
    matches a machine to the noise floor, and a mismatch smaller than that is not worth a verdict.
    ``sigma = sqrt(std^2 + (rel_tol |X|)^2)``; significance = |residual| / sigma.

Located mismatch (:func:`locate_mismatch`)
    Residuals (measured minus predicted) are grouped by probe and harmonic order (slow-roll windows, i.e. speeds
    below ``slow_roll_rpm``, separately); a group is reported when its largest significance exceeds ``threshold``:
    where (probe, node, direction), order, the speeds [rpm] where it is significant, its size [m] (largest |residual|)
    and significance.  Units: SI inside, rpm for speeds in the report.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
import math

import numpy as np

from ..conventions import direction_words, rad_s_to_rpm
from ..signals import harmonics as signals
from ..signals.subsync import subsynchronous_bands
from ..signals.windows import steady_windows

DEFAULT_ORDERS = (1, 2, 3)


@dataclass
class Window:
    """
    One steady-speed window of one recording.

    rec : recording index.   i0, i1 : sample range used.   speed : mean speed [rad/s].
    X, std : complex (n_orders, nch) harmonic vectors [m] and their 1-sigma std [m].
    sub_ratio : sub-synchronous ratio fitted (frequency / speed) or None.   X_sub, std_sub : (nch,) or None.
    sub_snr : peak-to-floor ratio of the strongest sub-synchronous line found in this window (0 if not searched).
    whirl : 'forward' / 'backward' of that line for the first x/y probe pair, or None.
    own_ratio : the whirl ratio detected in *this* window (None when it holds no whirl); ``sub_ratio`` may instead be
    a ratio assigned from other windows (the median of the whirl windows of the fit's data, see
    :meth:`Observations.assign_sub`).   transient_ratio : ratio of a free-vibration line kept in the regression.
    """

    rec: int
    i0: int
    i1: int
    speed: float
    X: np.ndarray
    std: np.ndarray
    sub_ratio: float | None = None
    X_sub: np.ndarray | None = None
    std_sub: np.ndarray | None = None
    sub_snr: float = 0.0
    whirl: str | None = None
    own_ratio: float | None = None
    transient_ratio: float | None = None
    own_sub: tuple | None = field(default=None, repr=False)

    @property
    def rpm(self) -> float:
        return float(rad_s_to_rpm(self.speed))


@dataclass
class Observations:
    """
    Measured harmonic vectors of all recordings: ``windows`` (list of Window), ``orders``, and the recordings.

    ``sub_present``: the windows carry sub-synchronous data (some window holds a whirl, :meth:`assign_sub`).
    """

    recordings: list
    windows: list
    orders: tuple
    sub_present: bool = False
    notes: list = field(default_factory=list)
    sub_cache: dict = field(default_factory=dict, repr=False)     # (window, ratio) -> sub-synchronous vector

    def probes(self, rec: int):
        return tuple(self.recordings[rec].probes)

    def sub_vector(self, k: int, ratio: float):
        """
        Return (X_sub (nch,), std_sub (nch,)) [m], the sub-synchronous vector of window ``k`` at ``ratio`` x speed.

        The window's own fit when ``ratio`` is the whirl it holds, else a regression at that ratio (jointly with the
        nX orders and the window's free-vibration line), cached.
        """
        w = self.windows[k]
        if w.own_ratio is not None and abs(ratio - w.own_ratio) < 1e-12 and w.own_sub is not None:
            return w.own_sub
        cache = self.sub_cache
        key = (k, round(float(ratio), 12))
        v = cache.get(key)
        if v is None:
            rec = self.recordings[w.rec]
            x = np.asarray(rec.samples[w.i0:w.i1], dtype=float)
            subs = [float(ratio)] + ([w.transient_ratio] if w.transient_ratio is not None else [])
            fit = signals.harmonic_vectors(x, rec.angle[w.i0:w.i1], self.orders, subsync=subs, nonfinite='drop')
            v = (fit.X_sub[0], np.sqrt(fit.std_sub[0] ** 2 + (FLOOR_TOL * np.abs(fit.X[0])) ** 2))
            cache[key] = v
        return v

    def whirl_windows(self, windows=None) -> list:
        """Return the indices (among ``windows``, default all) of the windows holding a whirl of their own."""
        ks = range(len(self.windows)) if windows is None else windows
        return [k for k in ks if self.windows[k].own_ratio is not None]

    def assign_sub(self, train=None):
        """
        Return a copy whose sub-synchronous data come from the windows ``train`` only (default all).

        A whirl window of ``train`` keeps its own ratio; every other window (of ``train`` or held out) gets the median
        whirl ratio of ``train``'s whirl windows, and its vector at that ratio.  Without a whirl window in ``train`` no
        window has sub-synchronous data (``sub_present`` False): nothing about a whirl is learnt from held-out
        windows.
        """
        train = set(range(len(self.windows)) if train is None else train)
        own = [k for k in self.whirl_windows() if k in train]
        out = copy.copy(self)
        wins = []
        med = float(np.median([self.windows[k].own_ratio for k in own])) if own else None
        for k, w in enumerate(self.windows):
            w2 = copy.copy(w)
            if med is None:
                w2.sub_ratio, w2.X_sub, w2.std_sub = None, None, None
            else:
                r = w.own_ratio if (k in train and w.own_ratio is not None) else med
                w2.sub_ratio = float(r)
                w2.X_sub, w2.std_sub = self.sub_vector(k, r)
            wins.append(w2)
        out.windows = wins
        out.sub_present = med is not None
        return out


def xy_pair(probes):
    """Return (i, j), the channel indices of the first x and y probes at one node, or None."""
    for i, p in enumerate(probes):
        for j, q in enumerate(probes):
            if p.node == q.node and p.direction == 'x' and q.direction == 'y':
                return i, j
    return None


def _stationary(x, ang, ratio, keep: float = 0.6) -> bool:
    """
    Return True when the ``ratio`` component keeps its amplitude over the window (a whirl).

    Its amplitude in the second half is at least ``keep`` x that in the first; False when it decays (the free
    vibration left by a speed change).
    """
    h = x.shape[0] // 2
    amp = []
    for sl in (slice(0, h), slice(h, None)):
        fit = signals.harmonic_vectors(x[sl], ang[sl], (1,), subsync=ratio, whole_revs=False)
        amp.append(float(np.sqrt(np.sum(np.abs(fit.X_sub) ** 2))))
    return amp[1] >= keep * amp[0]


WHIRL_BAND = (0.3, 0.6)   # frequency ratios accepted as oil whirl (classically 0.42-0.49X)


def observe(recordings, *, orders=DEFAULT_ORDERS, settle: float = 0.2, min_duration: float = 0.25,
            tol_rel: float = 0.005, sub_snr: float = 10.0, whirl_band=WHIRL_BAND) -> Observations:
    """
    Harmonic vectors of every steady window of every recording (see module docstring).

    recordings : sequence of objects with ``t`` (N,) s, ``speed`` (N,) rad/s, ``angle`` (N,) rad, ``samples``
    (N, nch) m, ``sample_rate`` Hz and ``probes`` (as :class:`bearing_id.signals.recording.Recording`).
    """
    windows = []
    notes = []
    transient = {}          # window index -> ratio of a free-vibration line kept in the regression
    for r, rec in enumerate(recordings):
        fs = float(rec.sample_rate)
        t = np.asarray(rec.t) if getattr(rec, 't', None) is not None else np.arange(len(rec.speed)) / fs
        pair = xy_pair(rec.probes)
        for a, b in steady_windows(t, rec.speed, tol_rel=tol_rel, min_duration=min_duration):
            skip = min(int(round((settle + 0.2 * (b - a) / fs) * fs)), (b - a) // 2)
            a2 = a + skip
            ang = np.asarray(rec.angle[a2:b], dtype=float)
            if (ang[-1] - ang[0]) < 2 * math.pi * 1.05:
                notes.append(f'recording {r}: window at {rad_s_to_rpm(np.mean(rec.speed[a2:b])):.0f} rpm '
                             f'skipped (less than one revolution after settling)')
                continue
            x = np.asarray(rec.samples[a2:b], dtype=float)
            # the nX vectors are fitted below, once the lines fitted with them are known (a window with a whirl or a
            # free-vibration line needs only the fit that holds them)
            w = Window(rec=r, i0=a2, i1=b, speed=float(np.mean(rec.speed[a2:b])), X=None, std=None)
            try:                # (ratio, snr, whirl direction) per band; the synchronous fit done once for both
                found = subsynchronous_bands(x, ang, fs, ((0.05, 0.95), tuple(whirl_band)), xy=pair)
            except ValueError:
                found = []
            lines = [(sc.ratio, sc.snr, sc.whirl) for sc in found if sc is not None]
            strong = [ln for ln in lines if ln[1] >= sub_snr]
            whirl = next((ln for ln in reversed(strong) if whirl_band[0] <= ln[0] <= whirl_band[1]
                          and ln[2] != 'backward' and _stationary(x, ang, ln[0])), None)
            if whirl is not None:
                w.sub_ratio, w.sub_snr, w.whirl = whirl
            others = [ln for ln in strong if whirl is None or abs(ln[0] - whirl[0]) > 0.02]
            if others:
                # free vibration: fitted in the regression so that it does not leak into the nX vectors
                ln = others[0]
                transient[len(windows)] = ln[0]
                notes.append(f'recording {r}: a {ln[0] * w.speed / (2 * math.pi):.1f} Hz ({ln[0]:.2f}X, {ln[2]}) '
                             f'line at {w.rpm:.0f} rpm is free vibration (decaying, backward or outside the whirl '
                             f'band), removed from the nX vectors, not a whirl')
            subs = ([w.sub_ratio] if whirl is not None else []) + ([transient[len(windows)]] if others else [])
            if others:
                w.transient_ratio = float(transient[len(windows)])
            fit = signals.harmonic_vectors(x, ang, orders, subsync=subs or None, nonfinite='drop')
            w.X, w.std = fit.X, fit.std
            if whirl is not None:
                w.own_ratio = float(w.sub_ratio)
                w.own_sub = (fit.X_sub[0], np.sqrt(fit.std_sub[0] ** 2 + (FLOOR_TOL * np.abs(fit.X[0])) ** 2))
            windows.append(w)
    # the nX vectors of a window come from its own regression only (its own whirl / free-vibration lines); the
    # sub-synchronous data of the windows without a whirl of their own are assigned per fit (assign_sub)
    obs = Observations(recordings=list(recordings), windows=windows, orders=tuple(orders), notes=notes)
    return obs.assign_sub() if obs.whirl_windows() else obs


FLOOR_TOL = 0.003   # harmonic content below 0.3 % of the channel's 1X is not diagnosed


def sigma(X, std, rel_tol: float, floor_tol: float = FLOOR_TOL):
    """
    Return the effective 1-sigma [m] of harmonic vectors X (n_orders, nch) [m] with their fit 1-sigma ``std``.

    sqrt(std^2 + (rel_tol |X|)^2 + (floor_tol |X_1X|)^2), floored at 1e-15 m.  The last term (first row of X is
    taken as the 1X) keeps leakage and residual transients of a strong 1X from posing as nX content.
    """
    X = np.asarray(X)
    ref = np.abs(X[:1]) if X.ndim == 2 else np.abs(X)
    return np.maximum(np.sqrt(np.asarray(std) ** 2 + (rel_tol * np.abs(X)) ** 2 + (floor_tol * ref) ** 2), 1e-15)


# --------------------------------------------------------------------------------------------- locate
@dataclass
class Mismatch:
    """
    A located mismatch.

    ``where`` (probe text), ``order`` ('1X', '2X', '1X slow roll', '0.45X forward' ...), ``speeds_rpm`` where it is
    significant, ``size`` [m] (largest |residual|), ``relative`` (size / |measured| there), ``significance`` (largest
    |residual| / sigma).
    """

    where: str
    order: str
    speeds_rpm: list
    size: float
    relative: float
    significance: float

    def as_dict(self) -> dict:
        return {'where': self.where, 'order': self.order, 'speeds_rpm': [round(s, 1) for s in self.speeds_rpm],
                'size': self.size, 'size_um': self.size * 1e6, 'relative': self.relative,
                'significance': self.significance}


def _probe_text(p) -> str:
    return f'{p.name} (node {p.node}, {direction_words(p.direction)})'


def locate_mismatch(obs: Observations, pred_X: list, pred_sub: list | None = None, *, rel_tol: float = 0.02,
                    threshold: float = 5.0, slow_roll_rpm: float = 400.0) -> list[Mismatch]:
    """
    Group the residuals ``measured - predicted`` and report the significant groups.

    pred_X : per window, complex (n_orders, nch) predicted harmonic vectors [m] (same layout as Window.X).
    pred_sub : per window, complex (nch,) predicted sub-synchronous vectors (phase-aligned), or None (zero).
    """
    groups: dict = {}
    for k, w in enumerate(obs.windows):
        probes = obs.probes(w.rec)
        slow = w.rpm < slow_roll_rpm
        R = w.X - pred_X[k]
        S = sigma(w.X, w.std, rel_tol)
        for o, order in enumerate(obs.orders):
            for c, p in enumerate(probes):
                label = f'{order}X' + (' slow roll' if slow else '')
                groups.setdefault((_probe_text(p), label), []).append(
                    (w.rpm, abs(R[o, c]), abs(R[o, c]) / S[o, c], abs(w.X[o, c])))
        if obs.sub_present and w.X_sub is not None:
            Ps = np.zeros_like(w.X_sub) if pred_sub is None or pred_sub[k] is None else pred_sub[k]
            Rs = np.abs(w.X_sub) - np.abs(Ps)
            for c, p in enumerate(probes):
                label = f'sub-synchronous {w.sub_ratio:.2f}X' + (f' {w.whirl} whirl' if w.whirl else '')
                key = (_probe_text(p), 'sub-synchronous')
                groups.setdefault(key, []).append((w.rpm, abs(Rs[c]), abs(Rs[c]) / max(w.std_sub[c], 1e-15),
                                                   abs(w.X_sub[c]), label))
    out = []
    for (where, order), rows in groups.items():
        sig = [r for r in rows if r[2] >= threshold]
        if not sig:
            continue
        best = max(rows, key=lambda r: r[2])
        label = best[4] if len(best) > 4 else order
        speeds = sorted({round(r[0], 0) for r in sig})          # one entry per speed, however many runs hold it
        out.append(Mismatch(where=where, order=label, speeds_rpm=speeds, size=float(best[1]),
                            relative=float(best[1] / max(best[3], 1e-300)), significance=float(best[2])))
    out.sort(key=lambda m: -m.significance)
    return out


__all__ = ['Window', 'Observations', 'observe', 'sigma', 'Mismatch', 'locate_mismatch', 'xy_pair', 'DEFAULT_ORDERS']
