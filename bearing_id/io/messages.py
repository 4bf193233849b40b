"""
Conversions between the bearing_id_msgs messages and plain numpy / params objects (SI units throughout).

Works with both flavours of message objects, duck-typed by field name:

* rclpy classes (``bearing_id_msgs.msg.*``, built by ``msg_defs/``), the default for ``*_to_msg``;
* rosbags dataclasses from a typestore (``bearing_id.io.bags.typestore()``): pass ``types=that_typestore``.

``*_from_msg`` accept either flavour.  No ROS module is imported when this module is imported: the rclpy message
classes load on first use (``messages.DisplacementBlock`` etc. are resolved lazily).

Message layouts (see ``msg_defs/msg/*.msg``):

* DisplacementBlock: ``samples`` row-major (sample, channel) [m]; ``channels``/``nodes``/``directions`` per channel.
  A direction is 'x', 'y' or a probe at any angle in the x-y plane as '<angle>deg' (e.g. '45.0deg'), optionally with
  a gain '*<g>' (:func:`bearing_id.conventions.probe_direction`).
* Excitation: parallel arrays, one index per :class:`bearing_id.config.params.ExcitationEntry`.
* BearingCoefficients: 4 entries per bearing in :data:`bearing_id.conventions.COEFF_ORDER` (xx, xy, yx, yy).
"""
from __future__ import annotations

import array
from dataclasses import dataclass
import importlib
import math
from typing import Any, Mapping

import numpy as np

from ..bearings.viscosity import ZERO_CELSIUS
from ..config.params import ExcitationEntry, Probe, Run
from ..conventions import COEFF_ORDER, parse_probe_direction
from ..signals.recording import MAX_PLAUSIBLE_DISPLACEMENT

PACKAGE = 'bearing_id_msgs'
MESSAGE_NAMES = ('DisplacementBlock', 'RotorSpeed', 'Excitation', 'BearingCoefficients')


# ------------------------------------------------------------------------------------------------ message classes
def msg_class(name: str):
    """
    Return the rclpy message class ``bearing_id_msgs/msg/<name>`` (or ``pkg/msg/Name``, ``pkg.msg.Name``).

    Imported with importlib (``rosidl_runtime_py.get_message`` is not on PyPI).
    """
    text = name.replace('.', '/')
    parts = text.split('/')
    if len(parts) == 1:
        pkg, typ = PACKAGE, parts[0]
    elif len(parts) == 2:
        pkg, typ = parts
    elif len(parts) == 3:
        pkg, _, typ = parts
    else:
        raise ValueError(f'bad message type name {name!r}')
    try:
        mod = importlib.import_module(f'{pkg}.msg')
    except ImportError as exc:
        raise ImportError(f'cannot import {pkg}.msg ({exc}); run scripts/setup_env.sh (builds msg_defs into .venv) '
                          f'or source the colcon workspace that built bearing_id_msgs') from exc
    try:
        return getattr(mod, typ)
    except AttributeError:
        raise ImportError(f'{pkg}.msg has no message {typ!r}') from None


