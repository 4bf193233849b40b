"""
The ``kf_estimator`` node's core (no ROS): the paper's Kalman filter (section 3.1) block by block.

Besides the filter: the node's health items for /diagnostics (filter consistency: mean NIS against its 95 %
chi-square band; model health: 1X/2X-coherent or correlated innovations; model validity: orbit against
``ORBIT_LIMIT`` of the clearance, speed against the stability threshold).

Model cache
    The discretised FE model (:func:`bearing_id.estimation.kalman.rotor_kalman_model`, on the Craig-Bampton reduced
    rotor that keeps every mode below ``model_cutoff`` times the sample rate; its bearings are the identifier's latest
    fully determined coefficients where they cover the speed, else the theory's: :class:`IdentifiedBearings`) is
    cached per speed band (relative width ``speed_band``) and the bearing results it uses, at most ``MAX_MODELS`` (the
    filter operators of ``MAX_OPERATORS``), and
    built by a worker thread with the latest noise.  A block whose model is not built yet waits in an ordered queue (at
    most ``max_pending_blocks``) while the callback returns at once.  Expected speeds (``prebuild_speeds_rpm``) are
    built at start-up.  When a channel's noise moves by more than ``NOISE_STEP`` from the model's, or the process noise
    the innovations imply by more than ``Q_STEP`` (``process_noise`` 0, the default:
    :meth:`EstimatorCore._fit_process_noise`; on a speed ramp at least ``RAMP_PROCESS_NOISE``), its gain is re-solved
    (and cached).  The filter starts from the model's
    steady state (kalman.StreamingKF) at a new run or after lost data; when only the model changes (speed band,
    bearings, noise) the state carries over (``continue_from``).

Speed ramps
    The model follows the speed within a block: a block whose speed crosses bands is split at their edges
    (:func:`speed_pieces`, ``SPEED_PIECE`` samples resolution) and each piece filtered on its band's model, with its
    own excitation; ramp models are cached per band, a steady speed's per ``MODEL_RESOLUTION`` of a band (its model
    within 0.1 % of the speed).  With one model per block (its mean speed) a 0.3 s ramp through the first critical
    speed of an unequal-bearing variant put the estimated bearing motion 29 % of the orbit warning limit off the
    truth; split, 4.8 % (``test_kf_identified.py``).

Filter consistency
    The mean NIS over the last ``nis_window`` blocks is judged against its 95 % chi-square band widened by the
    relative 1-sigma of the R it is normalised by when R comes from the data (:meth:`EstimatorCore.noise_rel_std`,
    :func:`bearing_id.estimation.kalman.nis_band`): the chi-square band alone assumes R known, and at long windows
    it is narrower than any R a few blocks can estimate (20 s at 10,240 Hz, 2 probes: +-0.44 %, against ~3 % for
    R from 8 blocks of 1024 samples).
"""
from __future__ import annotations

from collections import deque, OrderedDict
from dataclasses import dataclass
import math
import queue
import threading
import time

import numpy as np

from .heap import release_free_heap
from .specs import ParamSpec
from .status import DiagItem, OK, WARN
from ..config import defaults
from ..config.params import Probe
from ..conventions import phasor_to_time, rad_s_to_rpm
from ..estimation.kalman import nis_band, rotor_kalman_model, StreamingKF
from ..estimation.process_noise import process_noise_scale
from ..estimation.uncertainty import coefficient_sigma, filter_std
from ..excitation import harmonic_forces
from ..identify.plausibility import ORBIT_LIMIT
from ..rotor import stability, supports
from ..rotor.assembly import probe_matrix, RotorModel
from ..rotor.reduction import craig_bampton, kf_kept_dofs, receptance_error
from ..signals.harmonics import harmonic_vectors
from ..signals.noise import difference_noise

NAME = 'kf_estimator'
# the default reduction: modes above the Nyquist frequency are left out (88 -> 52 states on the packaged rig at
# 10,240 Hz; the bearing-node 1X at 3000 rpm as the full model's within 0.05 of its stated 1-sigma: error against
# the simulated truth 3.111 % full, 3.120 % reduced).  A lower cutoff is not
# free: the process noise on the modes between it and Nyquist shapes the gain (at 1000 Hz the 3000 rpm estimates
# move by 2.4 %), so it is a parameter, not a tuning knob
MODEL_CUTOFF = 0.5

SPECS = [
    ParamSpec('rig_params', '', 'rig YAML with the nominal model (empty: the packaged params/rig.yaml)'),
    ParamSpec('process_noise', 0.0, 'Q, process noise variance per step times identity (paper: 1e-16 .. '
              '1e-18); 0: from the data (the multiple of 1e-16 I the broadband innovations imply, refitted every 8 '
              'blocks, kept within 1e-6 .. 1e6 of it, starting at its bottom: none until the data show some; on a '
              'speed ramp at least 1e-16)', 'm^2', lo=0.0, hi=1.0),
    ParamSpec('bearing_source', 'identified', "the model's bearing coefficients: the identifier's latest fully "
              'determined ones (subscribed on bearing_id/coefficients; theory where none cover the speed), or always '
              'the theory', choices=('identified', 'theory')),
    ParamSpec('measurement_noise', 0.0, 'probe noise standard deviation (R = value^2 times identity); 0: per '
              'channel from the data (the white part of the residual of a DC + 1X + 2X fit, from its third '
              'differences; median over the last 8 blocks, afresh at a new speed; the NIS band then allows for its '
              'uncertainty)', 'm',
              lo=0.0, hi=1e-3),
    ParamSpec('model_cutoff', MODEL_CUTOFF, "the filter's FE model is Craig-Bampton reduced: the probe and bearing "
              'DOFs kept, and the rotor modes (bearings fixed) below this fraction of the sample rate (0.5: every '
              'mode below the Nyquist frequency, all the data can see); its 1X receptance error is on /diagnostics; '
              '0: the full FE model', '-', lo=0.0, hi=1e3),
    ParamSpec('speed_band', 0.01, 'relative width of the speed bands: a block crossing more than one (a fast ramp) is '
              "filtered piece by piece on each band's model; at a steady speed the model is within a tenth of it",
              '-',
              lo=1e-5, hi=0.2),
    ParamSpec('min_speed_rpm', 60.0, 'below this speed no oil-film model is run (blocks are skipped)', 'rpm',
              lo=0.0, hi=1e5),
    ParamSpec('prebuild_speeds_rpm', None, 'models built at start-up (unset: simulation.speeds_rpm of rig_params)',
              'rpm', lo=1.0, hi=1e5, type_='float[]'),
    ParamSpec('channels', None, "expected probe channel names (unset: the rig's probes)", type_='str[]'),
    ParamSpec('max_displacement', 1e-3, 'samples above this are implausible (wrong units or garbage)', 'm',
              lo=1e-9, hi=1.0),
    ParamSpec('max_pending_blocks', 400, "blocks held while their speed band's model is being built", 'blocks',
              lo=1, hi=100000),
    ParamSpec('nis_window', 50, 'blocks in the running mean of the normalised innovation squared', 'blocks',
              lo=1, hi=100000),
    ParamSpec('speed_timeout', 2.0, 'a /rotor/speed older than this is not used for blocks without speed', 's',
              lo=0.01, hi=3600.0),
    ParamSpec('stale_after', 5.0, 'an input silent for this long is reported STALE', 's', lo=0.1, hi=3600.0),
    ParamSpec('diagnostics_period', 1.0, 'period of /diagnostics', 's', lo=0.05, hi=60.0),
]


