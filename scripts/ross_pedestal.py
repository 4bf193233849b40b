#!/usr/bin/env python
"""
Flexible pedestals made with ROSS: test/data/ross/faults/<name>_nominal_{A,B}.npz and their README.json entries.

Dev tool only (ROSS is not a runtime or CI dependency; the tests read the committed files).  Set-up as for
scripts/ross_faults.py::

    /tmp/rossenv/bin/pip install "ross-rotordynamics==2.3.0" "plotly<7" pyyaml "pandas<3"
    /tmp/rossenv/bin/python scripts/ross_pedestal.py     # after scripts/ross_faults.py, which rewrites README.json

The rotor is scripts/ross_faults.py's ``nominal`` set (the paper rig's shaft and discs on the packaged nominal
bearings at each speed), with the bearing at ``bearing_node`` on a pedestal ROSS's way: the bearing element
links the shaft node to an extra node (``n_link``) that carries a ``PointMass`` and a support ``BearingElement`` to
ground (stiffness and damping per direction).  A pedestal is linear, so each speed's steady response is ROSS's own
matrices solved at that speed (``ross_faults.healthy_state``: K(w) - w^2 M + j w (C(w) + w G), no gravity) and the
recording is that 1X at the probes, x(t) = Re{X e^(j angle)}, ``ross_faults.KEEP`` s per speed at ``FS``, noise-free
(the test adds its noise), in ross_faults' .npz layout (angle continuous across the speeds).

One pair of recordings per entry of ``PEDESTALS`` (its key is the file stem and the README.json entry
``sets.nominal.faults.<key>``): the parameters and ``truth``: per direction the pedestal's stiffness, damping and
mass and its dynamic stiffness k - m w^2 at every speed.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import sys

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'scripts'))

import ross as rs  # noqa: E402, I100
from ross_faults import (_rounded, FS, healthy_state, KEEP, OUT, probe_dofs, Setup, SPEEDS_RPM,  # noqa: E402
                         write_npz)

# other values than issue 24's own example (6e5 / 1.2e6 N/m, 0.9 kg under bearing 2): bearing 2 stiffer in y; bearing 1
# (node 2) as soft in x as in y, heavier -- at the model tolerance a disc mass error fits it about as well
PEDESTALS = {'pedestal': {'bearing_node': 10, 'k_x': 8.0e5, 'k_y': 1.5e6, 'c_x': 60.0, 'c_y': 90.0, 'm': 1.2},
             'pedestal_b1': {'bearing_node': 2, 'k_x': 5.0e5, 'k_y': 5.0e5, 'c_x': 60.0, 'c_y': 60.0, 'm': 2.0}}


def pedestal_rotor(setup: Setup, w: float, p: dict):
    """Return ROSS's rotor at w [rad/s]: the nominal set's, with the pedestal ``p`` under ``p['bearing_node']``."""
    base = setup.rotor_at(w)
    support = len(base.shaft_elements) + 1      # shaft nodes 0 .. n_elements: the next index is the support's
    brgs = []
    for n, (K, C) in sorted(setup.bearings_at(w).items()):
        link = {'n_link': support} if n == p['bearing_node'] else {}
        brgs.append(rs.BearingElement(n=n - 1, kxx=K[0, 0], kxy=K[0, 1], kyx=K[1, 0], kyy=K[1, 1],
                                      cxx=C[0, 0], cxy=C[0, 1], cyx=C[1, 0], cyy=C[1, 1], **link))
    brgs.append(rs.BearingElement(n=support, kxx=p['k_x'], kyy=p['k_y'], cxx=p['c_x'], cyy=p['c_y'], tag='pedestal'))
    pms = [rs.PointMass(n=support, mx=p['m'], my=p['m'], mz=p['m'], tag='pedestal_mass')]   # mz: M nonsingular
    return rs.Rotor(shaft_elements=base.shaft_elements, disk_elements=base.disk_elements, bearing_elements=brgs,
                    point_mass_elements=pms)


def write_pedestal(setup: Setup, name: str, p: dict) -> None:
    """Write ``<name>_nominal_{A,B}.npz`` and README.json's ``sets.nominal.faults.<name>`` for the pedestal ``p``."""
    n_keep = int(round(KEEP * FS))
    t = np.arange(n_keep) / FS
    files = {}
    for run in setup.rig.simulation.runs:
        pieces, angle0 = [], 0.0
        for rpm in SPEEDS_RPM:
            w = rpm * 2 * math.pi / 60
            rotor = pedestal_rotor(setup, w, p)
            _, X = healthy_state(rotor, w, run.excitation, False)
            Xp = X[probe_dofs(rotor)]
            ang = angle0 + w * t
            x = np.real(Xp[None, :] * np.exp(1j * ang[:, None]))
            pieces.append((x, ang, np.full(n_keep, w)))
            angle0 = ang[-1] + w / FS
        path = OUT / f'{name}_nominal_{run.id}.npz'
        write_npz(path, run, pieces, setup.rig.name)
        files[run.id] = path.name
        print(f'wrote {path}')
    truth = {'bearing_node': p['bearing_node'], **{k: v for k, v in p.items() if k != 'bearing_node'},
             'kdyn_N_per_m': {str(rpm): {d: p[f'k_{d}'] - p['m'] * (rpm * 2 * math.pi / 60) ** 2 for d in 'xy'}
                              for rpm in SPEEDS_RPM}}
    readme_path = OUT / 'README.json'
    readme = json.loads(readme_path.read_text())
    readme['sets']['nominal']['faults'][name] = {
        'generator': 'scripts/ross_pedestal.py', 'ross_version': rs.__version__,
        'model': ("bearing at node {bearing_node} on a pedestal, ROSS's way: BearingElement n_link to a support node "
                  'with a PointMass and a support BearingElement to ground; linear, each speed solved from '
                  "ROSS's own matrices (no gravity), 1X only").format(**p),
        'files': files, 'truth': truth}
    readme_path.write_text(json.dumps(_rounded(readme), indent=1) + '\n')
    print(f'updated {readme_path}')


def main() -> int:
    setup = Setup('nominal')
    for name, p in PEDESTALS.items():
        write_pedestal(setup, name, p)
    return 0


if __name__ == '__main__':
    sys.exit(main())
