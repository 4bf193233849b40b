"""
The nodes with stock ROS 2 tools and a plant's set-up (issue 10, items 6 and 7).

* params files in the ``/**:`` form, generated from the nodes' specs; a node under a namespace
  (``-r __ns:=/rig1 --params-file``) takes the file's values and creates its topics under ``/rig1``;
* ``ros2 param dump``: the list_parameters / get_parameters services answer for every declared parameter (also the
  unset ones), and the dumped file starts the node again with the same values;
* QoS: the excitation subscription hears a volatile publisher (a plain ``ros2 bag play``) and the latched value of a
  transient-local one (delivered twice, processed once); ``input_reliability: best_effort`` lets a SensorDataQoS
  publisher connect;
* DDS confined to loopback: no UDP/TCP socket of a node is bound to 0.0.0.0 or another interface;
* package.xml declares a rosdep key for every import; the console scripts are found in a colcon install too.

The ROS clients run as subprocesses (``python test_stock_tools.py client SPEC.json``; rclpy never in pytest).
"""
from __future__ import annotations

import ast
import importlib
import json
import math
import os
from pathlib import Path
import re
import socket
import struct
import sys
import time
import xml.etree.ElementTree as ET

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------------------------ socket check
def _socket_inodes(pid: int) -> set[int]:
    out = set()
    fd_dir = Path(f'/proc/{pid}/fd')
    for fd in fd_dir.iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith('socket:['):
            out.add(int(target[8:-1]))
    return out


def _ip(hex_addr: str) -> str:
    raw = bytes.fromhex(hex_addr)
    if len(raw) == 4:
        return socket.inet_ntop(socket.AF_INET, struct.pack('<I', int(hex_addr, 16)))
    return socket.inet_ntop(socket.AF_INET6, b''.join(raw[i:i + 4][::-1] for i in range(0, 16, 4)))


def inet_sockets(pid: int) -> list[tuple[str, str, int]]:
    """
    Return (protocol, local address, port) of every UDP socket and listening TCP socket the process holds.

    /proc/<pid>/fd socket inodes matched against /proc/<pid>/net/{udp,udp6,tcp,tcp6}.
    """
    inodes = _socket_inodes(pid)
    out = []
    for proto in ('udp', 'udp6', 'tcp', 'tcp6'):
        try:
            lines = Path(f'/proc/{pid}/net/{proto}').read_text().splitlines()[1:]
        except OSError:
            continue
        for ln in lines:
            f = ln.split()
            if int(f[9]) not in inodes or (proto.startswith('tcp') and f[3] != '0A'):   # 0A: TCP LISTEN
                continue
            addr, port = f[1].split(':')
            out.append((proto, _ip(addr), int(port, 16)))
    return out


def _descendants(pid: int) -> list[int]:
    kids: dict[int, list[int]] = {}
    for d in Path('/proc').iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / 'stat').read_text().rsplit(')', 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d.name))
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo += kids.get(p, [])
    return out


def _is_loopback(ip: str) -> bool:
    return ip.startswith('127.') or ip == '::1' or ip.startswith('::ffff:127.')


# ------------------------------------------------------------------------------------------------ ROS client
def _value(v):
    """Return a rcl_interfaces/ParameterValue as plain python (as ros2param's get_value does); NaN -> 'NaN'."""
    t = v.type
    val = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value', 5: 'byte_array_value',
           6: 'bool_array_value', 7: 'integer_array_value', 8: 'double_array_value', 9: 'string_array_value'}.get(t)
    if val is None:
        return None
    x = getattr(v, val)
    if t >= 5:
        x = list(x)
    return x


def _jsonable(x):
    if isinstance(x, float) and math.isnan(x):
        return 'NaN'
    if isinstance(x, list):
        return [_jsonable(e) for e in x]
    return x


