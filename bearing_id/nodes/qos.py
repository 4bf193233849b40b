"""
The QoS of the bearing_id topics (the choice, documented also in params/*.yaml and docs/ROS.md).

* displacement blocks (``/rotor/displacement``, ``/bearing_id/bearing_displacement``, ``/bearing_id/innovation``):
  RELIABLE, KEEP_LAST with a deep queue (``QOS_STREAM_DEPTH`` blocks = 40 s of data at 1024 samples/10,240 Hz; the
  sensor_driver's publisher holds ``QOS_STREAM_SECONDS`` whatever its block size, :func:`stream_depth`):
  identification needs contiguous blocks, so a slow subscriber must get back-pressure, not silent loss; the depth
  absorbs a model rebuild or a garbage-collection pause.  VOLATILE: a late joiner starts at the present.
* ``/rotor/speed``: RELIABLE, KEEP_LAST 50.
* Subscriptions to the streams follow the parameter ``input_reliability`` (every node,
  :data:`bearing_id.nodes.specs.COMMON_SPECS`): ``reliable`` (default) or ``best_effort``, which also accepts a
  best-effort publisher (a DAQ driver with SensorDataQoS); the trade-off: a block lost on the way is not re-sent, it
  is detected by its sequence number and ends the steady window.  Publishers stay RELIABLE, which serves both kinds
  of subscriber.
* ``/rotor/excitation`` and ``/bearing_id/coefficients``: published RELIABLE + TRANSIENT_LOCAL (latched), KEEP_LAST
  20: a node started late still learns the current run's excitation and the latest results.  The excitation is
  subscribed twice (:func:`subscribe_latched`): TRANSIENT_LOCAL to receive the latched value, and VOLATILE to match a
  volatile publisher too (``ros2 bag play`` of a bag without recorded QoS offers RELIABLE, VOLATILE, depth 10); a
  transient-local publisher matches both, and the callbacks ignore the repeat.
* ``/diagnostics``: the ROS default (RELIABLE, VOLATILE, depth 10).
"""
from __future__ import annotations

import math

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from .specs import INPUT_RELIABILITY
from ..config.params import ParamError

QOS_STREAM_DEPTH = 400
QOS_STREAM_SECONDS = 40.0     # s of data a stream publisher keeps for a slow subscriber (400 x 1024 / 10,240 Hz)
QOS_LATCHED_DEPTH = 20


def _reliability(name: str):
    if name not in INPUT_RELIABILITY:
        raise ParamError(f'reliability must be one of {list(INPUT_RELIABILITY)}, got {name!r}')
    return ReliabilityPolicy.RELIABLE if name == 'reliable' else ReliabilityPolicy.BEST_EFFORT


def qos_stream(depth: int = QOS_STREAM_DEPTH, reliability: str = 'reliable'):
    """
    Return the QoS of data streams: KEEP_LAST ``depth``, VOLATILE, RELIABLE.

    ``reliability='best_effort'`` for a subscription that must also accept a best-effort publisher; see
    :func:`qos_input`.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=_reliability(reliability),
                      durability=DurabilityPolicy.VOLATILE)


def stream_depth(sample_rate: float, block_size: int) -> int:
    """
    Return the KEEP_LAST depth [blocks] that holds ``QOS_STREAM_SECONDS`` of data for a stream publisher.

    The publisher's history holds that many whole messages: a fixed 400 blocks of 8192 samples (0.8 s each) were
    320 s of data, ~80 MB that the sensor_driver kept (its RSS +100 MB over its first pass).  At least 10 blocks.
    """
    return max(10, math.ceil(QOS_STREAM_SECONDS * float(sample_rate) / max(int(block_size), 1)))


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
    quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _event: None)
    latched = node.create_subscription(msg_type, topic, callback, qos_latched(depth), event_callbacks=quiet, raw=raw)
    volatile = node.create_subscription(msg_type, topic, callback, qos_input(node, depth), raw=raw)
    return latched, volatile
