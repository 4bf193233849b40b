"""
Forked workers for the window fits (bearing_id.commands.workers, issue 13): the results of the plain loop, bit for bit.

Reference: the built-in ``map`` / list comprehension on the same function and items.  Also: work really runs in
another process (pids), an exception is that of the first failing item in item order with this process's traceback
(an item that failed in a worker is redone here), a worker that dies costs no result, workers never fork again, ignore
Ctrl-C and die with their parent, and no fork happens with another thread alive or with BEARING_ID_WORKERS=0.
"""
import os
import threading

from bearing_id.commands import workers
from bearing_id.commands.workers import forked_map
from bearing_id.identify import harmonics
import numpy as np
import pytest

PARENT = os.getpid()


def _work(i):
    """Return a result that depends on the item only, and the pid that computed it (slow enough to be shared)."""
    import time
    time.sleep(0.03)
    rng = np.random.default_rng(i)
    A = rng.standard_normal((200, 6))
    return np.linalg.qr(A, mode='r'), os.getpid()


def test_results_equal_the_loop_and_come_from_a_worker():
    items = list(range(9))
    got = forked_map(_work, items, workers=1)
    ref = [_work(i) for i in items]
    assert len(got) == len(ref)
    for (r1, _), (r0, _) in zip(got, ref):
        assert np.array_equal(r1, r0)
    pids = [p for _, p in got]
    assert PARENT in pids and len(set(pids)) == 2       # shared between this process and one worker


def _fail_on(i):
    if i in (2, 3):
        raise ValueError(f'item {i} is bad')
    return i


def test_the_first_failing_item_in_order_is_raised_with_a_traceback_from_here():
    for _ in range(3):              # whichever process took items 2 and 3
        with pytest.raises(ValueError, match='item 2 is bad') as info:
            forked_map(_slow_fail_on, range(8), workers=2)
        tb = info.value.__traceback__
        while tb.tb_next is not None:
            tb = tb.tb_next
        assert tb.tb_frame.f_code.co_name == '_fail_on'     # not forked_map: the item was redone here


def _slow_fail_on(i):
    import time
    time.sleep(0.02)
    return _fail_on(i)


def _fail_in_worker(i):
    """Return i here; raise in a worker (what a worker-only fault looks like: redone here, so no error)."""
    import time
    time.sleep(0.03)
    if os.getpid() != PARENT:
        raise RuntimeError('worker-only fault')
    return i


def test_an_item_that_failed_in_a_worker_is_redone_here():
    assert forked_map(_fail_in_worker, range(9), workers=1) == list(range(9))


def _die_in_worker(i):
    if os.getpid() != PARENT:
        os._exit(3)
    return i * i


def test_a_worker_that_dies_costs_no_result():
    assert forked_map(_die_in_worker, range(5), workers=1) == [i * i for i in range(5)]


def test_no_fork_with_another_thread_alive_or_workers_off(monkeypatch):
    stop = threading.Event()
    th = threading.Thread(target=stop.wait)
    th.start()
    try:
        assert {p for _, p in forked_map(_work, range(4), workers=1)} == {PARENT}
    finally:
        stop.set()
        th.join()
    monkeypatch.setenv(workers.WORKERS_ENV, '0')
    assert workers.default_workers() == 0
    assert {p for _, p in forked_map(_work, range(4))} == {PARENT}
    monkeypatch.setenv(workers.WORKERS_ENV, '2')
    assert workers.default_workers() == 2


def test_from_recordings_with_forked_workers_equals_the_plain_route():
    """The 1X extraction the commands run (windows fitted in a worker) equals from_recordings' own loop, bit for bit."""
    from bearing_id.config.params import load_rig
    from bearing_id.simulation.rig import simulate_run
    rig = load_rig()
    recs = [simulate_run(rig, run, speeds_rpm=[1200, 1800], dwell=1.2, ramp=0.3) for run in rig.simulation.runs[:2]]
    ref = harmonics.from_recordings(recs)
    got = harmonics.from_recordings(recs, window_map=lambda fn, xs: forked_map(fn, xs, workers=1))
    assert np.array_equal(got.speeds, ref.speeds)
    assert np.array_equal(got.X, ref.X) and np.array_equal(got.X_std, ref.X_std)
    assert got.windows == ref.windows
    for name in ('X', 'var_re', 'var_im', 'noise_var'):
        assert np.array_equal(getattr(got.plain, name), getattr(ref.plain, name))
    assert ref.X.shape[:2] == (2, 2)


