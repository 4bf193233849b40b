"""
A node's process: command line, start-up, the spin loop, a clean stop on SIGINT/SIGTERM, and a bounded teardown.

:func:`run_node` builds the node (a parameter error is one line naming the parameter, exit 2), spins until a signal
or the node's ``finished``, runs the node's ``close()`` (records flushed, workers stopped), then tears the middleware
down under a watchdog (Fast DDS can hang there: the process then exits without it, nothing lost).
"""
from __future__ import annotations

import argparse
import faulthandler
import os
import signal
import sys
import threading
import traceback

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from .specs import help_epilog, ParamSpec, with_common
from ..config.params import ParamError


class StopInStartup(Exception):
    """Raised in the main thread by a SIGINT/SIGTERM that arrives while the node is still being built."""


class StopFlag:
    """
    Set by SIGINT/SIGTERM; the spin loop polls it.

    While ``starting`` is True (the node's constructor may simulate or load data for seconds) a signal also raises
    :class:`StopInStartup`, so start-up is abandoned at once.
    """

    def __init__(self):
        self.event = threading.Event()
        self.signal_name = None
        self.starting = False

    def install(self):
        def handler(signum, frame):
            self.signal_name = signal.Signals(signum).name
            self.event.set()
            if self.starting:
                self.starting = False
                raise StopInStartup(self.signal_name)
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
        return self


