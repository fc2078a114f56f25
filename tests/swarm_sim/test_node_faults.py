"""``swarm-sim --faults`` as a process, driven by a stand-in navigator in this test: a frozen
robot stands still while its odometry keeps coming; lost odometry is not waited for; a dead
robot gets nothing more and its body stays; a coordinator kill holds its tick until
acknowledged; every transition is announced on ``/swarm/events`` at its tick."""

from __future__ import annotations

import json
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from swarm_common.faults import FaultAck, FaultEvent
from swarm_common.stamps import NS_PER_S
from tests.support.ros import ros_context, spin_until, start, stop

pytestmark = pytest.mark.node

SPEC = "freeze:1@1+1,drop:2/odom:1@2+0.5,kill-robot:2@3,kill-coordinator@0.5+0.3"
RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
EVENTS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _t(stamp) -> float:
    return round((stamp.sec * NS_PER_S + stamp.nanosec) / NS_PER_S, 3)


def test_sim_executes_faults_at_their_ticks(tmp_path):
    summary = tmp_path / "summary.json"
    with ros_context() as (ctx, executor):
        from rclpy.node import Node

        node = Node("fake_navigators", context=ctx)
        executor.add_node(node)
        odom = {1: {}, 2: {}}  # robot -> tick -> (x, v)
        truth = {1: {}, 2: {}}
        events: list[FaultEvent] = []
        # transient local, as the simulator reads acknowledgements
        ack_pub = node.create_publisher(DiagnosticStatus, "/swarm/fault_acks", EVENTS)
        pubs = {r: node.create_publisher(TwistStamped, f"/Srobot{r}/cmd_vel", RELIABLE)
                for r in (1, 2)}

        def on_odom(r, msg):
            odom[r][_t(msg.header.stamp)] = (msg.pose.pose.position.x, msg.twist.twist.linear.x)
            cmd = TwistStamped()
            cmd.header.stamp = msg.header.stamp
            cmd.twist.linear.x = -0.2  # drive along -x (the robots face it)
            pubs[r].publish(cmd)

        def on_truth(r, msg):
            truth[r][_t(msg.header.stamp)] = msg.pose.pose.position.x

        def on_events(msg: DiagnosticArray):
            for st in msg.status:
                ev = FaultEvent.decode({kv.key: kv.value for kv in st.values})
                if st.name == "fault" and ev is not None:
                    events.append(ev)
                    if ev.kind == "kill-coordinator":  # the stand-in coordinator's owner acks
                        ack = FaultAck(ev.fault, ev.phase, "test")
                        ack_pub.publish(DiagnosticStatus(name="fault_ack", values=[
                            KeyValue(key=k, value=v) for k, v in ack.encode().items()]))

        for r in (1, 2):
            node.create_subscription(Odometry, f"/Srobot{r}/odom",
                                     lambda m, r=r: on_odom(r, m), RELIABLE)
            node.create_subscription(Odometry, f"/Srobot{r}/ground_truth",
                                     lambda m, r=r: on_truth(r, m), RELIABLE)
        node.create_subscription(DiagnosticArray, "/swarm/events", on_events, EVENTS)
        sim = start(["swarm-sim", "--world", "empty", "--swarm-size", "2", "--rtf", "0",
                     "--wait-for", "2", "--duration", "4", "--summary", str(summary),
                     "--faults", SPEC], tmp_path / "sim.log")
        try:
            t0 = time.monotonic()
            spin_until(executor, lambda: sim.poll() is not None, 60.0, "the simulator's end")
            wall = time.monotonic() - t0
            spin_until(executor, lambda: len(events) >= 6, 5.0, "every fault event")
        finally:
            code = stop(sim)
            node.destroy_node()
    log = (tmp_path / "sim.log").read_text()
    assert code == 0, log
    got = [(e.fault, e.kind, e.phase, e.robot, e.t) for e in events]
    assert got == [
        (4, "kill-coordinator", "start", "", 0.5), (4, "kill-coordinator", "end", "", 0.8),
        (1, "freeze", "start", "Srobot1", 1.0), (1, "freeze", "end", "Srobot1", 2.0),
        (2, "drop", "start", "Srobot2", 2.0), (2, "drop", "end", "Srobot2", 2.5),
        (3, "kill-robot", "start", "Srobot2", 3.0)], log
    s = json.loads(summary.read_text())
    assert s["late_ticks"] == 0 and "ack_timeouts" not in s["faults"], log
    assert s["faults"]["messages_dropped"] == {"2": 5}, log
    assert wall < 20.0, f"the simulator waited for lost messages ({wall:.1f} s)\n{log}"
    # Frozen: the steps of ticks 1.0 .. 1.9 are held (odometry of 1.1 .. 2.0 shows a zero
    # twist, and the pose of tick 1.0 throughout); odometry keeps coming; it moves again after.
    o1 = odom[1]
    frozen = [o1[t] for t in sorted(o1) if 1.1 <= t <= 2.0]
    assert len(frozen) == 10 and all(v == 0.0 for _, v in frozen), o1
    assert {x for x, _ in frozen} == {o1[1.0][0]}, o1
    assert o1[0.9][0] > o1[1.0][0] > o1[2.2][0]
    assert o1[1.0][1] < -0.1 and o1[2.2][1] < 0.0
    # Lost odometry at 2.0 .. 2.4; none after the death at 3.0; the body stays where it stopped.
    o2 = odom[2]
    assert [t for t in (1.9, 2.0, 2.1, 2.2, 2.3, 2.4, 2.5) if t in o2] == [1.9, 2.5], o2
    assert max(o2) == 2.9, o2
    dead = [truth[2][t] for t in sorted(truth[2]) if t >= 3.1]
    assert len(dead) >= 9 and len(set(dead)) == 1, truth[2]
