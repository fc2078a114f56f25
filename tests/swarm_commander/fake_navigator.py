"""A fake swarm navigator for commander tests: the navigator's ROS contract, no driving.

It subscribes ``<ns>/goal_pose``, publishes ``<ns>/nav_status`` (DiagnosticStatus, reliable +
transient local, depth 1, as docs/ARCHITECTURE.md fixes it) ``IDLE`` at start, then
``PLANNING`` -> ``DRIVING`` -> ``SUCCEEDED`` ``drive_time`` wall seconds after a goal, with the
distance remaining shrinking linearly; a goal with ``x > abort_x`` is ``ABORTED`` at once (reason
"goal outside the map"); a goal listed in ``take_instead`` is reached at another pose, as a
navigator that took another workstation (``swap_range``) reports it;
``<ns>/navigator/cancel`` (std_srvs/Trigger) cancels the running goal. It republishes its
status at 2 Hz, and uses the wall clock (``use_sim_time`` False).
"""

from __future__ import annotations

import math
import threading
import time
import warnings
from contextlib import contextmanager

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile, QoSReliabilityPolicy
from std_srvs.srv import Trigger

from swarm_common.geometry import quaternion_to_yaw
from swarm_common.nav_status import NavState, NavStatusRecord, encode, level_of
from swarm_common.stamps import format_stamp

# rclpy imports rosidl_generator_py -> lark -> the deprecated sre_* modules on the first node; the
# suite turns warnings into errors, so import it here once with that one warning silenced.
with warnings.catch_warnings():
    warnings.filterwarnings("ignore", "module 'sre_.*' is deprecated", DeprecationWarning)
    import rosidl_generator_py  # noqa: F401

STATUS_QOS = QoSProfile(
    reliability=QoSReliabilityPolicy.RELIABLE,
    durability=QoSDurabilityPolicy.TRANSIENT_LOCAL,
    history=QoSHistoryPolicy.KEEP_LAST,
    depth=1,
)
ACTIVE = ("PLANNING", "DRIVING")


