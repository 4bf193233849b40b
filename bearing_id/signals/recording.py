"""
A recording: what a DAQ gives for one excitation run (samples, keyphasor angle, speed, probes, the known excitation).

The one in-memory form every route shares: the simulator makes it (:mod:`bearing_id.simulation.rig`), the readers
of .npz, CSV and bag files return it (:mod:`bearing_id.io`), the 1X fits take it (:mod:`bearing_id.identify`).
:func:`check_recording` refuses one the pipeline cannot use.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ..config.params import Run
from ..conventions import parse_probe_direction

#: |displacement| above this [m] is not a plausible shaft vibration in metres (mm or µm sent by mistake?)
MAX_PLAUSIBLE_DISPLACEMENT = 1e-2
# a channel with this share of its samples at exactly its largest (or smallest) value is clipped: a probe or DAQ input
# beyond its range (flat tops), or a resolution so coarse the peaks span a few codes.  A sampled sinusoid with noise
# reaches its extreme once; quantised to 100 codes of amplitude it sits on its peak code ~2 % of the time.
CLIP_FRACTION = 0.05


@dataclass
class Recording:
    """
    A DAQ-like record of one excitation run.

    Attributes
    ----------
    sample_rate : Hz.
    t : (N,) s from the start of the run.
    speed : (N,) rad/s.
    angle : (N,) rad, keyphasor rotor angle (unwrapped; 0 at the key mark).
    probes : tuple of params.Probe, one per channel.
    samples : (N, nch) m.
    run : params.Run (the known excitation).
    segments : list of (i0, i1, speed [rad/s], steady) sample ranges of constant speed (truth bookkeeping).
    truth : dict with 'coefficients': {speed_rad_s: {node: (K, C)}} of the truth bearings, and 'description'.
    rig_name : str.
    gaps : sample indices at which the record resumes after lost data (a bag with a missing block); no steady window
        spans a gap.

    """

    sample_rate: float
    t: np.ndarray
    speed: np.ndarray
    angle: np.ndarray
    probes: tuple
    samples: np.ndarray
    run: Run
    segments: list = field(default_factory=list)
    truth: dict = field(default_factory=dict)
    rig_name: str = 'rig'
    gaps: tuple = ()

    @property
    def channels(self) -> list[str]:
        return [p.name for p in self.probes]

    def pieces(self):
        """Yield (samples, angle, contiguous) between its ``gaps`` (views; ``contiguous`` False after a gap)."""
        n = np.shape(self.samples)[0]
        for a, b, contiguous in split_rows(n, getattr(self, 'gaps', ()), max(n, 1)):
            yield self.samples[a:b], self.angle[a:b], contiguous


def split_rows(n: int, gaps, rows: int):
    """Yield (i0, i1, contiguous) ranges of ``n`` samples, at most ``rows`` long, cut at ``gaps`` (not contiguous)."""
    bounds = [0] + sorted({int(g) for g in gaps if 0 < g < n}) + [n]
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        for i in range(a, b, rows):
            yield i, min(b, i + rows), not (k and i == a)


class RecordingError(ValueError):
    """A recording's values cannot be used (:func:`check_recording`, :class:`RecordingCheck`); names where and what."""


def check_recording(rec: 'Recording', where: str = 'recording') -> 'Recording':
    """
    Refuse a Recording the offline pipeline cannot use (ValueError naming what); returns ``rec``.

    Refused: sizes that disagree, a sample rate that is not > 0, NaN/inf in samples/angle/speed/t, a displacement beyond
    :data:`MAX_PLAUSIBLE_DISPLACEMENT` (not metres, or damaged data), a dead channel (one value throughout: a probe
    not connected, a channel not recorded) or a clipped one (:data:`CLIP_FRACTION` of its samples at its extreme
    value), instrument faults named before any physics is fitted, probe nodes < 1 or
    directions other than x/y/'<angle>deg', excitation entries of unknown kind.  The values are checked by
    :class:`RecordingCheck` (the whole arrays as one piece; a recording streamed from disk is checked piece by piece
    by the same code).
    """
    fs = rec.sample_rate
    if not (isinstance(fs, (int, float, np.floating, np.integer)) and math.isfinite(float(fs)) and fs > 0):
        raise RecordingError(f'{where}: sample_rate must be a number > 0 Hz, got {fs!r}')
    x = np.asarray(rec.samples)
    if x.ndim != 2 or x.shape[0] < 2 or x.shape[1] < 1:
        raise RecordingError(f'{where}: samples must be (N >= 2, n_channels >= 1), has shape {x.shape}')
    if x.shape[1] != len(rec.probes):
        raise RecordingError(f'{where}: {x.shape[1]} sample column(s) but {len(rec.probes)} channel(s)')
    for name in ('angle', 'speed', 't'):
        a = np.asarray(getattr(rec, name))
        if a.shape != (x.shape[0],):
            raise RecordingError(f'{where}: {name} has shape {a.shape}, samples has {x.shape[0]} rows')
    check = RecordingCheck(rec, where)
    check.feed(x, rec.angle, rec.speed, rec.t)
    check.finish()
    return rec