NOISE_BLOCKS = 8         # fitted blocks whose median DC and noise the filter uses
NOISE_EVERY = 4          # once NOISE_BLOCKS are fitted, every this many blocks of a stream is fitted (the rest reuse)
NOISE_STEP = 1.01       # a channel's noise std moving by more than this factor re-solves the filter's gain
NOISE_FLOOR = 1e-12     # m: the smallest noise std used (a noise-free signal still needs R > 0)
Q_STEP = 2.0            # the process noise the innovations imply moving by more than this factor re-solves the gain
Q_RANGE = 1e6           # the fitted process noise stays within this factor of defaults.KF_PROCESS_NOISE either way
# on a speed ramp (a block's speed more than the band from the last one's) the process noise is at least the paper's:
# the model follows the speed in steps and its response lags the machine's, a model error the dwells' fit never sees
RAMP_PROCESS_NOISE = defaults.KF_PROCESS_NOISE
DC_REG = 0.1            # Tikhonov weight of the DC step through the filter's bias gain (_track_dc)
DEFAULT_R_STD = 1e-7    # m: R of the cached models before the data give theirs
MODEL_MOVE = 0.25       # an identified coefficient moving less than this times its 1-sigma keeps the models
MODEL_TOL = 0.01        # ... or less than this fraction of its bearing's largest K (C) entry (IdentifiedBearings)
MAX_MODELS = 256        # models kept in the cache (the least recently used goes first): a run-up's ramp bands too
MAX_OPERATORS = 4       # ... of which this many most recently used keep their filter operators (~0.65 MB each)
TRIM_EVERY = 32         # operators dropped (~20 MB) between two returns of the C heap's free pages (nodes.heap)
SPEED_PIECE = 128       # samples: the resolution a block spanning several speed bands is split at (speed_pieces)
MODEL_RESOLUTION = 0.1  # models are cached per this fraction of a speed band: a model's speed is within it of the data
REDUCTION_WARN = 1e-3   # a reduced model's relative 1X receptance error above this is a WARN (raise the cutoff)


def _noise_moved(R, R_used, rel_std: float = 0.0) -> bool:
    """
    Whether the per-channel noise variance ``R`` moved from ``R_used`` by more than NOISE_STEP (in std).

    ``rel_std``: the relative 1-sigma of ``R``; a move within twice it is not taken as one (a ramp's noise rests on
    one block, ~7 % in variance: every block would re-solve the gain of every model the ramp crosses).
    """
    return bool(np.any(np.abs(np.log(R / R_used)) > max(2 * math.log(NOISE_STEP), 2 * rel_std)))


HEALTH_COHERENT = 0.2   # share of innovation power coherent with 1X or 2X above which the model is flagged
HEALTH_LAG1 = 0.5       # |lag-1 autocorrelation| of the innovations above which they are not white


def innovation_health_terms(nu: np.ndarray, angle: np.ndarray) -> dict:
    """Per-block sums for :func:`innovation_health`: nu (n, m) innovations [m], angle (n,) rotor angle [rad]."""
    nu = np.asarray(nu, dtype=float)
    return {'n': nu.shape[0], 'power': np.sum(nu**2, axis=0),
            1: nu.T @ np.exp(-1j * angle), 2: nu.T @ np.exp(-2j * angle),
            'lag1': np.sum(nu[1:] * nu[:-1], axis=0)}


def innovation_health(terms: list) -> dict:
    """
    Model health from innovations: the share of their power coherent with 1X and 2X, and lag-1 whiteness.

    A model that predicts the measurement leaves white innovations (shares ~ 2/N, lag-1 correlation ~ 0); a model
    that mispredicts the synchronous response leaves a coherent 1X (or 2X) in them.  Shares are the worst channel's.
    """
    n = sum(t['n'] for t in terms)
    power = sum(t['power'] for t in terms)
    out = {'n': n, 'fraction': {}}
    for k in (1, 2):
        c = sum(t[k] for t in terms) / n                 # mean of nu e^{-jk phi} = X_k / 2
        out['fraction'][k] = float(np.max(2 * np.abs(c) ** 2 / np.maximum(power / n, 1e-300)))
    out['lag1'] = float(np.max(sum(t['lag1'] for t in terms) / np.maximum(power, 1e-300)))
    return out


