"""
Collect the measured 1X harmonic vectors per excitation run and per steady speed, from recordings or a bag.

Rule for each run
    The speed record is split into steady windows (:func:`bearing_id.signals.windows.steady_windows`, speed constant
    within ``tol_rel``); the first ``settle`` fraction of each window is discarded and the 1X vectors of the rest are
    fitted over whole revolutions (:func:`bearing_id.signals.harmonics.harmonic_vectors`) jointly with up to
    ``transients`` exponentially decaying sinusoids (default 3: the rotor's lightly damped modes ring for seconds after
    every speed change, and a mode near running speed biases a plain 1X fit by percent).  The 1X std is the joint fit's.
    A window-halves check on the signal minus the fitted transients adds a bias bound for anything left unmodelled
    (:func:`stationarity_excess`).
    Speeds from different runs are matched when they agree within ``tol_rel``; only speeds present in every run are
    kept (identification stacks the runs at one speed).

Shapes: ``X`` complex (n_runs, n_speeds, n_channels) [m] with x(t) = Re{X exp(j phi)}; ``X_std`` the 1-sigma of the
real and of the imaginary part (each) [m]; ``plain`` the plain 1X fit of the same samples (:class:`PlainFit`, what the
paper method's filter takes); ``speeds`` (n_speeds,) rad/s.
"""
from __future__ import annotations

from collections import deque
import copy
from dataclasses import dataclass, field, replace
import math
import uuid

import numpy as np

from ..config import defaults
from ..config.params import Run
from ..signals.harmonics import harmonic_vectors
from ..signals.keyphasor import continued_angle
from ..signals.windows import SteadyWindowTracker


@dataclass
class HarmonicData:
    """
    Measured 1X phasors per run and speed (see module docstring for shapes and units).

    windows[r][s] = (i0, i1) sample range of run r used at speed s (into ``recordings[r]``), or None.
    truth = {speed [rad/s]: {node: (K, C)}} when the recordings carry it (simulated rig), else {}.
    plain: :class:`PlainFit` (n_runs, n_speeds, n_channels) of the same windows, or None; sample_rate [Hz] of the
    recordings (None: unknown).  The live identifier has no recordings: its data carry the vectors, ``plain`` and
    ``sample_rate``.
    """

    speeds: np.ndarray
    probes: tuple
    runs: tuple
    X: np.ndarray
    X_std: np.ndarray
    recordings: list = field(default_factory=list, repr=False)
    windows: list = field(default_factory=list, repr=False)
    truth: dict = field(default_factory=dict, repr=False)
    plain: 'PlainFit | None' = field(default=None, repr=False)
    sample_rate: float | None = None

    def __post_init__(self):
        if self.plain is not None and self.plain.X.shape != np.shape(self.X):
            raise ValueError(f'plain fit of shape {self.plain.X.shape} for vectors of shape {np.shape(self.X)}')

    def truth_at(self, speed: float, tol_rel: float = defaults.SPEED_TOLERANCE):
        """Return the true coefficients {node: (K, C)} nearest ``speed`` [rad/s], or None."""
        if not self.truth:
            return None
        s = min(self.truth, key=lambda k: abs(k - speed))
        return self.truth[s] if abs(s - speed) <= tol_rel * max(abs(speed), 1e-12) else None

    def select(self, speeds_idx) -> 'HarmonicData':
        """Return a copy holding only the speeds at the given indices."""
        idx = list(speeds_idx)
        return HarmonicData(self.speeds[idx], self.probes, self.runs, self.X[:, idx], self.X_std[:, idx],
                            self.recordings, [[w[i] for i in idx] for w in self.windows] if self.windows else [],
                            self.truth, None if self.plain is None else self.plain.take((slice(None), idx)),
                            self.sample_rate)


