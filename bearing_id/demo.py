"""
``python -m bearing_id.demo``: the whole pipeline on the simulated rig, three ROS 2 nodes in three processes.

sensor_driver (simulated rig, truth bearings ~25 % off theory) -> kf_estimator -> identifier, on localhost-only DDS
with a private ROS_DOMAIN_ID.  The demo listens to /bearing_id/coefficients and /diagnostics, prints identified vs
true coefficients per speed (rpm, N/m, N s/m), writes plots to ``--out``, and stops every process cleanly (SIGINT,
then SIGKILL after a timeout).  Exit code 0 when every speed was identified, 1 otherwise.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from .config import defaults
from .config.params import load_rig
from .conventions import COEFF_ORDER, rad_s_to_rpm
from .identify import METHODS
from .identify.result import IdentResult
from .io import messages as M
from .nodes.dds import loopback_dds_env
from .nodes.qos import qos_latched
from .nodes.topics import TOPIC_COEFFICIENTS
from .plots.coefficients import plot_coefficients
from .rotor.supports import bearing_fn
from .simulation import rig as rigmod

NODES = ('identifier', 'kf_estimator', 'sensor_driver')


def ros_env(domain_id: int | None = None) -> dict:
    """
    Return the environment for ROS processes: DDS on this machine only, a private domain id.

    DDS on this machine only: LOCALHOST discovery and the loopback Fast DDS profile
    (:func:`bearing_id.nodes.dds.loopback_dds_env`).
    """
    env = dict(os.environ)
    env.update(loopback_dds_env())
    if domain_id is None:
        domain_id = int(env.get('ROS_DOMAIN_ID') or (10 + os.getpid() % 90))
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    env.setdefault('PYTHONUNBUFFERED', '1')
    return env


def start_node(name: str, params: dict, env: dict, log_dir: Path) -> subprocess.Popen:
    """Start ``bearing_id.nodes.<name>`` as its own process with ``-p key:=value`` parameters."""
    cmd = [sys.executable, '-m', f'bearing_id.nodes.{name}', '--ros-args']
    for k, v in params.items():
        cmd += ['-p', f'{k}:={_ros_value(v)}']
    log = open(log_dir / f'{name}.log', 'w')
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def _ros_value(v) -> str:
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, (list, tuple)):
        return '[' + ','.join(_ros_value(x) for x in v) + ']'
    if isinstance(v, float):
        return repr(v)
    return str(v)


def stop_processes(procs: dict, timeout: float = 10.0) -> dict:
    """SIGINT every process, wait up to ``timeout`` s, SIGKILL what is left; returns {name: return code}."""
    for p in procs.values():
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    t_end = time.monotonic() + timeout
    codes = {}
    for name, p in procs.items():
        try:
            codes[name] = p.wait(timeout=max(0.1, t_end - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            codes[name] = f'killed after {timeout:g} s'
            p.wait(timeout=5)
    return codes


class Listener:
    """In-process rclpy node collecting /bearing_id/coefficients and /diagnostics."""

    def __init__(self, domain_id: int | None = None):
        """Listen on ``domain_id`` (default: ROS_DOMAIN_ID of this process's environment)."""
        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('bearing_id_demo', context=self.context)
        self.results = {}                # speed [rad/s] -> coefficients dict (latest)
        self.last_result_time = None
        self.diag = {}                   # status name -> (level, message)
        self.diag_values = {}            # status name -> {key: value}
        self.lock = threading.Lock()
        self.node.create_subscription(M.BearingCoefficients, TOPIC_COEFFICIENTS, self._on_coeffs, qos_latched(100))
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 50)
        self._M = M
        self.ex = SingleThreadedExecutor(context=self.context)
        self.ex.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.ex.spin_once(timeout_sec=0.05)

    def _on_coeffs(self, msg):
        d = self._M.coefficients_from_msg(msg)
        with self.lock:
            self.results[round(d['speed'], 6)] = d
            self.last_result_time = time.monotonic()

    def _on_diag(self, msg):
        with self.lock:
            for st in msg.status:
                self.diag[st.name] = (int.from_bytes(st.level, 'little') if isinstance(st.level, bytes)
                                      else int(st.level), st.message)
                self.diag_values[st.name] = {kv.key: kv.value for kv in st.values}

    def close(self, timeout: float = 10.0):
        """
        Stop spinning and shut rclpy down.

        Fast DDS can hang in teardown (eProsima/Fast-DDS#6513), so a watchdog ends the whole process (exit 3, after
        flushing output) if the shutdown has not returned within ``timeout`` s.
        """
        done = threading.Event()

        def watchdog():
            if not done.wait(timeout):
                print(f'demo: ROS shutdown hung for {timeout:g} s (Fast DDS teardown); exiting', file=sys.stderr,
                      flush=True)
                sys.stdout.flush()
                os._exit(3)

        threading.Thread(target=watchdog, daemon=True).start()
        self._stop.set()
        self.thread.join(timeout=2)
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)
        done.set()