class IdentifiedBearings:
    """
    The bearing coefficients the filter's model uses: the identifier's latest fully determined ones, else the theory.

    ``add(speed, coeffs, stds)`` takes a result ({node: (K (2, 2), C (2, 2))} [N/m, N s/m] at ``speed`` [rad/s], and
    their 1-sigma in the same form); a result within ``tol_rel`` of a known speed replaces it.  Called with a speed, it
    returns the coefficients there: inside the range of identified speeds linearly interpolated between the two
    nearest (a single identified speed: within ``tol_rel`` of it), outside it the theory's (``theory_fn``).

    A result at a known speed is no change when every coefficient moved by less than MODEL_MOVE of its 1-sigma or
    less than MODEL_TOL of its bearing's largest K (C) entry: the identifier tracking a machine sends a new result at
    every window, and on a machine whose oil temperature cycles the coefficients drift by hundredths of a percent per
    result with a sigma smaller still; re-solving every model for each would cost the filter's whole budget.  The
    coefficients in use then stay, and their 1-sigma becomes sqrt(sigma^2 + move^2) per coefficient, so the stated
    uncertainty of the bearing motion (:meth:`uncertainty`) covers the model's lag behind the latest result.
    ``tag(speed)`` names the identified results a speed's coefficients come from (None: theory); the model cache is
    keyed by it, so a changed result rebuilds the models between its neighbours only.  ``generation`` counts the
    changes.  With one probe station the bearing-node motion is the model's extrapolation: theory bearings 25 % off
    put it ~80 % off, identified ones within their accuracy (issue 23).
    """

    def __init__(self, theory_fn, tol_rel: float):
        self.theory_fn = theory_fn
        self.tol_rel = float(tol_rel)
        self.speeds: list = []
        self.coeffs: list = []
        self.stds: list = []
        self.ids: list = []           # one id per result in use (a new one at every change)
        self.generation = 0           # changes of the coefficients in use
        self.revision = 0             # results taken (kept ones too: their 1-sigma changes)
        self.lock = threading.Lock()

    def add(self, speed: float, coeffs: dict, stds: dict | None = None) -> bool:
        """Take a result; return whether the coefficients in use changed (False: within MODEL_MOVE sigma/MODEL_TOL)."""
        with self.lock:
            self.revision += 1
            for i, w in enumerate(self.speeds):
                if abs(w - speed) <= self.tol_rel * speed:
                    kept = _kept_stds(self.coeffs[i], coeffs, stds)
                    if kept is not None:
                        self.stds[i] = kept
                        return False
                    self.generation += 1
                    self.speeds[i], self.coeffs[i], self.stds[i] = float(speed), coeffs, stds
                    self.ids[i] = self.generation
                    break
            else:
                self.generation += 1
                self.speeds.append(float(speed))
                self.coeffs.append(coeffs)
                self.stds.append(stds)
                self.ids.append(self.generation)
            order = np.argsort(self.speeds)
            self.speeds, self.coeffs, self.stds, self.ids = ([x[k] for k in order]
                                                             for x in (self.speeds, self.coeffs, self.stds, self.ids))
            return True

    def tag(self, speed: float):
        """Return the ids of the results the coefficients at ``speed`` [rad/s] come from, or None (theory)."""
        with self.lock:
            br = self._bracket(speed)
            return None if br is None else (self.ids[br[0]], self.ids[br[1]])

    def tags(self) -> set:
        """Return every tag a speed can have now (None, the theory's, aside)."""
        with self.lock:
            ids = self.ids
            return set(zip(ids, ids[1:])) if len(ids) > 1 else {(i, i) for i in ids}

    def source(self, speed: float) -> str:
        """Return what the model at ``speed`` [rad/s] uses: 'identified' or 'theory'."""
        with self.lock:
            return 'identified' if self._bracket(speed) is not None else 'theory'

    def _bracket(self, speed):
        sp = self.speeds
        if not sp or speed < sp[0] * (1 - self.tol_rel) or speed > sp[-1] * (1 + self.tol_rel):
            return None
        k = int(np.clip(np.searchsorted(sp, speed), 1, max(len(sp) - 1, 1)))
        if len(sp) == 1:
            return 0, 0, 0.0
        a, b = k - 1, k
        t = float(np.clip((speed - sp[a]) / (sp[b] - sp[a]), 0.0, 1.0))
        return a, b, t

    def __call__(self, speed: float) -> dict:
        with self.lock:
            br = self._bracket(speed)
            if br is None:
                return self.theory_fn(speed)
            return _blend(self.coeffs, *br)

    def uncertainty(self, speed: float) -> dict | None:
        """
        Return the 1-sigma {node: (K_std, C_std)} of the coefficients used at ``speed`` [rad/s], or None (theory).

        Between two identified speeds the 1-sigma are interpolated as the values are (the interpolated values' error
        is at most the larger of the two ends' for a coefficient that is linear between them).
        """
        with self.lock:
            br = self._bracket(speed)
            if br is None or any(s is None for s in (self.stds[br[0]], self.stds[br[1]])):
                return None
            return _blend(self.stds, *br)

    def describe(self) -> str:
        """Return, for people, which bearings the models use (identified where, theory where)."""
        with self.lock:
            if not self.speeds:
                return 'theory bearings (no identified coefficients received yet)'
            lo, hi = rad_s_to_rpm(self.speeds[0]), rad_s_to_rpm(self.speeds[-1])
            return (f'identified bearings at {len(self.speeds)} speed(s), {lo:.0f}-{hi:.0f} rpm (interpolated '
                    f'between them); theory outside')


def _kept_stds(used: dict, new: dict, stds: dict | None) -> dict | None:
    """
    Return the 1-sigma of the coefficients in use once ``new`` arrived, or None when ``new`` must replace them.

    None: some coefficient moved from ``used`` beyond both MODEL_MOVE of its 1-sigma (``stds``) and MODEL_TOL of its
    bearing's largest K (C) entry.  Kept: sqrt(sigma^2 + move^2) per coefficient.
    """
    if stds is None or set(used) != set(new):
        return None
    out = {}
    for n in new:
        pair = []
        for j in (0, 1):
            u, v, s = (np.asarray(x[n][j], dtype=float) for x in (used, new, stds))
            move = np.abs(v - u)
            if np.any((move > MODEL_MOVE * s) & (move > MODEL_TOL * np.max(np.abs(u)))):
                return None
            pair.append(np.hypot(s, move))
        out[n] = tuple(pair)
    return out


def _blend(items: list, a: int, b: int, t: float) -> dict:
    """Return (1 - t) items[a] + t items[b] for {node: (K, C)} dicts."""
    ca, cb = items[a], items[b]
    return {n: ((1 - t) * np.asarray(ca[n][0]) + t * np.asarray(cb[n][0]),
                (1 - t) * np.asarray(ca[n][1]) + t * np.asarray(cb[n][1])) for n in ca}


# ------------------------------------------------------------------------------------------------ pure part
def block_speed(angles: np.ndarray, sample_rate: float) -> float | None:
    """Mean rotor speed [rad/s] over a block from its per-sample angles [rad] (None when not positive/finite)."""
    if angles.size < 2:
        return None
    w = float((angles[-1] - angles[0]) * sample_rate / (angles.size - 1))
    return w if math.isfinite(w) and w > 0 else None


def band_key(speed: float, width: float) -> int:
    """Index of the relative speed band holding ``speed`` [rad/s] (bands of relative width ``width``)."""
    return int(math.floor(math.log(speed) / math.log1p(width)))


