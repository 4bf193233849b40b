"""Parameter loading: the packaged rig parses, and bad files fail with a message that names the field."""
import copy

from bearing_id.config.params import default_rig_path, load_rig, ParamError, parse_rig
import pytest
import yaml


@pytest.fixture(scope='module')
def raw():
    return yaml.safe_load(default_rig_path().read_text())


def test_packaged_rig(raw):
    rig = load_rig()
    assert rig.shaft.n_nodes == 11
    assert rig.bearing_nodes() == (2, 10)
    assert [d.node for d in rig.discs] == [4, 8]
    assert rig.shaft.node_z[-1] == pytest.approx(0.85)
    # Table 1: shaft + two 80 x 15 mm discs; the paper quotes 0.86 kg for the rotor (shaft) mass
    assert rig.shaft.mass == pytest.approx(0.86, rel=0.05)
    assert rig.discs[0].mass == pytest.approx(7800 * 3.14159265 / 4 * (0.08**2 - 0.01265**2) * 0.015, rel=1e-6)


@pytest.mark.parametrize('path,value,field', [
    (('bearings', 1, 'clearance'), -1.0, 'bearings[1].clearance'),
    (('bearings', 0, 'viscosity'), 'oil', 'bearings[0].viscosity'),
    (('discs', 0, 'node'), 12, 'discs[0].node'),
    (('shaft', 'poisson_ratio'), 0.7, 'shaft.poisson_ratio'),
    (('shaft', 'youngs_modulus'), 6894.75, 'shaft.youngs_modulus'),    # v1 keeps its 1e6 Pa bound (materials: > 0)
    (('probes', 0, 'direction'), 'z', 'probes[0].direction'),
    (('simulation', 'sample_rate'), float('nan'), 'simulation.sample_rate'),
])
def test_bad_values_name_the_field(raw, path, value, field):
    d = copy.deepcopy(raw)
    tgt = d
    for k in path[:-1]:
        tgt = tgt[k]
    tgt[path[-1]] = value
    with pytest.raises(ParamError, match=field.replace('[', r'\[').replace(']', r'\]')):
        parse_rig(d)


def test_missing_section_and_bad_yaml(raw, tmp_path):
    d = copy.deepcopy(raw)
    del d['shaft']
    with pytest.raises(ParamError, match='shaft'):
        parse_rig(d)
    p = tmp_path / 'bad.yaml'
    p.write_text('shaft: [unclosed\n')
    with pytest.raises(ParamError, match='not valid YAML'):
        load_rig(p)
    with pytest.raises(ParamError, match='cannot read'):
        load_rig(tmp_path / 'nope.yaml')
