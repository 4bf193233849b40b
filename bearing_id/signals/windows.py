"""
Steady-speed windows of a recording: the per-sample speed from the keyphasor angle and the steady-window rule.

Speeds in rad/s (any unit works for the rule: only ratios matter), times in s, sample indices half open (i0, i1).
"""
from __future__ import annotations

import numpy as np


def speed_from_angle(angle, sample_rate: float) -> np.ndarray:
    """
    Per-sample rotor speed [rad/s], shape (N,), from the per-sample keyphasor angle [rad] (N,).

    Forward difference: speed[i] = (angle[i+1] - angle[i]) * sample_rate, the last sample repeating the one before
    (NaN for a single sample).  On a constant-speed step of the simulated rig this is the step's speed exactly; on an
    angle rebuilt from key marks it is each revolution's mean speed.  :class:`SteadyWindowTracker` users that receive
    the angle in chunks (:class:`bearing_id.identify.harmonics.RunStream`) compute the same numbers by holding back
    each chunk's last sample until the next chunk arrives.
    """
    a = np.asarray(angle, dtype=float).reshape(-1)
    if a.size < 2:
        return np.full(a.size, np.nan)
    d = np.diff(a) * float(sample_rate)
    return np.append(d, d[-1])


class SteadyWindowTracker:
    """
    The steady-window rule, fed one chunk of per-sample speeds at a time.

    A window is a maximal run of finite speeds in which max(speed) - min(speed) <= tol_rel * |mean speed of the run
    so far| (greedy from its first sample; the sample that breaks the rule starts the next window; a non-finite
    speed ends a window and belongs to none).  ``feed(speed_chunk)`` returns the windows (i0, i1) (absolute,
    half-open sample indices since the first sample fed) that the chunk closed; ``close()`` ends the open one.
    Feeding a record in any chunking gives the windows of feeding it whole: :func:`steady_windows` is this tracker
    fed at once, so the offline and the streaming routes cut the same windows.
    """

    def __init__(self, tol_rel: float = 0.005):
        if not tol_rel > 0:
            raise ValueError(f'tol_rel must be > 0, got {tol_rel}')
        self.tol_rel = float(tol_rel)
        self.n = 0              # samples fed so far
        self.i0 = None          # start of the open window (absolute index) or None
        self._hi = self._lo = self._sum = 0.0
        self._count = 0

    @property
    def open_length(self) -> int:
        """Return the number of samples in the open window (0 when none is open)."""
        return self._count if self.i0 is not None else 0

    def feed(self, speed) -> list[tuple[int, int]]:
        """Feed the next chunk of per-sample speeds (M,); return the windows (i0, i1) it closed."""
        w = np.asarray(speed, dtype=float).reshape(-1)
        base = self.n
        self.n += w.size
        closed = []
        j = 0
        while j < w.size:
            if self.i0 is None:
                if not np.isfinite(w[j]):
                    j += 1
                    continue
                self.i0, self._count = base + j, 0
                self._hi, self._lo, self._sum = -np.inf, np.inf, 0.0
            end = min(w.size, j + max(self._count, 1024))     # bounded scan: O(window length) work per window
            seg = w[j:end]
            fin = np.isfinite(seg)
            stop = seg.size if fin.all() else int(np.argmin(fin))
            seg = seg[:stop]
            hi = np.maximum(np.maximum.accumulate(seg), self._hi)
            lo = np.minimum(np.minimum.accumulate(seg), self._lo)
            csum = np.cumsum(np.concatenate(([self._sum], seg)))[1:]    # sequential sum: any chunking, same bits
            ref = np.abs(csum / (self._count + np.arange(1, seg.size + 1)))
            br = np.nonzero(hi - lo > self.tol_rel * np.maximum(ref, 1e-300))[0]
            take = int(br[0]) if br.size else seg.size
            if take:
                self._hi, self._lo, self._sum = float(hi[take - 1]), float(lo[take - 1]), float(csum[take - 1])
                self._count += take
            j += take
            if br.size or j < end:             # broken by the rule, or by a non-finite speed at j
                closed.append((self.i0, base + j))
                self.i0 = None
        return closed

    def close(self) -> list[tuple[int, int]]:
        """End the open window (end of the record, a gap, a change of run); returns it if it holds samples."""
        out = [(self.i0, self.i0 + self._count)] if self.i0 is not None and self._count else []
        self.i0, self._count = None, 0
        return out


def steady_windows(t, speed, tol_rel: float = 0.005, min_duration: float = 0.5) -> list[tuple[int, int]]:
    """
    Sample ranges (i0, i1) (half open) where the speed is constant within ``tol_rel``.

    The rule of :class:`SteadyWindowTracker` applied to the whole record; windows shorter than ``min_duration`` [s]
    are dropped (duration = number of samples x the mean sample interval of the window).

    Parameters: t (N,) s, speed (N,) rad/s (or rpm: only ratios matter).
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    w = np.asarray(speed, dtype=float).reshape(-1)
    if t.size != w.size:
        raise ValueError(f't has {t.size} values but speed has {w.size}')
    tr = SteadyWindowTracker(tol_rel)
    out = []
    for i0, i1 in tr.feed(w) + tr.close():
        if i1 - 1 > i0 and t[i1 - 1] - t[i0] + (t[i1 - 1] - t[i0]) / (i1 - 1 - i0) >= min_duration:
            out.append((i0, i1))
    return out