class RecordingCheck:
    """
    The value checks of :func:`check_recording`, fed piece by piece.

    ``feed(samples, angle, speed, t)`` the pieces in order, then ``finish()`` raises the :class:`RecordingError` the
    whole arrays would have raised (or returns).

    ``rec`` gives ``sample_rate``, ``probes`` and ``run`` (checked at ``finish``).  Every problem is noted while the
    pieces go by and the first one in the order of the whole-array checks is raised at the end, so its message is
    the whole recording's (a count of NaN over all samples, the first slip).  :attr:`failed` says early that
    ``finish`` will raise (a consumer may stop working on the data).  Bounded memory: a few hundred samples of angle
    across piece boundaries (the slip check's neighbours) and at most :data:`RATIO_SUBSAMPLE` values of the speed
    ratio (beyond that a regular subsample, so the median named is that of every k-th sample).
    """

    def __init__(self, rec, where: str = 'recording'):
        self.fs = float(rec.sample_rate)
        self.probes, self.run, self.where = tuple(rec.probes), rec.run, where
        self.n = 0
        self._bad = {}                  # name -> [count, first index (tuple)] of its NaN/inf values
        self._size = {}                 # name -> values fed
        self._peak = (-1.0, None)      # (max |x|, (row, channel) of its first occurrence when beyond the limit)
        self._hi = self._lo = None      # per channel: [extreme value (nch,), samples at it (nch,)]
        self._slip = _SlipScan(self.fs)
        self._prev = None               # (angle, speed) of the last sample fed (its angle step needs the next)
        self._any_speed = False
        self._any_turning = False
        self._ratio, self._w_angle, self._speed = (_Subsample() for _ in range(3))

    @property
    def failed(self) -> bool:
        return bool(self._bad) or self._slip.found is not None

    def feed(self, samples, angle, speed, t=None) -> None:
        x = np.asarray(samples)
        a, w = np.asarray(angle, dtype=float), np.asarray(speed, dtype=float)
        if not a.size:
            return
        for name, v in (('samples', x), ('angle', a), ('speed', w), ('t', t)):
            if v is None:
                continue
            bad = ~np.isfinite(np.asarray(v, dtype=float))
            self._size[name] = self._size.get(name, 0) + bad.size
            if name in self._bad:
                self._bad[name][0] += int(bad.sum())
            elif bad.any():
                idx = np.argwhere(bad)[0]
                idx[0] += self.n
                self._bad[name] = [int(bad.sum()), tuple(int(i) for i in idx)]
        if not self._bad:
            pk = max(float(x.max()), -float(x.min()))        # = max |x| (finite), no (n, nch) temporary
            if pk > self._peak[0]:
                where = None                                  # where it is: only needed to refuse it
                if pk > MAX_PLAUSIBLE_DISPLACEMENT:
                    i, j = np.unravel_index(int(np.argmax(np.abs(x))), x.shape)
                    where = (int(i) + self.n, int(j))
                self._peak = (pk, where)
            self._extremes(x)
            self._slip.feed(a)
            self._any_speed = self._any_speed or bool(np.any(w != 0))
            if self._prev is None:
                aa, ww = a, w[:-1]
            else:
                aa, ww = np.concatenate(([self._prev[0]], a)), np.concatenate(([self._prev[1]], w[:-1]))
            d = np.diff(aa)
            turning = d > 0
            if np.any(turning):
                self._any_turning = True
                w_angle = d[turning] * self.fs
                self._ratio.add(ww[turning] / w_angle)
                self._w_angle.add(w_angle)
            self._speed.add(w)
            self._prev = (float(a[-1]), float(w[-1]))
        self.n += a.size

    def _extremes(self, x) -> None:
        """Track each channel's largest and smallest value and how many samples sit exactly at it."""
        x = x.reshape(x.shape[0], -1)
        if not x.shape[0]:
            return
        for attr, ext in (('_hi', np.max), ('_lo', np.min)):
            v = ext(x, axis=0)
            c = np.sum(x == v, axis=0)
            cur = getattr(self, attr)
            if cur is None:
                setattr(self, attr, [v, c])
                continue
            beyond = v > cur[0] if attr == '_hi' else v < cur[0]
            cur[1] = np.where(beyond, c, np.where(v == cur[0], cur[1] + c, cur[1]))
            cur[0] = np.where(beyond, v, cur[0])

    def _instrument_faults(self, where: str) -> None:
        """Refuse a dead or a clipped channel (see :func:`check_recording`)."""
        if self._hi is None or self.n < 2:
            return
        (hi, n_hi), (lo, n_lo) = self._hi, self._lo
        for j, p in enumerate(self.probes):
            if hi[j] == lo[j]:
                raise RecordingError(f'{where}: channel {p.name!r} is dead: all {self.n} samples are {hi[j]:.6g} m (a '
                                     'probe not connected or a channel not recorded); remove that channel from the '
                                     'export, the others are used')
            for side, value, count in (('largest', hi[j], n_hi[j]), ('smallest', lo[j], n_lo[j])):
                if count >= CLIP_FRACTION * self.n:
                    share = 100 * count / self.n
                    raise RecordingError(
                        f'{where}: channel {p.name!r} is clipped: {count} of {self.n} samples ({share:.1f} %) sit '
                        f'at its {side} value {value:.6g} m (a probe or DAQ input beyond its range, or a '
                        'resolution too coarse for the signal); fix the range, or remove that channel from the export')

    def finish(self) -> None:
        """Raise the first problem of the recording fed (in the order of :func:`check_recording`'s checks)."""
        where = self.where
        for name in ('samples', 'angle', 'speed', 't'):
            if name in self._bad:
                count, idx = self._bad[name]
                raise RecordingError(f'{where}: {name}: {count} of {self._size[name]} values are NaN/inf (first at '
                                     f'index {idx}); remove or repair those samples')
        limit = MAX_PLAUSIBLE_DISPLACEMENT
        peak = self._peak[0]
        if peak > limit:
            i, j = self._peak[1]
            raise RecordingError(f'{where}: samples reach {peak:.3g} m (row {i}, channel {j}), beyond the {limit:g} m '
                                 'a shaft displacement can be: not metres (mm or um?) or damaged data')
        self._instrument_faults(where)
        for p in self.probes:
            try:
                parse_probe_direction(p.direction)
                ok = int(p.node) >= 1
            except (ValueError, TypeError):
                ok = False
            if not ok:
                raise RecordingError(f'{where}: channel {p.name!r}: node {p.node} direction {p.direction!r} (need a '
                                     "1-based node and x, y or an angle such as '45.0deg')")
        for e in self.run.excitation:
            if e.kind not in ('unbalance', 'force') or e.direction not in ('forward', 'x', 'y') or e.node < 1 \
                    or not all(math.isfinite(v) for v in (e.magnitude, e.phase, e.frequency_ratio)):
                raise RecordingError(f'{where}: run {self.run.id}: invalid excitation entry {e}')
        self._slip.feed(np.zeros(0), final=True)
        if self._slip.found is not None:
            i, jump = self._slip.found
            raise RecordingError(f'{where}: keyphasor angle jumps by {jump:+.3g} rad at sample {i + 1} '
                                 f'(t = {(i + 1) / self.fs:.4g} s) against its neighbours: a keyphasor slip (a lost '
                                 'or extra key mark) or a wrapped angle; repair the angle there or split the recording')
        if self._any_speed and self._any_turning:
            ratio = float(np.median(self._ratio.values()))
            if abs(ratio - 1) > SPEED_MISMATCH:
                raise RecordingError(
                    f'{where}: the speed channel is x{ratio:.3g} the speed of the keyphasor angle (median over the '
                    f'samples; e.g. {float(np.median(self._speed.values())):.6g} against '
                    f'{float(np.median(self._w_angle.values())):.6g} rad/s): a speed in rpm or Hz instead of rad/s, '
                    'or a keyphasor with more than one mark per revolution?')


