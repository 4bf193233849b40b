"""
Foundation, bags: bearing_id_msgs messages round-trip through sqlite3 and mcap bags, also with stock ROS 2.

Every bearing_id_msgs message round-trips through sqlite3 and mcap bags with equal values; bags written here deserialize
in rclpy (the stock ROS 2 path) and bags written from rclpy messages read here; the rosbags type hashes equal rosidl's;
broken bags raise BagError naming the file.
"""
from __future__ import annotations

import json

from bearing_id.io import bags
import pytest
import rosutil

STORAGES = ('sqlite3', 'mcap')
SAMPLES = rosutil.sample_messages()


def _write_samples(path, storage):
    ts = bags.typestore()
    items = [(s['topic'], 1_000 + i, rosutil.build_with_converters(s, ts)) for i, s in enumerate(SAMPLES)]
    return bags.write_bag(path, items, storage=storage)


@pytest.mark.parametrize('storage', STORAGES)
def test_each_message_round_trips_through_bag(tmp_path, storage):
    bag = _write_samples(tmp_path / 'bag', storage)
    files = {p.suffix for p in bag.iterdir()}
    assert ('.mcap' if storage == 'mcap' else '.db3') in files, files
    got = list(bags.read_bag(bag))
    assert [(t, mt, ts) for t, mt, ts, _ in got] == [(s['topic'], s['type'], 1_000 + i) for i, s in enumerate(SAMPLES)]
    for (topic, _, _, msg), s in zip(got, SAMPLES):
        assert rosutil.normalise(rosutil.msg_to_dict(msg)) == rosutil.normalise(s['fields']), topic
    topics = bags.bag_topics(bag)
    assert topics == {s['topic']: (s['type'], 1) for s in SAMPLES}


@pytest.mark.parametrize('storage', STORAGES)
def test_topic_filter_and_raw_rewrite(tmp_path, storage):
    """read_bag(topics=...) returns only those; its raw tuples write back to an identical bag."""
    bag = _write_samples(tmp_path / 'bag', storage)
    only = list(bags.read_bag(bag, topics=['/bearing_id_test/speed'], raw=True))
    assert [x[0] for x in only] == ['/bearing_id_test/speed'] and isinstance(only[0][3], bytes)
    raw = list(bags.read_bag(bag, raw=True))
    copy = bags.write_bag(tmp_path / 'copy', raw, storage='mcap' if storage == 'sqlite3' else 'sqlite3')
    assert list(bags.read_bag(copy, raw=True)) == raw


@pytest.mark.parametrize('storage', STORAGES)
def test_bag_written_here_deserializes_in_rclpy_and_back(tmp_path, storage):
    """
    Interoperability with stock ROS 2, both ways, with the same values.

    Raw CDR from our bag -> rclpy.serialization.deserialize_message gives the same values; a bag written from rclpy
    messages (rclpy's serializer) reads here with the same values.
    """
    rosutil.require_ros()
    bag = _write_samples(tmp_path / 'bag', storage)
    spec = tmp_path / 'samples.json'
    spec.write_text(json.dumps(SAMPLES))
    code = f"""
import json, sys, importlib
sys.path.insert(0, {str(rosutil.REPO / 'test')!r})
import rosutil
from rclpy.serialization import deserialize_message
from bearing_id.io import bags
out = {{}}
for topic, mt, t, raw in bags.read_bag(sys.argv[1], raw=True):
    pkg, _, name = mt.split('/')
    cls = getattr(importlib.import_module(pkg + '.msg'), name)
    out[topic] = rosutil.msg_to_dict(deserialize_message(raw, cls))
samples = json.loads(open(sys.argv[2]).read())
items = [(s['topic'], 5 + i, rosutil.msg_from_dict(s['type'], s['fields'])) for i, s in enumerate(samples)]
bags.write_bag(sys.argv[3], items, storage=sys.argv[4])
print(json.dumps(out))
"""
    back = tmp_path / 'from_rclpy'
    r = rosutil.run_python(code, timeout=90, args=(bag, spec, back, storage))
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    for s in SAMPLES:
        assert rosutil.normalise(got[s['topic']]) == rosutil.normalise(s['fields']), s['type']
    read = {t: msg for t, _, _, msg in bags.read_bag(back)}
    for s in SAMPLES:
        assert rosutil.normalise(rosutil.msg_to_dict(read[s['topic']])) == rosutil.normalise(s['fields']), s['type']


