"""``identifier``: accumulates 1X harmonic vectors per (run, speed) and publishes identified bearing coefficients.

Consumes ``/rotor/displacement`` (measured), ``/bearing_id/bearing_displacement`` (the kf_estimator's bearing-node
estimates) and ``/rotor/excitation``; publishes ``/bearing_id/coefficients`` (BearingCoefficients, latched) and
/diagnostics.

Data path (the offline route, call for call)
    Contiguous usable blocks of one run at one steady speed form a *segment*; a segment closes when the speed or run
    changes, a block is lost or rejected, or the stream pauses (``segment_timeout``).  Each closed segment becomes a
    :class:`bearing_id.rig.Recording` and goes through :func:`bearing_id.identify.harmonics.from_recordings` -- the
    same steady-window rule (settling part dropped, whole revolutions) as ``bearing-id identify`` -- giving one 1X
    vector per (run, speed).  Once every required run has a vector at a speed, the runs are stacked into a
    ``HarmonicData`` and :func:`bearing_id.identify.identify` solves with the configured method in a worker thread
    (the data path never waits for a solve).  Results the data do not determine are not published as numbers
    (unless ``publish_undetermined``); /diagnostics reports their rank and condition instead.

Record and resume
    Every excitation, accumulated vector and result is appended to ``<record_dir>/record.jsonl``
    (:class:`bearing_id.record.Record`); on start-up the node replays it, so a restart loses nothing already
    accumulated and re-publishes the results.
"""
from __future__ import annotations

import math
import queue
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..conventions import rad_s_to_rpm
from ..params import ExcitationEntry, Probe, Run
from .common import (ERROR, OK, STALE, TOPIC_BEARING_DISPLACEMENT, TOPIC_COEFFICIENTS, TOPIC_DISPLACEMENT,
                     TOPIC_EXCITATION, WARN, DiagItem, ExcitationTimeline, ParamSpec, StreamMonitor, diagnostics_msg,
                     qos_latched, qos_stream, run_node, stamp_to_sec)

NAME = "identifier"

SPECS = [
    ParamSpec("rig_params", "", "rig YAML with the nominal model (empty: the packaged params/rig.yaml)"),
    ParamSpec("method", "physical", "identification method (bearing-id identify --method); physical is the one "
              "unbalance runs at one probe location determine",
              choices=("paper", "conventional", "direct", "physical")),
    ParamSpec("record_dir", "~/.ros/bearing_id_record", "directory of the append-only record (resumed on restart)"),
    ParamSpec("runs", None, "excitation runs that must all be present at a speed before solving (unset: every run "
              "announced on /rotor/excitation)", type_="str[]"),
    ParamSpec("channels", None, "expected probe channel names (unset: the rig's probes)", type_="str[]"),
    ParamSpec("speed_tolerance", 0.005, "relative speed change that ends a steady window; also matches speeds "
              "across runs", "-", lo=1e-5, hi=0.2),
    ParamSpec("settle_fraction", 0.25, "fraction of each steady window discarded at its start (transient after a "
              "speed step)", "-", lo=0.0, hi=0.9),
    ParamSpec("min_window", 0.2, "shortest usable steady window", "s", lo=0.01, hi=3600.0),
    ParamSpec("segment_timeout", 0.3, "a steady segment closes when no block arrived for this long", "s",
              lo=0.01, hi=3600.0),
    ParamSpec("max_segment", 600.0, "a steady segment closes at this length (bounds memory)", "s", lo=0.1,
              hi=86400.0),
    ParamSpec("max_displacement", 1e-3, "samples above this are implausible (wrong units or garbage)", "m",
              lo=1e-9, hi=1.0),
    ParamSpec("kf_process_noise", 1e-16, "method paper: the kf_estimator's process_noise (set both alike); used "
              "to check how much of the result follows the KF's theory", "m^2", lo=0.0, hi=1.0),
    ParamSpec("kf_measurement_noise", 1e-7, "method paper: the kf_estimator's measurement_noise (set both alike)",
              "m", lo=1e-12, hi=1e-3),
    ParamSpec("publish_undetermined", False, "publish results the data do not fully determine (NaN std and "
              "determined=false mark the undetermined coefficients)"),
    ParamSpec("stale_after", 5.0, "an input silent for this long is reported STALE", "s", lo=0.1, hi=3600.0),
    ParamSpec("diagnostics_period", 1.0, "period of /diagnostics", "s", lo=0.05, hi=60.0),
]


