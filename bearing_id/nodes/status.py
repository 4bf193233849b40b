"""Diagnostic items without ROS: what one ``diagnostic_msgs/DiagnosticStatus`` will say (the cores build them)."""
from __future__ import annotations

from dataclasses import dataclass, field

# diagnostic levels (diagnostic_msgs/DiagnosticStatus)
OK, WARN, ERROR, STALE = 0, 1, 2, 3


@dataclass
class DiagItem:
    """One DiagnosticStatus: ``name`` (e.g. 'kf_estimator: input /rotor/displacement'), level, message, values."""

    name: str
    level: int = OK
    message: str = 'ok'
    values: dict = field(default_factory=dict)
