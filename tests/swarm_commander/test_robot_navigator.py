"""BasicNavigator against a fake navigator (node tests, wall clock, in-process)."""

from __future__ import annotations

import itertools
import math
import re
import threading
import time

import pytest
import rclpy
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from swarm_commander.robot_navigator import BasicNavigator, NavFeedback, TaskResult
from swarm_common.geometry import yaw_to_quaternion

from .fake_navigator import running_fake_navigator

pytestmark = pytest.mark.node


_COUNTER = itertools.count(1)
GOAL_ID = re.compile(r"^\d+\.\d{9}$")


@pytest.fixture
def context():
    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def ns():
    """A namespace no earlier test used (their latched statuses may linger in discovery)."""
    return f"Tnav{next(_COUNTER)}"


@pytest.fixture
def navigator(context, ns):
    nav = BasicNavigator(namespace=ns, context=context)
    yield nav
    nav.destroyNode()


def pose(x, y, yaw=0.0, frame="map") -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x, msg.pose.position.y = float(x), float(y)
    qx, qy, qz, qw = yaw_to_quaternion(yaw)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = qx, qy, qz, qw
    return msg


def run_task(nav: BasicNavigator, timeout=10.0) -> list[NavFeedback]:
    """The nav2 script loop; returns every feedback seen, the final one last."""
    seen = []
    deadline = time.monotonic() + timeout
    while not nav.isTaskComplete():
        feedback = nav.getFeedback()
        if feedback is not None:
            seen.append(feedback)
        assert time.monotonic() < deadline, "task did not complete"
    if nav.getFeedback() is not None:
        seen.append(nav.getFeedback())
    return seen


def seconds(d: Duration) -> float:
    return d.sec + d.nanosec * 1e-9


def test_task_result_matches_nav2():
    assert [(r.name, int(r)) for r in TaskResult] == [
        ("UNKNOWN", 0), ("SUCCEEDED", 1), ("CANCELED", 2), ("FAILED", 3)]


def test_no_task_is_complete_with_unknown_result(navigator):
    assert navigator.isTaskComplete() is True
    assert navigator.getResult() == TaskResult.UNKNOWN
    assert navigator.getFeedback() is None


def test_wait_until_active_times_out_without_navigator(navigator):
    t0 = time.monotonic()
    assert navigator.waitUntilNav2Active(timeout_sec=0.3) is False
    assert 0.3 <= time.monotonic() - t0 < 2.0


def test_a_silent_navigator_gets_a_new_reader_until_it_is_heard(context, ns):
    """The workaround for eProsima/Fast-DDS#3822: the remade reader still gets the latched status,
    and once a status arrived no more readers are made."""
    nav = BasicNavigator(namespace=ns, context=context, status_rematch_s=0.2)
    try:
        assert nav.waitUntilNav2Active(timeout_sec=1.0) is False
        assert nav.status_rematches >= 2
        with running_fake_navigator(ns, context):
            assert nav.waitUntilNav2Active(timeout_sec=10.0)
            nav._spin_until(lambda: False, 0.6)  # the timer fires at least twice more
            made = nav.status_rematches
            nav._spin_until(lambda: False, 0.6)
            assert nav.status_rematches == made
            assert nav.count_subscribers(f"/{ns}/nav_status") == 1  # the old readers are gone
    finally:
        nav.destroyNode()


def test_go_to_pose_succeeds(context, ns, navigator):
    with running_fake_navigator(ns, context, drive_time=0.6) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(3.0, 4.0, 1.0)) is True
        feedbacks = run_task(navigator)
        assert navigator.getResult() == TaskResult.SUCCEEDED
    assert len(fake.goals) == 1
    goal_id, x, y = fake.goals[0]
    assert (x, y) == (3.0, 4.0)
    assert GOAL_ID.match(goal_id)
    assert feedbacks and all(f.goal_id == goal_id for f in feedbacks)
    distances = [f.distance_remaining for f in feedbacks]
    assert distances[0] == pytest.approx(5.0, abs=1e-3)  # from the fake's start at (0, 0)
    assert all(a >= b for a, b in zip(distances, distances[1:], strict=False))
    assert isinstance(feedbacks[-1].navigation_time, Duration)
    assert 0.0 <= seconds(feedbacks[-1].navigation_time) < 0.7
    assert feedbacks[-1].number_of_recoveries == 0
    assert navigator.getFeedback().state == "SUCCEEDED"


