"""``swarm-nav``: the navigator node ``/<ns>/navigator`` (docs/reference/contract.md#s3, #s5).

A thin ROS 2 shell around :class:`swarm_nav.core.NavigatorCore`: it converts messages to arrays,
declares the parameters of :func:`swarm_nav.config.flat_defaults` and answers the simulator's
synchronous control loop (docs/ARCHITECTURE.md): every ``odom`` tick gets exactly one
``cmd_vel`` stamped with that tick (in a group process, an entry in the group's batch of
answers); on a lidar tick (one ``scan_time`` after the last scan) the
answer waits until that tick's scan has arrived, so a run does not depend on message order.

Nothing is shared with any other robot's navigator: it knows the others only through its scan.
Several navigators may share a process and an executor (:mod:`swarm_up.group`).

Usage: ``swarm-nav --ros-args -r __ns:=/Srobot3 --params-file RUN/params/Srobot3.yaml``.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.experimental import EventsExecutor
from rclpy.node import Node

from swarm_common.cdr import (
    PathWriter,
    TwistStampedWriter,
    diagnostic_status,
    odom_pose,
    scan_ranges,
)
from swarm_common.errors import InputError
from swarm_common.geometry import quaternion_to_yaw, transform_points
from swarm_common.lockstep import COMING, NONE_COMING, GoalHandshake, poll_period
from swarm_common.nav_status import OUTCOMES, TERMINAL, NavState, NavStatusRecord, encode, level_of
from swarm_common.stamps import NS_PER_S, format_stamp
from swarm_nav import jit
from swarm_nav.config import NavigatorConfig, flat_defaults
from swarm_nav.core import NavigatorCore
from swarm_nav.holding import holding_sites_from_poi, site_kinds_from_poi
from swarm_ros.messages import stamp_ns
from swarm_ros.navigator import navigator_interface
from swarm_ros.session import node_session, spin_forever
from swarm_scene.occupancy import OccupancyMap

STATUS_PERIOD_NS = NS_PER_S // 2  # nav_status at 2 Hz simulated, and on every change of state
STATUS_REPEAT_S = 1.0  # [s] wall: while a tick waits for the next goal, the status again
# Parameters that describe the robot and its world rather than an algorithm.
_CONTEXT_PARAMS = {
    "robot": ("turtlebot3_waffle", "-", "robot name under robots/ or a .urdf/.xacro path: the "
              "footprint and the lidar mounting come from it"),
    "poi_file": ("", "-", "the world's points-of-interest YAML (workstations and their holding "
                 "spots); empty: hold near the goal"),
    "map_yaml_path": ("", "-", "a map_server YAML to use instead of /map; empty: /map"),
    "robot_name": ("", "-", "the robot's namespace without '/', for logs (default: the node's)"),
    "wait_for_commander": (False, "-", "the commander is a party of the lockstep (swarm-up "
                           "--commanders): the first answer to the simulator waits for a "
                           "goal_pose publisher to connect, and no wait for the commander has a "
                           "wall-clock limit (swarm_common.lockstep)"),
    "hold_goal_end": (False, "-", "the answer to the tick at which a goal ended waits for the "
                      "commander's word: a goal, a cancel (no goal coming) or navigator/"
                      "goal_coming (swarm-up --coordination centralized)"),
    "wait_for_status_readers": (0, "-", "hold the first answer to the simulator until nav_status "
                                "has this many readers (swarm-up: its metrics listener and the "
                                "commander), so that a restarted navigator's first statuses reach "
                                "them all"),
    "wait_for_cmd_vel_readers": (0, "-", "hold the first answer to the simulator until cmd_vel "
                                 "has this many readers (swarm-up: the simulator, and its "
                                 "recorder when it records cmd_vel), so that no reader misses "
                                 "the first commands"),
    "wait_for_plan_readers": (0, "-", "hold the first answer to the simulator until plan has "
                              "this many readers (swarm-up: its recorder when it records plan): "
                              "the plan is built only while it has a reader, so a reader matched "
                              "after the run's last change would get none"),
    "goal_wait_timeout": (0.5, "s", "a commander outside the lockstep (wait_for_commander "
                          "false, e.g. a user's route script): wall time the first tick after "
                          "a goal ended may wait for its next goal; a wait that times out makes "
                          "the run irreproducible and is counted (nav_status goal_wait_timeouts)"),
}


def goal_id_of(stamp) -> str:
    """The goal id (:mod:`swarm_common.nav_status`): the text of the goal's stamp."""
    return format_stamp(stamp.sec, stamp.nanosec)


