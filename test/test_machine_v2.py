"""
Schema v2 machines (issue 12): stepped shafts, inertia discs, table bearings, pedestals, probes at any angle.

References: the v1 description of the same rig, the exact Euler-Bernoulli transfer-matrix solution of a stepped
free-free beam, numpy's linear interpolation, the frequency-domain condensation of a pedestal, the rotation of an
x/y probe pair, and the simulated plant-like machine's truth bearings.  Where two routes compute one quantity the
tolerance is derived from machine epsilon (EPS) and the operations or the condition number involved, written out
at each check.
"""
import argparse
import copy
import dataclasses
import json
import math
import sys

from bearing_id import conventions as cv
from bearing_id.bearings import finite, finite_table, solution
from bearing_id.bearings.table import interpolate
from bearing_id.commands import model as cmd
from bearing_id.config import units
from bearing_id.config.params import (default_rig_path, load_rig, PACKAGE_PARAMS, ParamError, parse_rig, Probe,
                                      rig_to_dict)
from bearing_id.identify import identify
from bearing_id.identify.conventional import identify_conventional
from bearing_id.identify.harmonics import from_recordings
from bearing_id.io.bags import typestore
from bearing_id.io.messages import block_from_msg, block_to_msg, validate_block
from bearing_id.rotor.assembly import dynamic_stiffness, probe_matrix, RotorModel, static_bearing_loads
from bearing_id.rotor.elements import ShaftElement, shear_coefficient
from bearing_id.rotor.modal import free_free_frequencies
from bearing_id.rotor.supports import bearing_fn
from bearing_id.simulation.rig import simulate_data, simulate_plan, simulate_run, truth_bearing_fn
from error_bounds import solve_tol
from film_oracle import short_film_force
import numpy as np
import pytest
from scipy.optimize import brentq
import yaml

PLANT = PACKAGE_PARAMS / 'examples' / 'plant_like.yaml'
EPS = sys.float_info.epsilon


@pytest.fixture(scope='module')
def raw():
    return yaml.safe_load(default_rig_path().read_text())


def v2_of_v1(raw: dict) -> dict:
    """Return the packaged v1 rig written in the v2 schema: a named material and one section."""
    d = copy.deepcopy(raw)
    sh = d['shaft']
    d['materials'] = {'steel': {'E': sh['youngs_modulus'], 'nu': sh['poisson_ratio'], 'density': sh['density']}}
    d['shaft'] = {'damping_alpha': sh['damping_alpha'], 'damping_beta': sh['damping_beta'],
                  'sections': [{'length': sh['length'], 'outer_diameter': sh['diameter'], 'material': 'steel',
                                'n_elements': sh['n_elements']}]}
    for b in d['bearings']:
        b['kind'] = b.pop('model')
    return d


# ------------------------------------------------------------------------------------------------ schema
def test_v1_and_v2_descriptions_give_the_same_model(raw):
    """
    The same rig as v1 keys and as a v2 material and section: the same element inputs, so the same matrices.

    Tolerance: both give each element the same L, D, E, rho and G = E / (2 (1 + nu)) (to 1 ulp); an element entry
    is computed in fewer than 32 roundings and a global entry sums at most two elements (and the bearings' K, C
    alike), so entries agree to 2 x 32 EPS of the largest.
    """
    m1 = RotorModel.from_params(load_rig())
    m2 = RotorModel.from_params(parse_rig(v2_of_v1(raw)))
    w = 2000 * math.pi / 30
    co = bearing_fn(load_rig())(w)
    pairs = [(getattr(m1, name), getattr(m2, name)) for name in ('M', 'K', 'G', 'C')]
    for a, b in pairs + [(dynamic_stiffness(m1, w, w, co), dynamic_stiffness(m2, w, w, co))]:
        assert a.shape == b.shape and np.max(np.abs(a - b)) <= 64 * EPS * np.max(np.abs(a))


def test_units_in_strings(raw, monkeypatch):
    d = copy.deepcopy(raw)
    d['shaft']['diameter'] = '12.65 mm'
    d['bearings'][0]['clearance'] = '50 um'
    d['simulation']['speeds_rpm'] = ['600 rpm', '62.83185307179586 rad/s']
    rig = parse_rig(d)
    # pint multiplies by the unit's factor (1e-3, 1e-6: each a rounded decimal): two roundings, and the decimal
    # literal one more
    assert rig.shaft.diameter == pytest.approx(0.01265, rel=2 * EPS)
    assert rig.bearings[0].clearance == pytest.approx(5e-5, rel=2 * EPS)
    # 20 pi rounded to 16 digits (3e-17 relative), times pint's factor 60 / (2 pi) (a few roundings): 8 EPS
    assert rig.simulation.speeds_rpm == pytest.approx((600.0, 600.0), rel=8 * EPS)
    d['shaft']['diameter'] = '12.65 kg'
    with pytest.raises(ParamError, match=r'shaft\.diameter.*wrong unit'):
        parse_rig(d)

    # pint evaluates expressions: anything but NUMBER UNIT is refused before it gets there (9**9**9 never returns)
    def no_pint():
        raise AssertionError('an expression reached pint')
    monkeypatch.setattr(units, '_registry', no_pint)
    for text in ('9**9**9 mm', '10 m**9**9', '(3+4) mm', '1 mm; import os', 'eighty-five'):
        d['shaft']['diameter'] = text
        with pytest.raises(ParamError, match=r'shaft\.diameter must be a number \[m\]'):
            parse_rig(d)


