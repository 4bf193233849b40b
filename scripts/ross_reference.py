#!/usr/bin/env python
"""
Regenerate test/data/ross_reference.json: the paper rig built in ROSS (an independent rotordynamics code).

Dev tool only: ROSS is NOT a runtime or CI dependency; the tests read the committed JSON.  Set-up (≈70 packages)::

    python3.11 -m venv /tmp/rossvenv
    /tmp/rossvenv/bin/pip install "ross-rotordynamics>=2" "plotly<7" pyyaml
    /tmp/rossvenv/bin/python scripts/ross_reference.py            # writes test/data/ross_reference.json

The rig is read from params/rig.yaml with bearing_id.params (pure Python + PyYAML, no numpy needed there) so the
geometry has one source.  ROSS model, like for like with bearing_id.rotor:
  * ShaftElement: Timoshenko with shear (Cowper's kappa, see SHEAR below), rotary inertia, gyroscopics;
    per-element proportional damping alpha, beta from shaft.damping_alpha/beta (bearing_id uses the shaft matrices
    the same way);
  * DiskElement with explicit m, Id, Ip from params.Disc (thick annulus: Id = m (D^2 + d^2)/16 + m t^2/12);
  * BearingElement with constant, cross-coupled K and C (no frequency dependence), given below.
ROSS has 6 DOF per node [x, y, z, alpha, beta, theta] with 0-based nodes; the lateral subset [x, y, alpha, beta]
equals bearing_id's [x, y, tx, ty].  Axial and torsional modes of ROSS are filtered out by their mode shapes.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import sys

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bearing_id.params import load_rig  # noqa: E402, I100  (after the sys.path insert above)
import ross as rs  # noqa: E402

# Constant bearing coefficients (our (x, y) frame, force on shaft -K q - C q'), one set per bearing node (1-based):
# deliberately asymmetric and cross-coupled, of the order of the rig's oil-film values.
BEARINGS = {
    2: {'K': [[2.4e5, 1.1e5], [-0.7e5, 3.1e5]], 'C': [[420.0, 35.0], [55.0, 610.0]]},
    10: {'K': [[1.9e5, 0.8e5], [-0.5e5, 2.6e5]], 'C': [[380.0, 20.0], [30.0, 540.0]]},
}
SPEEDS_RPM = [500.0, 1500.0, 3000.0, 6000.0]
UNBALANCE = {'node': 8, 'magnitude': 1.0e-4, 'phase': math.pi / 2}   # kg m at 90 deg, node 1-based
RESPONSE_NODES = [2, 6, 10]
N_MODES = 8
# Cowper's shear coefficient on both sides: ROSS 2.3.0's "hutchinson" formula lacks the square on (1 + nu)
# (Hutchinson 2001: kappa = 6 (1 + nu)^2 / (7 + 12 nu + 4 nu^2) for a solid circle), bearing_id's does not.
SHEAR = 'cowper'


def build_rotor(rig, bearings=True, shear=None):
    sh = rig.shaft
    steel = rs.Material(name='rig_steel', rho=sh.density, E=sh.youngs_modulus, Poisson=sh.poisson_ratio)
    shaft = [rs.ShaftElement(L=le, idl=sh.inner_diameter, odl=sh.diameter, material=steel, n=i,
                             shear_effects=True, rotary_inertia=True, gyroscopic=True,
                             shear_method_calc=shear or SHEAR, alpha=sh.damping_alpha, beta=sh.damping_beta)
             for i, le in enumerate(sh.element_lengths)]
    disks = [rs.DiskElement(n=d.node - 1, m=d.mass, Id=d.diametral_inertia, Ip=d.polar_inertia) for d in rig.discs]
    brgs = []
    for node, kc in BEARINGS.items():
        K = np.array(kc['K']) if bearings else np.zeros((2, 2))
        C = np.array(kc['C']) if bearings else np.zeros((2, 2))
        brgs.append(rs.BearingElement(n=node - 1, kxx=K[0, 0], kxy=K[0, 1], kyx=K[1, 0], kyy=K[1, 1],
                                      cxx=C[0, 0], cxy=C[0, 1], cyx=C[1, 0], cyy=C[1, 1]))
    return rs.Rotor(shaft_elements=shaft, disk_elements=disks, bearing_elements=brgs)


def lateral_modes(rotor, speed, n):
    """Lowest n lateral modes of ROSS's full eigen-solution (axial/torsional/rigid filtered by shape)."""
    modal = rotor.run_modal(speed=speed, sparse=False)
    lam = np.asarray(modal.evalues)
    V = np.asarray(modal.evectors)[:rotor.ndof]
    nd = rotor.number_dof
    lat = np.zeros(rotor.ndof, dtype=bool)
    for k in (0, 1, 3, 4):
        lat[k::nd] = True
    frac = np.sum(np.abs(V[lat]) ** 2, axis=0) / np.sum(np.abs(V) ** 2, axis=0)
    keep = (frac > 0.99) & (lam.imag > 0)
    lam = lam[keep]
    lam = lam[np.argsort(lam.imag)][:n]
    return lam