@dataclass
class PlainFit:
    """
    The plain 1X fit (1X + offset over whole revolutions, no decaying components) of windows' fitted parts.

    What the paper method's Kalman filter takes: the paper filters the samples as they are, a mode still ringing
    included, and fits the 1X of the estimates plainly.  X complex [m]; var_re, var_im [m^2] the
    variances of its real and imaginary parts; noise_var [m^2] the residual variance per probe (the filter's R: probe
    noise plus whatever the plain fit leaves).  Shapes (nch,) for one window, (n_runs, n_speeds, nch) stacked.
    """

    X: np.ndarray
    var_re: np.ndarray
    var_im: np.ndarray
    noise_var: np.ndarray

    @classmethod
    def of(cls, fit) -> 'PlainFit':
        """From a :class:`bearing_id.signals.harmonics.HarmonicFit` of order 1."""
        return cls(np.asarray(fit.X[0], dtype=complex), np.asarray(fit.std_re[0]) ** 2,
                   np.asarray(fit.std_im[0]) ** 2, np.asarray(fit.residual_rms) ** 2)

    def arrays(self) -> tuple:
        return self.X, self.var_re, self.var_im, self.noise_var

    def take(self, index) -> 'PlainFit':
        """Return the fit with ``index`` applied to every array."""
        return PlainFit(*(np.asarray(a)[index] for a in self.arrays()))

    @staticmethod
    def stack(rows) -> 'PlainFit':
        """Stack nested lists (runs x speeds) of per-window fits into one (n_runs, n_speeds, nch) fit."""
        return PlainFit(*(np.array([[getattr(f, k) for f in row] for row in rows])
                          for k in ('X', 'var_re', 'var_im', 'noise_var')))

    def combined(self, other: 'PlainFit') -> 'PlainFit':
        """Inverse-variance mean with the fit of another piece of the same dwell (its variances propagated)."""
        wa, wb = (2.0 / np.maximum(f.var_re + f.var_im, 1e-300) for f in (self, other))
        w = wa + wb
        return PlainFit((wa * self.X + wb * other.X) / w, (wa ** 2 * self.var_re + wb ** 2 * other.var_re) / w ** 2,
                        (wa ** 2 * self.var_im + wb ** 2 * other.var_im) / w ** 2,
                        (wa * self.noise_var + wb * other.noise_var) / w)


# ------------------------------------------------------------------------------------------ the one route to 1X
@dataclass
class ClosedWindow:
    """
    The raw data of one steady window cut from a run's sample stream (SI).

    i0, i1 : its sample range, counted over everything fed to the run's :class:`RunStream` (for a whole recording:
    indices into it); samples (n, nch) [m]; angle (n,) [rad]; speed (n,) [rad/s] (from the angle);
    after_gap : the window starts right after lost data (the remainder of a dwell split by a lost block);
    continued : the window continues the previous one, closed only because it reached the length limit (no
    settling part is dropped from it);
    stamp : time of its first sample [s] when the stream was stamped, else None; seqs : (first, last) block
    sequence numbers when fed block by block, else None; stream_id : the :class:`RunStream` it was cut from;
    provisional : cut by :meth:`RunStream.peek` from a stream still open (its data so far, as ``close()`` would cut
    it now), not by the stream itself.
    """

    run: Run
    probes: tuple
    sample_rate: float
    i0: int
    i1: int
    samples: np.ndarray
    angle: np.ndarray
    speed: np.ndarray
    after_gap: bool = False
    continued: bool = False
    stamp: float | None = None
    seqs: tuple | None = None
    stream_id: str | None = None
    provisional: bool = False

    @property
    def duration(self) -> float:
        return (self.i1 - self.i0) / self.sample_rate

    @property
    def key(self) -> str:
        """Return what names the window: its stream and first sample (a provisional cut and the final one share it)."""
        return f'{self.stream_id}:{self.i0}'


@dataclass
class WindowVector:
    """
    The 1X vector of one steady window.

    Fields: speed [rad/s] (median over the fitted part), X complex (nch,) [m], X_std (nch,) [m] (1-sigma of the real and
    of the imaginary part), the fitted sample range [i0, i1), the window, and ``plain`` the plain 1X fit of the same
    samples (:class:`PlainFit`, None when not known).
    """

    speed: float
    X: np.ndarray
    X_std: np.ndarray
    i0: int
    i1: int
    window: ClosedWindow = field(repr=False)
    plain: PlainFit | None = None


