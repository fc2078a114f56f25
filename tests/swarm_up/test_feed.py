"""A group process's sensor feed (swarm_up.feed): from the robots' states each navigator gets the
odometry and the scan it would have read from the simulator's ``odom`` and ``scan``, to the last
bit; faults' mutes, ticks sent again and a late start."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_common import topics
from swarm_common.cdr import (
    ODOM_PUBLISHED,
    SCAN_PUBLISHED,
    RobotStatesWriter,
    odom_pose,
    scan_ranges,
)
from swarm_ros.robot_topics import RobotTopics
from swarm_scene.world import load_world
from swarm_sim.sensors import SwarmSensors
from swarm_up.feed import SensorFeed

N = 6
NAMES = [f"Srobot{i + 1}" for i in range(N)]
POSES = [(2.0 + 0.9 * (i % 3), 1.6 + 1.1 * (i // 3), 0.9 * i - 2.0) for i in range(N)]
PERIOD_NS = 100_000_000


class FakeNode:
    """What SensorFeed and RobotTopics ask of a node: subscriptions and publishers that keep
    what is written."""

    def __init__(self):
        self.subs, self.pubs = {}, {}

    def create_subscription(self, msg_type, name, callback, profile, raw=False):
        self.subs[name] = callback
        return callback

    def create_publisher(self, msg_type, name, profile):
        pub = FakePublisher()
        self.pubs[name] = pub
        return pub


class FakePublisher:
    def __init__(self):
        self.sent = []

    def publish(self, buf):
        self.sent.append(buf)

    def get_subscription_count(self):
        return 1


class FakeNavigator:
    def __init__(self):
        self.got = []

    def take_scan(self, t, meta, ranges):
        self.got.append(("scan", t, tuple(meta), np.asarray(ranges).tobytes()))

    def take_odom(self, odom):
        self.got.append(("odom", *odom))


@pytest.fixture(scope="module")
def slim():
    return load_world("slim_blockage")


@pytest.fixture(scope="module")
def robots():
    from swarm_scene.robot_model import load_robot

    return {name: load_robot(name) for name in ("turtlebot3_waffle", "turtlebot3_burger")}


def _expected(slim, robots, models, mine, ticks_seen, mute):
    """What each navigator of ``mine`` reads from the simulator's messages: its scan (on lidar
    ticks) then its odometry, through the very writers and readers of today's topics."""
    from swarm_sim.engine import SimEngine

    engine = SimEngine(slim, models, np.array(POSES), seed=4)
    try:
        node = FakeNode()
        writers = []
        for i, ns in enumerate(NAMES):
            pattern = engine.kind_lidars[engine.kind[i]].pattern
            lidar = engine.models[i].lidar
            from swarm_common.cdr import LaserScanWriter

            writers.append(RobotTopics(node, ns, LaserScanWriter(
                f"{ns}/{lidar.frame}", float(pattern.angles[0]), float(pattern.angles[-1]),
                float(pattern.angle_increment), 1.0 / float(lidar.rate_hz),
                float(pattern.range_min), float(pattern.range_max))))
        want = {ns: [] for ns in mine}
        states = []
        for k in range(1, max(ticks_seen) + 1):
            engine.step(np.full(N, 0.2), np.linspace(-0.5, 0.5, N))  # tick k
            scans = engine.scans() if engine.lidar_due() else None
            t = engine.ticks * PERIOD_NS
            published = np.full(N, ODOM_PUBLISHED | SCAN_PUBLISHED, np.uint8)
            for i in mute.get(k, ()):
                published[i] = ODOM_PUBLISHED
            states.append(RobotStatesWriter(N).write(t, engine.poses, engine.v, engine.w,
                                                     published))
            if k not in ticks_seen:
                continue
            for i, ns in enumerate(NAMES):
                if ns not in mine:
                    continue
                if scans is not None and scans[i] is not None and i not in mute.get(k, ()):
                    writers[i].publish_scan(t, scans[i])
                    st, a0, inc, rmin, rmax, ranges = scan_ranges(
                        node.pubs[f"/{ns}/scan"].sent[-1])
                    want[ns].append(("scan", st, (a0, inc, rmin, rmax), ranges.tobytes()))
                writers[i].publish_odom(t, engine.poses[i].tolist(), float(engine.v[i]),
                                        float(engine.w[i]))
                want[ns].append(("odom", *odom_pose(node.pubs[f"/{ns}/odom"].sent[-1])))
        return want, states
    finally:
        engine.close()