def __getattr__(name: str):  # lazy: messages.DisplacementBlock -> rclpy class
    if name in MESSAGE_NAMES:
        return msg_class(name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


class _RclpyTypes:
    """Builds rclpy message objects."""

    def make(self, full: str, **fields):
        return msg_class(full)(**fields)

    def f64(self, x) -> array.array:
        a = array.array('d')
        a.frombytes(np.ascontiguousarray(np.asarray(x, dtype=float).ravel(), dtype='<f8').tobytes())
        return a

    def u32(self, x) -> array.array:
        v = np.asarray(x, dtype=np.int64).ravel()
        if v.size and (v.min() < 0 or v.max() > 0xFFFFFFFF):
            raise ValueError(f'values out of uint32 range: {v}')
        return array.array('I', v.astype(np.uint32).tolist())

    def bools(self, x) -> list:
        return [bool(b) for b in np.asarray(x, dtype=bool).ravel()]


class _RosbagsTypes:
    """Builds rosbags dataclass message objects from a typestore."""

    def __init__(self, typestore):
        self.ts = typestore

    def make(self, full: str, **fields):
        try:
            cls = self.ts.types[full]
        except KeyError:
            raise KeyError(f'type {full} is not registered in the typestore '
                           f'(use bearing_id.io.bags.typestore())') from None
        return cls(**fields)

    def f64(self, x) -> np.ndarray:
        return np.ascontiguousarray(np.asarray(x, dtype=np.float64).ravel())

    def u32(self, x) -> np.ndarray:
        v = np.asarray(x, dtype=np.int64).ravel()
        if v.size and (v.min() < 0 or v.max() > 0xFFFFFFFF):
            raise ValueError(f'values out of uint32 range: {v}')
        return v.astype(np.uint32)

    def bools(self, x) -> np.ndarray:
        return np.asarray(x, dtype=bool).ravel()


def _types(types):
    return _RclpyTypes() if types is None else _RosbagsTypes(types)


# ----------------------------------------------------------------------------------------------------- time stamps
def stamp_to_ns(stamp) -> int:
    """
    Return a time stamp as integer nanoseconds.

    Accepts a ``builtin_interfaces/Time``-like object (``sec``, ``nanosec``; rclpy or rosbags), a message with a
    ``header``, an ``int`` (ns) or a ``float`` (s).
    """
    if stamp is None:
        return 0
    if hasattr(stamp, 'header'):
        stamp = stamp.header.stamp
    if hasattr(stamp, 'sec') and hasattr(stamp, 'nanosec'):
        return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    if hasattr(stamp, 'nanoseconds'):  # rclpy.time.Time
        return int(stamp.nanoseconds)
    if isinstance(stamp, (int, np.integer)):
        return int(stamp)
    if isinstance(stamp, (float, np.floating)):
        if not math.isfinite(stamp):
            raise ValueError(f'time stamp must be finite, got {stamp}')
        return int(round(float(stamp) * 1e9))
    raise TypeError(f'cannot interpret {stamp!r} as a time stamp')


def _header(t, stamp, frame_id: str):
    ns = stamp_to_ns(stamp)
    if ns < 0:
        raise ValueError(f'negative time stamp {ns} ns')
    sec, nsec = divmod(ns, 1_000_000_000)
    return t.make('std_msgs/msg/Header',
                  stamp=t.make('builtin_interfaces/msg/Time', sec=int(sec), nanosec=int(nsec)),
                  frame_id=str(frame_id))


# --------------------------------------------------------------------------------------------- DisplacementBlock
@dataclass
class Block:
    """
    A DisplacementBlock as plain data (SI).

    stamp_ns : time of the first sample [ns]; sequence : block counter; sample_rate [Hz]; speed [rad/s] (NaN if
    unknown); angle : keyphasor angle at the first sample [rad]; channels / nodes (1-based) / directions ('x' | 'y' |
    '<angle>deg[*<gain>]') per channel; samples : (n, nch) displacement [m]; frame_id : rig name; sample_angles :
    (n,) keyphasor angle of every sample [rad] or None when the sender gave none; run_id : the excitation run ('' = by
    stamp).
    """

    stamp_ns: int
    sequence: int
    sample_rate: float
    speed: float
    angle: float
    channels: tuple
    nodes: tuple
    directions: tuple
    samples: np.ndarray
    frame_id: str = ''
    sample_angles: np.ndarray | None = None
    run_id: str = ''

    @property
    def has_sample_angles(self) -> bool:
        """Return True when the sender gave the angle of every sample (not only the first sample's)."""
        return self.sample_angles is not None

    def angles(self) -> np.ndarray:
        """
        Return the keyphasor angle of every sample [rad], shape (n,).

        The sender's per-sample angles, or -- when it gave only the first sample's -- ``angle + speed * k /
        sample_rate`` (constant speed over the block assumed).
        """
        if self.sample_angles is not None:
            return self.sample_angles
        return self.angle + self.speed * np.arange(self.n_samples) / self.sample_rate

    @property
    def stamp(self) -> float:
        """Time of the first sample [s]."""
        return self.stamp_ns * 1e-9

    @property
    def seq(self) -> int:
        return self.sequence

    @property
    def probes(self) -> tuple:
        """Return the channels as :class:`bearing_id.config.params.Probe` (name, node, direction)."""
        return tuple(Probe(c, int(n), d) for c, n, d in zip(self.channels, self.nodes, self.directions))

    @property
    def n_samples(self) -> int:
        return int(self.samples.shape[0])

    def t(self) -> np.ndarray:
        """Sample times relative to the first sample [s], shape (n,)."""
        return np.arange(self.n_samples) / self.sample_rate


def block_to_msg(samples, sequence: int, sample_rate: float, speed: float, angle: float, probes=None, *,
                 channels=None, nodes=None, directions=None, stamp=0, frame_id: str = '', types=None,
                 sample_angles=None, run_id: str = ''):
    """
    Build a DisplacementBlock message.

    samples : (n, nch) displacement [m]; probes : sequence of Probe-like (``name``, ``node``, ``direction``) or give
    ``channels``, ``nodes``, ``directions`` explicitly; stamp : time of the first sample (Time-like, int ns or float s);
    sample_angles : (n,) keyphasor angle of every sample [rad] (None: not sent); run_id : excitation run;
    types : None for rclpy, or a rosbags typestore.
    """
    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f'samples must be (n, nch), got shape {x.shape}')
    if probes is not None:
        channels = [p.name for p in probes]
        nodes = [p.node for p in probes]
        directions = [p.direction for p in probes]
    nch = x.shape[1]
    channels = [str(c) for c in (channels if channels is not None else [f'ch{i}' for i in range(nch)])]
    nodes = list(nodes if nodes is not None else [0] * nch)
    directions = [str(d) for d in (directions if directions is not None else [''] * nch)]
    for what, v in (('channels', channels), ('nodes', nodes), ('directions', directions)):
        if len(v) != nch:
            raise ValueError(f'{what} has {len(v)} entries but samples has {nch} channels')
    ang = np.zeros(0) if sample_angles is None else np.asarray(sample_angles, dtype=float).ravel()
    if ang.size and ang.size != x.shape[0]:
        raise ValueError(f'sample_angles has {ang.size} values but samples has {x.shape[0]} rows')
    t = _types(types)
    return t.make(f'{PACKAGE}/msg/DisplacementBlock',
                  header=_header(t, stamp, frame_id), sequence=int(sequence) & 0xFFFFFFFF,
                  sample_rate=float(sample_rate), speed=float(speed), angle=float(angle),
                  sample_angles=t.f64(ang), run_id=str(run_id or ''),
                  channels=channels, nodes=t.u32(nodes), directions=directions, samples=t.f64(x))


