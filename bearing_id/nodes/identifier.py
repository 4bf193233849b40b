"""
``identifier``: accumulates 1X harmonic vectors per (run, speed) and publishes identified bearing coefficients.

Consumes ``/rotor/displacement`` (measured), ``/rotor/excitation`` and the optional oil inlet temperature (every method
identifies from the measured vectors: the kf_estimator's bearing-node estimates are its own output, reported on its own
/diagnostics, and not read here); publishes ``/bearing_id/coefficients``
(BearingCoefficients, latched), ``/bearing_id/alarms`` (a DiagnosticArray per change the history's change detection
finds: bearing, parameter, size with its 1-sigma, onset, evidence; latched) and /diagnostics.  The data path, the
record and the solve are :class:`bearing_id.nodes.identifier_core.IdentifierCore` (the offline route's functions, call
for call); this module only moves messages, runs the fits and solves in a worker thread and reports.
"""
from __future__ import annotations

from collections import deque
import math
import queue
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Temperature

from .declare import declare_parameters
from .diagnostics import diagnostics_msg, flag_best_effort, flag_publishers
from .identifier_core import alarm_items, history_url, identifiability_item, IdentifierCore, NAME, SPECS
from .machine import label, machine_id, record_dir
from .monitor import StreamMonitor
from .oil import oil_law
from .process import run_node
from .qos import qos_input, qos_latched, subscribe_latched
from .runs import excitation_of, MALFORMED, RunResolver
from .status import DiagItem, ERROR, OK, STALE, Throttle, WARN, WARN_EVERY
from .topics import (relative, TOPIC_ALARMS, TOPIC_COEFFICIENTS, TOPIC_DISPLACEMENT, TOPIC_EXCITATION,
                     TOPIC_OIL_TEMPERATURE)
from ..bearings.viscosity import celsius
from ..config.params import load_rig
from ..history import HistoryStore, redacted_url
from ..io import messages as M

# while windows queue, a solve starts no sooner than SOLVE_BACKLOG times the last solve's duration after it ended; the
# worker fits the queued windows in between (a replay faster than the solves: one solve for several windows, every
# window fitted).  With none queued a pending solve starts at once (at real time: every new window, solved at once).
# Before, the hold was counted from the window's closing: a worker that had fallen behind found every hold expired,
# solved after every window and fell further behind (a 72-hour stream at 50x: ~60 solves per stream hour, then 1,052
# in one hour, the window queue at 5.3 GB).
SOLVE_BACKLOG = 3.0


