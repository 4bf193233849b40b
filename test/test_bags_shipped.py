"""
The shipped bags offer each topic's publisher QoS (issue 23 item 5), so `ros2 bag play` replays them as published.

Expected, from the nodes' publishers (bearing_id/nodes/qos.py): /rotor/excitation reliable + transient-local (latched:
a subscriber that starts late still gets the run), /rotor/displacement and /rotor/speed reliable + volatile.  An empty
``offered_qos_profiles`` made every `ros2 bag play` warn and replay the excitation volatile.
"""
from __future__ import annotations

from pathlib import Path

from bearing_id.io import bags
import pytest
from rosbags.rosbag2.metadata import QosDurability, QosReliability

BAGS = Path(__file__).resolve().parents[1] / 'bags'
EXPECTED = {'/rotor/excitation': QosDurability.TRANSIENT_LOCAL, '/rotor/displacement': QosDurability.VOLATILE,
            '/rotor/speed': QosDurability.VOLATILE}


@pytest.mark.parametrize('bag', ['unbalance_ab_sweep', 'force_plan', 'slow_roll'])
def test_shipped_bags_offer_their_publishers_qos(bag):
    qos = bags.offered_qos(BAGS / bag)
    assert set(qos) == set(EXPECTED), qos
    for topic, durability in EXPECTED.items():
        assert len(qos[topic]) == 1, (topic, qos[topic])
        q = qos[topic][0]
        assert q.reliability == QosReliability.RELIABLE and q.durability == durability, (topic, q)