# ------------------------------------------------------------------------------------------------ pure part
@dataclass
class Segment:
    """Contiguous usable blocks of one run at one steady speed (raw samples, SI)."""
    run: Run
    speed0: float
    sample_rate: float
    probes: tuple
    stamps: list = field(default_factory=list)
    speeds: list = field(default_factory=list)
    angles: list = field(default_factory=list)
    samples: list = field(default_factory=list)
    seqs: list = field(default_factory=list)
    last_arrival: float = 0.0

    @property
    def n(self) -> int:
        return sum(s.shape[0] for s in self.samples)

    def recording(self):
        """This segment as a rig.Recording (per-sample angle = block angle + speed x time within the block)."""
        from ..rig import Recording
        fs = self.sample_rate
        t, sp, an = [], [], []
        for st, w, a0, x in zip(self.stamps, self.speeds, self.angles, self.samples):
            k = np.arange(x.shape[0]) / fs
            t.append(st + k)
            sp.append(np.full(x.shape[0], w))
            an.append(a0 + w * k)
        return Recording(sample_rate=fs, t=np.concatenate(t), speed=np.concatenate(sp), angle=np.concatenate(an),
                         probes=self.probes, samples=np.concatenate(self.samples), run=self.run)


class Segmenter:
    """Cuts one block stream into steady segments (see the module docstring)."""

    def __init__(self, tol_rel: float, max_duration: float):
        self.tol_rel = float(tol_rel)
        self.max_duration = float(max_duration)
        self.open: Segment | None = None

    def steady_count(self, o: Segment, w: float, n: int) -> int:
        """How many of the next ``n`` samples at speed ``w`` keep ``o`` steady: the rule of
        :func:`bearing_id.signals.steady_windows` (max - min speed <= tol x |running mean|, tested at every sample),
        so that node and offline cut the same windows even when a speed step falls inside a block."""
        hi, lo = max(max(o.speeds), w), min(min(o.speeds), w)
        N = float(o.n)
        S = float(sum(x.shape[0] * v for x, v in zip(o.samples, o.speeds)))

        def breaks(k):                              # the window fails at the k-th new sample (1-based)
            return hi - lo > self.tol_rel * max(abs((S + k * w) / (N + k)), 1e-300)

        if not breaks(1):
            if not breaks(n):
                return n
            lo_k, hi_k = 1, n                       # breaks(lo_k) False, breaks(hi_k) True; the mean is monotone
            while hi_k - lo_k > 1:
                mid = (lo_k + hi_k) // 2
                lo_k, hi_k = (mid, hi_k) if not breaks(mid) else (lo_k, mid)
            return hi_k - 1
        return 0

    def add(self, block, run: Run, speed: float, contiguous: bool, now: float) -> list[Segment]:
        closed = []
        o = self.open
        x = np.asarray(block.samples, dtype=float)
        n = x.shape[0]
        fs = float(block.sample_rate)
        keep = n
        if o is not None:
            if (not contiguous or o.run.id != run.id or fs != o.sample_rate
                    or [(p.node, p.direction) for p in block.probes] != [(p.node, p.direction) for p in o.probes]):
                keep = 0
            else:
                keep = self.steady_count(o, float(speed), n)
            if keep:
                self._append(o, block.stamp, speed, block.angle, x[:keep], block.seq, now)
            if keep < n:
                closed.append(o)
                o = self.open = None
        if keep < n or o is None:
            k0 = keep if self.open is None and keep < n else 0
            o = self.open = Segment(run, float(speed), fs, tuple(block.probes))
            self._append(o, block.stamp + k0 / fs, speed, block.angle + speed * k0 / fs, x[k0:], block.seq, now)
        if o.n / o.sample_rate >= self.max_duration:
            closed.append(o)
            self.open = None
        return closed

    @staticmethod
    def _append(o: Segment, stamp, speed, angle, x, seq, now):
        o.stamps.append(float(stamp))
        o.speeds.append(float(speed))
        o.angles.append(float(angle))
        o.samples.append(x)
        o.seqs.append(int(seq))
        o.last_arrival = now

    def reassign(self, stamp: float, run: Run) -> list[Segment]:
        """A run announced late (after blocks stamped at or after its start arrived): the open segment's blocks from
        ``stamp`` [s] on move to ``run``; the earlier part is returned closed."""
        o = self.open
        if o is None or o.run.id == run.id or o.stamps[-1] < stamp - 1e-9:
            return []
        k = next(i for i, st in enumerate(o.stamps) if st >= stamp - 1e-9)
        head = None
        if k > 0:
            head = Segment(o.run, o.speed0, o.sample_rate, o.probes, o.stamps[:k], o.speeds[:k], o.angles[:k],
                           o.samples[:k], o.seqs[:k], o.last_arrival)
        self.open = Segment(run, o.speeds[k], o.sample_rate, o.probes, o.stamps[k:], o.speeds[k:], o.angles[k:],
                            o.samples[k:], o.seqs[k:], o.last_arrival)
        return [head] if head is not None else []

    def flush(self, now: float, timeout: float) -> list[Segment]:
        o = self.open
        if o is not None and now - o.last_arrival >= timeout:
            self.open = None
            return [o]
        return []


