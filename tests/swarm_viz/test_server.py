"""The live view in-process, fed by a fake swarm: ``/api/state``, ``/swarm/markers``, the page in
headless Chromium (robots drawn, KPIs equal to the metrics recorder's, the scan of a watched
robot subscribed only while a browser watches it).

The fake swarm publishes what the simulator and the navigators do, with their QoS:
``/swarm/poses``, latched ``plan`` and ``nav_status``, ``/clock``, ``/swarm/events`` (one
collision, two late ticks), and best-effort scans.  Three robots: Srobot1 docked at loader1,
Srobot2 holding for loader2, Srobot3 driving with a plan and a goal reached.
"""

from __future__ import annotations

import json
import math
import socket
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from nav_msgs.msg import Path
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import Marker, MarkerArray

from swarm_common import topics
from swarm_common.nav_status import NavState, NavStatusRecord, encode
from swarm_metrics.listener import MetricsListener
from swarm_ros.qos import publisher
from swarm_up.args import build_parser, validate
from swarm_viz.fleet_view import ViewConfig
from swarm_viz.server import LiveView
from tests.support.browser import Chromium, require_chromium
from tests.support.ros import ros_context, spin_until

pytestmark = pytest.mark.node

RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
EVENTS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                  durability=DurabilityPolicy.TRANSIENT_LOCAL)  # as the simulator's writer
LOADER1 = (-7.74575, -3.57766)
LOADER2 = (-7.74575, -1.38526)
POSES = {"Srobot1": (LOADER1[0] + 0.05, LOADER1[1], math.pi),
         "Srobot2": (-7.74575, -2.48146, math.pi / 2),
         "Srobot3": (1.0, 2.0, 0.0)}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _status(ns, state, goal_id, goal, t):
    record = NavStatusRecord(state=state, goal_id=goal_id, stamp_ns=int(t * 1e9), goal=goal,
                             distance_remaining=0.0, navigation_time=1.0, recoveries=0,
                             holding_time=0.0, goal_wait_timeouts=0, reason="")
    return DiagnosticStatus(message=state.value, name=f"{ns}/navigator", hardware_id=ns,
                            values=[KeyValue(key=k, value=v) for k, v in encode(record).items()])


def _event(kind, robot, **values):
    kv = [KeyValue(key="robot", value=robot)] + [KeyValue(key=k, value=v)
                                                  for k, v in values.items()]
    return DiagnosticStatus(name=kind, message=kind, values=kv)


class FakeSwarm:
    """Publishers of a 3-robot swarm in ``ctx``."""

    def __init__(self, ctx):
        self.node = rclpy.create_node("fake_swarm", context=ctx)
        n = self.node
        self.clock = n.create_publisher(Clock, "/clock", RELIABLE)
        self.events = n.create_publisher(DiagnosticArray, "/swarm/events", EVENTS)
        self.poses = publisher(n, PoseArray, topics.POSES)  # as the simulator's
        self.plan = {ns: n.create_publisher(Path, f"/{ns}/plan", LATCHED) for ns in POSES}
        self.status = {ns: n.create_publisher(DiagnosticStatus, f"/{ns}/nav_status", LATCHED)
                       for ns in POSES}
        self.scan = n.create_publisher(LaserScan, "/Srobot3/scan", qos_profile_sensor_data)
        self.t = 0.0

    def publish_tick(self):
        self.t += 0.1
        sec = int(self.t)
        stamp = rclpy.time.Time(nanoseconds=int(self.t * 1e9)).to_msg()
        self.clock.publish(Clock(clock=stamp))
        msg = PoseArray()
        msg.header.stamp = stamp
        msg.header.frame_id = "map"
        for x, y, yaw in POSES.values():  # in the namespaces' order, as the simulator does
            p = Pose()
            p.position.x, p.position.y = x, y
            p.orientation.z, p.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            msg.poses.append(p)
        self.poses.publish(msg)
        scan = LaserScan()
        scan.header.stamp = stamp
        scan.header.frame_id = "Srobot3/base_scan"
        scan.angle_min, scan.angle_increment = 0.0, 2 * math.pi / 36
        scan.range_min, scan.range_max = 0.12, 3.5
        scan.ranges = [1.0 + 0.01 * k for k in range(36)]
        self.scan.publish(scan)
        return sec

    def publish_once(self):
        self.status["Srobot1"].publish(_status("Srobot1", NavState.SUCCEEDED, "1.000000000",
                                               (*LOADER1, math.pi), 1.0))
        self.status["Srobot2"].publish(_status("Srobot2", NavState.HOLDING, "1.000000000",
                                               (*LOADER2, math.pi), 1.0))
        self.status["Srobot3"].publish(_status("Srobot3", NavState.DRIVING, "2.000000000",
                                               (5.0, 5.0, 0.0), 1.0))
        path = Path()
        path.header.frame_id = "map"
        for k in range(50):
            ps = PoseStamped()
            ps.header = path.header
            ps.pose.position.x, ps.pose.position.y = 1.0 + 0.08 * k, 2.0 + 0.06 * k
            path.poses.append(ps)
        self.plan["Srobot3"].publish(path)
        self.events.publish(DiagnosticArray(status=[
            _event("collision", "Srobot1", other="Srobot2"),
            _event("late", "Srobot3"), _event("late", "Srobot3")]))


