"""Checks of an incoming stream of displacement blocks and the counters /diagnostics reports (no ROS)."""
from __future__ import annotations

from dataclasses import dataclass
import math
import threading
import time

import numpy as np

from .status import DiagItem, OK, STALE, WARN
from ..io.messages import SAMPLE_RATE_RANGE


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
