"""
Machines served live by one box (issue 23 item 7).

Each machine is the three nodes (sensor_driver, kf_estimator, identifier with its default method) in its own
namespace ``/mK`` with default parameters, streaming the packaged rig at 1x real time (10,240 Hz, 2 probes) from
DAQ files (the sensor_driver's ``file`` source, as a plant's DAQ would feed it; its ``sim`` source would add the
simulation's own CPU, ~0.12 core, which no plant pays), the files in a loop (``passes``).  For ``--machines`` M at
once it measures the first pass (start-up: every speed's filter model and first identification are computed there)
and a ``--window`` in the later passes (steady: what a plant running for months pays):

* CPU per machine (the three processes' CPU seconds / wall seconds, from /proc/<pid>/stat) and per node;
* whether the box kept up (the drivers' late blocks, from /diagnostics);
* the identifier's latency (last block of a window -> its coefficients published; its /diagnostics values);
* resident memory per machine (VmRSS of its three processes), and its proportional share (PSS, from
  /proc/<pid>/smaps_rollup: the pages of shared libraries divided among the processes that map them -- what a box
  of many machines really spends per machine).

The machines one 2-core box can serve = 2 / (CPU per machine), given the figures stay put as M grows (they are
printed for each M to show it).

Machines beyond ``--per-domain`` (default 39) go on further domain ids, split evenly (one domain holds 120
participants on one host with the shipped profile; this benchmark's listener is one of them).  Discovery costs grow
with the square of the participants on a domain (the "DDS threads" column): many machines go on domains of a few.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_machines.py [--machines 1,4] [--window 20] [--floor]
          [--block-size N] [--dwell S] [--per-domain N] [--stagger S]
      50 machines:  --machines 50 --per-domain 5 --block-size 8192 --dwell 20 --window 40 --stagger 6
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread setting above)
from collections import Counter  # noqa: E402
import faulthandler  # noqa: E402
from pathlib import Path  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'benchmarks'))

from bearing_id.config.params import load_rig  # noqa: E402, I100
from bearing_id.demo import Listener, ros_env, stop_processes  # noqa: E402
from bearing_id.io.recordings import save_npz  # noqa: E402
from bearing_id.simulation.rig import simulate_run  # noqa: E402
from bench_streaming import _domain_ids, cpu_seconds, memory_mb, stat_cpu_seconds  # noqa: E402

NODES = ('sensor_driver', 'kf_estimator', 'identifier')
CORES = 2
# machines of three nodes one domain holds beside this benchmark's listener (120 participants on one host with
# params/fastdds_localhost.xml; the 121st is never discovered)
PER_DOMAIN = 39
MEM_RESERVE_MB = 1500    # start no further machine when the box has less than this available


def start(machine: str, node: str, env: dict, log_dir: Path, params=(), floor: bool = False) -> subprocess.Popen:
    """
    Start one node of ``machine`` in namespace /machine with default parameters (plus ``params``).

    ``floor``: kf_estimator and identifier are ``transport_floor.py``'s stand-ins (the messages, no computation).
    """
    if floor and node != 'sensor_driver':
        cmd = [sys.executable, str(REPO / 'benchmarks' / 'transport_floor.py'), node]
        params = ()
    else:
        cmd = [sys.executable, '-m', f'bearing_id.nodes.{node}']
    cmd += ['--ros-args', '-r', f'__ns:=/{machine}']
    for p in params:
        cmd += ['-p', p]
    log = open(log_dir / f'{machine}_{node}.log', 'w')
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def pss_mb(pid: int) -> float:
    """Return the proportional set size [MB] of process ``pid`` (NaN where smaps_rollup is not readable)."""
    try:
        for line in open(f'/proc/{pid}/smaps_rollup'):
            if line.startswith('Pss:'):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float('nan')


def daq_files(out: Path, dwell: float | None = None) -> tuple[list[str], float]:
    """
    Simulate the packaged rig's runs once into .npz DAQ files (the drivers' file source); (paths, one pass [s]).

    ``dwell`` [s] at each speed (default: the rig's 2 s, a run-up test: a new steady window every 2.5 s per run).
    """
    rig = load_rig()
    recs = [simulate_run(rig, r, dwell=dwell) for r in rig.simulation.runs]
    paths = [str(save_npz(rec, out / f'run_{r.id}.npz')) for rec, r in zip(recs, rig.simulation.runs)]
    return paths, sum(rec.samples.shape[0] / rec.sample_rate for rec in recs)


def available_mb() -> float:
    """Return the box's available memory [MB] (MemAvailable of /proc/meminfo)."""
    for line in open('/proc/meminfo'):
        if line.startswith('MemAvailable:'):
            return int(line.split()[1]) / 1024
    return float('inf')


def _late(listeners, machines) -> int:
    """Return the drivers' late blocks so far (their /diagnostics ``late_blocks``, cumulative)."""
    return sum(int(li.diag_values.get(f'{mc}/sensor_driver: source', {}).get('late_blocks', 0))
               for li, group in listeners for mc in group)


def dds_cpu(procs) -> float:
    """Return the CPU seconds so far of the processes' Fast DDS threads (``dds.*``: discovery, events, transports)."""
    total = 0.0
    for p in procs.values():
        for task in Path(f'/proc/{p.pid}/task').glob('*'):
            try:
                if (task / 'comm').read_text().startswith('dds.'):
                    total += stat_cpu_seconds(task / 'stat')
            except (OSError, IndexError, ValueError):      # a thread that ended meanwhile
                pass
    return total


def _cpu(procs) -> dict:
    return {k: cpu_seconds(p.pid) for k, p in procs.items()}


def _per_node(c0, c1, wall, machines) -> dict:
    m = len(machines)
    return {n: sum(c1[(mc, n)] - c0[(mc, n)] for mc in machines) / wall / m for n in NODES}


def run(m: int, window: float, settle: float, out: Path, files: list[str], pass_s: float, floor: bool = False,
        block_size: int = 0, stagger: float = 0.0, per_domain: int = PER_DOMAIN) -> dict:
    """
    Stream ``m`` machines at once (the files in a loop); return the figures of the first pass and of later passes.

    Machines go on as few domains as hold ``per_domain`` machines each, split evenly (one listener per domain),
    started ``stagger`` s apart.  First pass: from the moment every driver publishes to the end of the first pass
    (every speed's filter model and first identification are computed there: start-up).  Steady: ``window`` s from
    ``settle`` s into the second pass of the last machine started (what a plant running for months pays).  Late
    blocks are counted up to the steady window and in it.
    """
    out.mkdir(parents=True, exist_ok=True)
    machines = [f'm{k + 1}' for k in range(m)]
    n_dom = -(-m // per_domain)
    groups = [machines[k * m // n_dom:(k + 1) * m // n_dom] for k in range(n_dom)]     # as even as can be
    envs = [ros_env(d) for d in _domain_ids(len(groups))]
    os.environ.update({k: envs[0][k] for k in envs[0] if k.startswith(('ROS_', 'FAST'))})
    passes = 3 + int((settle + window + stagger * m) // pass_s)
    procs, row = {}, None
    listeners = [(Listener(int(env['ROS_DOMAIN_ID'])), group) for env, group in zip(envs, groups)]
    try:
        for k, (mc, env) in enumerate((mc, env) for env, group in zip(envs, groups) for mc in group):
            if available_mb() < MEM_RESERVE_MB:
                raise RuntimeError(f'{available_mb():.0f} MB available after {k} machine(s): '
                                   f'not starting {m} (logs in {out})')
            rec = out / mc / 'record'
            procs[(mc, 'identifier')] = start(mc, 'identifier', env, out, [f'record_dir:={rec}'], floor)
            procs[(mc, 'kf_estimator')] = start(mc, 'kf_estimator', env, out, floor=floor)
            procs[(mc, 'sensor_driver')] = start(mc, 'sensor_driver', env, out, [
                'wait_for_subscribers:=2', 'source:=file', f"files:=[{','.join(files)}]", f'passes:={passes}',
                *([f'block_size:={block_size}'] if block_size else [])])
            time.sleep(stagger)
        t_end = time.monotonic() + 180 + 3 * m
        while time.monotonic() < t_end:                 # every driver publishing
            time.sleep(0.1)
            st = [li.diag.get(f'{mc}/sensor_driver: source') for li, group in listeners for mc in group]
            if all(s and s[1].startswith('publishing') for s in st):
                break
        else:
            missing = [mc for li, group in listeners for mc in group
                       if not (li.diag.get(f'{mc}/sensor_driver: source') or ('', ''))[1].startswith('publishing')]
            text = f'not every driver started publishing ({len(missing)} not: {missing[:5]}); logs in {out}'
            print(text, file=sys.stderr, flush=True)     # a Fast DDS teardown hang below must not swallow it
            raise RuntimeError(text)
        t_start, c_start = time.monotonic(), _cpu(procs)
        time.sleep(max(0.0, t_start + pass_s - time.monotonic()))
        t_first, c_first = time.monotonic(), _cpu(procs)
        time.sleep(settle)
        c0, d0, t0, late0 = _cpu(procs), dds_cpu(procs), time.monotonic(), _late(listeners, machines)
        time.sleep(window)
        c1, d1 = _cpu(procs), dds_cpu(procs)
        wall = time.monotonic() - t0
        time.sleep(2.0)                                 # the drivers publish /diagnostics every second
        late1 = _late(listeners, machines)
        rss = {k: memory_mb(p.pid)[0] for k, p in procs.items()}
        pss = {k: pss_mb(p.pid) for k, p in procs.items()}
        lat = [float(v) for li, group in listeners for mc in group
               for k, v in li.diag_values.get(f'{mc}/identifier: accumulation', {}).items() if k == 'max_latency_s']
        first = _per_node(c_start, c_first, t_first - t_start, machines)
        per_node = _per_node(c0, c1, wall, machines)
        row = {'m': m, 'cpu_machine': sum(per_node.values()), 'per_node': per_node, 'late_start': late0,
               'late': late1 - late0, 'domains': len(groups), 'dds': (d1 - d0) / wall / m,
               'cpu_first': sum(first.values()), 'max_latency': max(lat) if lat else float('nan'),
               'rss_machine': sum(rss.values()) / m, 'pss_machine': sum(pss.values()) / m}
        print_row(row)                      # before the teardown below, which Fast DDS can hang
    finally:
        codes = stop_processes({f'{a}/{b}': p for (a, b), p in procs.items()}, timeout=10.0 + 0.5 * len(procs))
        print(f'{m} machines, node exits: ' + ', '.join(
            f'{c} x{n}' for c, n in sorted(Counter(map(str, codes.values())).items())), flush=True)
        for (mc, node), p in procs.items():      # a node that did not exit 0: the end of its log (deleted after)
            code = codes.get(f'{mc}/{node}')
            if code != 0:
                tail = (out / f'{mc}_{node}.log').read_text(errors='replace').splitlines()[-12:]
                print(f'{mc}/{node} exit {code}; its log ends:\n  ' + '\n  '.join(tail), flush=True)
        # Fast DDS's teardown can hang holding the GIL (eProsima/Fast-DDS#6513), where Listener.close's watchdog
        # thread cannot run: faulthandler's own thread ends the process then (exit 1), the figures already printed
        faulthandler.dump_traceback_later(60.0, exit=True)
        for li, _ in listeners:
            li.close()
        faulthandler.cancel_dump_traceback_later()
    return row


def print_header(pass_s: float, floor: bool) -> None:
    """Print the table's title and column names."""
    if floor:
        print('TRANSPORT FLOOR: kf_estimator and identifier are stand-ins that only move the messages')
    print(f'one pass of the files: {pass_s:.1f} s; CPU per machine [core] in the first pass (start-up) and in later '
          f'passes (steady; "DDS threads": the part spent in Fast DDS\'s own threads, discovery and transport)')
    print('machines  domains  first pass  steady  DDS threads  sensor_driver  kf_estimator  identifier  late blocks '
          '(start-up / steady)  max latency [s]  RSS/machine [MB]  PSS/machine [MB]  served by 2 cores', flush=True)


def print_row(r: dict) -> None:
    """Print one machine count's figures (a row of :func:`print_header`'s table)."""
    n = r['per_node']
    late = f"{r['late_start']} / {r['late']}"
    print(f"{r['m']:8d}  {r['domains']:7d}  {r['cpu_first']:10.3f}  {r['cpu_machine']:6.3f}  {r['dds']:11.3f}  "
          f"{n['sensor_driver']:13.3f}  {n['kf_estimator']:12.3f}  {n['identifier']:10.3f}  {late:>30}  "
          f"{r['max_latency']:15.2f}  {r['rss_machine']:16.0f}  {r['pss_machine']:16.0f}  "
          f"{CORES / r['cpu_machine']:17.1f}", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--machines', default='1,4', help='comma-separated machine counts to run (default 1,4)')
    ap.add_argument('--window', type=float, default=20.0, help='measurement window [s] (default 20)')
    ap.add_argument('--settle', type=float, default=5.0, help='seconds into the second pass before the steady window '
                    '(default 5)')
    ap.add_argument('--floor', action='store_true', help='the transport floor: kf_estimator and identifier replaced by '
                    'stand-ins that receive (and, for kf_estimator, publish) the same messages and compute nothing '
                    '(benchmarks/transport_floor.py)')
    ap.add_argument('--dwell', type=float, default=None, help='seconds at each speed in the DAQ files (default: the '
                    "packaged rig's 2 s, a run-up; a plant in steady running changes speed far less often)")
    ap.add_argument('--per-domain', type=int, default=PER_DOMAIN, help=f'most machines per domain id (default '
                    f"{PER_DOMAIN}: with this benchmark's listener, the 120 participants one domain holds with the "
                    f'shipped profile)')
    ap.add_argument('--stagger', type=float, default=0.0, help="seconds between two machines' starts (default 0: "
                    'all at once)')
    ap.add_argument('--block-size', type=int, default=0, help="the drivers' samples per DisplacementBlock (default: "
                    "sensor_driver's own, params/sensor_driver.yaml)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        files, pass_s = daq_files(Path(tmp), args.dwell)
        print_header(pass_s, args.floor)
        for m in (int(s) for s in args.machines.split(',')):
            run(m, args.window, args.settle, Path(tmp) / f'm{m}', files, pass_s, args.floor, args.block_size,
                args.stagger, args.per_domain)
    return 0


if __name__ == '__main__':
    sys.exit(main())