@pytest.fixture
def live(tmp_path):
    """A LiveView of 3 robots on slim_blockage (dashboard on a free port) and its listener."""
    port = _free_port()
    args = build_parser().parse_args(["--swarm-size", "3", "--dashboard", str(port),
                                      "--run-dir", str(tmp_path / "run")])
    cfg = validate(args)
    listener = MetricsListener(cfg.robots, time.monotonic())
    view = LiveView(cfg, listener)
    listener.start()
    url = view.start()
    try:
        yield view, listener, url
    finally:
        view.stop()
        listener.stop()


def _get(url: str):
    with urllib.request.urlopen(url, timeout=10) as resp:
        return resp.status, resp.read()


def _state(url: str) -> dict:
    return json.loads(_get(url + "api/state")[1])


def test_state_markers_and_pages(live):
    view, listener, url = live
    assert url.startswith("http://127.0.0.1:")
    with ros_context() as (ctx, executor):
        swarm = FakeSwarm(ctx)
        markers: list[MarkerArray] = []
        swarm.node.create_subscription(MarkerArray, "/swarm/markers", markers.append, RELIABLE)
        executor.add_node(swarm.node)
        spin_until(executor, lambda: swarm.poses.get_subscription_count() >= 1
                   and swarm.status["Srobot3"].get_subscription_count() >= 1
                   and swarm.events.get_subscription_count() >= 1, 20.0, "the live view")
        swarm.publish_once()
        deadline = time.monotonic() + 20.0
        while True:
            swarm.publish_tick()
            executor.spin_once(timeout_sec=0.05)
            state = _state(url)
            if (state["paths"].get("2") and all(state["robots"]) and state["kpi"]["late_ticks"]
                    == 2 and state["holding"] and markers and len(markers[-1].markers) > 20):
                break
            assert time.monotonic() < deadline, state
    robots = state["robots"]
    assert [r[3] for r in robots] == ["SUCCEEDED", "HOLDING", "DRIVING"]
    assert robots[2][:3] == [1.0, 2.0, 0.0]
    assert robots[0][2] == pytest.approx(math.pi, abs=1e-3)
    assert state["ws"] == ["occupied", "held", "free", "free", "free", "free"]
    assert state["holding"] == [1]
    # the plan's 50 points lie on one line: the page gets its two ends (fleet_view.simplify)
    assert state["paths"]["2"] == [[1.0, 2.0], [4.92, 4.94]] and state["paths"]["0"] == []
    kpi = state["kpi"]
    assert (kpi["tasks"], kpi["collisions"], kpi["late_ticks"], kpi["robots"]) == (1, 1, 2, 3)
    with listener.lock:
        assert kpi["tasks"] == listener.recorder.goal_totals()[0]
    assert kpi["sim_time_s"] > 0

    msg = markers[-1]
    assert {m.header.frame_id for m in msg.markers} == {"map"}
    assert msg.markers[0].action == Marker.DELETEALL
    by_ns: dict[str, list[Marker]] = {}
    for m in msg.markers[1:]:
        by_ns.setdefault(m.ns, []).append(m)
    assert {k: len(v) for k, v in by_ns.items()} == {
        "footprint": 3, "heading": 3, "name": 3, "path": 1, "workstation": 6,
        "workstation_name": 6}
    assert sorted(m.text for m in by_ns["name"]) == ["Srobot1", "Srobot2", "Srobot3"]
    assert len(by_ns["footprint"][0].points) == 5  # the closed 4-corner outline
    held = by_ns["workstation"][1].color
    assert (held.r, held.g) == (pytest.approx(0.9), pytest.approx(0.15))

    assert _get(url + "robot/Srobot2")[0] == 200
    assert b"dashboard.js" in _get(url)[1]
    assert _get(url + "static/dashboard.js")[0] == 200
    png = _get(url + "map.png")[1]
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(urllib.error.HTTPError) as err:
        _get(url + "robot/Nobody")
    err.value.close()
    assert err.value.code == 404


