"""
The ``sensor_driver`` node's core (no ROS): its sources and the message stream it publishes.

Sources
    ``sim`` (default): the simulated rig of ``rig_params`` (:func:`bearing_id.simulation.rig.simulate_stream`, truth
    bearings != theory), one run per excitation run of the chosen scenario, computed piece by piece while it streams
    (the first block goes out at once, memory stays bounded for any stream length).  ``file``: DAQ exports (CSV or
    NPZ, :mod:`bearing_id.io.daq`), one per run, each read when its turn comes (one file in memory at a time).
    :func:`stream_messages` turns them into the node's messages (also ``scripts/make_bags.py``'s bags).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
import queue
import threading

import numpy as np

from .oil import oil_law, OIL_SPECS
from .specs import ParamSpec
from .topics import TOPIC_DISPLACEMENT, TOPIC_EXCITATION, TOPIC_OIL_TEMPERATURE, TOPIC_SPEED
from ..config.params import load_rig, ParamError, parse_probes
from ..io import messages as M
from ..io.daq import read_daq
from ..rotor.assembly import RotorModel
from ..signals.recording import Recording
from ..simulation import rig as rigmod
from ..simulation.operation import Operation

NAME = 'sensor_driver'

SPECS = [
    ParamSpec('source', 'sim', 'data source: the simulated rig of rig_params, or DAQ export files',
              choices=('sim', 'file')),
    ParamSpec('rig_params', '', 'rig YAML (empty: the packaged params/rig.yaml)'),
    ParamSpec('scenario', 'default', "excitation plan of the sim source: the runs in rig_params, the paper's "
              'unbalance of Table 3 or 4, or the directional-force plan',
              choices=('default', 'paper_table3', 'paper_table4', 'force')),
    ParamSpec('files', None, 'file source: DAQ exports (.csv or .npz), one per excitation run, played in order',
              type_='str[]'),
    ParamSpec('speeds_rpm', None, 'sim source: speed steps (unset: simulation.speeds_rpm of rig_params)', 'rpm',
              lo=1.0, hi=1e5, type_='float[]'),
    ParamSpec('dwell', None, 'sim source: time at each speed (unset: simulation.dwell)', 's', lo=0.01, hi=1e4,
              type_='float'),
    ParamSpec('noise', None, "sim source: noise std as a fraction of each channel's RMS (unset: simulation.noise)",
              '-', lo=0.0, hi=1.0, type_='float'),
    ParamSpec('probes', None, "sim source: probe channels NODE+x|y, e.g. [6x, 6y] (unset: the rig's probes)",
              type_='str[]'),
    ParamSpec('passes', 1, 'times the whole plan (sim: every run at every speed, each pass with its own noise) or the '
              'file list (file: read again each pass) is streamed', '', lo=1, hi=100000),
    ParamSpec('truth_change_after', None, 'sim source: stream time from which the simulated machine changes (unset: '
              'never; e.g. wear after the first hour)', 's', lo=0.0, hi=1e8, type_='float'),
    ParamSpec('truth_change_clearance', 1.0, 'sim source: the true bearing clearances times this after '
              'truth_change_after (wear: > 1)', '-', lo=0.1, hi=10.0),
    ParamSpec('truth_change_viscosity', 1.0, 'sim source: the true oil viscosity times this after truth_change_after '
              '(oil temperature)', '-', lo=0.1, hi=10.0),
    ParamSpec('oil_temperature_mean', None, 'sim source: the oil inlet temperature, published on rotor/oil_temperature '
              '(sensor_msgs/Temperature) and moving the true viscosity by the oil law (oil_viscosities); unset: none',
              'K', lo=250.0, hi=450.0, type_='float'),
    ParamSpec('oil_temperature_amplitude', 0.0, 'sim source: the amplitude of its sinusoidal cycle', 'K', lo=0.0,
              hi=100.0),
    ParamSpec('oil_temperature_period', 86400.0, 'sim source: the period of that cycle (a day)', 's', lo=1.0,
              hi=1e8),
    ParamSpec('oil_temperature_interval', 1.0, 'sim source: stream time between two published readings', 's',
              lo=0.01, hi=3600.0),
    *OIL_SPECS,
    ParamSpec('wear_bearing', '', 'sim source: the bearing (its name in rig_params) whose clearance grows from '
              'wear_onset to wear_end (empty: none)'),
    ParamSpec('wear_onset', 0.0, 'sim source: stream time the wear starts', 's', lo=0.0, hi=1e9),
    ParamSpec('wear_end', 1.0, 'sim source: stream time it reaches wear_clearance (constant after)', 's', lo=0.0,
              hi=1e9),
    ParamSpec('wear_clearance', 1.0, "sim source: the wearing bearing's clearance at wear_end, times its start",
              '-', lo=0.1, hi=10.0),
    ParamSpec('block_size', 1024, 'samples per DisplacementBlock', 'samples', lo=16, hi=1 << 20),
    ParamSpec('rate_factor', 1.0, 'playback speed relative to real time', '-', lo=0.01, hi=1000.0),
    ParamSpec('wait_for_subscribers', 1, 'start once this many subscribers listen to /rotor/displacement '
              '(reliable QoS only protects matched subscribers)', '', lo=0, hi=100),
    ParamSpec('subscriber_timeout', 60.0, 'give up waiting for subscribers after this long and start anyway', 's',
              lo=0.0, hi=3600.0),
    ParamSpec('exit_when_done', False, 'exit after the last block (else stay up, reporting diagnostics)'),
    ParamSpec('frame_id', '', 'header frame_id (empty: the machine id, else the rig name)'),
    ParamSpec('diagnostics_period', 1.0, 'period of /diagnostics', 's', lo=0.05, hi=60.0),
]


class RecordingRun:
    """A Recording held in memory, served in pieces like a :class:`bearing_id.simulation.rig.SimulatedRun`."""

    def __init__(self, rec):
        self.rec = rec
        self.sample_rate, self.probes, self.run, self.rig_name = rec.sample_rate, rec.probes, rec.run, rec.rig_name
        self.n_samples = rec.samples.shape[0]

    def pieces(self):
        """Yield (i0, speed (n,) [rad/s], angle (n,) [rad], samples (n, nch) [m]), whole."""
        r = self.rec
        yield 0, r.speed, r.angle, r.samples


class StreamedRun:
    """A .npz DAQ export read piece by piece as it streams (never whole in memory), served like a RecordingRun."""

    def __init__(self, rec):
        self.rec = rec                     # bearing_id.io.recordings.NpzRecording
        self.sample_rate, self.probes, self.run, self.rig_name = rec.sample_rate, rec.probes, rec.run, rec.rig_name
        self.n_samples = rec.n_samples

    def pieces(self):
        """Yield (i0, speed (n,) [rad/s], angle (n,) [rad], samples (n, nch) [m]) piece by piece."""
        i0 = 0
        for y, a, w, _ in self.rec.pieces(speed=True):
            yield i0, w, a, y
            i0 += y.shape[0]


class DaqFile:
    """A DAQ export opened only when its turn comes (:meth:`read`): a .npz streamed piece by piece, a .csv whole."""

    def __init__(self, path: str):
        self.path = str(path)

    def read(self):
        """Open the file (:func:`bearing_id.io.daq.read_daq`); raises DaqError/FileNotFoundError with the reason."""
        src = read_daq(self.path, stream=True)
        return RecordingRun(src) if isinstance(src, Recording) else StreamedRun(src)


def load_sources(values: dict) -> Sequence:
    """
    Return the source's runs from validated parameter ``values``, none of them computed or read yet.

    ``sim``: a :class:`SimulatedPlan`, a :class:`bearing_id.simulation.rig.SimulatedRun` per run and pass (each
    computed piece by piece as it streams; the truth changed from ``truth_change_after`` on);
    ``file``: a :class:`DaqFile` per file and pass (read when its turn comes; each must exist).  Raises ParamError.
    """
    if values['source'] == 'file':
        files = values['files'] or []
        if not files:
            raise ParamError("parameter 'files' must list at least one DAQ export when source is 'file'")
        missing = [f for f in files if not Path(f).is_file()]
        if missing:
            raise ParamError(f"parameter 'files': {', '.join(missing)} not found")
        return [DaqFile(f) for _ in range(values['passes']) for f in files]
    rig = load_rig(values['rig_params'] or None)
    if rig.simulation is None:
        raise ParamError(f"parameter 'rig_params': {values['rig_params'] or 'the packaged rig'} has no simulation "
                         f'section')
    runs = rig.simulation.runs if values['scenario'] == 'default' else rigmod.scenario(values['scenario'])
    if not runs:
        raise ParamError(f"parameter 'rig_params': {values['rig_params'] or 'the packaged rig'} has no excitation "
                         f'runs in its simulation section')
    probes = None
    if values['probes']:
        try:
            probes = parse_probes(','.join(values['probes']))
        except ParamError as exc:
            raise ParamError(f"parameter 'probes': {exc}") from None
    model = RotorModel.from_params(rig)
    schedule = rigmod.run_schedule(rig, values['speeds_rpm'], values['dwell'])
    op = operation_of(values, rig)
    if op is not None and values['truth_change_after'] is not None:
        raise ParamError("parameters 'truth_change_after' and an operating profile (oil_temperature_mean, "
                         'wear_bearing) both change the simulated machine: give one')
    truth_at = None if op is None else (lambda t: op.truth_at(rig, t))
    changes = ()
    if values['truth_change_after'] is not None:
        changed = rigmod.changed_truth(rig, values['truth_change_clearance'], values['truth_change_viscosity'])
        changes = ((values['truth_change_after'], changed),)

    def make(k, r, t0):
        return rigmod.simulate_stream(rig, r, schedule, noise=values['noise'], probes=probes, model=model,
                                      seed=rigmod.run_seed(rig.simulation.seed, r.id, k), t0=t0,
                                      truth_changes=changes, truth_at=truth_at)
    return SimulatedPlan(make, runs, values['passes'])


class SimulatedPlan(Sequence):
    """
    The sim source's runs, pass after pass, as a sequence: run ``i`` is built when it is asked for and not kept.

    Building a :class:`bearing_id.simulation.rig.SimulatedRun` computes no physics; keeping them all would hold every
    run's segments and the truth it fills in as it streams (a 72-hour plan of 478 runs grew the driver by ~220 MB),
    and a plan of ``passes`` up to 100,000 would not fit at all.  Every run has the same schedule, so run ``i``
    starts at stream time :meth:`start` = ``i`` x the run's samples / the sample rate [s].
    """

    def __init__(self, make, runs, passes: int):
        self._make, self._runs, self._passes = make, tuple(runs), int(passes)
        first = make(0, self._runs[0], 0.0)
        self.n_samples_per_run, self.sample_rate = first.n_samples, first.sample_rate

    def __len__(self) -> int:
        return len(self._runs) * self._passes

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        if not -len(self) <= i < len(self):
            raise IndexError(f'run {i} of a plan of {len(self)}')
        i %= len(self)
        k, j = divmod(i, len(self._runs))
        return self._make(k, self._runs[j], self.start(i))

    def start(self, i: int) -> float:
        """Return the stream time [s] at which run ``i`` starts (``i`` = len: the plan's end)."""
        return i * self.n_samples_per_run / self.sample_rate

    def n_blocks(self, block_size: int) -> int:
        """Return the blocks of ``block_size`` the whole plan is cut into (blocks never span two runs)."""
        return len(self) * n_blocks(self.n_samples_per_run, block_size)


def operation_of(values: dict, rig=None):
    """
    Return the sim source's operating profile (:class:`bearing_id.simulation.operation.Operation`) or None.

    From the ``oil_*`` and ``wear_*`` parameters; ParamError naming the parameter when they do not make one.
    """
    T_mean, wear = values['oil_temperature_mean'], str(values['wear_bearing']).strip()
    if T_mean is None and not wear:
        return None
    oil = None
    if T_mean is not None:
        try:
            oil = oil_law(values['oil_viscosities'], values['oil_reference_temperatures'], values['oil_density'])
        except ValueError as exc:
            raise ParamError(f'parameter {exc}') from None
        if oil is None:
            raise ParamError("parameter 'oil_viscosities' needs the oil's two reference viscosities (and "
                             "'oil_reference_temperatures' their two temperatures) with oil_temperature_mean")
    index = None
    if wear:
        names = [b.name for b in rig.bearings] if rig is not None else []
        if wear not in names:
            raise ParamError(f"parameter 'wear_bearing': {wear!r} is not a bearing of the rig ({', '.join(names)})")
        index = names.index(wear)
    try:
        return Operation(oil=oil, T_mean=T_mean, T_amplitude=values['oil_temperature_amplitude'],
                         T_period=values['oil_temperature_period'], wear_bearing=index,
                         wear_onset=values['wear_onset'], wear_end=values['wear_end'],
                         wear_clearance=values['wear_clearance'])
    except ValueError as exc:
        raise ParamError(f'operating profile: {exc}') from None


def sim_temperature(values: dict):
    """Return the sim source's oil inlet temperature profile (stream time [s] -> K), or None when it has none."""
    if values['source'] != 'sim' or values['oil_temperature_mean'] is None:
        return None
    return operation_of({**values, 'wear_bearing': ''}).temperature


def opened(source):
    """Return the source ready to stream: a DaqFile is read now, a Recording wrapped, a SimulatedRun as it is."""
    if isinstance(source, DaqFile):
        return source.read()
    return RecordingRun(source) if isinstance(source, Recording) else source


def n_blocks(n_samples: int, block_size: int) -> int:
    """Return how many blocks of ``block_size`` a run of ``n_samples`` is cut into (the last may be shorter)."""
    return -(-int(n_samples) // int(block_size))


def blocks_total(sources, block_size: int):
    """Return the blocks of ``block_size`` the whole stream of ``sources`` is cut into; None while a file is unread."""
    if isinstance(sources, SimulatedPlan):
        return sources.n_blocks(block_size)
    known = [src for src in sources if hasattr(src, 'n_samples')]     # files: known once read
    return sum(n_blocks(src.n_samples, block_size) for src in known) if len(known) == len(sources) else None


def run_blocks(src, block_size: int):
    """
    Cut one opened run into blocks: yields (i0, speed (n,), angle (n,), samples (n, nch)) with i0 = 0, block_size, ...

    Blocks are cut at multiples of ``block_size`` from the run's first sample whatever the pieces it arrives in.
    """
    buf = None
    for i0, w, a, y in src.pieces():
        if buf is not None:
            w, a, y = (np.concatenate([p, q]) for p, q in zip(buf[1:], (w, a, y)))
            i0 = buf[0]
        k = 0
        while w.size - k >= block_size:
            yield i0 + k, w[k:k + block_size], a[k:k + block_size], y[k:k + block_size]
            k += block_size
        buf = (i0 + k, w[k:], a[k:], y[k:]) if k < w.size else None
    if buf is not None:
        yield buf


def stream_messages(sources, block_size: int, t0_ns: int, frame_id: str, types=None, on_skip=None,
                    temperature=None, temperature_interval: float = 1.0):
    """
    Yield everything the driver publishes for ``sources``, in order, as (topic, stamp_ns, msg, end_ns).

    ``sources``: one run each (Recordings, SimulatedRuns or DaqFiles).

    Per block: an Excitation when the run changes (stamped at the run's first block), a RotorSpeed and the
    DisplacementBlock (stamp = time of the first sample; ``end_ns`` = time one sample after its last; the keyphasor
    angle of every sample in ``sample_angles``; the run in ``run_id``).  Blocks never span two runs; the stream's time
    runs on across runs at the first run's sample rate.  Each run is opened (a file read, a simulation started) when
    its turn comes.  A run that cannot be opened or has another sample rate is skipped: ``on_skip(source, reason)``
    is called (None: raise).  ``types``: None for rclpy messages, a rosbags typestore for bag writing.
    ``temperature``: stream time [s] -> oil inlet temperature [K] (an operating profile), published as a
    ``sensor_msgs/Temperature`` every ``temperature_interval`` [s] of stream time, before the block that passes it.
    """
    fs = None
    t_off = 0.0
    seq = 0
    t_next = 0.0          # stream time of the next oil temperature reading [s]
    for source in sources:
        try:
            src = opened(source)
            if fs is not None and src.sample_rate != fs:
                raise ValueError(f"sample rate {src.sample_rate:g} Hz differs from the stream's {fs:g} Hz")
        except (ValueError, OSError) as exc:
            if on_skip is None:
                raise
            on_skip(source, str(exc))
            continue
        fs = fs or src.sample_rate
        first = True
        blocks = run_blocks(src, block_size)
        while True:
            try:
                i0, w, a, y = next(blocks)
            except StopIteration:
                break
            except (ValueError, OSError) as exc:      # a streamed file's values fail their check mid-way
                if on_skip is None:
                    raise
                on_skip(source, f'{exc} (its rest not streamed)')
                break
            t_ns = t0_ns + int(round((t_off + i0 / fs) * 1e9))
            end_ns = t0_ns + int(round((t_off + (i0 + w.size) / fs) * 1e9))
            if first:
                yield (TOPIC_EXCITATION, t_ns, M.excitation_to_msg(src.run, stamp=t_ns, frame_id=frame_id,
                                                                   types=types), t_ns)
                first = False
            while temperature is not None and t_off + i0 / fs >= t_next:
                r_ns = t0_ns + int(round(t_next * 1e9))
                yield (TOPIC_OIL_TEMPERATURE, r_ns, M.temperature_to_msg(float(temperature(t_next)), stamp=r_ns,
                                                                         frame_id=frame_id, types=types), r_ns)
                t_next += temperature_interval
            w0, a0 = float(w[0]), float(a[0])
            yield TOPIC_SPEED, t_ns, M.speed_to_msg(w0, a0, stamp=t_ns, frame_id=frame_id, types=types), t_ns
            yield (TOPIC_DISPLACEMENT, t_ns, M.block_to_msg(y, seq, fs, w0, a0, src.probes, stamp=t_ns,
                                                            frame_id=frame_id, types=types, sample_angles=a,
                                                            run_id=src.run.id), end_ns)
            seq += 1
        t_off += src.n_samples / fs


class Prefetch:
    """
    Iterate ``items`` in a background thread, at most ``ahead`` items ahead of the consumer.

    The sensor_driver paces its blocks in real time while the next ones are computed or read (a speed ramp's many
    short simulated segments, the next file): a burst of work is absorbed as long as the average keeps up, and memory
    stays bounded by ``ahead`` items.  An exception in the producer is raised in the consumer; :meth:`close` stops the
    producer.
    """

    _END = object()

    def __init__(self, items, ahead: int):
        self._q: queue.Queue = queue.Queue(maxsize=max(1, int(ahead)))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._produce, args=(items,), name='prefetch', daemon=True)
        self._thread.start()

    def _put(self, item) -> bool:
        while not self._stop.is_set():
            try:
                self._q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _produce(self, items):
        try:
            for item in items:
                if not self._put(item):
                    return
        except Exception as exc:      # handed to the consumer, raised there
            self._put((self._END, exc))
            return
        self._put((self._END, None))

    def __iter__(self):
        while True:
            item = self._q.get()
            if isinstance(item, tuple) and len(item) == 2 and item[0] is self._END:
                if item[1] is not None:
                    raise item[1]
                return
            yield item

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
