"""
Helpers every test that touches ROS must use.

rclpy never runs inside the pytest process: Fast DDS can hang at teardown, upstream eProsima/Fast-DDS#6513, so each ROS
participant lives in a bounded subprocess.

* :func:`ros_python` -- a Python that imports rclpy and bearing_id_msgs (this one, else ``<repo>/.venv``); the
  :func:`require_ros` guard skips a ROS test when there is none -- except under CI (``CI`` set), where it fails.
* :func:`ros_env` -- the environment for ROS subprocesses: ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` plus the
  Fast DDS profile ``params/fastdds_localhost.xml`` (UDPv4 on 127.0.0.1 + shared memory, discovery by unicast to
  127.0.0.1), and a ``ROS_DOMAIN_ID`` unique to this test process (1..100, reserved with a lock file so parallel runs
  never share one).
* :func:`script` -- a console script of bearing_id: next to the ROS python (``.venv/bin``), else in a colcon install
  (``<prefix>/lib/bearing_id/`` of ``AMENT_PREFIX_PATH``), else on ``PATH``.
* :class:`RosProcess` -- a subprocess in its own process group with a hard kill timeout; ``interrupt()`` sends SIGINT
  and reports whether it exited within :data:`STOP_WITHIN` (30 s: an upper bound for a loaded machine, not a speed
  test).
* :func:`run` -- run to completion with a hard timeout (the process group is killed on expiry).
* :func:`shm_clean` -- ``fastdds shm clean``: removes the Fast DDS shared-memory segments that no live process uses
  (never another process's files by name).

Run as a script it is a ROS peer for the transport tests (``python rosutil.py pub|sub SPEC.json``).
"""
from __future__ import annotations

import array
import fcntl
import functools
import importlib
import json
import math
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
DDS_PROFILE = REPO / 'params' / 'fastdds_localhost.xml'
DOMAIN_RANGE = range(1, 101)
STOP_WITHIN = 30.0  # s: how long a stopping process may take -- a generous upper bound, never a verdict on speed
_domain_lock = None  # (domain id, open lock file) held for the life of this process
_more_domain_locks = []  # further (domain id, open lock file) of domain_ids(n)


# ------------------------------------------------------------------------------------------------ interpreters
def _can_import_ros(python: str) -> bool:
    try:
        r = subprocess.run([python, '-c', 'import rclpy, bearing_id_msgs.msg, bearing_id'], capture_output=True,
                           timeout=60, env=_base_env(), cwd=str(REPO))
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


@functools.lru_cache(maxsize=1)
def ros_python() -> str | None:
    """Path of a Python with rclpy + bearing_id_msgs + bearing_id, or None."""
    for cand in (sys.executable, str(REPO / '.venv' / 'bin' / 'python')):
        if Path(cand).exists() and _can_import_ros(cand):
            return cand
    return None


def require_ros() -> str:
    """Return the ROS python; skips the test when there is none (fails under CI, where there must be one)."""
    import pytest

    py = ros_python()
    if py is None:
        text = ('no Python with rclpy and bearing_id_msgs (neither this interpreter nor .venv): run `make test`, '
                'which runs scripts/setup_env.sh')
        if os.environ.get('CI'):
            pytest.fail(text)
        pytest.skip(text)
    return py


def script_candidates(name: str, python: str | None = None) -> list[Path]:
    """
    Return where a console script of bearing_id may be, in the order :func:`script` tries them.

    Next to ``python`` (the venv of ``make test``), in ``<prefix>/lib/bearing_id/`` of each ``AMENT_PREFIX_PATH`` entry
    (a colcon install, where setup.cfg puts them and ``ros2 run`` looks), then on ``PATH``.
    """
    out = []
    if python:
        out.append(Path(python).parent / name)
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            out.append(Path(prefix) / 'lib' / 'bearing_id' / name)
    found = shutil.which(name)
    if found:
        out.append(Path(found))
    return out


