"""
Forked workers for the window fits (bearing_id.commands.workers, issue 13): the results of the plain loop, bit for bit.

Reference: the built-in ``map`` / list comprehension on the same function and items.  Also: work really runs in
another process (pids), an exception is that of the first failing item in item order, a worker that dies costs no
result, and no fork happens with another thread alive or with BEARING_ID_WORKERS=0.
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
    """Return a result that depends on the item only, and the pid that computed it."""
    rng = np.random.default_rng(i)
    A = rng.standard_normal((200, 6))
    return np.linalg.qr(A, mode='r'), os.getpid()


def test_results_equal_the_loop_and_come_from_a_worker():
    items = list(range(7))
    got = forked_map(_work, items, workers=1)
    ref = [_work(i) for i in items]
    assert len(got) == len(ref)
    for (r1, _), (r0, _) in zip(got, ref):
        assert np.array_equal(r1, r0)
    pids = [p for _, p in got]
    assert all(pids[i] == PARENT for i in range(0, 7, 2))        # items 0, 2, ... here
    assert all(pids[i] != PARENT for i in range(1, 7, 2))        # items 1, 3, ... in the worker


def _fail_on(i):
    if i in (2, 3):
        raise ValueError(f'item {i} is bad')
    return i


def test_the_first_failing_item_in_order_is_raised():
    # item 3 fails here (this process takes 0, 3) and item 2 in a worker (2 workers: 1, 4 / 2, 5): 2 comes first
    with pytest.raises(ValueError, match='item 2 is bad'):
        forked_map(_fail_on, range(6), workers=2)


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
    from bearing_id.params import load_rig
    from bearing_id.rig import simulate_run
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


def _pid_and(x):
    return os.getpid(), x * 2


def _raise_value_error(msg):
    raise ValueError(msg)


def _unpicklable():
    return lambda: os.getpid()                      # a lambda does not pickle: redone here


def test_a_background_job_runs_in_a_worker_and_gives_the_plain_result():
    with workers.in_background(_pid_and, 21) as bg:
        assert bg.forked
        pid, v = bg.result()
    assert v == 42 and pid != PARENT
    assert bg.result() == (pid, 42)                 # kept once collected


def test_a_background_exception_is_raised_by_result():
    with workers.in_background(_raise_value_error, 'no steady window') as bg:
        with pytest.raises(ValueError, match='no steady window'):
            bg.result()


def test_an_unpicklable_background_result_is_computed_here():
    with workers.in_background(_unpicklable) as bg:
        assert bg.forked
        assert bg.result()() == PARENT


def test_close_stops_a_background_job_not_needed_any_more():
    import time
    bg = workers.in_background(time.sleep, 60.0)
    assert bg.forked
    t0 = time.perf_counter()
    bg.close()
    assert time.perf_counter() - t0 < 5.0


def test_no_background_fork_with_another_thread_alive_or_workers_off(monkeypatch):
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