def test_aborted_goal_fails_with_reason(context, ns, navigator):
    with running_fake_navigator(ns, context) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(150.0, 0.0))
        run_task(navigator)
        assert navigator.getResult() == TaskResult.FAILED
        assert navigator.getFeedback().reason == "goal outside the map"
        assert fake.state == "ABORTED"


def test_cancel_task_cancels(context, ns, navigator):
    with running_fake_navigator(ns, context, drive_time=30.0) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(1.0, 0.0))
        deadline = time.monotonic() + 5.0
        while not (navigator.getFeedback() and navigator.getFeedback().state == "DRIVING"):
            assert not navigator.isTaskComplete()
            assert time.monotonic() < deadline
        t0 = time.monotonic()
        navigator.cancelTask()
        run_task(navigator, timeout=5.0)
        assert navigator.getResult() == TaskResult.CANCELED
        assert time.monotonic() - t0 < 5.0
        assert fake.cancels == 1 and fake.state == "CANCELED"


def test_cancel_after_ros_shut_down_warns_instead_of_raising(context, ns, navigator, capfd):
    """A Ctrl-C in a route script shuts ROS down; a cancelTask in its cleanup must not raise."""
    with running_fake_navigator(ns, drive_time=30.0):  # its own context: it keeps running
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(1.0, 0.0))
        rclpy.shutdown(context=context)
        navigator.cancelTask()
        assert not navigator.isTaskComplete()  # no answer can come any more; no exception
    assert "ROS is shut down: cannot cancel goal" in capfd.readouterr().err


def test_follow_waypoints_visits_all_in_order(context, ns, navigator):
    xs = [1.0, 2.0, 3.0]
    with running_fake_navigator(ns, context, drive_time=0.4) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.followWaypoints([pose(x, 0.0) for x in xs])
        feedbacks = run_task(navigator)
        assert navigator.getResult() == TaskResult.SUCCEEDED
    assert [x for _, x, _ in fake.goals] == xs
    assert len({goal_id for goal_id, _, _ in fake.goals}) == 3
    waypoints = [f.current_waypoint for f in feedbacks]
    assert sorted(set(waypoints)) == [0, 1, 2]
    assert waypoints == sorted(waypoints)  # never goes back


def test_follow_waypoints_stops_at_an_aborted_waypoint(context, ns, navigator):
    with running_fake_navigator(ns, context, drive_time=0.2) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.followWaypoints([pose(1.0, 0.0), pose(150.0, 0.0), pose(2.0, 0.0)])
        feedbacks = run_task(navigator)
        assert navigator.getResult() == TaskResult.FAILED
    assert [x for _, x, _ in fake.goals] == [1.0, 150.0]
    assert feedbacks[-1].current_waypoint == 1


def test_go_through_poses_reports_the_whole_remaining_distance(context, ns, navigator):
    poses = [pose(3.0, 4.0), pose(3.0, 0.0), pose(0.0, 0.0, math.pi)]
    with running_fake_navigator(ns, context, drive_time=0.4) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goThroughPoses(poses)
        feedbacks = run_task(navigator)
        assert navigator.getResult() == TaskResult.SUCCEEDED
    assert [(x, y) for _, x, y in fake.goals] == [(3.0, 4.0), (3.0, 0.0), (0.0, 0.0)]
    first = feedbacks[0]
    assert first.number_of_poses_remaining == 3
    assert first.distance_remaining == pytest.approx(5.0 + 4.0 + 3.0, abs=1e-3)
    remaining = [f.number_of_poses_remaining for f in feedbacks]
    assert remaining == sorted(remaining, reverse=True) and remaining[-1] == 1
    total = seconds(feedbacks[-1].navigation_time)
    assert 1.0 <= total < 2.5  # three legs of 0.4 s each, summed


