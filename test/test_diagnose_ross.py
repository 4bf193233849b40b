"""
Diagnose on fault recordings made with another library's fault models: ROSS 2.3.0 (physics written elsewhere).

The recordings are ``test/data/ross/faults/*.npz``, made by ``scripts/ross_faults.py`` with ROSS's own ``Crack``
(Mayes breathing, depth 0.2 of the diameter, gravity), ``Rubbing`` and ``MisalignmentFlex`` fault objects on the
paper rig's shaft (see README.json there: parameters, step-size convergence, and ``truth``: what ROSS's fault object
says about the fault's size, e.g. the coupling's 2X reaction force computed by ROSS over one revolution).  The
``_nominal`` set runs on the project's own nominal bearings (the model diagnose starts from); the reference set on
ROSS-style constant bearings the model does not have.  ``pedestal*_nominal`` (``scripts/ross_pedestal.py``) put
a bearing on a pedestal ROSS's way (n_link to a support node with a point mass and a support bearing).  1 % white
noise (of each channel's RMS) is added here, seeded.

Right answers (issue 24): a library fault is named and sized within 15 % (or its size is reported not determined);
a fault outside the library, or a recording whose bearings differ from the model, gets no validated wrong name.

The crack's size is its depth by Papadopoulos & Dimarogonas' c55 law, which ROSS's ``Crack`` reads from its table
too -- but ROSS's Mayes crack puts the cracked flexibility into the element's clamped-rotation translational
stiffness alone (its ``_compute_crack_stiffness_gasch_mayes`` keeps the healthy rotation terms).  That loss is
exactly a hinge at 0.325 of the element eleven times as compliant as c55 (an ad-hoc check with ROSS's own open and
closed element matrices, depth 0.2 of the diameter on this shaft: 1.40e-4 against 1.27e-5 rad/(N m)).  A depth
sized from ROSS's recording by the law is so not ROSS's depth; this set's final model misfits at the noise floor
and the depth is reported not determined, which the test accepts (a number would have to be within 15 %).
"""
from __future__ import annotations

import json
from pathlib import Path

from bearing_id.config.params import load_rig
from bearing_id.diagnose import diagnose
from bearing_id.diagnose.effect import determined
from bearing_id.io.recordings import load_npz
import numpy as np
import pytest

DATA = Path(__file__).parent / 'data' / 'ross' / 'faults'
README = json.loads((DATA / 'README.json').read_text())
NOISE = 0.01


def noisy(name: str, seed: int) -> list:
    """Return runs A and B of ``name`` with 1 % white noise (of each channel's RMS about its mean) added."""
    rng = np.random.default_rng(seed)
    out = []
    for run in ('A', 'B'):
        rec = load_npz(DATA / f'{name}_{run}.npz')
        x = np.asarray(rec.samples, float)
        s = np.std(x - x.mean(axis=0), axis=0)
        rec.samples = x + NOISE * s * rng.standard_normal(x.shape)
        out.append(rec)
    return out


@pytest.fixture(scope='module')
def rig():
    return load_rig()


def places(d, effect: dict) -> list[str]:
    """Return the location diagnose chose for ``effect`` and the ones it says fit about as well."""
    return [effect['where']] + [a['where'] for a in effect.get('alternatives', [])]


def test_a_ross_breathing_crack_is_named_at_its_element(rig):
    truth = README['sets']['nominal']['faults']['crack']['truth']
    d = diagnose(noisy('crack_nominal', 1), rig)
    assert d.verdict == 'breathing_crack', d.sentences
    (eff,) = d.effects
    a, b = truth['element_nodes']
    # the crack's element, or the location diagnose says it cannot tell from it (one probe station)
    assert any(f'nodes {a}-{b}' in w for w in places(d, eff)), places(d, eff)
    # its signature: a 3X beside the 2X (Mayes breathing under the sag: about half), the same in both runs
    p = eff['parameters']
    assert 0.3 <= p['kink_3x'] / p['kink_2x'] <= 0.8, p
    # its depth: within 15 % of ROSS's or reported not determined (with the sentence saying so)
    depth = README['sets']['nominal']['faults']['crack']['parameters']['depth_ratio']
    if 'depth_ratio' in eff['undetermined']:
        assert 'crack depth not determined by these data' in eff['sentence'], eff['sentence']
    else:
        assert p['depth_ratio'] == pytest.approx(depth, rel=0.15), eff['sentence']
    # it explains the mismatch (>= 80 % of the residual power)
    assert d.residual_after ** 2 <= 0.2 * d.residual_before ** 2


def test_a_ross_coupling_misalignment_is_named_and_sized(rig):
    truth = README['sets']['nominal']['faults']['misalignment']['truth']
    f2 = truth['force_2x']['node_a']
    d = diagnose(noisy('misalignment_nominal', 2), rig)
    assert d.verdict == 'misalignment', d.sentences
    (eff,) = d.effects
    p = eff['parameters']
    # ROSS's reaction force on each coupling node, split into its rotating parts, within 15 %
    assert p['backward'] == pytest.approx(f2['backward_N'], rel=0.15), (p, f2)
    assert p['forward'] <= 0.15 * f2['backward_N'] + f2['forward_N'], (p, f2)
    # the coupling's end (nodes 1-2), or the mirror end it says fits as well (symmetric rig, one probe station)
    a, b = truth['element_nodes']
    assert any(f'node {a}' in w or f'nodes {a} and {b}' in w for w in places(d, eff)), places(d, eff)