class FakeNavigatorNode(Node):
    """The fake navigator of one robot.

    Args:
        namespace: the robot's namespace.
        drive_time: [s] wall from a goal to SUCCEEDED.
        abort_x: [m] goals with ``x`` above it are aborted.
        ignore_goals: the first this many goals are dropped (stays IDLE), as by a restart.
        take_instead: goal (x, y) [m] -> the pose (x, y, yaw) reached instead of it.
        stamp_step_ns: if set, every status carries a ``stamp`` (simulated time), this many ns
            after the previous one; the stamps of the SUCCEEDED statuses are kept in ``ended``.
        context: the rclpy context.
    """

    def __init__(self, namespace, *, drive_time=0.3, abort_x=100.0, ignore_goals=0,
                 take_instead=None, stamp_step_ns=None, context=None):
        super().__init__("navigator", namespace=namespace, context=context,
                         parameter_overrides=[Parameter("use_sim_time", value=False)])
        self.drive_time = drive_time
        self.abort_x = abort_x
        self.ignore_goals = ignore_goals
        self.take_instead = dict(take_instead or {})
        self.stamp_step_ns = stamp_step_ns
        self.stamp_ns = 0
        self.ended: list[int] = []  # stamps of the SUCCEEDED statuses (with stamp_step_ns)
        self._published = ""
        self.goals: list[tuple[str, float, float]] = []  # (goal_id, x, y) of every goal received
        self.cancels = 0
        self.state = "IDLE"
        self.goal_id = ""
        self.goal = (0.0, 0.0, 0.0)
        self.reason = ""
        self.position = (0.0, 0.0)
        self.start = 0.0
        self.distance0 = 0.0
        self.elapsed = 0.0
        self._last_publish = 0.0
        self.ns = self.get_namespace().strip("/")
        self._status_pub = self.create_publisher(DiagnosticStatus, "nav_status", STATUS_QOS)
        self._goal_sub = self.create_subscription(PoseStamped, "goal_pose", self._on_goal_pose, 10)
        self._cancel_srv = self.create_service(Trigger, "navigator/cancel", self._on_cancel)
        self._timer = self.create_timer(0.02, self._on_timer)
        self._publish()

    def _on_goal_pose(self, msg: PoseStamped):
        goal_id = format_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        x, y = msg.pose.position.x, msg.pose.position.y
        self.goals.append((goal_id, x, y))
        if self.ignore_goals > 0:
            self.ignore_goals -= 1
            return
        q = msg.pose.orientation
        yaw = quaternion_to_yaw(q.x, q.y, q.z, q.w)
        self.goal_id, self.goal, self.reason = goal_id, (x, y, yaw), ""
        self.start, self.elapsed = time.monotonic(), 0.0
        self.distance0 = math.dist(self.position, (x, y))
        self._set("PLANNING")
        if x > self.abort_x:
            self.reason = "goal outside the map"
            self._set("ABORTED")
        else:
            self._set("DRIVING")

    def _on_cancel(self, request, response):
        self.cancels += 1
        if self.state in ACTIVE:
            self.reason = "canceled by request"
            self._set("CANCELED")
            response.success, response.message = True, f"canceled goal {self.goal_id}"
        else:
            response.success, response.message = False, "no active goal"
        return response

    def _on_timer(self):
        now = time.monotonic()
        if self.state in ACTIVE:
            self.elapsed = now - self.start
            if self.elapsed >= self.drive_time:
                other = self.take_instead.get(self.goal[:2])
                if other is not None:
                    self.reason = (f"took the workstation at ({other[0]:.3f}, {other[1]:.3f}), "
                                   f"free while the goal at ({self.goal[0]:.3f}, "
                                   f"{self.goal[1]:.3f}) was taken")
                    self.goal = tuple(other)
                self.position = self.goal[:2]
                self._set("SUCCEEDED")
                return
        if now - self._last_publish >= 0.5:
            self._publish()

    def _set(self, state):
        self.state = state
        self._publish()

    def _publish(self):
        if self.state in ACTIVE:
            fraction = min(1.0, self.elapsed / self.drive_time) if self.drive_time > 0 else 1.0
            distance = self.distance0 * (1.0 - fraction)
        else:
            distance = 0.0 if self.state == "SUCCEEDED" else self.distance0
        state = NavState(self.state)
        stamp = None
        if self.stamp_step_ns is not None:
            self.stamp_ns += self.stamp_step_ns
            stamp = self.stamp_ns
            if self.state == "SUCCEEDED" and self._published != "SUCCEEDED":
                self.ended.append(stamp)
        self._published = self.state
        values = encode(NavStatusRecord(
            state=state, goal_id=self.goal_id, goal=self.goal, distance_remaining=distance,
            navigation_time=self.elapsed, recoveries=0, holding_time=0.0, reason=self.reason,
            stamp_ns=stamp))
        msg = DiagnosticStatus(
            level=bytes((level_of(state),)), name=f"{self.ns}/navigator",
            message=self.state, hardware_id=self.ns,
            values=[KeyValue(key=k, value=v) for k, v in values.items()])
        self._last_publish = time.monotonic()
        self._status_pub.publish(msg)


@contextmanager
def running_fake_navigator(namespace, context: Context | None = None, **kwargs):
    """Run a :class:`FakeNavigatorNode` on its own executor thread; stop everything on exit.

    Args:
        namespace: the robot's namespace.
        context: an initialised rclpy context; a private one is made (and shut down) if None.
        **kwargs: passed to :class:`FakeNavigatorNode`.

    Yields:
        The node (read ``.goals``, ``.cancels``, ``.state``).
    """
    own_context = context is None
    if own_context:
        context = Context()
        rclpy.init(context=context)
    node = FakeNavigatorNode(namespace, context=context, **kwargs)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stop = threading.Event()

    def spin():
        while not stop.is_set() and context.ok():
            executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, name=f"fake_navigator_{namespace}", daemon=True)
    thread.start()
    try:
        yield node
    finally:
        stop.set()
        thread.join(timeout=5.0)
        executor.shutdown(timeout_sec=0)
        node.destroy_node()
        if own_context:
            rclpy.try_shutdown(context=context)