class RunStream:
    """
    One excitation run's sample stream, cut into steady windows as it arrives -- the route every 1X vector takes.

    ``feed(samples (n, nch), angle (n,), contiguous=True)`` appends a chunk (a whole recording, or one
    DisplacementBlock) and returns the :class:`ClosedWindow` s it closed; ``close()`` ends the stream's open window. The
    per-sample speed is :func:`bearing_id.signals.windows.speed_from_angle` of the concatenated angle (each chunk's last
    sample waits for the next chunk's first); windows follow :class:`bearing_id.signals.windows.SteadyWindowTracker`, so
    any chunking gives the windows of the whole record. A contiguous chunk whose angle restarts (a sender writing each
    block's angle wrapped to [0, 2 pi)) is moved by whole turns to continue the last one
    (:func:`bearing_id.signals.keyphasor.continued_angle`, the rule the bag reader joins blocks by).
    ``contiguous=False`` (data were lost before this chunk) ends the open window at the gap.  A window that starts
    within ``SAME_DWELL_REVS`` revolutions of the last one's end at its speed (a dwell cut by a brief speed glitch, e.g.
    keyphasor jitter) is marked ``continued``: the two are one dwell, combined, and a later dwell at that speed is not
    confused with its second piece.  A window is also closed once it reaches ``max_duration`` [s] (bounds memory; the
    next window is then marked ``continued``).  Only the open window's samples are buffered.  ``peek()`` returns the
    windows ``close()`` would return now without closing anything (a live consumer's provisional look at the open window
    while its data pause; the stream goes on as if not asked).
    """

    def __init__(self, run, probes, sample_rate: float, *, tol_rel: float = defaults.SPEED_TOLERANCE,
                 max_duration: float = defaults.MAX_WINDOW):
        if not (math.isfinite(sample_rate) and sample_rate > 0):
            raise ValueError(f'sample_rate must be a positive number of Hz, got {sample_rate}')
        self.run, self.probes, self.fs = run, tuple(probes), float(sample_rate)
        self.tracker = SteadyWindowTracker(tol_rel)
        self.max_len = max(2, int(max_duration * self.fs)) if math.isfinite(max_duration) else None
        self._chunks: list = []        # (absolute start, samples, angle, speed, stamp, seq) of buffered samples
        self._held = None              # (x (1, nch), angle (1,), stamp, seq): last sample, waiting for its speed
        self._last_speed = math.nan
        self._after_gap = False        # the next window starts after a gap
        self._continued = False        # the next window continues one closed for its length
        self._recent: deque = deque(maxlen=8)   # (end sample, median speed [rad/s]) of the last windows cut
        self.tol_rel = float(tol_rel)
        self.n_fed = 0
        self.id = uuid.uuid4().hex[:16]  # names its windows (ClosedWindow.key), unique across processes and restarts

    def feed(self, samples, angle, *, contiguous: bool = True, stamp: float | None = None,
             seq: int | None = None) -> list[ClosedWindow]:
        x = np.asarray(samples, dtype=float)
        x = x[:, None] if x.ndim == 1 else x
        a = np.asarray(angle, dtype=float).reshape(-1)
        if x.shape[0] != a.size:
            raise ValueError(f'{x.shape[0]} sample rows but {a.size} angles')
        if x.ndim != 2 or x.shape[1] != len(self.probes):
            raise ValueError(f'samples shape {x.shape} does not match {len(self.probes)} probes')
        out = [] if contiguous else self._gap()
        if not a.size:
            return out
        if self._held is not None:
            hx, ha, hst, hseq = self._held
            w = self._last_speed if math.isfinite(self._last_speed) else (
                (a[-1] - a[0]) * self.fs / (a.size - 1) if a.size > 1 else math.nan)
            a = continued_angle(a, stamp, float(ha[-1]), hst, w, self.fs)     # a block restarting its angle
            ang = np.concatenate((ha, a))
            sp = np.diff(ang) * self.fs
            out += self._push(hx, ha, sp[:1], hst, hseq)
            sp = sp[1:]
        else:
            sp = np.diff(a) * self.fs
        if sp.size:
            self._last_speed = float(sp[-1])
            out += self._push(x[:-1], a[:-1], sp, stamp, seq)
        st_last = None if stamp is None else stamp + (a.size - 1) / self.fs
        self._held = (x[-1:], a[-1:], st_last, seq)
        return out

    def close(self) -> list[ClosedWindow]:
        """End of the stream (or of this run's data): the held last sample and the open window are closed."""
        out = self._flush_held()
        out += self._cut(self.tracker.close())
        self._chunks = []
        return out

    def peek(self) -> list[ClosedWindow]:
        """Return the windows :meth:`close` would return now, marked provisional; the stream itself is unchanged."""
        snap = copy.copy(self)
        snap.tracker = copy.copy(self.tracker)
        snap._chunks = list(self._chunks)       # its close() appends the held sample to this list; arrays are shared
        snap._recent = copy.copy(self._recent)  # ... and its windows to this one
        return [replace(w, provisional=True) for w in snap.close()]

    def _gap(self) -> list[ClosedWindow]:
        out = self.close()
        self._after_gap = True
        return out

    def _flush_held(self) -> list[ClosedWindow]:
        if self._held is None:
            return []
        hx, ha, hst, hseq = self._held
        self._held = None
        return self._push(hx, ha, np.array([self._last_speed]), hst, hseq)

    def _push(self, x, a, sp, stamp, seq) -> list[ClosedWindow]:
        start = self.n_fed
        self._chunks.append((start, x, a, sp, stamp, seq))
        self.n_fed += a.size
        out = []
        if self.max_len is None:
            out += self._cut(self.tracker.feed(sp))
        else:                     # feed so that no window grows past max_len samples
            k = 0
            while k < sp.size:
                room = self.max_len - self.tracker.open_length
                part = sp[k:k + room]
                closed = self.tracker.feed(part)
                k += part.size
                if self.tracker.open_length >= self.max_len:
                    out += self._cut(closed + self.tracker.close())
                    self._continued = True
                else:
                    out += self._cut(closed)
        keep_from = self.tracker.i0 if self.tracker.i0 is not None else self.n_fed
        self._chunks = [c for c in self._chunks if c[0] + c[2].size > keep_from]
        return out

    def _cut(self, ranges) -> list[ClosedWindow]:
        out = []
        for i0, i1 in ranges:
            sl = [(c, slice(max(i0 - c[0], 0), min(i1 - c[0], c[2].size))) for c in self._chunks
                  if c[0] < i1 and c[0] + c[2].size > i0]
            if len(sl) == 1:        # one chunk (a whole recording fed at once): views, no copies
                xs, an, sp = (sl[0][0][k][sl[0][1]] for k in (1, 2, 3))
            else:
                xs, an, sp = (np.concatenate([c[k][s] for c, s in sl]) for k in (1, 2, 3))
            c0, s0 = sl[0]
            st = None if c0[4] is None else c0[4] + s0.start / self.fs
            seqs = None if c0[5] is None else (c0[5], sl[-1][0][5])
            w = float(np.median(sp))
            # a dwell cut by a speed glitch (the glitch a short window of its own): its pieces are one dwell
            glitch = not self._after_gap and w > 0 and any(
                0 <= i0 - end <= SAME_DWELL_REVS * 2 * math.pi / w * self.fs and abs(w - w0) <= self.tol_rel * w
                for end, w0 in self._recent)
            out.append(ClosedWindow(self.run, self.probes, self.fs, i0, i1, xs, an, sp, self._after_gap,
                                    self._continued or glitch, st, seqs, self.id))
            self._after_gap = self._continued = False
            if (i1 - i0) / self.fs >= defaults.MIN_WINDOW:   # a dwell's piece; not a ramp's slice or the glitch
                self._recent.append((i1, w))
        return out