def test_page_in_headless_chromium(live):
    require_chromium()
    view, listener, url = live
    with ros_context() as (ctx, executor):
        swarm = FakeSwarm(ctx)
        executor.add_node(swarm.node)

        def tick():
            swarm.publish_tick()
            executor.spin_once(timeout_sec=0.02)

        with Chromium(url) as browser:
            # The connected page makes the view subscribe to the poses and plans.
            spin_until(executor, lambda: swarm.poses.get_subscription_count() >= 1
                       and swarm.plan["Srobot3"].get_subscription_count() >= 1
                       and swarm.status["Srobot3"].get_subscription_count() >= 1, 20.0,
                       "the view")
            swarm.publish_once()
            deadline = time.monotonic() + 40.0
            stats = None
            while time.monotonic() < deadline:
                tick()
                stats = browser.evaluate("window.dash && window.dash.stats()")
                if stats and stats["drawn"] == 3 and stats["kpi"]["late_ticks"] == 2 \
                        and stats["frames"] >= 20:
                    break
            assert stats and stats["drawn"] == 3, (stats, browser.log()[-2000:])
            assert stats["robots"] == 3 and stats["paths"] == 1
            with listener.lock:
                assert stats["kpi"]["tasks"] == listener.recorder.goal_totals()[0] == 1
                assert stats["kpi"]["collisions"] == 1
            dom = browser.evaluate("document.getElementById('kpi-robots').textContent")
            assert dom == "3/3"
            assert browser.evaluate("document.getElementById('kpi-tasks').textContent") == "1"
            assert stats["fps"] >= 5.0, stats

            # Watching a robot subscribes to its scan; the page draws its 36 returns.
            assert view.node.watched == frozenset()
            browser.evaluate("window.dash.select('Srobot3')")
            deadline = time.monotonic() + 20.0
            while time.monotonic() < deadline:
                tick()
                stats = browser.evaluate("window.dash.stats()")
                if stats["scanPoints"] == 36 and stats["status"]:
                    break
            assert stats["scanPoints"] == 36, stats
            assert stats["status"]["state"] == "DRIVING"
            assert view.node.watched == frozenset({2})
        # The browser went away: its scan subscription and its client are gone.
        deadline = time.monotonic() + 15.0
        while view.node.watched or view.server.clients:
            assert time.monotonic() < deadline, (view.node.watched, view.server.clients)
            tick()


def test_poses_and_plans_are_read_only_while_someone_looks(tmp_path):
    """Nobody looking: no subscription to ``/swarm/poses`` or the plans (the simulator writes no
    poses, the navigators build no plan messages).  ``/api/state``, a ``/swarm/markers``
    subscriber and a page each subscribe them, until ``idle_grace_s`` after the last one."""
    require_chromium()
    port = _free_port()
    args = build_parser().parse_args(["--swarm-size", "3", "--dashboard", str(port),
                                      "--run-dir", str(tmp_path / "run")])
    listener = MetricsListener(validate(args).robots, time.monotonic())
    view = LiveView(validate(args), listener, ViewConfig(idle_grace_s=1.0, markers_hz=10.0))
    listener.start()
    url = view.start()
    try:
        with ros_context() as (ctx, executor):
            swarm = FakeSwarm(ctx)
            executor.add_node(swarm.node)

            def readers():
                return (swarm.poses.get_subscription_count(),
                        swarm.plan["Srobot2"].get_subscription_count())

            def wait_for(expected, what):
                spin_until(executor, lambda: readers() == expected, 20.0, what)

            # the listener reads nav_status from the start; the view reads nothing more
            spin_until(executor, lambda: swarm.status["Srobot3"].get_subscription_count() >= 1,
                       20.0, "the listener")
            end = time.monotonic() + 2.0
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
                assert readers() == (0, 0)
            assert not view.node.inputs_active

            # one read of /api/state
            _state(url)
            wait_for((1, 1), "the readers after /api/state")
            wait_for((0, 0), "the readers gone after the grace")

            # a markers subscriber, for as long as it stays
            markers = swarm.node.create_subscription(MarkerArray, "/swarm/markers",
                                                     lambda m: None, RELIABLE)
            wait_for((1, 1), "the readers for a markers subscriber")
            swarm.node.destroy_subscription(markers)
            wait_for((0, 0), "the readers gone with the markers subscriber")

            # a page: the latched plan published while nobody looked reaches it
            swarm.publish_once()
            with Chromium(url) as browser:
                wait_for((1, 1), "the readers for a page")
                deadline = time.monotonic() + 20.0
                stats = None
                while time.monotonic() < deadline:
                    swarm.publish_tick()
                    executor.spin_once(timeout_sec=0.02)
                    stats = browser.evaluate("window.dash && window.dash.stats()")
                    if stats and stats["drawn"] == 3 and stats["paths"] == 1:
                        break
                assert stats and stats["drawn"] == 3 and stats["paths"] == 1, stats
            wait_for((0, 0), "the readers gone after the page closed")
            assert view.node.input_activations == 3
    finally:
        view.stop()
        listener.stop()


def test_a_mixed_fleet_gets_every_robots_own_outline_and_lidar_mounting(tmp_path):
    from swarm_scene.robot_model import load_robot

    args = build_parser().parse_args(["--robot", "turtlebot3_burger:2,linorobot2_2wd:1",
                                      "--dashboard", str(_free_port()),
                                      "--run-dir", str(tmp_path / "run")])
    cfg = validate(args)
    view = LiveView(cfg, MetricsListener(cfg.robots, time.monotonic()))
    models = [load_robot(name) for name in cfg.models]
    assert [m.name for m in models] == ["turtlebot3_burger", "linorobot2_2wd",
                                        "turtlebot3_burger"]
    hello = view.server.hello
    for got, model in zip(hello["footprints"], models, strict=True):
        np.testing.assert_array_equal(got, model.footprint)
    np.testing.assert_array_equal(view.lidar_pose, [m.lidar.pose for m in models])