def speed_pieces(angles: np.ndarray, sample_rate: float, speed: float, width: float,
                 piece: int = SPEED_PIECE) -> list:
    """
    Split a block at the edges of the speed bands it crosses: [(start, stop, speed [rad/s])] covering its samples.

    ``angles`` (n,) keyphasor angle of every sample [rad]; ``speed`` [rad/s] the block's mean speed; ``width`` the
    bands' relative width (:func:`band_key`).  The speed of every ``piece`` samples is the slope of their angles (the
    last piece takes a short tail); consecutive pieces in one band are merged, each merged piece's speed is its own
    slope.  A block whose piece speeds span no more than ``width`` (a dwell, with keyphasor jitter), or whose angles
    give no positive finite speed, is one piece at ``speed``: only a ramp that crosses bands within the block is
    split, so the filter's model follows the speed within it.
    """
    n = angles.size
    edges = list(range(0, n - piece // 2, piece))[1:] if n >= 2 * piece else []
    if not edges:
        return [(0, n, float(speed))]
    bounds = [0] + edges + [n]

    def slope(i0, i1):
        return float((angles[i1 - 1] - angles[i0]) * sample_rate / (i1 - 1 - i0))

    sp = np.array([slope(a, b) for a, b in zip(bounds[:-1], bounds[1:])])
    if not (np.all(np.isfinite(sp)) and np.all(sp > 0)) or np.max(sp) <= (1 + width) * np.min(sp):
        return [(0, n, float(speed))]
    keys = [band_key(v, width) for v in sp]
    out, start = [], 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[start]:
            out.append((bounds[start], bounds[i], slope(bounds[start], bounds[i])))
            start = i
    return out


@dataclass
class Output:
    """What one processed block produced (SI units)."""

    seq: int
    stamp: float
    speed: float
    estimates: np.ndarray        # (n, 2 nb) bearing-node displacements [m]
    innovations: np.ndarray      # (n, m) [m]
    nis: np.ndarray              # (n,)
    block: object = None         # the input block (sample rate, angle, probes, frame)
    run_id: str = ''             # the excitation run the block was filtered with
    offset: np.ndarray | float = 0.0     # (m,) DC removed from the block's samples before filtering [m]
    nis_rel_std: float = 0.0     # relative 1-sigma of the R the NIS is normalised by (EstimatorCore.noise_rel_std)


class EstimatorCore:
    """
    The node's data path without ROS: model cache per speed band (built by a worker thread), one streaming filter.

    ``submit(block, run, speed, contiguous)`` queues a checked block; ``drain()`` processes every queued block whose
    model is ready, in order, and returns the Outputs.  ``block`` needs ``seq``, ``stamp`` [s], ``samples`` (n, m),
    ``angles()`` (n,) keyphasor angle of every sample [rad], ``sample_rate`` [Hz], ``probes`` (params.Probe per
    channel).  ``speed`` [rad/s] selects the model (its speed band) and the forcing frequency.
    """

    def __init__(self, rig, Q: float, R_std: float, band: float, max_pending: int = 400, nis_window: int = 50,
                 on_ready=None, cutoff: float = MODEL_CUTOFF):
        self.rig = rig
        self.on_ready = on_ready      # called (from the builder thread) after each model is built or failed
        self.rotor = RotorModel.from_params(rig)
        # the filter's model: Craig-Bampton reduced (cutoff > 0, one basis per sample rate) or the full rotor.  The
        # basis is speed and bearing independent, so the state carries over between the models of all speeds and
        # bearings
        self.cutoff = float(cutoff)
        self._kf_rotors: dict = {}     # sample rate [Hz] -> the rotor its models are built on
        self.reduction_error = 0.0     # largest relative 1X receptance error of the reduced models built
        self.bearing_fn = supports.bearing_fn(rig)
        self.bearings = IdentifiedBearings(self.bearing_fn, band)     # what the filter's models use
        # Q [m^2 per step, times identity on the full states] new models are built with: fixed (Q > 0), or fitted
        # to the broadband innovations (Q = 0: _fit_process_noise), starting at the bottom of its range (none)
        self.Q_fixed = float(Q) > 0
        self.Q = float(Q) if self.Q_fixed else defaults.KF_PROCESS_NOISE / Q_RANGE
        self.q_fits = 0               # times the fitted process noise moved the filter's gain
        self._q_unit: dict = {}       # sample rate [Hz] -> trace of the filter's Q for Q = 1 (full or reduced states)
        self._bb = None               # broadband innovation sums since the active model started (_fit_process_noise)
        self.R_fixed = float(R_std) > 0                 # else R per channel from the data (_clean)
        # R [m^2] new models are built with: fixed, or the latest per-channel noise the data gave (_clean)
        self.R = float(R_std) ** 2 if self.R_fixed else DEFAULT_R_STD ** 2
        self.band = float(band)
        self.max_pending = int(max_pending)
        self.outputs_probes = tuple(Probe(f'{b.name}_{d}', b.node, d) for b in rig.bearings for d in ('x', 'y'))
        self._models: OrderedDict = OrderedDict()      # key -> KalmanModel or the build's exception (LRU)
        self._building: set = set()
        self._lock = threading.Lock()
        self._jobs: queue.Queue = queue.Queue()
        self._pending: deque = deque()
        self._active = None          # (model key, run id, StreamingKF)
        self.dropped_pending = 0
        self.build_times: list = []
        self.nis_hist: deque = deque(maxlen=int(nis_window))
        self.health_hist: deque = deque(maxlen=int(nis_window))
        self.n_meas = None
        self.threshold = None        # stability threshold [rad/s] (computed by the worker)
        self.last_orbit: dict = {}
        self._last_motion = None      # (model key, speed, run, estimates (n, k), angle (n,), Kalman model): last block
        self._coef_sigma = None       # ((model key, run id, bearings.revision), the 1X 1-sigma radius (k,) it gives)
        self.resets = 0               # filter restarts from a steady state (new run, lost data)
        self.switches = 0             # model changes the state carried over (speed band, bearings, noise)
        self._dc: deque = deque(maxlen=NOISE_BLOCKS)
        self._noise: deque = deque(maxlen=NOISE_BLOCKS)
        self._noise_dof: deque = deque(maxlen=NOISE_BLOCKS)
        self.R_rel_std = 0.0          # relative 1-sigma of the estimated R (_clean; 0 when R is fixed)
        self._dc_used = (0, 0.0, 0.0)  # (blocks since the last fit, the DC [m] used, the speed [rad/s] of that fit)
        self._dc_track = None         # (m,) the DC [m] once it follows the innovations (_track_dc), else None
        self._dc_buf: list = []       # (innovations (n, m), angles (n,)) of the steady blocks since the last DC step
        self._submitted = 0.0         # the last queued block's speed [rad/s]: a change beyond the band is a ramp
        self._stripped = 0            # filter operators dropped since the C heap was last trimmed (_evict)
        self.errors: list = []
        self._worker = threading.Thread(target=self._work, name='kf_model_builder', daemon=True)
        self._worker.start()

    # ---- worker
    def _work(self):
        while True:
            job = self._jobs.get()
            if job is None:
                return
            key, speed, probes, fs, ramp = job
            t0 = time.perf_counter()
            try:
                if key == 'threshold':
                    self.threshold = float(stability.threshold_speed(self.rotor, self.bearing_fn, speed))
                    continue
                coeffs = self.bearings(speed)
                rotor = self.kf_rotor(fs)
                q = max(self.Q, RAMP_PROCESS_NOISE) if ramp and not self.Q_fixed else self.Q
                km = rotor_kalman_model(rotor, speed, coeffs, probes, fs, Q=q, R=self.R,
                                        outputs=[(p.node, p.direction) for p in self.outputs_probes])
                if rotor is not self.rotor:
                    self.reduction_error = max(self.reduction_error, receptance_error(rotor, speed, coeffs))
                StreamingKF(km)          # builds and caches the steady-state gain and the chunked operator
                with self._lock:
                    self._models[key] = km
                self.build_times.append(time.perf_counter() - t0)
            except Exception as exc:      # a model that cannot be built is reported, never silently used
                with self._lock:
                    self.errors.append(f'model at {rad_s_to_rpm(speed):.0f} rpm: {exc}')
                    self._models[key] = exc
            finally:
                with self._lock:
                    self._building.discard(key)
                if self.on_ready is not None and key != 'threshold':
                    try:
                        self.on_ready()
                    except Exception:     # the node is shutting down (its wake-up handle is gone): nothing to wake
                        pass
                if self._jobs.empty():    # a burst of builds (a ramp's bands) is over: its temporaries to the OS
                    release_free_heap()

    def kf_rotor(self, fs: float):
        """Return the rotor the models at sample rate ``fs`` [Hz] are built on (the reduced one, once per rate)."""
        if self.cutoff <= 0:
            return self.rotor
        with self._lock:          # built by the builder thread, read by the diagnostics timer
            red = self._kf_rotors.get(fs)
        if red is None:
            kept = kf_kept_dofs(self.rotor, [(p.node, p.direction) for p in self.rig.probes])
            red = craig_bampton(self.rotor, kept, cutoff_hz=self.cutoff * float(fs))
            with self._lock:
                red = self._kf_rotors.setdefault(fs, red)
        return red

    def request(self, speed: float, probes, fs: float, ramp: bool = False):
        """Return the cache key of the model at ``speed`` [rad/s] (:meth:`key`); queue its build if not cached."""
        key = self.key(speed, probes, fs, ramp)
        with self._lock:
            if key in self._models or key in self._building:
                return key
            self._building.add(key)
        self._jobs.put((key, speed, tuple(probes), fs, ramp))
        return key

    def request_threshold(self, speed_max: float):
        self._jobs.put(('threshold', speed_max, (), 0.0, False))

    def key(self, speed, probes, fs, ramp: bool = False):
        """
        Return a model's cache key: ((step width, speed step), probes, sample rate, the bearing results it uses).

        At a steady speed the step is ``MODEL_RESOLUTION`` of a band: a dwell is filtered on a model within 0.1 % of
        its speed (default band), not one built wherever a ramp first reached the band (up to 1 % off; 0.7 % in the
        1X at the packaged rig's 3000 rpm dwell).  On a ``ramp`` the step is the band (one model per band a run-up
        crosses, built with the ramp's process noise; the pieces a block is split into span a band each).
        """
        width = self.band if ramp else self.band * MODEL_RESOLUTION
        return ((width, band_key(speed, width)), tuple((p.node, p.direction) for p in probes), float(fs),
                self.bearings.tag(speed))

    def set_coefficients(self, speed: float, coeffs: dict, stds: dict | None = None) -> None:
        """
        Use identified coefficients {node: (K, C)} at ``speed`` [rad/s] from now on (see :class:`IdentifiedBearings`).

        ``stds``: their 1-sigma in the same form (the bearing motion's uncertainty, :meth:`motion_status`).

        The models are rebuilt for the new bearings as blocks ask for them; the filter goes on from its state on the
        new model.  Blocks already queued keep the model they were queued for.
        """
        if set(coeffs) != set(self.rotor.bearing_nodes):
            raise ValueError(f'coefficients for bearing nodes {sorted(coeffs)}, the model has '
                             f'{sorted(self.rotor.bearing_nodes)}')
        if not self.bearings.add(float(speed), coeffs, stds):
            return
        needed = self._needed()
        live = self.bearings.tags()
        with self._lock:                     # models on replaced results no queued block needs: never asked again
            self._models = OrderedDict((k, v) for k, v in self._models.items()
                                       if k[3] is None or k[3] in live or k in needed)

    def _needed(self) -> set:
        """Return the model keys a queued block or the active filter needs (never dropped from the cache)."""
        return ({pc[3] for p in self._pending for pc in p[4]}
                | ({self._active[0]} if self._active else set()))

    def ready(self, key) -> bool:
        with self._lock:
            return key in self._models

    @property
    def pending(self) -> int:
        return len(self._pending)

    # ---- data path
    def submit(self, block, run, speed: float, contiguous: bool) -> str | None:
        """
        Queue a block; returns a problem text if the queue overflowed (oldest block dropped).

        A block crossing speed bands (a fast ramp) is filtered piece by piece on each band's model
        (:func:`speed_pieces`); the models of all its pieces are requested here.  It, or a ``contiguous`` block whose
        ``speed`` [rad/s] moved by more than a band from the previous block's, is a ramp block: its models are cached
        per band and built with the ramp's process noise (:meth:`key`).
        """
        fs = block.sample_rate
        split = speed_pieces(block.angles(), fs, speed, self.band)
        last, self._submitted = self._submitted, speed
        ramp = bool(contiguous) and (len(split) > 1 or abs(speed - last) > self.band * last)
        pieces = tuple((i0, i1, sp, self.request(sp, block.probes, fs, ramp)) for i0, i1, sp in split)
        self._pending.append((block, run, speed, contiguous, pieces, ramp))
        if len(self._pending) > self.max_pending:
            old = self._pending.popleft()
            self.dropped_pending += 1
            self._active = None
            return (f'model for {rad_s_to_rpm(old[2]):.0f} rpm not ready in time: block seq {old[0].seq} dropped '
                    f'(queue of {self.max_pending} full)')
        return None

    def drain(self) -> list[Output]:
        out = []
        while self._pending:
            block, run, speed, contiguous, pieces, ramp = self._pending[0]
            with self._lock:
                kms = [self._models.get(pc[3]) for pc in pieces]
                for pc, km in zip(pieces, kms):
                    if km is not None:
                        self._models.move_to_end(pc[3])
            if any(km is None for km in kms):
                break
            self._pending.popleft()
            if any(isinstance(km, Exception) for km in kms):
                continue
            act = self._active
            angle = block.angles()
            n = angle.size
            same_stream = act is not None and act[1] == run.id and contiguous
            if not same_stream:
                self._dc.clear()
                self._noise.clear()
                self._noise_dof.clear()
                self._dc_used = (0, 0.0, 0.0)
                self._dc_track = None
                self._dc_buf = []
            ramp = same_stream and ramp
            z, dc = self._clean(block.samples, angle, speed, ramp)
            R = None if self.R_fixed else np.broadcast_to(self.R, (block.samples.shape[1],))
            q = self.Q if self.Q_fixed or not ramp else max(self.Q, RAMP_PROCESS_NOISE)
            parts = []
            tol = self.R_rel_std if ramp else 0.0
            for (i0, i1, sp, key), km in zip(pieces, kms):
                act = self._follow(act, key, km, run, same_stream, R, tol, q, sp, angle[i0])
                same_stream = True
                parts.append(act[2].step_block(z[i0:i1], angle[i0:i1], sp))
            est, nu, nis = (np.concatenate(p) for p in zip(*parts))
            kf = act[2]
            self._track_dc(kf.km, nu, angle, ramp)
            u = self.noise_rel_std(kf.km)
            self.nis_hist.append((float(np.sum(nis)), n, u * u * n))
            terms = innovation_health_terms(nu, angle)
            self.health_hist.append(terms)
            self._fit_process_noise(kf.km, terms)
            self.n_meas = nu.shape[1]
            for j, b in enumerate(self.rig.bearings):
                r = np.sqrt(est[:, 2 * j] ** 2 + est[:, 2 * j + 1] ** 2)
                self.last_orbit[b.name] = (float(np.max(r)), speed)
            self._last_motion = (act[0], speed, run, est, angle, kf.km)
            out.append(Output(block.seq, block.stamp, speed, est, nu, nis, block, run.id, dc, u))
        self._evict()
        return out

    def _follow(self, act, key, km, run, same_stream: bool, R, tol: float, q: float, speed: float, angle: float):
        """
        Return the active (model key, run id, StreamingKF) for the next samples, at ``speed`` [rad/s] on model ``km``.

        The active filter goes on unless the stream broke, the model (``key``) changed, or the noise to use (``R``
        per channel [m^2], None when fixed, ``tol`` its relative 1-sigma: :func:`_noise_moved`; process noise ``q``)
        moved from its model's.  Then the cached model takes
        that noise (its gain re-solved and cached for the next visit) and the known excitation of ``run`` at
        ``speed``; the state carries over from the previous filter at the keyphasor ``angle`` [rad] of the first
        sample, or the filter starts from its steady state (a new run, lost data).
        """
        if (same_stream and act[0] == key and not (R is not None and _noise_moved(R, np.diag(act[2].km.R), tol))
                and not self._q_moved(act[2].km, q)):
            return act
        r_moved = R is not None and _noise_moved(R, np.diag(km.R), tol)
        if r_moved or self._q_moved(km, q):
            # the cached model's noise is not the data's: its gain re-solved, and cached for the next visit
            km = km.with_noise(R=R if r_moved else None, Q=km.Q * (q / self._q_of(km)))
            km.steady_state()
            with self._lock:
                if key in self._models:
                    self._models[key] = km
        forces = harmonic_forces(run.excitation, speed, self.rotor.n_nodes, self.rotor.ndof)
        kf = StreamingKF(km.with_forces(forces, speed), band_tol_rel=self.band)
        if same_stream and act[2].km.n == kf.km.n:
            kf.continue_from(act[2], angle)   # the model follows the speed (or bearings, noise): no restart
            self.switches += 1
        else:
            self.resets += 1
            self.health_hist.clear()   # 1X coherence is only meaningful within one speed band and run
        self._active = (key, run.id, kf)
        self._bb = None
        return self._active

    def _q_of(self, km) -> float:
        """Return the process noise q [m^2 per step] model ``km`` was built with (its Q is q times that of Q = 1)."""
        fs = 1.0 / km.dt
        unit = self._q_unit.get(fs)
        if unit is None or unit[0] != km.n:
            rot = self.kf_rotor(fs)
            unit = (km.n, float(np.trace(rot.reduce_covariance(1.0))) if rot is not self.rotor else float(km.n))
            self._q_unit[fs] = unit
        return float(np.trace(km.Q)) / unit[1]

    def _q_moved(self, km, q: float) -> bool:
        """Whether the process noise to use, ``q`` [m^2 per step], moved by more than ``Q_STEP`` from model ``km``'s."""
        return not self.Q_fixed and abs(math.log(q / self._q_of(km))) > math.log(Q_STEP)

    def _fit_process_noise(self, km, terms: dict) -> None:
        """
        Fit the process noise to the broadband innovations of the active model (unless ``process_noise`` is fixed).

        Over every ``NOISE_BLOCKS`` blocks of one model: the innovations' variance per channel less their 1X and 2X
        (a model that mispredicts the synchronous response is the health check's finding, not process noise), and
        the multiple of the model's Q it implies (:func:`bearing_id.estimation.process_noise.process_noise_scale`).
        The new Q, kept within ``Q_RANGE`` of the paper's, is used once it moves by more than ``Q_STEP``.  On a
        machine the model predicts, the filter so stays consistent (mean NIS ~ number of probes) whatever the ratio
        of the probe noise to the paper's fixed Q.
        """
        if self.Q_fixed:
            return
        bb = self._bb
        if bb is None:
            bb = self._bb = {'n': 0, 'power': 0.0, 1: 0.0, 2: 0.0, 'blocks': 0}
        for k in ('n', 'power', 1, 2):
            bb[k] = bb[k] + terms[k]
        bb['blocks'] += 1
        if bb['blocks'] < NOISE_BLOCKS:
            return
        n = bb['n']
        var = bb['power'] / n - 2 * np.abs(bb[1] / n) ** 2 - 2 * np.abs(bb[2] / n) ** 2
        self._bb = None
        s = process_noise_scale(km, var)
        if not math.isfinite(s):
            return
        q0 = defaults.KF_PROCESS_NOISE
        q = min(max(self._q_of(km) * s, q0 / Q_RANGE), q0 * Q_RANGE)
        if abs(math.log(q / self.Q)) > math.log(Q_STEP):
            self.Q = q
            self.q_fits += 1

    def _evict(self):
        """
        Keep at most MAX_MODELS models, and the filter operators of the MAX_OPERATORS most recently used.

        The least recently used go first, never one a queued block or the active filter needs.  A model without its
        operator (~0.11 MB: matrices and gain) rebuilds it when used again (~0.5 ms, against ~5 ms for the model):
        a run-up's ramp bands (600-3000 rpm: ~160 of 1 %) stay cached for the next run-up, and the cache's memory is
        bounded at ~31 MB (it was 64 models with their operators, ~49 MB); the C heap is trimmed every ``TRIM_EVERY``
        operators dropped.
        """
        with self._lock:
            needed = self._needed()
            unused = [k for k in self._models if k not in needed]
            for k in unused[:max(len(self._models) - MAX_MODELS, 0)]:
                del self._models[k]
            held = [k for k, v in self._models.items() if not isinstance(v, Exception) and v._chunked]
            stripped = [k for k in held[:max(len(held) - MAX_OPERATORS, 0)] if k not in needed]
            for k in stripped:
                self._models[k]._chunked.clear()
        self._stripped += len(stripped)
        if self._stripped >= TRIM_EVERY:     # their memory to the OS now and then (each trim costs page faults later)
            self._stripped = 0
            release_free_heap()

    def _clean(self, samples, angle, speed: float, ramp: bool = False):
        """
        Return (samples with their DC removed, the DC removed (m,) [m]) for the filter; update the noise ``R``.

        A block's DC is the offset of a DC + 1X + 2X least-squares fit
        (:func:`bearing_id.signals.harmonics.harmonic_vectors`), its noise the white part of that fit's residual
        (:func:`bearing_id.signals.noise.difference_noise`: the free vibration a speed ramp leaves ringing is the
        filter's to track, not noise; the residual's RMS counted it, up to ~1000 times the noise's variance on the
        packaged rig); the values used are the medians over the last ``NOISE_BLOCKS`` fitted blocks of the stream (a
        probe gap offset never reaches the filter), the DC's only until ``NOISE_BLOCKS`` fits are in: from then on it
        follows the innovations (:meth:`_track_dc`).  The first ``NOISE_BLOCKS`` blocks of a stream are all fitted,
        and every block whose ``speed`` [rad/s] is more than the band width from the last fitted one's: the noise
        starts afresh there (a new operating point); at a steady speed every ``NOISE_EVERY``-th (DC and noise move
        over seconds; a step in them is followed within ``NOISE_BLOCKS * NOISE_EVERY / 2`` blocks); a ``ramp``
        block's DC is not taken (the 1X moves within it) unless the stream has none yet.  Unless
        ``measurement_noise`` is fixed, ``R`` [m^2] per channel becomes that noise: the filter's gain is re-solved
        when it moves by more than ``NOISE_STEP`` (in std; on a ramp, where it rests on one block, by more than twice
        its relative 1-sigma too: :func:`_noise_moved`), so R follows the real noise of each channel; ``R_rel_std``
        is the estimate's relative 1-sigma.
        """
        since, dc, fitted_at = self._dc_used
        moved = abs(speed - fitted_at) > self.band * abs(fitted_at)
        if moved:                 # a new operating point: its own noise
            self._noise.clear()
            self._noise_dof.clear()
        if len(self._noise) < NOISE_BLOCKS or since + 1 >= NOISE_EVERY or moved:
            try:
                fit = harmonic_vectors(samples, angle, (1, 2), whole_revs=False)
            except ValueError:            # too few samples for the fit: the previous blocks' values
                fit = None
            if fit is not None:
                if self._dc_track is None and (not ramp or not self._dc):   # a ramp's only to start from
                    self._dc.append(np.asarray(fit.offset, float))
                slow = fit.offset + sum(phasor_to_time(X, order * angle).T for X, order in zip(fit.X, fit.orders))
                var, dof = difference_noise(np.asarray(samples, float) - slow)
                self._noise.append(np.sqrt(var))
                self._noise_dof.append(dof)
                if self._dc_track is None:
                    dc = np.median(np.array(self._dc), axis=0)
                    if len(self._dc) >= NOISE_BLOCKS:
                        self._dc_track = dc
                if not self.R_fixed:
                    self.R = np.maximum(np.median(np.array(self._noise), axis=0), NOISE_FLOOR) ** 2
                    k = len(self._noise)   # a variance from dof samples: relative variance 2 / dof; a median of
                    eff = 1.0 if k <= 2 else math.pi / 2        # k of them: times pi / 2 (its normal efficiency) / k
                    self.R_rel_std = math.sqrt(eff * 2.0 / (k * float(np.mean(self._noise_dof))))
            since, fitted_at = 0, speed
        else:
            since += 1
        if self._dc_track is not None:
            dc = self._dc_track
        self._dc_used = (since, dc, fitted_at)
        return np.asarray(samples, float) - dc, dc

    def _track_dc(self, km, nu, angle, ramp: bool) -> None:
        """
        Move the DC removed by the innovations' own offset, once ``NOISE_BLOCKS`` fits of the stream gave a start.

        Every ``NOISE_EVERY`` steady blocks: the offset of a DC + 1X + 2X least-squares fit to the innovations ``nu``
        (n, m) [m] over them (``angle`` (n,) [rad]; no leak from a 1X the model mispredicts) is M (b - dc) for a true
        DC b, M = ``km.bias_gain()`` (the filter takes the rest into its state); the DC moves by that offset through
        M, regularised by ``DC_REG`` (a full step where M ~ I, the offset itself where M ~ 0, whose noise M^-1
        would amplify).  The filter explains the free vibration a speed ramp leaves ringing, so what its innovations
        keep as a mean is the DC's error; a fit to the samples alone takes part of that ringing for DC (0.4-0.7 of the
        noise's sigma for a whole 2 s dwell after a ramp on an unequal-bearing rig).  A ramp block restarts the
        collection.
        """
        if self._dc_track is None or ramp:
            self._dc_buf = []
            return
        self._dc_buf.append((nu, angle))
        if len(self._dc_buf) < NOISE_EVERY:
            return
        nus, angles = zip(*self._dc_buf)
        self._dc_buf = []
        try:
            mean = harmonic_vectors(np.concatenate(nus), np.concatenate(angles), (1, 2), whole_revs=False).offset
        except ValueError:            # too few samples for the fit: the DC stays
            return
        M = km.bias_gain()            # mean = M (b - dc) for a true DC b
        self._dc_track = self._dc_track + np.linalg.solve(M.T @ M + DC_REG ** 2 * np.eye(M.shape[0]), M.T @ mean)

    def noise_rel_std(self, km) -> float:
        """
        Relative 1-sigma of the measurement noise model ``km``'s NIS is normalised by, when R comes from the data.

        Two parts in quadrature: the estimate's own (``R_rel_std``: a median of at most ``NOISE_BLOCKS`` fitted
        blocks) and the largest relative difference between the R ``km`` was solved with and the data's latest (below
        ``NOISE_STEP`` squared: the gain is re-solved beyond).  0 with a fixed ``measurement_noise``: the NIS is then
        judged against the plain chi-square band.
        """
        if self.R_fixed:
            return 0.0
        used = np.diag(km.R)
        moved = float(np.max(np.abs(np.broadcast_to(self.R, used.shape) / used - 1.0)))
        return math.hypot(self.R_rel_std, moved)

    # ---- health
    def nis_status(self) -> DiagItem:
        name = f'{NAME}: filter consistency (NIS)'
        if not self.nis_hist or not self.n_meas:
            return DiagItem(name, OK, 'no filtered data yet', {})
        tot = sum(h[0] for h in self.nis_hist)
        n = sum(h[1] for h in self.nis_hist)
        mean = tot / n
        u = math.sqrt(sum(h[2] for h in self.nis_hist) / n)
        lo, hi = nis_band(n, self.n_meas, rel_std=u)
        widened = f' (95 % band, R estimated to {100 * u:.2g} %)' if u > 0 else ' (95 % chi-square band)'
        vals = {'mean_nis': mean, 'band_lo': lo, 'band_hi': hi, 'expected': self.n_meas, 'samples': n,
                'noise_rel_std': u,
                'filter_restarts': self.resets, 'model_switches_state_kept': self.switches,
                'process_noise_m2': self.Q, 'process_noise': 'fixed' if self.Q_fixed else 'from the innovations'}
        if lo <= mean <= hi:
            return DiagItem(name, OK, f'consistent: mean NIS {mean:.3g} in [{lo:.3g}, {hi:.3g}]{widened}', vals)
        how = 'model or noise settings disagree with the data (model error, R too small)' if mean > hi else \
            'R or Q larger than the data imply'
        return DiagItem(name, WARN, f'inconsistent: mean NIS {mean:.3g} outside [{lo:.3g}, {hi:.3g}]{widened}: {how}',
                        vals)

    def health_status(self) -> DiagItem:
        """Live model health from the innovations (see :func:`innovation_health`)."""
        name = f'{NAME}: model health (innovations)'
        if not self.health_hist:
            return DiagItem(name, OK, 'no filtered data yet', {})
        h = innovation_health(list(self.health_hist))
        vals = {'fraction_1x': h['fraction'][1], 'fraction_2x': h['fraction'][2], 'lag1_correlation': h['lag1'],
                'samples': h['n']}
        worst = max(h['fraction'][1], h['fraction'][2])
        if worst < HEALTH_COHERENT and abs(h['lag1']) < HEALTH_LAG1:
            return DiagItem(name, OK, f"innovations white: {100 * h['fraction'][1]:.1f} % of their power at 1X, "
                            f"{100 * h['fraction'][2]:.1f} % at 2X, lag-1 correlation {h['lag1']:.2f}", vals)
        order = 1 if h['fraction'][1] >= h['fraction'][2] else 2
        return DiagItem(name, WARN, f"model mismatch: {100 * h['fraction'][order]:.0f} % of the innovation power is "
                        f"coherent with {order}X (lag-1 correlation {h['lag1']:.2f}); the model mispredicts the "
                        f'{order}X response -- locate and explain it with `bearing-id diagnose` on a recording', vals)

    def motion_status(self) -> DiagItem:
        """
        Report the estimated bearing-node motion with its uncertainty and the bearing orbits against their clearance.

        Per output channel (``<bearing>_<x|y>``): the last block's 1X amplitude [um] and phase [deg], its 1-sigma
        radius from the 1-sigma of the identified coefficients the model uses (:func:`bearing_id.estimation.
        uncertainty.coefficient_sigma`), and the filter's per-sample posterior 1-sigma from the noise
        (:func:`~bearing_id.estimation.uncertainty.filter_std`); per bearing the largest orbit radius over the block as
        a fraction of the radial clearance.  On theory bearings the coefficients' uncertainty is not known and the
        estimate is the theory's extrapolation (tens of percent off on the packaged rig): WARN.
        """
        name = f'{NAME}: bearing motion'
        if self._last_motion is None:
            return DiagItem(name, OK, 'no filtered data yet', {})
        key, speed, run, est, angle, km = self._last_motion
        vals = {'speed_rpm': rad_s_to_rpm(speed)}
        try:
            X = harmonic_vectors(est, angle, (1,), whole_revs=False).X[0]
        except ValueError:
            X = np.full(est.shape[1], np.nan + 0j)
        stds = self.bearings.uncertainty(speed)
        sig = None
        if stds is not None:
            ck = (key, run.id, self.bearings.revision)
            if self._coef_sigma is None or self._coef_sigma[0] != ck:
                F = harmonic_forces(run.excitation, speed, self.rotor.n_nodes, self.rotor.ndof).get(1.0)
                rows = probe_matrix(self.rotor, self.outputs_probes)
                self._coef_sigma = (ck, np.zeros(len(rows)) if F is None else
                                    coefficient_sigma(self.rotor, speed, self.bearings(speed), stds, F, rows))
            sig = self._coef_sigma[1]
        noise = filter_std(km)
        for k, p in enumerate(self.outputs_probes):
            vals[f'{p.name}_1x_um'] = abs(X[k]) * 1e6
            vals[f'{p.name}_1x_deg'] = math.degrees(float(np.angle(X[k])))
            vals[f'{p.name}_1x_std_coefficients_um'] = 'not known (theory bearings)' if sig is None else sig[k] * 1e6
            vals[f'{p.name}_std_filter_um'] = noise[k] * 1e6
        for b in self.rig.bearings:              # the block's largest orbit radius, as drain() keeps it
            vals[f'{b.name}_orbit_of_clearance'] = self.last_orbit[b.name][0] / b.clearance
        if sig is None:
            return DiagItem(name, WARN, f'theory bearings at {rad_s_to_rpm(speed):.0f} rpm: the bearing-node motion is '
                            "the theory's extrapolation, its uncertainty not known (identified coefficients there "
                            'make it trustworthy)', vals)
        worst = max(sig[k] / max(abs(X[k]), 1e-300) for k in range(len(sig)))
        return DiagItem(name, OK, f'identified bearings at {rad_s_to_rpm(speed):.0f} rpm: 1X at the bearing nodes '
                        f'within {100 * worst:.2g} % (1-sigma from the coefficients)', vals)

    def validity_status(self, speed: float | None) -> DiagItem:
        name = f'{NAME}: model validity'
        vals = {}
        issues = []
        for b in self.rig.bearings:
            if b.name in self.last_orbit:
                r, sp = self.last_orbit[b.name]
                vals[f'{b.name}_orbit_um'] = r * 1e6
                vals[f'{b.name}_orbit_limit_um'] = ORBIT_LIMIT * b.clearance * 1e6
                if r > ORBIT_LIMIT * b.clearance:
                    issues.append(f'{b.name} (node {b.node}) orbit {r * 1e6:.1f} um > {ORBIT_LIMIT:.0%} of clearance '
                                  f'{b.clearance * 1e6:.0f} um at {rad_s_to_rpm(sp):.0f} rpm: linear coefficients '
                                  f'not valid')
        if self.threshold is not None:
            vals['stability_threshold_rpm'] = rad_s_to_rpm(self.threshold)
            if speed is not None and speed >= self.threshold:
                issues.append(f'speed {rad_s_to_rpm(speed):.0f} rpm at or above the stability threshold '
                              f'{rad_s_to_rpm(self.threshold):.0f} rpm (oil whip)')
        if speed is not None:
            vals['speed_rpm'] = rad_s_to_rpm(speed)
            vals['bearing_model'] = self.bearings.source(speed)
        vals['bearing_models'] = self.bearings.describe()
        with self._lock:          # the builder thread adds models while the diagnostics timer reads
            vals['models_cached'] = sum(1 for v in self._models.values() if not isinstance(v, Exception))
            kf_rotors = list(self._kf_rotors.values())
        if kf_rotors:
            vals['model_states'] = ' '.join(str(2 * r.nr) for r in kf_rotors)
            vals['reduction_error_1x'] = self.reduction_error
            if self.reduction_error > REDUCTION_WARN:
                issues.append(f'the reduced model misses {100 * self.reduction_error:.2g} % of the 1X receptance: '
                              f'raise model_cutoff')
        vals['pending_blocks'] = self.pending
        vals['dropped_blocks'] = self.dropped_pending
        if self.build_times:
            vals['last_model_build_s'] = self.build_times[-1]
        if self.errors:
            issues.append(self.errors[-1])
        if issues:
            return DiagItem(name, WARN, '; '.join(issues), vals)
        ok = f'orbits within {ORBIT_LIMIT:.0%} of clearance'
        return DiagItem(name, OK, ok + (', speed below the stability threshold' if self.threshold is not None else ''),
                        vals)

    def close(self):
        self._jobs.put(None)
        self._worker.join(timeout=2.0)
