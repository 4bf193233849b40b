"""
The ``identifier`` node's core (no ROS): 1X harmonic vectors per (run, speed), the record, the solve.

Data path (the offline route, call for call)
    Each block's samples and per-sample keyphasor angles (``sample_angles``) are appended to the stream of its run
    (the run its ``run_id`` names, else the one announced last before its stamp; a block whose run is not announced
    yet waits for it) -- a :class:`bearing_id.identify.harmonics.RunStream`, which is what ``bearing-id identify``
    feeds a whole recording or bag through: the speed of every sample from the angle, steady windows by the same
    rule, the same cut whatever the block boundaries.  A lost or rejected block ends the open window (the rest of
    the dwell becomes a second window, and the two vectors are combined); a change of run or probe set closes the
    stream.  A pause (no block for ``segment_timeout``, and for ``pause_blocks`` blocks' time: the end of a run's
    data, or a loaded machine, a paused replay) does not: the open window is handed out provisionally, fitted and
    used at once, and when the stream goes on, its final cut replaces that vector -- the wall clock never cuts the
    data, so the live vectors are the offline ones whatever the arrival timing.  Each closed window is fitted in a
    worker thread (:func:`bearing_id.identify.harmonics.window_vector`: settling part dropped, whole revolutions,
    transient-aware fit), giving one 1X vector per (run, speed).  As soon as every required run has a vector at a
    new speed, the runs are stacked into a ``HarmonicData`` and :func:`bearing_id.identify.identify` solves with the
    configured method (the data path never waits for a fit or a solve; while windows queue a solve starts no sooner than
    ``SOLVE_BACKLOG`` times the last one's duration after it ended, so a burst of windows is fitted first and shares
    one solve).  Results the data do not determine are not published as numbers (unless ``publish_undetermined``);
    /diagnostics reports their rank and condition instead.

Record and resume
    Every excitation, accumulated vector and result is appended to ``<record_dir>/record.jsonl``
    (:class:`bearing_id.io.record.Record`); on start-up the node replays it, so a restart loses nothing already
    accumulated and re-publishes the results; the runs announced before the restart (with their start stamps) are
    known again at once.  A malformed record line is skipped with a note.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from datetime import datetime, timezone
import math
from pathlib import Path
import threading
import time

import numpy as np

from .machine import label
from .oil import OIL_SPECS
from .specs import ParamSpec
from .status import DiagItem, ERROR, OK, WARN
from ..bearings.viscosity import ZERO_CELSIUS
from ..config import defaults
from ..config.params import ExcitationEntry, Probe, Run
from ..conventions import rad_s_to_rpm, rpm_to_rad_s
from ..history import record_from_result, redacted_url, sqlite_url
from ..history.oil_temperature import (compensated, RATIO, TEMPERATURE, TemperatureLog,
                                       viscosity_factors)
from ..history.trend import Change, ChangeWatch
from ..identify import get_method, harmonics, identify, METHODS
from ..identify.harmonics import (combine_vectors, common_speeds, HarmonicData, PlainFit, RunStream,
                                  WindowVector)
from ..identify.plausibility import stability_threshold
from ..io.record import lock_record, Record
from ..rotor.assembly import RotorModel

NAME = 'identifier'
COMPACT_AFTER = 10_000  # record lines (~4 MB, ~3 h of 1 s dwells) after which it is compacted (IdentifierCore.compact)
PER_SPEED_METHODS = ('paper', 'direct', 'conventional')   # a speed's result depends on that speed's vectors only
CHANGE_SIGMAS = 3.0     # a determined coefficient that moves more than this many sigma since the last result is named

SPECS = [
    ParamSpec('rig_params', '', 'rig YAML with the nominal model (empty: the packaged params/rig.yaml)'),
    ParamSpec('method', defaults.METHOD, 'identification method (bearing-id identify --method); auto: direct where '
              'the data determine every coefficient at every speed, else physical', choices=METHODS),
    ParamSpec('record_dir', '', 'directory of the append-only record (resumed on restart; one identifier per record). '
              'Empty: ~/.ros/bearing_id_record in the root namespace, else ~/.ros/bearing_id_record/<namespace>/<node '
              'name>'),
    ParamSpec('history', 'record', "database of every published identification, for trends: 'record' = the SQLite "
              'file history.db in record_dir; a SQLAlchemy URL (sqlite:////var/lib/bearing_id/fleet.db, '
              "postgresql+psycopg://user@host/db) to share one with a fleet; '' = none.  One writer per machine: a "
              'second identifier of this machine is an ERROR on /diagnostics; the record keeps every result and '
              'writes what the history lacks at the next start'),
    ParamSpec('alarm_arl0', defaults.ALARM_ARL0, "change detection on the history's fitted bearing parameters "
              '(two-sided CUSUM, as bearing-id trend): the average number of solves to a false alarm, per parameter '
              'series; alarms go to bearing_id/alarms and /diagnostics', 'solves', lo=2.0, hi=1e12),
    ParamSpec('alarm_shift', defaults.ALARM_SHIFT, 'the shift the change detection finds fastest', 'sigma', lo=0.05,
              hi=100.0),
    ParamSpec('alarm_reference', defaults.ALARM_REFERENCE, 'the first solves of each parameter series (and after each '
              'alarm) that are its in-control reference', 'solves', lo=1, hi=100000),
    *OIL_SPECS,
    ParamSpec('runs', None, 'excitation runs that must all be present at a speed before solving (unset: every run '
              'announced on /rotor/excitation)', type_='str[]'),
    ParamSpec('channels', None, "expected probe channel names (unset: the rig's probes)", type_='str[]'),
    ParamSpec('speed_tolerance', defaults.SPEED_TOLERANCE, 'relative speed change that ends a steady window; also '
              'matches speeds across runs', '-', lo=1e-5, hi=0.2),
    ParamSpec('settle_fraction', defaults.SETTLE_FRACTION, 'fraction of each steady window discarded at its start '
              '(transient after a speed step)', '-', lo=0.0, hi=0.9),
    ParamSpec('min_window', defaults.MIN_WINDOW, 'shortest usable steady window', 's', lo=0.01, hi=3600.0),
    ParamSpec('segment_timeout', 0.3, 'the open steady window is used provisionally when no block arrived for this '
              "long and for pause_blocks blocks' time (the next contiguous block continues it)", 's',
              lo=0.01, hi=3600.0),
    ParamSpec('pause_blocks', 3.0, "a pause is also at least this many blocks' time without a block (blocks longer "
              'than segment_timeout would otherwise make every gap between two a pause: a provisional fit and a solve '
              'per block); 0 = segment_timeout alone', 'blocks', lo=0.0, hi=1000.0),
    ParamSpec('max_waiting_blocks', 400, "blocks held while their run's excitation has not arrived yet (the oldest "
              'is dropped and counted beyond this)', 'blocks', lo=1, hi=100000),
    ParamSpec('max_segment', defaults.MAX_WINDOW, 'a steady window is fitted in pieces of at most this length, then '
              'combined (bounds memory; the offline route uses the same length)', 's', lo=0.1, hi=86400.0),
    ParamSpec('max_displacement', 1e-3, 'samples above this are implausible (wrong units or garbage)', 'm',
              lo=1e-9, hi=1.0),
    ParamSpec('kf_process_noise', defaults.KF_PROCESS_NOISE, "method paper: the filter's process noise Q "
              '(`bearing-id identify --Q`)', 'm^2', lo=0.0, hi=1.0),
    ParamSpec('kf_measurement_noise', 0.0, "method paper: the filter's probe noise std (R = value^2; `bearing-id "
              "identify --R`); 0: each window's residual around its plain 1X fit, as `bearing-id identify` by default",
              'm', lo=0.0, hi=1e-3),
    ParamSpec('publish_undetermined', False, 'publish results the data do not fully determine (NaN std and '
              'determined=false mark the undetermined coefficients)'),
    ParamSpec('stale_after', 5.0, 'an input silent for this long is reported STALE', 's', lo=0.1, hi=3600.0),
    ParamSpec('diagnostics_period', 1.0, 'period of /diagnostics', 's', lo=0.05, hi=60.0),
]


@dataclass
class _Stream:
    """The open stream of the measured probes' samples: the run and probe set it carries."""

    run: Run
    probes: tuple
    stream: object                 # identify.harmonics.RunStream
    last_arrival: float = 0.0
    peeked: bool = False           # its open windows were handed out provisionally and nothing was fed since
    block_s: float = 0.0           # the last block's duration [s] (samples / sample rate)


