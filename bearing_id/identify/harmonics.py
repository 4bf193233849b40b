"""Collect the measured 1X harmonic vectors per excitation run and per steady speed, from recordings or a bag.

Rule for each run
    The speed record is split into steady windows (:func:`bearing_id.signals.steady_windows`, speed constant within
    ``tol_rel``); the first ``settle`` fraction of each window is discarded and the 1X vectors of the rest are
    fitted over whole revolutions (:func:`bearing_id.signals.harmonic_vectors`) jointly with up to ``transients``
    exponentially decaying sinusoids (default 3: the rotor's lightly damped modes ring for seconds after every speed
    change, and a mode near running speed biases a plain 1X fit by percent).  The 1X std is the joint fit's.  A
    window-halves check on the signal minus the fitted transients adds a bias bound for anything left unmodelled
    (:func:`stationarity_excess`).
    Speeds from different runs are matched when they agree within ``tol_rel``; only speeds present in every run are
    kept (identification stacks the runs at one speed).

Shapes: ``X`` complex (n_runs, n_speeds, n_channels) [m] with x(t) = Re{X exp(j phi)}; ``X_std`` the 1-sigma of the
real and of the imaginary part (each) [m]; ``speeds`` (n_speeds,) rad/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..signals import harmonic_vectors, steady_windows

DEFAULT_SETTLE = 0.25      # fraction of each steady window discarded at its start (the identifier node uses the same)
DEFAULT_TOL_REL = 0.005    # relative speed tolerance of a steady window and of matching speeds across runs
DEFAULT_TRANSIENTS = 3     # decaying sinusoids (rotor modes ringing after a speed change) fitted with the 1X


@dataclass
class HarmonicData:
    """Measured 1X phasors per run and speed (see module docstring for shapes and units).

    windows[r][s] = (i0, i1) sample range of run r used at speed s (into ``recordings[r]``), or None.
    truth = {speed [rad/s]: {node: (K, C)}} when the recordings carry it (simulated rig), else {}.
    """
    speeds: np.ndarray
    probes: tuple
    runs: tuple
    X: np.ndarray
    X_std: np.ndarray
    recordings: list = field(default_factory=list, repr=False)
    windows: list = field(default_factory=list, repr=False)
    truth: dict = field(default_factory=dict, repr=False)

    @property
    def n_runs(self) -> int:
        return self.X.shape[0]

    def truth_at(self, speed: float, tol_rel: float = DEFAULT_TOL_REL):
        """The true coefficients {node: (K, C)} nearest ``speed`` [rad/s], or None."""
        if not self.truth:
            return None
        s = min(self.truth, key=lambda k: abs(k - speed))
        return self.truth[s] if abs(s - speed) <= tol_rel * max(abs(speed), 1e-12) else None

    def select(self, speeds_idx) -> "HarmonicData":
        """A copy holding only the speeds at the given indices."""
        idx = list(speeds_idx)
        return HarmonicData(self.speeds[idx], self.probes, self.runs, self.X[:, idx], self.X_std[:, idx],
                            self.recordings, [[w[i] for i in idx] for w in self.windows] if self.windows else [],
                            self.truth)


def run_windows(rec, *, tol_rel=DEFAULT_TOL_REL, settle=DEFAULT_SETTLE, min_duration=0.2) -> list[tuple]:
    """[(speed [rad/s], i0, i1)] steady windows of a recording with the settling part removed."""
    out = []
    for i0, i1 in steady_windows(rec.t, rec.speed, tol_rel=tol_rel, min_duration=min_duration):
        j0 = i0 + int(math.ceil(settle * (i1 - i0)))
        if i1 - j0 < 16:
            continue
        w = float(np.median(rec.speed[j0:i1]))
        if w <= 0:
            continue
        out.append((w, j0, i1))
    return out


STATIONARITY_SIGMA = 3.0   # halves of a window disagreeing by more than this many sigma count as a transient


def window_fit(rec, i0: int, i1: int, *, transients: int = DEFAULT_TRANSIENTS):
    """1X fit of samples i0..i1-1 of a recording: the transient-aware fit (:func:`bearing_id.signals.harmonic_vectors`
    with up to ``transients`` decaying components, 0 = plain least squares).

    The time base of the decaying components is the sample index / ``rec.sample_rate`` from i0 (the samples of a
    steady window are evenly spaced), not ``rec.t``: a live node and the offline route then fit the same numbers
    whatever their clocks' origin.
    """
    return harmonic_vectors(rec.samples[i0:i1], rec.angle[i0:i1], orders=(1,), transients=transients,
                            sample_rate=rec.sample_rate)


def stationarity_excess(rec, i0: int, i1: int, fit=None) -> np.ndarray:
    """Extra variance [m^2] per channel (per real/imaginary part) when a window is not stationary.

    The 1X vector is fitted on each half of the window, after subtracting the decaying components that ``fit``
    (the window's transient-aware fit, if given) found.  When the halves differ by more than ``STATIONARITY_SIGMA``
    times their combined noise std (a transient still ringing that the fit did not model), half the difference is
    taken as a bias bound and added in quadrature to the 1-sigma of X, so that every downstream std, rank and
    'determined' flag accounts for it.  Stationary windows get 0.
    """
    mid = (i0 + i1) // 2
    if mid - i0 < 16 or i1 - mid < 16:
        return np.zeros(rec.samples.shape[1])
    x = rec.samples[i0:i1]
    if fit is not None and fit.transient_rates.size:
        x = x - fit.transient_part(np.arange(i1 - i0) / rec.sample_rate)
    a = harmonic_vectors(x[:mid - i0], rec.angle[i0:mid], orders=(1,))
    b = harmonic_vectors(x[mid - i0:], rec.angle[mid:i1], orders=(1,))
    d = np.abs(a.X[0] - b.X[0])
    sig = np.sqrt(a.std[0] ** 2 + b.std[0] ** 2)
    return np.where(d > STATIONARITY_SIGMA * sig, (d / 2) ** 2 / 2, 0.0)


def from_recordings(recordings, *, tol_rel=DEFAULT_TOL_REL, settle=DEFAULT_SETTLE, min_duration=0.2,
                    transients: int = DEFAULT_TRANSIENTS) -> HarmonicData:
    """1X vectors of every run (one Recording per excitation run, same channels) at the speeds common to all runs.

    ``transients``: decaying components allowed in each window's fit (module docstring); 0 = the plain fit.
    """
    recordings = list(recordings)
    if not recordings:
        raise ValueError("no recordings given")
    probes = tuple(recordings[0].probes)
    for r in recordings[1:]:
        if tuple((p.node, p.direction) for p in r.probes) != tuple((p.node, p.direction) for p in probes):
            raise ValueError(f"run {r.run.id} has channels {r.channels}, run {recordings[0].run.id} has "
                             f"{recordings[0].channels}: all runs must use the same probes")
    per_run = [run_windows(r, tol_rel=tol_rel, settle=settle, min_duration=min_duration) for r in recordings]
    # speeds common to every run (match within tol_rel); the first run's list is the reference
    speeds, picks = [], []
    for w, *_ in per_run[0]:
        row = []
        for wins in per_run:
            m = [k for k, (v, *_) in enumerate(wins) if abs(v - w) <= tol_rel * w]
            if not m:
                break
            row.append(m[0])
        else:
            if not any(abs(w - s) <= tol_rel * w for s in speeds):
                speeds.append(w)
                picks.append(row)
    if not speeds:
        raise ValueError("no steady speed is common to all runs")
    nr, ns, nch = len(recordings), len(speeds), len(probes)
    X = np.zeros((nr, ns, nch), dtype=complex)
    Xs = np.zeros((nr, ns, nch))
    windows = [[None] * ns for _ in range(nr)]
    for s, row in enumerate(picks):
        for r, k in enumerate(row):
            _, i0, i1 = per_run[r][k]
            rec = recordings[r]
            fit = window_fit(rec, i0, i1, transients=transients)
            X[r, s] = fit.X[0]
            Xs[r, s] = np.sqrt(np.maximum(fit.std_re[0], fit.std_im[0]) ** 2 + stationarity_excess(rec, i0, i1, fit))
            windows[r][s] = (i0, i1)
    truth = {}
    for rec in recordings:
        truth.update(rec.truth.get("coefficients", {}) if rec.truth else {})
    return HarmonicData(np.array(speeds), probes, tuple(r.run for r in recordings), X, Xs, recordings, windows,
                        truth)


def from_npz(paths, **kw) -> HarmonicData:
    """Load .npz recordings (``rig.load_npz``; one file per run) and collect their 1X vectors."""
    from ..rig import load_npz
    return from_recordings([load_npz(p) for p in paths], **kw)


def recordings_from_bag(path) -> list:
    """One rig.Recording per excitation run from a bag (topics /rotor/displacement and /rotor/excitation).

    Each /rotor/excitation message (run_id and entries) starts a run; the DisplacementBlock messages that follow it
    belong to it.  Within a block the angle is the block's first-sample angle + speed * k / sample_rate (speed
    constant over one block).  A block whose channels differ from the run's first block is refused (ValueError).
    """
    from ..io.bags import read_bag
    from ..params import ExcitationEntry, Probe, Run
    from ..rig import Recording
    runs, cur = [], None
    for topic, _, _, msg in read_bag(path, topics=["/rotor/displacement", "/rotor/excitation"]):
        if topic == "/rotor/excitation":
            ex = tuple(ExcitationEntry(str(k), int(n), float(m), float(p), str(d), float(f)) for k, n, m, p, d, f in
                       zip(msg.kind, msg.node, msg.magnitude, msg.phase, msg.direction, msg.frequency_ratio))
            if cur is not None and cur["run"].id == msg.run_id and cur["run"].excitation == ex:
                continue        # re-sent (transient-local) copy of the same run
            cur = {"run": Run(str(msg.run_id), ex), "blocks": []}
            runs.append(cur)
            continue
        if cur is None:
            continue            # displacement before any excitation is known: not usable for identification
        cur["blocks"].append(msg)
    recs = []
    for r in runs:
        bl = r["blocks"]
        if not bl:
            continue
        chans = tuple(zip(bl[0].channels, bl[0].nodes, bl[0].directions))
        samples, angle, speed = [], [], []
        fs = float(bl[0].sample_rate)
        for m in bl:
            if tuple(zip(m.channels, m.nodes, m.directions)) != chans:
                raise ValueError(f"{path}: run {r['run'].id}: channels change from {chans} to "
                                 f"{tuple(zip(m.channels, m.nodes, m.directions))}")
            x = np.asarray(m.samples, dtype=float).reshape(-1, len(chans))
            k = np.arange(x.shape[0])
            samples.append(x)
            angle.append(float(m.angle) + float(m.speed) * k / fs)
            speed.append(np.full(x.shape[0], float(m.speed)))
        x = np.vstack(samples)
        recs.append(Recording(sample_rate=fs, t=np.arange(x.shape[0]) / fs, speed=np.concatenate(speed),
                              angle=np.unwrap(np.concatenate(angle)),
                              probes=tuple(Probe(str(c), int(n), str(d)) for c, n, d in chans), samples=x,
                              run=r["run"]))
    if not recs:
        raise ValueError(f"{path}: no displacement blocks after an excitation message")
    return recs


def from_bag(path, **kw) -> HarmonicData:
    """Read a bag into one Recording per excitation run (:func:`recordings_from_bag`) and collect their 1X vectors."""
    return from_recordings(recordings_from_bag(path), **kw)


def simulate_data(rig, runs, speeds_rpm, *, probes=None, noise=0.0, bearing_fn=None, model=None) -> HarmonicData:
    """Noise-free (or analytic-noise) 1X phasors straight from the truth system -- no time series (tests, design).

    X[r, s] = S q with q = Z(speed)^-1 F_r the steady response of the truth bearings ``bearing_fn`` (default the rig's
    truth); with ``noise`` > 0 a complex Gaussian error of std ``noise * |X| / sqrt(2)`` per Re/Im is NOT added here
    (the caller adds it with its own seed) but recorded in X_std.
    """
    from ..conventions import rpm_to_rad_s
    from ..excitation import harmonic_forces
    from ..rig import truth_bearing_fn
    from ..rotor.assembly import RotorModel, harmonic_response, probe_matrix
    model = model or RotorModel.from_params(rig)
    probes = tuple(probes if probes is not None else rig.probes)
    bearing_fn = bearing_fn or truth_bearing_fn(rig)
    speeds = np.array([float(rpm_to_rad_s(s)) for s in speeds_rpm])
    S = probe_matrix(model, probes)
    X = np.zeros((len(runs), len(speeds), len(probes)), dtype=complex)
    truth = {}
    for j, w in enumerate(speeds):
        co = bearing_fn(w)
        truth[float(w)] = co
        for i, run in enumerate(runs):
            F = harmonic_forces(run.excitation, w, model.n_nodes).get(1.0)
            if F is not None:
                X[i, j] = S @ harmonic_response(model, w, w, F, co)
    Xs = noise * np.abs(X) / math.sqrt(2)
    return HarmonicData(speeds, probes, tuple(runs), X, Xs, [], [], truth)


__all__ = ["HarmonicData", "from_recordings", "from_npz", "from_bag", "recordings_from_bag", "run_windows", "simulate_data",
           "window_fit", "stationarity_excess", "DEFAULT_SETTLE", "DEFAULT_TOL_REL", "DEFAULT_TRANSIENTS"]