def test_a_ross_rub_is_named_at_its_node_and_contact_speeds(rig):
    fault = README['sets']['nominal']['faults']['rub']
    truth = fault['truth']
    contact = {int(r) for runs in fault['contact_speeds_rpm'].values() for r in runs}
    d = diagnose(noisy('rub_nominal', 3), rig)
    assert d.verdict == 'rub', d.sentences
    (eff,) = d.effects
    assert f"node {truth['node']} " in eff['where'], eff['where']
    p = eff['parameters']
    # the contact speeds are ROSS's
    assert (p['contact_from_rpm'], p['contact_to_rpm']) == (min(contact), max(contact)), (p, contact)
    # the clearance and the contact stiffness within 15 %, or not determined
    for key, true in (('clearance', truth['clearance_m']), ('contact_stiffness', truth['contact_stiffness'])):
        assert key in eff['undetermined'] or p[key] == pytest.approx(true, rel=0.15), (key, p, eff['undetermined'])


def test_a_ross_crack_on_bearings_the_model_lacks_gets_no_wrong_name(rig):
    d = diagnose(noisy('crack', 4), rig)
    assert d.verdict in ('unexplained', 'breathing_crack'), d.sentences


def test_a_2x_source_outside_the_library_is_not_called_a_crack(rig):
    # the ROSS coupling with misalignment left out of the candidates: the crack fits its 2X but lacks its own 3X
    d = diagnose(noisy('misalignment_nominal', 5), rig, effects=('breathing_crack', 'probe_runout', 'shaft_bow'))
    assert d.verdict == 'unexplained', d.sentences
    assert max(d.signature['orders'], key=d.signature['orders'].get) == '2X', d.signature
    assert any(s.startswith('fits but not accepted: breathing_crack') for s in d.sentences), d.sentences


def test_a_ross_rub_on_bearings_the_model_lacks_gets_no_wrong_name(rig):
    # the reference set's constant bearings are not the model's theory: a probe orientation fits 39 % of it with
    # gains x0.7 and validates, but the model still misfits at the noise floor -- no wrong name
    fault = README['sets']['reference']['faults']['rub']
    contact = {int(r) for runs in fault['contact_speeds_rpm'].values() for r in runs}
    d = diagnose(noisy('rub', 6), rig)
    assert d.verdict in ('unexplained', 'rub'), d.sentences
    if d.verdict == 'rub':                   # the right name, at the right node
        assert f"node {fault['truth']['node']} " in d.effects[0]['where'], d.effects
    else:
        assert set(d.signature['speeds_rpm']) & contact, (d.signature['speeds_rpm'], contact)


@pytest.mark.parametrize('name, seed', [('pedestal', 4), ('pedestal_b1', 8)])
def test_a_ross_pedestal_is_named_at_its_bearing_and_sized_without_the_bearings_absorbing_it(rig, name, seed):
    """
    A pedestal ROSS made is named at its bearing (its response change stays below the model tolerance).

    Under bearing 2 it is stiffer in y; under bearing 1 as soft in x as in y, and heavier.

    Under bearing 2 it was "none": the bearing-2 viscosity refitted to x0.46 absorbed it; then, with the pedestal found
    only under a finite-bearing form, a wrong form name beside it.  Under bearing 1 a disc mass error at node 4 fitted
    it about as well at the model tolerance and was named, validated, though it misfits identify's vectors at the noise
    floor (chi2/dof 2.9e3).  The right answer: support flexibility at its bearing, the bearing factors left near 1,
    and each pedestal stiffness and dynamic stiffness within 15 % of ROSS's or not determined.
    """
    truth = README['sets']['nominal']['faults'][name]['truth']
    d = diagnose(noisy(f'{name}_nominal', seed), rig)
    assert d.verdict == 'support_flexibility', d.sentences
    (eff,) = d.effects
    nth = [b.node for b in rig.bearings].index(truth['bearing_node']) + 1
    assert f"bearing {nth} (node {truth['bearing_node']})" in eff['where'], eff['where']
    p, sd = eff['parameters'], eff['std']
    low, high = (str(r) for r in (min(README['speeds_rpm']), max(README['speeds_rpm'])))
    for dr in 'xy':
        if f'k_{dr}' not in p:
            continue
        kdyn = truth['kdyn_N_per_m']
        for key, true in ((f'k_{dr}', truth[f'k_{dr}']), (f'kdyn_{dr}_low', kdyn[low][dr]),
                          (f'kdyn_{dr}_high', kdyn[high][dr])):
            assert not determined(p[key], sd.get(key)) or p[key] == pytest.approx(true, rel=0.15), (key, p, sd)
    # the bearings did not absorb it: every refitted bearing factor within 10 % of nominal
    assert all(abs(f - 1.0) <= 0.1 for fs in d.bearing_factors.values() for f in np.ravel(fs)), d.bearing_factors
