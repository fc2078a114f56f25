"""Node tests of the navigator's goal handshake (docs/ARCHITECTURE.md, "Goal handshake").

A :class:`NavigatorNode` runs in this process next to a probe node that plays the simulator (it
publishes odometry and scans tick by tick and reads the stamped ``cmd_vel`` answers) and the
commander (``goal_pose``).  The map comes from the bundled ``empty`` world's file, so no simulator
process is needed.  What is checked: on the first tick after the start (or after a goal ended)
the navigator withholds its answer until a connected commander's goal arrives, the goal then takes
effect on that tick; a commander outside the lockstep that never answers costs
``goal_wait_timeout`` wall seconds once, counted in ``nav_status``, while inside the lockstep
(``wait_for_commander``, as swarm-up sets it) no wait ends by the wall clock; with
``hold_goal_end`` the tick at which a goal ends is answered only on the commander's word
(``navigator/goal_coming``).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import LaserScan

from swarm_common.stamps import NS_PER_S, format_stamp_ns
from swarm_nav.node import NavigatorNode
from tests.support.ros import spin_until

pytestmark = pytest.mark.node

ROOT = Path(__file__).resolve().parents[2]
TICK_NS = NS_PER_S // 10  # control_rate 10 Hz (params/navigator.yaml)
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Probe:
    """The simulator and the commander of one robot ``/hs``, at (0, 0) facing +x."""

    def __init__(self, goal_wait_timeout: float, status_readers: int = 0,
                 cmd_vel_readers: int = 0, lockstep: bool = False, hold_goal_end: bool = False):
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.nav = NavigatorNode(
            namespace="/hs", context=self.ctx,
            parameter_overrides=[
                Parameter("map_yaml_path", value=str(ROOT / "maps" / "empty.yaml")),
                Parameter("goal_wait_timeout", value=goal_wait_timeout),
                Parameter("wait_for_status_readers", value=status_readers),
                Parameter("wait_for_cmd_vel_readers", value=cmd_vel_readers),
                Parameter("wait_for_commander", value=lockstep),
                Parameter("hold_goal_end", value=hold_goal_end),
            ])
        self.node = rclpy.create_node("probe", context=self.ctx)
        self.answers: dict[int, tuple[float, float]] = {}  # tick [ns] -> (v, w)
        self.status: dict[str, str] = {}
        self.node.create_subscription(TwistStamped, "/hs/cmd_vel", self._on_cmd, RELIABLE)
        self.node.create_subscription(DiagnosticStatus, "/hs/nav_status", self._on_status,
                                      LATCHED)
        self.odom_pub = self.node.create_publisher(Odometry, "/hs/odom", RELIABLE)
        self.scan_pub = self.node.create_publisher(LaserScan, "/hs/scan", qos_profile_sensor_data)
        self.goal_pub = self.node.create_publisher(PoseStamped, "/hs/goal_pose", RELIABLE)
        for n in (self.nav, self.node):
            self.executor.add_node(n)

    def close(self) -> None:
        self.executor.shutdown()
        self.nav.destroy_node()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)

    def _on_cmd(self, msg: TwistStamped) -> None:
        t = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
        self.answers[t] = (msg.twist.linear.x, msg.twist.angular.z)

    def _on_status(self, msg: DiagnosticStatus) -> None:
        self.status = {kv.key: kv.value for kv in msg.values}

    def _stamp(self, msg, t: int) -> None:
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, NS_PER_S)

    def tick(self, t: int) -> None:
        """Publish tick ``t``'s scan (every tick; the navigator uses those of lidar ticks) and
        odometry, as the simulator does."""
        scan = LaserScan()
        self._stamp(scan, t)
        scan.header.frame_id = "hs/base_scan"
        scan.angle_min, scan.angle_max, scan.angle_increment = -3.14159, 3.14159, 0.0174533
        scan.range_min, scan.range_max = 0.12, 3.5
        scan.ranges = [float("inf")] * 360
        self.scan_pub.publish(scan)
        odom = Odometry()
        self._stamp(odom, t)
        odom.header.frame_id = "hs/odom"
        odom.pose.pose.orientation.w = 1.0
        self.odom_pub.publish(odom)

    def answer(self, t: int, timeout: float) -> float:
        """Spin until tick ``t`` is answered; the wall seconds it took."""
        t0 = time.monotonic()
        spin_until(self.executor, lambda: t in self.answers, timeout, f"the answer to tick {t}")
        return time.monotonic() - t0

    def silent_for(self, t: int, seconds: float) -> bool:
        """Spin ``seconds`` wall; True if tick ``t`` stayed unanswered."""
        end = time.monotonic() + seconds
        while time.monotonic() < end and t not in self.answers:
            self.executor.spin_once(timeout_sec=0.02)
        return t not in self.answers

    def republish_until_answered(self, t: int, timeout: float) -> None:
        """Publish held tick ``t`` again every 0.5 s wall, as the simulator does, until it is
        answered or ``timeout`` wall seconds passed (the caller asserts which)."""
        deadline = time.monotonic() + timeout
        while t not in self.answers and time.monotonic() < deadline:
            self.tick(t)
            self.silent_for(t, 0.5)

    def send_goal(self, stamp: int, x: float, y: float) -> None:
        goal = PoseStamped()
        self._stamp(goal, stamp)
        goal.header.frame_id = "map"
        goal.pose.position.x, goal.pose.position.y = x, y
        goal.pose.orientation.w = 1.0
        self.goal_pub.publish(goal)


@pytest.fixture
def probe(request):
    """A :class:`Probe` whose nodes have discovered each other."""
    p = Probe(*request.param) if isinstance(request.param, tuple) else Probe(request.param)
    spin_until(p.executor, lambda: p.nav.count_subscribers("/hs/goal_pose") > 0
               and p.node.count_subscribers("/hs/odom") > 0, 10.0, "discovery")
    yield p
    p.close()


@pytest.mark.parametrize("probe", [5.0], indirect=True)
def test_tick_after_the_start_waits_for_the_commanders_goal(probe):
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)  # the start: IDLE, nothing to wait for yet
    spin_until(probe.executor, lambda: probe.status.get("stamp") == "1.000000000", 5.0,
               "the status of the first tick")
    t1 = t0 + TICK_NS
    probe.tick(t1)
    assert probe.silent_for(t1, 1.0), "the tick after the start did not wait for the goal"
    probe.send_goal(t0, 2.0, 0.0)  # stamped with the status time, as BasicNavigator does
    probe.answer(t1, 5.0)
    v, _ = probe.answers[t1]
    assert v > 0.0, "the goal did not take effect on the tick it was waited for"
    spin_until(probe.executor, lambda: probe.status.get("goal_id") == "1.000000000", 5.0,
               "the goal's status")
    assert probe.status["goal_wait_timeouts"] == "0"
    # While the goal runs, ticks are answered at once.
    t2 = t1 + TICK_NS
    probe.tick(t2)
    assert probe.answer(t2, 5.0) < 0.5


@pytest.mark.parametrize("probe", [(5.0, 2)], indirect=True)
def test_the_first_answer_waits_for_the_readers_of_nav_status(probe):
    """``wait_for_status_readers`` (swarm-up: its metrics listener and the commander): a
    navigator, restarted or not, answers its first tick only once ``nav_status`` has that many
    readers, so that none of them misses a goal's end (a reader that joins later gets the
    latched last status alone)."""
    t0 = 10 * TICK_NS
    probe.tick(t0)
    assert probe.silent_for(t0, 1.5), "answered with one reader of nav_status of two required"
    probe.node.create_subscription(DiagnosticStatus, "/hs/nav_status", lambda msg: None, LATCHED)
    probe.republish_until_answered(t0, 10.0)
    assert t0 in probe.answers, "the first tick stayed unanswered with both readers there"


@pytest.mark.parametrize("probe", [(5.0, 2)], indirect=True)
def test_a_goal_already_there_does_not_open_the_start_gate(probe):
    """A navigator restarted mid-run (a kill-nav fault) gets its commander's goal again before
    it answers its first tick, stamped in the past: it still waits for the readers of
    ``nav_status``, or a reader that matches only after that goal ended never learns of it
    (a goal missing from a workstation's count in 1 of about 30 CI runs of
    ``tests/test_e2e_faults.py``)."""
    t0 = 10 * TICK_NS
    probe.send_goal(t0 - 2 * TICK_NS, 2.0, 0.0)
    spin_until(probe.executor, lambda: len(probe.nav._goals) == 1, 5.0, "the goal")
    probe.tick(t0)
    assert probe.silent_for(t0, 1.5), "a waiting goal let the first answer past the start gate"
    probe.node.create_subscription(DiagnosticStatus, "/hs/nav_status", lambda msg: None, LATCHED)
    probe.republish_until_answered(t0, 10.0)
    assert t0 in probe.answers, "the first tick stayed unanswered with both readers there"
    assert probe.answers[t0][0] > 0.0, "the goal did not take effect on the first tick"


@pytest.mark.parametrize("probe", [(5.0, 0, 2)], indirect=True)
def test_the_first_answer_waits_for_the_readers_of_cmd_vel(probe):
    """``wait_for_cmd_vel_readers`` (swarm-up: the simulator, and the recorder when it records
    ``cmd_vel``): the first tick is answered only once ``cmd_vel`` has that many readers, so that
    a recorder matched late does not miss the first commands (``cmd_vel`` is volatile)."""
    t0 = 10 * TICK_NS
    probe.tick(t0)
    assert probe.silent_for(t0, 1.5), "answered with one reader of cmd_vel of two required"
    late: list[int] = []
    probe.node.create_subscription(
        TwistStamped, "/hs/cmd_vel",
        lambda msg: late.append(msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec),
        RELIABLE)
    probe.republish_until_answered(t0, 10.0)
    assert t0 in probe.answers, "the first tick stayed unanswered with both readers there"
    spin_until(probe.executor, lambda: t0 in late, 5.0, "the first answer at the late reader")


@pytest.mark.parametrize("probe", [5.0], indirect=True)
def test_a_goal_stamped_ahead_ends_the_wait_and_applies_at_its_stamp(probe):
    """A commander that holds its robot until a known time (a coordinator's hand-over) sends
    the next goal at once, stamped ahead: the tick waiting for it is answered at once, the
    robot stands until the stamp, and the goal takes effect at the first tick after it."""
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)
    spin_until(probe.executor, lambda: probe.status.get("stamp") == "1.000000000", 5.0,
               "the status of the first tick")
    probe.send_goal(t0, 0.1, 0.0)  # within the goal tolerance: reached at once
    t1 = t0 + TICK_NS
    probe.tick(t1)
    probe.answer(t1, 5.0)
    spin_until(probe.executor, lambda: probe.status.get("state") == "SUCCEEDED", 5.0,
               "the first goal reached")
    ahead = t1 + 5 * TICK_NS
    t2 = t1 + TICK_NS
    probe.tick(t2)
    assert probe.silent_for(t2, 0.5), "the tick after the goal ended did not wait for a goal"
    probe.send_goal(ahead, 3.0, 0.0)
    assert probe.answer(t2, 2.0) < 1.0, "a goal stamped ahead did not end the wait"
    t = t2
    while t <= ahead:
        assert probe.answers[t] == (0.0, 0.0), f"moved at {t} before the goal's stamp {ahead}"
        t += TICK_NS
        probe.tick(t)
        assert probe.answer(t, 2.0) < 1.0
    assert probe.answers[t][0] > 0.0, "the goal did not take effect after its stamp"
    assert probe.status["goal_wait_timeouts"] == "0"


@pytest.mark.parametrize("probe", [0.0], indirect=True)
def test_a_reader_that_joins_late_gets_the_earlier_commands(probe):
    """``cmd_vel`` keeps ``CMD_VEL_HISTORY`` commands for transient-local readers (swarm-up's
    recorder): a reader matched after ten answers gets all ten, stamped in order, and a volatile
    reader such as the simulator's gets none of them."""
    ticks = [(10 + k) * TICK_NS for k in range(10)]
    for t in ticks:
        probe.tick(t)
        probe.answer(t, 10.0)
    history, volatile = [], []

    def stamps(into):
        return lambda msg: into.append(msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec)

    probe.node.create_subscription(TwistStamped, "/hs/cmd_vel", stamps(history), QoSProfile(
        depth=100, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    probe.node.create_subscription(TwistStamped, "/hs/cmd_vel", stamps(volatile), RELIABLE)
    spin_until(probe.executor, lambda: len(history) >= len(ticks), 5.0, "the earlier commands")
    t = ticks[-1] + TICK_NS
    probe.tick(t)
    probe.answer(t, 5.0)
    spin_until(probe.executor, lambda: t in history and t in volatile, 5.0, "the next command")
    assert history == ticks + [t]
    assert volatile == [t]


@pytest.mark.parametrize("probe", [0.0], indirect=True)
def test_a_reader_that_joins_late_gets_the_statuses_of_goals_gone_by(probe):
    """``nav_status`` keeps ``NAV_STATUS_HISTORY`` statuses: a reader matched after a goal was
    replaced by the next still learns of the first (swarm-up's metrics count goals per
    workstation from these), where a latched last status alone would name only the second."""
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)
    ids, t = [], t0
    for x in (2.0, -2.0):
        probe.send_goal(t, x, 0.0)  # replaces the running goal, if any
        ids.append(format_stamp_ns(t))
        deadline = time.monotonic() + 5.0
        while probe.status.get("goal_id") != ids[-1] and time.monotonic() < deadline:
            t += TICK_NS  # a running goal's tick is answered at once: the goal may come later
            probe.tick(t)
            probe.answer(t, 5.0)
            probe.silent_for(t + TICK_NS, 0.05)
        assert probe.status.get("goal_id") == ids[-1], f"goal {ids[-1]} never ran"
    seen: list[str] = []
    probe.node.create_subscription(
        DiagnosticStatus, "/hs/nav_status",
        lambda msg: seen.append({kv.key: kv.value for kv in msg.values}.get("goal_id", "")),
        QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    spin_until(probe.executor, lambda: ids[-1] in seen, 5.0, "the history")
    assert ids[0] in seen, f"the first goal's statuses were not kept: {seen}"
    assert seen.index(ids[0]) < seen.index(ids[-1])


@pytest.mark.parametrize("probe", [0.3], indirect=True)
def test_a_commander_that_never_answers_costs_one_timeout_and_is_counted(probe):
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)
    t1 = t0 + TICK_NS
    probe.tick(t1)
    took = probe.answer(t1, 5.0)
    assert took >= 0.3, f"tick answered after {took:.2f} s, before goal_wait_timeout"
    assert probe.answers[t1] == (0.0, 0.0)
    spin_until(probe.executor, lambda: probe.status.get("goal_wait_timeouts") == "1", 5.0,
               "goal_wait_timeouts 1 in nav_status")
    # Only the first tick after the goal ended waits.
    t2 = t1 + TICK_NS
    probe.tick(t2)
    assert probe.answer(t2, 5.0) < 0.25


@pytest.mark.parametrize("probe", [5.0], indirect=True)
def test_a_cancel_with_no_goal_running_says_no_next_goal_is_coming(probe):
    """A coordinated commander whose robot reached its waiting spot (issue 11): the tick after
    the goal ended is answered at once, without a goal-wait timeout."""
    from std_srvs.srv import Trigger

    client = probe.node.create_client(Trigger, "/hs/navigator/cancel")
    spin_until(probe.executor, client.service_is_ready, 10.0, "the cancel service")
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)
    spin_until(probe.executor, lambda: probe.status.get("stamp") == "1.000000000", 5.0,
               "the status of the first tick")
    future = client.call_async(Trigger.Request())  # before the next tick comes
    spin_until(probe.executor, future.done, 5.0, "the cancel's answer")
    assert future.result().success is False  # nothing was running
    t1 = t0 + TICK_NS
    probe.tick(t1)
    assert probe.answer(t1, 5.0) < 0.5, "the tick waited for a goal after all"
    assert probe.answers[t1] == (0.0, 0.0)
    assert probe.status["goal_wait_timeouts"] == "0"


def _reach_a_goal(probe, t0: int) -> int:
    """Start, send a goal within the goal tolerance and tick until it is reached; the tick at
    which it ended."""
    probe.tick(t0)
    probe.answer(t0, 10.0)
    spin_until(probe.executor, lambda: probe.status.get("stamp") == format_stamp_ns(t0), 5.0,
               "the status of the first tick")
    probe.send_goal(t0, 0.1, 0.0)  # within the goal tolerance: reached at once
    t = t0
    while probe.status.get("state") != "SUCCEEDED":
        t += TICK_NS
        assert t < t0 + 20 * TICK_NS, "the goal was not reached"
        probe.tick(t)
        probe.answer(t, 5.0)
        probe.silent_for(-1, 0.2)  # its status, if it changed, arrives meanwhile
    return t


@pytest.mark.parametrize("probe", [(0.3, 0, 0, True)], indirect=True)
def test_in_the_lockstep_the_wait_for_the_next_goal_has_no_wall_clock_limit(probe):
    """swarm-up's commanders are in the lockstep (``wait_for_commander``): a commander that is
    alive but slow (paused, descheduled) costs wall time, never a goal-wait timeout, so the goal
    still takes effect at the tick it was due (swarm_common.lockstep)."""
    t_end = _reach_a_goal(probe, 10 * TICK_NS)
    t1 = t_end + TICK_NS
    probe.tick(t1)
    assert probe.silent_for(t1, 1.5), "the tick after the goal ended did not wait (or timed out)"
    probe.send_goal(t_end, 3.0, 0.0)  # stamped with the status time, as BasicNavigator does
    probe.answer(t1, 5.0)
    assert probe.answers[t1][0] > 0.0, "the late goal did not take effect on the tick it was due"
    spin_until(probe.executor, lambda: probe.status.get("state") == "DRIVING", 5.0, "driving")
    assert probe.status["goal_wait_timeouts"] == "0"


@pytest.mark.parametrize("probe", [(0.3, 0, 0, True, True)], indirect=True)
def test_the_end_of_a_goal_is_answered_on_the_commanders_word(probe):
    """``hold_goal_end`` (centralized runs): the status of the tick at which a goal ended goes
    out, its answer waits for ``navigator/goal_coming``; the next tick then waits for the goal,
    which arrives pending (``pending_goal_id``) and takes effect at the tick after its stamp."""
    from std_srvs.srv import Trigger

    coming = probe.node.create_client(Trigger, "/hs/navigator/goal_coming")
    spin_until(probe.executor, coming.service_is_ready, 10.0, "the goal_coming service")
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)
    spin_until(probe.executor, lambda: probe.status.get("stamp") == format_stamp_ns(t0), 5.0,
               "the status of the first tick")
    probe.send_goal(t0, 0.1, 0.0)
    t = t0 + TICK_NS
    probe.tick(t)
    spin_until(probe.executor, lambda: probe.status.get("state") == "SUCCEEDED", 5.0,
               "the goal reached")
    t_end = t
    while t_end not in probe.answers and probe.status.get("stamp") != format_stamp_ns(t_end):
        probe.executor.spin_once(timeout_sec=0.05)
    assert probe.status.get("stamp") == format_stamp_ns(t_end)
    assert probe.silent_for(t_end, 1.5), "the tick at which the goal ended was answered"
    future = coming.call_async(Trigger.Request())
    spin_until(probe.executor, future.done, 5.0, "the goal_coming answer")
    assert future.result().success
    probe.answer(t_end, 5.0)
    t1 = t_end + TICK_NS
    probe.tick(t1)
    assert probe.silent_for(t1, 1.0), "the tick after the goal ended did not wait for the goal"
    probe.send_goal(t_end + 3 * TICK_NS, 3.0, 0.0)  # stamped ahead, as a hand-over is
    spin_until(probe.executor, lambda: probe.status.get("pending_goal_id")
               == format_stamp_ns(t_end + 3 * TICK_NS), 5.0, "the pending goal's status")
    probe.answer(t1, 5.0)
    assert probe.answers[t1] == (0.0, 0.0)


@pytest.mark.parametrize("probe", [5.0], indirect=True)
def test_a_tick_published_again_is_not_answered_again(probe):
    """The simulator publishes a held tick again (the start gate, a rejoining robot); a
    navigator that answered it already does not step it a second time."""
    t0 = 10 * TICK_NS
    probe.tick(t0)
    probe.answer(t0, 10.0)
    probe.answers.clear()
    probe.tick(t0)
    assert probe.silent_for(t0, 1.0), "an answered tick was answered again"
