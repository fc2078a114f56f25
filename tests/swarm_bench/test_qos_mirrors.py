"""The navigator's publisher QoS, mirrored where it cannot be imported, stays one contract.

``swarm_record.mcap_format`` writes each recorded topic's offered QoS into the MCAP (rosbag2's
names) and subscribes with it; ``swarm_bench.baseline_nodes`` plays the navigator in the
messaging baseline.
Both repeat ``swarm_nav.node``'s ``cmd_vel`` and ``nav_status`` profiles: a history shortened in
one place and not the others would lose late readers' messages again (session notes: 23 ticks of
``cmd_vel``, one goal of ``nav_status``).
"""

from __future__ import annotations

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from swarm_bench import baseline_nodes
from swarm_nav import node as nav
from swarm_record import mcap_format as recording

PROFILES = {"cmd_vel": nav.CMD_VEL_QOS, "nav_status": nav.NAV_STATUS_QOS}


def _as_rosbag2(qos) -> dict:
    return {
        "history": {HistoryPolicy.KEEP_LAST: "keep_last",
                    HistoryPolicy.KEEP_ALL: "keep_all"}[qos.history],
        "depth": qos.depth,
        "reliability": {ReliabilityPolicy.RELIABLE: "reliable",
                        ReliabilityPolicy.BEST_EFFORT: "best_effort"}[qos.reliability],
        "durability": {DurabilityPolicy.TRANSIENT_LOCAL: "transient_local",
                       DurabilityPolicy.VOLATILE: "volatile"}[qos.durability],
    }


@pytest.mark.parametrize("topic", sorted(PROFILES))
def test_the_recorder_asks_for_what_the_navigator_offers(topic):
    recorded = {suffix: qos for suffix, _, qos in recording.ROBOT_TOPICS}
    assert recorded[topic] == _as_rosbag2(PROFILES[topic])


@pytest.mark.parametrize("topic, mirror", [("cmd_vel", baseline_nodes.CMD_VEL_QOS),
                                           ("nav_status", baseline_nodes.NAV_STATUS_QOS)])
def test_the_messaging_baseline_offers_what_the_navigator_offers(topic, mirror):
    assert _as_rosbag2(mirror) == _as_rosbag2(PROFILES[topic])


def test_the_histories_cover_late_readers():
    """Transient local with a history: the point of both profiles (a latched depth 1 keeps the
    last message alone)."""
    for qos in PROFILES.values():
        assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL and qos.depth >= 100
