"""Publishing diagnostics: :class:`bearing_id.nodes.status.DiagItem` lists to ``diagnostic_msgs/DiagnosticArray``."""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import ReliabilityPolicy

from .machine import status_name
from .qos import input_reliability
from .status import DiagItem, WARN
from .topics import relative


INTERLEAVE = 'their blocks interleave (sequence restarts, stamps going back) -- stop all but one'


def flag_publishers(node, topic: str, item: DiagItem, consequence: str = INTERLEAVE, expected: int = 1) -> DiagItem:
    """
    WARN on ``item`` when more than ``expected`` publishers are on ``topic`` (this node's own included, if any).

    E.g. two DAQ drivers, or a bag replayed into a live system: their blocks interleave and every window breaks
    (``publishers`` is added to its values); ``consequence`` says what it does.
    """
    try:
        n = node.count_publishers(relative(topic))
    except Exception:            # noqa: BLE001 -- a graph query must never take diagnostics down
        return item
    item.values['publishers'] = n
    if n > expected and item.level < WARN:
        item.level = WARN
        item.message = f'{n} publishers on {topic}: {consequence}'
    return item


def flag_best_effort(node, topic: str, item: DiagItem) -> DiagItem:
    """
    WARN on ``item`` when a best-effort publisher on ``topic`` cannot reach this node's reliable subscription.

    A DAQ driver publishing with SensorDataQoS (BEST_EFFORT) matches no RELIABLE subscription: the node hears nothing
    and would only say "no data".  The message names the publisher and the parameter that accepts it
    (``input_reliability: best_effort``, :mod:`bearing_id.nodes.qos`).
    """
    if input_reliability(node) != 'reliable':
        return item
    try:
        infos = node.get_publishers_info_by_topic(node.resolve_topic_name(relative(topic)))
    except Exception:            # noqa: BLE001 -- a graph query must never take diagnostics down
        return item
    lost = [i for i in infos if i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT]
    if lost:
        names = sorted({f'{i.node_namespace.rstrip("/")}/{i.node_name}' for i in lost
                        if 'UNKNOWN' not in i.node_name})            # a node's name arrives after its endpoints
        item.values['best_effort_publishers'] = ', '.join(names) or str(len(lost))
        item.level = max(item.level, WARN)
        who = f" ({', '.join(names)})" if names else ''
        item.message = (f'{len(lost)} best-effort publisher(s) on {topic}{who} cannot deliver to this '
                        "node's reliable subscription: set its parameter input_reliability: best_effort (a block lost "
                        f'on the way then ends the steady window) or publish reliable; {item.message}')
    return item


def diagnostics_msg(items: list[DiagItem], stamp, hardware_id: str = '', machine: str = ''):
    """
    Build a DiagnosticArray with one status per item (values formatted with repr-precision for floats).

    ``machine``: the machine id (:mod:`bearing_id.nodes.machine`) that prefixes every status name, so that an
    aggregator keyed on the name keeps two machines' statuses apart.
    """
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    for it in items:
        st = DiagnosticStatus(level=bytes([int(it.level)]), name=status_name(machine, it.name),
                              message=str(it.message)[:1000], hardware_id=hardware_id)
        st.values = [KeyValue(key=str(k), value=_fmt(v)) for k, v in it.values.items()]
        arr.status.append(st)
    return arr


def _fmt(v) -> str:
    if isinstance(v, float):
        return f'{v:.6g}'
    return str(v)
