"""Diagnostic items without ROS: what one ``diagnostic_msgs/DiagnosticStatus`` will say (the cores build them)."""
from __future__ import annotations

from dataclasses import dataclass, field
import math

# diagnostic levels (diagnostic_msgs/DiagnosticStatus)
OK, WARN, ERROR, STALE = 0, 1, 2, 3
WARN_EVERY = 2.0      # s: a node logs at most one problem line per this (Throttle)


@dataclass
class DiagItem:
    """One DiagnosticStatus: ``name`` (e.g. 'kf_estimator: input /rotor/displacement'), level, message, values."""

    name: str
    level: int = OK
    message: str = 'ok'
    values: dict = field(default_factory=dict)


class Throttle:
    """
    At most one event per ``period`` [s] let through: the nodes' problem lines (the latest are on /diagnostics).

    ``due(now)`` [s, monotonic] returns None when this event is held back, else how many were held back since the last
    one let through; ``line(text, now)`` the log line for a problem ``text`` (None: held back), naming how many
    were.  Cheaper than rclpy's ``throttle_duration_sec``, which inspects the caller's frame on every call
    (10 % of the identifier's samples when kf_estimator's stream had a gap storm at 50x).
    """

    def __init__(self, period: float):
        self.period = float(period)
        self._last = -math.inf
        self._held = 0

    def due(self, now: float) -> int | None:
        if now - self._last < self.period:
            self._held += 1
            return None
        held, self._held, self._last = self._held, 0, float(now)
        return held

    def line(self, text: str, now: float) -> str | None:
        held = self.due(now)
        if held is None:
            return None
        return text + (f' ({held} more problem(s) not logged since the last line)' if held else '')
