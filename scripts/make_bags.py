#!/usr/bin/env python
"""
Regenerate the small mcap recordings in bags/ from the simulated rig (no ROS needed: rosbags writes them).

Each bag holds what sensor_driver publishes for one excitation plan: /rotor/excitation (one per run, stamped at the
run's first block), /rotor/speed and /rotor/displacement (1024-sample blocks at 10,240 Hz, sequence continuous across
runs, stamps continuous across runs).  Bag timestamps = header stamps (time of each block's first sample).
Truth: params/rig.yaml simulation.truth (viscosity x1.25, clearance x0.8 against the nominal bearings).

    OPENBLAS_NUM_THREADS=1 python scripts/make_bags.py [--out bags]
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from bearing_id.config.params import load_rig  # noqa: E402
from bearing_id.io import bags  # noqa: E402
from bearing_id.nodes.sensor_driver_core import stream_messages  # noqa: E402
from bearing_id.simulation import rig as rigmod  # noqa: E402

T0_NS = 1_700_000_000 * 1_000_000_000        # fixed start time: reproducible bags
BLOCK = 1024
RAMP = 0.2                                   # s, speed ramp between dwells (shorter than the rig default: size)

# name -> (runs, speeds [rpm], dwell [s], description)
PLANS = {
    'unbalance_ab_sweep': ('default', [600.0, 900.0, 1200.0, 1500.0, 1800.0, 2100.0, 2400.0, 2700.0, 3000.0], 1.2,
                           'unbalance runs A and B of params/rig.yaml, 600..3000 rpm in 300 rpm steps, 1.2 s each, '
                           '0.2 s ramps'),
    'force_plan': ('force', [1200.0, 2400.0], 1.5,
                   'directional 2 N synchronous force in x then y at nodes 4 and 8 (4 runs), 1200/2400 rpm, '
                   '1.5 s each, 0.2 s ramp'),
    'slow_roll': ('slow', [300.0], 4.0, "slow roll at 300 rpm with run A's unbalance, 4 s"),
}


def plan_runs(rig, which):
    if which == 'default':
        return list(rig.simulation.runs)
    if which == 'slow':
        return [rig.simulation.runs[0]]
    return rigmod.scenario(which)


def make(name: str, out_dir: Path, rig) -> Path:
    which, speeds, dwell, _ = PLANS[name]
    recs = [rigmod.simulate_run(rig, r, speeds_rpm=speeds, dwell=dwell, ramp=RAMP) for r in plan_runs(rig, which)]
    msgs = ((topic, t_ns, msg) for topic, t_ns, msg, _ in stream_messages(recs, BLOCK, T0_NS, rig.name,
                                                                          types=bags.typestore()))
    return bags.write_bag(out_dir / name, msgs, storage='mcap', overwrite=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--out', default=str(REPO / 'bags'))
    ap.add_argument('names', nargs='*', default=list(PLANS), help=f'bags to make (default all: {list(PLANS)})')
    args = ap.parse_args(argv)
    rig = load_rig()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.names:
        p = make(name, out, rig)
        size = sum(f.stat().st_size for f in p.rglob('*') if f.is_file())
        print(f'{p}: {size / 1e6:.2f} MB  ({PLANS[name][3]})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
