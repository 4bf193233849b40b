"""
CPU of ``diagnose()`` on the two machine sizes issue 24 sets targets for, printed case by case.

Cases (recordings simulated here, 1 % noise; the CPU is ``time.process_time`` of the ``diagnose`` call alone):

* ``rig3``: the packaged paper rig (11 nodes) with x/y probes at three stations (nodes 3, 6, 9), its runs A and B
  over its 9 speeds (2 s dwells, 0.5 s ramps), the simulated truth's bearings off theory as in params/rig.yaml and a
  pedestal under bearing 2 in y (1.5e5 N/m, 0.2 kg): target <= 20 s.
* ``compressor`` / ``compressor_force``: ROSS's 6-stage compressor as ``bearing-id import-ross`` gives it (56
  nodes, bearing and seal tables), +-45 deg probe pairs at nodes 9, 28 and 48, 7 speeds 4400-8000 rpm, 2 s dwells
  (``compressor_params`` of test/test_identify_tables.py); both bearing tables scaled coefficient by coefficient in
  the truth (factors below, not the tests'); its two unbalance runs, or four 200 N directional-force runs (x and y
  at two discs): target <= 60 s.

CPU time is less sensitive than wall time to the other load on this machine, but a busy machine still slows it
(shared caches, frequency); the load average is printed.  Each case prints its verdict so a change that speeds
diagnose up by answering differently is visible.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_diagnose_cpu.py [--cases rig3,compressor,compressor_force]
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import sys
import time

import yaml

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / 'test'))
from bearing_id.config.params import parse_rig  # noqa: E402, I100  (after the sys.path insert above)
from bearing_id.diagnose import diagnose  # noqa: E402
from bearing_id.rotor.assembly import RotorModel  # noqa: E402
from bearing_id.rotor.supports import bearing_fn  # noqa: E402
from bearing_id.simulation import effects as te, rig as rigmod  # noqa: E402
from test_identify_tables import compressor_params, scaled_tables  # noqa: E402

TARGET_S = {'rig3': 20.0, 'compressor': 60.0, 'compressor_force': 60.0}
# the truth's table factors (bearing 1, bearing 2): each coefficient scaled on its own
FACTORS = ({'kxx': 0.82, 'kxy': 1.25, 'kyx': 1.3, 'kyy': 1.18, 'cxx': 1.12, 'cxy': 0.78, 'cyx': 1.2, 'cyy': 0.88},
           {'kxx': 1.15, 'kxy': 0.8, 'kyx': 0.85, 'kyy': 0.9, 'cxx': 0.85, 'cxy': 1.22, 'cyx': 0.9, 'cyy': 1.1})


def rig3_case():
    """Return (recordings, rig, model) of the ``rig3`` case."""
    d = yaml.safe_load((REPO / 'params' / 'rig.yaml').read_text())
    d['probes'] = [{'name': f'p{n}{a}', 'node': n, 'direction': a} for n in (3, 6, 9) for a in 'xy']
    rig = parse_rig(d)
    model = RotorModel.from_params(rig)
    pedestal = [te.SupportFlexibility(10, k=(None, 1.5e5), c=(0.0, 50.0), mass=(0.0, 0.2))]
    recs = [rigmod.simulate_run(rig, r, effects=pedestal, model=model, seed=11 + i)
            for i, r in enumerate(rig.simulation.runs)]
    return recs, rig, model


def compressor_case(force: bool):
    """Return (recordings, rig, model) of the ``compressor`` or ``compressor_force`` case."""
    d = compressor_params(dwell=2.0)          # the tests' machine and plan (test/test_identify_tables.py)
    if force:
        discs = [x['node'] for x in d['discs']]
        d['simulation']['runs'] = [
            {'id': f'F{n}{a}', 'excitation': [{'kind': 'force', 'node': n, 'magnitude': 200.0, 'direction': a}]}
            for n in (discs[1], discs[-2]) for a in 'xy']
    rig = parse_rig(d)
    model = RotorModel.from_params(rig)
    truth_fn = bearing_fn(parse_rig(scaled_tables(d, FACTORS)))
    recs = [rigmod.simulate_run(rig, r, bearing_fn=truth_fn, model=model, seed=3 + i)
            for i, r in enumerate(rig.simulation.runs)]
    return recs, rig, model


CASES = {'rig3': rig3_case, 'compressor': lambda: compressor_case(False),
         'compressor_force': lambda: compressor_case(True)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--cases', default=','.join(CASES))
    args = ap.parse_args(argv)
    print(f'load average before: {os.getloadavg()[0]:.2f}')
    print(f"{'case':18s} {'nodes':>5s} {'runs':>4s} {'CPU s':>7s} {'target':>7s} {'ratio':>6s}  verdict")
    for name in args.cases.split(','):
        recs, rig, model = CASES[name]()
        t = time.process_time()
        d = diagnose(recs, rig, model=model)
        cpu = time.process_time() - t
        print(f'{name:18s} {model.n_nodes:5d} {len(recs):4d} {cpu:7.1f} {TARGET_S[name]:7.0f} '
              f'{cpu / TARGET_S[name]:6.2f}  {d.verdict}', flush=True)
    print(f'load average after: {os.getloadavg()[0]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