@pytest.fixture
def one_worker(monkeypatch):
    """BEARING_ID_WORKERS=1: a worker even on a machine without a spare core (the default would be none there)."""
    monkeypatch.setenv(workers.WORKERS_ENV, '1')


def _pid_and(x):
    return os.getpid(), x * 2


def _raise_value_error(msg):
    raise ValueError(msg)


def _unpicklable():
    return lambda: os.getpid()                      # a lambda does not pickle: redone here


def test_a_background_job_runs_in_a_worker_and_gives_the_plain_result(one_worker):
    with workers.in_background(_pid_and, 21) as bg:
        assert bg.forked
        pid, v = bg.result()
    assert v == 42 and pid != PARENT
    assert bg.result() == (pid, 42)                 # kept once collected


def test_a_background_exception_is_raised_by_result(one_worker):
    with workers.in_background(_raise_value_error, 'no steady window') as bg:
        with pytest.raises(ValueError, match='no steady window'):
            bg.result()


def test_an_unpicklable_background_result_is_computed_here(one_worker):
    with workers.in_background(_unpicklable) as bg:
        assert bg.forked
        assert bg.result()() == PARENT


def test_close_stops_a_background_job_not_needed_any_more(one_worker):
    import time
    bg = workers.in_background(time.sleep, 60.0)
    assert bg.forked
    t0 = time.perf_counter()
    bg.close()
    assert time.perf_counter() - t0 < 5.0


def test_no_background_fork_with_another_thread_alive_or_workers_off(one_worker, monkeypatch):
    stop = threading.Event()
    th = threading.Thread(target=stop.wait)
    th.start()
    try:
        bg = workers.in_background(_pid_and, 1)
        assert not bg.forked and bg.result() == (PARENT, 2)
    finally:
        stop.set()
        th.join()
    monkeypatch.setenv(workers.WORKERS_ENV, '0')
    bg = workers.in_background(_pid_and, 1)
    assert not bg.forked and bg.result() == (PARENT, 2)


def _nested(n):
    return forked_map(_pid_and, range(n), workers=1), os.getpid()


def test_no_nested_fork_inside_a_worker(one_worker):
    with workers.in_background(_nested, 4) as bg:
        assert bg.forked
        res, pid = bg.result()
    assert pid != PARENT and [v for _, v in res] == [0, 2, 4, 6] and {p for p, _ in res} == {pid}


WATCHED = r"""
import os, sys, time
sys.path.insert(0, {root!r})
from bearing_id.commands.workers import forked_map, in_background
def slow(i):
    print('PID', os.getpid(), flush=True)
    time.sleep(60)
bg = in_background(slow, 0)
forked_map(slow, range(4), workers=1)
"""


def test_workers_die_with_their_parent_and_ignore_ctrl_c(tmp_path):
    """Kill the command (SIGKILL): its forked workers go too (PR_SET_PDEATHSIG); they ignore SIGINT."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path
    root = str(Path(__file__).resolve().parent.parent)
    env = dict(os.environ, BEARING_ID_WORKERS='1')
    p = subprocess.Popen([sys.executable, '-c', WATCHED.format(root=root)], stdout=subprocess.PIPE, text=True,
                         env=env)
    pids = set()
    t0 = time.monotonic()
    while len(pids) < 3 and time.monotonic() - t0 < 30:      # the background worker, this process, the map worker
        line = p.stdout.readline()
        if line.startswith('PID '):
            pids.add(int(line.split()[1]))
    assert len(pids) == 3 and p.pid in pids, pids
    kids = pids - {p.pid}
    for k in kids:
        os.kill(k, signal.SIGINT)                              # ignored by the workers
    time.sleep(0.3)
    assert all(_alive(k) for k in kids)
    p.kill()
    p.wait(timeout=10)
    t0 = time.monotonic()
    while any(_alive(k) for k in kids) and time.monotonic() - t0 < 10:
        time.sleep(0.05)
    assert not any(_alive(k) for k in kids)


def _alive(pid: int) -> bool:
    """Return True while ``pid`` runs (a zombie counts as gone)."""
    try:
        with open(f'/proc/{pid}/stat') as fh:
            return fh.read().split(') ')[-1].split()[0] != 'Z'
    except OSError:
        return False