def _client(spec_path: str) -> int:
    """
    Actions of SPEC.json, in order, then print {"results": [...]} as JSON.

    * ``dump``: like ``ros2 param dump``: list_parameters + get_parameters of ``node`` in ``ns``; also the node's
      publishers and subscriptions (graph); with ``yaml`` the dump is written there in ros2 param dump's layout.
    * ``publish_excitation``: an Excitation (run ``run_id``) with ``qos``; waits for ``wait_match`` matched
      subscriptions first; the publisher is kept (a transient-local one keeps serving late joiners).
    * ``match``: publishers on ``topic`` with each of ``qos`` (names below); waits until those with an ``expect``
      reach it (at most ``timeout`` s), then reports every publisher's matched subscription count.
    Then holds for ``hold`` s (SIGINT ends it).  QoS names: ``bag_play`` (RELIABLE, VOLATILE, depth 10: rosbag2
    Jazzy's offer for a bag without recorded QoS), ``latched`` (RELIABLE, TRANSIENT_LOCAL), ``sensor_data``
    (BEST_EFFORT, VOLATILE, depth 5: rclpy's qos_profile_sensor_data).
    """
    import rclpy
    from rclpy._rclpy_pybind11 import NodeNameNonExistentError
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    import rosutil

    spec = json.loads(Path(spec_path).read_text())
    qos = {'bag_play': QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                  durability=DurabilityPolicy.VOLATILE),
           'latched': QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL),
           'sensor_data': qos_profile_sensor_data}
    rclpy.init()
    node = rclpy.create_node(f'stock_tools_client_{os.getpid()}')
    keep, results = [], []

    def spin_until(pred, timeout):
        t_end = time.monotonic() + timeout
        while not pred() and time.monotonic() < t_end:
            rclpy.spin_once(node, timeout_sec=0.05)
        return pred()

    def call(client, request):
        # a response is lost when it is sent before the server has discovered the client's reply reader (a
        # discovery race of rmw_fastrtps, seen on a loaded machine): ask again, as a user re-running the tool would
        for _ in range(6):
            fut = client.call_async(request)
            rclpy.spin_until_future_complete(node, fut, timeout_sec=5)
            if fut.result() is not None:
                return fut.result()
            client.remove_pending_request(fut)
        raise TimeoutError(f'no answer from {client.service_name}')

    try:
        for act in spec['actions']:
            if act['do'] == 'dump':
                from rcl_interfaces.srv import GetParameters, ListParameters
                full = act['ns'].rstrip('/') + '/' + act['node']
                lc = node.create_client(ListParameters, full + '/list_parameters')
                gc = node.create_client(GetParameters, full + '/get_parameters')
                assert lc.wait_for_service(timeout_sec=30) and gc.wait_for_service(timeout_sec=30), full
                names = sorted(call(lc, ListParameters.Request()).result.names)
                values = call(gc, GetParameters.Request(names=names)).values
                params = {n: _value(v) for n, v in zip(names, values)}

                def graph(kind):
                    try:
                        return sorted(t for t, _ in getattr(node, f'get_{kind}_names_and_types_by_node')(
                            act['node'], act['ns']))
                    except NodeNameNonExistentError:    # the graph has not heard of the node yet
                        return []
                spin_until(lambda: bool(graph('publisher')), 20)
                pubs, subs = graph('publisher'), graph('subscriber')
                if act.get('yaml'):
                    import yaml
                    Path(act['yaml']).write_text(yaml.dump({full: {'ros__parameters': params}},
                                                           default_flow_style=False))
                results.append({'names': names, 'n_values': len(values),
                                'params': {k: _jsonable(v) for k, v in params.items()},
                                'publishers': pubs, 'subscribers': subs})
            elif act['do'] == 'publish_excitation':
                from bearing_id_msgs.msg import Excitation
                pub = node.create_publisher(Excitation, act.get('topic', '/rotor/excitation'), qos[act['qos']])
                keep.append(pub)
                matched = spin_until(lambda: pub.get_subscription_count() >= act.get('wait_match', 0), 30)
                pub.publish(rosutil.msg_from_dict('bearing_id_msgs/msg/Excitation', {
                    'header': {'stamp': {'sec': 1000, 'nanosec': 0}, 'frame_id': 'rig'}, 'run_id': act['run_id'],
                    'kind': ['unbalance'], 'node': [8], 'magnitude': [2.5e-5], 'phase': [1.5707963267948966],
                    'direction': ['forward'], 'frequency_ratio': [1.0]}))
                print(f"published {act['run_id']}", file=sys.stderr, flush=True)
                results.append({'matched': matched, 'subscriptions': pub.get_subscription_count()})
            elif act['do'] == 'match':
                pkg, _, name = act['type'].split('/')
                cls = getattr(importlib.import_module(f'{pkg}.msg'), name)
                pubs = {q: node.create_publisher(cls, act['topic'], qos[q]) for q in act['qos']}
                keep += list(pubs.values())
                expect = act.get('expect', {})
                spin_until(lambda: all(pubs[q].get_subscription_count() >= n for q, n in expect.items()),
                           act.get('timeout', 20))
                spin_until(lambda: False, 0.5)          # a late (incompatible) match would show by now
                results.append({q: p.get_subscription_count() for q, p in pubs.items()})
        print('ready', file=sys.stderr, flush=True)
        spin_until(lambda: False, float(spec.get('hold', 0)))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(json.dumps({'results': results}), flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':  # python test_stock_tools.py client SPEC.json
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    sys.exit(_client(sys.argv[2]))


# ------------------------------------------------------------------------------------------------ tests
from bearing_id.config.params import load_rig, ParamError  # noqa: E402
from bearing_id.nodes import dds, runs, specs as node_specs, topics  # noqa: E402
import pytest  # noqa: E402
import rosutil  # noqa: E402
import yaml  # noqa: E402

NODES = ('sensor_driver', 'kf_estimator', 'identifier')


def _client_cmd(tmp_path, spec: dict, name: str = 'client') -> list[str]:
    path = tmp_path / f'{name}.json'
    path.write_text(json.dumps(spec))
    return [rosutil.require_ros(), str(Path(__file__).resolve()), 'client', str(path)]


def _results(out: str) -> list:
    return json.loads([ln for ln in out.splitlines() if ln.startswith('{')][-1])['results']


def _wait_for(proc: rosutil.RosProcess, pattern: str, timeout: float) -> bool:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if re.search(pattern, proc.stderr + proc.stdout):
            return True
        if not proc.alive():
            return False
        time.sleep(0.1)
    return False


def _peers(domain: str) -> str:
    """Other processes of this machine on ROS_DOMAIN_ID ``domain`` (for a failure message: cross-talk)."""
    out = []
    for d in Path('/proc').iterdir():
        try:
            env = (d / 'environ').read_bytes().split(b'\0')
            if f'ROS_DOMAIN_ID={domain}'.encode() in env:
                cmdline = (d / 'cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')
                out.append(f'{d.name}: {cmdline[:150]}')
        except OSError:
            continue
    return f'processes on ROS_DOMAIN_ID {domain}:\n' + '\n'.join(out)


def _expected(spec: node_specs.ParamSpec, override=None):
    v = override if override is not None else spec.default
    if v is None:
        return 'NaN' if spec.kind == 'float' else ([] if spec.kind.endswith('[]') else '')
    return list(v) if isinstance(v, tuple) else v


# ---------------------------------------------------------------------------------------------------- pure
@pytest.mark.parametrize('node', NODES)
def test_params_file_is_keyed_for_any_namespace_and_generated_from_the_specs(node, tmp_path):
    """
    params/<node>.yaml: one ``/**`` block holding every declared parameter at its default, generated from the specs.

    Every declared parameter (COMMON_SPECS too) at its default, unset ones commented out; and it is what ``python -m
    bearing_id.nodes.specs`` generates (header kept).
    """
    specs = node_specs.with_common(importlib.import_module(f'bearing_id.nodes.{node}_core').SPECS)
    path = REPO / 'params' / f'{node}.yaml'
    text = path.read_text()
    data = yaml.safe_load(text)
    assert list(data) == ['/**'], f"{path}: expected one '/**:' block, got {list(data)}"
    d = data['/**']['ros__parameters']
    for s in specs:
        if s.default is None:
            assert f'# {s.name}:' in text and s.name not in d, s.name
        else:
            assert d[s.name] == _expected(s), s.name
    assert set(d) <= {s.name for s in specs}
    node_specs.validate_values(specs, d)
    assert 'input_reliability' in d
    copy = tmp_path / path.name
    copy.write_text(text)
    regenerated = node_specs.write_params_file(copy, node, specs)
    assert regenerated == text, (f"{path} is out of date with the node's SPECS: run "
                                 f'`.venv/bin/python -m bearing_id.nodes.specs`')


def test_unset_parameters_are_declared_with_a_typed_value_and_read_back_as_unset():
    assert node_specs.unset_value('str[]') == [] and node_specs.unset_value('float[]') == []
    assert math.isnan(node_specs.unset_value('float')) and node_specs.unset_value('str') == ''
    with pytest.raises(TypeError):
        node_specs.unset_value('int')
    spec = node_specs.ParamSpec('speeds_rpm', None, 'speed steps', 'rpm', lo=1.0, hi=1e5, type_='float[]')
    for unset in (None, [], ()):
        assert node_specs.validate_value(spec, unset) is None
    assert node_specs.validate_value(spec, [600, 900.5]) == [600.0, 900.5]
    assert all(isinstance(x, float) for x in node_specs.validate_value(spec, [600, 900]))
    f = node_specs.ParamSpec('dwell', None, 'dwell', 's', lo=0.01, hi=1e4, type_='float')
    assert node_specs.validate_value(f, float('nan')) is None and node_specs.validate_value(f, 2) == 2.0
    with pytest.raises(ParamError, match='dwell'):
        node_specs.validate_value(f, 0.0)
    assert topics.relative(topics.TOPIC_DISPLACEMENT) == 'rotor/displacement'
    assert topics.relative(topics.TOPIC_DIAGNOSTICS) == '/diagnostics'


def test_a_repeated_excitation_is_ignored():
    """The latched excitation arrives twice from a transient-local publisher (both subscriptions match it)."""
    run = load_rig().simulation.runs[0]
    tl = runs.ExcitationTimeline()
    assert tl.add(1000.0, run) is True
    assert tl.add(1000.0, run) is False and len(tl) == 1
    assert tl.at(1001.0) is run


def test_fastdds_profile_allows_only_loopback_and_shared_memory():
    """
    The profile the Makefile and rosutil choose allows only loopback and shared memory.

    Builtin transports off, UDPv4 whitelisted to 127.0.0.1, SHM, discovery by unicast to 127.0.0.1 (no multicast
    locator), default participant profile.
    """
    path = REPO / 'params' / 'fastdds_localhost.xml'
    assert dds.fastdds_profile().read_bytes() == path.read_bytes()     # the source tree's or the installed copy
    ns = {'f': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
    root = ET.parse(path).getroot()
    descs = {d.findtext('f:transport_id', namespaces=ns): d for d in root.iterfind('.//f:transport_descriptor', ns)}
    parts = root.findall('.//f:participant', ns)
    assert len(parts) == 1 and parts[0].get('is_default_profile') == 'true'
    rtps = parts[0].find('f:rtps', ns)
    assert rtps.findtext('f:useBuiltinTransports', namespaces=ns).strip() == 'false'
    used = [t.text.strip() for t in rtps.iterfind('f:userTransports/f:transport_id', ns)]
    kinds = sorted(descs[t].findtext('f:type', namespaces=ns) for t in used)
    assert kinds == ['SHM', 'UDPv4'], kinds
    for t in used:
        if descs[t].findtext('f:type', namespaces=ns) == 'UDPv4':
            allowed = [a.text.strip() for a in descs[t].iterfind('f:interfaceWhiteList/f:address', ns)]
            assert allowed == ['127.0.0.1'], allowed
    builtin = rtps.find('f:builtin', ns)
    assert builtin.find('f:metatrafficMulticastLocatorList', ns) is None
    for lst in ('metatrafficUnicastLocatorList', 'initialPeersList'):
        addrs = [a.text.strip() for a in builtin.iterfind(f'f:{lst}/f:locator/f:udpv4/f:address', ns)]
        assert addrs == ['127.0.0.1'], (lst, addrs)
    env = rosutil.loopback_dds_env()
    assert env == {**dds.loopback_dds_env(), 'FASTRTPS_DEFAULT_PROFILES_FILE': str(path),
                   'FASTDDS_DEFAULT_PROFILES_FILE': str(path)}
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    mk = (REPO / 'Makefile').read_text()
    for var in ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE'):
        assert re.search(rf'^export {var} := \$\(DDS_PROFILE\)$', mk, re.M), var
    assert re.search(r'^DDS_PROFILE \?= \$\(CURDIR\)/params/fastdds_localhost.xml$', mk, re.M)
    assert re.search(r'^export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST$', mk, re.M)
    assert 'make test' in (REPO / '.ci' / 'run').read_text()


def test_socket_check_sees_a_socket_bound_to_every_interface():
    """
    Control for the check below: a socket on 0.0.0.0 and a listening one on 127.0.0.1 are both reported.

    A UDP socket on 0.0.0.0 and a listening TCP socket on 127.0.0.1 of this process.
    """
    u, t = socket.socket(socket.AF_INET, socket.SOCK_DGRAM), socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        u.bind(('0.0.0.0', 0))
        t.bind(('127.0.0.1', 0))
        t.listen(1)
        got = inet_sockets(os.getpid())
        assert ('udp', '0.0.0.0', u.getsockname()[1]) in got and ('tcp', '127.0.0.1', t.getsockname()[1]) in got
        assert not _is_loopback('0.0.0.0') and not _is_loopback('192.0.2.2') and _is_loopback('127.0.0.1')
    finally:
        u.close()
        t.close()


def test_package_xml_declares_a_rosdep_key_for_every_import():
    """
    Every third-party module imported by bearing_id/ maps to an exec_depend of package.xml.

    Rosdep keys as in rosdistro's rosdep/{base,python}.yaml; rosbags and filterpy only as *-pip keys; a key rosdistro
    lacks (pint, mcap, pydantic 2) is defined in the package's own rosdep source, rosdep/bearing_id.yaml.
    """
    keys = {'rclpy': 'rclpy', 'rcl_interfaces': 'rcl_interfaces', 'builtin_interfaces': 'builtin_interfaces',
            'std_msgs': 'std_msgs', 'diagnostic_msgs': 'diagnostic_msgs', 'sensor_msgs': 'sensor_msgs',
            'ament_index_python': 'ament_index_python',
            'bearing_id_msgs': 'bearing_id_msgs', 'numpy': 'python3-numpy', 'scipy': 'python3-scipy',
            'yaml': 'python3-yaml', 'matplotlib': 'python3-matplotlib', 'rosbags': 'python3-rosbags-pip',
            'filterpy': 'python3-filterpy-pip', 'pint': 'python3-pint-pip', 'mcap': 'python3-mcap-pip',
            'pydantic': 'python3-pydantic2-pip', 'pydantic_core': 'python3-pydantic2-pip',
            'sqlalchemy': 'python3-sqlalchemy'}
    own = yaml.safe_load((REPO / 'rosdep' / 'bearing_id.yaml').read_text())
    pip_keys = {'python3-pint-pip': 'pint', 'python3-mcap-pip': 'mcap', 'python3-pydantic2-pip': 'pydantic',
                'python3-import-linter-pip': 'import-linter', 'python3-threadpoolctl-pip': 'threadpoolctl',
                'python3-pytest-xdist-pip': 'pytest-xdist'}
    assert own == {k: {'*': {'pip': {'packages': [v]}}} for k, v in pip_keys.items()}
    imported: dict[str, str] = {}
    for f in sorted((REPO / 'bearing_id').rglob('*.py')):
        for n in ast.walk(ast.parse(f.read_text(), str(f))):
            mods = []
            if isinstance(n, ast.Import):
                mods = [a.name for a in n.names]
            elif isinstance(n, ast.ImportFrom) and n.level == 0 and n.module:
                mods = [n.module]
            for m in mods:
                top = m.split('.')[0]
                if top not in sys.stdlib_module_names and top != 'bearing_id' and top != '__future__':
                    imported.setdefault(top, str(f.relative_to(REPO)))
    unknown = {m: f for m, f in imported.items() if m not in keys}
    assert not unknown, f'imports without a known rosdep key (add one to package.xml and this table): {unknown}'
    root = ET.parse(REPO / 'package.xml').getroot()
    exec_deps = {e.text.strip() for e in root.iter('exec_depend')} | {e.text.strip() for e in root.iter('depend')}
    missing = sorted({keys[m] for m in imported} - exec_deps)
    assert not missing, f'package.xml lacks exec_depend {missing}'
    assert {e.text.strip() for e in root.iter('test_depend')} >= {'python3-pytest'}


def test_console_scripts_are_found_in_a_colcon_install(tmp_path, monkeypatch):
    """
    rosutil.script looks next to the ROS python (make test), then in a colcon install, then on PATH.

    The colcon install: <prefix>/lib/bearing_id of AMENT_PREFIX_PATH (colcon test).
    """
    prefix = tmp_path / 'install' / 'bearing_id'
    exe = prefix / 'lib' / 'bearing_id' / 'kf_estimator'
    exe.parent.mkdir(parents=True)
    exe.write_text('#!/bin/sh\n')
    exe.chmod(0o755)
    monkeypatch.setenv('AMENT_PREFIX_PATH', os.pathsep.join([str(tmp_path / 'none'), str(prefix)]))
    cands = rosutil.script_candidates('kf_estimator', str(tmp_path / 'venv' / 'bin' / 'python'))
    assert cands[:3] == [tmp_path / 'venv' / 'bin' / 'kf_estimator',
                         tmp_path / 'none' / 'lib' / 'bearing_id' / 'kf_estimator', exe]   # then PATH, if there


# ----------------------------------------------------------------------------------------------------- ROS
def _rtps_ports(domain: int) -> range:
    """
    Return the UDP ports RTPS uses to *receive* on ``domain``.

    Spec 9.6.1.1: PB 7400 + DG 250 x domain, the next 250 ports hold the multicast and the per-participant unicast
    metatraffic and user ports.
    """
    base = 7400 + 250 * int(domain)
    return range(base, base + 250)


def _stable_sockets(p):
    socks: list = []
    t_end = time.monotonic() + 30
    while time.monotonic() < t_end and p.alive():
        now = sorted({s for pid in _descendants(p.pid) for s in inet_sockets(pid)})
        if len([s for s in now if s[0] == 'udp']) >= 3 and now == socks:
            break                                   # participant up and its socket set stable for 1 s
        socks = now
        time.sleep(1.0)
    return socks


@pytest.mark.ros
def test_node_receives_dds_traffic_on_loopback_only(tmp_path):
    """
    With the environment of make test / CI, every socket a node receives RTPS traffic on is bound to 127.0.0.1.

    The environment: rosutil.ros_env: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, as the project requires, plus the Fast
    DDS profile.  Every socket a node receives RTPS traffic on -- the domain's discovery and user ports -- is bound to
    127.0.0.1; without the profile the same node binds them to 0.0.0.0 (the control).  What remains outside loopback are
    the two send-only sockets (ephemeral ports) that rmw_fastrtps adds in LOCALHOST mode whatever the profile says (with
    SYSTEM_DEFAULT and this profile there are none; see params/fastdds_localhost.xml) -- they are printed, and bounded
    to two.
    """
    env = rosutil.ros_env()
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    ports = _rtps_ports(int(env['ROS_DOMAIN_ID']))
    cmd = [rosutil.script('identifier'), '--ros-args', '-p', f"record_dir:={tmp_path / 'rec'}"]
    found = {}
    for label, e in (('profile', env), ('no profile', {k: v for k, v in env.items()
                                                       if not k.endswith('_DEFAULT_PROFILES_FILE')})):
        with rosutil.RosProcess(cmd, env=e, hard_timeout=60) as p:
            socks = _stable_sockets(p)
            assert p.alive(), p.output()
        found[label] = socks
    rtps = [s for s in found['profile'] if s[0] == 'udp' and s[2] in ports]
    assert len(rtps) >= 2, found
    assert all(_is_loopback(s[1]) for s in rtps), f'RTPS receive sockets outside loopback: {rtps}'
    others = [s for s in found['profile'] if not _is_loopback(s[1]) and s not in rtps]
    print(f'profile: RTPS receive sockets {rtps}; send-only sockets outside loopback {others}')
    assert len(others) <= 2 and all(s[2] not in ports for s in others), others
    control = [s for s in found['no profile'] if s[0] == 'udp' and s[2] in ports]
    assert any(not _is_loopback(s[1]) for s in control), f'control: {control}'


_MANY_PARTICIPANTS = """
import sys, time
import rclpy
from rclpy.qos import QoSProfile
from std_msgs.msg import String
n = int(sys.argv[1])
ctxs = [rclpy.Context() for _ in range(n)]
nodes = []
for k, c in enumerate(ctxs):
    rclpy.init(context=c)
    nodes.append(rclpy.create_node(f'participant{k}', context=c))
qos = QoSProfile(depth=1)
pubs = [nodes[0].create_publisher(String, 'many', qos), nodes[-2].create_publisher(String, 'many', qos)]
sub = nodes[-1].create_subscription(String, 'many', lambda m: None, qos)
t0 = time.monotonic()
while sub.get_publisher_count() < 2 and time.monotonic() - t0 < 20.0:
    time.sleep(0.1)
print(sub.get_publisher_count(), round(time.monotonic() - t0, 2))
for node, c in zip(nodes, ctxs):
    node.destroy_node()
    rclpy.shutdown(context=c)
"""


@pytest.mark.ros
def test_the_last_of_many_participants_on_one_domain_discover_each_other():
    """
    40 participants on one domain with the shipped profile: the last two still match (and the first one).

    Discovery is by unicast to the initial peers' ports only, one per participant id up to ``maxInitialPeersRange``;
    with the former range of 32, participants 38 and 39 never found each other (their publisher count stayed 1 of 2
    for 12 s), so a box with more than ten machines' three nodes on one domain would have lost its later machines.
    The range is 120, the participants one domain holds on one host (2 ports each within the domain's 250).
    """
    r = rosutil.run_python(_MANY_PARTICIPANTS, timeout=120.0, args=(40,), env=rosutil.ros_env())
    assert r.returncode == 0, r.stderr[-2000:]
    count, seconds = r.stdout.split()
    assert int(count) == 2, f'publishers matched by participant 39: {count} of 2 after {seconds} s'


@pytest.mark.ros
def test_namespace_params_file_and_param_dump_round_trip(tmp_path):
    """
    kf_estimator under ``-r __ns:=/rig1 --params-file``: namespaced topics, and ``ros2 param dump`` round-trips.

    The params file: a copy of params/kf_estimator.yaml with other values.  Its topics are /rig1/..., /diagnostics
    stays; ``ros2 param dump`` (list + get services) returns every declared parameter with the file's value, unset ones
    as [] / NaN; the dumped file starts the node again identically.
    """
    specs = node_specs.with_common(importlib.import_module('bearing_id.nodes.kf_estimator_core').SPECS)
    text = (REPO / 'params' / 'kf_estimator.yaml').read_text()
    changed = {'measurement_noise': 2.5e-07, 'speed_band': 0.02, 'input_reliability': 'best_effort'}
    for k, v in changed.items():
        text, n = re.subn(rf'^    {k}: .*$', f'    {k}: {v}', text, flags=re.M)
        assert n == 1, k
    text = text.replace('    # prebuild_speeds_rpm: (unset)', '    prebuild_speeds_rpm: [900.0]')
    changed['prebuild_speeds_rpm'] = [900.0]
    params = tmp_path / 'kf_estimator.yaml'
    params.write_text(text)
    env = rosutil.ros_env()
    dumps = []
    for k, pfile in enumerate([params, tmp_path / 'dump.yaml']):
        cmd = [rosutil.script('kf_estimator'), '--ros-args', '-r', '__ns:=/rig1', '--params-file', str(pfile)]
        with rosutil.RosProcess(cmd, env=env, hard_timeout=90) as node:
            r = rosutil.run(_client_cmd(tmp_path, {'actions': [
                {'do': 'dump', 'node': 'kf_estimator', 'ns': '/rig1', 'yaml': str(tmp_path / 'dump.yaml')}]},
                f'dump{k}'), timeout=60, env=env)
            assert r.returncode == 0 and node.alive(), r.stdout + r.stderr + node.output()
            rc, _ = node.interrupt()
            assert rc == 0 and 'parameter error' not in node.stderr, node.output()
        d = _results(r.stdout)[0]
        dumps.append(d)
        assert d['n_values'] == len(d['names']), d       # get_parameters answered for every name
        for s in specs:
            assert s.name in d['params'], (s.name, d['names'])
            assert d['params'][s.name] == _expected(s, changed.get(s.name)), s.name
        assert {'/rig1/bearing_id/bearing_displacement', '/rig1/bearing_id/innovation',
                '/diagnostics'} <= set(d['publishers']), d['publishers']
        assert {'/rig1/rotor/displacement', '/rig1/rotor/speed', '/rig1/rotor/excitation'} <= set(d['subscribers']), \
            d['subscribers']
        assert not any(t.startswith(('/rotor/', '/bearing_id/')) for t in d['publishers'] + d['subscribers']), d
    assert dumps[1]['params'] == dumps[0]['params']
    dumped = (tmp_path / 'dump.yaml').read_text()
    assert dumped.startswith('/rig1/kf_estimator:\n  ros__parameters:\n') and 'channels: []' in dumped, dumped


@pytest.mark.ros
def test_param_dump_answers_for_every_parameter_of_driver_and_identifier(tmp_path):
    env = rosutil.ros_env()
    cmds = {'sensor_driver': ['-p', 'speeds_rpm:=[600.0]', '-p', 'dwell:=0.5'],
            'identifier': ['-p', f"record_dir:={tmp_path / 'rec'}"]}
    procs = [rosutil.RosProcess([rosutil.script(n), '--ros-args', *a], env=env, hard_timeout=90)
             for n, a in cmds.items()]
    try:
        r = rosutil.run(_client_cmd(tmp_path, {'actions': [{'do': 'dump', 'node': n, 'ns': '/'} for n in cmds]}),
                        timeout=80, env=env)
        assert r.returncode == 0, r.stdout + r.stderr + ''.join(p.output() for p in procs)
    finally:
        for p in procs:
            p.close()
    overrides = {'sensor_driver': {'speeds_rpm': [600.0], 'dwell': 0.5},
                 'identifier': {'record_dir': str(tmp_path / 'rec')}}
    for n, d in zip(cmds, _results(r.stdout)):
        assert d['n_values'] == len(d['names']), (n, d)
        for s in node_specs.with_common(importlib.import_module(f'bearing_id.nodes.{n}_core').SPECS):
            assert s.name in d['params'], (n, s.name)
            assert d['params'][s.name] == _expected(s, overrides[n].get(s.name)), (n, s.name)


@pytest.mark.ros
@pytest.mark.slow(reason='three publisher kinds, each with its own node processes (~13 s)')
def test_excitation_from_volatile_and_transient_local_publishers_and_best_effort_input(tmp_path):
    """
    The identifier learns runs from transient-local and volatile publishers; best-effort input only when asked.

    The identifier learns run A from a transient-local publisher that published before it started (delivered to both of
    its excitation subscriptions, processed once) and run B from a volatile publisher offering what ``ros2 bag play``
    offers (RELIABLE, VOLATILE, depth 10).  A SensorDataQoS (best-effort) publisher of blocks connects only with
    ``input_reliability: best_effort``, which still accepts reliable publishers.
    """
    env = rosutil.ros_env()
    disp = {'do': 'match', 'topic': '/rotor/displacement', 'type': 'bearing_id_msgs/msg/DisplacementBlock',
            'qos': ['bag_play', 'sensor_data']}
    exc = {'do': 'match', 'topic': '/rotor/excitation', 'type': 'bearing_id_msgs/msg/Excitation',
           'qos': ['bag_play', 'latched', 'sensor_data']}
    with rosutil.RosProcess(_client_cmd(tmp_path, {'actions': [
            {'do': 'publish_excitation', 'run_id': 'A', 'qos': 'latched'}], 'hold': 60}, 'latched_pub'),
            env=env, hard_timeout=80) as latched_pub:
        assert _wait_for(latched_pub, r'published A', 30), latched_pub.output()
        ident_cmd = [rosutil.script('identifier'), '--ros-args', '-p', f"record_dir:={tmp_path / 'rec'}"]
        with rosutil.RosProcess(ident_cmd, env=env, hard_timeout=80) as ident:
            assert _wait_for(ident, r'excitation: run A\b', 30), ident.output() + _peers(env['ROS_DOMAIN_ID'])
            r = rosutil.run(_client_cmd(tmp_path, {'actions': [
                {'do': 'publish_excitation', 'run_id': 'B', 'qos': 'bag_play', 'wait_match': 1},
                {**exc, 'expect': {'bag_play': 1, 'latched': 2}}, {**disp, 'expect': {'bag_play': 1}}]}, 'volatile'),
                timeout=60, env=env)
            assert r.returncode == 0, r.stdout + r.stderr
            assert _wait_for(ident, r'excitation: run B\b', 20), ident.output() + _peers(env['ROS_DOMAIN_ID'])
            time.sleep(1.0)
            log = ident.stderr + ident.stdout
            assert len(re.findall(r'excitation: run A\b', log)) == 1, log     # the repeat was ignored
            assert len(re.findall(r'excitation: run B\b', log)) == 1, log
            pub_b, exc_counts, disp_counts = _results(r.stdout)
            assert pub_b == {'matched': True, 'subscriptions': 1}, pub_b
            # excitation: TRANSIENT_LOCAL + VOLATILE subscriptions; a best-effort publisher matches neither
            assert exc_counts == {'bag_play': 1, 'latched': 2, 'sensor_data': 0}, exc_counts
            assert disp_counts == {'bag_play': 1, 'sensor_data': 0}, disp_counts      # reliable input (default)
            assert ident.interrupt()[0] == 0, ident.output()
        ident_cmd = [rosutil.script('identifier'), '--ros-args', '-p', f"record_dir:={tmp_path / 'rec2'}",
                     '-p', 'input_reliability:=best_effort']            # a fresh record: run A is new to it
        with rosutil.RosProcess(ident_cmd, env=env, hard_timeout=80) as ident:
            assert _wait_for(ident, r'excitation: run A\b', 30), ident.output() + _peers(env['ROS_DOMAIN_ID'])
            r = rosutil.run(_client_cmd(tmp_path, {'actions': [
                {**exc, 'expect': {'bag_play': 1, 'latched': 2, 'sensor_data': 1}},
                {**disp, 'expect': {'bag_play': 1, 'sensor_data': 1}}]}, 'best_effort'), timeout=60, env=env)
            assert r.returncode == 0, r.stdout + r.stderr
            exc_counts, disp_counts = _results(r.stdout)
            assert exc_counts == {'bag_play': 1, 'latched': 2, 'sensor_data': 1}, exc_counts
            assert disp_counts == {'bag_play': 1, 'sensor_data': 1}, disp_counts
            assert ident.interrupt()[0] == 0, ident.output()


@pytest.mark.ros
def test_security_enabled_without_usable_keys_stops_cleanly(tmp_path):
    """
    ROS_SECURITY_ENABLE + Enforce (SROS2) with an enclave lacking its keys: the node names the cause, exits 2.

    (The PyPI Fast DDS is built without security, so here it says so; with apt's it reports the missing files.)
    """
    (tmp_path / 'keystore' / 'enclaves' / 'bearing_id' / 'kf_estimator').mkdir(parents=True)
    env = rosutil.ros_env({'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': 'Enforce',
                           'ROS_SECURITY_KEYSTORE': tmp_path / 'keystore'})
    r = rosutil.run([rosutil.script('kf_estimator'), '--ros-args', '--enclave', '/bearing_id/kf_estimator'],
                    timeout=60, env=env)
    assert r.returncode == 2, r.stdout + r.stderr
    assert 'kf_estimator: cannot start:' in r.stderr and 'Traceback' not in r.stderr, r.stderr
    assert re.search(r'security', r.stderr, re.I), r.stderr
