"""
Append-only on-disk record (JSON lines) of what the identifier accumulated and concluded.

One file, ``<directory>/record.jsonl``; each line one JSON object with a ``type`` (e.g. ``"vector"`` for an
accumulated harmonic vector, ``"result"`` for a published identification, ``"excitation"``, ``"session"``) and a
monotonically increasing ``n``.  Lines are only ever appended and flushed (and fsync'ed) one by one, so a crash
loses at most the line being written; :meth:`Record.entries` skips a torn last line and reports it.

Complex numbers and numpy arrays are stored as ``{"re": ..., "im": ...}`` / nested lists and restored by
:func:`decode`.  SI units, as everywhere inside (speed in rad/s, displacements in m).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import threading
import time

import numpy as np

RECORD_NAME = 'record.jsonl'


def encode(obj):
    """JSON-ready copy of ``obj``: complex -> {"re", "im"}, arrays -> lists, NaN kept as null-free strings."""
    if isinstance(obj, dict):
        return {str(k): encode(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [encode(v) for v in obj]
    if isinstance(obj, np.ndarray):
        if np.iscomplexobj(obj):
            return {'__complex__': True, 're': encode(obj.real.tolist()), 'im': encode(obj.imag.tolist())}
        return encode(obj.tolist())
    if isinstance(obj, (complex, np.complexfloating)):
        return {'__complex__': True, 're': _f(obj.real), 'im': _f(obj.imag)}
    if isinstance(obj, (np.floating, float)):
        return _f(float(obj))
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def _f(x: float):
    x = float(x)
    if x != x:
        return 'nan'
    if x in (float('inf'), float('-inf')):
        return 'inf' if x > 0 else '-inf'
    return x


def _unf(x):
    if isinstance(x, str) and x in ('nan', 'inf', '-inf'):
        return float(x)
    if isinstance(x, list):
        return [_unf(v) for v in x]
    return x


def decode(obj):
    """Inverse of :func:`encode` (complex arrays come back as numpy complex arrays)."""
    if isinstance(obj, dict):
        if obj.get('__complex__'):
            re, im = _unf(obj['re']), _unf(obj['im'])
            if isinstance(re, list):
                return np.asarray(re, dtype=float) + 1j * np.asarray(im, dtype=float)
            return complex(float(re), float(im))
        return {k: decode(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [decode(v) for v in obj]
    return _unf(obj)


class Record:
    """
    The append-only record in ``directory`` (created if missing).

    ``append(type, **payload)`` writes one line and returns its number ``n``; ``entries()`` reads every complete line
    back (decoded), in order.  ``fsync`` makes each line durable before ``append`` returns (default on).
    """

    def __init__(self, directory: str | Path, fsync: bool = True):
        self.directory = Path(directory).expanduser()
        self.directory.mkdir(parents=True, exist_ok=True)
        self.path = self.directory / RECORD_NAME
        self.fsync = fsync
        self.torn_lines = 0
        existing = self.entries()
        self._lock = threading.Lock()
        self._n = (existing[-1]['n'] + 1) if existing else 0
        self._repair_tail()
        self._fh = open(self.path, 'a', encoding='utf-8')

    def _repair_tail(self):
        """Terminate a torn last line (crash mid-write) so the next line starts cleanly; it stays in the file."""
        if self.path.exists() and self.path.stat().st_size:
            with open(self.path, 'rb') as fh:
                fh.seek(-1, os.SEEK_END)
                last = fh.read(1)
            if last != b'\n':
                with open(self.path, 'a', encoding='utf-8') as fh:
                    fh.write('\n')

    def append(self, type_: str, **payload) -> int:
        """Append one entry of ``type_`` with ``payload`` (JSON-encodable after :func:`encode`); returns its n."""
        with self._lock:      # callbacks and the identifier's worker thread both append
            n = self._n
            line = json.dumps({'n': n, 'type': type_, 'wall_time': time.time(), **encode(payload)},
                              separators=(',', ':'), allow_nan=False)
            self._fh.write(line + '\n')
            self._fh.flush()
            if self.fsync:
                os.fsync(self._fh.fileno())
            self._n += 1
            return n

    def entries(self, type_: str | None = None) -> list[dict]:
        """Every complete entry (decoded), oldest first; lines that do not parse are counted in ``torn_lines``."""
        out = []
        self.torn_lines = 0
        if not self.path.exists():
            return out
        with open(self.path, encoding='utf-8', errors='replace') as fh:
            for line in fh:
                line = line.strip()
                if not line:
                    continue
                try:
                    d = json.loads(line)
                except json.JSONDecodeError:
                    self.torn_lines += 1
                    continue
                if not isinstance(d, dict) or 'type' not in d or 'n' not in d:
                    self.torn_lines += 1
                    continue
                if type_ is None or d['type'] == type_:
                    out.append(decode(d))
        return out

    def close(self):
        if not self._fh.closed:
            self._fh.flush()
            self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