def parse_cli(prog: str, description: str, specs: list[ParamSpec], argv=None):
    """
    Strip ROS arguments, answer --help (listing every parameter), return (ros_argv, ns).

    ROS arguments rcl cannot parse (a params file that is missing or not YAML, a malformed ``-p``) end the process
    with one line and exit code 2.
    """
    argv = list(sys.argv if argv is None else argv)
    try:
        non_ros = remove_ros_args(argv)[1:]
    except RCLError as exc:
        text = str(exc).split(', at ')[0].strip()
        print(f'{prog}: bad ROS arguments: {text}', file=sys.stderr)
        raise SystemExit(2) from None
    ap = argparse.ArgumentParser(prog=prog, description=description, epilog=help_epilog(with_common(specs)),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ns = ap.parse_args(non_ros)
    return argv, ns


CLOSE_TRACE_AFTER = 6.0      # s: a node's close() still running after this prints every thread's stack to stderr
TEARDOWN_LIMIT = 2.0         # s: the DDS teardown after close() is abandoned after this (see _middleware_teardown)
TEARDOWN_HARD_LIMIT = 4.0    # s: ... and the process ended from outside the interpreter this long after it began
EXECUTOR_SHUTDOWN = 1.0      # s: the executor's shutdown waits this long for a callback still running


def make_executor(node):
    """
    Return the executor the node's ``executor`` parameter names (events unless ``single_threaded``).

    ``events`` is rclpy's :class:`rclpy.experimental.EventsExecutor`: rmw calls back as a message arrives and the
    callback is dispatched from C++, where the stock executor rebuilds and scans a wait set of every subscription,
    timer, service and QoS event at each wake-up (a machine's three nodes take 17 % more CPU with it on this machine:
    ``benchmarks/bench_machines.py``).  It has no guard conditions: a node wakes itself from another thread with
    ``node.executor.create_task(callback)``, which both executors run on their spinning thread.
    """
    kind = node.get_parameter('executor').value if node.has_parameter('executor') else 'single_threaded'
    if kind == 'events':
        return EventsExecutor()
    return SingleThreadedExecutor()


def run_node(prog: str, description: str, specs: list[ParamSpec], factory, argv=None) -> int:
    """
    Process entry point shared by the nodes.

    ``factory(context_args) -> node`` builds the node (declaring ``specs``); a ParamError raised there is printed as
    one line naming the parameter and the process exits 2.  SIGINT/SIGTERM stop the spin loop; the node's ``close()``
    (flush records, stop workers) runs before the context shuts down.  Returns the exit code.
    """
    argv, _ = parse_cli(prog, description, specs, argv)
    stop = StopFlag().install()
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    ex = None
    code = 0
    try:
        try:
            stop.starting = True
            try:
                node = factory()
            finally:
                stop.starting = False
        except StopInStartup as exc:
            print(f'{prog}: {exc}: shutting down (during start-up)', file=sys.stderr)
            return 0
        except ParamError as exc:
            print(f'{prog}: parameter error: {exc}', file=sys.stderr)
            code = 2
            return code
        except (FileNotFoundError, ValueError, RCLError) as exc:
            # RCLError: e.g. ROS_SECURITY_ENABLE with a Fast DDS built without security, a bad enclave
            print(f'{prog}: cannot start: {str(exc).strip()}', file=sys.stderr)
            code = 2
            return code
        ex = make_executor(node)
        ex.add_node(node)
        failures = 0
        while not stop.event.is_set() and rclpy.ok() and not getattr(node, 'finished', False):
            try:
                ex.spin_once(timeout_sec=0.25)
            except Exception as exc:        # a failing callback is a bug: reported in full, the node goes on
                failures += 1
                node.get_logger().error(callback_failure_text(exc, failures))
        if stop.signal_name:
            node.get_logger().info(f'{stop.signal_name}: shutting down')
    finally:
        _trace_later(CLOSE_TRACE_AFTER)      # a close() that hangs leaves its stacks in the log
        try:
            if ex is not None:
                ex.shutdown(timeout_sec=EXECUTOR_SHUTDOWN)   # no callback runs once the node is being closed
            if node is not None and hasattr(node, 'close'):
                node.close()
        finally:
            faulthandler.cancel_dump_traceback_later()
            _middleware_teardown(prog, rclpy, node, code)
    return code


def _trace_later(seconds: float, end_process: bool = False) -> None:
    """Arm faulthandler: every thread's stack to stderr after ``seconds`` (then ``_exit(1)`` if ``end_process``)."""
    try:
        faulthandler.dump_traceback_later(seconds, exit=end_process)
    except (AttributeError, ValueError, OSError):       # stderr without a file descriptor (embedded use): no trace
        pass


def _middleware_teardown(prog: str, rclpy, node, code: int) -> None:
    """
    Destroy the node and shut the context down, at most :data:`TEARDOWN_LIMIT` s.

    Runs after the node's ``close()`` (records flushed and closed, workers stopped), so nothing is lost when the DDS
    teardown hangs (Fast DDS can): the process then prints every thread's stack to stderr (the node's log) and exits
    with ``code`` without it.  Should the hang hold the interpreter lock (the watchdog thread then cannot run),
    faulthandler's own thread dumps the stacks and ends the process (exit code 1) :data:`TEARDOWN_HARD_LIMIT` s after
    the teardown began.
    """
    def abandon():
        try:
            print(f'{prog}: middleware teardown still running after {TEARDOWN_LIMIT:g} s (the node was closed, '
                  f'nothing is lost): exiting without it; the stacks follow', file=sys.stderr, flush=True)
            faulthandler.dump_traceback(sys.stderr)
            sys.stdout.flush()
        except (AttributeError, ValueError, OSError):   # stdout / stderr closed or without a descriptor: exit anyway
            pass
        os._exit(code)

    watchdog = threading.Timer(TEARDOWN_LIMIT, abandon)
    watchdog.daemon = True
    watchdog.start()
    _trace_later(TEARDOWN_HARD_LIMIT, end_process=True)
    try:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    finally:
        faulthandler.cancel_dump_traceback_later()
        watchdog.cancel()


def callback_failure_text(exc: BaseException, count: int) -> str:
    """
    Describe a callback that raised, for the node's log.

    The node keeps spinning (its other callbacks, its records and the data already accumulated are not lost), so the
    text carries the full traceback for the bug report and the running count of such failures.
    """
    tb = ''.join(traceback.format_exception(type(exc), exc, exc.__traceback__)).rstrip()
    return (f'callback failed ({count} so far; the node goes on, please report this): '
            f'{type(exc).__name__}: {exc}\n{tb}')