@pytest.mark.parametrize("mix", [False, True])
def test_each_navigator_gets_what_it_read_from_odom_and_scan(slim, robots, mix):
    from swarm_common.cdr import scan_reading

    names = ("turtlebot3_waffle", "turtlebot3_burger")
    models = [robots[names[i % 2]] for i in range(N)] if mix else [robots[names[0]]] * N
    mine = ["Srobot2", "Srobot3", "Srobot6"]
    seen = {3, 4, 5, 6, 7, 8}  # this process starts late: ticks 1 and 2 never reach it
    mute = {6: [2]}  # a fault drops robot 3's scan at tick 6
    want, states = _expected(slim, robots, models, mine, seen, mute)
    sensors = SwarmSensors(slim, models, seed=4, control_period=0.1)
    meta = []
    for i in range(N):
        p = sensors.kind_lidars[sensors.kind[i]].pattern
        meta.append(scan_reading(float(p.angles[0]), float(p.angle_increment),
                                 float(p.range_min), float(p.range_max)))
    navs = {ns: FakeNavigator() for ns in mine}
    node = FakeNode()
    busy = []
    SensorFeed(node, navs, NAMES, sensors, meta, PERIOD_NS, busy=lambda: busy.append(1))
    on_states = node.subs[topics.ROBOT_STATES.name]
    for k in sorted(seen):
        on_states(states[k - 1])
    assert len(busy) == len(seen)
    for ns in mine:
        assert navs[ns].got == want[ns], ns
    assert sum(1 for g in navs["Srobot3"].got if g[0] == "scan") == len(
        [k for k in seen if k % 2 == 0]) - 1  # the muted scan
    # the last tick sent again: fed again alike, nothing rendered or drawn anew
    before = {ns: list(navs[ns].got) for ns in mine}
    state = sensors.rng.bit_generator.state
    on_states(states[max(seen) - 1])
    assert sensors.rng.bit_generator.state == state
    for ns in mine:
        n_new = len(navs[ns].got) - len(before[ns])
        assert navs[ns].got[-n_new:] == before[ns][-n_new:]
    # an older tick is ignored; a killed navigator is not fed, the others are
    counts = {ns: len(navs[ns].got) for ns in mine}
    on_states(states[2])
    assert {ns: len(navs[ns].got) for ns in mine} == counts
    killed = navs.pop("Srobot2")
    on_states(states[max(seen) - 1])
    assert len(killed.got) == counts["Srobot2"]
    assert len(navs["Srobot3"].got) > counts["Srobot3"]


def test_a_malformed_or_foreign_message_is_dropped_with_a_warning(slim, robots):
    sensors = SwarmSensors(slim, [robots["turtlebot3_waffle"]] * N, seed=0, control_period=0.1)
    node, said = FakeNode(), []
    navs = {"Srobot1": FakeNavigator()}
    SensorFeed(node, navs, NAMES, sensors, [(0.0, 0.1, 0.1, 3.5)] * N, PERIOD_NS,
               warn=said.append)
    on_states = node.subs[topics.ROBOT_STATES.name]
    on_states(b"\x00\x01\x00\x00\x05")
    poses = np.array(POSES[:3])
    on_states(RobotStatesWriter(3).write(PERIOD_NS, poses, np.zeros(3), np.zeros(3),
                                         np.full(3, 3, np.uint8)))
    assert navs["Srobot1"].got == []
    assert len(said) == 1 and "malformed" in said[0]  # the second within 5 s: throttled