class IdentifierCore:
    """Vectors per (run, speed), the record, and the solve (no ROS).

    ``add_excitation(run)``, ``add_segment(segment, source)`` (source 'measured' or 'estimated') and ``solve()``
    (returns the IdentResults of every speed at which all required runs have a measured vector).
    """

    def __init__(self, rig, method: str, record_dir, required_runs=None, tol_rel: float = 0.005,
                 settle: float = 0.25, min_window: float = 0.2, options=None):
        from ..record import Record
        from ..rotor.assembly import RotorModel
        self.rig = rig
        self.model = RotorModel.from_params(rig)
        self.method = method
        self.options = options
        self.required = list(required_runs) if required_runs else None
        self.tol_rel, self.settle, self.min_window = float(tol_rel), float(settle), float(min_window)
        self.runs: dict = {}                   # id -> Run, in announcement order
        self.vectors: dict = {"measured": {}, "estimated": {}}   # source -> run id -> [(speed, X, X_std, probes)]
        self.notes: deque = deque(maxlen=20)
        self.results: dict = {}                # speed -> IdentResult (latest)
        self.lock = threading.Lock()
        from ..identify import get_method, harmonics  # noqa: F401  (import now, not on the first window)
        get_method(method)
        self.record = Record(record_dir)
        self.resumed = self._resume()

    # ---- record
    def _resume(self) -> dict:
        n_vec = n_res = 0
        for e in self.record.entries():
            if e["type"] == "excitation":
                run = Run(e["run_id"], tuple(ExcitationEntry(**x) for x in e["entries"]))
                self.runs.setdefault(run.id, run)
            elif e["type"] == "vector" and e.get("used", True):
                probes = tuple(Probe(*p) for p in e["probes"])
                self._store(e["source"], e["run_id"], float(e["speed"]), np.asarray(e["X"]).astype(complex),
                            np.asarray(e["X_std"], dtype=float), probes)
                n_vec += 1
            elif e["type"] == "result":
                n_res += 1
        if self.record.torn_lines:
            self.notes.append(f"record {self.record.path}: {self.record.torn_lines} torn line(s) skipped")
        self.record.append("session", resumed_vectors=n_vec, resumed_results=n_res, method=self.method)
        return {"vectors": n_vec, "results": n_res, "torn_lines": self.record.torn_lines}

    def add_excitation(self, run: Run) -> bool:
        with self.lock:
            if run.id in self.runs:
                if self.runs[run.id] != run:
                    self.notes.append(f"run {run.id} re-announced with a different excitation; the first is kept")
                return False
            self.runs[run.id] = run
        self.record.append("excitation", run_id=run.id,
                           entries=[{"kind": e.kind, "node": e.node, "magnitude": e.magnitude, "phase": e.phase,
                                     "direction": e.direction, "frequency_ratio": e.frequency_ratio}
                                    for e in run.excitation])
        return True

    def _store(self, source, run_id, speed, X, X_std, probes) -> bool:
        lst = self.vectors[source].setdefault(run_id, [])
        if any(abs(s - speed) <= self.tol_rel * speed for s, *_ in lst):
            return False                    # first vector at a speed is kept (as the offline route does)
        lst.append((speed, X, X_std, probes))
        return True

    # ---- accumulation
    def add_segment(self, seg: Segment, source: str = "measured") -> list[tuple]:
        """1X vectors of a closed segment (offline rule); returns [(speed, X)] stored, records each."""
        from ..identify import harmonics
        rec = seg.recording()
        try:
            data = harmonics.from_recordings([rec], tol_rel=self.tol_rel, settle=self.settle,
                                             min_duration=self.min_window)
        except ValueError as exc:
            self.notes.append(f"{source} segment run {seg.run.id} at {rad_s_to_rpm(seg.speed0):.0f} rpm, blocks "
                              f"{seg.seqs[0]}..{seg.seqs[-1]} ({rec.samples.shape[0] / rec.sample_rate:.2f} s): "
                              f"no steady window ({exc}); not used")
            return []
        out = []
        for j, w in enumerate(data.speeds):
            with self.lock:
                new = self._store(source, seg.run.id, float(w), data.X[0, j], data.X_std[0, j], seg.probes)
            self.record.append("vector", source=source, run_id=seg.run.id, speed=float(w), X=data.X[0, j],
                               X_std=data.X_std[0, j], probes=[[p.name, p.node, p.direction] for p in seg.probes],
                               stamp=seg.stamps[0], seqs=[seg.seqs[0], seg.seqs[-1]], used=new)
            if new:
                out.append((float(w), data.X[0, j]))
            else:
                self.notes.append(f"{source} run {seg.run.id} already has a vector at {rad_s_to_rpm(w):.0f} rpm; "
                                  f"the window of blocks {seg.seqs[0]}..{seg.seqs[-1]} is recorded, not used "
                                  f"(the first window at a speed is used, as offline)")
        return out

    def required_runs(self) -> list[str]:
        return list(self.required) if self.required else list(self.runs)

    def assemble(self):
        """HarmonicData of the measured vectors at every speed all required runs have (first run's speeds)."""
        from ..identify.harmonics import HarmonicData
        with self.lock:
            req = self.required_runs()
            if not req or any(r not in self.runs for r in req):
                return None
            meas = self.vectors["measured"]
            if any(r not in meas for r in req):
                return None
            speeds, rows = [], []
            for w, *_ in meas[req[0]]:
                row = []
                for rid in req:
                    m = [v for v in meas[rid] if abs(v[0] - w) <= self.tol_rel * w]
                    if not m:
                        break
                    row.append(m[0])
                else:
                    speeds.append(w)
                    rows.append(row)
            if not speeds:
                return None
            if self.method == "paper":          # needs the kf_estimator's bearing-node vectors too
                est = self.vectors["estimated"]
                keep, zrows = [], []
                for k, w in enumerate(speeds):
                    zr = []
                    for rid in req:
                        m = [v for v in est.get(rid, []) if abs(v[0] - w) <= self.tol_rel * w]
                        if not m:
                            break
                        zr.append(m[0])
                    else:
                        keep.append(k)
                        zrows.append(zr)
                speeds, rows = [speeds[k] for k in keep], [rows[k] for k in keep]
                if not speeds:
                    return None
            probes = rows[0][0][3]
            X = np.array([[rows[s][r][1] for s in range(len(speeds))] for r in range(len(req))], dtype=complex)
            Xs = np.array([[rows[s][r][2] for s in range(len(speeds))] for r in range(len(req))], dtype=float)
            runs = tuple(self.runs[r] for r in req)
            data = HarmonicData(np.array(speeds), probes, runs, X, Xs)
            if self.method == "paper":
                nb = len(self.rig.bearings)
                data.z_B = np.array([[zrows[s][r][1].reshape(nb, 2) for s in range(len(speeds))]
                                     for r in range(len(req))])
                data.z_B_std = np.array([[zrows[s][r][2].reshape(nb, 2) for s in range(len(speeds))]
                                         for r in range(len(req))])
        return data

    def solve(self):
        """Identify at every complete speed; returns (results, data) or ([], None)."""
        from ..identify import identify
        data = self.assemble()
        if data is None:
            return [], None
        opts = dict(self.options or {})
        if self.method == "paper":   # the KF ran in kf_estimator: its bearing-node vectors replace the offline KF
            opts.update(z_B=data.z_B, z_B_std=data.z_B_std)
            kf = opts.pop("kf", None)
            if kf:  # so that the theory-dominance check runs on the estimator's vectors as it does offline
                opts["z_B_kf"] = {"Q": kf["Q"], "R": kf["R"], "sample_rate": data.recordings[0].sample_rate}
        else:
            opts.pop("kf", None)
        results = identify(self.method, self.model, self.rig, data, options=opts or None)
        for r in results:
            self.results[float(r.speed)] = r
            self.record.append("result", **_result_payload(r))
        return results, data

    def close(self):
        self.record.close()


