"""Node tests of the simulator's ROS-standard side: ``/tf``, ``/tf_static``, each robot's
``robot_description`` (swarm_sim/tf_publisher.py) and the ``simulation_interfaces`` services
(swarm_sim/sim_services.py), with rclpy clients of the standard's own types."""

from __future__ import annotations

import json
import math
import time

import pytest
import rclpy
from nav_msgs.msg import Odometry
from simulation_interfaces import srv
from simulation_interfaces.msg import EntityCategory, Result, SimulationState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from tests.support.ros import ros_context, spin_until, stop
from tests.swarm_sim.test_node import LATCHED, RELIABLE, Driver, _sim

pytestmark = pytest.mark.node

FLEET = "turtlebot3_waffle:1,turtlebot3_burger:1"


def test_tf_static_descriptions_and_live_tf_describe_the_swarm(tmp_path):
    proc, _ = _sim(tmp_path, 2, "--robot", FLEET, "--duration", "60", wait_for=2, rtf="2")
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("probe", context=ctx)
            ex.add_node(node)
            Driver(node, {"Srobot1": (0.1, 0.2), "Srobot2": (0.1, -0.2)}, 10**6)
            static, tf, desc, odom = [], [], {}, {}
            node.create_subscription(TFMessage, "/tf_static", static.append, LATCHED)
            node.create_subscription(TFMessage, "/tf", tf.append, RELIABLE)
            for ns in ("Srobot1", "Srobot2"):
                node.create_subscription(String, f"/{ns}/robot_description",
                                         lambda m, ns=ns: desc.__setitem__(ns, m.data), LATCHED)
            node.create_subscription(
                Odometry, "/Srobot1/odom",
                lambda m: odom.__setitem__((m.header.stamp.sec, m.header.stamp.nanosec), m),
                RELIABLE)
            spin_until(ex, lambda: static and len(desc) == 2 and len(tf) >= 20, 60,
                       "/tf_static, both robot_descriptions and 20 /tf messages")
    finally:
        assert stop(proc) == 0
    assert '<robot name="turtlebot3_waffle"' in desc["Srobot1"]
    assert '<robot name="turtlebot3_burger"' in desc["Srobot2"]
    parent = {t.child_frame_id: t for t in static[0].transforms}
    for ns in ("Srobot1", "Srobot2"):
        up = parent[f"{ns}/odom"]
        assert up.header.frame_id == "map" and up.transform.rotation.w == 1.0
        # base_scan (the scans' frame) hangs from base_footprint (odom's child), as URDF says
        chain, frame = [], f"{ns}/base_scan"
        while frame in parent:
            chain.append(frame)
            frame = parent[frame].header.frame_id
        assert chain == [f"{ns}/base_scan", f"{ns}/base_link"]
        assert frame == f"{ns}/base_footprint" and f"{ns}/wheel_left_link" in parent
    matched = 0
    for msg in tf:
        assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == [
            ("Srobot1/odom", "Srobot1/base_footprint"), ("Srobot2/odom", "Srobot2/base_footprint")]
        t = msg.transforms[0]
        o = odom.get((t.header.stamp.sec, t.header.stamp.nanosec))
        if o is not None:  # the same tick: the same pose as the odometry
            p = o.pose.pose
            assert (t.transform.translation.x, t.transform.translation.y) == (
                p.position.x, p.position.y)
            assert (t.transform.rotation.z, t.transform.rotation.w) == (
                p.orientation.z, p.orientation.w)
            matched += 1
    assert matched >= 10
    stamps = [m.transforms[0].header.stamp for m in tf]
    ns = [s.sec * 10**9 + s.nanosec for s in stamps]
    assert ns == sorted(ns)  # simulated time; the start gate sends tick 1 again until it opens
    ticks = sorted(set(ns))
    assert {b - a for a, b in zip(ticks, ticks[1:], strict=False)} == {100_000_000}