def script(name: str) -> str:
    """
    Return the path of a console script, see :func:`script_candidates`.

    ``name``: sensor_driver, kf_estimator, identifier, bearing-id.  Fails (under CI) or skips the test when there is
    none.
    """
    import pytest

    py = require_ros()
    cands = script_candidates(name, py)
    for c in cands:
        if c.is_file() and os.access(c, os.X_OK):
            return str(c)
    text = f"console script {name!r} not found (looked at {', '.join(map(str, cands))})"
    if os.environ.get('CI'):
        pytest.fail(text)
    pytest.skip(text)


# -------------------------------------------------------------------------------------------------- environment
def _reserve_domain_id(start: int) -> tuple:
    """Flock the first free ROS_DOMAIN_ID of DOMAIN_RANGE from index ``start`` on; (id, open lock file)."""
    n = len(DOMAIN_RANGE)
    lock_dir = Path(tempfile.gettempdir())
    for k in range(n):
        d = DOMAIN_RANGE[(start + k) % n]
        f = open(lock_dir / f'bearing_id_ros_domain_{d}.lock', 'a+')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        return d, f
    raise RuntimeError('all ROS domain ids 1..100 are taken by other test processes')


def domain_id() -> int:
    """
    Reserve a ROS_DOMAIN_ID in 1..100 for this process (flock on /tmp/bearing_id_ros_domain_<id>.lock).

    Starts from a pid-derived id and takes the first free one, so concurrent test processes never collide.
    """
    global _domain_lock
    if _domain_lock is None:
        _domain_lock = _reserve_domain_id(os.getpid() % len(DOMAIN_RANGE))
    return _domain_lock[0]


def domain_ids(n: int) -> list[int]:
    """Reserve ``n`` ROS_DOMAIN_IDs for this process: :func:`domain_id` first, then further free ones."""
    ids = [domain_id()] + [d for d, _ in _more_domain_locks]
    while len(ids) < n:
        _more_domain_locks.append(_reserve_domain_id(DOMAIN_RANGE.index(ids[-1]) + 1))
        ids.append(_more_domain_locks[-1][0])
    return ids[:n]


def _base_env() -> dict:
    env = dict(os.environ)
    # The ros wheels' .pth bootstrapper re-execs Python with LD_LIBRARY_PATH pointing into its venv and marks the
    # environment done; a child that runs another venv's Python must bootstrap afresh, not inherit ours.
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    prefix = os.path.realpath(sys.prefix)
    ld = [p for p in env.get('LD_LIBRARY_PATH', '').split(os.pathsep)
          if p and not os.path.realpath(p).startswith(prefix + os.sep)]
    if ld:
        env['LD_LIBRARY_PATH'] = os.pathsep.join(ld)
    else:
        env.pop('LD_LIBRARY_PATH', None)
    for k in ('ROS_STATIC_PEERS', 'ROS_LOCALHOST_ONLY', 'ROS_DISCOVERY_SERVER', 'RMW_FASTRTPS_USE_QOS_FROM_XML',
              'FASTDDS_BUILTIN_TRANSPORTS'):
        env.pop(k, None)
    env.update(loopback_dds_env())
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env['PYTHONUNBUFFERED'] = '1'
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    return env


