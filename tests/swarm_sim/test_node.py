"""Node tests of ``swarm-sim``: the real simulator process, driven over ROS 2 from this test.

A driver node in the test answers every odometry tick of chosen robots with a stamped command,
as a navigator does, so the synchronous simulator waits for it and the runs are deterministic.
"""

from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import LaserScan

from tests.support.ros import ros_context, spin_until, start, stop

DATA = Path(__file__).resolve().parents[1] / "data"

pytestmark = pytest.mark.node

RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
EVENTS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Driver:
    """Answers each odom tick of ``drive`` robots with ``(v, w)`` for ``ticks`` ticks, then 0."""

    def __init__(self, node, drive: dict[str, tuple[float, float]], ticks: int, watch=()):
        self.node = node
        self.drive = drive
        self.ticks = ticks
        self.answered = {ns: set() for ns in drive}
        self.truth: dict[str, list[tuple[float, float, float, float]]] = {}
        self.pubs = {ns: node.create_publisher(TwistStamped, f"/{ns}/cmd_vel", RELIABLE)
                     for ns in drive}
        for ns in set(drive) | set(watch):
            self.truth[ns] = []
            node.create_subscription(Odometry, f"/{ns}/ground_truth",
                                     lambda m, ns=ns: self._on_truth(ns, m), RELIABLE)
            if ns in drive:
                node.create_subscription(Odometry, f"/{ns}/odom",
                                         lambda m, ns=ns: self._on_odom(ns, m), RELIABLE)

    def _on_odom(self, ns, msg):
        cmd = TwistStamped()
        cmd.header.stamp = msg.header.stamp
        cmd.header.frame_id = f"{ns}/base_footprint"
        answered = self.answered[ns]
        answered.add((msg.header.stamp.sec, msg.header.stamp.nanosec))  # the gate repeats tick 1
        if len(answered) <= self.ticks:
            cmd.twist.linear.x, cmd.twist.angular.z = self.drive[ns]
        self.pubs[ns].publish(cmd)

    def _on_truth(self, ns, msg):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.truth[ns].append((t, p.x, p.y, 2.0 * math.atan2(q.z, q.w)))


def _sim(tmp_path, n: int, *extra: str, wait_for: int = 0, rtf: str = "0"):
    summary = tmp_path / "summary.json"
    proc = start(["swarm-sim", "--swarm-size", str(n), "--rtf", rtf, "--seed", "7",
                  "--wait-for", str(wait_for), "--summary", str(summary), *extra],
                 tmp_path / "sim.log")
    return proc, summary


def test_three_robots_publish_map_scan_odom_at_their_rates(tmp_path):
    proc, _ = _sim(tmp_path, 3, "--duration", "60", rtf="1")
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("probe", context=ctx)
            ex.add_node(node)
            odom, scans, maps, wall = [], [], [], []

            def on_odom(msg):
                odom.append(msg)
                wall.append(time.monotonic())

            node.create_subscription(Odometry, "/Srobot1/odom", on_odom, RELIABLE)
            node.create_subscription(LaserScan, "/Srobot1/scan", scans.append,
                                     qos_profile_sensor_data)
            node.create_subscription(OccupancyGrid, "/map", maps.append, LATCHED)
            spin_until(ex, lambda: len(odom) >= 21 and len(scans) >= 11 and maps, 30,
                       "odom, scan and map")
        stamps = lambda msgs: [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs]  # noqa: E731
        t_odom, t_scan = stamps(odom), stamps(scans)
        d_odom = [round(b - a, 6) for a, b in zip(t_odom, t_odom[1:], strict=False)]
        d_scan = [round(b - a, 6) for a, b in zip(t_scan, t_scan[1:], strict=False)]
        assert set(d_odom) == {0.1}  # 10 Hz control ticks, in simulated time
        assert set(d_scan) == {0.2}  # the LDS-01's 5 Hz, from the URDF
        # --rtf 1 paces to the wall clock: 2 s of simulated odometry took about 2 s.
        assert wall[-1] - wall[0] == pytest.approx(t_odom[-1] - t_odom[0], rel=0.25)
        scan = scans[-1]
        assert len(scan.ranges) == 360 and scan.header.frame_id == "Srobot1/base_scan"
        assert scan.range_min == pytest.approx(0.12) and scan.range_max == pytest.approx(3.5)
        assert odom[-1].header.frame_id == "Srobot1/odom"
        assert odom[-1].child_frame_id == "Srobot1/base_footprint"
        assert odom[-1].pose.pose.position.x == pytest.approx(0.0)  # spawn pose, in map
        grid = maps[0]
        assert grid.header.frame_id == "map" and grid.info.resolution == pytest.approx(0.05)
        assert grid.info.width * grid.info.height == len(grid.data) > 0
    finally:
        assert stop(proc) == 0


