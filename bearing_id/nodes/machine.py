"""
Which machine a node serves, without ROS: its id (in diagnostics and results) and the identifier's record location.

Many machines share one DDS domain, each with its three nodes under its own namespace (``__ns:=/machine1``).  The
machine id is the ``machine_id`` parameter, else the namespace without its leading slash (``/plant/c101`` ->
``plant/c101``); in the root namespace there is none (a single machine: status names and ids as before, the rig name
as hardware_id and frame_id).  The identifier's record goes to a directory of its own per namespace and node name
(:func:`record_dir`), so two machines never append to one record with default parameters.
"""
from __future__ import annotations

from pathlib import Path


RECORD_BASE = '~/.ros/bearing_id_record'     # the record of the identifier in the root namespace (as before)


def machine_id(param: str, namespace: str) -> str:
    """Return the machine id: ``param`` if given, else the ``namespace`` without its leading slash ('' at the root)."""
    return str(param).strip() or str(namespace or '/').strip('/')


def label(machine: str, rig_name: str) -> str:
    """Return the name that identifies the machine to others (hardware_id, frame_id): its id, else the rig name."""
    return machine or rig_name


def status_name(machine: str, name: str) -> str:
    """Return a /diagnostics status name for the machine: ``machine1/identifier: accumulation`` (unprefixed at root)."""
    return f'{machine}/{name}' if machine else name


def record_dir(param: str, namespace: str, node_name: str) -> Path:
    """
    Return the identifier's record directory: ``param`` if given, else one per namespace and node name.

    ``~/.ros/bearing_id_record`` for the node ``identifier`` in the root namespace (where every earlier version kept
    it), else ``~/.ros/bearing_id_record/<namespace>/<node name>`` (``/machine2`` -> ``.../machine2/identifier``).
    """
    if str(param).strip():
        return Path(param).expanduser()
    parts = [p for p in str(namespace or '/').split('/') if p]
    base = Path(RECORD_BASE).expanduser()
    if not parts and node_name == 'identifier':
        return base
    return base.joinpath(*parts, node_name)