def _result_payload(r) -> dict:
    d = r.to_dict()
    d["speed_rad_s"] = float(r.speed)
    return {"result": d}


# ------------------------------------------------------------------------------------------------ node
def _make_node():
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node

    from ..io import messages as M
    from ..params import load_rig
    from .common import declare_parameters

    class Identifier(Node):
        def __init__(self):
            super().__init__(NAME)
            v = declare_parameters(self, SPECS)
            self.values = v
            rig = load_rig(v["rig_params"] or None)
            self.rig = rig
            channels = v["channels"] or [p.name for p in rig.probes]
            self.core = IdentifierCore(rig, v["method"], v["record_dir"], v["runs"], v["speed_tolerance"],
                                       v["settle_fraction"], v["min_window"],
                                       options={"kf": {"Q": v["kf_process_noise"],
                                                       "R": v["kf_measurement_noise"] ** 2}})
            self.monitor = StreamMonitor(TOPIC_DISPLACEMENT, channels, v["max_displacement"])
            self.monitor_est = StreamMonitor(TOPIC_BEARING_DISPLACEMENT, None, v["max_displacement"])
            self.timeline = ExcitationTimeline()
            self.seg = {"measured": Segmenter(v["speed_tolerance"], v["max_segment"]),
                        "estimated": Segmenter(v["speed_tolerance"], v["max_segment"])}
            self.problems: deque = deque(maxlen=10)
            self.skipped = {"no_speed": 0, "no_excitation": 0}
            self.published = 0
            self.last_results = []
            self.solve_time = None
            self.latency = deque(maxlen=50)         # s, last block of a window -> coefficients published
            self._jobs: queue.Queue = queue.Queue()
            self._worker = threading.Thread(target=self._work, daemon=True, name="identifier_solver")
            self.pub = self.create_publisher(M.BearingCoefficients, TOPIC_COEFFICIENTS, qos_latched(100))
            self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
            # the excitation subscription first: when a run's announcement and its first block are ready together,
            # the executor takes the announcement first (a late one is handled by Segmenter.reassign)
            self.create_subscription(M.Excitation, TOPIC_EXCITATION, self.on_excitation, qos_latched())
            self.create_subscription(M.DisplacementBlock, TOPIC_DISPLACEMENT,
                                     lambda m: self.on_block(m, "measured"), qos_stream())
            self.create_subscription(M.DisplacementBlock, TOPIC_BEARING_DISPLACEMENT,
                                     lambda m: self.on_block(m, "estimated"), qos_stream())
            self.create_timer(0.05, self.tick)
            self.create_timer(v["diagnostics_period"], self.diagnostics)
            self._worker.start()
            r = self.core.resumed
            self.get_logger().info(f"method {v['method']}, record {self.core.record.path} (resumed {r['vectors']} "
                                   f"vectors, {r['results']} results)")
            if r["vectors"]:
                self._jobs.put(time.monotonic())

        def _problem(self, text):
            self.problems.append(text)
            self.get_logger().warn(text, throttle_duration_sec=2.0)

        def on_excitation(self, msg):
            run = M.excitation_from_msg(msg)
            stamp = stamp_to_sec(msg.header.stamp)
            if self.timeline.add(stamp, run):
                self.core.add_excitation(run)
                self.get_logger().info(f"excitation: run {run.id}")
                now = time.monotonic()
                for source, sg in self.seg.items():     # blocks of this run that arrived before its announcement
                    self._close(sg.reassign(stamp, run), source, now)

        def on_block(self, msg, source):
            try:
                b = M.block_from_msg(msg)
            except (ValueError, TypeError) as exc:
                self._problem(f"malformed DisplacementBlock on the {source} stream: {exc}")
                return
            mon = self.monitor if source == "measured" else self.monitor_est
            chk = mon.check(b.seq, b.stamp, b.sample_rate, b.channels, b.samples)
            for p in chk.problems:
                self._problem(p)
            now = time.monotonic()
            if not chk.usable:
                self._close(self.seg[source].flush(now, 0.0), source, now)    # a bad block ends the window
                return
            if not (math.isfinite(b.speed) and b.speed > 0):
                self.skipped["no_speed"] += 1
                self._problem(f"{source} block seq {b.seq} has no speed; not accumulated")
                self._close(self.seg[source].flush(now, 0.0), source, now)
                return
            run = self.timeline.at(b.stamp)
            if run is None:
                self.skipped["no_excitation"] += 1
                self._problem(f"no excitation known for {source} block seq {b.seq} (stamp {b.stamp:.3f} s); "
                              f"not accumulated")
                return
            self._close(self.seg[source].add(b, run, b.speed, chk.contiguous, now), source, now)

        def _close(self, segments, source, now):
            # the harmonic fit of a closed segment (tens of ms when modes ring) runs in the worker thread, in
            # arrival order, so that the callbacks -- and with them the pause timer -- never wait for it
            for s in segments:
                self._jobs.put(("segment", s, source))

        def tick(self):
            now = time.monotonic()
            for source, sg in self.seg.items():
                self._close(sg.flush(now, self.values["segment_timeout"]), source, now)

        def _work(self):
            t_req = None              # arrival of the oldest measured window not yet solved (latency reference)
            while True:
                job = self._jobs.get()
                if job is None:
                    return
                if isinstance(job, tuple):             # ("segment", segment, source): fit and accumulate it
                    _, seg, source = job
                    try:
                        added = self.core.add_segment(seg, source)
                    except Exception as exc:          # reported; the segment is lost, nothing else is
                        self._problem(f"harmonic fit failed on a {source} segment: {type(exc).__name__}: {exc}")
                        added = False
                    while self.core.notes:
                        self._problem(self.core.notes.popleft())
                    if added and source == "measured":
                        t_req = seg.last_arrival if t_req is None else min(t_req, seg.last_arrival)
                else:                                  # a solve request (e.g. resumed from the record)
                    t_req = job if t_req is None else min(t_req, job)
                if t_req is None or not self._jobs.empty():   # coalesce: solve once the queue is drained
                    continue
                t0 = time.perf_counter()
                try:
                    results, _ = self.core.solve()
                except Exception as exc:              # reported, never published
                    self._problem(f"identification failed: {type(exc).__name__}: {exc}")
                    t_req = None
                    continue
                self.solve_time = time.perf_counter() - t0
                self.last_results = results
                sent = 0
                for r in results:
                    if r.fully_determined or self.values["publish_undetermined"]:
                        self.pub.publish(M.coefficients_to_msg(r, stamp=self.get_clock().now().to_msg(),
                                                               frame_id=self.rig.name))
                        sent += 1
                self.published += sent
                if sent:
                    self.latency.append(time.monotonic() - t_req)
                t_req = None

        def diagnostics(self):
            items = [self.monitor.status(f"{NAME}: input {TOPIC_DISPLACEMENT}", self.values["stale_after"]),
                     self.monitor_est.status(f"{NAME}: input {TOPIC_BEARING_DISPLACEMENT}", self.values["stale_after"])]
            if self.values["method"] != "paper" and items[1].level == STALE:
                items[1].level = OK
                items[1].message += " (not needed by the " + self.values["method"] + " method)"
            ex = DiagItem(f"{NAME}: input {TOPIC_EXCITATION}", OK, f"runs known: {list(self.core.runs)}",
                          {"runs": len(self.core.runs), "required": ",".join(self.core.required_runs()),
                           "blocks_without_excitation": self.skipped["no_excitation"]})
            if not self.core.runs:
                ex.level = ERROR if self.monitor.n_blocks else STALE
                ex.message = f"no excitation received on {TOPIC_EXCITATION}: nothing can be accumulated"
            items.append(ex)
            nvec = {rid: len(v) for rid, v in self.core.vectors["measured"].items()}
            acc = DiagItem(f"{NAME}: accumulation", OK, "ok", {
                "vectors_per_run": ", ".join(f"{k}: {n}" for k, n in nvec.items()) or "none",
                "record": str(self.core.record.path), "resumed_vectors": self.core.resumed["vectors"],
                "published_results": self.published, "blocks_without_speed": self.skipped["no_speed"]})
            if self.solve_time is not None:
                acc.values["last_solve_s"] = self.solve_time
            if self.latency:
                acc.values["last_latency_s"] = self.latency[-1]
                acc.values["median_latency_s"] = float(np.median(self.latency))
                acc.values["max_latency_s"] = max(self.latency)
            if self.problems:
                acc.level, acc.message = WARN, self.problems[-1]
                acc.values["problems"] = " | ".join(list(self.problems)[-5:])
                self.problems.clear()
            items.append(acc)
            items.append(identifiability_item(self.last_results, self.values["publish_undetermined"]))
            self.pub_diag.publish(diagnostics_msg(items, self.get_clock().now().to_msg(), self.rig.name))

        def close(self):
            self._jobs.put(None)
            self._worker.join(timeout=5.0)
            self.core.close()

    return Identifier()