SAME_DWELL_REVS = 2.0   # a window at the last one's speed starting within this many revolutions of its end: same dwell
STATIONARITY_SIGMA = 3.0   # halves of a window disagreeing by more than this many sigma count as a transient


def window_vector(win: ClosedWindow, *, settle: float = defaults.SETTLE_FRACTION,
                  min_duration: float = defaults.MIN_WINDOW, transients: int = defaults.TRANSIENTS
                  ) -> WindowVector | None:
    """
    Return the 1X vector of a steady window, or None when the window is too short to use.

    The rule: windows shorter than ``min_duration`` [s] are not used; the first ``settle`` fraction is discarded
    (the transient after the speed change); the rest (at least 16 samples) is fitted over whole revolutions jointly
    with up to ``transients`` decaying components (:func:`bearing_id.signals.harmonics.harmonic_vectors`; the decaying
    components' time base is the sample index / sample rate, so every route fits the same numbers); the 1-sigma is
    the joint fit's, plus the :func:`stationarity_excess` bias bound.
    """
    n = win.i1 - win.i0
    if n < 2 or win.duration < min_duration:
        return None
    j0 = 0 if win.continued else int(math.ceil(settle * n))
    if n - j0 < 16:
        return None
    w = float(np.median(win.speed[j0:]))
    if not w > 0:
        return None
    x, a = win.samples[j0:], win.angle[j0:]
    fit = harmonic_vectors(x, a, orders=(1,), transients=transients, sample_rate=win.sample_rate)
    std = np.sqrt(np.maximum(fit.std_re[0], fit.std_im[0]) ** 2 + stationarity_excess(x, a, win.sample_rate, fit))
    # with no decaying component kept, the fit is the plain one (harmonic_vectors keeps the plain regression then)
    plain = PlainFit.of(fit if fit.plain is None else fit.plain)
    return WindowVector(w, fit.X[0], std, win.i0 + j0, win.i1, win, plain)