def main(out=ROOT / 'test' / 'data' / 'ross_reference.json'):
    rig = load_rig(ROOT / 'params' / 'rig.yaml')
    rotor = build_rotor(rig)
    nd = rotor.number_dof
    data = {
        'generator': 'scripts/ross_reference.py',
        'ross_version': rs.__version__,
        'numpy_version': np.__version__,
        'params': 'params/rig.yaml',
        'shear_method': SHEAR,
        'model': 'Timoshenko shaft (shear, Cowper kappa; rotary inertia; gyroscopic), explicit disc m/Id/Ip, '
                 'constant cross-coupled bearings; ROSS nodes converted to 1-based',
        'bearings': {str(k): v for k, v in BEARINGS.items()},
        'speeds_rpm': SPEEDS_RPM,
        'modes': [],
        'unbalance': dict(UNBALANCE),
        'unbalance_response': [],
    }
    for rpm in SPEEDS_RPM:
        w = rpm * 2 * math.pi / 60
        lam = lateral_modes(rotor, w, N_MODES)
        data['modes'].append({'speed_rpm': rpm, 'eigenvalue_re': lam.real.tolist(), 'eigenvalue_im': lam.imag.tolist(),
                              'wn': np.abs(lam).tolist(), 'wd': lam.imag.tolist()})
    # zero speed, zero bearing coefficients: the free-free shaft with discs (rigid-body modes dropped by |lambda|)
    free = build_rotor(rig, bearings=False)
    lamf = lateral_modes(free, 0.0, 8)
    lamf = lamf[np.abs(lamf) > 1.0]
    # each bending mode appears twice (x-z and y-z planes); keep one of each pair
    wf = np.sort(np.abs(lamf))[::2]
    data['free_free_wn'] = wf[:4].tolist()
    # for the record: ROSS's own 'hutchinson' option (kappa without the square on 1 + nu)
    lamh = lateral_modes(build_rotor(rig, bearings=False, shear='hutchinson'), 0.0, 8)
    data['free_free_wn_ross_hutchinson'] = np.sort(np.abs(lamh[np.abs(lamh) > 1.0]))[::2][:4].tolist()
    speeds = [rpm * 2 * math.pi / 60 for rpm in SPEEDS_RPM]
    resp = rotor.run_unbalance_response(node=UNBALANCE['node'] - 1, unbalance_magnitude=UNBALANCE['magnitude'],
                                        unbalance_phase=UNBALANCE['phase'], frequency=speeds)
    q = np.asarray(resp.forced_resp)
    for j, rpm in enumerate(SPEEDS_RPM):
        entry = {'speed_rpm': rpm}
        for node in RESPONSE_NODES:
            for d, off in (('x', 0), ('y', 1)):
                v = q[nd * (node - 1) + off, j]
                entry[f'{node}{d}'] = [float(v.real), float(v.imag)]
        data['unbalance_response'].append(entry)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1) + '\n')
    print(f'wrote {out} (ROSS {rs.__version__}); free-free Hz:', np.round(np.array(wf[:4]) / 2 / math.pi, 3))


if __name__ == '__main__':
    main()