def _f64(v) -> np.ndarray:
    if isinstance(v, array.array):
        return np.frombuffer(v, dtype=np.float64).copy() if v.typecode == 'd' else np.asarray(v, dtype=float)
    return np.asarray(v, dtype=float).ravel()


#: bounds on one DisplacementBlock (a larger one is refused before its arrays are copied): values in ``samples``
#: (2^21 = 8 s of 8 channels at 32 kHz, 16 MB) and channels
MAX_BLOCK_VALUES = 1 << 21
MAX_CHANNELS = 256


def block_from_msg(msg, max_values: int = MAX_BLOCK_VALUES) -> Block:
    """
    Return a DisplacementBlock (rclpy or rosbags) as :class:`Block`.

    ``ValueError`` when its shape is inconsistent or it holds more than ``max_values`` samples or ``MAX_CHANNELS``
    channels (checked before anything is copied).
    """
    if len(msg.samples) > max_values or len(getattr(msg, 'sample_angles', ())) > max_values:
        raise ValueError(f'DisplacementBlock seq {msg.sequence}: {len(msg.samples)} sample values (limit '
                         f'{max_values}): split it into smaller blocks')
    if len(msg.channels) > MAX_CHANNELS:
        raise ValueError(f'DisplacementBlock seq {msg.sequence}: {len(msg.channels)} channels (limit {MAX_CHANNELS})')
    channels = tuple(str(c) for c in msg.channels)
    nch = len(channels)
    nodes = tuple(int(n) for n in msg.nodes)
    directions = tuple(str(d) for d in msg.directions)
    flat = _f64(msg.samples)
    if nch == 0:
        raise ValueError(f'DisplacementBlock seq {msg.sequence} has no channels ({flat.size} samples)')
    if len(nodes) != nch or len(directions) != nch:
        raise ValueError(f'DisplacementBlock seq {msg.sequence}: {nch} channels but {len(nodes)} nodes and '
                         f'{len(directions)} directions')
    if flat.size % nch:
        raise ValueError(f'DisplacementBlock seq {msg.sequence}: {flat.size} samples is not a multiple of '
                         f'{nch} channels')
    n = flat.size // nch
    ang = _f64(getattr(msg, 'sample_angles', ()))
    if ang.size not in (0, n):
        raise ValueError(f'DisplacementBlock seq {msg.sequence}: {ang.size} sample_angles for {n} samples')
    return Block(stamp_ns=stamp_to_ns(msg.header.stamp), sequence=int(msg.sequence),
                 sample_rate=float(msg.sample_rate), speed=float(msg.speed), angle=float(msg.angle),
                 channels=channels, nodes=nodes, directions=directions, samples=flat.reshape(-1, nch),
                 frame_id=str(msg.header.frame_id), sample_angles=ang if ang.size else None,
                 run_id=str(getattr(msg, 'run_id', '') or ''))