def stationarity_excess(x, angle, sample_rate: float, fit=None) -> np.ndarray:
    """
    Return the extra variance [m^2] per channel (per real/imaginary part) when a window is not stationary.

    The window: x (n, nch), angle (n,).

    The 1X vector is fitted on each half of the window, after subtracting the decaying components that ``fit``
    (the window's transient-aware fit, if given) found.  When the halves differ by more than ``STATIONARITY_SIGMA``
    times their combined noise std (a transient still ringing that the fit did not model), half the difference is
    taken as a bias bound and added in quadrature to the 1-sigma of X, so that every downstream std, rank and
    'determined' flag accounts for it.  Stationary windows get 0.
    """
    n = x.shape[0]
    mid = n // 2
    if mid < 16 or n - mid < 16:
        return np.zeros(x.shape[1])
    if fit is not None and fit.transient_rates.size:
        x = x - fit.transient_part(np.arange(n) / sample_rate)
    a = harmonic_vectors(x[:mid], angle[:mid], orders=(1,))
    b = harmonic_vectors(x[mid:], angle[mid:], orders=(1,))
    d = np.abs(a.X[0] - b.X[0])
    sig = np.sqrt(a.std[0] ** 2 + b.std[0] ** 2)
    return np.where(d > STATIONARITY_SIGMA * sig, (d / 2) ** 2 / 2, 0.0)


def combine_vectors(a: WindowVector, b: WindowVector) -> WindowVector:
    """
    Inverse-variance mean of two vectors of one dwell (a window split by lost data): X and its 1-sigma.

    Their plain fits are combined alike (:meth:`PlainFit.combined`; None when either part lacks one).
    """
    wa, wb = 1.0 / np.maximum(a.X_std, 1e-300) ** 2, 1.0 / np.maximum(b.X_std, 1e-300) ** 2
    X = (wa * a.X + wb * b.X) / (wa + wb)
    plain = None if a.plain is None or b.plain is None else a.plain.combined(b.plain)
    return WindowVector(float((a.speed + b.speed) / 2), X, 1.0 / np.sqrt(wa + wb), a.i0, b.i1, a.window, plain)