def occupancy_from_msg(msg: OccupancyGrid) -> OccupancyMap:
    """Convert ``nav_msgs/OccupancyGrid`` to an :class:`OccupancyMap`.

    Raises:
        ValueError: the grid's size does not match its data, or its resolution is not positive.
    """
    info = msg.info
    w, h = int(info.width), int(info.height)
    if w <= 0 or h <= 0 or len(msg.data) != w * h:
        raise ValueError(f"{w} x {h} cells but {len(msg.data)} values")
    if not (info.resolution > 0.0 and math.isfinite(info.resolution)):
        raise ValueError(f"resolution {info.resolution}")
    q = info.origin.orientation
    origin = np.array([info.origin.position.x, info.origin.position.y,
                       quaternion_to_yaw(q.x, q.y, q.z, q.w)])
    if not np.all(np.isfinite(origin)):
        raise ValueError("non-finite origin")
    data = np.frombuffer(bytes(np.asarray(msg.data, dtype=np.int8)), dtype=np.int8)
    return OccupancyMap(data=data.reshape(h, w).copy(), resolution=float(info.resolution),
                        origin=origin)


class NavigatorNode(Node):
    """The navigator of one robot.

    Args:
        namespace: the robot's namespace (``"/Srobot3"``); None takes it from ``--ros-args``.
        fed: its odometry and scans come from its group process (:meth:`take_odom`,
            :meth:`take_scan`, :mod:`swarm_up.feed`), not from subscriptions.
        **kwargs: passed to :class:`rclpy.node.Node` (``context``, ``cli_args``, ...).

    Raises:
        InputError: a parameter value is invalid, or the robot or points of interest do not load.
    """

    def __init__(self, namespace: str | None = None, fed: bool = False, **kwargs):
        if namespace is not None:
            kwargs["namespace"] = namespace
        super().__init__("navigator", **kwargs)
        # Parameters.
        self._flat_names = []
        for name, info in flat_defaults().items():
            self.declare_parameter(name, info.default, ParameterDescriptor(
                description=f"[{info.unit}] {info.description}"))
            self._flat_names.append(name)
        for name, (default, unit, text) in _CONTEXT_PARAMS.items():
            self.declare_parameter(name, default, ParameterDescriptor(
                description=f"[{unit}] {text}", read_only=True))
        self.cfg = NavigatorConfig.from_flat(self._flat_values())
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # State.
        self.ns = (self.get_parameter("robot_name").value
                   or self.get_namespace().strip("/") or "robot")
        robot, sites = self._load_context()
        self.lidar = robot.lidar
        # cmd_vel goes out every tick: written as CDR bytes (swarm_common.cdr), no message object
        self._cmd_writer = TwistStampedWriter(f"{self.ns}/base_footprint")
        self._batch_name = self.get_namespace().strip("/")  # its name in a batch of answers
        self._plan_writer = PathWriter("map")
        self.core = NavigatorCore(self.cfg, robot.footprint, *sites)
        took = jit.warm_up()  # before the first tick needs the compiled kernels (once a process)
        if took > 2.0:
            self.get_logger().info(f"compiled the navigator's kernels in {took:.1f} s "
                                   "(once per machine; later runs load them)")
        self.has_map = False
        self.ready = False
        self._scan: tuple[int, np.ndarray] | None = None  # (stamp, ranges) of the latest scan
        self._scan_meta: tuple[float, float, float, float] | None = None
        self._tick_ns = round(self.cfg.control_period * NS_PER_S)
        self._lidar_every = max(1, round(1.0 / (self.lidar.rate_hz * self.cfg.control_period)))
        self._pending: Odometry | None = None
        self._goals: list[tuple[int, np.ndarray, str]] = []  # (stamp, pose, id) awaiting a tick
        goal_wait_timeout = float(self.get_parameter("goal_wait_timeout").value)
        if not (math.isfinite(goal_wait_timeout) and goal_wait_timeout >= 0.0):
            raise InputError(f"parameter goal_wait_timeout: must be a finite number >= 0 "
                             f"[s], got {goal_wait_timeout}")
        self.handshake = GoalHandshake(
            lockstep=bool(self.get_parameter("wait_for_commander").value),
            hold_goal_end=bool(self.get_parameter("hold_goal_end").value),
            timeout_s=goal_wait_timeout)
        self._held: tuple[int, float, float, bytes] | None = None  # t, v, w, cmd_vel bytes:
        # a computed answer awaiting its commander
        self.answers = None
        """A group process's batch of answers (:class:`swarm_up.answers.AnswerBatch`), or None:
        answer on ``cmd_vel`` alone."""
        self._last_t: int | None = None  # the last tick answered (a re-published one is not)
        self._wait_timer = None  # polls a held tick (wall clock: it only reports and checks)
        self._wait_period = 0.0  # [s] wall, the period of _wait_timer
        self._wait_t = 0
        self._said_at = 0.0  # [s] monotonic: when a waiting tick last said its status again
        self._answered = False
        self._goal_topic = f"{self.get_namespace().rstrip('/')}/goal_pose"
        self._last_status: tuple | None = None
        self._last_status_ns = -STATUS_PERIOD_NS
        self._path_version = -1
        self._now_ns = 0
        self._warned: dict[str, float] = {}
        # Publishers, subscribers, service.
        self.cmd_pub, self.plan_pub, self.status_pub, self._goal_sub = navigator_interface(
            self, self._on_map, None if fed else self._on_scan, None if fed else self._on_odom,
            self._on_goal_pose, self._on_cancel, self._on_goal_coming)
        map_yaml = self.get_parameter("map_yaml_path").value
        if map_yaml:
            from swarm_scene.map_io import load_map

            self._set_map(load_map(map_yaml))

    # -- parameters ----------------------------------------------------------------------------

    def _flat_values(self) -> dict:
        return {name: self.get_parameter(name).value for name in self._flat_names}

    def _on_set_parameters(self, params) -> SetParametersResult:
        flat = self._flat_values()
        for p in params:
            if p.name in flat:
                flat[p.name] = p.value
        try:
            NavigatorConfig.from_flat(flat)
        except InputError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _load_context(self):
        from swarm_scene.poi import load_poi
        from swarm_scene.robot_model import load_robot

        robot = load_robot(self.get_parameter("robot").value)
        poi_file = self.get_parameter("poi_file").value
        poi = load_poi(poi_file) if poi_file else None
        sites = holding_sites_from_poi(poi), site_kinds_from_poi(poi)
        # The DWA checks the robot's own footprint (NavigatorCore); the costmap inflates by
        # robot_radius and the DWA samples up to max_vel_*: say when a params file made for
        # another robot does not fit this one (swarm-up writes fitted ones, rundir.robot_params).
        cfg, lim = self.cfg, robot.limits
        misfits = [f"robot_radius {cfg.costmap.robot_radius:g} m (the model's "
                   f"{robot.costmap_radius:g} m)"] if not math.isclose(
            cfg.costmap.robot_radius, robot.costmap_radius, abs_tol=1e-6) else []
        misfits += [f"{name} {ours:g} (the model's limit {theirs:g})" for name, ours, theirs in (
            ("max_vel_x", cfg.dwa.max_vel_x, lim.max_vel_x),
            ("max_vel_theta", cfg.dwa.max_vel_theta, lim.max_vel_theta))
            if ours > theirs + 1e-9]
        if misfits:
            self.get_logger().warning(f"parameters made for another robot than "
                                      f"{robot.name}?: {'; '.join(misfits)}")
        return robot, sites

    # -- helpers -------------------------------------------------------------------------------

    def _warn(self, key: str, text: str) -> None:
        """A warning at most every 5 s (wall) per kind of problem."""
        now = time.monotonic()
        if now - self._warned.get(key, -math.inf) >= 5.0:
            self._warned[key] = now
            self.get_logger().warning(text)

    def _set_map(self, occ: OccupancyMap) -> None:
        self.core.set_map(occ)
        self.has_map = True

    # -- callbacks -----------------------------------------------------------------------------

    def _on_map(self, msg: OccupancyGrid) -> None:
        if self.get_parameter("map_yaml_path").value:
            return
        if msg.header.frame_id not in ("map", "/map"):
            self._warn("map", f"dropped /map in frame '{msg.header.frame_id}', expected 'map'")
            return
        try:
            occ = occupancy_from_msg(msg)
        except ValueError as exc:
            self._warn("map", f"dropped a malformed /map: {exc}")
            return
        self._set_map(occ)
        self._release()

    def _on_scan(self, buf: bytes) -> None:
        try:
            t, angle_min, inc, range_min, range_max, ranges = scan_ranges(buf)
        except ValueError as exc:
            self._warn("scan", f"dropped a malformed scan ({exc})")
            return
        self.take_scan(t, (angle_min, inc, range_min, range_max), ranges)

    def take_scan(self, t: int, meta: tuple[float, float, float, float],
                  ranges: np.ndarray) -> None:
        """The scan of tick ``t`` [ns]: ``meta`` (angle_min [rad], angle_increment [rad],
        range_min [m], range_max [m]) and (B,) float32 ranges [m] in the lidar's frame (REP
        117), as :func:`swarm_common.cdr.scan_ranges` reads them."""
        if len(ranges) == 0 or not all(math.isfinite(x) for x in meta) or meta[3] <= 0.0:
            self._warn("scan", "dropped a malformed scan (no beams or non-finite geometry)")
            return
        self._scan = (t, ranges)
        self._scan_meta = meta
        self._release()

    def _is_lidar_tick(self, t: int) -> bool:
        """The simulator scans every ``1 / (rate_hz * control_period)`` ticks, from tick 0."""
        return round(t / self._tick_ns) % self._lidar_every == 0

    def _on_odom(self, buf: bytes) -> None:
        try:
            odom = odom_pose(buf)  # (stamp [ns], x, y, yaw, v, w)
        except ValueError as exc:
            self._warn("odom", f"dropped a malformed odometry message ({exc})")
            return
        self.take_odom(odom)

    def take_odom(self, odom: tuple[int, float, float, float, float, float]) -> None:
        """The odometry of a tick, ``(stamp [ns], x [m], y [m], yaw [rad], v [m/s], w [rad/s])``
        as :func:`swarm_common.cdr.odom_pose` reads it: the tick is answered once it may be
        (:meth:`_release`)."""
        if self._last_t is not None and odom[0] <= self._last_t:
            return  # a tick re-published (the start gate, a rejoin) that was answered already
        self._pending = odom  # a newer tick replaces one still waiting (that one is late anyway)
        self._release()

    def _release(self) -> None:
        """Answer what may be answered (docs/ARCHITECTURE.md, "Synchronous control loop"):

        - a computed answer held for the commander's word on the goal that ended
          (``hold_goal_end``, :mod:`swarm_common.lockstep` wait 1) goes once the word came;
        - the very first answer waits for the map, and for what the start gate asks
          (:meth:`_start_gate`): a navigator restarted mid-run (a fault) must not answer its
          first ticks blind, or when it becomes ready would depend on the wall clock;
        - on a lidar tick, that tick's scan has arrived (a lost scan makes the tick late);
        - the first tick answered after a goal ended waits for the commander's next goal
          (:mod:`swarm_common.lockstep` wait 2).

        No wait has a wall-clock limit, but for a commander outside the lockstep (wait 2 then
        lasts ``goal_wait_timeout``); a wait is polled (:meth:`_on_wait_poll`) to notice a
        commander that left and to report a stall.
        """
        if self.answers is not None:
            self.answers.busy()
        if self._held is not None:
            t, v, w, cmd = self._held
            if self.handshake.holds_end(t, bool(self._goals), self._commander_connected):
                self._hold(t)
                return
            self._held = None
            self._answer(t, v, w, cmd)
        odom = self._pending
        if odom is None:
            self._unhold()
            return
        t = odom[0]
        if not self._answered and self._start_gate(t):
            self._hold(t)
            return
        if self._is_lidar_tick(t) and (self._scan is None or self._scan[0] != t):
            return
        if self._answered and self.handshake.awaits_goal(t, bool(self._goals),
                                                         self._commander_connected):
            self._hold(t)
            return
        self._unhold()
        self._pending = None
        self._tick(odom)

    def _commander_connected(self) -> bool:
        return self._goal_sub.get_publisher_count() > 0

    def _start_gate(self, t: int) -> str:
        """What the first answer still waits for (``""``: nothing): the map; a commander
        (``wait_for_commander``); ``wait_for_status_readers`` readers of ``nav_status``;
        ``wait_for_cmd_vel_readers`` readers of ``cmd_vel``; ``wait_for_plan_readers`` readers
        of ``plan``. Without a wall-clock limit: the
        simulator holds the tick meanwhile, so the wait costs wall time, not reproducibility.

        The gate holds even when a goal is already there: a navigator restarted mid-run (a
        kill-nav fault) is a new writer and gets its commander's goal again at once; a reader
        that discovered it only after that goal ended would never see the goal. This gate counts
        the writer's matches only; the reader's side can lag behind, which the histories of
        :data:`swarm_common.topics.CMD_VEL` and :data:`~swarm_common.topics.NAV_STATUS` cover
        (why: docs/HISTORY.md, "The runs behind the internal contract").
        """
        waiting = [] if self.has_map else ["/map"]
        if (self.get_parameter("wait_for_commander").value
                and self._goal_sub.get_publisher_count() == 0):
            waiting.append(f"a commander on {self._goal_topic}")
        for param, pub, topic in (("wait_for_status_readers", self.status_pub, "nav_status"),
                                  ("wait_for_cmd_vel_readers", self.cmd_pub, "cmd_vel"),
                                  ("wait_for_plan_readers", self.plan_pub, "plan")):
            readers = int(self.get_parameter(param).value)
            if pub.get_subscription_count() < readers:
                waiting.append(f"{readers} readers of {topic}")
        return " and ".join(waiting)

    def _hold(self, t: int) -> None:
        """Tick ``t`` waits: poll it on a wall-clock timer (one at a time), less often the
        longer the wait lasts (:func:`swarm_common.lockstep.poll_period`)."""
        self._wait_t = t
        now = time.monotonic()
        self.handshake.waiting(now)
        period = poll_period(self.handshake.waited(now))
        if self._wait_timer is not None and self._wait_period != period:
            self.destroy_timer(self._wait_timer)
            self._wait_timer = None
        if self._wait_timer is None:
            self._wait_period = period
            self._wait_timer = self.create_timer(
                period, self._on_wait_poll, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _unhold(self) -> None:
        self.handshake.released()
        if self._wait_timer is not None:
            self.destroy_timer(self._wait_timer)
            self._wait_timer = None

    def _on_wait_poll(self) -> None:
        t = self._wait_t
        commander = self._commander_connected()
        over, stalled = self.handshake.poll(t, time.monotonic(), commander)
        if over and commander:
            self._warn("goal_wait", f"the commander's next goal did not come within "
                       f"{self.handshake.timeout_s:g} s (wall); tick {t / NS_PER_S:.3f} s "
                       f"answered without it: this run is not reproducible "
                       f"({self.handshake.timeouts} time(s) so far)")
        elif stalled is not None:
            self.get_logger().warning(
                f"tick {t / NS_PER_S:.3f} s has waited {stalled:.0f} s (wall) for "
                f"{self._awaited(t)}; still waiting (a stall costs wall time only)")
        now = time.monotonic()
        if self._answered and self._held is None and now - self._said_at >= STATUS_REPEAT_S:
            # waiting for the next goal: say the status again, so that a commander whose goal
            # went to this navigator's predecessor (killed before it took it) sends it again
            self._said_at = now
            self._publish_status(force=True)
        self._release()

    def _awaited(self, t: int) -> str:
        """What a held tick ``t`` waits for, in words (for the stall report)."""
        if self._held is not None:
            return "the commander's word on the goal that ended"
        if not self._answered:
            return self._start_gate(t) or "its start"
        return "the commander's next goal"

    def _on_goal_pose(self, msg: PoseStamped) -> None:
        p, q = msg.pose.position, msg.pose.orientation
        values = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
        goal_id = goal_id_of(msg.header.stamp)
        if msg.header.frame_id not in ("map", "/map"):
            self._reject(goal_id, f"goal frame '{msg.header.frame_id}' is not 'map'")
            return
        if not all(math.isfinite(v) for v in values):
            self._reject(goal_id, "goal pose has NaN or inf")
            return
        yaw = quaternion_to_yaw(q.x, q.y, q.z, q.w)
        # Applied at the first tick after its stamp (a stamp in the past: the next tick).
        self._goals.append((stamp_ns(msg.header.stamp), np.array([p.x, p.y, yaw]), goal_id))
        self.handshake.goal_arrived()
        # say at once that it is here (pending_goal_id): a coordinated commander confirms a
        # hand-over so (before the first tick too: a restarted navigator; the status then has
        # no stamp)
        self._publish_status()
        self._release()

    def _reject(self, goal_id: str, reason: str) -> None:
        self._warn("goal", f"rejected goal {goal_id}: {reason}")
        self.core.cancel(self._now_ns / NS_PER_S)  # a new goal replaces the current one
        self._publish_raw(NavState.ABORTED, goal_id, None, reason)

    def _on_cancel(self, request, response):
        active = self.core.state not in TERMINAL
        self.core.cancel(self._now_ns / NS_PER_S)
        self._publish_status(force=True)
        # A cancel with no goal running says "no next goal is coming": the tick after the goal
        # that ended need not wait for one (a coordinated commander whose robot reached its
        # waiting spot). Answered at that same tick: reproducible.
        if not active and self.handshake.said(NONE_COMING):
            self._release()
        response.success = active
        response.message = "canceled" if active else "no active goal"
        return response

    def _on_goal_coming(self, request, response):
        """``navigator/goal_coming``: the commander has taken in the goal that ended, and its
        next goal is coming (:mod:`swarm_common.lockstep` wait 1 ends, wait 2 begins)."""
        response.success = self.handshake.said(COMING)
        response.message = "waiting for the next goal" if response.success else "no goal ended"
        if response.success:
            self._release()
        return response

    # -- the control tick ----------------------------------------------------------------------

    def _tick(self, odom: tuple[int, float, float, float, float, float]) -> None:
        """One control tick on ``odom`` = :func:`swarm_common.cdr.odom_pose`'s
        ``(stamp [ns], x [m], y [m], yaw [rad], v [m/s], w [rad/s])`` (yaw NaN for a non-finite
        quaternion)."""
        t, x, y, yaw, odom_v, odom_w = odom
        if not all(math.isfinite(v) for v in (x, y, yaw, odom_v, odom_w)):
            self._warn("odom", "dropped odometry with NaN or inf")
            return
        self._now_ns = t
        self._answered = True
        pose = np.array([x, y, yaw])
        now = t / NS_PER_S
        due = [g for g in self._goals if g[0] < t]
        if due:
            self._goals = [g for g in self._goals if g[0] >= t]
            _, goal, goal_id = due[-1]  # a new goal replaces the current one
            self.core.set_goal(goal, goal_id, now)
            self.get_logger().info(
                f"goal {goal_id}: ({goal[0]:.2f}, {goal[1]:.2f}, {goal[2]:.2f})")
        v = w = 0.0
        if self.has_map:
            if self._scan is not None and self._scan[0] == t:
                self.core.on_scan(self._scan_points(pose), now)
            v, w = self.core.step(pose, odom_v, odom_w, now)
            if not (math.isfinite(v) and math.isfinite(w)):
                v = w = 0.0
        cmd = self._cmd_writer.write(t, float(v), float(w))
        self._last_t = t
        self.handshake.answered(t, self.core.state in TERMINAL, self.core.state in OUTCOMES,
                                bool(due))
        if self.has_map and not self.ready:
            self.ready = True
            self.get_logger().info("ready: map and odometry received")
        if self.ready:  # before the answer: a goal's end reaches the commander first
            self._publish_status()
            self._publish_plan()
        if self.handshake.holds_end(t, bool(self._goals), self._commander_connected):
            self._held = (t, float(v), float(w), cmd)
            self._hold(t)
        else:
            self._answer(t, float(v), float(w), cmd)

    def _answer(self, t: int, v: float, w: float, cmd: bytes) -> None:
        """Answer tick ``t`` [ns] with ``v`` [m/s], ``w`` [rad/s] (``cmd``: the ``cmd_vel``
        bytes): on ``cmd_vel``, or in the group's batch (:attr:`answers`), then on ``cmd_vel``
        too only while it has a reader besides the simulator (a recorder, ``ros2 topic
        echo``)."""
        if self.answers is None:
            self.cmd_pub.publish(cmd)
            return
        self.answers.put(self._batch_name, t, v, w)
        if self.cmd_pub.get_subscription_count() > 1:
            self.cmd_pub.publish(cmd)

    def _scan_points(self, pose: np.ndarray) -> np.ndarray:
        """(M, 2) end points in ``map`` of the valid beams of the tick's scan."""
        _, ranges = self._scan
        angle_min, inc, rmin, rmax = self._scan_meta
        r = ranges.astype(float)
        ok = np.isfinite(r) & (r >= rmin) & (r <= rmax)
        a = angle_min + inc * np.flatnonzero(ok)
        r = r[ok]
        mount = self.lidar.pose
        lx, ly = r * np.cos(a + mount[2]) + mount[0], r * np.sin(a + mount[2]) + mount[1]
        return transform_points(pose, np.column_stack((lx, ly)))

    # -- outputs -------------------------------------------------------------------------------

    def _publish_status(self, force: bool = False) -> None:
        key = (*self.core.status_key, self.handshake.timeouts, self._pending_goal_id())
        if not force and key == self._last_status and (
                self._now_ns - self._last_status_ns < STATUS_PERIOD_NS):
            return
        st = self.core.status
        self._last_status = key
        self._last_status_ns = self._now_ns
        self._publish_raw(st.state, st.goal_id, st.goal, st.reason, st)

    def _pending_goal_id(self) -> str:
        return self._goals[-1][2] if self._goals else ""

    def _publish_raw(self, state: NavState, goal_id: str, goal, reason: str, st=None) -> None:
        """Publish a status (:mod:`swarm_common.nav_status`); ``st`` None: no goal figures."""
        record = NavStatusRecord(
            state=state, goal_id=goal_id,
            stamp_ns=self._now_ns if self._last_t is not None else None,
            goal=None if goal is None else (float(goal[0]), float(goal[1]), float(goal[2])),
            distance_remaining=st.distance_remaining if st else 0.0,
            navigation_time=st.navigation_time if st else 0.0,
            recoveries=st.recoveries if st else 0,
            holding_time=st.holding_time if st else 0.0,
            goal_wait_timeouts=self.handshake.timeouts,
            pending_goal_id=self._pending_goal_id(), reason=reason)
        self.status_pub.publish(diagnostic_status(  # CDR bytes: no 13 KeyValue objects
            level_of(state), f"{self.ns}/navigator", state.value, self.ns, encode(record)))

    def _publish_plan(self) -> None:
        """Publish the global plan when it changed and someone reads ``plan``.

        With no reader the message is not even built (at 100 robots that was 2-3 % of a group
        process's CPU); a reader that joins later gets the current plan at the next tick, as the
        plan then differs from the last one published.
        """
        if self.core.path_version == self._path_version:
            return
        if not self.plan_pub.get_subscription_count():
            return
        self._path_version = self.core.path_version
        path = self.core.path
        self.plan_pub.publish(self._plan_writer.write(  # CDR bytes: no PoseStamped objects
            self._now_ns, np.zeros((0, 2)) if path is None else path))


def main(args=None) -> int:
    """Entry point of ``swarm-nav`` (STYLE.md point 7)."""
    argv = sys.argv if args is None else args
    if any(a in ("-h", "--help") for a in argv[1:]) and "--ros-args" not in argv:
        print(__doc__)
        print("Parameters (ros2 param describe /<ns>/navigator NAME):")
        for name, info in flat_defaults().items():
            print(f"  {name} = {info.default!r}  [{info.unit}] {info.description}")
        for name, (default, unit, text) in _CONTEXT_PARAMS.items():
            print(f"  {name} = {default!r}  [{unit}] {text}")
        return 0
    try:
        with node_session(argv) as nodes:
            nodes.append(NavigatorNode())
            executor = EventsExecutor()
            executor.add_node(nodes[0])
            spin_forever(executor, nodes[0].context)
    except InputError as exc:
        print(f"swarm-nav: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