#: a per-sample angle step this many times the block's median step is a keyphasor jump (a missed or extra key mark)
ANGLE_JUMP_FACTOR = 3.0


def check_sample_angles(angles, sample_rate: float) -> list[str]:
    """
    Return the problems with a block's per-sample keyphasor angles [rad] (empty list = fine).

    Non-finite values, the rotor turning backwards, or a jump (one step more than ``ANGLE_JUMP_FACTOR`` x the median
    step, or a step of more than a quarter revolution).  Every text starts with 'sample_angles'.
    """
    a = np.asarray(angles, dtype=float).reshape(-1)
    if not np.all(np.isfinite(a)):
        return [f'sample_angles: {int(np.count_nonzero(~np.isfinite(a)))} non-finite value(s) (no keyphasor)']
    if a.size < 2:
        return []
    d = np.diff(a)
    if np.any(d < 0):
        k = int(np.argmax(d < 0))
        return [f'sample_angles decrease at sample {k + 1} ({a[k]:.6g} -> {a[k + 1]:.6g} rad): not an unwrapped '
                f'angle of a forward-turning rotor']
    med = float(np.median(d))
    big = np.nonzero((d > ANGLE_JUMP_FACTOR * max(med, 0.0) + 1e-12) | (d > math.pi / 2))[0]
    if big.size:
        k = int(big[0])
        return [f'sample_angles jump by {d[k]:.4g} rad at sample {k + 1} (median step {med:.3g} rad, i.e. '
                f'{med * sample_rate:.4g} rad/s): keyphasor discontinuity (missed or extra key mark?)']
    return []


SAMPLE_RATE_RANGE = (1.0, 1e7)     # Hz a displacement DAQ can plausibly have


def _direction_ok(d) -> bool:
    """Return True for a probe direction text ('x', 'y', '<angle>deg[*<gain>]', conventions.parse_probe_direction)."""
    if d in ('x', 'y'):
        return True
    if not isinstance(d, str) or len(d) > 64:
        return False
    try:
        parse_probe_direction(d)
    except ValueError:
        return False
    return True