def _installed_share():
    """
    Return the installed ``share/bearing_id_msgs/msg`` (with rosidl's type descriptions).

    The venv of ``make test`` or a colcon install (``AMENT_PREFIX_PATH``), as :func:`bags._msg_dir_candidates` finds
    them after the source tree.
    """
    for d in bags._msg_dir_candidates()[1:]:
        if sorted(d.glob('*.json')):
            return d
    raise AssertionError(f'no installed bearing_id_msgs with type descriptions in {bags._msg_dir_candidates()[1:]}')


def test_type_hashes_match_rosidl():
    """RIHS01 hashes rosbags computes from the .msg text equal the ones rosidl generated at build time."""
    rosutil.require_ros()
    share = _installed_share()
    jsons = sorted(share.glob('*.json'))
    assert len(jsons) == 4, f'rosidl type descriptions not found in {share}'
    ts = bags.typestore()
    for j in jsons:
        name = f'bearing_id_msgs/msg/{j.stem}'
        want = {h['type_name']: h['hash_string'] for h in json.loads(j.read_text())['type_hashes']}[name]
        assert ts.hash_rihs01(name) == want, name


def test_missing_topic_names_file_and_topics(tmp_path):
    bag = _write_samples(tmp_path / 'bag', 'mcap')
    with pytest.raises(bags.BagError) as e:
        list(bags.read_bag(bag, topics=['/nope']))
    assert str(bag) in str(e.value) and '/nope' in str(e.value) and '/bearing_id_test/speed' in str(e.value)


@pytest.mark.parametrize('storage', STORAGES)
def test_truncated_bag_raises_bag_error(tmp_path, storage):
    bag = _write_samples(tmp_path / 'bag', storage)
    data = next(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3'))
    blob = data.read_bytes()
    data.write_bytes(blob[: len(blob) // 3])
    with pytest.raises(bags.BagError) as e:
        list(bags.read_bag(bag))
    assert str(bag) in str(e.value)


def test_corrupt_and_missing_bags_raise_bag_error(tmp_path):
    bag = _write_samples(tmp_path / 'bag', 'sqlite3')
    db = next(bag.glob('*.db3'))
    db.write_bytes(b'this is not an sqlite database' * 100)
    with pytest.raises(bags.BagError, match='bag'):
        list(bags.read_bag(bag))
    with pytest.raises(bags.BagError, match='no such bag'):
        list(bags.read_bag(tmp_path / 'absent'))
    other = _write_samples(tmp_path / 'other', 'mcap')
    (other / 'metadata.yaml').unlink()
    with pytest.raises(bags.BagError, match='metadata.yaml'):
        list(bags.read_bag(other))
    with pytest.raises(bags.BagError, match='exists'):
        _write_samples(other, 'mcap')


def test_msg_files_found_in_installed_share_without_source_tree(tmp_path, monkeypatch):
    """With no msg_defs/ next to the package (a colcon install), the .msg files come from share/bearing_id_msgs."""
    rosutil.require_ros()
    share = _installed_share()
    monkeypatch.setattr(bags, '_msg_dir_candidates', lambda: [tmp_path / 'nothing', share])
    files = bags.msg_files()
    assert sorted(files) == sorted(f'bearing_id_msgs/msg/{n}' for n in
                                   ('BearingCoefficients', 'DisplacementBlock', 'Excitation', 'RotorSpeed'))
    assert all(p.parent == share for p in files.values())
    ts = bags.make_typestore()
    assert ts.hash_rihs01('bearing_id_msgs/msg/DisplacementBlock') == \
        bags.typestore().hash_rihs01('bearing_id_msgs/msg/DisplacementBlock')
