"""
bearing_id.rotor against ROSS (ross-rotordynamics), an independent rotordynamics code.

The reference values come from scripts/ross_reference.py (ROSS version recorded in the JSON); ROSS itself is not
needed here.  Same rig (params/rig.yaml), Timoshenko shaft with Cowper's shear coefficient on both sides (ROSS 2.3.0's
'hutchinson' option misses the square on (1 + nu)), explicit disc m/Id/Ip, constant cross-coupled bearings.
Requirement (issue 3): natural frequencies and unbalance response agree to 1e-6 relative.
"""
import json
import math
from pathlib import Path

from bearing_id.config.params import load_rig
from bearing_id.conventions import dof_index, unbalance_phasors
from bearing_id.rotor.assembly import harmonic_response, RotorModel
from bearing_id.rotor.elements import ShaftElement
from bearing_id.rotor.modal import damped_modes, free_free_frequencies
import numpy as np
import pytest

REF = json.loads((Path(__file__).parent / 'data' / 'ross_reference.json').read_text())
TOL = 1e-6


@pytest.fixture(scope='module')
def model():
    return RotorModel.from_params(load_rig(), shear_method=REF['shear_method'])


@pytest.fixture(scope='module')
def coeffs():
    return {int(k): (np.array(v['K']), np.array(v['C'])) for k, v in REF['bearings'].items()}


def test_reference_is_from_ross_2():
    assert int(REF['ross_version'].split('.')[0]) >= 2


def test_free_free_frequencies(model):
    ref = np.array(REF['free_free_wn'])
    ours = free_free_frequencies(model, ref.size)
    assert np.allclose(ours, ref, rtol=TOL, atol=0), ours / ref - 1


@pytest.mark.parametrize('i', range(len(REF['modes'])))
def test_damped_eigenvalues(model, coeffs, i):
    e = REF['modes'][i]
    speed = e['speed_rpm'] * 2 * math.pi / 60
    ref = np.array(e['eigenvalue_re']) + 1j * np.array(e['eigenvalue_im'])
    m = damped_modes(model, speed, coeffs, ref.size)
    assert np.all(np.abs(m.eigenvalues / ref - 1) < TOL), np.abs(m.eigenvalues / ref - 1)
    assert np.allclose(m.natural_frequency, e['wn'], rtol=TOL, atol=0)
    assert np.allclose(m.frequency, e['wd'], rtol=TOL, atol=0)


@pytest.mark.parametrize('i', range(len(REF['unbalance_response'])))
def test_unbalance_response(model, coeffs, i):
    e = REF['unbalance_response'][i]
    u = REF['unbalance']
    speed = e['speed_rpm'] * 2 * math.pi / 60
    F = np.zeros(model.ndof, complex)
    fx, fy = unbalance_phasors(u['magnitude'], u['phase'], speed)
    F[dof_index(u['node'], 'x')], F[dof_index(u['node'], 'y')] = fx, fy
    q = harmonic_response(model, speed, speed, F, coeffs)
    for key, val in e.items():
        if key == 'speed_rpm':
            continue
        ref = complex(*val)
        ours = q[dof_index(int(key[:-1]), key[-1])]
        assert abs(ours - ref) <= TOL * abs(ref), (key, ours, ref)


def test_ross_hutchinson_difference_is_its_kappa():
    """
    The 'hutchinson' free-free frequencies of ROSS are reproduced exactly with kappa without the square.

    ROSS's 'hutchinson' free-free frequencies are reproduced exactly with kappa = 6(1+nu)/(7+12nu+4nu^2) (no square),
    and differ from bearing_id's Hutchinson (with the square) by more than the 1e-6 tolerance.
    """
    rig = load_rig()

    class RossKappa(ShaftElement):
        @property
        def kappa(self):
            nu = self.E / (2 * self.G_mod) - 1
            return 6 * (1 + nu) / (7 + 12 * nu + 4 * nu**2)

    sh = rig.shaft
    ours = RotorModel.from_params(rig)
    els = [RossKappa(le, sh.diameter, sh.inner_diameter, sh.youngs_modulus, sh.shear_modulus, sh.density)
           for le in sh.element_lengths]
    ross_like = RotorModel.from_elements(els, ours.discs)
    ref = np.array(REF['free_free_wn_ross_hutchinson'])
    assert np.allclose(free_free_frequencies(ross_like, ref.size), ref, rtol=TOL, atol=0)
    assert np.max(np.abs(free_free_frequencies(ours, ref.size) / ref - 1)) > 10 * TOL