def test_scan_sees_wall_at_analytic_range(tmp_path):
    # Robot 12 spawns at (-2, 0) facing pi; its lidar (x = -0.064 in base_footprint) sits at
    # x = -1.936; beam 0 looks along -x at the blockage's right face x = -3.762: 1.826 m.
    proc, _ = _sim(tmp_path, 12, "--duration", "60", rtf="1")
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("probe", context=ctx)
            ex.add_node(node)
            scans = []
            node.create_subscription(LaserScan, "/Srobot12/scan", scans.append,
                                     qos_profile_sensor_data)
            spin_until(ex, lambda: len(scans) >= 3, 30, "Srobot12 scans")
        ranges = scans[-1].ranges
        assert ranges[0] == pytest.approx(1.826, abs=0.05)  # sigma 0.01 m noise
    finally:
        assert stop(proc) == 0


def test_stamped_command_moves_robot_expected_distance(tmp_path):
    proc, summary = _sim(tmp_path, 3, "--duration", "6", wait_for=1)
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("driver", context=ctx)
            ex.add_node(node)
            # Srobot3 spawns at (2, 0) facing pi; drive 0.2 m/s for 30 ticks (3 s).
            driver = Driver(node, {"Srobot3": (0.2, 0.0)}, ticks=30)
            spin_until(ex, lambda: proc.poll() is not None, 60, "the simulator to finish")
        assert proc.returncode == 0
        t, x, y, yaw = driver.truth["Srobot3"][-1]
        # Acceleration 2.5 m/s^2 over 0.05 s substeps: 0.125 then 0.2 m/s; 30 ticks = 60 steps,
        # the first at 0.125 m/s: 0.05 * (0.125 + 59 * 0.2) = 0.59625 m; then braking from
        # 0.2 m/s to 0.075 to 0: 0.05 * 0.075 = 0.00375 m more; 0.6 m in all, towards -x.
        assert t > 4.0  # long after the robot stopped
        assert x == pytest.approx(2.0 - 0.6, abs=1e-6)
        assert y == pytest.approx(0.0, abs=1e-6)  # the POI yaw is 3.14159265, not exactly pi
        data = json.loads(summary.read_text())
        assert data["late_ticks"] == 0
        assert data["per_robot"]["Srobot3"]["distance_m"] == pytest.approx(0.6, abs=0.001)
        # one wall time per simulated second of the 6, increasing, the last within the loop's
        timeline = data["wall_timeline_s"]
        assert len(timeline) == 6 and timeline == sorted(timeline) and timeline[0] > 0
        assert timeline[-1] <= data["wall_time_s"]
    finally:
        stop(proc)


def test_fleet_poses_equal_each_robots_ground_truth(tmp_path):
    proc, _ = _sim(tmp_path, 3, "--duration", "3", wait_for=2)
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("driver", context=ctx)
            ex.add_node(node)
            fleet = {}  # stamp [s] -> (N, 3) x, y, yaw

            def on_poses(msg):
                t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                assert msg.header.frame_id == "map"
                fleet[round(t, 3)] = [(p.position.x, p.position.y,
                                       2.0 * math.atan2(p.orientation.z, p.orientation.w))
                                      for p in msg.poses]

            node.create_subscription(PoseArray, "/swarm/poses", on_poses, RELIABLE)
            driver = Driver(node, {"Srobot1": (0.2, 0.5), "Srobot3": (0.1, -0.3)}, ticks=20,
                            watch=["Srobot2"])
            spin_until(ex, lambda: proc.poll() is not None, 60, "the simulator to finish")
        assert proc.returncode == 0
        compared = 0
        for k, ns in enumerate(("Srobot1", "Srobot2", "Srobot3")):
            for t, x, y, yaw in driver.truth[ns]:
                if round(t, 3) in fleet:
                    assert len(fleet[round(t, 3)]) == 3
                    assert fleet[round(t, 3)][k] == pytest.approx((x, y, yaw), abs=1e-12)
                    compared += 1
        assert compared >= 3 * 20  # most of the 30 ticks, for every robot
        moved = fleet[max(fleet)]
        assert moved[0][:2] != pytest.approx(fleet[min(fleet)][0][:2], abs=0.1)  # Srobot1 drove
    finally:
        stop(proc)


def test_two_robots_driven_into_each_other_give_one_collision(tmp_path):
    proc, summary = _sim(tmp_path, 2, "--duration", "12", wait_for=1)
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("driver", context=ctx)
            ex.add_node(node)
            events = []
            node.create_subscription(DiagnosticArray, "/swarm/events",
                                     lambda m: events.extend(m.status), EVENTS)
            # Srobot2 at (1, 0) facing pi drives into Srobot1 at (0, 0) and keeps pushing.
            driver = Driver(node, {"Srobot2": (0.2, 0.0)}, ticks=100, watch=["Srobot1"])
            spin_until(ex, lambda: proc.poll() is not None, 60, "the simulator to finish")
            spin_until(ex, lambda: any(e.name == "collision" for e in events), 5,
                       "the collision event")
        collisions = [e for e in events if e.name == "collision"]
        assert len(collisions) == 1
        values = {kv.key: kv.value for kv in collisions[0].values}
        assert {values["robot"], values["other"]} == {"Srobot1", "Srobot2"}
        assert values["kind"] == "robot_robot"
        data = json.loads(summary.read_text())
        assert data["collisions"] == {"robot_robot": 1, "robot_wall": 0}
        # Bumped, not passed through: Srobot2 stopped behind Srobot1, which did not move.
        _, x2, _, _ = driver.truth["Srobot2"][-1]
        _, x1, _, _ = driver.truth["Srobot1"][-1]
        assert x1 == pytest.approx(0.0, abs=1e-9)
        assert 0.2 < x2 < 0.35  # two boxes 0.266 m long: touching at a gap of 0..0.05 m
    finally:
        stop(proc)