def validate_block(block, max_abs: float = MAX_PLAUSIBLE_DISPLACEMENT, n_nodes: int | None = None) -> list[str]:
    """
    Problems with a DisplacementBlock (message or :class:`Block`) as a list of texts (empty = usable). Never raises.

    Checks: channel metadata consistent with the samples, directions 'x'/'y'/'<angle>deg', nodes 1-based (and <=
    ``n_nodes`` when given), sample rate within ``SAMPLE_RATE_RANGE``, the keyphasor (``sample_angles`` finite,
    increasing, no jump -- :func:`check_sample_angles`; without them a finite positive speed and a finite first-sample
    angle), NaN/inf sample counts, and |samples| <= ``max_abs`` [m] (larger values almost always mean the data are in
    mm or µm).
    """
    problems: list[str] = []
    try:
        b = block if isinstance(block, Block) else block_from_msg(block)
    except (ValueError, TypeError, AttributeError) as exc:
        return [f'malformed DisplacementBlock: {exc}']
    x = np.asarray(b.samples, dtype=float)
    nch = len(b.channels)
    if x.ndim != 2 or x.shape[1] != nch:
        problems.append(f'samples shape {x.shape} does not match {nch} channels')
    if len(b.nodes) != nch or len(b.directions) != nch:
        problems.append(f'{nch} channels but {len(b.nodes)} nodes and {len(b.directions)} directions')
    if x.size == 0:
        problems.append('block holds no samples')
    bad_dir = [d for d in b.directions if not _direction_ok(d)]
    if bad_dir:
        problems.append(f"directions must be 'x' or 'y' or an angle such as '45.0deg', got {bad_dir[:8]}")
    bad_node = [n for n in b.nodes if n < 1 or (n_nodes is not None and n > n_nodes)]
    if bad_node:
        problems.append(f"FE nodes are 1-based (1..{n_nodes or '?'}), got {bad_node}")
    lo, hi = SAMPLE_RATE_RANGE
    if not (math.isfinite(b.sample_rate) and lo <= b.sample_rate <= hi):
        problems.append(f'sample_rate must be {lo:g}..{hi:g} Hz, got {b.sample_rate}')
    if b.sample_angles is not None:
        problems += check_sample_angles(b.sample_angles, b.sample_rate)
    else:
        if not (math.isfinite(b.speed) and b.speed > 0):
            problems.append(f'speed is {b.speed} and no sample_angles (unknown rotor speed)')
        if not math.isfinite(b.angle):
            problems.append(f'angle is {b.angle} (no keyphasor reference)')
    n_nan = int(np.count_nonzero(np.isnan(x)))
    n_inf = int(np.count_nonzero(np.isinf(x)))
    if n_nan:
        problems.append(f'{n_nan} NaN sample(s)')
    if n_inf:
        problems.append(f'{n_inf} infinite sample(s)')
    finite = x[np.isfinite(x)]
    if finite.size:
        peak = float(np.max(np.abs(finite)))
        if peak > max_abs:
            problems.append(f'|samples| up to {peak:g} > {max_abs:g} m: wrong units (mm or um?) - samples must be '
                            f'in metres')
    return problems


# ------------------------------------------------------------------------------------------------------ RotorSpeed
def speed_to_msg(speed: float, angle: float, *, stamp=0, frame_id: str = '', types=None):
    """Build a RotorSpeed message: speed [rad/s], keyphasor angle [rad] at ``stamp``."""
    t = _types(types)
    return t.make(f'{PACKAGE}/msg/RotorSpeed', header=_header(t, stamp, frame_id),
                  speed=float(speed), angle=float(angle))


# ---------------------------------------------------------------------------------------------- oil temperature
def temperature_to_msg(T: float, *, stamp=0, frame_id: str = '', types=None):
    """Build a ``sensor_msgs/Temperature`` of ``T`` [K] at ``stamp`` (the message carries degC, variance 0: unknown)."""
    t = _types(types)
    return t.make('sensor_msgs/msg/Temperature', header=_header(t, stamp, frame_id),
                  temperature=float(T) - ZERO_CELSIUS, variance=0.0)


# ------------------------------------------------------------------------------------------------------ Excitation
def excitation_to_msg(run, run_id: str | None = None, *, stamp=0, frame_id: str = '', types=None):
    """
    Build an Excitation message from a :class:`bearing_id.config.params.Run` or an iterable of ExcitationEntry.

    Give ``run_id`` with the iterable.
    """
    if hasattr(run, 'excitation'):
        entries = list(run.excitation)
        run_id = run.id if run_id is None else run_id
    else:
        entries = list(run)
    t = _types(types)
    return t.make(f'{PACKAGE}/msg/Excitation', header=_header(t, stamp, frame_id), run_id=str(run_id or ''),
                  kind=[str(e.kind) for e in entries], node=t.u32([e.node for e in entries]),
                  magnitude=t.f64([e.magnitude for e in entries]), phase=t.f64([e.phase for e in entries]),
                  direction=[str(e.direction) for e in entries],
                  frequency_ratio=t.f64([e.frequency_ratio for e in entries]))


def excitation_entries_from_msg(msg) -> list[ExcitationEntry]:
    """Return the entries of an Excitation message; ``ValueError`` when the parallel arrays differ in length."""
    cols = {k: list(getattr(msg, k)) for k in ('kind', 'node', 'magnitude', 'phase', 'direction', 'frequency_ratio')}
    lens = {k: len(v) for k, v in cols.items()}
    if len(set(lens.values())) > 1:
        raise ValueError(f'Excitation {msg.run_id!r}: per-entry arrays differ in length {lens}')
    return [ExcitationEntry(kind=str(k), node=int(n), magnitude=float(m), phase=float(p), direction=str(d),
                            frequency_ratio=float(r))
            for k, n, m, p, d, r in zip(*cols.values())]