def format_table(results: dict, truth_fn, theory_fn) -> str:
    """Format identified vs true (and theory) per speed and bearing: K [N/m], C [N s/m], errors in %."""
    lines = []
    hdr = f"{'speed':>7}  {'bearing':<9} {'coef':<4} {'identified':>12} {'1-sigma':>10} {'true':>12} " \
          f"{'error':>8} {'theory':>12} {'theory err':>10}"
    lines.append(hdr)
    lines.append('-' * len(hdr))
    errs = {'K': [], 'C': []}
    z = []          # error / stated 1-sigma of every determined coefficient
    for sp in sorted(results):
        d = results[sp]
        tr = truth_fn(d['speed'])
        th = theory_fn(d['speed'])
        rpm = rad_s_to_rpm(d['speed'])
        for i, (name, node) in enumerate(zip(d['bearings'], d['nodes'])):
            for sym, idx in (('K', 0), ('C', 1)):
                val = d[sym][i].reshape(4)
                std = d[f'{sym}_std'][i].reshape(4)
                det = d[f'{sym}_determined'][i].reshape(4)
                t = np.asarray(tr[node][idx]).reshape(4)
                h = np.asarray(th[node][idx]).reshape(4)
                for k, lab in enumerate(COEFF_ORDER):
                    e = 100 * abs(val[k] - t[k]) / abs(t[k])
                    eh = 100 * abs(h[k] - t[k]) / abs(t[k])
                    shown = f'{val[k]:12.4e}' if det[k] else f"{'undetermined':>12}"
                    if det[k]:
                        errs[sym].append(e)
                        z.append((val[k] - t[k]) / std[k])
                    lines.append(f'{rpm:7.0f}  {name:<9} {sym}{lab:<3} {shown} {std[k]:10.2e} {t[k]:12.4e} '
                                 f"{(f'{e:7.2f}%' if det[k] else '      -'):>8} {h[k]:12.4e} {eh:9.2f}%")
        lines.append('')
    for sym, unit in (('K', 'N/m'), ('C', 'N s/m')):
        if errs[sym]:
            lines.append(f'{sym} [{unit}]: mean |error| vs truth {np.mean(errs[sym]):.2f} %, max '
                         f'{np.max(errs[sym]):.2f} % over {len(errs[sym])} determined coefficients')
    if z:
        z = np.asarray(z)
        lines.append(f'error / stated 1-sigma: RMS {np.sqrt(np.mean(z ** 2)):.2f}, max |{np.max(np.abs(z)):.2f}| over '
                     f'{z.size} coefficients (an honest 1-sigma gives an RMS near 1)')
    return '\n'.join(lines)


