"""The ROS processes of the messaging baseline (:mod:`swarm_bench.baseline` says what it mirrors).

Three roles, each one process (``python -m swarm_bench.baseline_nodes ROLE --config PATH``)
started by :func:`swarm_bench.baseline.run_baseline`:

- :class:`BaselineSimNode` (``sim``): the simulator's loop (:class:`swarm_sim.loop.SimLoop`) with
  the physics, the ray casting and the collision checks taken out: every control tick ``/clock``,
  the robots' states and, while read, every robot's ``odom`` and ``ground_truth`` and, on lidar
  ticks, a ``scan`` with fixed ranges; then it waits for every active robot's answer stamped with
  that tick (its ``cmd_vel``, or its group's batch), and steps time.
- :class:`BaselineNavigatorNode` and :class:`BaselineCommanderNode` (``group``): a navigator's
  and a commander's topics, types, QoS and rates (``swarm_nav/node.py``,
  ``swarm_commander/robot_navigator.py``), answering each tick at once instead of navigating.
- :class:`BaselineListenerNode` (``listener``): the subscriptions of ``swarm-up``'s metrics node.

Every process loops on ``spin_once`` of an ``EventsExecutor``, as the real nodes do
(docs/ARCHITECTURE.md "Executors").
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time
from pathlib import Path

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.clock import Clock as RclpyClock
from rclpy.clock import ClockType
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger
from trajectory_msgs.msg import MultiDOFJointTrajectory

from swarm_bench.baseline import BaselineConfig
from swarm_commander.cli import CommanderConfig
from swarm_commander.robot_navigator import STATUS_REMATCH_S
from swarm_common import cli, topics
from swarm_common.cdr import (
    ODOM_PUBLISHED,
    SCAN_PUBLISHED,
    LaserScanWriter,
    PathWriter,
    PoseArrayWriter,
    RobotStatesWriter,
    TwistStampedWriter,
    cmd_vel_batch,
    diagnostic_status,
    odom_pose,
    scan_ranges,
    scan_reading,
    twist_stamped,
)
from swarm_common.errors import InputError, run_cli
from swarm_common.events import SPAWN, SpawnEvent
from swarm_common.lockstep import COMING, GoalHandshake, poll_period
from swarm_common.nav_status import TERMINAL
from swarm_common.stamps import NS_PER_S
from swarm_common.supervision import LOST, RobotsLost
from swarm_ros.latched import LatchedReader
from swarm_ros.messages import key_values, occupancy_grid_msg, stamp_ns, time_msg
from swarm_ros.navigator import navigator_interface
from swarm_ros.qos import publisher, subscription
from swarm_ros.robot_topics import RobotTopics, publish_sensors
from swarm_ros.session import node_session, spin_forever
from swarm_sim.loop import SimLoop
from swarm_up.answers import AnswerBatch, spin_batched
from swarm_up.clock import SharedClock
from swarm_up.feed import SensorFeed

STATUS_PERIOD_NS = NS_PER_S // 2  # nav_status at 2 Hz simulated and on every change (as nav)
PROGRESS_EVERY_S = 5.0  # [s] wall between the baseline simulator's progress lines

class _Cpu:
    """This process's CPU time since its traffic began (its first tick, status or clock)."""

    start_s: float | None = None

    @classmethod
    def begin(cls) -> None:
        """Note the start (only the first call counts)."""
        if cls.start_s is None:
            cls.start_s = time.process_time()

    @classmethod
    def line(cls) -> str:
        """``baseline: cpu_s X`` (0 if the traffic never began), parsed by ``run_baseline``."""
        used = 0.0 if cls.start_s is None else time.process_time() - cls.start_s
        return f"baseline: cpu_s {used:.3f}"


def _stamp_text(t_ns: int) -> str:
    sec, nsec = divmod(t_ns, NS_PER_S)
    return f"{sec}.{nsec:09d}"


def _sim_time() -> list[Parameter]:
    return [Parameter("use_sim_time", value=True)]