class Services:
    """Clients of ``/swarm_sim``'s services."""

    def __init__(self, node, ex):
        self.node, self.ex, self.clients = node, ex, {}

    def call(self, name: str, typ, request=None, timeout: float = 60.0):
        if name not in self.clients:
            self.clients[name] = self.node.create_client(typ, f"/swarm_sim/{name}")
            assert self.clients[name].wait_for_service(timeout_sec=timeout), name
        future = self.clients[name].call_async(request or typ.Request())
        spin_until(self.ex, future.done, timeout, f"the answer of {name}")
        return future.result()

    def set_state(self, state: int):
        req = srv.SetSimulationState.Request()
        req.state.state = state
        return self.call("set_simulation_state", srv.SetSimulationState, req).result

    def pose(self, ns: str):
        got = self.call("get_entity_state", srv.GetEntityState,
                        srv.GetEntityState.Request(entity=ns))
        assert got.result.result == Result.RESULT_OK
        s = got.state
        return (s.header.stamp.sec * 10**9 + s.header.stamp.nanosec, s.pose.position.x,
                s.pose.position.y, s.pose.orientation.z,
                math.hypot(s.twist.linear.x, s.twist.linear.y), s.twist.angular.z)


def test_pause_step_play_entities_and_stop_through_the_standard_services(tmp_path):
    proc, summary = _sim(tmp_path, 3, "--duration", "600", wait_for=3, rtf="4")
    try:
        with ros_context() as (ctx, ex):
            node = rclpy.create_node("harness", context=ctx)
            ex.add_node(node)
            Driver(node, {"Srobot1": (0.1, 0.3), "Srobot2": (0.05, 0.0), "Srobot3": (0.0, 0.0)},
                   10**6)
            sim = Services(node, ex)
            features = sim.call("get_simulator_features", srv.GetSimulatorFeatures).features
            assert {24, 25, 26, 31, 32, 10} <= set(features.features)
            state = sim.call("get_simulation_state", srv.GetSimulationState)
            assert state.state.state == SimulationState.STATE_PLAYING
            spin_until(ex, lambda: sim.pose("Srobot1")[0] >= 1_000_000_000, 60,
                       "simulated time past 1 s")

            assert sim.set_state(SimulationState.STATE_PAUSED).result == Result.RESULT_OK
            held = sim.pose("Srobot1")
            time.sleep(1.0)
            assert sim.pose("Srobot1") == held  # paused: no tick, however long
            again = sim.set_state(SimulationState.STATE_PAUSED)
            assert again.result == srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
            step = sim.call("step_simulation", srv.StepSimulation,
                            srv.StepSimulation.Request(steps=7))
            assert step.result.result == Result.RESULT_OK
            after = sim.pose("Srobot1")
            assert after[0] - held[0] == 7 * 100_000_000  # seven 10 Hz ticks, then held
            assert after[1:3] != held[1:3]  # driven at 0.1 m/s, 0.3 rad/s (in map)
            assert after[4:] == pytest.approx((0.1, 0.3))

            entities = sim.call("get_entities", srv.GetEntities)
            assert list(entities.entities) == ["Srobot1", "Srobot2", "Srobot3"]
            req = srv.GetEntities.Request()
            req.filters.filter = "[23]$"
            assert list(sim.call("get_entities", srv.GetEntities, req).entities) == [
                "Srobot2", "Srobot3"]
            req = srv.GetEntitiesStates.Request()
            req.filters.categories = [EntityCategory(category=EntityCategory.CATEGORY_ROBOT)]
            both = sim.call("get_entities_states", srv.GetEntitiesStates, req)
            assert len(both.states) == 3 and both.states[0].header.frame_id == "map"
            info = sim.call("get_entity_info", srv.GetEntityInfo,
                            srv.GetEntityInfo.Request(entity="Srobot2")).info
            assert info.category.category == EntityCategory.CATEGORY_ROBOT
            missing = sim.call("get_entity_state", srv.GetEntityState,
                               srv.GetEntityState.Request(entity="Srobot9"))
            assert missing.result.result == Result.RESULT_NOT_FOUND

            assert sim.set_state(SimulationState.STATE_PLAYING).result == Result.RESULT_OK
            busy = sim.call("step_simulation", srv.StepSimulation,
                            srv.StepSimulation.Request(steps=1))
            assert busy.result.result == Result.RESULT_INCORRECT_STATE
            spin_until(ex, lambda: sim.pose("Srobot1")[0] > after[0], 60, "ticks again")

            assert sim.set_state(SimulationState.STATE_STOPPED).result == Result.RESULT_OK
            proc.wait(30)  # stopped ends the run
    finally:
        code = stop(proc)
    assert code == 0
    report = json.loads(summary.read_text())
    assert 1.0 < report["sim_time_s"] < 600.0
