#!/usr/bin/env python
"""
Regenerate the ROSS reference data: the paper rig, and ROSS-saved rotors for the ``import-ross`` bridge.

Dev tool only: ROSS is NOT a runtime or CI dependency; the tests read the committed JSON/TOML.  Set-up (≈70
packages)::

    python3.11 -m venv /tmp/rossvenv
    /tmp/rossvenv/bin/pip install "ross-rotordynamics>=2" "plotly<7" pyyaml
    /tmp/rossvenv/bin/python scripts/ross_reference.py            # parts 1 and 2 below
    /tmp/rossvenv/bin/python scripts/ross_reference.py --paper    # test/data/ross_reference.json only
    /tmp/rossvenv/bin/python scripts/ross_reference.py --bridge   # test/data/ross/*.toml + *.json only
    /tmp/rossvenv/bin/python scripts/ross_reference.py --fluid-flow   # test/data/ross/fluid_flow_gumbel.json only

Part 1 (``--paper``, test/test_rotor_ross.py) -- test/data/ross_reference.json, the paper rig built in ROSS.

The rig is read from params/rig.yaml with bearing_id.config.params (its venv needs numpy, PyYAML, pint, pydantic) so the
geometry has one source.  ROSS model, like for like with bearing_id.rotor:
  * ShaftElement: Timoshenko with shear (Cowper's kappa, see SHEAR below), rotary inertia, gyroscopics;
    per-element proportional damping alpha, beta from shaft.damping_alpha/beta (bearing_id uses the shaft matrices
    the same way);
  * DiskElement with explicit m, Id, Ip from params.Disc (thick annulus: Id = m (D^2 + d^2)/16 + m t^2/12);
  * BearingElement with constant, cross-coupled K and C (no frequency dependence), given below.
ROSS has 6 DOF per node [x, y, z, alpha, beta, theta] with 0-based nodes; the lateral subset [x, y, alpha, beta]
equals bearing_id's [x, y, tx, ty].  Axial and torsional modes of ROSS are filtered out by their mode shapes.

Part 2 (``--bridge``, test/test_import_ross.py) -- rotors built in ROSS and saved with ``Rotor.save`` as
test/data/ross/NAME.toml, with ROSS's lateral damped eigenvalues at a few speeds in test/data/ross/NAME.json:
  * ``compressor``: ROSS's own ``compressor_example()`` (Timbo & Ritto 2019: 91 shaft elements on 55 stations,
    mass-only layers as extra elements on the same station, 7 discs by m/Id/Ip, two bearings and 12 seals as
    coefficient tables vs speed, cross-coupled);
  * ``stepped``: a stepped, partly hollow shaft (16 elements, Cowper), two discs, proportional
    damping alpha/beta, two cross-coupled bearings and a seal with tables vs speed;
  * ``hollow_hutchinson``: a hollow shaft with ROSS's 'hutchinson' shear option, constant cross-coupled bearings
    (no frequency given), a disc, one bearing on a pedestal (ROSS's n_link + point mass + support bearing).
The eigenvalues are taken at speeds that are rows of every table and (compressor) between them: ROSS interpolates
a table with a smoothing UnivariateSpline (s = number of rows), off the rows by ``table_deviation`` (per speed in the
JSON, relative to the largest entry); ``import-ross`` (its default ``--table-values ross``) writes ROSS's spline
sampled at and between the rows as a cubic table, so the model follows ROSS between rows too.

Part 3 (``--fluid-flow``, test/test_bearings_finite.py) -- test/data/ross/fluid_flow_gumbel.json: ROSS's
``FluidFlow`` finite-difference journal bearing (full-film Reynolds solved, negative pressures clipped: Gumbel's
half-Sommerfeld condition) -- radial and tangential film force at fixed eccentricities, on two grids (ROSS's scheme
converges at first order in the grid step, so the test extrapolates).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import sys

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bearing_id.config.params import load_rig  # noqa: E402, I100  (after the sys.path insert above)
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


# --------------------------------------------------------------------------------- part 2: import-ross bridge
BRIDGE_DIR = ROOT / 'test' / 'data' / 'ross'
BRIDGE_MODES = 12


def _poly(u, *c):
    """Polynomial c0 + c1 u + c2 u^2 + c3 u^3 (ROSS's cubic spline reproduces it exactly at and between rows)."""
    return [sum(ci * x**i for i, ci in enumerate(c)) for x in u]


def stepped_rotor():
    """Build a stepped shaft with discs, two cross-coupled table bearings and a table seal."""
    steel = rs.Material(name='bridge_steel', rho=7810.0, E=211e9, G_s=81.2e9)
    # (n_elements, element length, outer d, inner d) left to right
    sections = [(3, 0.06, 0.06, 0.0), (2, 0.05, 0.09, 0.0), (6, 0.07, 0.12, 0.04), (2, 0.05, 0.09, 0.0),
                (3, 0.06, 0.06, 0.0)]
    shaft = []
    for n_el, le, od, idd in sections:
        for _ in range(n_el):
            shaft.append(rs.ShaftElement(L=le, idl=idd, odl=od, material=steel, n=len(shaft), shear_effects=True,
                                         rotary_inertia=True, gyroscopic=True, shear_method_calc='cowper',
                                         alpha=1.5, beta=2.0e-5))
    disks = [rs.DiskElement(n=7, m=32.0, Id=0.35, Ip=0.62, tag='impeller_1'),
             rs.DiskElement(n=10, m=21.0, Id=0.21, Ip=0.39, tag='impeller_2')]
    f = [100.0, 300.0, 500.0, 700.0, 900.0]
    u = [x / 1000.0 for x in f]
    b_left = rs.BearingElement(
        n=1, frequency=f, tag='brg_drive_end',
        kxx=_poly(u, 2.0e7, 1.2e7, 4.0e6), kxy=_poly(u, 0.0, 9.0e6, 3.0e6), kyx=_poly(u, 0.0, -7.0e6, -2.0e6),
        kyy=_poly(u, 3.1e7, 8.0e6, 5.0e6, -1.0e6),
        cxx=_poly(u, 6.0e4, -2.0e4, 5.0e3), cxy=_poly(u, 1.5e3, 2.0e3), cyx=_poly(u, 1.0e3, 2.5e3),
        cyy=_poly(u, 8.0e4, -3.0e4, 7.0e3))
    b_right = rs.BearingElement(
        n=15, frequency=f, tag='brg_non_drive_end',
        kxx=_poly(u, 1.6e7, 1.0e7, 3.0e6), kxy=_poly(u, 0.0, 7.0e6, 2.0e6), kyx=_poly(u, 0.0, -5.0e6, -1.5e6),
        kyy=_poly(u, 2.4e7, 7.0e6, 4.0e6),
        cxx=_poly(u, 5.0e4, -1.5e4, 4.0e3), cxy=_poly(u, 800.0, 1.5e3), cyx=_poly(u, 600.0, 2.0e3),
        cyy=_poly(u, 6.5e4, -2.0e4, 5.0e3))
    seal = rs.SealElement(
        n=4, frequency=f, tag='balance_piston',
        kxx=_poly(u, 3.0e6, 5.0e5), kyy=_poly(u, 3.0e6, 5.0e5), kxy=_poly(u, 0.0, 2.5e6, 4.0e5),
        kyx=_poly(u, 0.0, -2.5e6, -4.0e5), cxx=_poly(u, 4.0e3, 300.0), cyy=_poly(u, 4.0e3, 300.0),
        cxy=_poly(u, 0.0, 150.0), cyx=_poly(u, 0.0, -150.0))
    rotor = rs.Rotor(shaft_elements=shaft, disk_elements=disks, bearing_elements=[b_left, b_right, seal])
    return rotor, f


def hollow_hutchinson_rotor():
    """
    Uniform hollow shaft, ROSS's 'hutchinson' shear option, constant cross-coupled bearings, one disc.

    Bearing b sits on a pedestal, ROSS's way: the bearing links shaft node 11 to an extra node 13 (``n_link``) that
    carries a point mass (different in x and y) and a support bearing to ground.
    """
    steel = rs.Material(name='bridge_steel_nu', rho=7850.0, E=205e9, Poisson=0.29)
    shaft = [rs.ShaftElement(L=0.08, idl=0.05, odl=0.1, material=steel, n=i, shear_method_calc='hutchinson')
             for i in range(12)]
    disks = [rs.DiskElement(n=6, m=40.0, Id=0.5, Ip=0.9)]
    brgs = [rs.BearingElement(n=1, kxx=5.0e7, kyy=7.0e7, kxy=2.0e7, kyx=-3.0e7, cxx=4.0e4, cyy=5.0e4, cxy=3.0e3,
                              cyx=-2.0e3, tag='brg_a'),
            rs.BearingElement(n=11, n_link=13, kxx=4.0e7, kyy=6.0e7, kxy=1.5e7, kyx=-2.5e7, cxx=3.5e4, cyy=4.5e4,
                              tag='brg_b'),
            rs.BearingElement(n=13, kxx=1.0e8, kyy=1.5e8, cxx=2.0e3, cyy=3.0e3, tag='pedestal_b')]
    pms = [rs.PointMass(n=13, mx=40.0, my=55.0, mz=40.0, tag='pedestal_b_mass')]   # mz: M nonsingular
    return (rs.Rotor(shaft_elements=shaft, disk_elements=disks, bearing_elements=brgs, point_mass_elements=pms),
            [0.0, 300.0, 600.0])


def compressor_rotor():
    """
    Return ROSS's compressor example and speeds at and between the rows common to its bearing and seal tables.

    Between each two rows a speed at 1/3 of the interval: no row of any table, ROSS's spline there.
    """
    rotor = rs.compressor_example()
    common = None
    for b in rotor.bearing_elements:
        f = np.round(np.asarray(b.frequency, dtype=float), 6)
        common = set(f) if common is None else common & set(f)
    rows = sorted(float(x) for x in common)
    return rotor, sorted(rows + [round(a + (b - a) / 3, 6) for a, b in zip(rows, rows[1:])])


def lateral_modes_by_wn(rotor, speed, n):
    """Lowest n lateral modes (Im > 0) by natural frequency |lambda| (lateral_modes above sorts by Im)."""
    lam = lateral_modes(rotor, speed, rotor.ndof)
    return lam[np.argsort(np.abs(lam))][:n]


def table_deviation(rotor, speed):
    """Largest |ROSS's K(speed), C(speed) - nearest table row| / largest |entry| over its bearings (0 if constant)."""
    worst = 0.0
    for b in rotor.bearing_elements:
        if b.frequency is None or len(b.frequency) < 2:
            continue
        i = int(np.argmin(np.abs(np.asarray(b.frequency) - speed)))
        for kind in ('k', 'c'):
            ross = np.array([getattr(b, f'{kind}{a}_interpolated')(speed) for a in ('xx', 'xy', 'yx', 'yy')], float)
            row = np.array([getattr(b, f'{kind}{a}')[i] for a in ('xx', 'xy', 'yx', 'yy')], float)
            worst = max(worst, float(np.max(np.abs(ross - row)) / np.max(np.abs(row))))
    return worst


def write_bridge(outdir=BRIDGE_DIR, names=None):
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    for name, build in (('compressor', compressor_rotor), ('stepped', stepped_rotor),
                        ('hollow_hutchinson', hollow_hutchinson_rotor)):
        if names and name not in names:
            continue
        rotor, speeds = build()
        toml = outdir / f'{name}.toml'
        if toml.exists():
            toml.unlink()               # Rotor.save merges into an existing file
        rotor.save(toml)
        again = rs.Rotor.load(toml)     # what the file holds is what we compare with
        data = {'generator': 'scripts/ross_reference.py --bridge', 'ross_version': rs.__version__,
                'numpy_version': np.__version__, 'rotor': f'{name}.toml', 'n_modes': BRIDGE_MODES,
                'method': 'Rotor.run_modal(speed, sparse=False) of the rotor loaded back from the TOML; lateral modes '
                          '(>99 % of the mode shape on x, y, alpha, beta) with Im > 0, lowest by |lambda|',
                'modes': []}
        for w in speeds:
            lam = lateral_modes_by_wn(again, w, BRIDGE_MODES)
            data['modes'].append({'speed': w, 'eigenvalue_re': lam.real.tolist(), 'eigenvalue_im': lam.imag.tolist(),
                                  'table_deviation': table_deviation(again, w)})
        (outdir / f'{name}.json').write_text(json.dumps(data, indent=1) + '\n')
        print(f'wrote {toml} ({toml.stat().st_size} bytes) and {name}.json: speeds {np.round(speeds, 3).tolist()}, '
              f'lowest wd {np.round(lam.imag[:4], 2).tolist()} rad/s')


# --------------------------------------------------------------------------------- part 3: Gumbel film forces
FF_CASES = [(0.5, 0.3), (0.5, 0.7), (1.0, 0.3), (1.0, 0.6)]     # (L/D, eccentricity ratio)
FF_GRIDS = [(32, 128), (64, 256)]                                # (nz, ntheta)


def write_fluid_flow(out=BRIDGE_DIR / 'fluid_flow_gumbel.json'):
    """ROSS FluidFlow (Gumbel) dimensionless film forces F / (mu omega R^4 / c^2) at fixed eccentricity."""
    from ross.bearings.fluid_flow import FluidFlow
    from ross.bearings.fluid_flow_coefficients import calculate_oil_film_force
    R, c, mu, omega = 0.05, 1e-4, 0.02, 300.0
    rows = []
    for ld, eps in FF_CASES:
        for nz, nt in FF_GRIDS:
            ff = FluidFlow(nz=nz, ntheta=nt, length=ld * 2 * R, omega=omega, p_in=0.0, p_out=0.0, radius_rotor=R,
                           radius_stator=R + c, viscosity=mu, density=860.0, eccentricity=eps * c,
                           attitude_angle=math.pi / 4, immediately_calculate_pressure_matrix_numerically=True)
            fr, ft, _, _ = calculate_oil_film_force(ff, force_type='numerical')
            scale = mu * omega * R**4 / c**2
            rows.append([ld, eps, nz, nt, fr / scale, ft / scale])
            print(f'L/D {ld} eps {eps} grid {nz}x{nt}: radial {fr / scale:.6f} tangential {ft / scale:.6f}')
    data = {'generator': 'scripts/ross_reference.py --fluid-flow', 'ross_version': rs.__version__,
            'model': 'ross.bearings.fluid_flow.FluidFlow (p_in = p_out = 0, cylindrical): full-film Reynolds by finite '
                     'differences, pressure clipped at 0 (Gumbel); forces by calculate_oil_film_force(numerical)',
            'radius': R, 'clearance': c, 'viscosity': mu, 'omega': omega,
            'columns': ['L_over_D', 'eps', 'nz', 'ntheta', 'radial', 'tangential'],
            'note': 'radial: opposite to the eccentricity; tangential: 90 deg ahead of it in the spin direction; '
                    'both divided by mu omega R^4 / c^2', 'rows': rows}
    Path(out).write_text(json.dumps(data, indent=1) + '\n')


# ----------------------------------------------------------------- part 4: the plant-like example machine
EXAMPLE_TOML = ROOT / 'params' / 'examples' / 'plant_compressor.toml'


def plant_rotor():
    """
    Build a plant-like centrifugal compressor in ROSS (not one of ROSS's examples): the params/examples machine.

    A stepped shaft (journal 90 mm, body 140 mm, 1.3 m) with shrunk-on sleeves under the impellers as a second
    element on the same station (a layered shaft), four impellers and a thrust collar as discs from their geometry,
    two tilting-pad-like journal bearings (small cross-coupling) and a balance-piston and an eye seal with strong
    cross-coupling, all as tables over 3000-12000 rpm (7 rows, smooth in speed).
    """
    steel = rs.Material(name='shaft_steel', rho=7850.0, E=207e9, G_s=79.5e9)
    sleeve = rs.Material(name='sleeve_steel', rho=7850.0, E=200e9, G_s=77.0e9)
    # (n_elements, element length [m], outer d [m], sleeve outer d or None) left to right
    sections = [(2, 0.05, 0.09, None), (3, 0.05, 0.09, None), (2, 0.06, 0.12, None), (8, 0.07, 0.14, 0.17),
                (2, 0.06, 0.12, None), (3, 0.05, 0.09, None), (2, 0.05, 0.09, None)]
    shaft, n = [], 0
    for n_el, le, od, sl in sections:
        for _ in range(n_el):
            shaft.append(rs.ShaftElement(L=le, idl=0.0, odl=od, material=steel, n=n, shear_effects=True,
                                         rotary_inertia=True, gyroscopic=True, shear_method_calc='cowper'))
            if sl is not None:
                shaft.append(rs.ShaftElement(L=le, idl=od, odl=sl, material=sleeve, n=n, shear_effects=True,
                                             rotary_inertia=True, gyroscopic=True, shear_method_calc='cowper'))
            n += 1
    disks = [rs.DiskElement.from_geometry(n=k, material=steel, width=0.05, i_d=0.17, o_d=0.42, tag=f'impeller_{i + 1}')
             for i, k in enumerate((9, 11, 13, 15))]
    disks.append(rs.DiskElement.from_geometry(n=3, material=steel, width=0.03, i_d=0.09, o_d=0.2, tag='thrust_collar'))
    f = [314.16, 418.88, 523.60, 628.32, 837.76, 1047.20, 1256.64]      # rad/s: 3000 ... 12000 rpm
    u = [x / 1000.0 for x in f]

    def journal(n, tag, k0, c0):
        return rs.BearingElement(
            n=n, frequency=f, tag=tag,
            kxx=_poly(u, k0, 0.6 * k0, -0.15 * k0), kyy=_poly(u, 1.2 * k0, 0.5 * k0, -0.1 * k0),
            kxy=_poly(u, 0.0, 0.04 * k0, 0.02 * k0), kyx=_poly(u, 0.0, -0.05 * k0, -0.01 * k0),
            cxx=_poly(u, c0, -0.35 * c0, 0.08 * c0), cyy=_poly(u, 1.15 * c0, -0.4 * c0, 0.1 * c0),
            cxy=_poly(u, 0.0, 0.02 * c0), cyx=_poly(u, 0.0, -0.015 * c0))

    def seal(n, tag, k0, q0, c0):
        return rs.SealElement(
            n=n, frequency=f, tag=tag,
            kxx=_poly(u, k0, 0.3 * k0), kyy=_poly(u, k0, 0.3 * k0), kxy=_poly(u, 0.0, q0, 0.2 * q0),
            kyx=_poly(u, 0.0, -q0, -0.2 * q0), cxx=_poly(u, c0, 0.1 * c0), cyy=_poly(u, c0, 0.1 * c0),
            cxy=_poly(u, 0.0, 0.05 * c0), cyx=_poly(u, 0.0, -0.05 * c0))

    brgs = [journal(1, 'journal_drive_end', 1.2e8, 9.0e4), journal(22, 'journal_non_drive_end', 1.0e8, 8.0e4),
            seal(7, 'eye_seal', 4.0e6, 3.0e6, 3.0e3), seal(17, 'balance_piston', 1.5e7, 1.2e7, 1.2e4)]
    return rs.Rotor(shaft_elements=shaft, disk_elements=disks, bearing_elements=brgs), f


def write_example(out=EXAMPLE_TOML):
    """Save the plant-like machine with ``Rotor.save`` (then ``bearing-id import-ross`` makes its params file)."""
    rotor, _ = plant_rotor()
    out = Path(out)
    if out.exists():
        out.unlink()                    # Rotor.save merges into an existing file
    rotor.save(out)
    again = rs.Rotor.load(out)
    lam = lateral_modes_by_wn(again, 628.32, 6)
    print(f'wrote {out} ({out.stat().st_size} bytes): ROSS {rs.__version__}, {len(again.shaft_elements)} shaft '
          f'elements, lowest damped natural frequencies at 6000 rpm {np.round(lam.imag / 2 / np.pi, 1).tolist()} Hz')


if __name__ == '__main__':
    args = sys.argv[1:]
    if '--example' in args:
        write_example()
    if '--fluid-flow' in args:
        write_fluid_flow()
    if not args or '--paper' in args:
        main()
    if not args or '--bridge' in args:
        write_bridge(names=[a for a in args if not a.startswith('--')])   # optional rotor names