RATIO_SUBSAMPLE = 1 << 16   # values of the speed-channel check kept (beyond: every k-th, k a power of 2)


class _Subsample:
    """The values added, in order, or (more than :data:`RATIO_SUBSAMPLE`) every ``stride``-th of them."""

    def __init__(self):
        self._parts, self._kept, self.stride, self.count = [], 0, 1, 0

    def add(self, v: np.ndarray) -> None:
        while self._kept + -(-v.size // self.stride) > RATIO_SUBSAMPLE:   # thin first: only what is kept is copied
            kept = self.values()[::2]                 # the first value kept is the first added: every 2 stride-th
            self._parts, self._kept, self.stride = [kept], kept.size, self.stride * 2
        first = (-self.count) % self.stride         # index into v of the next value to keep
        part = np.array(v[first::self.stride], dtype=float)
        self.count += v.size
        self._parts.append(part)
        self._kept += part.size

    def values(self) -> np.ndarray:
        return np.concatenate(self._parts) if self._parts else np.zeros(0)


# rad: an angle step this far from its neighbours' within one sample is a keyphasor slip.  Blocks that carry only their
# first sample's angle are joined with a constant speed per block: on a speed ramp that is off by up to alpha T^2 / 2
# at a join (0.79 rad on the shipped bag's ramps), which must pass; a quarter turn is beyond any such join.
SLIP_RAD = math.pi / 2
SPEED_MISMATCH = 0.05    # relative: a speed channel this far from the angle's speed (median) contradicts it


class _SlipScan:
    """
    The keyphasor-slip check of :class:`RecordingCheck`, fed the angle piece by piece.

    Slip: one sample's angle step differs from the median step of its 64 neighbours (each side) by more than
    ``SLIP_RAD`` (a quarter turn: no rotor accelerates so within one sample; a lost or extra key mark, or a wrapped
    angle).  Candidates are the samples where the step itself steps by more than that (O(N)); the first 100 are
    examined, each once its neighbours have arrived.  ``found`` = (step index, jump [rad]) of the first slip, or None.
    """

    K = 64
    MAX_CANDIDATES = 100

    def __init__(self, fs: float):
        self.fs = fs
        self.tail = np.zeros(0)         # angles from global index self.base on, kept for the next piece
        self.base = 0
        self.next_i = 1                 # first candidate step index not yet examined
        self.n_cand = 0
        self.found = None

    def feed(self, angle: np.ndarray, final: bool = False) -> None:
        a = np.concatenate((self.tail, angle)) if self.tail.size else np.asarray(angle, dtype=float)
        base, K = self.base, self.K
        d = np.diff(a)                      # d[j]: step base + j
        end = base + d.size                 # steps known so far
        limit = end if final else end - K   # candidates with all their right neighbours known
        if self.found is None and self.n_cand < self.MAX_CANDIDATES and d.size >= 2:
            for i in np.flatnonzero(np.abs(np.diff(d)) > SLIP_RAD) + 1 + base:
                if i < self.next_i:
                    continue
                if i >= limit or self.n_cand >= self.MAX_CANDIDATES:
                    break
                self.n_cand += 1
                local = float(np.median(d[max(0, i - K) - base:i + K + 1 - base]))
                if abs(d[i - base] - local) > SLIP_RAD:
                    self.found = (int(i), float(d[i - base] - local))
                    break
        self.next_i = max(self.next_i, limit)
        keep = max(base, self.next_i - K - 1)
        self.tail, self.base = a[keep - base:].copy(), keep