@pytest.mark.parametrize('edit,field', [
    (lambda d: d['bearings'][1].update(supprot={'mass': 1.0}), r'bearings\[1\]\.supprot: unknown key \(did you '
                                                               r'mean support\?\)'),
    (lambda d: d['shaft'].update(diametr=0.01), r'shaft\.diametr: unknown key'),
    (lambda d: d.update(seal=[]), r'rig\.seal: unknown key \(did you mean seals\?\)'),
    (lambda d: d['probes'][0].update(angle_deg=45.0), r'probes\[0\]: give direction'),
    (lambda d: d['discs'][0].update(mass=3.0), r'discs\[0\]: give the disc by mass'),
    (lambda d: d['bearings'][0].update(load=[1.0]), r'bearings\[0\]\.load'),
    (lambda d: d['bearings'][0].update(model='table'), r'bearings\[0\]\.table is missing'),
])
def test_unknown_keys_and_wrong_shapes_name_the_field(raw, edit, field):
    d = copy.deepcopy(raw)
    edit(d)
    with pytest.raises(ParamError, match=field):
        parse_rig(d)


def test_plant_example_loads():
    rig = load_rig(PLANT)
    assert rig.shaft.n_elements >= 30 and len({e.outer_diameter for e in rig.shaft.elements}) >= 4
    assert [p.angle_deg for p in rig.probes] == [135.0, 45.0] * 3
    assert rig.seals[0].table is not None and rig.bearings[1].support is not None
    assert rig.discs[0].mass == 12.0 and rig.discs[0].polar_inertia == 0.09


# ------------------------------------------------------------------------------------------------ rotor
def _eb_stepped_free_free(sections, n_roots=3, w_max=4000.0):
    """Return the exact Euler-Bernoulli free-free bending frequencies [rad/s] of a stepped beam (transfer matrices)."""
    def transfer(w):
        T = np.eye(4)
        for L, EI, rhoA in sections:
            b = (rhoA * w * w / EI) ** 0.25

            def phi(x):
                ch, sh, c, s = math.cosh(b * x), math.sinh(b * x), math.cos(b * x), math.sin(b * x)
                return np.array([[ch, sh, c, s], [b * sh, b * ch, -b * s, b * c],
                                 [EI * b**2 * ch, EI * b**2 * sh, -EI * b**2 * c, -EI * b**2 * s],
                                 [EI * b**3 * sh, EI * b**3 * ch, EI * b**3 * s, -EI * b**3 * c]])
            T = phi(L) @ np.linalg.inv(phi(0.0)) @ T
        return T

    def f(w):      # free ends: moment and shear zero at both ends
        return np.linalg.det(transfer(w)[2:4, 0:2])

    grid = np.linspace(1.0, w_max, 4000)
    vals = [f(w) for w in grid]
    roots = [brentq(f, a, b, xtol=1e-12) for a, b, fa, fb in zip(grid, grid[1:], vals, vals[1:]) if fa * fb < 0]
    return np.array(roots[:n_roots])


def test_stepped_shaft_free_free_frequencies_match_the_exact_beam():
    E, nu, rho = 2.1e11, 0.3, 7850.0
    secs = [(0.4, 0.02, 10), (0.6, 0.03, 15), (0.3, 0.015, 10)]      # length, diameter, elements: slender (L/D > 13)
    d = {'name': 'stepped', 'materials': {'s': {'E': E, 'nu': nu, 'density': rho}},
         'shaft': {'sections': [{'length': L, 'outer_diameter': D, 'material': 's', 'n_elements': n}
                                for L, D, n in secs]},
         'bearings': [{'node': 2, 'diameter': 0.02, 'length': 0.01, 'clearance': 5e-5, 'viscosity': 0.02}]}
    model = RotorModel.from_params(parse_rig(d))
    ref = _eb_stepped_free_free([(L, E * math.pi * D**4 / 64, rho * math.pi * D**2 / 4) for L, D, _ in secs])
    # the same elements without shear and rotary inertia are Euler-Bernoulli: only the FE discretisation differs
    eb = RotorModel.from_elements([ShaftElement(e.length, e.outer_d, e.inner_d, e.E, e.G_mod, e.rho, shear=False,
                                                rotary_inertia=False) for e in model.elements])
    assert free_free_frequencies(eb, 3) == pytest.approx(ref, rel=2e-5)     # measured 0.6e-6 ... 7e-6
    # the Timoshenko model (shear + rotary inertia) sits slightly below: the slender-beam correction, of order
    # (radius of gyration / half wavelength)^2, here < 0.3 % for the first two modes
    fe = free_free_frequencies(model, 2)
    assert fe == pytest.approx(ref[:2], rel=3e-3) and np.all(fe < ref[:2])


