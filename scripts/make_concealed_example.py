"""
Make the worked example of docs/METHODS.md: recordings of the default rig with two effects the nominal model lacks.

Hidden in the truth (simulator side, bearing_id.simulation.effects): a flexible pedestal under bearing 2 (node 10),
vertical, k = 2.5e5 N/m, c = 40 N s/m; and 3 um of electrical runout at 120 deg on probe p6y.  Everything else is the
default simulated rig of params/rig.yaml (bearings 25 % off theory, 1 % noise, 600-3000 rpm, 2 s dwells, ramps).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/make_concealed_example.py out/example
    .venv/bin/bearing-id diagnose out/example/run_A.npz out/example/run_B.npz --json out/example/diagnosis.json \
        --report out/example/report --identify physical
"""
import argparse
import math
from pathlib import Path

from bearing_id.config.params import load_rig
from bearing_id.io.recordings import save_npz
from bearing_id.simulation import effects as te, rig as rigmod


def main(out='out/example'):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rig = load_rig()
    effects = [te.SupportFlexibility(10, k=(None, 2.5e5), c=(0.0, 40.0)),
               te.ProbeRunout('p6y', 3e-6, math.radians(120.0))]
    for run in rig.simulation.runs:
        rec = rigmod.simulate_run(rig, run, effects=effects)
        print('wrote', save_npz(rec, out / f'run_{run.id}.npz'))


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('out', nargs='?', default='out/example', help='output directory (default: %(default)s)')
    main(ap.parse_args().out)
