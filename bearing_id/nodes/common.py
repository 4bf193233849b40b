"""
What the three nodes share.

Parameter specs and their validation, QoS choices, input-stream checks, diagnostics assembly and the process main loop
(clean exit on SIGINT/SIGTERM).

The pure parts (:class:`ParamSpec`, :func:`validate_values`, :class:`StreamMonitor`, :class:`DiagItem`) import no ROS
and are tested without it; the ROS parts import rclpy lazily.

Topic names: the ``TOPIC_*`` constants are the names in the root namespace (what bags store and ``bearing-id
play/record`` use); the nodes create their topics with :func:`relative` names, so a namespace (``--ros-args -r
__ns:=/rig1``) moves them to ``/rig1/rotor/displacement`` etc.  ``/diagnostics`` stays absolute (the ROS convention:
one aggregated topic).  Params files use the ``/**:`` key, so they apply to a node in any namespace.

QoS (the choice, documented also in params/*.yaml and the README):
    * displacement blocks (``/rotor/displacement``, ``/bearing_id/bearing_displacement``, ``/bearing_id/innovation``):
      RELIABLE, KEEP_LAST with a deep queue (``QOS_STREAM_DEPTH`` blocks = 40 s of data at 1024 samples/10,240 Hz):
      identification needs contiguous blocks, so a slow subscriber must get back-pressure, not silent loss; the depth
      absorbs a model rebuild or a garbage-collection pause.  VOLATILE: a late joiner starts at the present.
    * ``/rotor/speed``: RELIABLE, KEEP_LAST 50.
    * Subscriptions to the streams follow the parameter ``input_reliability`` (every node, :data:`COMMON_SPECS`):
      ``reliable`` (default) or ``best_effort``, which also accepts a best-effort publisher (a DAQ driver with
      SensorDataQoS); the trade-off: a block lost on the way is not re-sent, it is detected by its sequence number
      and ends the steady window.  Publishers stay RELIABLE, which serves both kinds of subscriber.
    * ``/rotor/excitation`` and ``/bearing_id/coefficients``: published RELIABLE + TRANSIENT_LOCAL (latched),
      KEEP_LAST 20: a node started late still learns the current run's excitation and the latest results.  The
      excitation is subscribed twice (:func:`subscribe_latched`): TRANSIENT_LOCAL to receive the latched value, and
      VOLATILE to match a volatile publisher too (``ros2 bag play`` of a bag without recorded QoS offers RELIABLE,
      VOLATILE, depth 10); a transient-local publisher matches both, and the callbacks ignore the repeat.
    * ``/diagnostics``: the ROS default (RELIABLE, VOLATILE, depth 10).

DDS transport: ``params/fastdds_localhost.xml`` (:data:`FASTDDS_PROFILE`, :func:`loopback_dds_env`) confines Fast DDS to
127.0.0.1 and shared memory; the Makefile and the tests choose it.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import faulthandler
import importlib
import math
import os
from pathlib import Path
import signal
import sys
import textwrap
import threading
import time
import traceback
from typing import Any, Callable

import numpy as np
import yaml

from ..config.params import ParamError
from ..io.messages import SAMPLE_RATE_RANGE

# ------------------------------------------------------------------------------------------------ topics
# Names in the root namespace (bags, play/record, diagnostics texts); nodes create them as relative(TOPIC_...).
TOPIC_DISPLACEMENT = '/rotor/displacement'
TOPIC_SPEED = '/rotor/speed'
TOPIC_EXCITATION = '/rotor/excitation'
TOPIC_BEARING_DISPLACEMENT = '/bearing_id/bearing_displacement'
TOPIC_INNOVATION = '/bearing_id/innovation'
TOPIC_COEFFICIENTS = '/bearing_id/coefficients'
TOPIC_DIAGNOSTICS = '/diagnostics'


def relative(topic: str) -> str:
    """
    Return the name a node creates ``topic`` with: relative, so it resolves in the node's namespace.

    ``/rotor/displacement`` -> ``rotor/displacement``, i.e. ``/rig1/rotor/displacement`` under ``__ns:=/rig1`` and
    unchanged in the root namespace.  ``/diagnostics`` stays absolute.
    """
    return topic if topic == TOPIC_DIAGNOSTICS else topic.lstrip('/')


QOS_STREAM_DEPTH = 400
QOS_LATCHED_DEPTH = 20

# diagnostic levels (diagnostic_msgs/DiagnosticStatus)
OK, WARN, ERROR, STALE = 0, 1, 2, 3


# ------------------------------------------------------------------------------------------------ parameters
@dataclass(frozen=True)
class ParamSpec:
    """
    One node parameter: its default, what it means (with unit) and the allowed values.

    ``lo``/``hi`` bound numbers (and every element of a number list); ``choices`` restricts strings;
    ``check`` is an extra predicate ``value -> error text or None``.
    """

    name: str
    default: Any
    description: str
    unit: str = ''
    lo: float | None = None
    hi: float | None = None
    choices: tuple | None = None
    check: Callable[[Any], str | None] | None = None
    type_: str | None = None       # needed when default is None ("unset": the node falls back, e.g. to the rig file)

    @property
    def kind(self) -> str:
        if self.type_ is not None:
            return self.type_
        d = self.default
        if isinstance(d, bool):
            return 'bool'
        if isinstance(d, int):
            return 'int'
        if isinstance(d, float):
            return 'float'
        if isinstance(d, str):
            return 'str'
        if isinstance(d, (list, tuple)):
            if d and all(isinstance(x, str) for x in d):
                return 'str[]'
            if d and all(isinstance(x, int) and not isinstance(x, bool) for x in d):
                return 'int[]'
            return 'float[]'
        raise TypeError(f'parameter {self.name}: unsupported default {d!r}')

    def doc(self) -> str:
        """One line for --help and the yaml comments: description [unit]; range; default."""
        parts = [self.description + (f' [{self.unit}]' if self.unit else '')]
        if self.choices:
            parts.append('one of ' + ' | '.join(map(str, self.choices)))
        elif self.lo is not None or self.hi is not None:
            parts.append(f"range [{'' if self.lo is None else self.lo}, {'' if self.hi is None else self.hi}]")
        parts.append('default: unset' if self.default is None else f'default {self.default!r}')
        return '; '.join(parts)


def _check_number(spec: ParamSpec, v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParamError(f"parameter '{where}' must be a number [{spec.unit}], got {v!r}")
    if not math.isfinite(float(v)):
        raise ParamError(f"parameter '{where}' must be finite [{spec.unit}], got {v!r}")
    if (spec.lo is not None and v < spec.lo) or (spec.hi is not None and v > spec.hi):
        raise ParamError(f"parameter '{where}' = {v!r} [{spec.unit}] is outside the allowed range "
                         f'[{spec.lo}, {spec.hi}]: {spec.description}')
    return v


def validate_value(spec: ParamSpec, v):
    """Check one value against its spec; returns it (ints kept int) or raises ParamError naming the parameter."""
    kind = spec.kind
    if spec.default is None and is_unset(v):
        return None
    if kind == 'bool':
        if not isinstance(v, bool):
            raise ParamError(f"parameter '{spec.name}' must be true or false, got {v!r}")
    elif kind == 'int':
        if isinstance(v, float) and v == int(v):
            v = int(v)
        if not isinstance(v, int) or isinstance(v, bool):
            raise ParamError(f"parameter '{spec.name}' must be a whole number [{spec.unit}], got {v!r}")
        _check_number(spec, v, spec.name)
    elif kind == 'float':
        v = float(_check_number(spec, v, spec.name))
    elif kind == 'str':
        if not isinstance(v, str):
            raise ParamError(f"parameter '{spec.name}' must be a string, got {v!r}")
        if spec.choices and v not in spec.choices:
            raise ParamError(f"parameter '{spec.name}' must be one of {list(spec.choices)}, got {v!r}")
    else:
        if not isinstance(v, (list, tuple)):
            raise ParamError(f"parameter '{spec.name}' must be a list, got {v!r}")
        v = list(v)
        for i, x in enumerate(v):
            if kind == 'str[]':
                if not isinstance(x, str):
                    raise ParamError(f"parameter '{spec.name}[{i}]' must be a string, got {x!r}")
            else:
                _check_number(spec, x, f'{spec.name}[{i}]')
        if kind == 'float[]':
            v = [float(x) for x in v]
    if spec.check is not None:
        msg = spec.check(v)
        if msg:
            raise ParamError(f"parameter '{spec.name}' = {v!r}: {msg}")
    return v


def unset_value(kind: str):
    """
    Return the typed value a parameter without a default is declared with.

    An empty list, NaN for a float, '' for a string, so that every declared parameter has a value (rclpy's
    get_parameters service -- ``ros2 param dump`` -- answers nothing at all for a request that names a declared
    parameter without one).
    """
    if kind.endswith('[]'):
        return []
    if kind == 'float':
        return float('nan')
    if kind == 'str':
        return ''
    raise TypeError(f"a parameter of kind {kind} needs a default (no 'unset' value for it)")


def is_unset(v) -> bool:
    """
    Return True for the values that mean "unset" for a parameter without a default.

    None (``[]`` in a params file reads as not set), an empty list, NaN, ''.
    """
    if v is None or (isinstance(v, (list, tuple)) and len(v) == 0) or (isinstance(v, str) and v == ''):
        return True
    return isinstance(v, float) and math.isnan(v)


INPUT_RELIABILITY = ('reliable', 'best_effort')

# Parameters every node declares (appended to its own specs by with_common()).
COMMON_SPECS = [
    ParamSpec('input_reliability', 'reliable',
              "reliability this node's stream subscriptions request (displacement, speed, bearing displacement; "
              'sensor_driver has none): reliable = nothing lost, a slow node back-pressures the publisher; '
              'best_effort = also accepts a best-effort publisher (e.g. a DAQ driver with SensorDataQoS), but a '
              'block lost on the way is not re-sent (it is detected by its sequence number and ends the steady '
              'window). Publishers stay reliable', choices=INPUT_RELIABILITY),
]


def with_common(specs: list[ParamSpec]) -> list[ParamSpec]:
    """``specs`` + the :data:`COMMON_SPECS` it does not already hold: the parameters a node really declares."""
    names = {s.name for s in specs}
    return list(specs) + [c for c in COMMON_SPECS if c.name not in names]


def validate_values(specs: list[ParamSpec], values: dict) -> dict:
    """Validate ``values`` (name -> value, missing names take the default); unknown names are an error."""
    names = {s.name for s in specs}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ParamError(f'unknown parameter(s) {unknown}; known: {sorted(names)}')
    return {s.name: validate_value(s, values.get(s.name, s.default)) for s in specs}


def help_epilog(specs: list[ParamSpec]) -> str:
    lines = ['ROS parameters (set with --ros-args -p name:=value or --params-file FILE):']
    for s in specs:
        lines.append(f'  {s.name}: {s.doc()}')
    return '\n'.join(lines)


PARAMS_KEY = '/**'


def yaml_block(node_name: str, specs: list[ParamSpec]) -> str:
    """
    Return the body of ``params/<node>.yaml`` for ``specs``.

    Every default written and commented; unset ones commented out.  Keyed ``/**:`` (any node name, any namespace): a
    file keyed by the node name is silently ignored when the node runs under a namespace (``/rig1/kf_estimator`` does
    not match ``kf_estimator:``).  ``node_name`` only names the node in a comment.
    """
    out = [f'{PARAMS_KEY}:  # the {node_name} node, under any namespace', '  ros__parameters:']
    for s in specs:
        out.append('')
        for ln in _wrap(s.doc(), 110):
            out.append(f'    # {ln}')
        if s.default is None:
            out.append(f'    # {s.name}: (unset)')
            continue
        val = yaml.safe_dump({s.name: list(s.default) if isinstance(s.default, tuple) else s.default},
                             default_flow_style=True, width=1000).strip()[1:-1]
        out.append(f'    {val}')
    return '\n'.join(out) + '\n'


def write_params_file(path, node_name: str, specs: list[ParamSpec]) -> str:
    """
    (Re)write ``params/<node>.yaml``; returns the text.

    Its leading comment block (the hand-written header) is kept, the body is :func:`yaml_block` of
    ``with_common(specs)``.  Regenerate all three after changing a node's SPECS: ``python -m bearing_id.nodes.common``.
    """
    path = Path(path)
    header = []
    if path.exists():
        for ln in path.read_text().splitlines():
            if ln.strip() and not ln.startswith('#'):
                break
            header.append(ln)
        while header and not header[-1].strip():
            header.pop()
    text = ('\n'.join(header) + '\n\n' if header else '') + yaml_block(node_name, with_common(specs))
    path.write_text(text)
    return text


def _wrap(text: str, width: int) -> list[str]:
    return textwrap.wrap(text, width) or ['']


def declare_parameters(node, specs: list[ParamSpec]) -> dict:
    """
    Declare ``specs`` + :data:`COMMON_SPECS` on an rclpy node with descriptors and return the validated values.

    Descriptors: description + unit, numeric ranges, read-only.  Raises ParamError naming the parameter on any bad
    value.

    Every parameter is declared with a value, so ``ros2 param dump`` / ``get_parameters`` answer for all of them: one
    without a default gets its :func:`unset_value` ([] / NaN / '') and dynamic typing (an empty list has no element
    type in rclpy, and a params file sets the typed value); its validated python value stays None.
    """
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException, ParameterException
    from rclpy.parameter import Parameter
    values = {}
    specs = with_common(specs)
    for s in specs:
        desc = ParameterDescriptor(description=s.doc(), read_only=True)
        kind = s.kind
        if s.default is None:
            desc.dynamic_typing = True      # type checked by validate_value; no range (NaN is not in one)
        elif kind in ('float', 'float[]') and (s.lo is not None or s.hi is not None):
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(-sys.float_info.max if s.lo is None else s.lo),
                to_value=float(sys.float_info.max if s.hi is None else s.hi), step=0.0)]
        if s.default is not None and kind in ('int', 'int[]') and (s.lo is not None or s.hi is not None):
            desc.integer_range = [IntegerRange(from_value=int(-2**62 if s.lo is None else s.lo),
                                               to_value=int(2**62 if s.hi is None else s.hi), step=1)]
        if s.choices:
            desc.additional_constraints = 'one of: ' + ', '.join(map(str, s.choices))
        default = list(s.default) if isinstance(s.default, tuple) else s.default
        # `[]` in a params file (what `ros2 param dump` writes for an unset list) reads as NOT_SET: declare the
        # sentinel instead, so that a dump of this node shows [] again (a NOT_SET value dumps as null, which a params
        # file reads as the string 'null')
        ignore = False
        if default is None:
            default = unset_value(kind)
            override = getattr(node, '_parameter_overrides', {}).get(s.name)
            ignore = override is not None and override.type_ == Parameter.Type.NOT_SET
        try:
            p = node.declare_parameter(s.name, default, desc, ignore_override=ignore)
        except (InvalidParameterValueException, InvalidParameterTypeException, ParameterException, TypeError) as exc:
            text = str(exc).split('\n')[0]
            raise ParamError(f"parameter '{s.name}': {text} (expected {s.doc()})") from None
        values[s.name] = p.value
    return validate_values(specs, values)


# ------------------------------------------------------------------------------------------------ QoS
def _reliability(name: str):
    from rclpy.qos import ReliabilityPolicy
    if name not in INPUT_RELIABILITY:
        raise ParamError(f'reliability must be one of {list(INPUT_RELIABILITY)}, got {name!r}')
    return ReliabilityPolicy.RELIABLE if name == 'reliable' else ReliabilityPolicy.BEST_EFFORT


def qos_stream(depth: int = QOS_STREAM_DEPTH, reliability: str = 'reliable'):
    """
    Return the QoS of data streams: KEEP_LAST ``depth``, VOLATILE, RELIABLE.

    ``reliability='best_effort'`` for a subscription that must also accept a best-effort publisher; see
    :func:`qos_input`.
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=_reliability(reliability),
                      durability=DurabilityPolicy.VOLATILE)


def input_reliability(node) -> str:
    """
    Return the node's ``input_reliability`` parameter (declared by :func:`declare_parameters`).

    'reliable' for a node that does not declare it (e.g. ``bearing-id record``).
    """
    if node.has_parameter('input_reliability'):
        return node.get_parameter('input_reliability').value
    return 'reliable'


def qos_input(node, depth: int = QOS_STREAM_DEPTH):
    """
    Return the QoS of a node's stream subscription: :func:`qos_stream` with the node's :func:`input_reliability`.

    A best-effort subscription matches reliable and best-effort publishers alike; a reliable one only reliable
    publishers.
    """
    return qos_stream(depth, input_reliability(node))


def qos_latched(depth: int = QOS_LATCHED_DEPTH):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def subscribe_latched(node, msg_type, topic: str, callback, depth: int = QOS_LATCHED_DEPTH, raw: bool = False) -> tuple:
    """
    Subscribe to a latched topic so that both kinds of publisher are heard; returns the two subscriptions.

    * TRANSIENT_LOCAL + RELIABLE, KEEP_LAST ``depth``: receives what a transient-local publisher holds (the current
      run's excitation from sensor_driver or ``bearing-id play``), also when this node starts after it was sent.
      Its "incompatible QoS" event for a volatile publisher is expected and not logged.
    * VOLATILE with the node's :func:`input_reliability`, KEEP_LAST ``depth``: matches a volatile publisher, e.g.
      ``ros2 bag play`` of a bag recorded without QoS (it offers RELIABLE, VOLATILE, depth 10) or ``ros2 topic pub``.

    A transient-local publisher matches both, so each of its messages arrives twice: ``callback`` must ignore a
    repeat (the nodes' excitation callbacks do, through :meth:`ExcitationTimeline.add`; a recorder must drop the
    second copy).  ``raw``: as for ``create_subscription`` (serialized bytes).
    """
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile

    quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _event: None)
    latched = node.create_subscription(msg_type, topic, callback, qos_latched(depth), event_callbacks=quiet, raw=raw)
    volatile = node.create_subscription(
        msg_type, topic, callback,
        QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, durability=DurabilityPolicy.VOLATILE,
                   reliability=_reliability(input_reliability(node))), raw=raw)
    return latched, volatile


# ------------------------------------------------------------------------------------------------ DDS transport
FASTDDS_PROFILE = Path(__file__).resolve().parents[2] / 'params' / 'fastdds_localhost.xml'


def fastdds_profile() -> Path | None:
    """
    Return the Fast DDS profile that confines DDS to loopback; None when neither copy exists.

    ``params/fastdds_localhost.xml`` of the source tree, else the installed copy (``share/bearing_id/params``, colcon).
    """
    if FASTDDS_PROFILE.is_file():
        return FASTDDS_PROFILE
    try:
        from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
    except ImportError:
        return None
    try:
        p = Path(get_package_share_directory('bearing_id')) / 'params' / FASTDDS_PROFILE.name
    except PackageNotFoundError:
        return None
    return p if p.is_file() else None


def loopback_dds_env(profile: Path | str | None = None) -> dict:
    """
    Return the environment variables that confine DDS to 127.0.0.1 and shared memory (no socket elsewhere).

    * ``FASTRTPS_DEFAULT_PROFILES_FILE`` / ``FASTDDS_DEFAULT_PROFILES_FILE`` = the profile (Fast DDS 2.x reads the
      first, 3.x the second): UDPv4 restricted to 127.0.0.1 + SHM, discovery by unicast to 127.0.0.1, no multicast;
    * ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (discovery by unicast to this host only; the project's rule for
      every ROS process of its tests, demo and CI).  In that mode rmw_fastrtps (Jazzy) still opens two send-only
      UDP sockets outside loopback (0.0.0.0 and the external interface, ephemeral ports) whatever the profile says;
      every socket that *receives* DDS traffic is on 127.0.0.1.  (``SYSTEM_DEFAULT`` with this profile leaves no
      socket outside loopback at all -- a choice for a plant's own launch environment.)
    """
    path = Path(profile) if profile is not None else fastdds_profile()
    if path is None or not Path(path).is_file():
        raise FileNotFoundError(f'Fast DDS profile not found: {path or FASTDDS_PROFILE}')
    return {'FASTRTPS_DEFAULT_PROFILES_FILE': str(path), 'FASTDDS_DEFAULT_PROFILES_FILE': str(path),
            'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}


# ------------------------------------------------------------------------------------------------ diagnostics
@dataclass
class DiagItem:
    """One DiagnosticStatus: ``name`` (e.g. 'kf_estimator: input /rotor/displacement'), level, message, values."""

    name: str
    level: int = OK
    message: str = 'ok'
    values: dict = field(default_factory=dict)


def flag_publishers(node, topic: str, item: DiagItem) -> DiagItem:
    """
    WARN on ``item`` when more than one publisher feeds ``topic``.

    E.g. two DAQ drivers, or a bag replayed into a live system: their blocks interleave and every window breaks
    (``publishers`` is added to its values).
    """
    try:
        n = node.count_publishers(relative(topic))
    except Exception:            # noqa: BLE001 -- a graph query must never take diagnostics down
        return item
    item.values['publishers'] = n
    if n > 1 and item.level < WARN:
        item.level = WARN
        item.message = (f'{n} publishers on {topic}: their blocks interleave (sequence restarts, stamps going '
                        f'back) -- stop all but one')
    return item


def diagnostics_msg(items: list[DiagItem], stamp, hardware_id: str = ''):
    """Build a DiagnosticArray with one status per item (values formatted with repr-precision for floats)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    for it in items:
        st = DiagnosticStatus(level=bytes([int(it.level)]), name=it.name, message=str(it.message)[:1000],
                              hardware_id=hardware_id)
        st.values = [KeyValue(key=str(k), value=_fmt(v)) for k, v in it.values.items()]
        arr.status.append(st)
    return arr


def _fmt(v) -> str:
    if isinstance(v, float):
        return f'{v:.6g}'
    return str(v)


# ------------------------------------------------------------------------------------------------ input checks
@dataclass
class BlockCheck:
    """
    Outcome of checking one block.

    ``usable`` (may enter estimation/identification), ``contiguous`` (follows the previous block without loss),
    ``problems`` (human-readable, each saying what and where).
    """

    usable: bool
    contiguous: bool
    problems: list


REORDER_WINDOW = 16        # blocks: a lower sequence number and stamp within this many blocks is a late block
SEQUENCE_JUMP = 100_000    # blocks: a jump further ahead than this is a renumbered source, not lost data


class StreamMonitor:
    """
    Checks a stream of displacement blocks and keeps the counters /diagnostics reports.

    Checks per block: sequence gaps (lost blocks) and repeats, stamp order, non-finite samples, channel names against
    ``expected_channels`` (None accepts any), and plausibility of the amplitude (|x| > ``max_abs`` [m] means the
    DAQ sent another unit, e.g. micrometres, or garbage).
    """

    def __init__(self, topic: str, expected_channels=None, max_abs: float = 1e-3, keep: int = 20):
        self.topic = topic
        self.expected_channels = list(expected_channels) if expected_channels else None
        self.max_abs = float(max_abs)
        self.n_blocks = 0
        self.n_rejected = 0
        self.n_samples = 0
        self.gaps = 0
        self.lost_blocks = 0
        self.out_of_order = 0
        self.nan_samples = 0
        self.bad_channels = 0
        self.bad_units = 0
        self.restarts = 0
        self.sequence_jumps = 0
        self.stamp_jumps = 0
        self.last_seq: int | None = None
        self.last_end: float | None = None      # stamp [s] one sample after the end of the last block
        self.recent: list[str] = []
        self.keep = keep
        self._arrivals: list[float] = []
        self._last_arrival: float | None = None
        self._lock = threading.Lock()

    def check(self, seq: int, stamp: float, sample_rate: float, channels, samples: np.ndarray,
              now: float | None = None) -> BlockCheck:
        """
        Check one block. ``stamp`` [s] = time of the first sample; ``samples`` (n, nch) [m].

        Ordering (a stream always resynchronises, one bad block never blocks the ones after it):

        * the sequence number leads: ``last + 1`` is contiguous; a repeated number, or a lower one (by at most
          ``REORDER_WINDOW``) stamped within that many blocks before the last, is a duplicate or late block
          (rejected); any other lower number means the source restarted or another recording began (``restarts``);
          a jump far
          ahead means it renumbered (``sequence_jumps``): both start a new segment and are accepted;
        * stamps: a gap starts a new segment; a stamp that goes back on a contiguous sequence number means the
          previous stamp (or the clock) jumped: a new segment, accepted (``stamp_jumps``); otherwise rejected;
        * a block with an implausible sample rate is rejected and changes no state; a block rejected for its content
          (NaN, units, channels) still advances the sequence state (it was not lost).
        """
        now = time.monotonic() if now is None else now
        problems = []
        usable = True
        contiguous = True
        where = f'{self.topic} block seq {seq} (stamp {stamp:.4f} s)'
        samples = np.asarray(samples, dtype=float)
        n = samples.shape[0] if samples.ndim == 2 else 0
        lo, hi = SAMPLE_RATE_RANGE
        with self._lock:
            self.n_blocks += 1
            self.n_samples += n
            self._arrivals.append(now)
            self._arrivals = self._arrivals[-50:]
            self._last_arrival = now
            if not (math.isfinite(sample_rate) and lo <= sample_rate <= hi and math.isfinite(stamp)):
                self.n_rejected += 1
                problems.append(f'sample_rate {sample_rate} Hz or stamp {stamp} implausible at {where}; block '
                                f'rejected')
                self.recent = (self.recent + problems)[-self.keep:]
                return BlockCheck(False, False, problems)
            order_ok, new_segment = True, False
            if self.last_seq is not None:
                d = seq - self.last_seq
                span = REORDER_WINDOW * max(n, 1) / sample_rate          # how far back a late block can be [s]
                late = d < 0 and -d <= REORDER_WINDOW and self.last_end is not None and \
                    self.last_end - span - 0.5 / sample_rate <= stamp < self.last_end - 0.5 / sample_rate
                if d == 0 or late:
                    self.out_of_order += 1
                    order_ok = usable = contiguous = False
                    problems.append(f'sequence went back from {self.last_seq} to {seq} at {where}: repeated or '
                                    f'reordered block rejected')
                elif d < 0:
                    self.restarts += 1
                    new_segment = True
                    problems.append(f'sequence restarted at {seq} (last was {self.last_seq}) at {where}: the source '
                                    f'restarted; a new segment starts here')
                elif d > SEQUENCE_JUMP:
                    self.sequence_jumps += 1
                    new_segment = True
                    problems.append(f'sequence jumped from {self.last_seq} to {seq} at {where}: renumbered source; '
                                    f'a new segment starts here')
                elif d > 1:
                    self.gaps += 1
                    self.lost_blocks += d - 1
                    contiguous = False
                    problems.append(f'sequence gap: {d - 1} block(s) lost between seq {self.last_seq} and {seq} '
                                    f'at {where}; windows restart here')
            if new_segment:
                contiguous = False
            elif order_ok and self.last_end is not None:
                dt = stamp - self.last_end
                if dt < -0.5 / sample_rate:
                    if self.last_seq is not None and seq == self.last_seq + 1:
                        self.stamp_jumps += 1
                        contiguous = False
                        problems.append(f'stamp went back {-dt:.4g} s at {where} although the sequence is '
                                        f'contiguous: the previous stamp or the clock jumped; a new segment starts')
                    else:
                        self.out_of_order += 1
                        order_ok = usable = contiguous = False
                        problems.append(f'stamp out of order: {where} starts {-dt:.4f} s before the end of the '
                                        f'previous block; block rejected')
                elif contiguous and dt > 1.5 / sample_rate:
                    contiguous = False
                    problems.append(f'time gap of {dt:.4f} s before {where}; windows restart here')
            if self.expected_channels is not None and list(channels) != self.expected_channels:
                self.bad_channels += 1
                usable = False
                problems.append(f'wrong channels {list(channels)} at {where}: expected {self.expected_channels}; '
                                f'block rejected')
            if samples.ndim != 2 or samples.shape[1] != len(channels):
                usable = False
                problems.append(f'samples shape {samples.shape} does not match {len(channels)} channels at {where}')
            else:
                bad = ~np.isfinite(samples)
                if bad.any():
                    nb = int(bad.sum())
                    self.nan_samples += nb
                    usable = False
                    rows, cols = np.nonzero(bad)
                    problems.append(f'{nb} non-finite sample(s) (NaN/inf) at {where}, first at sample {rows[0]} of '
                                    f'channel {list(channels)[cols[0]]}; block rejected')
                elif n and float(np.max(np.abs(samples))) > self.max_abs:
                    self.bad_units += 1
                    usable = False
                    j = int(np.argmax(np.max(np.abs(samples), axis=0)))
                    problems.append(f'implausible amplitude {np.max(np.abs(samples)):.4g} (limit {self.max_abs:g} m) '
                                    f'in channel {list(channels)[j]} at {where}: samples must be metres '
                                    f'(micrometres sent?); block rejected')
            if order_ok:                     # the block took its place in the stream (whatever its content)
                self.last_seq = seq
                self.last_end = stamp + n / sample_rate
            if not usable:
                self.n_rejected += 1
            self.recent = (self.recent + problems)[-self.keep:]
        return BlockCheck(usable, contiguous, problems)

    def input_rate(self) -> float:
        """Blocks per second over the recent arrivals (wall clock); 0 if fewer than two."""
        a = self._arrivals
        if len(a) < 2 or a[-1] <= a[0]:
            return 0.0
        return (len(a) - 1) / (a[-1] - a[0])

    def status(self, name: str, stale_after: float = 5.0, now: float | None = None) -> DiagItem:
        """Return a DiagItem for this input: STALE if nothing arrived for ``stale_after`` s, WARN if recent problems."""
        now = time.monotonic() if now is None else now
        with self._lock:
            vals = {'blocks': self.n_blocks, 'rejected_blocks': self.n_rejected, 'samples': self.n_samples,
                    'block_rate_hz': self.input_rate(), 'sequence_gaps': self.gaps, 'lost_blocks': self.lost_blocks,
                    'out_of_order': self.out_of_order, 'nonfinite_samples': self.nan_samples,
                    'wrong_channels': self.bad_channels, 'implausible_amplitude': self.bad_units,
                    'source_restarts': self.restarts, 'sequence_jumps': self.sequence_jumps,
                    'stamp_jumps': self.stamp_jumps,
                    'last_sequence': self.last_seq if self.last_seq is not None else -1}
            recent = list(self.recent)
            self.recent = []
            last = self._last_arrival
        if last is None:
            return DiagItem(name, STALE, f'no data received on {self.topic}', vals)
        if now - last > stale_after:
            return DiagItem(name, STALE, f'no data on {self.topic} for {now - last:.1f} s', vals)
        if recent:
            vals['problems'] = ' | '.join(recent[-5:])
            return DiagItem(name, WARN, recent[-1], vals)
        return DiagItem(name, OK, f'receiving {self.topic}', vals)


# ------------------------------------------------------------------------------------------------ main loop
class StopInStartup(Exception):
    """Raised in the main thread by a SIGINT/SIGTERM that arrives while the node is still being built."""


class StopFlag:
    """
    Set by SIGINT/SIGTERM; the spin loop polls it.

    While ``starting`` is True (the node's constructor may simulate or load data for seconds) a signal also raises
    :class:`StopInStartup`, so start-up is abandoned at once.
    """

    def __init__(self):
        self.event = threading.Event()
        self.signal_name = None
        self.starting = False

    def install(self):
        def handler(signum, frame):
            self.signal_name = signal.Signals(signum).name
            self.event.set()
            if self.starting:
                self.starting = False
                raise StopInStartup(self.signal_name)
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
        return self


def parse_cli(prog: str, description: str, specs: list[ParamSpec], argv=None):
    """Strip ROS arguments, answer --help (listing every parameter), return (ros_argv, ns)."""
    from rclpy.utilities import remove_ros_args
    argv = list(sys.argv if argv is None else argv)
    non_ros = remove_ros_args(argv)[1:]
    ap = argparse.ArgumentParser(prog=prog, description=description, epilog=help_epilog(with_common(specs)),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ns = ap.parse_args(non_ros)
    return argv, ns


CLOSE_TRACE_AFTER = 6.0      # s: a node's close() still running after this prints every thread's stack to stderr
TEARDOWN_LIMIT = 2.0         # s: the DDS teardown after close() is abandoned after this (see _middleware_teardown)
TEARDOWN_HARD_LIMIT = 4.0    # s: ... and the process ended from outside the interpreter this long after it began


def run_node(prog: str, description: str, specs: list[ParamSpec], factory, argv=None) -> int:
    """
    Process entry point shared by the nodes.

    ``factory(context_args) -> node`` builds the node (declaring ``specs``); a ParamError raised there is printed as
    one line naming the parameter and the process exits 2.  SIGINT/SIGTERM stop the spin loop; the node's ``close()``
    (flush records, stop workers) runs before the context shuts down.  Returns the exit code.
    """
    argv, _ = parse_cli(prog, description, specs, argv)
    import rclpy
    from rclpy._rclpy_pybind11 import RCLError
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    stop = StopFlag().install()
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    code = 0
    try:
        try:
            stop.starting = True
            try:
                node = factory()
            finally:
                stop.starting = False
        except StopInStartup as exc:
            print(f'{prog}: {exc}: shutting down (during start-up)', file=sys.stderr)
            return 0
        except ParamError as exc:
            print(f'{prog}: parameter error: {exc}', file=sys.stderr)
            code = 2
            return code
        except (FileNotFoundError, ValueError) as exc:
            print(f'{prog}: cannot start: {exc}', file=sys.stderr)
            code = 2
            return code
        except RCLError as exc:     # e.g. ROS_SECURITY_ENABLE with a Fast DDS built without security, bad enclave
            print(f'{prog}: cannot start: {str(exc).strip()}', file=sys.stderr)
            code = 2
            return code
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        failures = 0
        while not stop.event.is_set() and rclpy.ok() and not getattr(node, 'finished', False):
            try:
                ex.spin_once(timeout_sec=0.05)
            except Exception as exc:        # a failing callback is a bug: reported in full, the node goes on
                failures += 1
                node.get_logger().error(callback_failure_text(exc, failures))
        if stop.signal_name:
            node.get_logger().info(f'{stop.signal_name}: shutting down')
    finally:
        _trace_later(CLOSE_TRACE_AFTER)      # a close() that hangs leaves its stacks in the log
        try:
            if node is not None and hasattr(node, 'close'):
                node.close()
        finally:
            faulthandler.cancel_dump_traceback_later()
            _middleware_teardown(prog, rclpy, node, code)
    return code


def _trace_later(seconds: float, end_process: bool = False) -> None:
    """Arm faulthandler: every thread's stack to stderr after ``seconds`` (then ``_exit(1)`` if ``end_process``)."""
    try:
        faulthandler.dump_traceback_later(seconds, exit=end_process)
    except (AttributeError, ValueError, OSError):       # stderr without a file descriptor (embedded use): no trace
        pass


def _middleware_teardown(prog: str, rclpy, node, code: int) -> None:
    """
    Destroy the node and shut the context down, at most :data:`TEARDOWN_LIMIT` s.

    Runs after the node's ``close()`` (records flushed and closed, workers stopped), so nothing is lost when the DDS
    teardown hangs (Fast DDS can): the process then prints every thread's stack to stderr (the node's log) and exits
    with ``code`` without it.  Should the hang hold the interpreter lock (the watchdog thread then cannot run),
    faulthandler's own thread dumps the stacks and ends the process (exit code 1) :data:`TEARDOWN_HARD_LIMIT` s after
    the teardown began.
    """
    def abandon():
        try:
            print(f'{prog}: middleware teardown still running after {TEARDOWN_LIMIT:g} s (the node was closed, '
                  f'nothing is lost): exiting without it; the stacks follow', file=sys.stderr, flush=True)
            faulthandler.dump_traceback(sys.stderr)
            sys.stdout.flush()
        except (AttributeError, ValueError, OSError):   # stdout / stderr closed or without a descriptor: exit anyway
            pass
        os._exit(code)

    watchdog = threading.Timer(TEARDOWN_LIMIT, abandon)
    watchdog.daemon = True
    watchdog.start()
    _trace_later(TEARDOWN_HARD_LIMIT, end_process=True)
    try:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    finally:
        faulthandler.cancel_dump_traceback_later()
        watchdog.cancel()


def callback_failure_text(exc: BaseException, count: int) -> str:
    """
    Describe a callback that raised, for the node's log.

    The node keeps spinning (its other callbacks, its records and the data already accumulated are not lost), so the
    text carries the full traceback for the bug report and the running count of such failures.
    """
    tb = ''.join(traceback.format_exception(type(exc), exc, exc.__traceback__)).rstrip()
    return (f'callback failed ({count} so far; the node goes on, please report this): '
            f'{type(exc).__name__}: {exc}\n{tb}')


def stamp_to_sec(stamp) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def sec_to_stamp(t: float):
    from builtin_interfaces.msg import Time
    sec = int(math.floor(t))
    ns = int(round((t - sec) * 1e9))
    if ns >= 1_000_000_000:
        sec, ns = sec + 1, ns - 1_000_000_000
    return Time(sec=sec, nanosec=ns)


# ------------------------------------------------------------------------------------------------ excitation
class ExcitationTimeline:
    """Known excitation runs in stream time: a block belongs to the run announced last at or before its stamp."""

    def __init__(self):
        self._runs: list[tuple[float, Any]] = []     # (stamp [s], params.Run), sorted by stamp
        self._lock = threading.Lock()

    def add(self, stamp: float, run) -> bool:
        """Register ``run`` starting at ``stamp`` [s]; returns False for a repeat of a known (stamp, run id)."""
        with self._lock:
            if any(abs(s - stamp) < 1e-9 and r.id == run.id for s, r in self._runs):
                return False
            self._runs.append((float(stamp), run))
            self._runs.sort(key=lambda x: x[0])
            return True

    def at(self, stamp: float, tol: float = 1e-6):
        """Return the run in force at ``stamp`` [s] or None when no excitation was announced before it."""
        with self._lock:
            cur = None
            for s, r in self._runs:
                if s <= stamp + tol:
                    cur = r
                else:
                    break
            return cur

    def __len__(self):
        return len(self._runs)


if __name__ == '__main__':  # python -m bearing_id.nodes.common [PARAMS_DIR]: regenerate params/<node>.yaml
    from bearing_id.nodes import common as _common  # the module the nodes' specs refer to, not this __main__ copy
    _dir = Path(sys.argv[1]) if len(sys.argv) > 1 else _common.FASTDDS_PROFILE.parent
    for _node in ('sensor_driver', 'kf_estimator', 'identifier'):
        _specs = importlib.import_module(f'bearing_id.nodes.{_node}').SPECS
        _common.write_params_file(_dir / f'{_node}.yaml', _node, _specs)
        print(f"wrote {_dir / (_node + '.yaml')}")