def _layered(**over) -> dict:
    """Return a two-section shaft whose second section carries a steel sleeve and a soft hub as full layers."""
    d = {'name': 'layered',
         'materials': {'steel': {'E': 2.1e11, 'nu': 0.3, 'density': 7850.0},
                       'hub': {'E': 6894.75, 'G': 6894.75, 'density': 7833.412}},    # ROSS's compressor hub material
         'shaft': {'shear_coefficient': 'hutchinson', 'damping_alpha': 2.0, 'damping_beta': 3e-5, 'sections': [
             {'length': 0.4, 'outer_diameter': 0.03, 'material': 'steel', 'n_elements': 4},
             {'length': 0.3, 'outer_diameter': 0.03, 'inner_diameter': 0.01, 'material': 'steel', 'n_elements': 3,
              'shear_coefficient': 'cowper',
              'layers': [{'outer_diameter': 0.05, 'material': 'steel', 'shear_coefficient': 0.55},
                         {'outer_diameter': 0.12, 'inner_diameter': 0.05, 'material': 'hub'},
                         {'outer_diameter': 0.01, 'inner_diameter': 0.0, 'E': 7.0e10, 'nu': 0.33,
                          'density': 2700.0}]}]},
         'bearings': [{'node': 1, 'diameter': 0.03, 'length': 0.01, 'clearance': 5e-5, 'viscosity': 0.02},
                      {'node': 8, 'diameter': 0.03, 'length': 0.01, 'clearance': 5e-5, 'viscosity': 0.02}]}
    d['shaft'].update(over)
    return d


def test_layers_are_full_elements_on_the_host_nodes_with_their_own_shear():
    """
    ``layers``: concentric full Timoshenko elements (own phi from own E, G, kappa), summed on the host's two nodes.

    Reference: the same elements built one by one with rotor.elements.ShaftElement and summed by hand (as ROSS sums
    its several elements on one station); the rotor damping alpha M + beta K covers the layers; the mass is the
    closed form sum of rho A L.
    """
    rig = parse_rig(_layered())
    els = rig.shaft.elements
    assert len(els) == 7 and [len(e.layers) for e in els] == [0] * 4 + [3] * 3
    assert els[4].shear_coefficient == 'cowper' and els[0].shear_coefficient is None
    sleeve, hub, core = els[4].layers
    assert sleeve.inner_diameter == 0.03 and sleeve.shear_coefficient == 0.55   # inner defaults to the host's outer
    assert hub.youngs_modulus == hub.shear_modulus == 6894.75 and hub.shear_coefficient is None
    assert core.shear_modulus == pytest.approx(7.0e10 / 2.66, rel=2 * EPS)    # E / (2 (1 + nu)): 3 roundings
    model = RotorModel.from_params(rig)
    nd = 4 * 8
    M, K, G = (np.zeros((nd, nd)) for _ in range(3))
    A = {k: np.zeros((nd, nd)) for k in 'MKG'}     # per entry, the sum of its terms' magnitudes
    for i in range(7):
        parts = [ShaftElement(0.1, 0.03, 0.0, 2.1e11, 2.1e11 / 2.6, 7850.0, shear_method='hutchinson')]
        if i >= 4:
            parts = [ShaftElement(0.1, 0.03, 0.01, 2.1e11, 2.1e11 / 2.6, 7850.0, shear_method='cowper'),
                     ShaftElement(0.1, 0.05, 0.03, 2.1e11, 2.1e11 / 2.6, 7850.0, shear_method=0.55),
                     ShaftElement(0.1, 0.12, 0.05, 6894.75, 6894.75, 7833.412, shear_method='hutchinson'),
                     ShaftElement(0.1, 0.01, 0.0, 7.0e10, 7.0e10 / 2.66, 2700.0, shear_method='hutchinson')]
        s = slice(4 * i, 4 * i + 8)
        for el in parts:
            M[s, s] += el.M()
            K[s, s] += el.K()
            G[s, s] += el.G()
            for k, mat in (('M', el.M()), ('K', el.K()), ('G', el.G())):
                A[k][s, s] += np.abs(mat)
    # the same element matrices summed in another order: an entry of n <= 8 terms (4 parts on each of 2 elements)
    # is off by at most gamma_n ~ n EPS times the sum of its terms' magnitudes either way (Higham, eq. 4.4);
    # C = 2 M + 3e-5 K adds 3 roundings
    A['C'] = 2.0 * A['M'] + 3e-5 * A['K']
    for name, ref in (('M', M), ('K', K), ('G', G), ('C', 2.0 * M + 3e-5 * K)):
        assert np.all(np.abs(getattr(model, name) - ref) <= 2 * (8 + 3) * EPS * A[name]), name
    # E = G (nu = -0.5): the hub's own shear parameter 12 E I / (kappa G A L^2) = 12 (D^2 + d^2) / (16 kappa L^2)
    # with its own kappa(nu = -0.5) -- 2.8 here, ~20 on ROSS's shorter compressor elements
    hub_el = ShaftElement(0.1, 0.12, 0.05, 6894.75, 6894.75, 7833.412)
    kap = shear_coefficient(0.12, 0.05, -0.5)
    # both sides: about ten roundings of positive terms
    assert hub_el.phi == pytest.approx(12 * (0.12**2 + 0.05**2) / 16 / (kap * 0.01), rel=16 * EPS)
    area = math.pi / 4
    layered = (7850.0 * area * (0.03**2 - 0.01**2 + 0.05**2 - 0.03**2) + 7833.412 * area * (0.12**2 - 0.05**2)
               + 2700.0 * area * 0.01**2)
    want = 7850.0 * area * 0.03**2 * 0.4 + 0.3 * layered
    # sums of positive products (about 40 roundings either way): 64 EPS
    assert model.mass == pytest.approx(want, rel=64 * EPS) and rig.shaft.mass == pytest.approx(want, rel=64 * EPS)


