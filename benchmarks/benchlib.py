"""
Shared helpers of the benchmarks: repeated timings (wall and CPU), child processes with their own rusage, cached data.

Every figure is the min and the median over ``repeats`` runs, wall time (``time.perf_counter``) and CPU time
(``time.process_time`` plus reaped children's ``getrusage`` in-process; user + system from ``os.wait4`` for a child
process -- both include the worker processes a command forked).  A child's peak RSS is its own ``VmHWM``
(``/proc/<pid>/status``, read while it runs), or more while its forked workers hold memory of their own
(:func:`run_process`):
``wait4``'s ``ru_maxrss`` is not the child's own -- Linux carries the RSS of the process that spawned it into it at
``exec`` (this benchmark's own ~160 MiB showed up as every child's peak).  The machine load
(``os.getloadavg``) is printed with every table: compare figures as ratios within one run.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
import hashlib
import io
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / 'out' / 'bench_data'


def compile_package() -> None:
    """
    Write the package's bytecode before timing processes, as a regular install has it.

    With PYTHONDONTWRITEBYTECODE set (as on this machine) an editable install would compile every module at each
    process start, which is not what a user's installed package does.
    """
    subprocess.run([sys.executable, '-m', 'compileall', '-q', str(ROOT / 'bearing_id')], check=False,
                   stdout=subprocess.DEVNULL)


compile_package()


@dataclass
class Timing:
    """Wall and CPU times [s] of the repeats of one job, and (process jobs) the peak RSS [MiB] of each repeat."""

    wall: list
    cpu: list
    rss: list | None = None
    out: object = None

    @property
    def wall_min(self) -> float:
        return min(self.wall)

    @property
    def wall_med(self) -> float:
        return statistics.median(self.wall)

    @property
    def cpu_min(self) -> float:
        return min(self.cpu)

    @property
    def cpu_med(self) -> float:
        return statistics.median(self.cpu)

    @property
    def rss_max(self) -> float:
        return max(self.rss) if self.rss else float('nan')


def time_call(fn, repeats: int, *, warmup: int = 0, quiet: bool = True) -> Timing:
    """Call ``fn()`` ``warmup`` + ``repeats`` times (stdout/stderr swallowed when ``quiet``); time the repeats."""
    wall, cpu, out = [], [], None
    for k in range(warmup + repeats):
        sink = io.StringIO()
        with contextlib.ExitStack() as st:
            if quiet:
                st.enter_context(contextlib.redirect_stdout(sink))
                st.enter_context(contextlib.redirect_stderr(sink))
            w0, c0 = time.perf_counter(), time.process_time()
            out = fn()
            w1, c1 = time.perf_counter(), time.process_time()
        if k >= warmup:
            wall.append(w1 - w0)
            cpu.append(c1 - c0)
    return Timing(wall, cpu, None, out)


def _proc_mib(path: str, key: str) -> float:
    """Return the ``key`` line of a /proc file (a size in kB) in MiB, or 0 when it is not readable."""
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key):
                    return float(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return 0.0


def _vm_hwm(pid: int) -> float:
    """Return the peak RSS [MiB] of process ``pid``'s own address space (VmHWM), or 0 when it is not readable."""
    return _proc_mib(f'/proc/{pid}/status', 'VmHWM:')


def _descendants(pid: int) -> list:
    """Return the pids of ``pid``'s children, grandchildren, ... (from /proc/<pid>/task/*/children)."""
    out, todo = [], [pid]
    while todo:
        q = todo.pop()
        try:
            tasks = os.listdir(f'/proc/{q}/task')
        except OSError:
            continue
        for t in tasks:
            try:
                with open(f'/proc/{q}/task/{t}/children') as fh:
                    kids = [int(v) for v in fh.read().split()]
            except (OSError, ValueError):
                continue
            out += kids
            todo += kids
    return out


def _private(pid: int) -> float:
    """Return the memory [MiB] process ``pid`` holds alone (Private_Clean + Private_Dirty: not shared with any)."""
    path = f'/proc/{pid}/smaps_rollup'
    return _proc_mib(path, 'Private_Clean:') + _proc_mib(path, 'Private_Dirty:')