class Identifier(Node):
    """The identifier node: windows -> 1X vectors -> coefficients published (see the module docstring)."""

    def __init__(self):
        super().__init__(NAME)
        self._warn_gate = Throttle(WARN_EVERY)      # one problem line per WARN_EVERY s (the latest on /diagnostics)
        v = declare_parameters(self, SPECS)
        self.values = v
        rig = load_rig(v['rig_params'] or None)
        self.rig = rig
        self.machine = machine_id(v['machine_id'], self.get_namespace())
        self.label = label(self.machine, rig.name)            # hardware_id and frame_id
        channels = v['channels'] or [p.name for p in rig.probes]
        rdir = record_dir(v['record_dir'], self.get_namespace(), self.get_name())
        self.history_problem = ''
        history = None
        if str(v['history']).strip():
            url = history_url(v['history'], rdir)
            try:
                history = HistoryStore(url)
            except Exception as exc:      # the node runs and records without it; /diagnostics says why (ERROR)
                self.history_problem = (f'history database {redacted_url(url)} not opened: {type(exc).__name__}: '
                                        f'{str(exc).replace(url, redacted_url(url))}')
                self.get_logger().error(self.history_problem)
        oil = oil_law(v['oil_viscosities'], v['oil_reference_temperatures'], v['oil_density'])
        self.core = IdentifierCore(rig, v['method'], rdir,
                                   v['runs'], v['speed_tolerance'], v['settle_fraction'], v['min_window'],
                                   options={'kf': {'Q': v['kf_process_noise'],
                                                   'R': v['kf_measurement_noise'] ** 2 or None}},
                                   max_window=v['max_segment'], machine=self.machine, history=history,
                                   alarms={'arl0': v['alarm_arl0'], 'delta': v['alarm_shift'],
                                           'n_reference': v['alarm_reference']}, oil=oil)
        self.monitor = StreamMonitor(TOPIC_DISPLACEMENT, channels, v['max_displacement'])
        self.resolver = RunResolver(v['max_waiting_blocks'])     # the run of each measured block
        for stamp, run in self.core.run_starts:      # resumed: the runs (and the current one) are known
            self.resolver.announce(stamp, run)
        self.problems: deque = deque(maxlen=10)
        self._shared = threading.Lock()         # problems and latency: written by the solver thread
        self.skipped = {'no_speed': 0, 'no_angles': 0}
        self._gap = False                       # the next measured block follows rejected data
        self.published = 0
        self.last_results = []                  # the latest result at every speed (for /diagnostics)
        self.solve_time = None
        self.latency = deque(maxlen=50)         # s, last block of a window -> coefficients published
        self._jobs: queue.Queue = queue.Queue()
        self._worker = threading.Thread(target=self._work, daemon=True, name='identifier_solver')
        self.pub = self.create_publisher(M.BearingCoefficients, relative(TOPIC_COEFFICIENTS), qos_latched(100))
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.pub_alarms = self.create_publisher(DiagnosticArray, relative(TOPIC_ALARMS), qos_latched(100))
        self.alarms_published = 0
        self.publish_alarms()             # those already in the history (a late subscriber gets them: latched)
        # the excitation subscription first: when a run's announcement and its first block are ready together,
        # the executor takes the announcement first (a block of a run not yet announced waits for it)
        subscribe_latched(self, M.Excitation, relative(TOPIC_EXCITATION), self.on_excitation)
        self.create_subscription(M.DisplacementBlock, relative(TOPIC_DISPLACEMENT), self.on_block, qos_input(self))
        self.create_subscription(Temperature, relative(TOPIC_OIL_TEMPERATURE), self.on_temperature, qos_input(self, 50))
        # a pause is seen within half its length (segment_timeout, or pause_blocks blocks' time when longer: _pace)
        # of its end (a timer wake costs ~1 ms of CPU: no faster)
        self._tick_ns = int(0.5e9 * v['segment_timeout'])
        self._tick_timer = self.create_timer(self._tick_ns * 1e-9, self.tick)
        self.create_timer(v['diagnostics_period'], self.diagnostics)
        self._worker.start()
        r = self.core.resumed
        self.get_logger().info(f"method {v['method']}, record {self.core.record.path} (resumed {r['vectors']} "
                               f"vectors, {r['results']} results)")
        if r['vectors']:
            self._jobs.put(('solve', time.monotonic()))

    def _problem(self, text):
        with self._shared:
            self.problems.append(text)
        line = self._warn_gate.line(text, time.monotonic())
        if line is not None:
            self.get_logger().warn(line)

    def on_excitation(self, msg):
        try:
            stamp, run = excitation_of(msg, self.core.model.n_nodes)
        except MALFORMED as exc:
            self._problem(f'malformed Excitation rejected: {exc}')
            return
        _, released = self.resolver.announce(stamp, run)
        now = time.monotonic()
        for b, r, contiguous in released:        # blocks of this run that arrived before its announcement
            self._feed(b, r, contiguous, now)
        if self.core.add_excitation(run, stamp):
            self.get_logger().info(f'excitation: run {run.id}')

    def on_temperature(self, msg):
        """Take an oil inlet temperature [degC on the message] at its header stamp (the displacement blocks' clock)."""
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        if stamp <= 0:
            self._problem('oil temperature without a header stamp rejected: it cannot be matched to the data')
            return
        problem = self.core.add_temperature(stamp, float(celsius(msg.temperature)))
        if problem:
            self._problem(problem)

    def on_block(self, msg):
        try:
            b = M.block_from_msg(msg)
        except MALFORMED as exc:
            self._problem(f'malformed DisplacementBlock on the measured stream: {exc}')
            return
        chk = self.monitor.check(b.seq, b.stamp, b.sample_rate, b.channels, b.samples)
        for p in chk.problems:
            self._problem(p)
        now = time.monotonic()
        bad = [] if not chk.usable else M.validate_block(b, self.values['max_displacement'],
                                                         self.core.model.n_nodes)
        for p in bad:
            self._problem(f'measured block seq {b.seq} rejected: {p}')
        if not chk.usable or bad:
            self._gap = True                   # rejected data ends the open window there
            return
        if not b.has_sample_angles:
            self.skipped['no_angles'] += 1
        contiguous = chk.contiguous and not self._gap
        self._gap = False
        run = self.resolver.resolve(b, contiguous)
        if run is None:
            return
        self._feed(b, run, contiguous, now)

    def _feed(self, b, run, contiguous, now):
        try:
            wins = self.core.feed(b, run, contiguous, now)
        except ValueError as exc:
            self._problem(f'measured block seq {b.seq} not accumulated: {exc}')
            return
        self._close(wins, now)
        self._pace()

    def _pace(self):
        """Wake for pauses at half the pause length the blocks now give (long blocks need no 0.15 s wake-up)."""
        ns = int(0.5e9 * self.core.pause_after(self.values['segment_timeout'], self.values['pause_blocks']))
        if abs(ns - self._tick_ns) > 0.01 * self._tick_ns:
            self._tick_timer.timer_period_ns = ns
            self._tick_ns = ns

    def _close(self, windows, now):
        # the harmonic fit of a closed window (tens of ms when modes ring) runs in the worker thread, in
        # arrival order, so that the callbacks -- and with them the pause timer -- never wait for it
        for w in windows:     # (shorter ones, e.g. ramp steps, give nothing)
            if self.core.wants(w, 0.5 * self.core.min_window):
                self._jobs.put(('window', w, now))

    def tick(self):
        now = time.monotonic()
        self._close(self.core.flush(now, self.values['segment_timeout'], self.values['pause_blocks']), now)

    def _work(self):
        t_req = None              # when the oldest window not yet solved closed (latency reference)
        last_sig = None
        last_end = -math.inf      # when the last solve ended (monotonic)
        try:
            self.core.prepare()   # before the first window has closed (>= min_window of data away)
        except Exception as exc:  # reported; each solve then computes what it needs itself
            self._problem(f'preparing the solves failed: {type(exc).__name__}: {exc}')
        while True:
            due = None if t_req is None else last_end + SOLVE_BACKLOG * (self.solve_time or 0.0)
            if due is None or (time.monotonic() < due and not self._jobs.empty()):
                # a window or a request: wait for one when no solve is pending, else take the queued ones until
                # the solve is due (the worker is the only consumer: a non-empty queue stays non-empty)
                job = self._jobs.get() if due is None else self._jobs.get_nowait()
                if job is None:
                    return
                if job[0] == 'window':             # fit and accumulate it
                    _, win, closed_at = job
                    try:
                        added = self.core.add_window(win)
                    except Exception as exc:      # reported; the window is lost, nothing else is
                        self._problem(f'harmonic fit failed on a measured window: {type(exc).__name__}: {exc}')
                        added = []
                    if added:
                        t_req = closed_at if t_req is None else min(t_req, closed_at)
                else:                              # a solve request (e.g. resumed from the record)
                    t_req = job[1] if t_req is None else min(t_req, job[1])
                while self.core.notes:
                    self._problem(self.core.notes.popleft())
                continue                           # the solve may be due now, or later
            try:
                data = self.core.assemble()
                sig = self.core.signature(data)
                if sig is None or sig == last_sig:
                    t_req = None
                    continue          # no new complete speed
                t0 = time.perf_counter()
                results, _ = self.core.solve(data, record=False)     # recorded before they are published
                last_sig = sig
            except Exception as exc:              # reported, never published
                self._problem(f'identification failed: {type(exc).__name__}: {exc}')
                t_req = None
                last_end = time.monotonic()
                continue
            self.solve_time = time.perf_counter() - t0
            last_end = time.monotonic()
            # the latest result at every speed (a per-speed method returns only the speeds it solved again)
            self.last_results = sorted(self.core.results.values(), key=lambda r: r.speed)
            # in the record and the history first: a kill after the publishing loses no published result
            try:
                self.core.record_results(results)
            except (OSError, ValueError) as exc:
                self._problem(f'results not recorded: {type(exc).__name__}: {exc}')
            sent = 0
            for r in results:
                if r.fully_determined or self.values['publish_undetermined']:
                    self.pub.publish(M.coefficients_to_msg(r, stamp=self.get_clock().now().to_msg(),
                                                           frame_id=self.label))
                    sent += 1
            self.published += sent
            if sent:
                with self._shared:
                    self.latency.append(time.monotonic() - t_req)
            t_req = None
            self.publish_alarms()

    def publish_alarms(self):
        """Publish the changes the history's change detection found and has not published yet (one array)."""
        new = []
        while self.core.new_alarms:
            new.append(self.core.new_alarms.popleft())
        if not new:
            return
        self.pub_alarms.publish(diagnostics_msg(alarm_items(new), self.get_clock().now().to_msg(), self.label,
                                                self.machine))
        self.alarms_published += len(new)
        for c in new:
            self.get_logger().warn(f'bearing change: {c.sentence()}')

    def diagnostics(self):
        disp = self.monitor.status(f'{NAME}: input {TOPIC_DISPLACEMENT}', self.values['stale_after'])
        items = [flag_best_effort(self, TOPIC_DISPLACEMENT, flag_publishers(self, TOPIC_DISPLACEMENT, disp))]
        rs = self.resolver
        ex = DiagItem(f'{NAME}: input {TOPIC_EXCITATION}', OK, f'runs known: {list(self.core.runs)}',
                      {'runs': len(self.core.runs), 'required': ','.join(self.core.required_runs()),
                       'blocks_waiting_for_excitation': len(rs.waiting),
                       'blocks_assigned_after_waiting': rs.released,
                       'blocks_dropped_waiting_too_long': rs.dropped})
        if not self.core.runs:
            ex.level = ERROR if self.monitor.n_blocks else STALE
            ex.message = f'no excitation received on {TOPIC_EXCITATION}: blocks wait, nothing is accumulated'
        elif rs.dropped:
            ex.level = WARN
            ex.message = f"{rs.dropped} block(s) dropped after waiting too long for their run's excitation"
        items.append(ex)
        nvec = self.core.vector_counts()
        acc = DiagItem(f'{NAME}: accumulation', OK, 'ok', {
            'vectors_per_run': ', '.join(f'{k}: {n}' for k, n in nvec.items()) or 'none',
            'record': str(self.core.record.path), 'resumed_vectors': self.core.resumed['vectors'],
            'published_results': self.published, 'blocks_without_speed': self.skipped['no_speed'],
            'blocks_without_sample_angles': self.skipped['no_angles']})
        if self.skipped['no_angles']:
            acc.level = WARN
            acc.message = (f"{self.skipped['no_angles']} block(s) without sample_angles: their angle assumes "
                           f'constant speed over the block (biased on speed ramps)')
        if self.solve_time is not None:
            acc.values['last_solve_s'] = self.solve_time
        with self._shared:       # snapshots: the solver thread appends while this timer reads
            latency, problems = list(self.latency), list(self.problems)
            self.problems.clear()
        if latency:
            acc.values['last_latency_s'] = latency[-1]
            acc.values['median_latency_s'] = float(np.median(latency))
            acc.values['max_latency_s'] = max(latency)
        if problems:
            acc.level, acc.message = WARN, problems[-1]
            acc.values['problems'] = ' | '.join(problems[-5:])
        items.append(acc)
        items.append(identifiability_item(self.last_results, self.values['publish_undetermined']))
        items.append(self.core.gaps_item())
        items.append(DiagItem(f'{NAME}: history', ERROR, self.history_problem, {}) if self.history_problem
                     else self.core.history_item())
        alarm = self.core.alarm_item()
        alarm.values['published_on'] = f'{TOPIC_ALARMS} ({self.alarms_published})'
        items.append(alarm)
        items.append(flag_publishers(self, TOPIC_COEFFICIENTS, DiagItem(
            f'{NAME}: output {TOPIC_COEFFICIENTS}', OK, f'{self.published} result(s) published', {}),
            'another node publishes coefficients here too (a second identifier, or another machine in this '
            'namespace): a consumer cannot tell whose they are -- give each machine its own namespace'))
        self.pub_diag.publish(diagnostics_msg(items, self.get_clock().now().to_msg(), self.label, self.machine))

    def close(self):
        self._jobs.put(None)
        self._worker.join(timeout=5.0)
        self.core.close()
        if self.core.history is not None:
            self.core.history.close()


def main(argv=None) -> int:
    return run_node(NAME, 'Accumulate 1X harmonic vectors per excitation run and speed, identify the bearing '
                          'stiffness and damping, publish them with their uncertainty.', SPECS, Identifier, argv)


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