def test_a_same_material_layer_is_the_solid_shaft_in_the_slender_limit():
    """
    A core plus a same-steel annulus layer is the solid shaft as an Euler-Bernoulli beam (EI and rho A add).

    Reference: the exact free-free Euler-Bernoulli frequencies of the solid shaft; the Timoshenko model sits slightly
    below them (shear and rotary inertia, < 0.3 % at L/D = 23 as for the stepped shaft above).
    """
    E, nu, rho, D, d, L = 2.1e11, 0.3, 7850.0, 0.03, 0.018, 2.0
    spec = {'name': 'core_and_sleeve', 'materials': {'s': {'E': E, 'nu': nu, 'density': rho}},
            'shaft': {'sections': [{'length': L, 'outer_diameter': d, 'material': 's', 'n_elements': 20,
                                    'layers': [{'outer_diameter': D, 'material': 's'}]}]},
            'bearings': [{'node': 2, 'diameter': D, 'length': 0.01, 'clearance': 5e-5, 'viscosity': 0.02}]}
    fe = free_free_frequencies(RotorModel.from_params(parse_rig(spec)), 2)
    # uniform free-free Euler-Bernoulli beam: (beta L)^2 sqrt(EI / rho A) / L^2, cosh(bL) cos(bL) = 1
    ref = np.array([4.730040744862704, 7.853204624095838]) ** 2 * math.sqrt(E * D**2 / 16 / rho) / L**2
    assert fe == pytest.approx(ref, rel=3e-3) and np.all(fe < ref)


@pytest.mark.parametrize('edit,field', [
    (lambda s: s['sections'][1]['layers'][1].pop('material'), r'sections\[1\]\.layers\[1\]\.material is missing'),
    (lambda s: s['sections'][1]['layers'][1].update(density=7800.0), r'layers\[1\]: give material or'),
    (lambda s: s['sections'][1]['layers'][0].update(lenght=0.1), r'layers\[0\]\.lenght: unknown key'),
    (lambda s: s['sections'][1]['layers'][0].update(inner_diameter=0.06), r'layers\[0\]\.inner_diameter'),
    (lambda s: s['sections'][1]['layers'][2].update(E=0.0), r'layers\[2\]\.E = 0\.0 \[Pa\] must be > 0'),
    (lambda s: s['sections'][1]['layers'][2].update(E=-5.0), r'layers\[2\]\.E = -5\.0 .*outside'),
    (lambda s: s['sections'][1].update(shear_coefficient='timoshenko'), r'sections\[1\]\.shear_coefficient'),
    (lambda s: s['sections'][1]['layers'][0].update(shear_coefficient=3.0), r'layers\[0\]\.shear_coefficient'),
    (lambda s: s['sections'][1]['layers'][0].update(material='brass'), r"layers\[0\]\.material = 'brass'"),
])
def test_layer_errors_name_the_field(edit, field):
    d = _layered()
    edit(d['shaft'])
    with pytest.raises(ParamError, match=field):
        parse_rig(d)


def test_materials_may_be_soft_but_not_zero():
    d = _layered()
    assert parse_rig(d).materials[1].youngs_modulus == 6894.75     # below the v1 shaft's 1e6 Pa bound
    for key, v, msg in (('E', 0.0, 'must be > 0'), ('G', float('inf'), 'must be finite'), ('E', 'soft', 'number')):
        d = _layered()
        d['materials']['hub'][key] = v
        with pytest.raises(ParamError, match=rf'materials\.hub\.{key}.*{msg}'):
            parse_rig(d)


def test_layers_and_element_shear_round_trip():
    rig = parse_rig(_layered())
    text = yaml.safe_dump(rig_to_dict(rig), sort_keys=False)
    assert parse_rig(yaml.safe_load(text)) == rig and 'layers' in text        # exact: YAML keeps a float's repr


def test_table_interpolation_is_linear_in_speed_and_flat_outside():
    d = yaml.safe_load(default_rig_path().read_text())
    d['seals'] = [{'name': 's', 'node': 6, 'table': {
        'speed_rpm': [1000, 2000, 4000], 'kxx': [1e5, 2e5, 6e5], 'kxy': [0.0, 5e4, -5e4], 'kyx': [1.0, 2.0, 3.0],
        'kyy': [3e5, 3e5, 1e5], 'cxx': [10.0, 20.0, 40.0], 'cyy': [5.0, 5.0, 5.0], 'cxy': [1.0, 0.0, 2.0]}}]
    t = parse_rig(d).seals[0].table
    rpm = np.array([1000.0, 2000.0, 4000.0])
    cols = {'kxx': [1e5, 2e5, 6e5], 'kxy': [0.0, 5e4, -5e4], 'kyx': [1.0, 2.0, 3.0], 'kyy': [3e5, 3e5, 1e5],
            'cxx': [10.0, 20.0, 40.0], 'cxy': [1.0, 0.0, 2.0], 'cyx': [0.0] * 3, 'cyy': [5.0, 5.0, 5.0]}
    for s in (500.0, 1000.0, 1500.0, 2500.0, 3999.0, 4000.0, 9000.0):
        K, C = interpolate(t, s * math.pi / 30)
        for k, v in cols.items():
            want = np.interp(s, rpm, v)    # numpy's linear interpolation holds the end values outside
            got = (K if k[0] == 'k' else C)['xy'.index(k[1]), 'xy'.index(k[2])]
            # a + t (b - a) here and in numpy, t from speeds in rad/s here and in rpm there: a few roundings each
            assert abs(got - want) <= 8 * EPS * max(map(abs, v)), (s, k)