def iter_windows(rec, *, tol_rel=defaults.SPEED_TOLERANCE, max_window: float = defaults.MAX_WINDOW):
    """
    Yield the steady windows of one recording as they close: its pieces fed in order to a :class:`RunStream`.

    ``rec.pieces()`` gives (samples, angle, contiguous): an in-memory Recording its arrays between its ``gaps``
    (views), a recording read from disk (:class:`bearing_id.io.recordings.NpzRecording`) pieces of it, so that at most
    one window (``max_window`` [s]; the next one is then marked ``continued``) and one piece are held.
    """
    stream = RunStream(rec.run, rec.probes, rec.sample_rate, tol_rel=tol_rel, max_duration=max_window)
    for x, a, contiguous in rec.pieces():
        yield from stream.feed(x, a, contiguous=contiguous)
    yield from stream.close()


def recording_windows(rec, *, tol_rel=defaults.SPEED_TOLERANCE, max_window: float = defaults.MAX_WINDOW
                      ) -> list[ClosedWindow]:
    """
    Return the steady windows of one recording (:func:`iter_windows`): fed to a :class:`RunStream`, split at its gaps.

    A window is closed at the ``max_window`` [s] length limit too (the next one is then marked ``continued``).
    """
    return list(iter_windows(rec, tol_rel=tol_rel, max_window=max_window))


def window_vectors(wins, vectors, tol_rel: float = defaults.SPEED_TOLERANCE) -> list[WindowVector]:
    """
    Return one recording's 1X vectors from its windows ``wins`` and their :func:`window_vector` results ``vectors``.

    Windows without a vector (None) are left out; a vector is given its window; the pieces of a dwell split by a gap
    or by the window length limit are combined (:func:`combine_vectors`).
    """
    out: list[WindowVector] = []
    for win, v in zip(wins, vectors):
        if v is None:
            continue
        if v.window is not win:
            v = replace(v, window=win)
        if (win.after_gap or win.continued) and out and abs(out[-1].speed - v.speed) <= tol_rel * v.speed:
            out[-1] = combine_vectors(out[-1], v)
        else:
            out.append(v)
    return out


def recording_vectors(rec, *, tol_rel=defaults.SPEED_TOLERANCE, settle=defaults.SETTLE_FRACTION,
                      min_duration=defaults.MIN_WINDOW, transients: int = defaults.TRANSIENTS,
                      max_window: float = defaults.MAX_WINDOW) -> list[WindowVector]:
    """
    Return the 1X vectors of every steady window of one recording.

    Its windows (:func:`iter_windows`), each one's :func:`window_vector` as it closes, assembled by
    :func:`window_vectors`.  A window's arrays are dropped once fitted (the vectors keep its description,
    :func:`bare_window`): a recording is held one window at a time, never whole.
    """
    wins, vecs = [], []
    for w in iter_windows(rec, tol_rel=tol_rel, max_window=max_window):
        v = window_vector(w, settle=settle, min_duration=min_duration, transients=transients)
        wins.append(bare_window(w))
        vecs.append(None if v is None else replace(v, window=wins[-1]))
    return window_vectors(wins, vecs, tol_rel)


def bare_window(win: ClosedWindow) -> ClosedWindow:
    """Return ``win`` without its samples, angle and speed (empty arrays of their kind: no view keeps them alive)."""
    return replace(win, samples=np.zeros((0, win.samples.shape[1])), angle=np.zeros(0), speed=np.zeros(0))