MAX_FREQUENCY_RATIO = 100.0     # excitation frequency / rotor speed above this is not a rotor excitation
MAX_RUN_ID = 256                # characters


def check_excitation(run_id: str, entries, n_nodes: int | None = None) -> list[str]:
    """
    Return the problems with an excitation run (empty list = usable).

    Run id non-empty and short; per entry a known kind ('unbalance' with direction 'forward', or 'force' along 'x'/'y'
    or rotating), a 1-based node (<= ``n_nodes`` when given), finite magnitude >= 0, finite phase, finite frequency
    ratio in (0, MAX_FREQUENCY_RATIO].
    """
    out = []
    if not run_id or len(run_id) > MAX_RUN_ID:
        out.append(f'run_id must be 1..{MAX_RUN_ID} characters, got {len(run_id)}')
    if not entries:
        out.append('no excitation entries')
    for i, e in enumerate(entries):
        where = f'entry {i}'
        if e.kind == 'unbalance':
            if e.direction != 'forward':
                out.append(f"{where}: an unbalance rotates 'forward', got direction {e.direction!r}")
        elif e.kind == 'force':
            if e.direction not in ('x', 'y', 'forward', 'backward'):
                out.append(f"{where}: a force acts along 'x' or 'y' or rotates 'forward'/'backward', got "
                           f'direction {e.direction!r}')
        else:
            out.append(f"{where}: kind must be 'unbalance' or 'force', got {e.kind!r}")
        if e.node < 1 or (n_nodes is not None and e.node > n_nodes):
            out.append(f"{where}: node {e.node} is not a node of the model (1..{n_nodes or '?'})")
        if not (math.isfinite(e.magnitude) and e.magnitude >= 0):
            out.append(f'{where}: magnitude must be finite and >= 0, got {e.magnitude}')
        if not math.isfinite(e.phase):
            out.append(f'{where}: phase must be finite, got {e.phase}')
        if not (math.isfinite(e.frequency_ratio) and 0 < e.frequency_ratio <= MAX_FREQUENCY_RATIO):
            out.append(f'{where}: frequency_ratio must be in (0, {MAX_FREQUENCY_RATIO:g}], got {e.frequency_ratio}')
    return out


def excitation_from_msg(msg, n_nodes: int | None = None) -> Run:
    """
    Return an Excitation message as :class:`bearing_id.config.params.Run` (``id``, ``excitation`` tuple of entries).

    ``ValueError`` naming every problem (:func:`check_excitation`) when it cannot be used.
    """
    run = Run(id=str(msg.run_id), excitation=tuple(excitation_entries_from_msg(msg)))
    bad = check_excitation(run.id, run.excitation, n_nodes)
    if bad:
        raise ValueError(f'Excitation {run.id[:40]!r}: ' + '; '.join(bad[:4]) + (' ...' if len(bad) > 4 else ''))
    return run


# --------------------------------------------------------------------------------------------- BearingCoefficients
def _get(src, key, default=None):
    if isinstance(src, Mapping):
        return src.get(key, default)
    return getattr(src, key, default)