def test_known_elements_are_in_the_model_and_not_identified():
    rig = load_rig(PLANT)
    model = RotorModel.from_params(rig)
    w = 3000 * math.pi / 30
    assert model.bearing_nodes == (4, 30) and set(bearing_fn(rig)(w)) == {4, 30}
    Z = dynamic_stiffness(model, w, w, {})
    K, C = interpolate(rig.seals[0].table, w)
    i = cv.dof_index(24, 'x', model.n_nodes)
    Zr = RotorModel.from_params(dataclasses.replace(rig, seals=())).K - w * w * model.M \
        + 1j * w * (model.C + w * model.G)
    # the seal block is what remains of the 3.6e10 diagonal it sits on after subtracting the model without it: a few
    # roundings of that diagonal (K - w^2 M + j w (C + w G), summed in another order)
    tol = 16 * EPS * np.max(np.abs(Z[i:i + 2, i:i + 2]))
    assert np.max(np.abs(Z[i:i + 2, i:i + 2] - Zr[i:i + 2, i:i + 2] - (K + 1j * w * C))) <= tol


def test_pedestal_in_series_equals_the_condensed_impedance():
    rig = load_rig(PLANT)
    ped = RotorModel.from_params(rig)
    bare = RotorModel.from_params(dataclasses.replace(
        rig, seals=(), bearings=tuple(dataclasses.replace(b, support=None) for b in rig.bearings)))
    ped_noseal = RotorModel.from_params(dataclasses.replace(rig, seals=()))
    assert ped.ndof == bare.ndof + 2
    sup = rig.bearings[1].support
    for rpm, ratio in ((1500, 1.0), (3000, 1.0), (3000, 2.7)):
        W = rpm * math.pi / 30
        w = ratio * W
        co = bearing_fn(rig)(W)
        F = np.zeros(ped_noseal.ndof, complex)
        F[cv.dof_index(17, 'x', bare.n_nodes)] = 100.0
        F[cv.dof_index(13, 'y', bare.n_nodes)] = 50.0j
        Z_full = dynamic_stiffness(ped_noseal, W, w, co)
        q_full = np.linalg.solve(Z_full, F)[:bare.ndof]
        # condensed: film Zf in series with the pedestal Zs = k - w^2 m + j w c (diagonal), K_eff = Zf (Zf + Zs)^-1 Zs
        Kb, Cb = co[30]
        Zf = Kb + 1j * w * Cb
        Zs = np.diag([sup.stiffness[a] - w * w * sup.mass[a] + 1j * w * sup.damping[a] for a in range(2)])
        Keff = Zf @ np.linalg.solve(Zf + Zs, Zs)
        Z = dynamic_stiffness(bare, W, w, {4: co[4]}).astype(complex)
        i = cv.dof_index(30, 'x', bare.n_nodes)
        Z[i:i + 2, i:i + 2] += Keff
        q_cond = np.linalg.solve(Z, F[:bare.ndof])
        # two backward-stable solves (LU, partial pivoting; test/error_bounds.py solve_tol) and the 2 x 2
        # condensation's own solve
        tol = solve_tol(Z_full, Z, Zf + Zs)
        assert np.max(np.abs(q_full - q_cond)) <= tol * np.max(np.abs(q_cond))


# ------------------------------------------------------------------------------------------------ probes at an angle
def test_probe_direction_text_round_trips():
    for a, g in ((0.0, 1.0), (90.0, 1.0), (45.0, 1.0), (-45.0, 1.02), (135.0, 0.98), (12.345678901234567, 1.0)):
        assert cv.parse_probe_direction(cv.probe_direction(a, g)) == (a, g)
    assert cv.probe_direction(0.0) == 'x' and cv.probe_direction(90.0) == 'y'
    with pytest.raises(ValueError):
        cv.parse_probe_direction('z')


def test_pm45_pair_equals_the_xy_pair_rotated_exactly():
    rig = load_rig()
    model = RotorModel.from_params(rig)
    xy = probe_matrix(model, [(6, 'x'), (6, 'y')])
    pm = probe_matrix(model, [(6, cv.probe_direction(45.0)), (6, cv.probe_direction(-45.0))])
    c, s = cv.probe_row(45.0)
    R = np.array([[c, s], [c, -s]])
    # the x/y rows are unit vectors: R @ xy is c * 1 + s * 0 per entry, one rounding at most
    assert np.max(np.abs(pm - R @ xy)) <= EPS
    # and through the simulated rig (time domain, no noise): the +-45 channels are the rotated x/y channels
    run = rig.simulation.runs[0]
    kw = {'speeds_rpm': [1200, 2400], 'dwell': 0.2, 'ramp': 0.0, 'noise': 0.0}
    a = simulate_run(rig, run, probes=(Probe('x', 6, 'x'), Probe('y', 6, 'y')), **kw)
    b = simulate_run(rig, run, probes=(Probe('p', 6, cv.probe_direction(45.0)),
                                       Probe('m', 6, cv.probe_direction(-45.0))), **kw)
    # both are c x +- s y of the same states (the x/y channels are x and y themselves): 3 roundings each side with
    # |c| + |s| = sqrt(2), so at most 2 * 3/2 * sqrt(2) EPS of the largest sample
    assert np.max(np.abs(b.samples - a.samples @ R.T)) <= 3 * math.sqrt(2) * EPS * np.max(np.abs(a.samples))


