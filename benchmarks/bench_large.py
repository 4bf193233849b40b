"""
Scale benchmark (issues 12 and 22): `bearing-id model` and a 9-speed identification by every method, 160 elements.

Rotor: ``params/examples/plant_like.yaml`` (a between-bearings compressor-type rotor, schema v2) with each of its
32 elements split into 5 (``--factor``): 160 Timoshenko elements, 161 nodes, the discs, coupling mass, bearings,
seal, probes and forces at the same positions (node n -> 5 (n - 1) + 1).  The DE bearing's pedestal is dropped by
default so that every method applies (paper and conventional refuse bearings on pedestals); ``--pedestal`` keeps it
(paper and conventional are then reported as not applicable).

Data: the example's own plan (run A, residual unbalance at two impellers; runs F13x/F13y/F21x/F21y, a synchronous
directional shaker) simulated in the time domain by ``rig.simulate_run`` at 9 speeds (1500 ... 4000 rpm, the
example's dwell, noise and truth: viscosity and clearance 7 ... 15 % off the nominal), all 6 probes
(+-45 deg pairs beside each bearing and at midspan) -> ``identify.harmonics.from_recordings``.  Not timed.

Timed: ``bearing-id model --params <this rotor> --out <tmp>`` as a process with its default options (the machine's
speed range, Campbell diagram, critical speeds, stability threshold, mode shapes, plots; target <= 10 s, issue 22);
``identify.identify(method, model, rig, data)`` in-process, the model built inside the timed call and the
bearing-solution cache cleared before it (nothing reused from a previous repeat: the plausibility gate's stability
threshold is kept on the model object), wall (``perf_counter``) and CPU (``process_time``), min and median over
``--repeats`` (default 3: a paper-method repeat at 160 elements takes seconds and the machine is shared).  Methods:
paper (``options={'reduce': True}``, the Kalman filter on the Craig-Bampton reduction), conventional (if it applies
to these probes), direct, physical.  Target: <= 10 s per method (judged on the CPU minimum; the load average is
printed with the table).  Accuracy: eq. 38 error [%] (mean |(true - identified) / true| over speeds and the four K or C
entries of both bearings) against the simulator's true bearings, over the entries the method calls determined and
over all it returns; the not-determined entries are counted.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_large.py [--repeats 3] [--factor 5] [--pedestal]
      [--methods paper,direct,physical,conventional] [--no-model]
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')       # before numpy: threaded BLAS slows the small solves
os.environ.setdefault('OMP_NUM_THREADS', '1')
os.environ.setdefault('MKL_NUM_THREADS', '1')

import argparse  # noqa: E402, I100  (after the thread settings above)
import copy  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchlib as bl  # noqa: E402, I100  (after the sys.path insert above)

EXAMPLE = bl.ROOT / 'params' / 'examples' / 'plant_like.yaml'
SPEEDS_RPM = tuple(np.linspace(1500.0, 4000.0, 9))
TARGET_S = 10.0
OPTIONS = {'paper': {'reduce': True}}


def large_params(factor: int = 5, pedestal: bool = False) -> dict:
    """Return the plant-like example's params with every element split into ``factor`` (the YAML's dict)."""
    from bearing_id.config.params import load_yaml_bounded
    d = copy.deepcopy(load_yaml_bounded(EXAMPLE))

    def node(n):
        return factor * (int(n) - 1) + 1

    for s in d['shaft']['sections']:
        s['n_elements'] = int(s['n_elements']) * factor
    for key in ('discs', 'point_masses', 'bearings', 'seals', 'probes'):
        for x in d.get(key) or ():
            x['node'] = node(x['node'])
    for b in d['bearings']:
        if not pedestal:
            b.pop('support', None)
    for r in d['simulation']['runs']:
        for e in r['excitation']:
            e['node'] = node(e['node'])
    return d


def large_rig(factor: int = 5, pedestal: bool = False):
    """Return the plant-like example with every element split into ``factor`` (RigParams)."""
    from bearing_id.config.params import parse_rig
    return parse_rig(large_params(factor, pedestal), base_dir=EXAMPLE.parent)


def time_model(factor: int, pedestal: bool, repeats: int):
    """Time ``bearing-id model --params <the large rig> --out <tmp>`` as a process (default options)."""
    import yaml
    with tempfile.TemporaryDirectory() as tmp:
        params = Path(tmp) / 'large.yaml'
        params.write_text(yaml.safe_dump(large_params(factor, pedestal)))
        return bl.time_process(bl.cli('model', '--params', params, '--out', Path(tmp) / 'model'), repeats,
                               ok_codes=(0,))


def simulate(rig):
    """
    Return HarmonicData of the example's runs at SPEEDS_RPM (time-domain simulation, the example's truth).

    Each dwell is simulated from its steady state (as bench_accuracy's ``steady_start``) and the dwells of a run are
    joined into one record, keyphasor angle advanced by whole revolutions: the simulator's ramps would take one dense
    eigendecomposition of the 2 ndof state matrix per ramp step (~1.3 s each at 160 elements, minutes per run).
    """
    from bearing_id.identify.harmonics import from_recordings
    from bearing_id.simulation.rig import simulate_run
    from bench_accuracy import join_dwells
    return from_recordings([join_dwells([simulate_run(rig, run, speeds_rpm=(s,), ramp=0.0, seed=11 + 97 * k + j)
                                         for j, s in enumerate(SPEEDS_RPM)])
                            for k, run in enumerate(rig.simulation.runs)])


def accuracy(results, data) -> tuple:
    """
    Return eq. 38 errors [%] against the simulator's truth: (K, C over the determined entries; K, C over all entries).

    Plus (entries not determined, all entries).  "All" includes the values a method returns but does not call
    determined (e.g. the paper method's prior-pulled ones), so a method is not judged only on what it vouches for.
    """
    errs = {'K': [], 'C': [], 'K_all': [], 'C_all': []}
    nd = tot = 0
    for r in results:
        truth = data.truth_at(r.speed)
        for i, node in enumerate(r.nodes):
            Kt, Ct = truth[node]
            for name, est, tr, det in (('K', r.K[i], Kt, r.K_determined[i]), ('C', r.C[i], Ct, r.C_determined[i])):
                for a in range(2):
                    for b in range(2):
                        tot += 1
                        e = abs((tr[a, b] - est[a, b]) / tr[a, b]) * 100
                        if np.isfinite(e):
                            errs[name + '_all'].append(e)
                        if not det[a, b] or not np.isfinite(e):
                            nd += 1
                            continue
                        errs[name].append(e)
    mean = {k: (float(np.mean(v)) if v else math.nan) for k, v in errs.items()}
    return mean['K'], mean['C'], mean['K_all'], mean['C_all'], nd, tot


def run_method(method, rig, data):
    """One whole identification: model built, bearing cache cleared, identify() with the gates."""
    from bearing_id import bearings
    from bearing_id.identify import identify
    from bearing_id.rotor.assembly import RotorModel
    bearings._solve.cache_clear()
    model = RotorModel.from_params(rig)
    return identify(method, model, rig, data, options=OPTIONS.get(method))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--factor', type=int, default=5, help='elements per element of the example (32 x factor)')
    ap.add_argument('--pedestal', action='store_true', help="keep the DE bearing's pedestal")
    ap.add_argument('--methods', default='paper,conventional,direct,physical')
    ap.add_argument('--no-model', action='store_true', help='skip the `bearing-id model` row')
    args = ap.parse_args(argv)
    from bearing_id.rotor.assembly import RotorModel
    rig = large_rig(args.factor, args.pedestal)
    model = RotorModel.from_params(rig)
    t0 = time.perf_counter()
    data = simulate(rig)
    t_sim = time.perf_counter() - t0
    args_text = ' '.join(argv if argv is not None else sys.argv[1:])
    cmd = 'OPENBLAS_NUM_THREADS=1 python benchmarks/bench_large.py ' + args_text
    print(f'# Scale benchmark: 9-speed identification on a {rig.shaft.n_elements}-element rotor\n\n'
          f'command: `{cmd}`\n\n{rig.name} refined x{args.factor}: {rig.shaft.n_elements} elements, {model.ndof} DOFs '
          f'({2 * model.ndof} states), pedestal {"kept" if args.pedestal else "dropped"}; {len(rig.simulation.runs)} '
          f'runs x {len(data.speeds)} speeds x {len(data.probes)} probes (simulated in {t_sim:.1f} s wall, not timed); '
          f'{args.repeats} repeats; {bl.load_note()}\n')
    rows = []
    if not args.no_model:
        t = time_model(args.factor, args.pedestal, args.repeats)
        rows.append(bl.timing_row('`bearing-id model` (process, default options)', t, TARGET_S, 'cpu',
                                  ['', '', '', '', '']) + ['Campbell, critical speeds, stability, mode shapes, plots'])
        print(f'model: CPU min {t.cpu_min:.2f} s', file=sys.stderr, flush=True)
    for method in args.methods.split(','):
        try:
            t = bl.time_call(lambda: run_method(method, rig, data), args.repeats)
        except (ValueError, np.linalg.LinAlgError) as e:
            rows.append([method, 'n/a', '', '', '', '', '', '', '', f'<= {TARGET_S:g} s', '-',
                         str(e).split('\n')[0][:90]])
            continue
        ek, ec, eka, eca, nd, tot = accuracy(t.out, data)
        acc = [('-' if math.isnan(v) else f'{v:.2f}') for v in (ek, ec, eka, eca)] + [f'{nd}/{tot}']
        rows.append(bl.timing_row(method + (' (reduce)' if method == 'paper' else ''), t, TARGET_S, 'cpu', acc)
                    + [''])
        print(f'{method}: CPU min {t.cpu_min:.2f} s', file=sys.stderr, flush=True)
    print(bl.table(bl.TIMING_HEADER + ['K err % (det.)', 'C err % (det.)', 'K err % (all)', 'C err % (all)',
                                       'not determined', 'target', 'met', 'note'], rows))
    print(f'\n{bl.load_note()} (after)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
