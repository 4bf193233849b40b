"""
Topic names of the bearing_id nodes and how a node creates them (no ROS).

The ``TOPIC_*`` constants are the names in the root namespace (what bags store and ``bearing-id play/record`` use);
the nodes create their topics with :func:`relative` names, so a namespace (``--ros-args -r __ns:=/rig1``) moves them
to ``/rig1/rotor/displacement`` etc.  ``/diagnostics`` stays absolute (the ROS convention: one aggregated topic).
Params files use the ``/**:`` key, so they apply to a node in any namespace.
"""
from __future__ import annotations

# Names in the root namespace (bags, play/record, diagnostics texts); nodes create them as relative(TOPIC_...).
TOPIC_DISPLACEMENT = '/rotor/displacement'
TOPIC_SPEED = '/rotor/speed'
TOPIC_EXCITATION = '/rotor/excitation'
TOPIC_OIL_TEMPERATURE = '/rotor/oil_temperature'
TOPIC_BEARING_DISPLACEMENT = '/bearing_id/bearing_displacement'
TOPIC_INNOVATION = '/bearing_id/innovation'
TOPIC_COEFFICIENTS = '/bearing_id/coefficients'
TOPIC_ALARMS = '/bearing_id/alarms'
TOPIC_DIAGNOSTICS = '/diagnostics'


def relative(topic: str) -> str:
    """
    Return the name a node creates ``topic`` with: relative, so it resolves in the node's namespace.

    ``/rotor/displacement`` -> ``rotor/displacement``, i.e. ``/rig1/rotor/displacement`` under ``__ns:=/rig1`` and
    unchanged in the root namespace.  ``/diagnostics`` stays absolute.
    """
    return topic if topic == TOPIC_DIAGNOSTICS else topic.lstrip('/')