def plot(results: dict, truth_fn, theory_fn, path: Path) -> Path:
    """
    Write the coefficients vs speed (``results``: speed -> :func:`bearing_id.io.messages.coefficients_from_msg`).

    :func:`bearing_id.plots.coefficients.plot_coefficients`: identified +-1-sigma, truth and theory per coefficient.
    """
    keys = {f.name for f in dataclasses.fields(IdentResult)}
    rs = [IdentResult(**{k: v for k, v in results[s].items() if k in keys}) for s in sorted(results)]
    return plot_coefficients(rs, path, truth_fn=truth_fn, theory_fn=theory_fn,
                             title='bearing_id demo: identified vs true bearing coefficients (ROS 2 nodes, '
                                   'simulated rig)')


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog='python -m bearing_id.demo', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--out', default='out/demo', help='output directory (plots, node logs, record)')
    ap.add_argument('--method', default=defaults.METHOD, choices=METHODS,
                    help=f'identification method (default {defaults.METHOD}, as bearing-id identify: here physical, '
                         'which the single midspan probe determines)')
    ap.add_argument('--rate', type=float, default=2.0, help='playback speed relative to real time (default 2)')
    ap.add_argument('--params', default='', help='rig YAML (default the packaged params/rig.yaml)')
    ap.add_argument('--speeds', help="comma-separated speeds [rpm] (default: the rig's simulation.speeds_rpm)")
    ap.add_argument('--dwell', type=float, help='seconds at each speed (default: simulation.dwell)')
    ap.add_argument('--timeout', type=float, default=170.0, help='give up after this many seconds (default 170)')
    args = ap.parse_args(argv)

    rig = load_rig(args.params or None)
    speeds = [float(s) for s in args.speeds.split(',')] if args.speeds else list(rig.simulation.speeds_rpm)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    record_dir = out / 'record'
    if record_dir.exists():
        shutil.rmtree(record_dir)          # a fresh demo; the identifier would otherwise resume the last one
    env = ros_env()
    t0 = time.monotonic()
    print(f'bearing_id demo: rig {rig.name}, runs {[r.id for r in rig.simulation.runs]}, speeds {speeds} rpm, '
          f"method {args.method}, rate x{args.rate:g}, ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} (localhost only)")
    os.environ.update({k: env[k] for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_DOMAIN_ID',
                                           'FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')})
    common = {'rig_params': args.params} if args.params else {}
    drv = dict(common, speeds_rpm=speeds, rate_factor=args.rate, wait_for_subscribers=2, exit_when_done=True)
    if args.dwell:
        drv['dwell'] = args.dwell
    procs = {
        'identifier': start_node('identifier', dict(common, method=args.method, record_dir=str(record_dir),
                                                    runs=[r.id for r in rig.simulation.runs]), env, out),
        'kf_estimator': start_node('kf_estimator', dict(common, prebuild_speeds_rpm=speeds), env, out),
        'sensor_driver': start_node('sensor_driver', drv, env, out),
    }
    listener = Listener()
    ok = False
    try:
        expected = len(speeds)
        while time.monotonic() - t0 < args.timeout:
            time.sleep(0.25)
            dead = [n for n, p in procs.items() if p.poll() is not None and n != 'sensor_driver']
            if dead or (procs['sensor_driver'].poll() not in (None, 0)):
                print(f"demo: node(s) {dead or ['sensor_driver']} exited early; see {out}/*.log")
                break
            with listener.lock:
                n = len(listener.results)
                quiet = listener.last_result_time is not None and time.monotonic() - listener.last_result_time > 2.0
            if procs['sensor_driver'].poll() == 0 and n >= expected and quiet:
                ok = True
                break
        else:
            print(f'demo: timed out after {args.timeout:g} s with {len(listener.results)} of {len(speeds)} speeds')
    finally:
        codes = stop_processes(procs)
        listener.close()
    elapsed = time.monotonic() - t0
    results = dict(listener.results)
    truth_fn = rigmod.truth_bearing_fn(rig)
    theory_fn = bearing_fn(rig)
    if results:
        print()
        print(format_table(results, truth_fn, theory_fn))
        png = plot(results, truth_fn, theory_fn, out / 'coefficients.png')
        print(f'\nplot: {png}')
    print('\nlast diagnostics:')
    for name, (level, msg) in sorted(listener.diag.items()):
        print(f"  [{('OK', 'WARN', 'ERROR', 'STALE')[min(level, 3)]:5}] {name}: {msg}")
    print(f'\nnode exits: {codes}; node logs in {out}/; identifier record {record_dir}/record.jsonl')
    print(f"demo finished in {elapsed:.1f} s: {'all' if ok else 'NOT all'} {len(speeds)} speeds identified")
    return 0 if ok else 1


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
