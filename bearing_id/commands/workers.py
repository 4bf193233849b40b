"""
Forked worker processes for a command's independent fits (the 1X fit of every steady window): wall time.

* :func:`forked_map` is ``map`` for :func:`bearing_id.identify.harmonics.from_recordings`'s ``window_map``: this
  process and ``workers`` processes forked from it (they inherit the function and the items, so nothing big is
  pickled but the results) take the items one at a time from a shared counter until none is left (long and short
  windows balance themselves).
* :func:`in_background` starts ``fn(*args)`` in one forked process now and returns a :class:`Background` whose
  ``result()`` collects it later (``diagnose`` fits identify's 1X vectors for its noise-floor check this way while it
  locates and selects effects).

The results are those of the plain call (the same code on the same inputs, bit for bit; test/test_workers.py), in
order; an exception is raised as the plain call would raise it (for a map, that of the first failing item).

Used only when it is safe and can help: a spare core (CPU affinity and the cgroup's CPU quota), the platform forks,
this process runs no other thread (forking a threaded process can copy a lock held by another thread; the ROS nodes
never come here) and is not itself a worker.  ``BEARING_ID_WORKERS`` (an integer, 0 = none) overrides the default of
one worker per spare core, at most 3.  Otherwise the work is done here, at the point where the plain call would do
it.  A worker that dies (killed, out of memory) or a result that does not pickle costs nothing but time: the work is
redone here; so is an item that failed in a worker, so that its exception carries this process's traceback.  Workers
ignore Ctrl-C (this process stops them) and are killed by the kernel when this process dies (``PR_SET_PDEATHSIG``).
"""
from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
import math
import multiprocessing
import os
import signal
import threading

WORKERS_ENV = 'BEARING_ID_WORKERS'
MAX_DEFAULT_WORKERS = 3

_JOB: tuple | None = None     # (fn, items, counter) while a map runs: what the forked workers inherit
_PARENT: int | None = None    # the pid that forked the workers
_IN_WORKER = False            # True in a forked worker: it never forks again


