"""
Forked worker processes for a command's independent fits (the 1X fit of every steady window): wall time.

* :func:`forked_map` is ``map`` for :func:`bearing_id.identify.harmonics.from_recordings`'s ``window_map``: it hands
  every (workers + 1)-th item to one of ``workers`` processes forked from this one (they inherit the function and the
  items, so nothing big is pickled but the results) and computes the rest here meanwhile.
* :func:`in_background` starts ``fn(*args)`` in one forked process now and returns a :class:`Background` whose
  ``result()`` collects it later (``diagnose`` fits identify's 1X vectors for its noise-floor check this way while it
  locates and selects effects).

The results are those of the plain call (the same code on the same inputs, bit for bit; test/test_workers.py), in
order; an exception is raised as the plain call would raise it (for a map, that of the first failing item).

Used only when it is safe and can help: a spare core (``os.sched_getaffinity``), the platform forks, and this
process runs no other thread (forking a threaded process can copy a lock held by another thread; the ROS nodes never
come here).  ``BEARING_ID_WORKERS`` (an integer, 0 = none) overrides the default of one worker per spare core, at
most 3.  Otherwise the work is done here, at the point where the plain call would do it.  A worker that dies
(killed, out of memory) or a result that does not pickle costs nothing but time: the work is redone here.
"""
from __future__ import annotations

import os
import threading

WORKERS_ENV = 'BEARING_ID_WORKERS'
MAX_DEFAULT_WORKERS = 3

_JOB: tuple | None = None     # (fn, items, step) while a map runs: what the forked workers inherit


def default_workers() -> int:
    """Return ``BEARING_ID_WORKERS`` when it is a non-negative integer, else one per spare core (at most 3)."""
    v = os.environ.get(WORKERS_ENV, '').strip()
    if v.isdigit():
        return int(v)
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(0, min(MAX_DEFAULT_WORKERS, cores - 1))


def _outcome(fn, x) -> tuple:
    """Return (True, fn(x)) or (False, the exception it raised)."""
    try:
        return True, fn(x)
    except Exception as exc:            # noqa: B902 -- handed back and re-raised in item order by forked_map
        return False, exc


def _share(k: int) -> list:
    """Return the outcomes of items k, k + step, ... of the inherited job (runs in worker k)."""
    fn, items, step = _JOB
    return [_outcome(fn, x) for x in items[k::step]]


def forked_map(fn, items, workers: int | None = None) -> list:
    """
    Return ``[fn(x) for x in items]``, items 1, 2, ... of every (workers + 1) in forked workers when worthwhile.

    ``workers``: default :func:`default_workers`.  ``fn``'s results must pickle.
    """
    global _JOB
    items = list(items)
    n = min(default_workers() if workers is None else int(workers), len(items) - 1)
    if n < 1 or threading.active_count() > 1 or _JOB is not None:
        return [fn(x) for x in items]
    try:
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool
        import multiprocessing
        ctx = multiprocessing.get_context('fork')
    except (ImportError, ValueError):             # no fork on this platform
        return [fn(x) for x in items]
    step = n + 1
    out: list = [None] * len(items)
    _JOB = (fn, items, step)
    try:
        pool = ProcessPoolExecutor(max_workers=n, mp_context=ctx)
        try:
            futures = [pool.submit(_share, k) for k in range(1, step)]     # forked here, inheriting _JOB
            for i in range(0, len(items), step):
                out[i] = _outcome(fn, items[i])
            for k, fut in enumerate(futures, 1):
                idx = range(k, len(items), step)
                try:
                    res = fut.result()
                except BrokenProcessPool:             # the worker died: its items are computed here
                    res = [_outcome(fn, items[i]) for i in idx]
                for i, r in zip(idx, res):
                    out[i] = r
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
    except OSError:                                   # the pool could not start (no processes left)
        out = [_outcome(fn, x) for x in items]
    finally:
        _JOB = None
    for ok, v in out:
        if not ok:
            raise v
    return [v for _, v in out]


def _may_fork() -> bool:
    """Return True when this process may fork a worker now (a spare core, no other thread, no map running)."""
    return default_workers() >= 1 and threading.active_count() == 1 and _JOB is None


def _background_child(conn, fn, args) -> None:
    """Run ``fn(*args)`` in the forked worker and send (ok, result or exception) back."""
    try:
        out = _outcome(lambda a: fn(*a), args)
        try:
            conn.send(out)
        except Exception:               # noqa: B902 -- an unpicklable result: the parent computes it itself
            pass
    finally:
        conn.close()


class Background:
    """
    ``fn(*args)`` computed in a process forked by :func:`in_background`, or here when ``result()`` is first called.

    ``result()`` returns it (or raises its exception); ``close()`` stops a worker whose result is not wanted any more
    (the command failed before it needed it).  Use as a context manager to close it in any case.
    """

    def __init__(self, fn, args: tuple, fork: bool):
        self._fn, self._args = fn, args
        self._proc = self._conn = None
        self._have = None                               # (ok, value) once known
        self.forked = False                             # True when the work runs (or ran) in a forked worker
        if fork:
            try:
                import multiprocessing
                ctx = multiprocessing.get_context('fork')
                self._conn, child = ctx.Pipe(duplex=False)
                self._proc = ctx.Process(target=_background_child, args=(child, fn, args), daemon=True)
                self._proc.start()                      # forked here: fn and args are inherited, not pickled
                child.close()
                self.forked = True
            except (ImportError, ValueError, OSError):     # no fork on this platform, or no process left
                self._proc = self._conn = None

    def result(self):
        """Return ``fn(*args)`` (waiting for the worker), or raise what it raised."""
        if self._have is None:
            if self._proc is not None:
                try:
                    self._have = self._conn.recv()
                except (EOFError, OSError):            # the worker died or its result did not pickle: do it here
                    pass
                self.close()
            if self._have is None:
                self._have = _outcome(lambda a: self._fn(*a), self._args)
        ok, v = self._have
        if not ok:
            raise v
        return v

    def close(self) -> None:
        """Stop the worker if it still runs; release the pipe."""
        if self._proc is not None:
            if self._proc.is_alive() and self._have is None:
                self._proc.kill()
            self._proc.join()
            self._conn.close()
            self._proc.close()
            self._proc = self._conn = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def in_background(fn, *args) -> Background:
    """Start ``fn(*args)`` in a forked worker when that is safe and a core is spare; see :class:`Background`."""
    return Background(fn, args, _may_fork())


__all__ = ['forked_map', 'in_background', 'Background', 'default_workers', 'WORKERS_ENV']