def identifiability_item(results, publish_undetermined: bool = False) -> DiagItem:
    """Rank / unknowns / condition per speed; WARN naming the speeds whose coefficients the data do not determine."""
    name = f"{NAME}: identifiability"
    if not results:
        return DiagItem(name, OK, "no complete speed yet (waiting for every required run)", {})
    vals = {}
    bad = []
    for r in results:
        rpm = rad_s_to_rpm(r.speed)
        vals[f"{rpm:.0f}rpm"] = f"rank {r.rank}/{r.unknowns}, condition {r.condition:.3g}, residual {r.residual:.3g}"
        if not r.fully_determined:
            und = r.undetermined_names()
            bad.append(f"{rpm:.0f} rpm: rank {r.rank} of {r.unknowns}, {len(und)} coefficient(s) not determined "
                       f"({', '.join(und[:4])}{'...' if len(und) > 4 else ''})")
    if bad:
        tail = "published flagged" if publish_undetermined else "not published"
        return DiagItem(name, WARN, f"{'; '.join(bad[:3])}{' ...' if len(bad) > 3 else ''} -- {tail}", vals)
    return DiagItem(name, OK, f"all {len(results)} speed(s) determined", vals)


def main(argv=None) -> int:
    return run_node(NAME, "Accumulate 1X harmonic vectors per excitation run and speed, identify the bearing "
                          "stiffness and damping, publish them with their uncertainty.", SPECS, _make_node, argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
