"""
Identify from simulated recordings and print each bearing's error against the simulator's truth.

Usage (from the repository root)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/error_vs_truth.py --params params/examples/plant_like.yaml \
        --method physical out/plant_mid/run_A.npz

The recordings must carry their truth (every .npz written by ``bearing-id simulate`` does).  Printed per speed and
bearing: the worst |K - K_true| / max|K_true| and |C - C_true| / max|C_true| [%] over the 2x2 block, and the worst
|error| / 1-sigma; then the worst over all speeds.  The identification is the CLI's (``identify.identify``).
"""
import argparse
from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bearing_id.config.params import load_rig  # noqa: E402
from bearing_id.conventions import rad_s_to_rpm  # noqa: E402
from bearing_id.identify import identify  # noqa: E402
from bearing_id.io.recordings import from_npz  # noqa: E402
from bearing_id.rotor.assembly import RotorModel  # noqa: E402
import numpy as np  # noqa: E402


def main(argv=None):
    """Run the identification and print the errors against the truth (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('recordings', nargs='+', help='.npz recordings written by bearing-id simulate')
    ap.add_argument('--params', default=None, help='machine YAML (default: the packaged params/rig.yaml)')
    ap.add_argument('--method', default='physical', choices=('paper', 'conventional', 'direct', 'physical'))
    args = ap.parse_args(argv)
    rig = load_rig(args.params)
    model = RotorModel.from_params(rig)
    data = from_npz(sorted(args.recordings))
    results = identify(args.method, model, rig, data)
    worst = np.zeros(3)
    print(f'{"speed rpm":>9} {"bearing":>12} {"K err %":>8} {"C err %":>8} {"max |err|/sigma":>15}')
    for r in results:
        truth = data.truth_at(r.speed)
        if truth is None:
            sys.exit(f'{args.recordings[0]}: no truth in the recordings')
        for i, node in enumerate(r.nodes):
            kt, ct = truth[node]
            ek = 100 * np.max(np.abs(r.K[i] - kt)) / np.max(np.abs(kt))
            ec = 100 * np.max(np.abs(r.C[i] - ct)) / np.max(np.abs(ct))
            z = max(np.max(np.abs((r.K[i] - kt) / r.K_std[i])), np.max(np.abs((r.C[i] - ct) / r.C_std[i])))
            worst = np.maximum(worst, (ek, ec, z))
            name = next((b.name for b in rig.bearings if b.node == node), str(node))
            print(f'{rad_s_to_rpm(r.speed):9.0f} {name:>12} {ek:8.3f} {ec:8.3f} {z:15.2f}')
    print(f'worst: K {worst[0]:.3f} %, C {worst[1]:.3f} %, |error|/sigma {worst[2]:.2f}')


if __name__ == '__main__':
    main()