def coefficients_to_msg(result, *, stamp=0, frame_id: str = '', types=None):
    """
    Build a BearingCoefficients message from an ``IdentResult`` or a dict with the same keys.

    Keys: speed [rad/s], method, bearings (names), nodes (1-based), K, C (nb, 2, 2) [N/m], [N s/m], K_std, C_std
    (NaN = undetermined; default all NaN), K_determined, C_determined (bool; default: finite std), rank, unknowns,
    condition, residual, notes.
    """
    K = np.asarray(_get(result, 'K'), dtype=float).reshape(-1, 2, 2)
    C = np.asarray(_get(result, 'C'), dtype=float).reshape(-1, 2, 2)
    nb = K.shape[0]
    if C.shape[0] != nb:
        raise ValueError(f'K has {nb} bearings but C has {C.shape[0]}')
    K_std = _get(result, 'K_std')
    C_std = _get(result, 'C_std')
    K_std = np.full_like(K, np.nan) if K_std is None else np.asarray(K_std, dtype=float).reshape(nb, 2, 2)
    C_std = np.full_like(C, np.nan) if C_std is None else np.asarray(C_std, dtype=float).reshape(nb, 2, 2)
    K_det = _get(result, 'K_determined')
    C_det = _get(result, 'C_determined')
    K_det = np.isfinite(K_std) if K_det is None else np.asarray(K_det, dtype=bool).reshape(nb, 2, 2)
    C_det = np.isfinite(C_std) if C_det is None else np.asarray(C_det, dtype=bool).reshape(nb, 2, 2)
    bearings = [str(b) for b in (_get(result, 'bearings') or [f'bearing{i + 1}' for i in range(nb)])]
    nodes = list(_get(result, 'nodes') or [0] * nb)
    if len(bearings) != nb or len(nodes) != nb:
        raise ValueError(f'{nb} bearings in K but {len(bearings)} names and {len(nodes)} nodes')
    t = _types(types)
    cond = _get(result, 'condition', _get(result, 'condition_number', math.nan))
    return t.make(f'{PACKAGE}/msg/BearingCoefficients', header=_header(t, stamp, frame_id),
                  speed=float(_get(result, 'speed')), method=str(_get(result, 'method', '') or ''),
                  bearings=bearings, nodes=t.u32(nodes),
                  stiffness=t.f64(K), damping=t.f64(C), stiffness_std=t.f64(K_std), damping_std=t.f64(C_std),
                  stiffness_determined=t.bools(K_det), damping_determined=t.bools(C_det),
                  rank=int(_get(result, 'rank', 0)), unknowns=int(_get(result, 'unknowns', 0)),
                  condition_number=float(cond), residual=float(_get(result, 'residual', math.nan)),
                  notes=[str(n) for n in (_get(result, 'notes') or [])])


def coefficients_from_msg(msg) -> dict[str, Any]:
    """
    Return a BearingCoefficients message as a dict with the keys of ``IdentResult`` plus a few.

    Arrays (nb, 2, 2), SI; the extra keys are ``stamp_ns``, ``frame_id`` and ``coeffs`` (the shared ``{node: (K, C)}``
    shape).  ``ValueError`` when the arrays do not hold 4 entries per bearing.
    """
    bearings = tuple(str(b) for b in msg.bearings)
    nb = len(bearings)
    out: dict[str, Any] = {'stamp_ns': stamp_to_ns(msg.header.stamp), 'frame_id': str(msg.header.frame_id),
                           'speed': float(msg.speed), 'method': str(msg.method), 'bearings': bearings,
                           'nodes': tuple(int(n) for n in msg.nodes)}
    for key, fld in (('K', 'stiffness'), ('C', 'damping'), ('K_std', 'stiffness_std'), ('C_std', 'damping_std')):
        v = _f64(getattr(msg, fld))
        if v.size != 4 * nb:
            raise ValueError(f'BearingCoefficients.{fld} has {v.size} entries, expected 4 per bearing '
                             f'({COEFF_ORDER}) x {nb} bearings')
        out[key] = v.reshape(nb, 2, 2)
    for key, fld, std in (('K_determined', 'stiffness_determined', 'K_std'),
                          ('C_determined', 'damping_determined', 'C_std')):
        v = np.asarray(list(getattr(msg, fld)), dtype=bool)
        out[key] = v.reshape(nb, 2, 2) if v.size == 4 * nb else np.isfinite(out[std])
    if len(out['nodes']) != nb:
        raise ValueError(f"BearingCoefficients: {nb} bearings but {len(out['nodes'])} nodes")
    out.update(rank=int(msg.rank), unknowns=int(msg.unknowns), condition=float(msg.condition_number),
               residual=float(msg.residual), notes=[str(n) for n in msg.notes])
    out['coeffs'] = {n: (out['K'][i].copy(), out['C'][i].copy()) for i, n in enumerate(out['nodes'])}
    return out


__all__ = ['PACKAGE', 'MESSAGE_NAMES', 'MAX_PLAUSIBLE_DISPLACEMENT', 'MAX_BLOCK_VALUES', 'MAX_CHANNELS',
           'SAMPLE_RATE_RANGE', 'msg_class', 'stamp_to_ns', 'Block',
           'block_to_msg', 'block_from_msg', 'validate_block', 'check_sample_angles', 'speed_to_msg',
           'excitation_to_msg', 'excitation_entries_from_msg', 'excitation_from_msg', 'check_excitation',
           'coefficients_to_msg', 'coefficients_from_msg']