def run_process(argv, env=None, timeout: float = 900.0) -> tuple[float, float, float, int]:
    """
    Run ``argv`` as a child process -> (wall s, CPU s (user + system), peak RSS MiB, exit code).

    The CPU time includes that of the worker processes it forked and reaped.  The peak RSS is the larger of the
    child's VmHWM polled every 2 ms while it runs (its last reading before exit) and, while it has worker processes,
    the largest sum of its resident memory and their private memory (what they hold alone; what they share with it
    is in its own) seen every 10 ms: the process tree's peak, sampled; nan if never read.
    """
    e = dict(os.environ)
    e.update(env or {})
    w0 = time.perf_counter()
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=e, cwd=str(ROOT))
    deadline = w0 + timeout
    hwm = 0.0
    k = 0
    while True:
        hwm = max(hwm, _vm_hwm(p.pid))
        k += 1
        if k % 5 == 0:
            kids = _descendants(p.pid)
            if kids:
                hwm = max(hwm, _proc_mib(f'/proc/{p.pid}/status', 'VmRSS:') + sum(_private(c) for c in kids))
        pid, status, ru = os.wait4(p.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() > deadline:
            p.kill()
            pid, status, ru = os.wait4(p.pid, 0)
            break
        time.sleep(0.002)
    wall = time.perf_counter() - w0
    p.returncode = os.waitstatus_to_exitcode(status)
    return wall, ru.ru_utime + ru.ru_stime, (hwm if hwm > 0 else float('nan')), p.returncode


def time_process(argv, repeats: int, env=None, ok_codes=(0, 1)) -> Timing:
    """Time a command ``repeats`` times as a fresh process; a run exiting outside ``ok_codes`` is an error."""
    wall, cpu, rss = [], [], []
    for _ in range(repeats):
        w, c, r, code = run_process(argv, env)
        if code not in ok_codes:
            raise RuntimeError(f"{' '.join(map(str, argv))} exited {code}")
        wall.append(w)
        cpu.append(c)
        rss.append(r)
    return Timing(wall, cpu, rss)


CHILD = r"""
import json, os, sys, time
sys.path.insert(0, {root!r})
{setup}
def cpu():  # this process and its reaped children, in us
    import resource
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + r.ru_utime + r.ru_stime
w0, c0 = time.perf_counter(), cpu()
{timed}
w1, c1 = time.perf_counter(), cpu()
print('BENCH ' + json.dumps([w1 - w0, c1 - c0]))
"""


def time_in_child(setup: str, timed: str, repeats: int, env=None) -> Timing:
    """
    Time ``timed`` (Python statements) in a fresh interpreter after ``setup`` (imports, data), ``repeats`` times.

    In-process figures with the imports done but every cache cold (the bearing-coefficient caches, the model's
    stability threshold): what a caller sees on a new input; a repeated call in one process would reuse them.  The CPU
    time includes that of the worker processes the command forked (reaped before the clock stops).
    """
    wall, cpu = [], []
    code = CHILD.format(root=str(ROOT), setup=setup, timed=timed)
    e = dict(os.environ)
    e.update(env or {})
    for _ in range(repeats):
        out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=e, cwd=str(ROOT),
                             timeout=1800)
        line = [x for x in out.stdout.splitlines() if x.startswith('BENCH ')]
        if out.returncode != 0 or not line:
            raise RuntimeError(f'child failed ({out.returncode}): {out.stderr[-2000:]}')
        w, c = json.loads(line[-1][6:])
        wall.append(w)
        cpu.append(c)
    return Timing(wall, cpu)


def cli_in_child(argv, repeats: int, setup: str = '', ok_codes=(0, 1)) -> Timing:
    """Time ``bearing_id.cli.main(argv)`` in a fresh interpreter (modules imported first, output discarded)."""
    imports = ('import contextlib, io\nfrom bearing_id.cli import main, build_parser\nbuild_parser()\n'
               + IMPORTS.get(argv[0], '') + '\n' + setup)
    timed = (f'with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n'
             f'    rc = main({list(map(str, argv))!r})\n'
             f'assert rc in {tuple(ok_codes)!r}, rc')
    return time_in_child(imports, timed, repeats)