def test_goal_stamps_are_unique_when_the_clock_stands_still(context, ns):
    """With use_sim_time and no /clock, now() is 0: stamps still differ by 1 ns."""
    nav = BasicNavigator(namespace=ns, context=context,
                         parameter_overrides=[Parameter("use_sim_time", value=True)])
    try:
        with running_fake_navigator(ns, context, drive_time=0.3) as fake:
            assert nav.waitUntilNav2Active(timeout_sec=10.0)
            for x in (1.0, 2.0, 3.0):
                assert nav.goToPose(pose(x, 0.0))
            run_task(nav)
            assert nav.getResult() == TaskResult.SUCCEEDED
            deadline = time.monotonic() + 5.0
            while len(fake.goals) < 3 and time.monotonic() < deadline:
                time.sleep(0.02)
        assert [g[0] for g in fake.goals] == ["0.000000001", "0.000000002", "0.000000003"]
        assert nav.getFeedback().goal_id == "0.000000003"
    finally:
        nav.destroy_node()


def test_rejects_a_pose_in_another_frame_or_with_nan(context, ns, navigator):
    with running_fake_navigator(ns, context) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(1.0, 0.0, frame="odom")) is False
        assert navigator.goToPose(pose(math.nan, 0.0)) is False
        assert navigator.goThroughPoses([]) is False
        time.sleep(0.2)
        assert fake.goals == []


def test_goal_lost_by_the_navigator_is_sent_again(context, ns, navigator):
    navigator.resend_after = 0.3
    with running_fake_navigator(ns, context, ignore_goals=1, drive_time=0.2) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(1.0, 1.0))
        run_task(navigator, timeout=10.0)
        assert navigator.getResult() == TaskResult.SUCCEEDED
    assert len(fake.goals) == 2 and fake.goals[0][0] != fake.goals[1][0]


def test_goal_is_sent_again_at_once_when_a_navigator_that_took_it_restarts(context, ns,
                                                                        navigator):
    """A navigator that had taken our goal and reports ``IDLE`` was restarted (a fault): the
    goal goes again at once, not after ``resend_after`` (the wall clock must not decide)."""
    navigator.resend_after = 30.0
    with running_fake_navigator(ns, context, drive_time=30.0) as fake:
        assert navigator.waitUntilNav2Active(timeout_sec=10.0)
        assert navigator.goToPose(pose(1.0, 1.0))
        deadline = time.monotonic() + 5.0
        while not (navigator.getFeedback() and navigator.getFeedback().state == "DRIVING"):
            assert not navigator.isTaskComplete() and time.monotonic() < deadline
        fake.drive_time = 0.2
        fake.goal_id, fake.state = "", "IDLE"  # what a restarted navigator publishes first
        fake._publish()
        restarted = time.monotonic()
        run_task(navigator, timeout=10.0)
        assert navigator.getResult() == TaskResult.SUCCEEDED
        assert time.monotonic() - restarted < 5.0
    assert len(fake.goals) == 2 and fake.goals[0][0] != fake.goals[1][0]


def test_goal_replaced_by_someone_else_fails(context, ns, navigator):
    other = rclpy.create_node("rviz_like", namespace=ns, context=context)
    pub = other.create_publisher(PoseStamped, "goal_pose", 10)
    try:
        with running_fake_navigator(ns, context, drive_time=30.0):
            assert navigator.waitUntilNav2Active(timeout_sec=10.0)
            assert navigator.goToPose(pose(1.0, 0.0))
            deadline = time.monotonic() + 5.0
            while not (navigator.getFeedback() and navigator.getFeedback().state == "DRIVING"):
                assert not navigator.isTaskComplete() and time.monotonic() < deadline
            foreign = pose(2.0, 0.0)
            foreign.header.stamp.sec = 999
            while pub.get_subscription_count() == 0:
                assert time.monotonic() < deadline
                time.sleep(0.02)
            pub.publish(foreign)
            run_task(navigator, timeout=5.0)
            assert navigator.getResult() == TaskResult.FAILED
            assert "999.000000000" in navigator.getFeedback().reason
    finally:
        other.destroy_node()


def test_works_when_spun_by_an_executor_in_another_thread(context, ns, navigator):
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(navigator)
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        with running_fake_navigator(ns, context, drive_time=0.3):
            assert navigator.waitUntilNav2Active(timeout_sec=10.0)
            ended = []
            navigator.on_task_complete = ended.append
            assert navigator.goToPose(pose(1.0, 0.0))
            run_task(navigator)
            assert navigator.getResult() == TaskResult.SUCCEEDED
            assert ended == [TaskResult.SUCCEEDED]
    finally:
        stop.set()
        thread.join(timeout=5.0)
        executor.shutdown(timeout_sec=0)
