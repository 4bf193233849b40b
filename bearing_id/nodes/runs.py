"""
Which excitation run a displacement block belongs to, for the kf_estimator and the identifier (no ROS).

A block names its run (``DisplacementBlock.run_id``, set by the sensor_driver) or, when the sender leaves it empty,
belongs to the run announced last on /rotor/excitation at or before its stamp.  A block whose run is not known yet
(its Excitation is still on the way, or the node started in the middle of a run) is not dropped: it waits, in
arrival order, until the run is announced (blocks of one run keep their order: while a run is unknown, all of its
blocks wait) (at most ``max_waiting`` blocks; beyond that the oldest is dropped and
counted, and /diagnostics says so).
"""
from __future__ import annotations

from collections import deque
import threading
from typing import Any

from ..io.messages import excitation_from_msg

#: what converting a hostile message can raise (reported and dropped by the callbacks, never raised out of them)
MALFORMED = (ValueError, TypeError, AttributeError, OverflowError, IndexError)


def stamp_to_sec(stamp) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


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


def excitation_of(msg, n_nodes: int | None = None):
    """
    Return (stamp [s], params.Run) of an Excitation message, validated.

    Validated by :func:`bearing_id.io.messages.check_excitation` with the model's ``n_nodes``; raises one of
    :data:`MALFORMED` saying what is wrong.
    """
    run = excitation_from_msg(msg, n_nodes)
    return stamp_to_sec(msg.header.stamp), run


class RunResolver:
    """
    Match blocks to the excitation runs announced for them.

    ``resolve(block, tag)`` -> the block's params.Run, or None when it was queued (with ``tag``, e.g. the block's
    contiguity) to wait for its announcement; ``announce(stamp, run)`` registers a run and returns the waiting [(block,
    run, tag)] it releases (in arrival order).

    ``block`` needs ``run_id`` ('' = by stamp) and ``stamp`` [s].  ``known`` maps run id -> Run.
    """

    def __init__(self, max_waiting: int = 400):
        self.timeline = ExcitationTimeline()
        self.known: dict = {}
        self.waiting: deque = deque()
        self.max_waiting = int(max_waiting)
        self.dropped = 0          # blocks that waited too long (queue overflow)
        self.released = 0         # blocks that waited and were then assigned

    def announce(self, stamp: float, run) -> tuple[bool, list]:
        """Register ``run`` starting at ``stamp`` [s]: (new announcement?, [(block, run, tag)] released)."""
        new = self.timeline.add(stamp, run)
        self.known.setdefault(run.id, run)
        out, keep = [], deque()
        while self.waiting:
            b, tag = self.waiting.popleft()
            r = self._lookup(b)
            if r is None:
                keep.append((b, tag))
            else:
                out.append((b, r, tag))
        self.waiting = keep
        self.released += len(out)
        return new, out

    def _lookup(self, block):
        rid = getattr(block, 'run_id', '') or ''
        if rid:
            return self.known.get(rid)
        return self.timeline.at(block.stamp)

    def resolve(self, block, tag=None):
        """Return the block's run, or None (the block now waits, with ``tag``; see ``waiting``)."""
        run = self._lookup(block)
        if run is not None:
            return run
        self.waiting.append((block, tag))
        if len(self.waiting) > self.max_waiting:
            self.waiting.popleft()
            self.dropped += 1
        return None

    def __len__(self):
        return len(self.known)