def test_messages_carry_the_probe_angle():
    probes = (Probe('p5L', 5, cv.probe_direction(135.0)), Probe('p5R', 5, cv.probe_direction(45.0, 1.01)))
    x = np.zeros((8, 2)) + 1e-6
    msg = block_to_msg(x, 1, 1000.0, 100.0, 0.0, probes, types=typestore(), sample_angles=np.arange(8) * 0.1)
    b = block_from_msg(msg)
    assert b.probes == probes and [p.angle_deg for p in b.probes] == [135.0, 45.0] and b.probes[1].gain == 1.01
    assert validate_block(b) == []
    bad = dataclasses.replace(b, directions=('x', 'sideways'))
    assert any('directions' in p for p in validate_block(bad))


# ------------------------------------------------------------------------------------------------ plant-like example
@pytest.fixture(scope='module')
def plant_data():
    rig = load_rig(PLANT)
    model = RotorModel.from_params(rig)
    recs = simulate_plan(rig, ramp=0.0, model=model)        # time domain, 1 % noise, instant speed steps
    return rig, model, from_recordings(recs)


def _worst_errors(rig, results):
    truth = truth_bearing_fn(rig)
    ek = ec = 0.0
    for r in results:
        t = truth(r.speed)
        for i, n in enumerate(r.nodes):
            K, C = t[n]
            ek = max(ek, float(np.max(np.abs(r.K[i] - K)) / np.max(np.abs(K))))
            ec = max(ec, float(np.max(np.abs(r.C[i] - C)) / np.max(np.abs(C))))
    return ek, ec


def test_plant_truth_is_10_to_30_percent_off(plant_data):
    rig, _, _ = plant_data
    w = 3000 * math.pi / 30
    nom, tru = bearing_fn(rig)(w), truth_bearing_fn(rig)(w)
    for n in nom:
        for j in range(2):
            d = np.max(np.abs(tru[n][j] - nom[n][j])) / np.max(np.abs(nom[n][j]))
            assert 0.1 <= d <= 0.3, (n, j, d)


def test_plant_physical_from_one_pm45_pair(plant_data):
    rig, model, data = plant_data
    idx = [i for i, p in enumerate(data.probes) if p.node == 17]          # the midspan +-45 deg pair only
    sub = dataclasses.replace(data, probes=tuple(data.probes[i] for i in idx), runs=data.runs[:1],
                              X=data.X[:1][:, :, idx], X_std=data.X_std[:1][:, :, idx],     # unbalance run only
                              plain=data.plain.take((slice(0, 1), slice(None), idx)))
    ek, ec = _worst_errors(rig, identify('physical', model, rig, sub))
    assert ek <= 0.02 and ec <= 0.03, (ek, ec)


def test_plant_direct_with_the_force_plan(plant_data):
    rig, model, data = plant_data
    ek, ec = _worst_errors(rig, identify('direct', model, rig, data))
    assert ek <= 0.03 and ec <= 0.03, (ek, ec)


def test_model_command_writes_modes_for_any_machine(tmp_path):
    args = argparse.Namespace(params=str(PLANT), out=str(tmp_path), max_rpm=5000.0, speeds='1500,3000', modes=6,
                              no_update=True)
    assert cmd.run(args) == 0
    r = json.loads((tmp_path / 'model.json').read_text())
    assert [row['speed_rpm'] for row in r['speeds']] == [1500.0, 3000.0]
    assert all(len(row['modes_hz']) == 6 and len(row['log_dec']) == 6 for row in r['speeds'])
    assert r['n_elements'] >= 30 and r['known_elements'][0]['kind'] == 'table'