def _run_once(tmp_path, tag: str):
    d = tmp_path / tag
    d.mkdir()
    proc, summary = _sim(d, 4, "--duration", "5", wait_for=2)
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("driver", context=ctx)
            ex.add_node(node)
            driver = Driver(node, {"Srobot1": (0.15, 0.4), "Srobot3": (0.26, -0.9)}, ticks=40,
                            watch=["Srobot2", "Srobot4"])
            spin_until(ex, lambda: proc.poll() is not None, 60, "the simulator to finish")
        # Compare at a tick both runs certainly delivered (the last ones may be in flight).
        return {ns: [r for r in rows if r[0] == pytest.approx(4.0)][0]
                for ns, rows in driver.truth.items()}
    finally:
        stop(proc)


def test_same_seed_gives_identical_odometry(tmp_path):
    first = _run_once(tmp_path, "a")
    second = _run_once(tmp_path, "b")
    assert first == second
    assert first["Srobot1"][1] != pytest.approx(0.0)  # the robots did move
    assert first["Srobot3"][3] != pytest.approx(first["Srobot2"][3])


def test_manual_commands_outrank_an_idle_navigator_while_they_keep_coming(tmp_path):
    proc, _ = _sim(tmp_path, 2, "--duration", "60", wait_for=1, rtf="1")
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("teleop", context=ctx)
            ex.add_node(node)
            # An idle navigator: answers every tick of Srobot1 with a stamped zero.
            driver = Driver(node, {"Srobot1": (0.0, 0.0)}, ticks=10**6)
            teleop = node.create_publisher(TwistStamped, "/Srobot1/cmd_vel", RELIABLE)
            spin_until(ex, lambda: len(driver.truth["Srobot1"]) > 5, 30, "Srobot1 running")
            cmd = TwistStamped()  # zero stamp: manual driving, as `ros2 topic pub` sends it
            cmd.twist.linear.x = 0.2
            end = time.monotonic() + 2.0
            while time.monotonic() < end:  # 10 Hz, like `ros2 topic pub -r 10`
                teleop.publish(cmd)
                t_stop = time.monotonic() + 0.1
                while time.monotonic() < t_stop:
                    ex.spin_once(timeout_sec=0.02)
            moved = abs(driver.truth["Srobot1"][-1][1])
            # Teleop stopped: within 0.5 s wall the navigator's zero answers take over.
            t_end = time.monotonic() + 2.0
            while time.monotonic() < t_end:
                ex.spin_once(timeout_sec=0.05)
            x1 = driver.truth["Srobot1"][-1][1]
            t_more = time.monotonic() + 1.0
            while time.monotonic() < t_more:
                ex.spin_once(timeout_sec=0.05)
            x2 = driver.truth["Srobot1"][-1][1]
        assert moved > 0.2  # about 2 s at 0.2 m/s, towards -x
        assert x2 == pytest.approx(x1, abs=1e-9)  # stopped: the navigator has the robot again
    finally:
        stop(proc)


def test_a_world_with_skipped_elements_says_so_once_at_start(tmp_path):
    """A world given by path, with no points of interest beside it and an actor and a road the
    simulator leaves out: its log names them once (as swarm-map does) and says where the robots
    went; its summary carries both for swarm-up."""
    world = tmp_path / "boxed_walker.world"
    world.write_text((DATA / "world_boxed.world").read_text().replace(
        "</world>", '<actor name="walker"><skin><filename>walk.dae</filename></skin></actor>'
        '<road name="lane"><width>3</width><point>0 0 0</point><point>5 0 0</point></road>'
        "</world>"))
    proc, summary = _sim(tmp_path, 2, "--world", str(world), "--duration", "1")
    try:
        assert proc.wait(60) == 0
    finally:
        stop(proc)
    lines = (tmp_path / "sim.log").read_text().splitlines()
    skip = [i for i, ln in enumerate(lines) if "skipped unsupported" in ln]
    (spawned,) = [i for i, ln in enumerate(lines) if ln.startswith("spawned 2 robots")]
    assert [lines[i] for i in skip] == [
        "swarm-sim: warning: boxed_walker.world: skipped unsupported elements: actor 'walker', "
        "road 'lane'"]
    assert skip[0] < spawned  # at start
    assert re.search(r"in the largest (enclosed )?free region \(.*; no points-of-interest "
                     r"file\), x ", lines[spawned]), lines[spawned]
    data = json.loads(summary.read_text())
    assert data["world_skipped"] == ["actor 'walker'", "road 'lane'"]
    assert lines[spawned].endswith(f") {data['spawn']}")  # the line's text, after the names
