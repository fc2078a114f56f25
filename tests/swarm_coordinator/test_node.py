"""The coordinator's ROS shell: its first answers wait until the metrics can hear its start."""

import json
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from std_msgs.msg import String

from swarm_common import topics
from swarm_common.coordination import EVENT_COORDINATOR, METRICS_NODE, Request, encode_request
from swarm_coordinator.node import CoordinatorNode
from swarm_ros.qos import publisher, subscription
from tests.support.ros import ros_context, spin_until
from tests.swarm_coordinator.test_core import make_core


def _spin_for(executor, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


@pytest.mark.node
def test_first_answers_wait_for_a_reader_of_the_events():
    """A restarted coordinator's first batch came out before discovery had matched the metrics'
    reader of the volatile /swarm/events: its "up" event and rebuilt reservations were lost (CI;
    and 8 false reservation conflicts in a kill-coordinator run, where the groups' fault nodes
    read /swarm/events and matched first)."""
    with ros_context() as (ctx, executor):
        coordinator = CoordinatorNode(make_core({"r1": ["A"], "r2": ["B"]}), context=ctx)
        robot = Node("fake_robots", context=ctx)
        events: list[DiagnosticArray] = []
        answers: list[str] = []
        acks: list[str] = []

        def on_assignment(msg):
            (acks if json.loads(msg.data)["kind"] == "ack" else answers).append(msg.data)

        requests = publisher(robot, String, topics.COORDINATOR_REQUEST)
        for ns in ("r1", "r2"):
            subscription(robot, String, topics.ASSIGNMENT, on_assignment, ns)
        for node in (coordinator, robot):
            executor.add_node(node)
        spin_until(executor, lambda: requests.get_subscription_count() > 0, 10.0,
                   "the coordinator's request reader")
        for ns in ("r1", "r2"):
            requests.publish(String(data=encode_request(Request(ns, 1, "ready", 0))))
        # every robot is heard, but only another node (a group's fault node) reads
        # /swarm/events: no answer goes out
        subscription(robot, DiagnosticArray, topics.EVENTS, lambda m: None)
        _spin_for(executor, 1.5)
        assert answers == []
        # each request is acknowledged at once all the same: it is there
        assert sorted(json.loads(a)["robot"] for a in acks) == ["r1", "r2"]
        metrics = Node(METRICS_NODE, context=ctx)
        subscription(metrics, DiagnosticArray, topics.EVENTS, events.append)
        executor.add_node(metrics)
        spin_until(executor, lambda: len(answers) == 2 and events, 10.0,
                   "the answers and the events")
        kinds = [s.name for msg in events for s in msg.status]
        assert kinds[0] == EVENT_COORDINATOR
        assert {json.loads(a)["robot"] for a in answers} == {"r1", "r2"}
        for node in (coordinator, robot, metrics):
            executor.remove_node(node)
            node.destroy_node()


@pytest.mark.node
def test_without_swarm_ups_metrics_the_first_answers_still_go_out():
    """A coordinator started by hand (no metrics node): the first answers go out
    ``metrics_absent_s`` after every robot was heard (what is recorded depends on it, not what
    is simulated: the navigators wait for their first goals)."""
    with ros_context() as (ctx, executor):
        coordinator = CoordinatorNode(make_core({"r1": ["A"]}), metrics_absent_s=1.0,
                                      context=ctx)
        robot = Node("fake_robot", context=ctx)
        answers: list[str] = []
        requests = publisher(robot, String, topics.COORDINATOR_REQUEST)
        subscription(robot, String, topics.ASSIGNMENT, lambda m: answers.append(m.data), "r1")
        for node in (coordinator, robot):
            executor.add_node(node)
        spin_until(executor, lambda: requests.get_subscription_count() > 0, 10.0,
                   "the coordinator's request reader")
        requests.publish(String(data=encode_request(Request("r1", 1, "ready", 0))))
        spin_until(executor, lambda: any(json.loads(a)["kind"] != "ack" for a in answers), 10.0,
                   "the answer")
        assert [json.loads(a)["robot"] for a in answers] == ["r1", "r1"]  # the ack, the answer
        for node in (coordinator, robot):
            executor.remove_node(node)
            node.destroy_node()


def test_a_mixed_fleet_gets_its_parking_spots():
    """``--robot`` as swarm-up passes a mix: the parking spots on the spawn grid (checked for the
    largest model) are there, as for a fleet of that model alone (an unreadable --robot would
    leave none)."""
    from swarm_coordinator.node import build_core

    robots = tuple(f"Srobot{i}" for i in range(1, 5))
    mixed = build_core("slim_blockage", 0, robots, "turtlebot3_burger:3,turtlebot3_waffle:1",
                       0.1, "e")
    waffles = build_core("slim_blockage", 0, robots, "turtlebot3_waffle", 0.1, "e")
    park = [s.xy for s in mixed.spots.values() if not s.near]
    assert park and park == [s.xy for s in waffles.spots.values() if not s.near]


def test_build_core_takes_the_policy_and_plans_path_lengths_on_the_map():
    """The scheduler's distance is the planner's path length: around the blockage, longer than
    the straight line; the hall variant has no waiting spots; route has no distance at all."""
    import math

    from swarm_coordinator.node import build_core, policy_argv

    robots = tuple(f"Srobot{i}" for i in range(1, 4))
    near = build_core("slim_blockage", 0, robots, "turtlebot3_waffle", 0.1, "e")
    hall = build_core("slim_blockage", 0, robots, "turtlebot3_waffle", 0.1, "e",
                      waiting_spots="hall", silence_timeout=0.0)
    assert sum(s.startswith("wait") for s in near.spots) == 9
    assert not any(s.startswith("wait") for s in hall.spots)
    assert hall.cfg.silence_timeout_ns == 0 and near.cfg.assignment == "nearest-free"
    # from the hall's right of the blockage to loader3 (x -7.7): around the blockage's end
    here, loader = (-3.0, 1.0), near.stations["loader3"].pose
    straight = math.hypot(here[0] - loader[0], here[1] - loader[1])
    assert near._distance(here, "loader3") > straight + 4.0
    assert near.robots["Srobot1"].xy is not None  # its spawn pose
    route = build_core("slim_blockage", 0, robots, "turtlebot3_waffle", 0.1, "e",
                       assignment="route")
    assert route._distance(here, "loader3") == straight

    class Args:
        assignment, waiting_spots, silence_timeout = "route", None, 120.0

    assert policy_argv(Args()) == ("--assignment", "route", "--silence-timeout", "120")