def test_load_vector_rotates_the_bearing_against_the_film_force_itself(raw):
    """
    Check a load vector (the film force on the journal, e.g. a misaligned machine's (-2.59, 13.2) N).

    Equilibrium and K, C against the short-bearing film force by direct quadrature (short_film_force), not the closed
    form.
    """
    d = copy.deepcopy(raw)
    d['bearings'][0]['load'] = [-2.59, 13.2]
    b = parse_rig(d).bearings[0]
    W = math.hypot(-2.59, 13.2)
    assert b.load == pytest.approx(W) and b.load_direction == pytest.approx((-2.59 / W, 13.2 / W))
    speed = 1800 * math.pi / 30
    s = solution(b, speed, b.load)
    x, y = s.journal_position
    geo = (b.diameter, b.length, b.clearance, b.viscosity, speed)
    assert short_film_force(x, y, 0.0, 0.0, *geo, n=200000) == pytest.approx((-2.59, 13.2), rel=2e-4)
    h, v = 1e-4 * b.clearance, 1e-4 * b.clearance * speed
    for j, (dx, dy) in enumerate(((h, 0.0), (0.0, h))):     # K = -dF/dq, C = -dF/dq' (central differences)
        fp = np.array(short_film_force(x + dx, y + dy, 0.0, 0.0, *geo, n=200000))
        fm = np.array(short_film_force(x - dx, y - dy, 0.0, 0.0, *geo, n=200000))
        assert -(fp - fm) / (2 * h) == pytest.approx(s.K[:, j], rel=2e-3, abs=2e-3 * np.abs(s.K).max())
        vx, vy = (v, 0.0) if j == 0 else (0.0, v)
        fp = np.array(short_film_force(x, y, vx, vy, *geo, n=200000))
        fm = np.array(short_film_force(x, y, -vx, -vy, *geo, n=200000))
        assert -(fp - fm) / (2 * v) == pytest.approx(s.C[:, j], rel=2e-3, abs=2e-3 * np.abs(s.C).max())
    # gravity along x (a vertical machine lying on its side): the load follows -gravity
    d = copy.deepcopy(raw)
    d['gravity'] = [-9.80665, 0.0]
    rig = parse_rig(d)
    assert rig.bearings[0].load_direction == (1.0, 0.0)
    assert static_bearing_loads(RotorModel.from_params(rig)) == static_bearing_loads(RotorModel.from_params(
        load_rig()))


def test_physical_fits_one_scale_on_k_and_one_on_c_of_table_bearings(raw):
    """Two identified table bearings (cross-coupled, speed-dependent), truth = table x (1.2 on K, 0.85 on C)."""
    d = copy.deepcopy(raw)
    rpm = [500, 1500, 3500]
    tab = {'speed_rpm': rpm, 'kxx': [2e5, 3e5, 4e5], 'kxy': [2e4, 8e4, 2e5], 'kyx': [-2e4, -8e4, -2e5],
           'kyy': [2.5e5, 3.5e5, 4.5e5], 'cxx': [300.0, 250.0, 200.0], 'cyy': [350.0, 300.0, 250.0],
           'cxy': [-20.0, -30.0, -40.0], 'cyx': [-20.0, -30.0, -40.0]}
    for b in d['bearings']:
        for k in ('diameter', 'length', 'clearance', 'viscosity', 'load', 'model'):
            b.pop(k)
        b.update(kind='table', table=tab)
    d['simulation']['truth'] = {'k_factor': [1.2, 1.1], 'c_factor': [0.85, 0.9]}
    rig = parse_rig(d)
    model = RotorModel.from_params(rig)
    want = {'bearing1.k_scale': 1.2, 'bearing2.k_scale': 1.1, 'bearing1.c_scale': 0.85, 'bearing2.c_scale': 0.9}
    # noise-free phasors (sigma 1e-6 relative, for the weights): the scales come back to the solver tolerance
    data = simulate_data(rig, rig.simulation.runs, rig.simulation.speeds_rpm, noise=0.0, model=model)
    data.X_std[...] = 1e-6 * np.abs(data.X)
    res = identify('physical', model, rig, data, options={'table_form': 2})      # the truth's form
    par = res[0].extra['parameters']
    for k, v in want.items():
        assert par[k]['value'] == pytest.approx(v, rel=1e-8), k
    truth = truth_bearing_fn(rig)
    for r in res:
        t = truth(r.speed)
        for i, n in enumerate(r.nodes):
            assert np.max(np.abs(r.K[i] - t[n][0])) <= 1e-8 * np.max(np.abs(t[n][0]))
            assert np.max(np.abs(r.C[i] - t[n][1])) <= 1e-8 * np.max(np.abs(t[n][1]))
    # 1 % noise: within 3 sigma of the truth (C is weakly determined on this rig: sigma ~ 20 %, stated honestly)
    data = simulate_data(rig, rig.simulation.runs, rig.simulation.speeds_rpm, noise=0.01, model=model)
    rng = np.random.default_rng(5)
    data.X[...] += data.X_std * (rng.standard_normal(data.X.shape) + 1j * rng.standard_normal(data.X.shape))
    par = identify('physical', model, rig, data, options={'table_form': 2})[0].extra['parameters']
    for k, v in want.items():
        assert abs(par[k]['value'] - v) <= 3 * par[k]['std'], (k, par[k])


def test_conventional_from_pm45_pairs_equals_from_xy_pairs():
    """The conventional method on +-45 deg pairs (x, y rebuilt at each probe node) = on x/y pairs at those nodes."""
    rig = load_rig()
    model = RotorModel.from_params(rig)
    nodes = (1, 3, 9, 11)
    xy = tuple(Probe(f'p{n}{d}', n, d) for n in nodes for d in ('x', 'y'))
    pm = tuple(Probe(f'p{n}{a}', n, cv.probe_direction(a)) for n in nodes for a in (45.0, 135.0))
    runs = rig.simulation.runs
    speeds = [900, 1800, 2700]
    out = []
    for probes in (xy, pm, xy):
        data = simulate_data(rig, runs, speeds, probes=probes, noise=0.0, model=model)
        data.X_std[...] = 1e-3 * np.abs(data.X).max()
        if len(out) == 2:      # the x/y phasors moved by a relative 1e-8: the method's sensitivity to its data
            data.X[...] *= 1.0 + 1e-8 * np.random.default_rng(3).standard_normal(data.X.shape)
        out.append(identify_conventional(model, rig, data, probes, runs, {'bearing_fn': bearing_fn(rig)}))
    # the +-45 deg phasors are the x/y ones rotated (c x + s y, a few roundings: 4 EPS relative) and rotated back by
    # the method; K and C move by the measured sensitivity (their change per relative change of the phasors, the
    # method's condition number) times those 2 x 4 EPS -- bounded here with a factor 4 for the random direction
    for a, b, p in zip(*out):
        for sym in ('K', 'C'):
            scale = np.max(np.abs(getattr(a, sym)))
            kappa = np.max(np.abs(getattr(p, sym) - getattr(a, sym))) / (1e-8 * scale)
            assert np.max(np.abs(getattr(a, sym) - getattr(b, sym))) <= 4 * kappa * 8 * EPS * scale, sym