def _probe_key(probes) -> tuple:
    return tuple((p.name, int(p.node), p.direction) for p in probes)


class IdentifierCore:
    """
    Windows, vectors per (run, speed), the record, and the solve (no ROS).

    ``feed(block, run, contiguous, now)`` appends a checked block of the measured probes to the run stream
    (:class:`bearing_id.identify.harmonics.RunStream`, the offline route's windowing) and returns the steady windows
    it closed (cheap: the data path); ``flush`` hands out the open windows of a stream that paused, provisionally
    (the stream stays open: when in doubt, a window is not ended by wall-clock time, only by the data -- lost blocks,
    a change of run -- as offline); ``add_window(window)`` fits one window
    (:func:`bearing_id.identify.harmonics.window_vector`) and stores its vector (the worker thread); a later cut of
    the same window (:attr:`ClosedWindow.key`: the final one after a provisional one) replaces its vector;
    ``solve()`` identifies at every speed at which all required runs have a measured vector; with ``warm_start``
    (default) the physical method starts from the parameters of the previous solve (the same answer to the solver's
    tolerance, fewer iterations: :func:`bearing_id.identify.physical.fit_physical` ``p0``).
    Every method, paper included, identifies from the measured probes' vectors as ``bearing-id identify`` does (the
    paper method's filter acts on them through its closed-form 1X transfer); the kf_estimator's estimates are not
    accumulated (an 'estimated' vector in a record of an older version is not resumed).
    Vectors are kept per probe set: a probe set that changes (between runs, or across a restart that resumes the
    record) is never stacked with another; the latest probe set is the one identified.
    """

    def __init__(self, rig, method: str, record_dir, required_runs=None, tol_rel: float = defaults.SPEED_TOLERANCE,
                 settle: float = defaults.SETTLE_FRACTION, min_window: float = defaults.MIN_WINDOW, options=None,
                 max_window: float | None = None,
                 warm_start: bool = True, machine: str = '', history=None, alarms: dict | None = None, oil=None):
        self.rig = rig
        self.machine = label(machine, rig.name)    # the machine the record belongs to
        self.model = RotorModel.from_params(rig)
        self.method = method
        self.options = options
        self.required = list(required_runs) if required_runs else None
        self.tol_rel, self.settle, self.min_window = float(tol_rel), float(settle), float(min_window)
        self.max_window = float(defaults.MAX_WINDOW if max_window is None else max_window)
        self.sample_rate = float(rig.simulation.sample_rate) if rig.simulation is not None else math.nan
        self.runs: dict = {}                   # id -> Run, in announcement order
        self.run_starts: list = []             # (stamp [s], Run) as announced (resumed from the record too)
        # run id -> [(speed, X, X_std, probes, plain)] (plain: the window's plain 1X fit, harmonics.PlainFit)
        self.vectors: dict = {}
        self._last_stored: dict = {}           # run id -> index of the vector its last window went to
        self._parts: dict = {}                 # run id -> per vector: [[key, (speed, X, X_std, plain)]]
        self._window_at: dict = {}             # (run id, window key) -> (vector index, part index)
        self._span: dict = {}                  # (run id, vector index) -> (first, last) stamp [s] of its data
        self._data_spans: dict = {}            # speed [rad/s] -> (first, last) stamp [s] of the data assembled
        self._run_spans: dict = {}             # speed [rad/s] -> [(first, last) stamp [s] or None per run]
        self._noted_combined: set = set()      # window keys whose 'combined' note was given
        self._noted_no_plain = False           # the note on resumed vectors without a plain fit was given
        self._seq_before: dict = {}            # run id -> last block seq in the record (resumed; consumed at 1st block)
        self.missed: list = []                 # (run id, first seq, last seq) not received while the node was down
        self.stream = None                     # _Stream: the open stream of the measured probes
        self.probe_set = None                  # probe key of the latest measured vector (the set identified)
        self.notes: deque = deque(maxlen=20)
        self.results: dict = {}                # speed -> IdentResult (latest)
        self._solved: dict = {}                # speed -> signature of the vectors its latest result came from
        self.warm_start = bool(warm_start)
        self._warm = None                      # (parameter names, values [SI]) of the last physical fit
        self._ran = None                       # the method the last solve ran (auto chooses per solve)
        self.lock = threading.Lock()
        self.history = history                 # a HistoryStore (or None): every result recorded is written there too
        self.history_rows = 0                  # identifications this process added to the history
        self.history_error = ''                # the last failed write (kept until a write succeeds)
        # change detection on the history (history/trend.ChangeWatch); alarms not yet published wait in new_alarms
        a = {'arl0': defaults.ALARM_ARL0, 'delta': defaults.ALARM_SHIFT, 'n_reference': defaults.ALARM_REFERENCE,
             **(alarms or {})}
        self.watch = None if history is None else ChangeWatch(history, self.machine, **a)
        self.new_alarms: deque = deque()
        self.alarm_error = ''
        self.temperature = TemperatureLog()      # oil inlet readings (stamp [s], T [K])
        self.oil = oil                           # the oil's viscosity law (bearings.viscosity.Oil) or None
        get_method(method)
        self._lock_file = lock_record(record_dir)      # one writer per record (RecordInUse otherwise)
        try:
            self.record = Record(record_dir)
            entries = self.record.entries()          # read once for both
            self._check_machine(entries)
            self.resumed = self._resume(entries)
            self.resumed['history_backfilled'] = self._backfill_history(entries)
            self.check_changes()           # the alarms already in the history: reported again after a restart
        except BaseException:
            self._lock_file.close()
            raise

    def _check_machine(self, entries: list) -> None:
        """Refuse another machine's record (ValueError); name this machine in a record that names none."""
        named = [e for e in entries if e['type'] == 'machine']
        if named and str(named[-1].get('machine')) != self.machine:
            raise ValueError(f"the record {self.record.path} belongs to machine '{named[-1].get('machine')}', this "
                             f"identifier serves '{self.machine}': give it its own record_dir (or machine_id)")
        if not named:
            self.record.append('machine', machine=self.machine, rig=self.rig.name)

    # ---- record
    def _resume(self, entries: list) -> dict:
        n_vec = n_res = n_bad = 0
        for e in entries:
            try:
                if e['type'] == 'excitation':
                    run = Run(str(e['run_id']), tuple(ExcitationEntry(**x) for x in e['entries']))
                    if run.id not in self.runs:
                        self.runs[run.id] = run
                        self.run_starts.append((float(e.get('stamp', -math.inf)), run))
                elif e.get('source', 'measured') != 'measured':
                    continue                                # an 'estimated' vector (older records): never used
                elif e['type'] == 'vector' and e.get('used', True):
                    probes = tuple(Probe(str(n), int(k), str(d)) for n, k, d in e['probes'])
                    X = np.asarray(e['X']).astype(complex).reshape(-1)
                    Xs = np.asarray(e['X_std'], dtype=float).reshape(-1)
                    plain = None
                    if e.get('plain_X') is not None:        # (absent from records of older versions)
                        var = np.asarray(e['plain_var'], dtype=float).reshape(3, -1)
                        plain = PlainFit(np.asarray(e['plain_X']).astype(complex).reshape(-1), *var)
                    if X.size != len(probes) or Xs.size != len(probes) or not float(e['speed']) > 0 or \
                            (plain is not None and plain.X.size != len(probes)):
                        raise ValueError(f'{X.size} values for {len(probes)} probes')
                    t0 = e.get('stamp')
                    span = None if t0 is None else (float(t0), float(t0) + float(e.get('duration') or 0.0))
                    self._store(str(e['run_id']), float(e['speed']), X, Xs, probes, bool(e.get('after_gap', False)),
                                e.get('window'), plain, span)
                    if e.get('sample_rate') is not None:
                        self.sample_rate = float(e['sample_rate'])
                    n_vec += 1
                    if e.get('seqs'):
                        rid = str(e['run_id'])
                        self._seq_before[rid] = max(self._seq_before.get(rid, -1), int(e['seqs'][1]))
                elif e['type'] == 'withdrawn':
                    self._withdraw(str(e['run_id']), str(e['window']))
                elif e['type'] == 'result':
                    n_res += 1
            except (KeyError, ValueError, TypeError, AttributeError) as exc:
                n_bad += 1
                self.notes.append(f"record {self.record.path}: entry n={e.get('n')} ({e.get('type')}) is malformed "
                                  f'({type(exc).__name__}: {exc}); skipped')
        if self.record.torn_lines:
            self.notes.append(f'record {self.record.path}: {self.record.torn_lines} torn line(s) skipped')
        out = {'vectors': n_vec, 'results': n_res, 'torn_lines': self.record.torn_lines, 'malformed': n_bad}
        self.record.append('session', resumed_vectors=n_vec, resumed_results=n_res, method=self.method)
        if self.record.lines > COMPACT_AFTER:
            self.compact()
        return out

    def compact(self) -> int:
        """
        Rewrite the record with what the identifier's state rests on; returns the number of lines dropped.

        Kept: the machine and every excitation; of the vectors, the last cut of each window whose part is stored now
        (the latest dwell at each run, speed and probe set, with the parts of a dwell split by lost data; vectors of
        records without window keys are all kept); the latest result at each speed.  Dropped: superseded dwells,
        provisional cuts, withdrawn windows, sessions, older results.  Resuming the compacted record gives the same
        vectors.  Runs when the record exceeds ``COMPACT_AFTER`` lines (at start-up and after a solve), so it stays
        bounded over months of dwells.
        """
        with self.lock:
            live = set(self._window_at)
        entries = self.record.entries()
        keep, vec, res = [], {}, {}
        for e in entries:
            t = e.get('type')
            if t in ('machine', 'excitation'):
                keep.append(e)
            elif t == 'vector' and e.get('window') is None:
                keep.append(e)
            elif t == 'vector' and (str(e.get('run_id')), e.get('window')) in live:
                vec[(str(e['run_id']), e['window'])] = e
            elif t == 'result' and isinstance(e.get('result'), dict):
                res[round(float(e['result'].get('speed_rad_s', math.nan)), 6)] = e
        kept = sorted(keep + list(vec.values()) + list(res.values()), key=lambda e: e['n'])
        self.record.rewrite(kept)
        dropped = len(entries) - len(kept)
        self.record.append('compacted', kept=len(kept), dropped=dropped)
        return dropped

    def add_excitation(self, run: Run, stamp: float = -math.inf) -> bool:
        with self.lock:
            if run.id in self.runs:
                if self.runs[run.id] != run:
                    self.notes.append(f'run {run.id} re-announced with a different excitation; the first is kept')
                return False
            self.runs[run.id] = run
            self.run_starts.append((float(stamp), run))
        self.record.append('excitation', run_id=run.id, stamp=float(stamp),
                           entries=[{'kind': e.kind, 'node': e.node, 'magnitude': e.magnitude, 'phase': e.phase,
                                     'direction': e.direction, 'frequency_ratio': e.frequency_ratio}
                                    for e in run.excitation])
        return True

    def _store(self, run_id, speed, X, X_std, probes, after_gap=False, key=None, plain=None, span=None) -> str:
        """
        Store a window's vector; returns 'new', 'combined', 'replaced' or 'updated'.

        'combined': the rest of a dwell split by lost data, inverse-variance merged with the vector of the window before
        the gap (also when a later cut of that rest replaces it).  'replaced': a later cut of a window already stored
        (``key``, :attr:`ClosedWindow.key`; the final cut after a provisional one): its part is replaced and the vector
        recombined.  'updated': a new dwell at a speed the run already has with this probe set supersedes the stored
        one -- the machine as it is now (the tracking rule; :func:`~bearing_id.identify.harmonics.common_speeds`
        takes the latest dwell offline too).  ``span``: (first, last) stamp [s] of the window's data.
        """
        pkey = _probe_key(probes)
        lst = self.vectors.setdefault(run_id, [])
        parts = self._parts.setdefault(run_id, [])
        at = self._window_at.get((run_id, key)) if key is not None else None
        if at is not None:
            parts[at[0]][at[1]][1] = (speed, X, X_std, plain)
            lst[at[0]] = self._combined(parts[at[0]], probes)
            self._widen_span(run_id, at[0], span)
            return 'combined' if at[1] > 0 else 'replaced'
        last = self._last_stored.get(run_id)
        if after_gap and last is not None and lst[last] is not None and _probe_key(lst[last][3]) == pkey and \
                abs(lst[last][0] - speed) <= self.tol_rel * speed:
            parts[last].append([key, (speed, X, X_std, plain)])
            self._window_at[(run_id, key)] = (last, len(parts[last]) - 1)
            lst[last] = self._combined(parts[last], probes)
            self._widen_span(run_id, last, span)
            return 'combined'
        same = [i for i, v in enumerate(lst)
                if v is not None and abs(v[0] - speed) <= self.tol_rel * speed and _probe_key(v[3]) == pkey]
        if same:
            i = same[-1]
            for k in [k for k, a in self._window_at.items() if k[0] == run_id and a[0] == i]:
                del self._window_at[k]                  # the superseded dwell's windows
            lst[i] = (speed, X, X_std, probes, plain)
            parts[i] = [[key, (speed, X, X_std, plain)]]
            self._window_at[(run_id, key)] = (i, 0)
            self._last_stored[run_id] = i
            self._span[(run_id, i)] = span
            return 'updated'
        lst.append((speed, X, X_std, probes, plain))
        parts.append([[key, (speed, X, X_std, plain)]])
        self._window_at[(run_id, key)] = (len(lst) - 1, 0)
        self._last_stored[run_id] = len(lst) - 1
        self._span[(run_id, len(lst) - 1)] = span
        if self.probe_set is not None and self.probe_set != pkey:
            self.notes.append(f'probe set changed from {[k[0] for k in self.probe_set]} to {[k[0] for k in pkey]}: '
                              f'vectors of different probe sets are kept apart; the new set is identified')
        self.probe_set = pkey
        return 'new'

    def _widen_span(self, run_id, i, span) -> None:
        old = self._span.get((run_id, i))
        if span is not None:
            self._span[(run_id, i)] = span if old is None else (min(old[0], span[0]), max(old[1], span[1]))

    @staticmethod
    def _combined(parts, probes):
        """Return the vector (speed, X, X_std, probes, plain) of a dwell's parts, combined in window order."""
        v = None
        for _, part in parts:
            if part is None:
                continue
            w = WindowVector(part[0], part[1], part[2], 0, 0, None, part[3])
            v = w if v is None else combine_vectors(v, w)        # as offline (recording_vectors)
        return None if v is None else (v.speed, v.X, v.X_std, probes, v.plain)

    def _withdraw(self, run_id, key) -> bool:
        """Drop the stored part of window ``key`` (its final cut gives no vector); returns whether one was stored."""
        at = self._window_at.pop((run_id, key), None)
        self._noted_combined.discard(key)
        if at is None:
            return False
        lst, parts = self.vectors[run_id], self._parts[run_id][at[0]]
        parts[at[1]][1] = None
        lst[at[0]] = None if lst[at[0]] is None else self._combined(parts, lst[at[0]][3])
        return True

    # ---- data path (callback thread)
    def feed(self, block, run: Run, contiguous: bool, now: float) -> list:
        """
        Append a checked block of ``run`` (the measured probes) to the stream; returns the steady windows it closed.

        The block has ``samples`` (n, nch) [m], ``angles()`` (n,) [rad], ``probes``, ``sample_rate``, ``stamp``,
        ``seq``.
        """
        out = []
        last = self._seq_before.pop(run.id, None)
        if last is not None and block.seq is not None and int(block.seq) > last + 1:
            self.missed.append((run.id, last + 1, int(block.seq) - 1))   # streamed while this node was down
        cur = self.stream
        probes = tuple(block.probes)
        if cur is not None and (cur.run.id != run.id or _probe_key(cur.probes) != _probe_key(probes)
                                or cur.stream.fs != float(block.sample_rate)):
            closed = cur.stream.close()        # the stream moved on to another run / probe set / rate
            if not cur.peeked:                 # (else these are the windows flush() handed out: no new data since)
                out += closed
            cur = None
        if cur is None:
            cur = self.stream = _Stream(run, probes, RunStream(run, probes, float(block.sample_rate),
                                                               tol_rel=self.tol_rel, max_duration=self.max_window))
            contiguous = True
        out += cur.stream.feed(block.samples, block.angles(), contiguous=contiguous, stamp=block.stamp,
                               seq=block.seq)
        cur.last_arrival, cur.peeked = now, False
        cur.block_s = len(block.samples) / float(block.sample_rate)
        return out

    def flush(self, now: float, timeout: float, pause_blocks: float = 0.0) -> list:
        """
        Return the stream's open windows, provisionally, when no block arrived for a while (:meth:`pause_after`).

        A while: ``timeout`` [s], and ``pause_blocks`` times the last block's duration (a 1x stream sends a block
        per block time: with blocks longer than ``timeout`` every gap between two would otherwise be a pause, a
        provisional fit and a solve per block).

        The end of a run's data, or only a pause in their arrival (a loaded machine, a paused replay): either way the
        windows are cut as if the stream ended now (:meth:`RunStream.peek`) so that their vectors are used at once,
        but the stream stays open -- a contiguous next block continues the window, whose final cut then replaces the
        provisional vector.  Wall-clock time never cuts the data: the vectors are those of the offline route whatever
        the arrival timing.  Once per pause.
        """
        cur = self.stream
        if cur is None or cur.peeked or now - cur.last_arrival < self.pause_after(timeout, pause_blocks):
            return []
        cur.peeked = True
        return cur.stream.peek()

    def pause_after(self, timeout: float, pause_blocks: float = 0.0) -> float:
        """Return how long [s] without a block is a pause (:meth:`flush`) for the blocks the stream has now."""
        cur = self.stream
        return max(timeout, pause_blocks * (cur.block_s if cur is not None else 0.0))

    def wants(self, win, min_duration: float) -> bool:
        """Whether a window is worth fitting: ``min_duration`` [s] long, or a later cut of one stored already."""
        if win.duration >= min_duration:
            return True
        with self.lock:
            return (win.run.id, win.key) in self._window_at

    # ---- accumulation (worker thread)
    def add_window(self, win) -> list[tuple]:
        """Fit one closed window (the offline rule) and store its vector; returns [(speed, X)] newly usable."""
        what = (f'window of run {win.run.id} at {rad_s_to_rpm(float(np.median(win.speed))):.0f} rpm, '
                f'blocks {win.seqs[0]}..{win.seqs[1]}' if win.seqs else f'window of run {win.run.id}')
        try:
            v = harmonics.window_vector(win, settle=self.settle, min_duration=self.min_window)
        except ValueError:
            if not win.provisional:
                raise
            v = None                # the data so far do not make a vector yet (e.g. under one revolution)
        if v is None:
            with self.lock:
                withdrawn = self._withdraw(win.run.id, win.key)
            if withdrawn:           # its provisional cut was stored; the final one is too short
                self.record.append('withdrawn', source='measured', run_id=win.run.id, window=win.key)
            elif win.duration >= 0.5 * self.min_window and not win.provisional:
                self.notes.append(f'{what} ({win.duration:.2f} s): too short for a 1X vector; not used')
            return []
        span = None if win.stamp is None else (float(win.stamp), float(win.stamp) + float(win.duration))
        with self.lock:
            how = self._store(win.run.id, v.speed, v.X, v.X_std, win.probes, win.after_gap or win.continued, win.key,
                              v.plain, span)
            self.sample_rate = win.sample_rate
        self.record.append('vector', source='measured', run_id=win.run.id, speed=v.speed, X=v.X, X_std=v.X_std,
                           plain_X=None if v.plain is None else v.plain.X, sample_rate=win.sample_rate,
                           plain_var=None if v.plain is None else np.array(v.plain.arrays()[1:]),
                           probes=[[p.name, p.node, p.direction] for p in win.probes], stamp=win.stamp,
                           seqs=list(win.seqs) if win.seqs else None, after_gap=win.after_gap or win.continued,
                           used=True, window=win.key, provisional=win.provisional, duration=float(win.duration))
        if how == 'combined' and win.key not in self._noted_combined:     # once per window, provisional or final
            self._noted_combined.add(win.key)
            self.notes.append(f'{what}: the rest of a dwell split by lost data, combined with its first part')
        return [(v.speed, v.X)]

    def incomplete(self) -> list[tuple]:
        """
        Return [(speed [rad/s], runs lacking it)] for the speeds some required runs have and others lack.

        Such a speed is not identified (every required run is needed there): after a restart it names what the node
        missed while down, until the machine dwells there again.
        """
        with self.lock:
            req = self.required_runs()
            have = {rid: [v[0] for v in self.vectors.get(rid, []) if v is not None and
                          (self.probe_set is None or _probe_key(v[3]) == self.probe_set)] for rid in req}
        out = []
        for w in sorted(w for ws in have.values() for w in ws):
            if any(abs(w - u) <= self.tol_rel * w for u, _ in out):
                continue
            lack = [rid for rid, ws in have.items() if not any(abs(w - u) <= self.tol_rel * w for u in ws)]
            if lack:
                out.append((w, lack))
        return out

    def gaps_item(self) -> DiagItem:
        """
        Return the /diagnostics item of data missed while the node was down and of the speeds that lack a run.

        WARN naming the missed sequence ranges (and the speeds lacking a run) until no speed lacks a run any more (the
        machine dwelt there again); otherwise OK (the runs of a plan arrive one after the other).
        """
        name = f'{NAME}: completeness'
        inc = self.incomplete()
        if not inc:
            self.missed.clear()
        parts = [f"{rad_s_to_rpm(w):.0f} rpm lacks run(s) {', '.join(lack)}" for w, lack in inc]
        missed = [f'run {rid} blocks seq {a}..{b}' for rid, a, b in self.missed]
        vals = {'speeds_lacking_a_run': len(inc), 'missed_while_down': '; '.join(missed) or 'none'}
        if not inc and not missed:
            return DiagItem(name, OK, 'every speed has every required run', vals)
        text = '; '.join(parts[:4]) + (' ...' if len(parts) > 4 else '')
        if not missed:          # the runs of a plan arrive one after the other: waiting is normal
            return DiagItem(name, OK, f'waiting: {text}', vals)
        text = f"not received while this node was down: {'; '.join(missed[:3])}" + (' -- ' + text if text else '')
        return DiagItem(name, WARN, text + ' (not identified until the machine dwells there again)', vals)

    def vector_counts(self) -> dict:
        """Return {run id: number of usable vectors}."""
        with self.lock:
            return {rid: sum(x is not None for x in v) for rid, v in self.vectors.items()}

    def required_runs(self) -> list[str]:
        return list(self.required) if self.required else list(self.runs)

    def assemble(self):
        """
        Return the HarmonicData of the measured vectors (latest probe set) at every speed all required runs have.

        In the first required run's order: :func:`bearing_id.identify.harmonics.common_speeds`, as offline.
        """
        with self.lock:
            req = self.required_runs()
            if not req or any(r not in self.runs for r in req) or self.probe_set is None:
                return None

            def of_set(rid):
                out = [(i, v) for i, v in enumerate(self.vectors.get(rid, []))
                       if v is not None and _probe_key(v[3]) == self.probe_set]
                if self.method == 'paper' and any(v[4] is None for _, v in out):
                    if not self._noted_no_plain:
                        self._noted_no_plain = True
                        self.notes.append('method paper: vectors resumed from a record of an older version lack '
                                          "the plain 1X fit the paper method's filter takes; they are not used "
                                          '(start with an empty record_dir to identify those speeds again)')
                    out = [(i, v) for i, v in out if v[4] is not None]
                return out

            indexed = [of_set(rid) for rid in req]
            meas = [[v for _, v in m] for m in indexed]
            speeds, picks = common_speeds(meas, self.tol_rel)
            if not speeds:
                return None
            rows = [[meas[r][k] for r, k in enumerate(row)] for row in picks]
            spans = [[self._span.get((req[r], indexed[r][k][0])) for r, k in enumerate(row)] for row in picks]
            self._data_spans = {float(w): (min(t[0] for t in sp), max(t[1] for t in sp))
                                for w, sp in zip(speeds, spans) if all(t is not None for t in sp)}
            self._run_spans = {float(w): sp for w, sp in zip(speeds, spans)}     # per required run
            probes = rows[0][0][3]
            ns, nr = len(speeds), len(req)
            X = np.array([[rows[s][r][1] for s in range(ns)] for r in range(nr)], dtype=complex)
            Xs = np.array([[rows[s][r][2] for s in range(ns)] for r in range(nr)], dtype=float)
            plain = None
            if all(rows[s][r][4] is not None for s in range(ns) for r in range(nr)):
                plain = PlainFit.stack([[rows[s][r][4] for s in range(ns)] for r in range(nr)])
            runs = tuple(self.runs[r] for r in req)
            fs = self.sample_rate if math.isfinite(self.sample_rate) else None
            data = HarmonicData(np.array(speeds), probes, runs, X, Xs, plain=plain, sample_rate=fs)
        return data

    def signature(self, data) -> tuple:
        """Return what a solve depends on (run ids, speeds, vectors): equal signatures give equal results."""
        return None if data is None else (tuple(r.id for r in data.runs), data.speeds.tobytes(), data.X.tobytes(),
                                          data.X_std.tobytes())

    @staticmethod
    def _speed_signature(data, i: int) -> tuple:
        """Return what a per-speed method's result at speed index ``i`` depends on: runs and that speed's vectors."""
        return (tuple(r.id for r in data.runs), data.X[:, i].tobytes(), data.X_std[:, i].tobytes())

    def _changed_speeds(self, data) -> list[int]:
        """
        Return the speed indices to solve: every one for a global fit, for a per-speed method only those new or changed.

        A per-speed method (:data:`PER_SPEED_METHODS`) gives a speed's result from that speed's vectors alone, so a
        speed whose vectors did not change keeps its result: the cost of a solve does not grow with the history.
        """
        idx = range(len(data.speeds))
        if self.method not in PER_SPEED_METHODS:
            return list(idx)
        return [i for i in idx if self._solved.get(float(data.speeds[i])) != self._speed_signature(data, i)]

    def solve(self, data=None, record: bool = True):
        """
        Identify at every complete speed that needs it; returns (results, data) or ([], None).

        A global fit (``physical``, ``auto``) solves every speed, warm-started from its last fit; a per-speed method
        only the speeds whose vectors are new or changed (the others keep their last result, not returned again).

        ``data``: an :meth:`assemble` result, default a new one.  ``record``: append the results to the record now
        (False: the caller does it with :meth:`record_results`, e.g. after publishing them).
        """
        data = self.assemble() if data is None else data
        if data is None:
            return [], None
        opts = dict(self.options or {})
        kf = opts.pop('kf', None) or {}
        if self.method == 'paper':   # the offline route's filter settings (`bearing-id identify --Q --R`)
            opts.update({k: kf[k] for k in ('Q', 'R') if kf.get(k) is not None})
        if self.method in ('physical', 'auto') and self.warm_start and self._warm is not None and 'p0' not in opts:
            opts['p0'] = self._warm[1]
        factors = None
        if self.method in ('physical', 'auto'):   # each speed's viscosity from its data's oil inlet temperature
            nr = len(data.runs)
            spans = [self._run_spans.get(float(w)) or [None] * nr for w in data.speeds]   # (ns, nr)
            factors = viscosity_factors(self.temperature, [[sp[r] if r < len(sp) else None for sp in spans]
                                                           for r in range(nr)], self.oil)
            if factors is not None:
                opts['viscosity_factors'] = factors
        if self.method == 'auto':          # its options are per method; the warm start is the physical fit's
            opts = {'physical': opts} if opts else {}
        todo = self._changed_speeds(data)
        if not todo:
            return [], data
        results = identify(self.method, self.model, self.rig, data if len(todo) == len(data.speeds) else
                           data.select(todo), options=opts or None)
        if self.method in PER_SPEED_METHODS:
            self._solved.update({float(data.speeds[i]): self._speed_signature(data, i) for i in todo})
        fit = results[0].extra.get('fit') if results else None
        if results and results[0].method == 'physical' and fit is not None and np.all(np.isfinite(fit.values)):
            self._warm = (fit.names, np.array(fit.values))
        ran = results[0].method if results else None
        if self.method == 'auto' and ran is not None and ran != self._ran and self._ran is not None:
            self.notes.append(f'method auto now runs {ran} (it ran {self._ran}): '
                              f"{results[0].extra['auto']['reason']}")
        self._ran = ran or self._ran
        for r in results:
            span = self._data_spans.get(float(r.speed))
            if span is not None:
                r.extra['data_span'] = span
                r.notes.append(f'data of {_utc(span[0])} to {_utc(span[1])}')
            moved = _moved(self.results.get(float(r.speed)), r)
            if moved:
                r.notes.append(moved)
            self.results[float(r.speed)] = r
        self._with_oil_temperature(results, per_speed=factors is not None)
        if record:
            self.record_results(results)
        return results, data

    def add_temperature(self, stamp: float, T: float) -> str:
        """Take an oil inlet temperature reading ``T`` [K] at ``stamp`` [s]; return why it was refused, or ''."""
        return self.temperature.add(float(stamp), float(T))

    def _with_oil_temperature(self, results, per_speed: bool = False) -> None:
        """
        Add the oil inlet temperature over a global fit's data, and each viscosity against the oil law, to its results.

        Only a fit with physical parameters (one value for all speeds) and readings within its data span: the mean
        and spread of the readings from the first to the last sample behind any of its speeds, and with an oil law
        (parameters ``oil_*``) each bearing's fitted viscosity over the law's at that mean
        (:func:`bearing_id.history.oil_temperature.compensated`), as parameters beside the fitted ones.
        ``per_speed``: the fit took each speed's temperature (its viscosity is the one at that mean), so the spread
        adds nothing to the ratio's 1-sigma.
        """
        spans = [r.extra['data_span'] for r in results if r.extra.get('data_span') and r.extra.get('parameters')]
        if not spans or not len(self.temperature):
            return
        T, T_std, n = self.temperature.over(min(s[0] for s in spans), max(s[1] for s in spans))
        if not n:
            return
        derived = compensated(results[0].extra['parameters'], T, 0.0 if per_speed else T_std, self.oil)
        derived[TEMPERATURE]['std'] = T_std             # the spread of the readings, as before
        ratios = ', '.join(f"{k.split('.')[0]} {v['value']:.4g} +- {v['std']:.2g}" for k, v in derived.items()
                           if k.endswith(RATIO))
        note = (f'oil inlet {T:.2f} K ({T - ZERO_CELSIUS:.1f} degC) +- {T_std:.2g} K over the data ({n} readings)'
                + (f"; fitted viscosity / the oil law's: {ratios}" if ratios else ''))
        for r in results:
            if r.extra.get('parameters'):
                r.extra['parameters'] = {**r.extra['parameters'], **derived}
                r.notes.append(note)

    def prepare(self) -> None:
        """
        Compute once, off the data path, what the solves at the planned speeds share.

        The plausibility gate's stability threshold for the rig's planned speed range (``simulation.speeds_rpm``):
        without it the first solve at each new top speed searches for it (~0.4 s).
        """
        sim = self.rig.simulation
        if sim is not None and sim.speeds_rpm:          # every method's results pass the same gate
            stability_threshold(self.model, self.rig, float(rpm_to_rad_s(max(sim.speeds_rpm))))

    def record_results(self, results) -> None:
        """
        Append results to the record, write them to the history and look for changes.

        A line each in the record, fsync'ed together; one transaction in the history.
        """
        stamp = time.time()
        payloads = [{'stamp': stamp, **_result_payload(r)} for r in results]
        self.record.append_many('result', payloads)
        added = self._to_history([(p['result'], stamp) for p in payloads])
        if added:
            self.check_changes()
        if self.record.lines > COMPACT_AFTER:
            self.compact()

    def check_changes(self) -> None:
        """
        Run the change detection on this machine's history; queue the alarms not reported yet in ``new_alarms``.

        A failure (the database unreachable) is kept for /diagnostics (:meth:`alarm_item`), never raised.
        """
        if self.watch is None:
            return
        try:
            new = self.watch.update()
        except Exception as exc:      # the results are recorded; the next write retries the detection
            self.alarm_error = f'{type(exc).__name__}: {exc}'
            return
        self.alarm_error = ''
        self.new_alarms.extend(new)

    def alarm_item(self) -> DiagItem:
        """Return the /diagnostics item of the change detection: the alarms found, or the series watched."""
        name = f'{NAME}: bearing change alarms'
        w = self.watch
        if w is None:
            return DiagItem(name, OK, 'no history database: no change detection (parameter history)', {})
        vals = {'series_watched': w.series, 'independent_points': w.points, 'alarms': len(w.found),
                'arl0_solves': w.arl0, 'shift_sigma': w.delta, 'reference_solves': w.n_reference}
        if self.alarm_error:
            return DiagItem(name, ERROR, f'change detection failed: {self.alarm_error}', vals)
        if not w.found:
            return DiagItem(name, OK, f'no change in {w.series} parameter series over {w.points} independent '
                            f'solve(s) (average {w.arl0:g} to a false alarm per series)', vals)
        latest: dict = {}
        for c in w.found:              # the latest alarm of each series
            latest[(c.bearing, c.name)] = c
        for i, c in enumerate(latest.values()):
            vals[f'alarm_{i + 1}'] = c.sentence()
        last = max(w.found, key=lambda c: c.alarm.time)
        return DiagItem(name, WARN, f'{len(w.found)} change(s) in {len(latest)} series; latest: {last.sentence()}',
                        vals)

    def _to_history(self, results: list[tuple]) -> int:
        """
        Write recorded results [(result dict, stamp [s])] to the history in one transaction; return the new rows.

        A failure is kept for /diagnostics, never raised (the record keeps them; the next start writes them); a result
        that does not make a history row is left out alone.
        """
        if self.history is None or not results:
            return 0
        recs, error = [], ''
        for result, stamp in results:
            try:
                recs.append(record_from_result(result, self.machine, rig_name=self.rig.name, stamp=stamp,
                                               provenance={'record': str(self.record.path)}))
            except Exception as exc:      # a bad value: this result only
                error = f'{type(exc).__name__}: {exc}'
        try:
            inserted = sum(w.inserted for w in self.history.write_many(recs)) if recs else 0
        except Exception as exc:      # a database down, a second writer: the record still has them
            self.history_error = f'{type(exc).__name__}: {exc}'
            return 0
        self.history_error = error
        self.history_rows += inserted
        return inserted

    def _backfill_history(self, entries: list) -> int:
        """Write the record's results the history lacks (a write that failed, a kill before it); return how many."""
        return self._to_history([(e['result'], float(e.get('stamp', e.get('wall_time', 0.0)))) for e in entries
                                 if e.get('type') == 'result' and isinstance(e.get('result'), dict)])

    def history_item(self) -> DiagItem:
        """Return the /diagnostics item of the history database: rows written, or the failed write (ERROR)."""
        name = f'{NAME}: history'
        if self.history is None:
            return DiagItem(name, OK, 'no history database (parameter history)', {})
        vals = {'database': redacted_url(self.history.url), 'identifications_written': self.history_rows,
                'backfilled_at_start': self.resumed.get('history_backfilled', 0)}
        if self.history_error:
            return DiagItem(name, ERROR, f'not written to the history: {self.history_error} (the record keeps '
                                         f'every result; they are written at the next start)', vals)
        return DiagItem(name, OK, f'{self.history_rows} identification(s) written', vals)

    def close(self):
        self.record.close()
        self._lock_file.close()


