"""
Parameter files: every shipped one validates and round-trips; a bad file fails with one message naming the field.

References: the paper's Table 1 (the rig), the closed-form mass of an annular disc, and for the round trip the file
itself (YAML writes a float as its repr, which reads back to the same float: the round trip is exact by design,
not by rounding luck).  The messages are checked for the field's path, the offending value and what was expected.
"""
import copy
import math
import sys

from bearing_id.config.params import (default_rig_path, load_rig, PACKAGE_PARAMS, ParamError, parse_rig,
                                      rig_to_dict)
import pytest
import yaml

SHIPPED = [PACKAGE_PARAMS / 'rig.yaml'] + sorted((PACKAGE_PARAMS / 'examples').glob('*.yaml'))
PLANT = PACKAGE_PARAMS / 'examples' / 'plant_like.yaml'
EPS = sys.float_info.epsilon


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
    # the annulus rho pi/4 (D^2 - d^2) t: 7 operations, each rounding by at most EPS/2 in either evaluation
    assert rig.discs[0].mass == pytest.approx(7800 * math.pi / 4 * (0.08**2 - 0.01265**2) * 0.015, rel=8 * EPS)


@pytest.mark.parametrize('path', SHIPPED, ids=lambda p: p.name)
def test_every_shipped_params_file_validates_and_round_trips(path):
    rig = load_rig(path)
    assert rig.bearings and rig.probes and rig.simulation is not None and rig.shaft.n_nodes >= 3
    text = yaml.safe_dump(rig_to_dict(rig), sort_keys=False)
    assert parse_rig(yaml.safe_load(text), base_dir=path.parent) == rig


def test_no_shipped_rig_file_is_a_copy_of_another():
    texts = [yaml.safe_load(p.read_text()) for p in SHIPPED]
    assert all(a != b for i, a in enumerate(texts) for b in texts[i + 1:])


def _set(d, path, value):
    for k in path[:-1]:
        d = d[k]
    if value is KeyError:
        del d[path[-1]]
    else:
        d[path[-1]] = value


@pytest.mark.parametrize('path,value,message', [
    (('bearings', 1, 'clearance'), -1.0, r'bearings\[1\]\.clearance = -1\.0 \[m\] is outside the allowed range '
                                         r'\[1e-07, 0\.01\]'),
    (('bearings', 0, 'viscosity'), 'oil', r'bearings\[0\]\.viscosity must be a number \[Pa s\] or a number with a '
                                          r"unit such as \"12\.65 mm\", got 'oil'"),
    (('discs', 0, 'node'), 12, r'discs\[0\]\.node = 12 is not a node of the shaft \(1 to 11\)'),
    (('shaft', 'poisson_ratio'), 0.7, r'shaft\.poisson_ratio = 0\.7 \[-\] is outside the allowed range \[0, 0\.5\]'),
    (('shaft', 'youngs_modulus'), 6894.75, r'shaft\.youngs_modulus = 6894\.75 \[Pa\] is outside'),   # v1: >= 1e6
    (('shaft', 'length'), KeyError, r'shaft\.length is missing \(m\)'),
    (('probes', 0, 'direction'), 'z', r"probes\[0\]\.direction must be one of \('x', 'y'\) or an angle text .*"
                                      r"got 'z'"),
    (('simulation', 'sample_rate'), float('nan'), r'simulation\.sample_rate must be finite \[Hz\], got nan'),
    (('simulation', 'speeds_rpm', 2), [1], r'simulation\.speeds_rpm\[2\] must be a number \[rpm\], got a list \[1\]'),
    (('simulation', 'block_size'), 100.5, r'simulation\.block_size must be a whole number, got 100\.5'),
    (('bearings', 0, 'identify'), 'yes', r"bearings\[0\]\.identify must be true or false, got a string 'yes'"),
    (('bearings', 0, 'model'), 'long', r"bearings\[0\]\.model must be one of 'short', 'finite' or 'table', got a "
                                       r"string 'long'"),
    (('modal_test',), [1, 2], r'modal_test must be a mapping \(key: value\), got a list \[1, 2\]'),
    (('bearings',), [1, 2], r'bearings\[0\] must be a mapping \(key: value\), got a number 1; bearings\[1\]'),
    (('simulation', 'truth', 'viscosity_factor'), [1.0], r'simulation\.truth\.viscosity_factor must be a list with '
                                                         r'one factor per identified bearing \(2\), got \[1\.0\]'),
    (('name',), True, r'name must be a name \(text\), got a boolean True'),
])
def test_a_bad_value_is_named_with_what_was_expected(raw, path, value, message):
    d = copy.deepcopy(raw)
    _set(d, path, value)
    with pytest.raises(ParamError, match=f'^{message}') as exc:
        parse_rig(d)
    assert '\n' not in str(exc.value)


def test_several_problems_are_listed_on_one_line(raw):
    d = copy.deepcopy(raw)
    d['bearings'][0]['clearance'] = 'wide'
    d['discs'][1]['thickness'] = -1
    with pytest.raises(ParamError) as exc:
        parse_rig(d)
    text = str(exc.value)
    assert 'discs[1].thickness = -1.0 [m]' in text and 'bearings[0].clearance must be a number [m]' in text
    assert '\n' not in text


def test_missing_section_and_bad_yaml(raw, tmp_path):
    d = copy.deepcopy(raw)
    del d['shaft']
    with pytest.raises(ParamError, match=r'^rig\.shaft is missing'):
        parse_rig(d)
    with pytest.raises(ParamError, match='must be a YAML mapping'):
        parse_rig([d])
    p = tmp_path / 'bad.yaml'
    p.write_text('shaft: [unclosed\n')
    with pytest.raises(ParamError, match='not valid YAML'):
        load_rig(p)
    with pytest.raises(ParamError, match='cannot read'):
        load_rig(tmp_path / 'nope.yaml')


def test_a_table_from_csv_equals_the_inline_table(tmp_path):
    """``table: {csv: FILE}`` (relative to the params file) reads the same seal as the plant example's inline table."""
    d = yaml.safe_load(PLANT.read_text())
    t = d['seals'][0]['table']
    cols = ['speed_rpm', 'kxx', 'kxy', 'kyx', 'kyy', 'cxx', 'cyy']
    rows = [','.join(str(t[c][i]) for c in cols) for i in range(len(t['speed_rpm']))]
    (tmp_path / 'seal.csv').write_text('# labyrinth seal\n' + ','.join(cols) + '\n' + '\n'.join(rows) + '\n')
    d['seals'][0]['table'] = {'csv': 'seal.csv'}
    (tmp_path / 'plant.yaml').write_text(yaml.safe_dump(d))
    assert load_rig(tmp_path / 'plant.yaml').seals == load_rig(PLANT).seals
    (tmp_path / 'seal.csv').write_text(','.join(cols) + '\n' + rows[0].replace(',300.0,', ',x,', 1) + '\n')
    with pytest.raises(ParamError, match=r"seals\[0\]\.table\.csv: cxx\[0\] must be a number \[N s/m\].*got 'x'"):
        load_rig(tmp_path / 'plant.yaml')
    d['seals'][0]['table'] = {'csv': 'absent.csv'}
    with pytest.raises(ParamError, match=r'seals\[0\]\.table\.csv: cannot read'):
        parse_rig(d, base_dir=tmp_path)