def test_known_table_bearing_is_a_support_in_statics():
    """
    A shaft on two identified bearings and a known (table) bearing midway: the continuous beam on three supports.

    Under its own weight q [N/m] over two equal spans l the reactions are 3/8 q l, 10/8 q l, 3/8 q l (Euler-Bernoulli,
    which cubic elements with consistent loads reproduce exactly; the Timoshenko shear flexibility of this shaft,
    l/D = 20, moves them by ~5e-4).
    """
    D, L, rho = 0.03, 1.2, 7800.0
    tab = {'speed_rpm': [1000], 'kxx': [1e7], 'kyy': [1e7], 'cxx': [100.0], 'cyy': [100.0]}
    d = {'name': 'three', 'shaft': {'length': L, 'diameter': D, 'n_elements': 24, 'density': rho,
                                    'youngs_modulus': 2.1e11, 'poisson_ratio': 0.3},
         'bearings': [{'node': 1, 'diameter': D, 'length': 0.01, 'clearance': 5e-5, 'viscosity': 0.02},
                      {'node': 25, 'diameter': D, 'length': 0.01, 'clearance': 5e-5, 'viscosity': 0.02},
                      {'name': 'middle', 'node': 13, 'kind': 'table', 'identify': False, 'table': tab}]}
    rig = parse_rig(d)
    assert [b.node for b in rig.bearings] == [1, 25] and rig.known_bearings[0].node == 13
    model = RotorModel.from_params(rig)
    ql = rho * math.pi * D**2 / 4 * 9.80665 * L / 2
    want = {1: 3 / 8 * ql, 13: 10 / 8 * ql, 25: 3 / 8 * ql}
    r = static_bearing_loads(model)
    assert set(r) == {1, 13, 25} and all(r[n] == pytest.approx(want[n], rel=2e-3) for n in want)
    eb = RotorModel.from_elements([ShaftElement(e.length, e.outer_d, e.inner_d, e.E, e.G_mod, e.rho, shear=False,
                                                rotary_inertia=False) for e in model.elements], bearing_nodes=(1, 25))
    eb.support_nodes = model.support_nodes
    r = static_bearing_loads(eb)
    # exact in exact arithmetic; the reactions come from one backward-stable solve on the free DOFs of the vertical
    # plane: a few EPS times its condition number
    plane = [cv.dof_index(k, a, eb.n_nodes) for k in range(1, eb.n_nodes + 1) for a in ('y', 'tx')]
    free = [i for i in plane if i not in {cv.dof_index(k, 'y', eb.n_nodes) for k in want}]
    tol = 8 * EPS * np.linalg.cond(eb.K[np.ix_(free, free)])
    assert all(r[n] == pytest.approx(want[n], rel=tol) for n in want)


def test_finite_bearing_with_gumbel_cavitation_uses_the_half_sommerfeld_table(raw):
    """
    cavitation: gumbel -- 'finite' evaluates the shipped half-Sommerfeld table, 'finite_direct' the direct solver.

    Direct: the same solver call, each converged to |F - W| / W <= 1e-8, which moves K and C by less than 1e-7 of
    their largest entry (dK/dq * c / K < 10 for eccentricities < 0.9).  Table: within its stated accuracy against the
    direct solver on the default grid (finite_table.stated_tolerance, of the largest entry of each block).
    """
    d = copy.deepcopy(raw)
    for b in d['bearings']:
        b['model'] = 'finite'
    d['bearings'][0]['cavitation'] = 'gumbel'
    b0, b1 = parse_rig(d).bearings
    ref = finite.reynolds(b0.diameter, b0.length, b0.clearance, b0.viscosity, 9.7, 300.0, cavitation='gumbel')
    direct = solution(b0, 300.0, 9.7, model='finite_direct')
    for a, b in ((direct.K, ref.K), (direct.C, ref.C)):
        assert np.max(np.abs(a - b)) <= 1e-7 * np.max(np.abs(b))
    s = solution(b0, 300.0, 9.7)
    tol = finite_table.stated_tolerance(ref.sommerfeld, table_grid=False)
    for a, b in ((s.K, ref.K), (s.C, ref.C)):
        assert np.max(np.abs(a - b)) <= tol * np.max(np.abs(b)), (np.max(np.abs(a - b)) / np.max(np.abs(b)), tol)
    assert not np.allclose(solution(b1, 300.0, 9.7).K, s.K, rtol=0.02)   # Swift-Stieber differs by > 2 %
