"""nav2 simple-commander facade over one swarm navigator's topics.

:class:`BasicNavigator` and :class:`TaskResult` mirror ``nav2_simple_commander.robot_navigator``
(ros-navigation/navigation2, ``nav2_simple_commander/nav2_simple_commander/robot_navigator.py``,
Apache-2.0): the same class, method names, signatures and return conventions, so a nav2 route
script ports by changing one import::

    from swarm_commander.robot_navigator import BasicNavigator, TaskResult

    rclpy.init()
    navigator = BasicNavigator(namespace='Srobot3')
    navigator.waitUntilNav2Active()
    navigator.goToPose(goal_pose)
    while not navigator.isTaskComplete():
        feedback = navigator.getFeedback()
    if navigator.getResult() == TaskResult.SUCCEEDED:
        ...

The transport is not nav2's actions (``nav2_msgs`` is not available as a wheel) but the swarm
navigator's topics (docs/ARCHITECTURE.md, "ROS conventions chosen by us"):

- a goal is a ``geometry_msgs/PoseStamped`` on ``<ns>/goal_pose`` in ``map`` whose
  ``header.stamp`` is unique per goal: the simulated time of the navigator's latest status
  (its ``stamp`` value; the node's clock when there is none), 1 ns later than the previous goal
  if that has not moved.  The navigator applies a goal at its first control tick after the
  stamp, so the same seed gives the same run (docs/ARCHITECTURE.md, "goal handshake");
  ``"<sec>.<nanosec:09d>"`` of the stamp is the goal's id;
- progress and the outcome come from ``<ns>/nav_status`` (``diagnostic_msgs/DiagnosticStatus``,
  reliable + transient local; its values are :mod:`swarm_common.nav_status`'s record); a status
  refers to our goal when its ``goal_id`` value is our id;
  ``SUCCEEDED`` / ``ABORTED`` / ``CANCELED`` map onto :class:`TaskResult` ``SUCCEEDED`` /
  ``FAILED`` / ``CANCELED``;
- ``cancelTask`` calls ``<ns>/navigator/cancel`` (``std_srvs/Trigger``).

``goThroughPoses`` and ``followWaypoints`` send their poses one after the other, each on success of
the one before; the task fails at the first aborted pose (nav2's waypoint follower default,
``stop_on_failure: true``).

The blocking verbs (``isTaskComplete`` waits up to 0.1 s, ``waitUntilNav2Active``, ``cancelTask``)
spin the node themselves, as nav2's do, unless the node has been added to an executor that spins
it elsewhere (e.g. ``rclpy.spin`` in a thread); then they wait for that executor's callbacks
instead. Code that runs *inside* that executor's callbacks (a commander driven by timers, several
robots in one process) uses the non-blocking :attr:`BasicNavigator.navigator_ready`,
:meth:`BasicNavigator.task_complete`, :attr:`BasicNavigator.on_task_complete` and
:attr:`BasicNavigator.on_first_status` instead.

If the navigator reports ``IDLE`` while our goal should be running (it was restarted, or the goal
message was lost), the current pose is sent again after :attr:`BasicNavigator.resend_after`
seconds; a goal replaced by someone else's goal ends the task as ``FAILED``, as a preempted nav2
goal is aborted.

A navigator that has not been heard from :data:`STATUS_REMATCH_S` seconds (wall) after the
``nav_status`` reader was first spun gets a new reader, until the first status arrives: Fast DDS
can intermittently leave a late-joining reliable, transient-local reader without the writer's
history (eProsima/Fast-DDS#3822, open), and the navigator publishes nothing new while the
simulation waits for this very commander.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from enum import IntEnum

from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from rclpy._rclpy_pybind11 import RCLError  # what a call on a shut-down context raises
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from swarm_common import topics
from swarm_common.errors import EXIT_BAD_INPUT, EXIT_RUNTIME
from swarm_common.nav_status import NavState, NavStatusRecord, decode
from swarm_common.stamps import NS_PER_S, format_stamp
from swarm_ros.latched import REMATCH_S, LatchedReader
from swarm_ros.qos import publisher

__all__ = ["BasicNavigator", "NavFeedback", "TaskResult"]

MAP_FRAME = "map"

STATUS_REMATCH_S = REMATCH_S
"""[s] wall: how long the commander waits for its first ``nav_status`` before it makes the reader
again (:class:`swarm_ros.latched.LatchedReader`, eProsima/Fast-DDS#3822)."""


class TaskResult(IntEnum):
    """Outcome of a task, as ``nav2_simple_commander.robot_navigator.TaskResult``."""

    UNKNOWN = 0
    SUCCEEDED = 1
    CANCELED = 2
    FAILED = 3


_RESULT_OF = {
    NavState.SUCCEEDED: TaskResult.SUCCEEDED,
    NavState.ABORTED: TaskResult.FAILED,
    NavState.CANCELED: TaskResult.CANCELED,
}
"""The task result of each navigator state that ends a goal
(:data:`swarm_common.nav_status.OUTCOMES`)."""


@dataclass
class NavFeedback:
    """Feedback of the running task: the fields nav2 scripts read from the feedback of
    ``NavigateToPose``, ``NavigateThroughPoses`` and ``FollowWaypoints``, plus the navigator's own.

    Not carried: ``current_pose`` (the navigator's status has no pose; read ``<ns>/odom``).

    Attributes:
        distance_remaining: [m] along the navigator's path to the current pose, plus the
            straight-line distances between the poses still to come (multi-pose tasks).
        navigation_time: ``builtin_interfaces/Duration`` since the task started, in the
            navigator's clock (simulated time in a simulation).
        estimated_time_remaining: ``builtin_interfaces/Duration``: ``distance_remaining`` over the
            speed at which the distance has been shrinking; zero while it does not shrink.
        number_of_recoveries: recoveries of the navigator during this task.
        number_of_poses_remaining: poses not reached yet, the current one included.
        current_waypoint: 0-based index of the pose being driven to.
        state: the navigator's state (``PLANNING``, ``DRIVING``, ``HOLDING``, ...).
        goal_id: the id (``"<sec>.<nanosec:09d>"``) of the goal being driven to.
        holding_time: [s] spent in the holding pattern for the current pose.
        reason: the navigator's reason, e.g. why a goal was aborted; ``""`` if none.
        goal: (x [m], y [m], yaw [rad]) in ``map`` of the goal the navigator drives to, as it
            reports it: the pose sent, or another workstation of its kind taken instead
            (``swap_range``); None before the navigator reported one.
    """

    distance_remaining: float = 0.0
    navigation_time: Duration = field(default_factory=Duration)
    estimated_time_remaining: Duration = field(default_factory=Duration)
    number_of_recoveries: int = 0
    number_of_poses_remaining: int = 0
    current_waypoint: int = 0
    state: str = ""
    goal_id: str = ""
    holding_time: float = 0.0
    reason: str = ""
    goal: tuple[float, float, float] | None = None


@dataclass
class _Task:
    """One goToPose / goThroughPoses / followWaypoints request and its progress."""

    kind: str
    poses: list
    index: int = 0
    goal_id: str = ""
    sent_wall: float = 0.0  # [s] monotonic, when the current pose was sent
    seen: bool = False  # a status for the current pose's goal id arrived
    done_time: float = 0.0  # [s] navigation time of the poses already reached
    done_recoveries: int = 0
    sample: tuple[float, float] | None = None  # (navigation time [s], distance [m]) last seen
    speed: float = 0.0  # [m/s] rate at which the distance remaining shrinks
    result: TaskResult | None = None
    not_before_ns: int = 0  # [ns] no goal of this task is stamped earlier (go_to_pose_at)
    cancel_requested: bool = False
    cancel_future: object = None


class BasicNavigator(Node):
    """nav2's ``BasicNavigator`` for one swarm robot (see the module docstring).

    Args:
        node_name: the node's name, as nav2's.
        namespace: the robot's namespace (``"Srobot3"``); topics are resolved in it.
        **kwargs: passed on to ``rclpy.node.Node`` (e.g. ``context``, ``parameter_overrides``).
    """

    resend_after = 3.0
    """[s] wall: how long the navigator may report ``IDLE`` for something else than our goal
    before the goal is sent again."""

    cancel_timeout = 5.0
    """[s] wall: how long ``cancelTask`` waits for the navigator's answer when it spins."""

    def __init__(self, node_name="basic_navigator", namespace="", connect=True,
                 status_rematch_s=STATUS_REMATCH_S, **kwargs):
        """Args:
            node_name, namespace, kwargs: as ``rclpy.node.Node``.
            connect: create the ``goal_pose`` publisher now (nav2's behaviour).  False defers it
                to :meth:`connect`: a navigator started by swarm-up with ``wait_for_commander``
                holds the simulation until a ``goal_pose`` publisher appears, so a commander
                that must first reach someone else (the coordinator) connects only then.
            status_rematch_s: [s] wall, > 0: until the first ``nav_status``, the reader is made
                again this often (:data:`STATUS_REMATCH_S`, the module docstring).
        """
        super().__init__(node_name=node_name, namespace=namespace, **kwargs)
        # state
        self.initial_pose = PoseStamped()
        self.initial_pose.header.frame_id = MAP_FRAME
        self.initial_pose_received = False
        self.feedback: NavFeedback | None = None
        self.last_nav_status: DiagnosticStatus | None = None
        self.on_task_complete = None
        """Optional ``callable(TaskResult)``, called in the executor's thread right after a task
        ends (from the ``nav_status`` callback), for commanders driven by callbacks."""
        self.on_first_status = None
        """Optional ``callable()``, called in the executor's thread right after the first
        ``nav_status`` arrived (for commanders driven by callbacks: the navigator may be ready)."""
        self._cond = threading.Condition(threading.RLock())
        self._task: _Task | None = None
        self._result = TaskResult.UNKNOWN
        self._nav_status_received = False
        self._last_stamp_ns = 0
        self._status_stamp_ns: int | None = None  # simulated time of the latest nav_status
        self._last_status: NavStatusRecord | None = None
        self._sent_ids: deque[str] = deque(maxlen=64)
        self._own_executor: SingleThreadedExecutor | None = None
        # publishers, subscribers, clients
        self._goal_pub = None
        if connect:
            self.connect()
        self._status_reader = LatchedReader(self, DiagnosticStatus, topics.NAV_STATUS,
                                            self._on_nav_status, rematch_s=status_rematch_s,
                                            qos=topics.NAV_STATUS_COMMANDER_READER_QOS)
        self._cancel_client = self.create_client(Trigger, topics.CANCEL_SERVICE)

    @property
    def status_rematches(self) -> int:
        """How many times the ``nav_status`` reader was made again (:data:`STATUS_REMATCH_S`)."""
        return self._status_reader.rematches

    def connect(self) -> None:
        """Create the ``goal_pose`` publisher (idempotent): the navigator sees a commander."""
        if self._goal_pub is None:
            self._goal_pub = publisher(self, PoseStamped, topics.GOAL_POSE)

    @property
    def connected(self) -> bool:
        """True once the ``goal_pose`` publisher exists (see ``connect``)."""
        return self._goal_pub is not None

    # ------------------------------------------------------------------ nav2 verbs

    def destroyNode(self):
        """Destroy the node (nav2's spelling)."""
        self.destroy_node()

    def destroy_node(self):
        """Destroy the node and the executor it spins itself with."""
        if self._own_executor is not None:
            self._own_executor.shutdown(timeout_sec=0)
            self._own_executor = None
        return super().destroy_node()

    def setInitialPose(self, initial_pose):
        """Accept an initial pose, as nav2's (for AMCL).

        The swarm's odometry starts at the true spawn pose in ``map`` and does not drift, so
        there is no localiser to tell: the pose is only stored in ``self.initial_pose``.

        Args:
            initial_pose: ``geometry_msgs/PoseStamped`` in ``map``.
        """
        self.initial_pose = initial_pose
        self.initial_pose_received = True
        self.debug("setInitialPose: no localiser to initialise (odometry starts in map)")

    def goToPose(self, pose, behavior_tree=""):
        """Send the robot to one pose.

        Args:
            pose: ``geometry_msgs/PoseStamped`` in ``map`` (an empty ``frame_id`` means ``map``).
            behavior_tree: ignored (the swarm navigator has no behaviour trees).

        Returns:
            True if the goal was sent; False if it was rejected (a pose in another frame or
            with NaN/inf, or, when the node is spun by an executor, no navigator subscribed).
        """
        x, y = pose.pose.position.x, pose.pose.position.y
        self.info(f"Navigating to goal: {x} {y}...")
        return self._start_task("goToPose", [pose], behavior_tree)

    def goThroughPoses(self, poses, behavior_tree=""):
        """Send the robot through several poses, in order.

        The poses are sent one after the other; the task succeeds when the last is reached.

        Args:
            poses: list of ``geometry_msgs/PoseStamped`` in ``map``.
            behavior_tree: ignored.

        Returns:
            True if the task was started, False if rejected (see :meth:`goToPose`).
        """
        self.info(f"Navigating with {len(poses)} goals....")
        return self._start_task("goThroughPoses", poses, behavior_tree)

    def followWaypoints(self, poses):
        """Visit waypoints in order; ``getFeedback().current_waypoint`` says which is next.

        Args:
            poses: list of ``geometry_msgs/PoseStamped`` in ``map``.

        Returns:
            True if the task was started, False if rejected (see :meth:`goToPose`).
        """
        self.info(f"Following {len(poses)} goals....")
        return self._start_task("followWaypoints", poses)

    def cancelTask(self):
        """Cancel the running task (``<ns>/navigator/cancel``).

        The task ends as ``CANCELED`` when the navigator reports the goal canceled (or as
        ``SUCCEEDED`` / ``FAILED`` if it ended before the request arrived, as in nav2).  After
        ROS has been shut down (a Ctrl-C in a route script) nothing can be sent: a warning says
        so and the navigator keeps the goal until it ends or is replaced.
        """
        with self._cond:
            task = self._task
            if task is None or task.result is not None:
                return
            if not self.context.ok():
                self.warn(f"ROS is shut down: cannot cancel goal {task.goal_id}; the navigator "
                          "keeps it")
                return
            task.cancel_requested = True
        self.info("Canceling current task.")
        if not self._in_executor() and not self._cancel_client.service_is_ready():
            self._spin_until(self._cancel_client.service_is_ready, self.cancel_timeout)
        if not self._cancel_client.service_is_ready():
            self.error("navigator/cancel is not available; the goal keeps running")
            return
        future = self._cancel_client.call_async(Trigger.Request())
        with self._cond:
            task.cancel_future = future
        if not self._in_executor():
            self._spin_until(lambda: future.done() and task.result is not None,
                             self.cancel_timeout)
            with self._cond:
                self._check_cancel_response(task)

    def isTaskComplete(self):
        """Whether the task has ended; waits up to 0.1 s for it, as nav2's.

        Returns:
            True if the task ended (or there is none), False while it runs.
        """
        with self._cond:
            task = self._task
        if task is None:
            return True
        self._spin_until(lambda: task.result is not None, 0.1)
        return task.result is not None

    def getFeedback(self):
        """The running task's latest :class:`NavFeedback`, or None before the first status."""
        return self.feedback

    def getResult(self):
        """The last task's :class:`TaskResult` (``UNKNOWN`` while it runs or if none)."""
        return self._result

    def waitUntilNav2Active(self, navigator="bt_navigator", localizer="amcl", timeout_sec=None):
        """Block until the robot's navigator is up: its ``nav_status`` has been received (any
        state; ``IDLE`` means ready) and it subscribes ``goal_pose``.

        Args:
            navigator: ignored (nav2's lifecycle node name).
            localizer: ignored (the swarm has no localiser).
            timeout_sec: [s] wall; ``None`` waits forever, as nav2's.

        Returns:
            True once the navigator answered, False if ``timeout_sec`` passed first.
        """
        topic = self._status_reader.subscription.topic_name
        if not self._nav_status_received:
            self.info(f"Waiting for the navigator on {topic}...")
        if not self._spin_until(lambda: self.navigator_ready, timeout_sec):
            within = "" if timeout_sec is None else f" within {timeout_sec:g} s"
            self.error(f"No navigator answered on {topic}{within}")
            return False
        self.info("Nav2 is ready for use!")
        return True

    def lifecycleStartup(self):
        """No-op: the swarm navigator is not a lifecycle node (it is up when it publishes)."""
        self.debug("lifecycleStartup: nothing to start")

    def lifecycleShutdown(self):
        """No-op: the swarm navigator is not a lifecycle node."""
        self.debug("lifecycleShutdown: nothing to shut down")

    def info(self, msg):
        self.get_logger().info(msg)

    def warn(self, msg):
        self.get_logger().warn(msg)

    def error(self, msg):
        self.get_logger().error(msg)

    def debug(self, msg):
        self.get_logger().debug(msg)

    # ------------------------------------------------------------------ non-blocking extras

    @property
    def navigator_ready(self) -> bool:
        """True once a ``nav_status`` was received and a navigator subscribes ``goal_pose``."""
        return (self._nav_status_received and self._goal_pub is not None
                and self._goal_pub.get_subscription_count() > 0)

    @property
    def nav_status_received(self) -> bool:
        """True once any ``nav_status`` was received from the navigator."""
        return self._nav_status_received

    def not_ready_reason(self, waited_s: float) -> tuple[int, str]:
        """Why :attr:`navigator_ready` is still False after ``waited_s`` [s] wall, for a
        commander that gives up.

        Returns:
            ``(exit code, sentence)``: 2 (:data:`~swarm_common.errors.EXIT_BAD_INPUT`, a wrong
            namespace is the usual cause) when no ``nav_status`` came, with how often its reader
            was made again and how many writers it matched; 1
            (:data:`~swarm_common.errors.EXIT_RUNTIME`) when one came but nothing subscribes
            ``goal_pose``.
        """
        ns = self.get_namespace().rstrip("/")
        if self._nav_status_received:
            return EXIT_RUNTIME, (f"the navigator publishes {ns}/nav_status but nothing "
                                  f"subscribes {ns}/goal_pose within {waited_s:g} s")
        writers = self._status_reader.subscription.get_publisher_count()
        return EXIT_BAD_INPUT, (f"no navigator answered on {ns}/nav_status within "
                                f"{waited_s:g} s ({writers} writer(s) matched, the reader "
                                f"made again {self._status_reader.rematches} time(s))")

    @property
    def status_stamp_ns(self) -> int | None:
        """[ns] simulated time of the navigator's latest ``nav_status`` (None before one)."""
        return self._status_stamp_ns

    def go_to_pose_at(self, pose, not_before_ns: int) -> bool:
        """``goToPose`` whose goal is stamped no earlier than ``not_before_ns``.

        The navigator applies a goal at its first control tick after the goal's stamp
        (docs/ARCHITECTURE.md, goal handshake), so a goal stamped ahead takes effect at a known
        simulated time when it arrives before that tick: how a coordinator hands a freed
        workstation to a waiting robot reproducibly (:mod:`swarm_commander.coordinated`).

        Args:
            pose: ``geometry_msgs/PoseStamped`` in ``map``.
            not_before_ns: [ns] simulated time; the goal's stamp is the later of this and the
                usual one (the latest status's ``stamp``).

        Returns:
            As :meth:`goToPose`.
        """
        return self._start_task("goToPose", [pose], not_before_ns=int(not_before_ns))

    def current_goal_id(self) -> str:
        """The id of the goal last sent for the current task (``""`` without one)."""
        with self._cond:
            return self._task.goal_id if self._task is not None else ""

    @property
    def last_status(self) -> NavStatusRecord | None:
        """The latest ``nav_status``, decoded (None before the first)."""
        return self._last_status

    def task_complete(self) -> bool:
        """``isTaskComplete`` without waiting or spinning, for use inside callbacks."""
        with self._cond:
            return self._task is None or self._task.result is not None

    # ------------------------------------------------------------------ internals

    def _start_task(self, kind, poses, behavior_tree="", not_before_ns=0):
        poses = list(poses)
        if behavior_tree:
            self.debug("behavior_tree is ignored: the swarm navigator has no behaviour trees")
        if not poses:
            self.error(f"{kind}: no poses given; rejected")
            return False
        for i, pose in enumerate(poses):
            problem = _pose_problem(pose)
            if problem:
                self.error(f"{kind}: pose {i} rejected: {problem}")
                return False
        if not self._wait_for_navigator():
            self.get_logger().error(
                f"{kind}: no navigator subscribes {self.get_namespace().rstrip('/')}/goal_pose;"
                " rejected",
                throttle_duration_sec=5.0)
            return False
        with self._cond:
            self._task = _Task(kind, poses, not_before_ns=not_before_ns)
            self._result = TaskResult.UNKNOWN
            self.feedback = None
            self._send_current()
        return True

    def _wait_for_navigator(self) -> bool:
        """Wait (spinning) for a ``goal_pose`` subscriber, as nav2 waits for its action server;
        without waiting when spun by an executor elsewhere."""
        if self._goal_pub is None:
            return False
        while True:
            # Ctrl-C may shut the context down while a callback runs this: then the publisher's
            # context is invalid and rclpy raises RCLError instead of counting.
            if not self.context.ok():
                return False
            try:
                if self._goal_pub.get_subscription_count() > 0:
                    return True
            except RCLError:
                if not self.context.ok():
                    return False
                raise
            if self._in_executor():
                return False
            self.info(f"{self._goal_pub.topic_name} subscriber not available, waiting...")
            self._spin_until(lambda: self._goal_pub.get_subscription_count() > 0, 1.0)

    def _send_current(self):
        """The one place a goal is sent: publish the task's current pose with a fresh stamp."""
        task = self._task
        pose = task.poses[task.index]
        msg = PoseStamped()
        msg.header.frame_id = MAP_FRAME
        base = self._status_stamp_ns
        if base is None:
            base = self.get_clock().now().nanoseconds
        stamp_ns = max(base, self._last_stamp_ns + 1, task.not_before_ns)
        self._last_stamp_ns = stamp_ns
        sec, nanosec = divmod(stamp_ns, NS_PER_S)
        msg.header.stamp = Time(sec=sec, nanosec=nanosec)
        msg.pose = pose.pose
        task.goal_id = format_stamp(sec, nanosec)
        task.sent_wall = time.monotonic()
        task.seen = False
        task.sample = None
        self._sent_ids.append(task.goal_id)
        self._goal_pub.publish(msg)
        self.debug(f"sent goal {task.goal_id} ({task.index + 1}/{len(task.poses)})")

    def _on_nav_status(self, msg: DiagnosticStatus):
        status = decode({kv.key: kv.value for kv in msg.values}, msg.message)
        state, goal_id = status.state, status.goal_id
        ended = None
        first = not self._nav_status_received
        with self._cond:
            if status.stamp_ns is not None:
                self._status_stamp_ns = status.stamp_ns
            self.last_nav_status = msg
            self._last_status = status
            self._nav_status_received = True
            task = self._task
            if task is not None and task.result is None:
                self._check_cancel_response(task)
            if task is not None and task.result is None:
                if goal_id == task.goal_id and state != NavState.IDLE:
                    self._on_own_status(task, status)
                elif state == NavState.IDLE and status.pending_goal_id != task.goal_id:
                    self._on_idle(task)
                elif task.seen and goal_id not in self._sent_ids:
                    reason = f"goal {task.goal_id} was replaced by goal {goal_id!r}"
                    self.warn(reason)
                    self._finish(task, TaskResult.FAILED, reason)
                if task.result is not None:
                    ended = task.result
            self._cond.notify_all()
        if first and self.on_first_status is not None:
            self.on_first_status()
        if ended is not None and self.on_task_complete is not None:
            self.on_task_complete(ended)

    def _on_own_status(self, task: _Task, status: NavStatusRecord):
        task.seen = True
        self._update_feedback(task, status)
        result = _RESULT_OF.get(status.state)
        if result is None:
            return
        last = task.index == len(task.poses) - 1
        if result == TaskResult.SUCCEEDED and not last:
            if task.cancel_requested:
                self._finish(task, TaskResult.CANCELED)
                return
            task.done_time += status.navigation_time or 0.0
            task.done_recoveries += status.recoveries or 0
            task.index += 1
            self._send_current()
            self.feedback.current_waypoint = task.index
            self.feedback.number_of_poses_remaining = len(task.poses) - task.index
            return
        self._finish(task, result)

    def _on_idle(self, task: _Task):
        """The navigator is idle while our goal should run: it lost the goal (restart).

        Once the navigator has taken our goal (``task.seen``), an ``IDLE`` can only come from a
        restarted navigator: the goal is sent again at once, stamped with that status, so the
        same run gives the same goal at the same tick. Before, a stale ``IDLE`` (published before
        the goal arrived) is told apart by waiting :attr:`resend_after` wall seconds; an ``IDLE``
        that names our goal as pending (``pending_goal_id``) says it is there."""
        if task.cancel_requested:
            self._finish(task, TaskResult.CANCELED)
        elif task.seen or time.monotonic() - task.sent_wall > self.resend_after:
            self.warn(f"navigator is idle, not driving to goal {task.goal_id}; sending it again")
            self._send_current()

    def _check_cancel_response(self, task: _Task):
        future = task.cancel_future
        if future is None or not future.done() or task.result is not None:
            return
        response = future.result()
        if response is not None and not response.success and not task.seen:
            # The navigator never started our goal and has nothing to cancel.
            self._finish(task, TaskResult.CANCELED, "canceled before the navigator started it")

    def _finish(self, task: _Task, result: TaskResult, reason: str = ""):
        if reason:
            self.feedback = self.feedback or NavFeedback(goal_id=task.goal_id)
            self.feedback.reason = reason
        task.result = result
        self._result = result
        self._cond.notify_all()

    def _update_feedback(self, task: _Task, status: NavStatusRecord):
        distance = status.distance_remaining or 0.0
        nav_time = status.navigation_time or 0.0
        if task.sample is not None and nav_time > task.sample[0]:
            speed = (task.sample[1] - distance) / (nav_time - task.sample[0])
            task.speed = max(0.0, 0.5 * task.speed + 0.5 * speed)
        task.sample = (nav_time, distance)
        ahead = [_xy(p) for p in task.poses[task.index:]]
        distance += sum(math.dist(a, b) for a, b in zip(ahead, ahead[1:], strict=False))
        eta = distance / task.speed if task.speed > 1e-3 else 0.0
        self.feedback = NavFeedback(
            distance_remaining=distance,
            navigation_time=_duration(task.done_time + nav_time),
            estimated_time_remaining=_duration(eta),
            number_of_recoveries=task.done_recoveries + (status.recoveries or 0),
            number_of_poses_remaining=len(task.poses) - task.index,
            current_waypoint=task.index,
            state=status.state or "",
            goal_id=task.goal_id,
            holding_time=status.holding_time or 0.0,
            reason=status.reason,
            goal=status.goal,
        )

    def _in_executor(self) -> bool:
        """True if an executor other than our own spins this node (e.g. in another thread)."""
        executor = self.executor
        return (executor is not None and executor is not self._own_executor
                and self in executor.get_nodes())

    def _spin_until(self, predicate, timeout_sec) -> bool:
        """Spin (or, if spun elsewhere, wait) until ``predicate()`` or ``timeout_sec`` [s]."""
        deadline = math.inf if timeout_sec is None else time.monotonic() + timeout_sec
        if not self.context.ok():  # shut down (Ctrl-C): nothing more will arrive
            return bool(predicate())
        if self._in_executor():
            with self._cond:
                while not predicate() and time.monotonic() < deadline:
                    self._cond.wait(min(0.05, deadline - time.monotonic()))
            return bool(predicate())
        if self._own_executor is None:
            self._own_executor = SingleThreadedExecutor(context=self.context)
        executor = self._own_executor
        executor.add_node(self)
        try:
            while not predicate() and self.context.ok():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                executor.spin_once(timeout_sec=min(remaining, 0.1))
        finally:
            executor.remove_node(self)
        return bool(predicate())


def _pose_problem(pose) -> str:
    """Why a goal pose cannot be sent, or ``""``."""
    if not isinstance(pose, PoseStamped):
        return f"expected geometry_msgs/PoseStamped, got {type(pose).__name__}"
    if pose.header.frame_id not in ("", MAP_FRAME, "/" + MAP_FRAME):
        return f"frame '{pose.header.frame_id}' is not '{MAP_FRAME}'"
    p, q = pose.pose.position, pose.pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z, q.x, q.y, q.z, q.w)):
        return "NaN or inf in the pose"
    return ""


def _duration(seconds: float) -> Duration:
    ns = max(0, round(seconds * NS_PER_S))
    sec, nanosec = divmod(ns, NS_PER_S)
    return Duration(sec=sec, nanosec=nanosec)


def _xy(pose: PoseStamped) -> tuple[float, float]:
    return (pose.pose.position.x, pose.pose.position.y)