def loopback_dds_env() -> dict:
    """
    Return the environment for DDS on this machine.

    ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (the project's rule for every ROS process) plus the Fast DDS profile
    :data:`DDS_PROFILE` (Fast DDS 2.x and 3.x variable names), which binds the sockets that receive DDS traffic to
    127.0.0.1.  The same as the Makefile and ``bearing_id.nodes.dds.loopback_dds_env``; kept here so the test helpers
    do not depend on the package under test.
    """
    if not DDS_PROFILE.is_file():
        raise FileNotFoundError(f'Fast DDS profile {DDS_PROFILE} is missing')
    return {'FASTRTPS_DEFAULT_PROFILES_FILE': str(DDS_PROFILE), 'FASTDDS_DEFAULT_PROFILES_FILE': str(DDS_PROFILE),
            'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}


def ros_env(extra: dict | None = None) -> dict:
    """os.environ + DDS on loopback (:func:`loopback_dds_env`) + this process's ROS_DOMAIN_ID (+ ``extra``)."""
    env = _base_env()
    env['ROS_DOMAIN_ID'] = str(domain_id())
    if extra:
        env.update({k: str(v) for k, v in extra.items()})
    return env


# ---------------------------------------------------------------------------------------------------- processes
def _kill_group(p: subprocess.Popen, sig=signal.SIGKILL) -> None:
    try:
        os.killpg(p.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


class RosProcess:
    """
    A ROS subprocess in its own session/process group, output captured to temp files.

    ``hard_timeout`` [s]: the group is SIGKILLed if the process is still alive that long after start (checked by
    every wait/interrupt/stop call and by :meth:`close`).  Use as a context manager so it never outlives the test.
    """

    def __init__(self, cmd: list[str], env: dict | None = None, hard_timeout: float = 60.0, cwd=None):
        self.cmd = [str(c) for c in cmd]
        self.hard_timeout = float(hard_timeout)
        self._out = tempfile.TemporaryFile()
        self._err = tempfile.TemporaryFile()
        self.t0 = time.monotonic()
        self.killed = False
        self.proc = subprocess.Popen(self.cmd, env=env if env is not None else ros_env(), cwd=str(cwd or REPO),
                                     stdin=subprocess.DEVNULL, stdout=self._out, stderr=self._err,
                                     start_new_session=True)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def _remaining(self) -> float:
        return self.hard_timeout - (time.monotonic() - self.t0)

    def wait(self, timeout: float | None = None) -> int | None:
        """Wait for exit (at most ``timeout`` s, never past the hard timeout); returns the exit code or None."""
        limit = self._remaining() if timeout is None else min(timeout, self._remaining())
        try:
            return self.proc.wait(timeout=max(limit, 0.0))
        except subprocess.TimeoutExpired:
            if self._remaining() <= 0:
                self.kill()
            return None

    def interrupt(self, within: float = STOP_WITHIN) -> tuple[int | None, float]:
        """
        Send SIGINT (like Ctrl-C) and wait up to ``within`` s: (exit code or None if it did not exit, seconds).

        A process that ignores SIGINT is SIGKILLed afterwards (``killed`` is then True).
        """
        if not self.alive():
            return self.proc.returncode, 0.0
        t = time.monotonic()
        try:
            os.kill(self.proc.pid, signal.SIGINT)
        except ProcessLookupError:
            pass
        rc = self.wait(within)
        dt = time.monotonic() - t
        if rc is None:
            self.kill()
        return rc, dt

    def kill(self) -> None:
        if self.alive():
            self.killed = True
        _kill_group(self.proc, signal.SIGKILL)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:  # pragma: no cover
            pass

    def _read(self, f) -> str:
        f.seek(0)
        return f.read().decode('utf-8', 'replace')

    @property
    def stdout(self) -> str:
        return self._read(self._out)

    @property
    def stderr(self) -> str:
        return self._read(self._err)

    def output(self) -> str:
        """Both streams, for assertion messages."""
        return f"$ {' '.join(self.cmd)}\n--- stdout ---\n{self.stdout}\n--- stderr ---\n{self.stderr}"

    def close(self) -> None:
        self.kill()  # no-op when it has exited; otherwise the group goes
        _kill_group(self.proc, signal.SIGKILL)  # children left behind by an exited leader

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def run(cmd: list[str], timeout: float = 60.0, env: dict | None = None, input_text: str | None = None, cwd=None):
    """Run to completion; the process group is SIGKILLed after ``timeout`` s (then AssertionError with output)."""
    p = subprocess.Popen([str(c) for c in cmd], env=env if env is not None else ros_env(), cwd=str(cwd or REPO),
                         stdin=subprocess.PIPE if input_text is not None else subprocess.DEVNULL,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = p.communicate(input=input_text, timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_group(p)
        out, err = p.communicate()
        raise AssertionError(f"timed out after {timeout} s (killed): {' '.join(map(str, cmd))}\n--- stdout ---\n"
                             f'{out}\n--- stderr ---\n{err}')
    finally:
        _kill_group(p)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def run_python(code: str, timeout: float = 60.0, args=(), env: dict | None = None):
    """Run a code snippet under the ROS python (rclpy stays out of the pytest process)."""
    return run([require_ros(), '-c', code, *map(str, args)], timeout=timeout, env=env)


# ------------------------------------------------------------------------------------------------ shared memory
def fastdds_command() -> list[str] | None:
    """
    Return the command line of Fast DDS's ``fastdds`` tool, or None when there is none.

    Next to the ROS python (``.venv/bin/fastdds``, a shell wrapper of ``.venv/tools/fastdds/fastdds.py``, which is run
    with that python), else ``fastdds`` on ``PATH``.
    """
    py = ros_python()
    if py:
        script_py = Path(py).parent.parent / 'tools' / 'fastdds' / 'fastdds.py'
        if script_py.is_file():
            return [py, str(script_py)]
        wrapper = Path(py).parent / 'fastdds'
        if wrapper.is_file() and os.access(wrapper, os.X_OK):
            return [str(wrapper)]
    found = shutil.which('fastdds')
    return [found] if found else None


def shm_clean() -> str:
    """
    Clean Fast DDS shared memory left by crashed or killed participants: ``fastdds shm clean``, nothing else.

    The tool removes only the segments and ports no live process uses, so the transport of ROS processes that run
    beside the tests (other sessions, a plant's nodes) is never touched; no file is deleted here by name.  Returns
    the tool's report, or why nothing was cleaned.
    """
    cmd = fastdds_command()
    if cmd is None:
        return 'fastdds not found: shared memory not cleaned'
    try:
        r = subprocess.run([*cmd, 'shm', 'clean'], capture_output=True, text=True, timeout=60, env=_base_env())
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f'fastdds shm clean did not run: {exc}'
    return r.stdout.strip() if r.returncode == 0 else f'fastdds shm clean failed ({r.returncode}): {r.stderr.strip()}'


# ------------------------------------------------------------------------------------- generic message <-> dict
def _is_nested(typ: str) -> bool:
    return '/' in typ.split('<')[-1]


def msg_from_dict(msgtype: str, values: dict):
    """
    Build an rclpy message from plain values (nested dicts for nested messages).

    Independent of bearing_id.io.messages, so the transport tests check the wire, not our converters.
    """
    parts = msgtype.split('/')  # 'pkg/msg/Name' or 'pkg/Name'
    pkg, name = parts[0], parts[-1]
    cls = getattr(importlib.import_module(f'{pkg}.msg'), name)
    kw = {}
    for field, typ in cls.get_fields_and_field_types().items():
        if field not in values:
            continue
        v = values[field]
        if _is_nested(typ):
            inner = typ.split('<')[-1].rstrip('>')
            kw[field] = msg_from_dict(inner, v)
        elif typ.startswith('sequence<double') or typ.startswith('sequence<float'):
            kw[field] = array.array('d', [float(x) for x in v])
        elif typ.startswith('sequence<uint32'):
            kw[field] = array.array('I', [int(x) for x in v])
        else:
            kw[field] = v
    return cls(**kw)


def msg_to_dict(msg) -> dict:
    """Plain values of an rclpy or rosbags message (arrays -> lists)."""
    out = {}
    if hasattr(msg, 'get_fields_and_field_types'):
        fields = list(msg.get_fields_and_field_types())
    else:  # rosbags dataclass
        fields = [f for f in msg.__dataclass_fields__ if f != '__msgtype__']
    for f in fields:
        v = getattr(msg, f)
        if hasattr(v, 'get_fields_and_field_types') or hasattr(v, '__msgtype__'):
            out[f] = msg_to_dict(v)
        elif hasattr(v, 'tolist'):  # numpy / array.array
            out[f] = v.tolist()
        elif isinstance(v, (list, tuple)):
            out[f] = [x.tolist() if hasattr(x, 'tolist') else x for x in v]
        else:
            out[f] = v.item() if hasattr(v, 'item') else v
    return out


def normalise(v):
    """Make values comparable with ==: NaN -> 'NaN', inf -> 'inf', tuples -> lists, numpy -> python."""
    if isinstance(v, dict):
        return {k: normalise(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [normalise(x) for x in v]
    if hasattr(v, 'tolist'):
        return normalise(v.tolist())
    if isinstance(v, float):
        if math.isnan(v):
            return 'NaN'
        if math.isinf(v):
            return 'inf' if v > 0 else '-inf'
    if isinstance(v, bool):
        return v
    return v


# ------------------------------------------------------------------------------------------------ peer processes
def _peer(role: str, spec_path: str) -> int:
    """
    Run a peer process: ``role`` pub or sub.

    pub: publish each message of the spec once (reliable, transient local) and spin until SIGINT.  sub: wait
    (spec['timeout'] s) for one message per topic, print them as JSON, exit 0 (3 when some missing).
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    spec = json.loads(Path(spec_path).read_text())
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rclpy.init()
    node = rclpy.create_node(f'bearing_id_test_{role}_{os.getpid()}')
    received: dict = {}
    keep = []
    try:
        for m in spec['messages']:
            parts = m['type'].split('/')
            pkg, name = parts[0], parts[-1]
            cls = getattr(importlib.import_module(f'{pkg}.msg'), name)
            if role == 'pub':
                pub = node.create_publisher(cls, m['topic'], qos)
                pub.publish(msg_from_dict(m['type'], m['fields']))
                keep.append(pub)
            else:
                keep.append(node.create_subscription(
                    cls, m['topic'], lambda msg, t=m['topic']: received.setdefault(t, msg_to_dict(msg)), qos))
        print('ready', file=sys.stderr, flush=True)
        deadline = time.monotonic() + float(spec.get('timeout', 20))
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.1)
            if role == 'sub' and (len(received) == len(spec['messages']) or time.monotonic() > deadline):
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    if role == 'sub':
        print(json.dumps(received))
        return 0 if len(received) == len(spec['messages']) else 3
    return 0


if __name__ == '__main__':  # python rosutil.py pub|sub spec.json
    sys.exit(_peer(sys.argv[1], sys.argv[2]))


# ------------------------------------------------------------------------------------------ sample message values
def sample_messages() -> list[dict]:
    """
    Return one message of each bearing_id_msgs type as plain values (topic, type, fields), with awkward content.

    uint32 max, NaN/inf, a 64 kB sample array, non-ASCII text, empty strings.
    """
    n, nch = 2000, 4
    samples = [1e-5 * math.sin(0.01 * i + 0.7 * c) for i in range(n) for c in range(nch)]
    samples[5] = float('nan')
    samples[6] = -0.0
    header = {'stamp': {'sec': 1_700_000_000, 'nanosec': 123_456_789}, 'frame_id': 'paper_rig'}
    return [
        {'topic': '/bearing_id_test/displacement', 'type': 'bearing_id_msgs/msg/DisplacementBlock',
         'fields': {'header': header, 'sequence': 4_294_967_295, 'sample_rate': 2560.0,
                    'speed': 314.1592653589793, 'angle': 6.2,
                    'sample_angles': [6.2 + 314.1592653589793 * i / 2560.0 for i in range(n)], 'run_id': 'Ä run',
                    'channels': ['probe_x', 'probe_y', 'probe_x2', 'probe_y2'], 'nodes': [3, 3, 7, 7],
                    'directions': ['x', 'y', 'x', 'y'], 'samples': samples}},
        {'topic': '/bearing_id_test/speed', 'type': 'bearing_id_msgs/msg/RotorSpeed',
         'fields': {'header': header, 'speed': 157.07963267948966, 'angle': 1e-300}},
        {'topic': '/bearing_id_test/excitation', 'type': 'bearing_id_msgs/msg/Excitation',
         'fields': {'header': header, 'run_id': 'unbalance+shaker',
                    'kind': ['unbalance', 'force'], 'node': [2, 5], 'magnitude': [1.2e-5, 3.5],
                    'phase': [0.0, -1.5707963267948966], 'direction': ['forward', 'y'],
                    'frequency_ratio': [1.0, 0.37]}},
        {'topic': '/bearing_id_test/coefficients', 'type': 'bearing_id_msgs/msg/BearingCoefficients',
         'fields': {'header': header, 'speed': 209.43951023931956, 'method': 'paper',
                    'bearings': ['bearing_A', 'bearing_B'], 'nodes': [1, 9],
                    'stiffness': [1.5e7, -2.0e6, 3.1e6, 2.2e7, 9.0e6, 1.0e5, -4.0e5, 1.1e7],
                    'damping': [1.2e4, 3.0e2, 3.1e2, 1.9e4, 8.0e3, 0.0, -1.0, 7.5e3],
                    'stiffness_std': [1e5, float('nan'), 2e5, 3e5, 1e5, 1e5, 1e5, 1e5],
                    'damping_std': [10.0, 20.0, float('nan'), float('nan'), 1.0, 2.0, 3.0, 4.0],
                    'stiffness_determined': [True, False, True, True, True, True, True, True],
                    'damping_determined': [True, True, False, False, True, True, True, True],
                    'rank': 14, 'unknowns': 16, 'condition_number': float('inf'), 'residual': 0.0123,
                    'notes': ['prior dominates Cyx, Cyy (±20 µm orbit)', '']}},
    ]


def build_with_converters(sample: dict, types=None):
    """
    Build the message of a :func:`sample_messages` entry through bearing_id.io.messages.

    rclpy when ``types`` is None, else rosbags from that typestore.
    """
    from bearing_id.io import messages as M
    from bearing_id.config.params import ExcitationEntry
    import numpy as np

    f = sample['fields']
    h = f['header']
    stamp = h['stamp']['sec'] * 1_000_000_000 + h['stamp']['nanosec']
    kw = {'stamp': stamp, 'frame_id': h['frame_id'], 'types': types}
    name = sample['type'].split('/')[-1]
    if name == 'DisplacementBlock':
        nch = len(f['channels'])
        return M.block_to_msg(np.array(f['samples']).reshape(-1, nch), f['sequence'], f['sample_rate'], f['speed'],
                              f['angle'], channels=f['channels'], nodes=f['nodes'], directions=f['directions'],
                              sample_angles=f['sample_angles'], run_id=f['run_id'], **kw)
    if name == 'RotorSpeed':
        return M.speed_to_msg(f['speed'], f['angle'], **kw)
    if name == 'Excitation':
        entries = [ExcitationEntry(*row) for row in zip(f['kind'], f['node'], f['magnitude'], f['phase'],
                                                        f['direction'], f['frequency_ratio'])]
        return M.excitation_to_msg(entries, run_id=f['run_id'], **kw)
    if name == 'BearingCoefficients':
        nb = len(f['bearings'])
        r = {'speed': f['speed'], 'method': f['method'], 'bearings': f['bearings'], 'nodes': f['nodes'],
             'K': np.reshape(f['stiffness'], (nb, 2, 2)), 'C': np.reshape(f['damping'], (nb, 2, 2)),
             'K_std': np.reshape(f['stiffness_std'], (nb, 2, 2)), 'C_std': np.reshape(f['damping_std'], (nb, 2, 2)),
             'K_determined': np.reshape(f['stiffness_determined'], (nb, 2, 2)),
             'C_determined': np.reshape(f['damping_determined'], (nb, 2, 2)), 'rank': f['rank'],
             'unknowns': f['unknowns'], 'condition': f['condition_number'], 'residual': f['residual'],
             'notes': f['notes']}
        return M.coefficients_to_msg(r, **kw)
    raise ValueError(name)