def common_speeds(per_run, tol_rel: float = defaults.SPEED_TOLERANCE) -> tuple[list, list]:
    """
    Find the speeds present in every run.

    per_run[r] = list of objects with ``.speed`` (or tuples whose first item is the speed) in the run's order.  Returns
    (speeds of the first run, picks) with picks[s][r] the index into per_run[r] of the LATEST entry within ``tol_rel``
    of speed s: a speed dwelt at again is the machine as it is now (the tracking rule, live and offline alike).  A
    speed repeated in the first run counts once, at its first place.
    """
    def sp(v):
        return float(v.speed) if hasattr(v, 'speed') else float(v[0])
    speeds, picks = [], []
    for v0 in per_run[0] if per_run else []:
        w = sp(v0)
        row = []
        for lst in per_run:
            m = [k for k, v in enumerate(lst) if abs(sp(v) - w) <= tol_rel * w]
            if not m:
                break
            row.append(m[-1])
        else:
            if not any(abs(w - s) <= tol_rel * w for s in speeds):
                speeds.append(w)
                picks.append(row)
    return speeds, picks


def from_recordings(recordings, *, tol_rel=defaults.SPEED_TOLERANCE, settle=defaults.SETTLE_FRACTION,
                    min_duration=defaults.MIN_WINDOW, transients: int = defaults.TRANSIENTS) -> HarmonicData:
    """
    1X vectors of every run (one Recording per excitation run, same channels) at the speeds common to all runs.

    ``transients``: decaying components allowed in each window's fit (module docstring); 0 = the plain fit.
    """
    recordings = list(recordings)
    if not recordings:
        raise ValueError('no recordings given')
    probes = tuple(recordings[0].probes)
    for r in recordings[1:]:
        if tuple((p.node, p.direction) for p in r.probes) != tuple((p.node, p.direction) for p in probes):
            raise ValueError(f'run {r.run.id} has channels {r.channels}, run {recordings[0].run.id} has '
                             f'{recordings[0].channels}: all runs must use the same probes')
    per_run = [recording_vectors(r, tol_rel=tol_rel, settle=settle, min_duration=min_duration, transients=transients)
               for r in recordings]
    return stack_vectors(recordings, per_run, tol_rel)


def stack_vectors(recordings, per_run, tol_rel=defaults.SPEED_TOLERANCE) -> HarmonicData:
    """
    Stack the runs' window vectors at the speeds common to all runs into a :class:`HarmonicData`.

    ``per_run[r]`` holds :func:`recording_vectors` of ``recordings[r]``; speeds are matched by :func:`common_speeds`.
    """
    recordings = list(recordings)
    speeds, picks = common_speeds(per_run, tol_rel)
    if not speeds:
        raise ValueError('no steady speed is common to all runs')
    nr, ns, nch = len(recordings), len(speeds), len(recordings[0].probes)
    X = np.zeros((nr, ns, nch), dtype=complex)
    Xs = np.zeros((nr, ns, nch))
    plains = [[None] * ns for _ in range(nr)]
    windows = [[None] * ns for _ in range(nr)]
    for s, row in enumerate(picks):
        for r, k in enumerate(row):
            v = per_run[r][k]
            X[r, s], Xs[r, s], windows[r][s] = v.X, v.X_std, (v.i0, v.i1)
            plains[r][s] = v.plain
    truth = {}
    for rec in recordings:
        truth.update(rec.truth.get('coefficients', {}) if rec.truth else {})
    return HarmonicData(np.array(speeds), tuple(recordings[0].probes), tuple(r.run for r in recordings), X, Xs,
                        recordings, windows, truth,
                        None if any(p is None for row in plains for p in row) else PlainFit.stack(plains),
                        float(recordings[0].sample_rate))


__all__ = ['HarmonicData', 'PlainFit', 'ClosedWindow', 'WindowVector', 'RunStream', 'window_vector',
           'stationarity_excess', 'combine_vectors', 'iter_windows', 'recording_windows', 'bare_window',
           'window_vectors', 'recording_vectors', 'common_speeds', 'stack_vectors',
           'from_recordings']