# the libraries the physics imports on first use (lazily, so that a process that never needs them does not pay for
# them): in-process figures import them before the clock too, like every other module; the process rows carry them
LIBS = 'import scipy.linalg, scipy.optimize, scipy.sparse, scipy.sparse.linalg, scipy.special\n'
IMPORTS = {     # what each command imports on its way (imported before the clock starts)
    'identify': (LIBS + 'import bearing_id.commands.identify, bearing_id.commands.inputs, bearing_id.simulation.rig, '
                 'bearing_id.identify, bearing_id.identify.harmonics, bearing_id.identify.plausibility, '
                 'bearing_id.identify.paper, bearing_id.identify.conventional, bearing_id.identify.direct, '
                 'bearing_id.identify.physical, bearing_id.identify.lsq, bearing_id.estimation.kalman, '
                 'bearing_id.signals.harmonics, bearing_id.bearings, bearing_id.rotor.stability, '
                 'bearing_id.rotor.assembly, bearing_id.excitation'),
    'diagnose': (LIBS + 'import bearing_id.commands.diagnose, bearing_id.commands.inputs, bearing_id.simulation.rig, '
                 'bearing_id.identify, bearing_id.identify.harmonics, bearing_id.identify.plausibility, '
                 'bearing_id.identify.physical, bearing_id.identify.direct, bearing_id.estimation.kalman, '
                 'bearing_id.signals.harmonics, bearing_id.bearings, bearing_id.rotor.assembly, bearing_id.diagnose, '
                 'bearing_id.diagnose.locate, bearing_id.diagnose.selection, bearing_id.diagnose.effects, '
                 'bearing_id.diagnose.report'),
}


def cli(*args) -> list:
    """Return the argv of the ``bearing-id`` console command (the installed script next to this Python, else -m)."""
    script = Path(sys.executable).with_name('bearing-id')
    return ([str(script)] if script.exists() else [sys.executable, '-m', 'bearing_id.cli']) + [str(a) for a in args]


def simulated(speeds_rpm, *, dwell: float | None = None, probes: str | None = None, fresh: bool = False) -> list:
    """
    Return the two run files (run_A.npz, run_B.npz) of ``bearing-id simulate`` with these settings.

    Cached in out/bench_data/<hash of params/rig.yaml, bearing_id/simulation/rig.py and bearing_id/io/recordings.py
    (the simulator and the file writer) and the settings>/ (``fresh``: simulate again).
    """
    args = ['--speeds', ','.join(f'{float(s):g}' for s in speeds_rpm)]
    if dwell is not None:
        args += ['--dwell', f'{dwell:g}']
    if probes:
        args += ['--probes', probes]
    sources = [ROOT / 'params' / 'rig.yaml', ROOT / 'bearing_id' / 'simulation' / 'rig.py',
               ROOT / 'bearing_id' / 'io' / 'recordings.py']
    key = hashlib.sha256(b''.join(f.read_bytes() for f in sources) + ' '.join(args).encode()).hexdigest()[:16]
    d = DATA / key
    files = [d / 'run_A.npz', d / 'run_B.npz']
    if fresh or not all(f.exists() for f in files):
        d.mkdir(parents=True, exist_ok=True)
        subprocess.run(cli('simulate', *args, '--out', d), check=True, cwd=str(ROOT), stdout=subprocess.DEVNULL,
                       timeout=1800)
        (d / 'settings.txt').write_text(' '.join(args) + '\n')
    return files


def load_note() -> str:
    """One line: the 1-, 5- and 15-minute load averages and the cores."""
    a = os.getloadavg()
    return f'load average {a[0]:.2f} {a[1]:.2f} {a[2]:.2f} on {os.cpu_count()} cores'


def yes(ok) -> str:
    return '-' if ok is None else ('yes' if ok else 'NO')


def fmt_s(v: float) -> str:
    """Seconds with 3 significant figures (ms below 0.1 s)."""
    return f'{1e3 * v:.3g} ms' if v < 0.1 else f'{v:.3g} s'


def table(header, rows) -> str:
    """Return a markdown table."""
    out = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    out += ['| ' + ' | '.join(str(c) for c in r) + ' |' for r in rows]
    return '\n'.join(out)


def timing_row(name: str, t: Timing, target: float | None = None, basis: str = 'cpu', extra=()) -> list:
    """Return a row: name, wall min/median, CPU min/median, target, met (judged on ``basis``: 'wall' or 'cpu' min)."""
    v = t.wall_min if basis == 'wall' else t.cpu_min
    tgt = '' if target is None else f'<= {fmt_s(target)}'
    return [name, fmt_s(t.wall_min), fmt_s(t.wall_med), fmt_s(t.cpu_min), fmt_s(t.cpu_med), *extra, tgt,
            yes(None if target is None else v <= target)]


TIMING_HEADER = ['job', 'wall min', 'wall median', 'CPU min', 'CPU median']