def alarm_items(changes: list[Change]) -> list[DiagItem]:
    """
    Return one WARN item per change, for the alarm topic.

    Values: bearing, parameter, direction, size with its 1-sigma (SI; the mean since the onset, and the change at the
    alarm), reference, onset and alarm time (UNIX s and
    UTC; the UNIX stamps as text to the millisecond, not to /diagnostics' 6 digits), and the evidence (CUSUM statistic,
    threshold, points).
    """
    out = []
    for c in changes:
        a = c.alarm
        out.append(DiagItem(f'{NAME}: alarm: {c.bearing} {c.name}', WARN, c.sentence(), {
            'bearing': c.bearing, 'parameter': c.name, 'direction': 'up' if a.direction > 0 else 'down',
            'size': a.size, 'size_sigma': a.size_sigma, 'change_at_alarm': a.latest,
            'change_at_alarm_sigma': a.latest_sigma, 'reference': a.reference,
            'reference_sigma': a.reference_sigma, 'onset_stamp': f'{a.onset_time:.3f}', 'onset_utc': _utc(a.onset_time),
            'alarm_stamp': f'{a.time:.3f}', 'alarm_utc': _utc(a.time), 'cusum_statistic_sigma': a.statistic,
            'threshold_sigma': a.h, 'points_since_onset': a.n}))
    return out


