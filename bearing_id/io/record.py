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

import fcntl
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


LOCK_NAME = 'record.lock'


class RecordInUse(ValueError):
    """The record directory is held by another writer (another identifier process)."""


def lock_record(directory: str | Path):
    """
    Take the record directory for this process: an exclusive, non-blocking ``flock`` on ``<directory>/record.lock``.

    Returns the open lock file (keep it open; the lock ends with it or with the process, also on kill -9).  Raises
    :class:`RecordInUse` naming the directory and the holder's pid when another process holds it: two writers on one
    record interleave their line numbers and each resumes the other's vectors.
    """
    d = Path(directory).expanduser()
    d.mkdir(parents=True, exist_ok=True)
    fh = open(d / LOCK_NAME, 'a+', encoding='utf-8')
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        fh.seek(0)
        holder = fh.read().strip() or 'unknown'
        fh.close()
        raise RecordInUse(f'the record {d} is in use by another identifier (pid {holder}); give each identifier its '
                          'own record_dir (the default is one per namespace and node name)') from None
    fh.seek(0)
    fh.truncate()
    fh.write(str(os.getpid()))
    fh.flush()
    return fh


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
        self.lines = len(existing) + self.torn_lines      # lines in the file (what compaction bounds)
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
        return self.append_many(type_, [payload])[0]

    def append_many(self, type_: str, payloads: list[dict]) -> list[int]:
        """
        Append one entry of ``type_`` per payload, in order, made durable together (one flush and fsync); return n's.

        Each line is complete on its own: a crash part-way keeps the lines before it (and a torn last one, which
        :meth:`entries` skips and the next start terminates).
        """
        with self._lock:      # callbacks and the identifier's worker thread both append
            out = []
            for payload in payloads:
                line = json.dumps({'n': self._n, 'type': type_, 'wall_time': time.time(), **encode(payload)},
                                  separators=(',', ':'), allow_nan=False)
                self._fh.write(line + '\n')
                out.append(self._n)
                self._n += 1
                self.lines += 1
            self._fh.flush()
            if self.fsync and out:
                os.fsync(self._fh.fileno())
            return out

    def rewrite(self, entries: list[dict]) -> None:
        """
        Replace the file by ``entries`` (decoded, as :meth:`entries` returns them; each keeps its ``n``).

        Atomic: a temporary file is written and fsync'ed, then renamed over the record (a crash leaves the old or the
        new file whole).  Appends wait meanwhile; later ones continue the numbering.
        """
        with self._lock:
            tmp = self.path.with_name(self.path.name + '.tmp')
            with open(tmp, 'w', encoding='utf-8') as fh:
                for e in entries:
                    fh.write(json.dumps(encode(e), separators=(',', ':'), allow_nan=False) + '\n')
                fh.flush()
                os.fsync(fh.fileno())
            self._fh.close()
            os.replace(tmp, self.path)
            dfd = os.open(self.directory, os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
            self._fh = open(self.path, 'a', encoding='utf-8')
            self.lines = len(entries)

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