# ------------------------------------------------------------------------------------ simulator
class StillWorld:
    """The world of the baseline's simulator: robots standing on a 1 m grid, nothing moves, no
    ray casting (every scan the same ranges), no collisions.  It offers what
    :class:`swarm_sim.loop.SimLoop` and the sensor topics read of the engine.

    Args:
        cfg: the baseline's settings (robots, lidar).
    """

    def __init__(self, cfg: BaselineConfig):
        n = len(cfg.robots)
        self.poses = np.array([(i % 10, i // 10, 0.0) for i in range(n)], dtype=float)
        self.v = np.zeros(n)
        self.w = np.zeros(n)
        self.ticks = 0
        self.lidar_every = cfg.lidar_every
        ranges = np.full(cfg.beams, 0.5 * (cfg.range_min + cfg.range_max), np.float32)
        self._scans = [ranges] * n

    def step(self, v, w, held=None) -> list:
        """Advance one tick (nothing moves, nothing collides)."""
        self.ticks += 1
        return []

    def lidar_due(self) -> bool:
        """Whether the lidars scan at this tick (every ``lidar_every`` ticks from tick 0)."""
        return self.ticks % self.lidar_every == 0

    def lidar_due_mask(self) -> np.ndarray:
        return np.full(len(self.poses), self.lidar_due())

    def scans(self) -> list:
        return self._scans


class FixedScans:
    """A group's renderer of the baseline's scans (:class:`swarm_up.feed.SensorFeed`): every
    robot's lidar every ``lidar_every`` ticks, the same ranges as :class:`StillWorld`'s, nothing
    cast and nothing drawn."""

    def __init__(self, cfg: BaselineConfig):
        self.n = len(cfg.robots)
        self.lidar_every = cfg.lidar_every
        self.ranges = np.full(cfg.beams, 0.5 * (cfg.range_min + cfg.range_max), np.float32)

    def due_mask(self, ticks: int) -> np.ndarray:
        return np.full(self.n, ticks % self.lidar_every == 0)

    def scans(self, poses, ticks: int, rows) -> list:
        return [self.ranges] * len(rows)

    def skip(self, ticks: int) -> None:
        pass


class BaselineSimNode(Node):
    """The simulator's control loop (:class:`swarm_sim.loop.SimLoop`, the same tick gate and
    waits as ``swarm-sim``) and its messages, on a :class:`StillWorld`: no physics, ray casting
    or collision checks.

    Args:
        cfg: the baseline's settings.
    """

    def __init__(self, cfg: BaselineConfig):
        super().__init__("swarm_sim_baseline")
        # State.
        self.cfg = cfg
        self.names = list(cfg.robots)
        self._index = {ns: i for i, ns in enumerate(self.names)}
        self.world = StillWorld(cfg)
        self.period_ns = round(NS_PER_S / cfg.control_rate_hz)
        self.loop = SimLoop(self.world, self, self.names, self.period_ns,
                            wait_for=len(self.names))
        self.stop_requested = False
        self.executor_ = None
        self._last_line = 0.0
        # Publishers and subscribers (names, types and QoS of swarm_sim.node).
        self.clock_pub = publisher(self, Clock, topics.CLOCK)
        self.map_pub = publisher(self, OccupancyGrid, topics.MAP)
        self.events_pub = publisher(self, DiagnosticArray, topics.EVENTS)
        self.poses_pub = publisher(self, PoseArray, topics.POSES)
        self.states_pub = publisher(self, PointCloud2, topics.ROBOT_STATES)
        self._states_writer = RobotStatesWriter(len(self.names))
        self._published = np.full(len(self.names), ODOM_PUBLISHED | SCAN_PUBLISHED, np.uint8)
        self._states_resent = -math.inf
        self.robots = [RobotTopics(self, ns, LaserScanWriter(
            f"{ns}/{cfg.lidar_frame}", cfg.angle_min, cfg.angle_max,
            (cfg.angle_max - cfg.angle_min) / max(cfg.beams - 1, 1), 1.0 / cfg.lidar_rate_hz,
            cfg.range_min, cfg.range_max)) for ns in cfg.robots]
        self._cmd_subs = [subscription(
            self, TwistStamped, topics.CMD_VEL, lambda buf, i=i: self._on_cmd_vel(i, buf), ns,
            topics.CMD_VEL_READER_QOS, raw=True) for i, ns in enumerate(cfg.robots)]
        subscription(self, MultiDOFJointTrajectory, topics.CMD_VEL_BATCH,
                     self._on_cmd_vel_batch, qos=topics.CMD_VEL_BATCH_READER_QOS, raw=True)
        subscription(self, DiagnosticStatus, topics.SUPERVISION, self._on_supervision)
        self._poses_writer = PoseArrayWriter("map")
        from swarm_scene.map_io import load_map

        self.map_pub.publish(occupancy_grid_msg(load_map(cfg.map_yaml), time_msg(0)))
        self.events_pub.publish(DiagnosticArray(status=[
            DiagnosticStatus(name=SPAWN, message=f"spawned {ns}", hardware_id=ns,
                             values=key_values(SpawnEvent(ns, float(x), float(y), 0.0,
                                                          float(yaw)).encode()))
            for ns, (x, y, yaw) in zip(cfg.robots, self.world.poses, strict=True)]))

    def _on_cmd_vel(self, i: int, buf: bytes) -> None:
        try:
            stamp, _, v, w = twist_stamped(buf)
        except ValueError:
            return
        if math.isfinite(v) and math.isfinite(w):
            self.loop.gate.answer(i, stamp, v, w, time.monotonic())

    def _on_cmd_vel_batch(self, buf: bytes) -> None:
        try:
            stamp, names, vw = cmd_vel_batch(buf)
        except ValueError:
            return
        now = time.monotonic()
        for ns, (v, w) in zip(names, vw.tolist(), strict=True):
            i = self._index.get(ns)
            if i is not None and math.isfinite(v) and math.isfinite(w):
                self.loop.gate.answer(i, stamp, v, w, now)

    def _on_supervision(self, msg: DiagnosticStatus) -> None:
        if msg.name == LOST:
            word = RobotsLost.decode({kv.key: kv.value for kv in msg.values})
            for ns in word.robots if word is not None else ():
                if ns in self.names:
                    self.loop.lose(self.names.index(ns), word.reason, word.for_good)

    # -- the loop's ports (swarm_sim.loop.Ports), as swarm_sim.node's --------------------------
    def spin(self, timeout_s: float) -> None:
        self.executor_.spin_once(timeout_sec=timeout_s)

    def stopped(self) -> bool:
        return self.stop_requested or not rclpy.ok()

    def log(self, level: str, text: str) -> None:
        print(f"baseline: {text}", file=sys.stderr if level == "warning" else sys.stdout,
              flush=True)

    def cmd_writer(self, i: int) -> bool:
        return self._cmd_subs[i].get_publisher_count() > 0

    def progress_writer(self) -> bool:
        return False  # no recorder

    def reader_matched(self, deadline_s: float) -> bool:
        return True  # no reader awaited

    def publish_tick(self) -> None:
        """``/clock``, every robot's odometry (ground truth while heard) and, on lidar ticks,
        its scan, robot after robot; ``/swarm/poses`` while heard: as ``swarm_sim.node``."""
        t_ns, world = self.loop.gate.t_ns, self.world
        self.clock_pub.publish(Clock(clock=time_msg(t_ns)))
        self._publish_states()
        publish_sensors(self.robots, t_ns, world.poses, world.v, world.w,
                        world.scans() if world.lidar_due() else None, lazy=True)
        if self.poses_pub.get_subscription_count():
            self.poses_pub.publish(self._poses_writer.write(t_ns, world.poses))

    def _publish_states(self) -> None:
        if self.states_pub.get_subscription_count():
            world = self.world
            self.states_pub.publish(self._states_writer.write(
                self.loop.gate.t_ns, world.poses, world.v, world.w, self._published))

    def republish(self, i: int) -> None:
        t_ns, world, robot = self.loop.gate.t_ns, self.world, self.robots[i]
        if world.lidar_due() and robot.scan_pub.get_subscription_count():
            robot.publish_scan(t_ns, world.scans()[i])
        if robot.odom_pub.get_subscription_count():
            robot.publish_odom(t_ns, world.poses[i].tolist(), 0.0, 0.0, truth=False)
        now = time.monotonic()
        if now - self._states_resent > 0.25:  # once a round of re-publishing, as swarm_sim
            self._states_resent = now
            self._publish_states()

    def announce_faults(self, due: list) -> None:
        pass  # the baseline injects none

    def announce_late(self, robots: list[int]) -> None:
        if robots:
            print(f"baseline: late at t = {self.loop.gate.t_ns / NS_PER_S:.1f} s: "
                  + ", ".join(self.names[i] for i in robots), file=sys.stderr, flush=True)

    def stepped(self, events: list) -> None:
        """Once the gate opened: say so, then a progress line every ``PROGRESS_EVERY_S`` wall
        (nothing collides here)."""
        if not self.loop.opened:
            return
        now = time.monotonic()
        if not self._last_line:
            print(f"baseline: all {len(self.names)} robots answering; running "
                  f"{self.cfg.duration_s:g} simulated s", flush=True)
        elif now - self._last_line >= PROGRESS_EVERY_S:
            sim_s = self.loop.gate.t_ns / NS_PER_S
            print(f"baseline: t = {sim_s:.0f} / {self.cfg.duration_s:g} s simulated, "
                  f"RTF {sim_s / max(now - self.loop.opened_at, 1e-9):.2f}", flush=True)
        else:
            return
        self._last_line = now

    # -- life --------------------------------------------------------------------------------
    def run(self, executor) -> tuple[float, bool]:
        """Tick unpaced until ``duration`` simulated seconds.

        Returns:
            ``(wall seconds from the gate's opening to the end, whether the gate opened)``.
        """
        self.executor_ = executor
        self.loop.run(self.cfg.duration_s, rtf=0.0)
        return self.loop.wall_s, self.loop.opened

    def request_stop(self, signum=None, frame=None) -> None:
        """Signal handler: end the loop at its next check."""
        self.stop_requested = True

    def summary(self, wall_s: float, started: bool) -> dict:
        """The baseline's figures (see :mod:`swarm_bench.baseline`)."""
        sim_s = self.loop.gate.t_ns / NS_PER_S
        ticks = self.world.ticks
        return {
            "robots": len(self.names),
            "ticks": ticks,
            "sim_time_s": round(sim_s, 3),
            "wall_time_s": round(wall_s, 3),
            "rtf": round(sim_s / wall_s, 3) if wall_s > 0 else None,
            "robot_ticks_per_s": round(len(self.names) * ticks / wall_s, 1) if wall_s > 0
            else None,
            "late_ticks": int(self.loop.gate.late_ticks.sum()),
            "sim_cpu_s": round(self.loop.cpu_s, 3),
            "started": started,
            "interrupted": self.stop_requested,
        }


def run_sim(cfg: BaselineConfig) -> int:
    """The ``sim`` process: run the loop and write ``cfg.summary_path``.

    Returns:
        0 when the run reached its duration, 130 when stopped, 1 when the gate never opened.
    """
    wall_s, started = 0.0, False
    with node_session(["baseline_sim"], signal_handler_options=SignalHandlerOptions.NO) as nodes:
        node = BaselineSimNode(cfg)
        nodes.append(node)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, node.request_stop)
        executor = EventsExecutor()
        executor.add_node(node)
        try:
            wall_s, started = node.run(executor)
        finally:
            summary = node.summary(wall_s, started)
            Path(cfg.summary_path).write_text(json.dumps(summary, indent=2) + "\n")
            print(f"baseline: simulated {summary['sim_time_s']:.1f} s in {wall_s:.1f} s wall "
                  f"(RTF {summary['rtf']}), late ticks {summary['late_ticks']}", flush=True)
            executor.shutdown()
    if node.stop_requested:
        return 130
    return 0 if started else 1


# ------------------------------------------------------------------------------------ navigator
class BaselineNavigatorNode(Node):
    """A navigator's traffic: answers every tick at once, with a stand-in goal lifecycle.

    A goal becomes ``DRIVING`` at the first tick after its stamp (one ``plan`` of
    ``plan_poses`` poses is published) and ``SUCCEEDED`` ``goal_period_s`` simulated seconds
    later. As the real navigator, the first answer waits for a commander to connect, the answer
    on the first tick after a goal ended waits for the commander's next goal (the same
    :class:`swarm_common.lockstep.GoalHandshake`; its commanders are in the lockstep), and a lidar
    tick is answered only once its scan arrived.

    Args:
        ns: the robot's namespace without ``/``.
        cfg: the baseline's settings.
    """

    def __init__(self, ns: str, cfg: BaselineConfig, fed: bool = False):
        super().__init__("navigator", namespace=f"/{ns}", parameter_overrides=_sim_time())
        # State.
        self.ns = ns
        self._cmd_writer = TwistStampedWriter(f"{ns}/base_footprint")
        self._plan_writer = PathWriter("map")
        self.cfg = cfg
        self.tick_ns = round(NS_PER_S / cfg.control_rate_hz)
        self.goal_period_ns = round(cfg.goal_period_s * NS_PER_S)
        self.has_map = False
        self.answered = False
        self.state = "IDLE"
        self.goal_id = ""
        self.goal_start_ns = 0
        self.path_version = 0
        self.goals_taken = 0
        self.handshake = GoalHandshake(  # the real navigator's handshake
            lockstep=cfg.commanders, timeout_s=cfg.goal_wait_timeout_s)
        self._wait_timer = None
        self._wait_period = 0.0  # [s] wall, the period of _wait_timer
        self._published_path = 0
        self._scan_stamp = -1
        self._ranges = None
        self._pending: Odometry | None = None
        self.answers = None  # the group's AnswerBatch, as swarm_nav.node's
        self._goals: list[tuple[int, str]] = []  # (stamp, id) awaiting a tick
        self._last_status: tuple | None = None
        self._last_status_ns = -STATUS_PERIOD_NS
        self._now_ns = 0
        # Publishers, subscribers, service (swarm_nav.node's).
        self.cmd_pub, self.plan_pub, self.status_pub, self._goal_sub = navigator_interface(
            self, self._on_map, None if fed else self._on_scan, None if fed else self._on_odom,
            self._on_goal_pose, self._on_cancel, self._on_goal_coming)

    def _on_map(self, msg: OccupancyGrid) -> None:
        np.asarray(msg.data, dtype=np.int8)  # the conversion the real navigator makes
        self.has_map = True

    def _on_scan(self, buf: bytes) -> None:
        t, *meta, ranges = scan_ranges(buf)
        self.take_scan(t, tuple(meta), ranges)

    def _on_odom(self, buf: bytes) -> None:
        self.take_odom(odom_pose(buf))  # (stamp [ns], x, y, yaw, v, w)

    def take_scan(self, t: int, meta: tuple, ranges) -> None:
        """A scan, as swarm_nav.node's (from the group's feed, or ``scan``)."""
        self._scan_stamp, self._ranges = t, ranges
        self._release()

    def take_odom(self, odom: tuple) -> None:
        """A tick's odometry, as swarm_nav.node's (from the group's feed, or ``odom``)."""
        self._pending = odom
        self._release()

    def _on_goal_pose(self, msg: PoseStamped) -> None:
        stamp = msg.header.stamp
        self._goals.append((stamp_ns(stamp), _stamp_text(stamp_ns(stamp))))
        self.handshake.goal_arrived()
        self._release()

    def _on_cancel(self, request, response):
        response.success = self.state not in TERMINAL
        self.state = "CANCELED"
        response.message = "canceled"
        return response

    def _on_goal_coming(self, request, response):
        response.success = self.handshake.said(COMING)
        self._release()
        return response

    def _release(self) -> None:
        if self.answers is not None:
            self.answers.busy()
        odom = self._pending
        if odom is None:
            return
        t = odom[0]
        if round(t / self.tick_ns) % self.cfg.lidar_every == 0 and self._scan_stamp != t:
            return
        if self._awaits_goal(t):  # polls the wait, as the real navigator
            now = time.monotonic()
            self.handshake.waiting(now)
            period = poll_period(self.handshake.waited(now))
            if self._wait_timer is not None and self._wait_period != period:
                self.destroy_timer(self._wait_timer)
                self._wait_timer = None
            if self._wait_timer is None:
                self._wait_period = period
                self._wait_timer = self.create_timer(
                    period, lambda: self._on_wait_poll(t),
                    clock=RclpyClock(clock_type=ClockType.STEADY_TIME))
            return
        if self._wait_timer is not None:
            self.destroy_timer(self._wait_timer)
            self._wait_timer = None
        self.handshake.released()
        self._pending = None
        self._tick(odom)

    def _awaits_goal(self, t: int) -> bool:
        if not self.cfg.commanders:
            return False
        if not self.answered:  # the start gate waits for the commander to connect
            return (not any(stamp < t for stamp, _ in self._goals)
                    and not self._commander_connected())
        return self.handshake.awaits_goal(t, bool(self._goals), self._commander_connected)

    def _commander_connected(self) -> bool:
        return self._goal_sub.get_publisher_count() > 0

    def _on_wait_poll(self, t: int) -> None:
        self.handshake.poll(t, time.monotonic(), self._commander_connected())
        self._release()

    def _tick(self, odom: tuple) -> None:
        _Cpu.begin()
        t = odom[0]
        self._now_ns = t
        self.answered = True
        due = [g for g in self._goals if g[0] < t]
        if due:
            self._goals = [g for g in self._goals if g[0] >= t]
            self.goal_id = due[-1][1]
            self.goal_start_ns = t
            self.state = "DRIVING"
            self.path_version += 1
            self.goals_taken += 1
        elif self.state == "DRIVING" and t - self.goal_start_ns >= self.goal_period_ns:
            self.state = "SUCCEEDED"
        if self.answers is None:  # as swarm_nav.node: cmd_vel bytes, or the group's batch
            self.cmd_pub.publish(self._cmd_writer.write(t, 0.0, 0.0))
        else:
            self.answers.put(self.ns, t, 0.0, 0.0)
            if self.cmd_pub.get_subscription_count() > 1:
                self.cmd_pub.publish(self._cmd_writer.write(t, 0.0, 0.0))
        self.handshake.answered(t, self.state in TERMINAL, goal_set=bool(due))
        if self.has_map:
            self._publish_status()
            self._publish_plan()

    def _publish_status(self) -> None:
        key = (self.state, self.goal_id)
        if key == self._last_status and self._now_ns - self._last_status_ns < STATUS_PERIOD_NS:
            return
        self._last_status = key
        self._last_status_ns = self._now_ns
        kv = {"state": self.state, "goal_id": self.goal_id,
              "stamp": _stamp_text(self._now_ns), "goal_x": "1.000", "goal_y": "2.000",
              "goal_yaw": "0.0000", "distance_remaining_m": "1.000",
              "navigation_time_s": f"{(self._now_ns - self.goal_start_ns) / NS_PER_S:.3f}",
              "recoveries": "0", "holding_time_s": "0.000",
              "goal_wait_timeouts": str(self.handshake.timeouts), "reason": ""}
        self.status_pub.publish(diagnostic_status(  # bytes, as swarm_nav.node
            0, f"{self.ns}/navigator", self.state, self.ns, kv))

    def _publish_plan(self) -> None:
        if self.path_version == self._published_path:
            return
        if not self.plan_pub.get_subscription_count():  # as the navigator: only when read
            return
        self._published_path = self.path_version
        n = self.cfg.plan_poses
        self.plan_pub.publish(self._plan_writer.write(  # bytes, as swarm_nav.node
            self._now_ns, np.column_stack((0.05 * np.arange(n), np.zeros(n)))))


# ------------------------------------------------------------------------------------ commander
class BaselineCommanderNode(Node):
    """A commander's traffic: a next goal in answer to each ended goal, stamped as the real one.

    As the real commander (:data:`swarm_commander.robot_navigator.STATUS_REMATCH_S`), its
    ``nav_status`` reader is made again every ``STATUS_REMATCH_S`` wall seconds of spinning until
    the first status arrives: Fast DDS can leave a late-joining transient-local reader without the
    writer's history (eProsima/Fast-DDS#3822), and the navigator, waiting for this commander's
    first goal in the lockstep, publishes nothing new (a CI run's baseline held its second tick
    for 10 minutes so).

    Args:
        ns: the robot's namespace without ``/``.
        status_rematch_s: [s] wall, the reader's remaking period until the first status.
        context: the rclpy context (None: the default one).
    """

    def __init__(self, ns: str, status_rematch_s: float = STATUS_REMATCH_S, context=None):
        super().__init__("commander", namespace=f"/{ns}", parameter_overrides=_sim_time(),
                         context=context)
        self._sent: str | None = None
        self._goals = 0
        # Publishers, subscribers, client and the runner's poll timer (swarm_commander's).
        self._goal_pub = publisher(self, PoseStamped, topics.GOAL_POSE)
        self._status_reader = LatchedReader(self, DiagnosticStatus, topics.NAV_STATUS,
                                            self._on_nav_status, rematch_s=status_rematch_s,
                                            qos=topics.NAV_STATUS_COMMANDER_READER_QOS)
        self._cancel_client = self.create_client(Trigger, topics.CANCEL_SERVICE)
        self.create_timer(CommanderConfig.idle_period, self._on_timer,
                          clock=RclpyClock(clock_type=ClockType.STEADY_TIME))

    @property
    def status_rematches(self) -> int:
        """How many times the ``nav_status`` reader was made again."""
        return self._status_reader.rematches

    def _on_timer(self) -> None:
        pass  # the runner's poll while nothing is due: nothing to retry here

    def _on_nav_status(self, msg: DiagnosticStatus) -> None:
        _Cpu.begin()
        values = {kv.key: kv.value for kv in msg.values}
        state = values.get("state") or msg.message
        if self._sent is not None and values.get("goal_id") != self._sent:
            return  # our goal is not taken yet
        if state not in TERMINAL:
            return
        sec, _, nsec = values.get("stamp", "0.0").partition(".")
        goal = PoseStamped()
        goal.header.frame_id = "map"
        goal.header.stamp = Time(sec=int(sec), nanosec=int(nsec or 0))
        self._goals += 1
        goal.pose.position.x = float(self._goals % 7)
        goal.pose.orientation.w = 1.0
        self._sent = _stamp_text(stamp_ns(goal.header.stamp))
        self._goal_pub.publish(goal)


# ------------------------------------------------------------------------------------- listener
class BaselineListenerNode(Node):
    """The subscriptions of ``swarm-up``'s metrics node, with callbacks that only unpack.

    Args:
        cfg: the baseline's settings.
    """

    def __init__(self, cfg: BaselineConfig):
        super().__init__("swarm_up_metrics")
        self.statuses = 0
        for ns in cfg.robots:
            subscription(self, DiagnosticStatus, topics.NAV_STATUS, self._on_status, ns,
                         topics.NAV_STATUS_METRICS_READER_QOS)
        subscription(self, DiagnosticArray, topics.EVENTS, self._on_events)
        subscription(self, Clock, topics.CLOCK, self._on_clock,
                     qos=topics.CLOCK_METRICS_READER_QOS)

    def _on_status(self, msg: DiagnosticStatus) -> None:
        {kv.key: kv.value for kv in msg.values}  # noqa: B018 - the unpacking the real one does
        self.statuses += 1

    def _on_events(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            {kv.key: kv.value for kv in status.values}  # noqa: B018

    def _on_clock(self, msg: Clock) -> None:
        _Cpu.begin()


# ------------------------------------------------------------------------------------ processes
def _spin(nodes: list[Node], batch: AnswerBatch | None = None) -> None:
    """Spin ``nodes`` until SIGINT/SIGTERM (rclpy's own handlers end the spin), then print the
    navigators' goals and this process's CPU line; ``batch``: the group's answers
    (:func:`swarm_up.answers.spin_batched`)."""
    executor = EventsExecutor()
    for node in nodes:
        executor.add_node(node)
    try:
        if batch is not None:
            spin_batched(executor, nodes[0].context, batch)
        else:
            spin_forever(executor, nodes[0].context)
    finally:
        executor.shutdown()
        for node in nodes:
            if isinstance(node, BaselineNavigatorNode):
                print(f"baseline: {node.ns} took {node.goals_taken} goals, "
                      f"{node.handshake.timeouts} goal-wait timeouts", flush=True)
        print(_Cpu.line(), flush=True)


def run_group(cfg: BaselineConfig, namespaces: list[str], navigators: bool,
              commanders: bool) -> int:
    """The ``group`` process: baseline navigators and/or commanders of ``namespaces``.

    Returns:
        0 (stopped by SIGINT/SIGTERM).
    """
    grouped = len(namespaces) * (int(navigators) + int(commanders)) > 1
    with node_session(["baseline_group"]) as nodes:
        navs = {}
        for ns in namespaces:
            if navigators:  # a group's navigators are fed, as swarm_up.group's
                navs[ns] = BaselineNavigatorNode(ns, cfg, fed=grouped)
                nodes.append(navs[ns])
            if commanders:
                nodes.append(BaselineCommanderNode(ns))
        batch = None
        if grouped:  # a group process: one /clock subscription, the navigators' answers in one
            clock = SharedClock(f"/{namespaces[0]}")  # message, and their sensors fed from the
            batch = AnswerBatch(clock.node)  # robots' states: as swarm_up.group
            for node in nodes:
                clock.adopt(node)
                if isinstance(node, BaselineNavigatorNode):
                    node.answers = batch
            if navs:
                scans = FixedScans(cfg)
                meta = scan_reading(cfg.angle_min, (cfg.angle_max - cfg.angle_min)
                                    / max(cfg.beams - 1, 1), cfg.range_min, cfg.range_max)
                SensorFeed(clock.node, navs, list(cfg.robots), scans, [meta] * len(cfg.robots),
                           round(NS_PER_S / cfg.control_rate_hz), busy=batch.busy)
            nodes.append(clock.node)
        _spin(nodes, batch)
    return 0


def run_listener(cfg: BaselineConfig) -> int:
    """The ``listener`` process: the metrics node's subscriptions.

    Returns:
        0 (stopped by SIGINT/SIGTERM).
    """
    with node_session(["baseline_listener"]) as nodes:
        nodes.append(BaselineListenerNode(cfg))
        _spin(nodes)
    return 0


# ------------------------------------------------------------------------------------- command
PROG = "swarm_bench.baseline_nodes"


def build_parser():
    """``python -m swarm_bench.baseline_nodes {sim,group,listener} --config PATH ...``."""
    p = cli.ArgumentParser(prog=f"python -m {PROG}", allow_abbrev=False,
                           description="One process of the messaging baseline (started by "
                           "swarm_bench.baseline.run_baseline).")
    sub = p.add_subparsers(dest="role", required=True)
    for role in ("sim", "listener", "group"):
        sub.add_parser(role).add_argument("--config", type=Path, required=True)
    group = sub.choices["group"]
    group.add_argument("--namespaces", required=True)
    group.add_argument("--navigators", action="store_true")
    group.add_argument("--commanders", action="store_true")
    return p


def _read_config(path: Path) -> BaselineConfig:
    try:
        return BaselineConfig.decode(path.read_text())
    except OSError as exc:
        raise InputError(f"--config: cannot read '{path}' ({exc.strerror})") from None


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m swarm_bench.baseline_nodes``."""

    def body() -> int:
        args = build_parser().parse_args(argv)
        cfg = _read_config(args.config)
        if args.role == "sim":
            return run_sim(cfg)
        if args.role == "listener":
            return run_listener(cfg)
        names = [n for n in args.namespaces.split(",") if n]
        return run_group(cfg, names, args.navigators, args.commanders)

    return run_cli(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