def history_url(param: str, record) -> str:
    """
    Return the history database's SQLAlchemy URL from the ``history`` parameter.

    'record': the SQLite file ``history.db`` in the record directory ``record``; a URL (``scheme://...``) as given;
    anything else: a SQLite file path.
    """
    p = str(param).strip()
    if p == 'record':
        return sqlite_url(Path(record) / 'history.db')
    return p if '://' in p else sqlite_url(p)


def _utc(stamp: float) -> str:
    """Return the ISO time (UTC, whole seconds) of a stamp [s since the epoch], for people."""
    return datetime.fromtimestamp(float(stamp), timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ')


def _moved(old, new) -> str:
    """
    Return a note naming the determined coefficient of ``new`` that moved most since ``old`` (> 3 sigma), else ''.

    ``old``: the last result at that speed.  The sigma of a change: both 1-sigma in quadrature (independent windows).
    """
    if old is None or tuple(old.nodes) != tuple(new.nodes):
        return ''
    best = (0.0, '')
    for sym in ('K', 'C'):
        a, b = getattr(old, sym), getattr(new, sym)
        sd = np.hypot(getattr(old, sym + '_std'), getattr(new, sym + '_std'))
        both = np.asarray(getattr(old, sym + '_determined'), bool) & np.asarray(getattr(new, sym + '_determined'), bool)
        with np.errstate(invalid='ignore', divide='ignore'):
            z = np.where(both & (sd > 0), np.abs(b - a) / sd, 0.0)
        i = np.unravel_index(int(np.argmax(z)), z.shape)
        if z[i] > best[0]:
            best = (float(z[i]), f"{new.bearings[i[0]]} {sym}{'xy'[i[1]]}{'xy'[i[2]]} {a[i]:.4g} -> {b[i]:.4g}")
    if best[0] <= CHANGE_SIGMAS:
        return ''
    return f'changed since the last result at this speed: {best[1]} ({best[0]:.1f} sigma)'


def _result_payload(r) -> dict:
    d = r.to_dict()
    d['speed_rad_s'] = float(r.speed)
    return {'result': d}


def identifiability_item(results, publish_undetermined: bool = False) -> DiagItem:
    """Rank / unknowns / condition per speed; WARN naming the speeds whose coefficients the data do not determine."""
    name = f'{NAME}: identifiability'
    if not results:
        return DiagItem(name, OK, 'no complete speed yet (waiting for every required run)', {})
    vals = {}
    auto = results[0].extra.get('auto')
    if auto:                                  # method auto: which method ran, and why
        vals['method'] = f"{auto['method']} (auto: {auto['reason']})"
    bad = []
    for r in results:
        rpm = rad_s_to_rpm(r.speed)
        vals[f'{rpm:.0f}rpm'] = f'rank {r.rank}/{r.unknowns}, condition {r.condition:.3g}, residual {r.residual:.3g}'
        if r.misfit:
            bad.append(f'{rpm:.0f} rpm: MODEL MISFIT, nothing determined')
        elif not r.fully_determined:
            und = r.undetermined_names()
            bad.append(f'{rpm:.0f} rpm: rank {r.rank} of {r.unknowns}, {len(und)} coefficient(s) not determined '
                       f"({', '.join(und[:4])}{'...' if len(und) > 4 else ''})")
    if bad:
        tail = 'published flagged' if publish_undetermined else 'not published'
        return DiagItem(name, WARN, f"{'; '.join(bad[:3])}{' ...' if len(bad) > 3 else ''} -- {tail}", vals)
    return DiagItem(name, OK, f'all {len(results)} speed(s) determined', vals)