def _cores() -> int:
    """Return the cores this process may use: its CPU affinity, capped by a cgroup CPU quota (containers)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    quota = None
    try:
        with open('/sys/fs/cgroup/cpu.max') as fh:                 # cgroup v2: "quota period" or "max period"
            q, per = fh.read().split()[:2]
        if q != 'max':
            quota = float(q) / float(per)
    except (OSError, ValueError):
        try:                                                        # cgroup v1
            with open('/sys/fs/cgroup/cpu/cpu.cfs_quota_us') as fh:
                q = float(fh.read())
            with open('/sys/fs/cgroup/cpu/cpu.cfs_period_us') as fh:
                per = float(fh.read())
            if q > 0 and per > 0:
                quota = q / per
        except (OSError, ValueError):
            pass
    if quota is not None and quota > 0:
        cores = min(cores, max(1, math.ceil(quota)))
    return cores


def default_workers() -> int:
    """Return ``BEARING_ID_WORKERS`` when it is a non-negative integer, else one per spare core (at most 3)."""
    v = os.environ.get(WORKERS_ENV, '').strip()
    if v.isdigit():
        return int(v)
    return max(0, min(MAX_DEFAULT_WORKERS, _cores() - 1))


def _may_fork() -> bool:
    """Return True when this process may fork workers now: no other thread, not a worker, no map running."""
    return threading.active_count() == 1 and not _IN_WORKER and _JOB is None


def worker_setup() -> None:
    """
    In a forked worker: never fork again, leave Ctrl-C to the parent, die with the parent.

    The initializer of every worker pool a command forks (also the report's figure workers).
    """
    global _IN_WORKER
    _IN_WORKER = True
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))   # PR_SET_PDEATHSIG (Linux)
    except (OSError, AttributeError):
        pass
    if _PARENT is not None and os.getppid() != _PARENT:                   # the parent died before the prctl
        os._exit(1)


def _outcome(fn, x) -> tuple:
    """Return (True, fn(x)) or (False, the exception it raised)."""
    try:
        return True, fn(x)
    except Exception as exc:            # noqa: B902 -- handed back, then raised as the plain call would raise it
        return False, exc


def _take(counter, n: int):
    """Return the next item index of the shared counter, or None when all ``n`` are taken."""
    with counter.get_lock():
        i = counter.value
        counter.value = i + 1
    return i if i < n else None


def _share() -> list:
    """Return [(index, outcome)] of the items this worker took from the inherited job's counter."""
    fn, items, counter = _JOB
    out = []
    while (i := _take(counter, len(items))) is not None:
        out.append((i, _outcome(fn, items[i])))
    return out


def forked_map(fn, items, workers: int | None = None) -> list:
    """
    Return ``[fn(x) for x in items]``, shared with ``workers`` forked processes when that is safe and worthwhile.

    ``workers``: default :func:`default_workers`.  Every item is computed before an exception is raised (that of
    the first failing item, with this process's traceback).
    """
    global _JOB, _PARENT
    items = list(items)
    n = min(default_workers() if workers is None else int(workers), len(items) - 1)
    if n < 1 or not _may_fork():
        return [fn(x) for x in items]
    try:
        ctx = multiprocessing.get_context('fork')
        counter = ctx.Value('q', 0)
    except (ImportError, ValueError, OSError):        # no fork on this platform
        return [fn(x) for x in items]
    out: list = [None] * len(items)
    here = set()
    _JOB, _PARENT = (fn, items, counter), os.getpid()
    try:
        pool = ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=worker_setup)
        try:
            futures = [pool.submit(_share) for _ in range(n)]             # forked here, inheriting _JOB
            while (i := _take(counter, len(items))) is not None:
                out[i] = _outcome(fn, items[i])
                here.add(i)
            for fut in futures:
                try:
                    for i, r in fut.result():
                        out[i] = r
                except Exception:     # noqa: B902 -- the worker died or its results did not pickle: redone below
                    pass
        except BaseException:
            with counter.get_lock():                  # interrupted: the workers stop after their current item
                counter.value = len(items)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
    except OSError:                                   # the pool could not start (no processes left)
        pass
    finally:
        _JOB = _PARENT = None
    for i, r in enumerate(out):
        if r is None or (not r[0] and i not in here):
            out[i] = r = _outcome(fn, items[i])       # lost, or failed in a worker: here (this process's traceback)
        if not r[0]:
            raise r[1]
    return [v for _, v in out]


def _background_child(conn, other, fn, args) -> None:
    """Run ``fn(*args)`` in the forked worker and send (ok, result or exception) back."""
    worker_setup()
    other.close()                                     # the parent's end: EOF there if this process dies
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

    ``result()`` returns it (or raises its exception, recomputed here so that it carries this process's traceback);
    ``close()`` stops a worker whose result is not wanted any more (the command failed before it needed it).  Use as
    a context manager to close it in any case.
    """

    def __init__(self, fn, args: tuple, fork: bool):
        global _PARENT
        self._fn, self._args = fn, args
        self._proc = self._conn = None
        self._have = None                               # (ok, value) once known
        self.forked = False                             # True when the work runs (or ran) in a forked worker
        if fork:
            try:
                ctx = multiprocessing.get_context('fork')
                self._conn, child = ctx.Pipe(duplex=False)
                _PARENT = os.getpid()
                self._proc = ctx.Process(target=_background_child, args=(child, self._conn, fn, args), daemon=True)
                self._proc.start()                      # forked here: fn and args are inherited, not pickled
                child.close()
                self.forked = True
            except (ImportError, ValueError, OSError, AssertionError):     # no fork here, or no process left
                self._proc = self._conn = None
            finally:
                _PARENT = None

    def result(self):
        """Return ``fn(*args)`` (waiting for the worker), or raise what it raised."""
        if self._have is None:
            if self._proc is not None:
                try:
                    ok, v = self._conn.recv()
                    if ok:
                        self._have = (ok, v)
                except Exception:     # noqa: B902 -- died, or its result or exception did not pickle: do it here
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
    return Background(fn, args, default_workers() >= 1 and _may_fork())


__all__ = ['forked_map', 'in_background', 'Background', 'default_workers', 'worker_setup', 'WORKERS_ENV']
