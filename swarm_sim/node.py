"""``swarm-sim``: the simulator node ``/swarm_sim`` (docs/reference/contract.md#s2, #s3, #s5).

Loads a Gazebo world and a URDF robot, spawns exactly N robots, and runs the synchronous control
loop of docs/ARCHITECTURE.md: each control tick it publishes ``/clock``, every robot's ``odom``
and ``ground_truth`` and, on lidar ticks, ``scan``; then waits for the ``cmd_vel`` each active
navigator computed from that tick's data (stamped with the tick), applies the commands and steps
the world.  ``--rtf 1`` paces simulated time to the wall clock, ``--rtf 0`` runs unpaced.

Everything runs on one thread: ``EventsExecutor.spin_once`` services the subscriptions between
ticks (publishing from another thread while an ``EventsExecutor`` spins deadlocks this rclpy).
"""

from __future__ import annotations

import argparse
import array
import contextlib
import logging
import math
import signal
import sys
import time
from dataclasses import dataclass

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseArray, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.node import Node, NodeNameNonExistentError
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan

from swarm_common import cli, topics
from swarm_common.cdr import LaserScanWriter, OdometryWriter, PoseArrayWriter, twist_stamped
from swarm_common.errors import InputError, run_cli
from swarm_common.faults import (
    ACK_NAME,
    END,
    EVENT_NAME,
    KILL_COORDINATOR,
    KILL_NAV,
    KILL_ROBOT,
    START,
    FaultAck,
    FaultEvent,
    parse_faults,
)
from swarm_common.sim_summary import CollisionCounts, RobotSummary, SimSummary
from swarm_common.stamps import NS_PER_S
from swarm_common.supervision import LOST, RobotsLost
from swarm_ros.qos import publisher, subscription
from swarm_ros.session import node_session
from swarm_scene.world import describe_skipped
from swarm_sim.standstill import StandstillTracker

# A manual (zero-stamp) command outranks the navigator's answers for this long after it arrived,
# as teleop outranks navigation in twist_mux (its default timeout is 0.5 s).
MANUAL_PRIORITY_S = 0.5  # [s] wall
RESEND_S = 0.5  # [s] wall: a tick not yet answered is published again this often
WRITER_CHECK_S = 0.5  # [s] wall: how often a waiting tick checks its robots still have a writer
READER_GRACE_S = 10.0  # [s] wall: how long the start gate waits for --wait-for-reader to match
ACK_WAIT_S = 1.0  # [s] wall: how long the simulator waits at exit for its last ticks' acks


@dataclass(frozen=True)
class SimSettings:
    """What ``swarm-sim`` was asked to run (command-line flags, validated).

    Attributes:
        world: world name under ``worlds/`` or a path to a ``.world``/``.sdf``.
        robot: robot name under ``robots/`` or a path to a ``.urdf``/``.xacro``; or a mixed
            fleet ``NAME:COUNT,...`` or fleet ``.yaml`` (:mod:`swarm_scene.fleet`).
        swarm_size: number of robots N [-].
        name_prefix: namespace prefix; robot i (1..N) is ``/<prefix><i>``.
        seed: seed of the simulator's random generator (lidar noise).
        rtf: real-time factor to pace to; 0 runs as fast as possible [-].
        duration: simulated seconds to run, or None for until Ctrl-C [s].
        map_path: map_server YAML to publish on ``/map``, or None for the world's map.
        summary: path of the JSON summary written at exit, or None.
        control_rate: control ticks per simulated second [Hz].
        stall_report: wall seconds a tick may wait before the robots it waits for are
            reported (and again every as long); it goes on waiting [s].
        wait_for: robots that must have answered before simulated time starts (the start gate;
            ``swarm-up`` passes N) [-].
        wait_for_reader: a node (``name`` or ``/ns/name``) whose subscriptions to the
            simulator's topics must be matched before simulated time starts (``swarm-up
            --record`` passes its recorder), or None; given up after ``READER_GRACE_S``.
        reader_subscriptions: how many subscriptions of ``wait_for_reader`` to the simulator's
            topics it waits for: those discovered so far are not all of them while discovery
            runs (``swarm-up`` passes the recorder's count,
            :func:`swarm_record.mcap_format.simulator_readers`) [-].
        record_window: hold each tick until the recorder's ``/swarm/record/progress`` is at
            most this many ticks behind (``swarm-up --record`` passes
            :data:`swarm_common.topics.RECORD_WINDOW_TICKS`), or 0 for never; not waited for
            once the progress has no writer (the recorder is gone) [ticks].
        gui: open PyBullet's window.
        faults: the ``--faults`` SPEC (inline syntax or YAML path, :mod:`swarm_common.faults`),
            or None.
    """

    world: str = "slim_blockage"
    robot: str = "turtlebot3_waffle"
    swarm_size: int = 5
    name_prefix: str = "Srobot"
    seed: int = 0
    rtf: float = 1.0
    duration: float | None = None
    map_path: str | None = None
    summary: str | None = None
    control_rate: float = 10.0  # [Hz]
    stall_report: float = 10.0  # [s] wall
    wait_for: int = 0  # [robots]
    wait_for_reader: str | None = None
    reader_subscriptions: int = 1  # [subscriptions]
    record_window: int = 0  # [ticks]
    gui: bool = False
    faults: str | None = None


def _time_msg(t_ns: int) -> Time:
    return Time(sec=t_ns // NS_PER_S, nanosec=t_ns % NS_PER_S)


def _stamp_ns(stamp) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def _kv(key: str, value) -> KeyValue:
    return KeyValue(key=key, value=str(value))


def occupancy_grid_msg(occ, stamp: Time) -> OccupancyGrid:
    """Convert a :class:`swarm_scene.occupancy.OccupancyMap` into ``nav_msgs/OccupancyGrid``."""
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.header.stamp = stamp
    msg.info.map_load_time = stamp
    msg.info.resolution = float(occ.resolution)
    msg.info.width = occ.width
    msg.info.height = occ.height
    msg.info.origin.position.x = float(occ.origin[0])
    msg.info.origin.position.y = float(occ.origin[1])
    msg.info.origin.orientation.z = math.sin(float(occ.origin[2]) / 2.0)
    msg.info.origin.orientation.w = math.cos(float(occ.origin[2]) / 2.0)
    msg.data = array.array("b", np.ascontiguousarray(occ.data, dtype=np.int8).tobytes())
    return msg


class SimulatorNode(Node):
    """The ROS 2 shell around :class:`swarm_sim.engine.SimEngine`.

    Args:
        settings: validated flags.
        engine: the world, already built with the spawned robots.
        occ: the map published once on ``/map`` (transient local).
        namespaces: robot namespaces without the leading slash, index-aligned with the engine.
        faults: the fault schedule (:func:`swarm_common.faults.parse_faults`); empty: none.
    """

    def __init__(self, settings: SimSettings, engine, occ, namespaces: list[str],
                 faults=()):
        super().__init__("swarm_sim")
        # Parameters: read-only mirrors of the flags, so `ros2 param get /swarm_sim rtf` works.
        for name, value in (
            ("world", settings.world), ("robot", settings.robot),
            ("swarm_size", settings.swarm_size), ("name_prefix", settings.name_prefix),
            ("seed", settings.seed), ("rtf", settings.rtf),
            ("duration", settings.duration if settings.duration is not None else -1.0),
            ("control_rate", settings.control_rate),
            ("stall_report", settings.stall_report),
        ):
            self.declare_parameter(name, value)
        # State.
        self.settings = settings
        self.engine = engine
        self.namespaces = namespaces
        self.n = len(namespaces)
        self.period_ns = round(NS_PER_S / settings.control_rate)
        self.t_ns = 0
        self.answers: dict[int, tuple[float, float]] = {}
        self.manual: dict[int, tuple[float, float, float]] = {}  # v, w, wall time received
        self.active = np.zeros(self.n, dtype=bool)
        self.late_ticks = np.zeros(self.n, dtype=int)
        self.lost: set[int] = set()
        """Robots whose navigator is gone (the supervisor's word, or no ``cmd_vel`` writer):
        not waited for until they answer again."""
        self._for_good: set[int] = set()  # lost robots whose navigator is not restarted
        self.dropped = 0
        self.stop_requested = False
        """Set by :meth:`request_stop` (SIGINT/SIGTERM): the loops end at their next check."""
        self.wall_timeline: list[float] = []  # [k]: wall s, start gate to simulated s k + 1
        self.standstills = StandstillTracker(engine.poses)  # robots at rest for 60 s or more
        self._last_warn = 0.0
        self._scans = None  # the current tick's scans, cast once (re-publishing reuses them)
        # Fault injection (swarm_sim.faults): this tick's silenced robots, lost messages,
        # rejoining navigators; the acknowledgements received; the commands applied last tick.
        self.faults = None
        if faults:
            from swarm_sim.faults import SimFaults, TickDrops

            self.faults = SimFaults(faults, namespaces, settings.seed)
            self._drops = TickDrops()
        self._silenced: set[int] = set()
        self._rejoin: set[int] = set()
        self._acks: set[tuple[int, str]] = set()
        self.fault_log: list[dict] = []  # every fault transition applied, in order
        self._last_cmd = np.zeros((self.n, 2))
        # Publishers and subscribers.
        self.clock_pub = publisher(self, Clock, topics.CLOCK)
        self.map_pub = publisher(self, OccupancyGrid, topics.MAP)
        self.events_pub = publisher(self, DiagnosticArray, topics.EVENTS)
        self.poses_pub = publisher(self, PoseArray, topics.POSES)
        self.odom_pubs, self.truth_pubs, self.scan_pubs, self._cmd_subs = [], [], [], []
        for i, ns in enumerate(namespaces):
            self.odom_pubs.append(publisher(self, Odometry, topics.ODOM, ns))
            self.truth_pubs.append(publisher(self, Odometry, topics.GROUND_TRUTH, ns))
            self.scan_pubs.append(publisher(self, LaserScan, topics.SCAN, ns))
            self._cmd_subs.append(subscription(
                self, TwistStamped, topics.CMD_VEL, lambda buf, i=i: self._on_cmd_vel(i, buf),
                ns, topics.CMD_VEL_READER_QOS, raw=True))  # read with swarm_common.cdr
        subscription(self, DiagnosticStatus, topics.SUPERVISION, self._on_supervision)
        self.recorded_ns = -1  # the latest /clock the recorder has taken (RECORD_PROGRESS)
        self._record_window = settings.record_window
        self._progress_sub = None
        if self._record_window:
            self._progress_sub = subscription(self, Clock, topics.RECORD_PROGRESS,
                                              self._on_record_progress)
        if self.faults is not None:
            # transient local (as swarm-up's writers): an acknowledgement sent before this
            # reader matched its writer comes from the writer's history, not lost
            subscription(self, DiagnosticStatus, topics.FAULT_ACKS, self._on_fault_ack)
        # Odometry, ground truth and scans are published as CDR bytes (swarm_common.cdr): 100
        # robots' messages a tick, each a struct.pack instead of rclpy's conversion.
        self._odom_writers = [OdometryWriter(f"{ns}/odom", f"{ns}/base_footprint")
                              for ns in namespaces]
        self._truth_writers = [OdometryWriter("map", f"{ns}/base_footprint") for ns in namespaces]
        self._scan_writers = [self._make_scan_writer(i, ns) for i, ns in enumerate(namespaces)]
        self._poses_writer = PoseArrayWriter("map")
        self.map_pub.publish(occupancy_grid_msg(occ, _time_msg(0)))

    # -- message templates ---------------------------------------------------------------------

    def _make_scan_writer(self, i: int, ns: str) -> LaserScanWriter:
        """Robot ``i``'s ``LaserScan`` writer: its own model's lidar (frame, beams, rate)."""
        eng = self.engine
        pattern = eng.kind_lidars[eng.kind[i]].pattern
        lidar = eng.models[i].lidar
        return LaserScanWriter(f"{ns}/{lidar.frame}", float(pattern.angles[0]),
                               float(pattern.angles[-1]), float(pattern.angle_increment),
                               1.0 / float(lidar.rate_hz), float(pattern.range_min),
                               float(pattern.range_max))

    def _odom_bytes(self, i: int, writer: OdometryWriter) -> bytes:
        """Robot ``i``'s odometry (or ground truth) of this tick, by ``writer``."""
        eng = self.engine
        x, y, yaw = eng.poses[i].tolist()
        return writer.write(self.t_ns, x, y, math.sin(yaw / 2.0), math.cos(yaw / 2.0),
                            float(eng.v[i]), float(eng.w[i]))

    # -- callbacks -----------------------------------------------------------------------------

    def _on_cmd_vel(self, i: int, buf: bytes) -> None:
        try:
            stamp, frame, v, w = twist_stamped(buf)
        except ValueError as exc:
            self._drop(f"/{self.namespaces[i]}/cmd_vel: malformed message ({exc})")
            return
        ns = self.namespaces[i]
        if not (math.isfinite(v) and math.isfinite(w)):
            self._drop(f"/{ns}/cmd_vel: non-finite velocity ({v}, {w})")
            return
        if frame not in ("", "base_footprint", "base_link", f"{ns}/base_footprint",
                         f"{ns}/base_link"):
            self._drop(f"/{ns}/cmd_vel: frame '{frame}' is not {ns}/base_footprint")
            return
        if stamp == 0:  # manual driving: apply now, hold until replaced
            self.manual[i] = (v, w, time.monotonic())
        elif stamp == self.t_ns and i not in self._silenced:
            self.answers[i] = (v, w)
            self.lost.discard(i)  # (its successor) answers: waited for again
            self._for_good.discard(i)
            if not self.active[i]:
                self.active[i] = True
                if self.engine.ticks > 1 and self.late_ticks[i]:
                    self._event("fault", i, f"{ns} answers again")
        # Any other stamp answers an earlier tick: too late, ignored.

    def _drop(self, why: str) -> None:
        self.dropped += 1
        now = time.monotonic()
        if now - self._last_warn > 5.0:
            self._last_warn = now
            self.get_logger().warning(f"dropped a malformed message: {why}")

    # -- events --------------------------------------------------------------------------------

    def _status(self, name: str, i: int, message: str, xy=None,
                values: dict | None = None) -> DiagnosticStatus:
        """One event: ``name`` is its kind; robot ``i``; ``xy`` defaults to the robot's pose."""
        level = {"collision": DiagnosticStatus.ERROR, "fault": DiagnosticStatus.WARN}.get(
            name, DiagnosticStatus.OK)
        x, y = self.engine.poses[i, :2] if xy is None else xy
        kv = [_kv("robot", self.namespaces[i]), _kv("x", f"{x:.3f}"), _kv("y", f"{y:.3f}"),
              _kv("t", f"{self.t_ns / NS_PER_S:.3f}")]
        kv += [_kv(k, v) for k, v in (values or {}).items()]
        return DiagnosticStatus(level=level, name=name, message=message,
                                hardware_id=self.namespaces[i], values=kv)

    def _publish_events(self, statuses: list[DiagnosticStatus]) -> None:
        if statuses:
            msg = DiagnosticArray(status=statuses)
            msg.header.stamp = _time_msg(self.t_ns)
            self.events_pub.publish(msg)

    def _event(self, name: str, i: int, message: str) -> None:
        self._publish_events([self._status(name, i, message)])

    # -- faults (swarm_sim.faults, docs/ARCHITECTURE.md "Faults") ------------------------------

    def _on_record_progress(self, msg: Clock) -> None:
        self.recorded_ns = max(self.recorded_ns, _stamp_ns(msg.clock))

    def wait_for_recorder(self, executor) -> None:
        """The record window: hold this tick until the recorder has taken the ``/clock`` of the
        tick ``record_window`` ticks before, however long that takes (topics.RECORD_PROGRESS:
        a stalled recorder then loses nothing).  Not waited for once the progress topic has no
        writer (checked every ``WRITER_CHECK_S``: the recorder is gone); a wait of
        ``stall_report`` wall seconds is reported, and goes on."""
        need = self.t_ns - self._record_window * self.period_ns
        if not self._record_window or self.recorded_ns >= need:
            return
        since = time.monotonic()
        check = since + WRITER_CHECK_S
        reported = 0
        while self.recorded_ns < need and not self.stop_requested:
            now = time.monotonic()
            if now >= check:
                check = now + WRITER_CHECK_S
                if self._progress_sub.get_publisher_count() == 0:
                    self._record_window = 0
                    self.get_logger().warning("the recorder is gone; ticks no longer wait for it")
                    return
            if now - since >= (reported + 1) * self.settings.stall_report:
                reported += 1
                self._report_stall(now - since, "the recorder")
            executor.spin_once(timeout_sec=0.05)

    def _on_supervision(self, msg: DiagnosticStatus) -> None:
        if msg.name != LOST:
            return
        word = RobotsLost.decode({kv.key: kv.value for kv in msg.values})
        index = {ns: i for i, ns in enumerate(self.namespaces)}
        for ns in word.robots if word is not None else ():
            if ns in index and index[ns] not in self.answers:
                self._lose(index[ns], word.reason, word.for_good)

    def _lose(self, i: int, reason: str, for_good: bool = False) -> None:
        """Robot ``i``'s navigator is gone: no tick waits for it until it answers again."""
        if i not in self.lost:
            self.get_logger().warning(f"{self.namespaces[i]}: navigator gone ({reason}); "
                                      "not waited for until it answers again")
        self.lost.add(i)
        if for_good:
            self._for_good.add(i)

    def _report_stall(self, waited: float, what: str) -> None:
        self.get_logger().warning(f"t = {self.t_ns / NS_PER_S:.1f} s: waited {waited:.0f} s "
                                  f"(wall) for {what}; still waiting (a stall costs wall time "
                                  "only)")

    def _on_fault_ack(self, msg: DiagnosticStatus) -> None:
        if msg.name != ACK_NAME:
            return
        ack = FaultAck.decode({kv.key: kv.value for kv in msg.values})
        if ack is not None:
            self._acks.add((ack.fault, ack.phase))

    def _fault_status(self, fault, phase: str) -> DiagnosticStatus:
        """The ``/swarm/events`` status announcing a fault's start or end at this tick."""
        t = self.t_ns / NS_PER_S
        ev = FaultEvent(fault=fault.index, kind=fault.kind, phase=phase,
                        robot=fault.robot or "", t=t, duration=fault.duration,
                        topic=fault.topic or "", fraction=fault.fraction)
        values = ev.encode()
        if fault.robot is not None:
            x, y = self.engine.poses[self.faults.robot(fault), :2]
            values["x"], values["y"] = f"{x:.3f}", f"{y:.3f}"
        verb = "starts" if phase == START else "ends"
        return DiagnosticStatus(
            level=DiagnosticStatus.WARN, name=EVENT_NAME,
            message=f"fault {fault.index} {fault.label()} {verb} at t = {t:.1f} s",
            hardware_id=fault.robot or "coordinator",
            values=[_kv(k, v) for k, v in values.items()])

    def apply_faults(self, executor) -> None:
        """Start and end the faults due at this tick, before it is published: announce each on
        ``/swarm/events``; hold the tick for the acknowledgements the protocol needs (a killed
        coordinator, its restart; a killed navigator before its robot rejoins); decide the
        messages lost at this tick."""
        due = self.faults.advance(self.t_ns)
        for f, phase in due:
            entry = {"fault": f.index, "kind": f.kind, "phase": phase, "robot": f.robot,
                     "t": round(self.t_ns / NS_PER_S, 3)}
            if f.robot is not None:  # where the robot was (a dead robot's body stays there)
                x, y = self.engine.poses[self.faults.robot(f), :2]
                entry["x"], entry["y"] = round(float(x), 3), round(float(y), 3)
            self.fault_log.append(entry)
        if due:
            self._publish_events([self._fault_status(f, phase) for f, phase in due])
        for f, phase in due:
            self.get_logger().warning(f"fault {f.index}: {f.label()} {phase} at "
                                      f"t = {self.t_ns / NS_PER_S:.1f} s")
            i = self.faults.robot(f) if f.robot is not None else None
            if f.kind in (KILL_NAV, KILL_ROBOT) and phase == START:
                self.active[i] = False  # not waited for; its answers are ignored from now
                self.answers.pop(i, None)
            elif f.kind == KILL_NAV and phase == END:
                # The old navigator must be gone before its robot's odometry flows again, so
                # that the answer the tick waits for comes from its successor.
                self._hold_for_ack(executor, f, START)
                self._rejoin.add(i)
            elif f.kind == KILL_COORDINATOR:
                self._hold_for_ack(executor, f, phase)
        self._silenced = self.faults.silenced()
        self._drops = self.faults.draw_drops(self.engine.lidar_due_mask())

    def _hold_for_ack(self, executor, fault, phase: str) -> None:
        """Hold simulated time until fault ``fault``'s ``phase`` is acknowledged on
        ``/swarm/fault_acks``, however long that takes (a stall is reported)."""
        since = time.monotonic()
        reported = 0
        while (fault.index, phase) not in self._acks:
            if self.stop_requested or not rclpy.ok():
                return
            waited = time.monotonic() - since
            if waited >= (reported + 1) * self.settings.stall_report:
                reported += 1
                self._report_stall(waited, f"the acknowledgement of fault {fault.index} "
                                   f"({fault.label()}) {phase}")
            executor.spin_once(timeout_sec=0.05)

    def wait_for_rejoin(self, executor) -> None:
        """Hold this tick until every rejoining robot (a killed navigator's outage ended) has
        answered it, re-publishing its odometry and scan every ``RESEND_S`` wall for a
        navigator that subscribed late; a robot whose navigator the supervisor gave up on is not
        waited for. However long it takes (a stall is reported)."""
        since = time.monotonic()
        resend = since + RESEND_S
        reported = 0
        while self._rejoin - self.answers.keys() - self._for_good:
            now = time.monotonic()
            if self.stop_requested or not rclpy.ok():
                return
            if now >= resend:
                resend = now + RESEND_S
                for i in self._rejoin - self.answers.keys():
                    self._republish(i)
            if now - since >= (reported + 1) * self.settings.stall_report:
                reported += 1
                names = ", ".join(self.namespaces[i] for i in sorted(self._rejoin))
                self._report_stall(now - since, f"the restarted navigator of {names}")
            executor.spin_once(timeout_sec=0.05)
        self._rejoin.clear()

    def _republish(self, i: int) -> None:
        """Publish robot ``i``'s odometry (and scan, on a lidar tick) of this tick again."""
        if (self.engine.lidar_due() and self._scans is not None
                and self._scans[i] is not None):
            self.scan_pubs[i].publish(self._scan_writers[i].write(self.t_ns, self._scans[i]))
        self.odom_pubs[i].publish(self._odom_bytes(i, self._odom_writers[i]))

    # -- the loop ------------------------------------------------------------------------------

    def publish_spawns(self) -> None:
        """Announce every robot's spawn pose on ``/swarm/events``."""
        self._publish_events([
            self._status("spawn", i, f"spawned {ns} at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})",
                         values={"yaw": f"{p[2]:.4f}"})
            for i, (ns, p) in enumerate(zip(self.namespaces, self.engine.poses, strict=True))
        ])

    def publish_tick(self) -> None:
        """Publish ``/clock``, odometry, ground truth and (on lidar ticks) scans for this tick,
        and ``/swarm/poses`` while it has a subscriber."""
        stamp = _time_msg(self.t_ns)
        self.clock_pub.publish(Clock(clock=stamp))
        eng = self.engine
        scans = None
        if eng.lidar_due():
            if self._scans is None:
                self._scans = eng.scans()
            scans = self._scans
            mute_scan = self._silenced | self._drops.scan if self.faults is not None else ()
        mute = self._silenced | self._drops.odom if self.faults is not None else ()
        # Robot after robot, its scan then its odometry: a navigator answers once it has both,
        # so the first robots' navigators start while the last robots' messages are still being
        # written (all scans first held every navigator back by the 100 scans' writing time).
        for i in range(self.n):
            if scans is not None and i not in mute_scan and scans[i] is not None:
                self.scan_pubs[i].publish(self._scan_writers[i].write(self.t_ns, scans[i]))
            if i not in mute:
                self.odom_pubs[i].publish(self._odom_bytes(i, self._odom_writers[i]))
            # Ground truth only while someone listens (a probe, a recorder, ros2 topic echo):
            # in a swarm-up run nothing does, and converting and writing 100 messages a tick
            # for no reader was a third of the simulator's publishing time.
            if self.truth_pubs[i].get_subscription_count():
                self.truth_pubs[i].publish(self._odom_bytes(i, self._truth_writers[i]))
        if self.poses_pub.get_subscription_count():
            self._publish_poses()

    def _publish_poses(self) -> None:
        """``/swarm/poses`` (:data:`swarm_common.topics.POSES`): every robot's pose in ``map``,
        written as CDR bytes (100 rclpy Pose objects a tick were a millisecond of the
        simulator's tick, on the lockstep's critical path, while a dashboard watched)."""
        self.poses_pub.publish(self._poses_writer.write(self.t_ns, self.engine.poses))

    def wait_for_acks(self, timeout: float = ACK_WAIT_S) -> bool:
        """Wait, at most ``timeout`` wall seconds in all, until every reliable reader has
        acknowledged what this node published: the last ticks reach the recorder before the
        node's writers are destroyed (a loaded machine once lost a 3 s run's last tick).

        Returns:
            True if everything was acknowledged in time.
        """
        deadline = time.monotonic() + timeout
        for pub in self.publishers:
            left = deadline - time.monotonic()
            if left <= 0.0 or not pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
                return False
        return True

    def request_stop(self, signum=None, frame=None) -> None:
        """Ask the run loop to end after the current step (a signal handler: only sets a flag)."""
        self.stop_requested = True

    def collect_commands(self, executor) -> tuple[np.ndarray, np.ndarray] | None:
        """Wait for this tick's answers of the active robots, however long that takes, then
        build the command vectors; None if a stop was requested meanwhile (the tick is neither
        stepped nor counted late).

        No wall-clock timeout decides anything (docs/ARCHITECTURE.md, "Synchronous control
        loop"): a robot is not waited for only once its navigator is known to be gone
        (:mod:`swarm_common.supervision`: the supervisor's word, or its ``cmd_vel`` without a
        writer, checked every ``WRITER_CHECK_S``); a wait of ``stall_report`` wall seconds is
        reported, and goes on. The tick's scan and odometry are published again every
        ``RESEND_S`` to a robot not yet answered: scans are best effort (sensor-data QoS), and a
        navigator that was paused or busy may have lost one, which it waits for; a copy changes
        nothing simulated (the navigator answers a tick once).
        """
        excused = self._drops.excused if self.faults is not None else ()
        waiting: set[int] = set()
        since = time.monotonic()
        check = since + WRITER_CHECK_S
        resend = since + RESEND_S
        reported = 0
        while True:
            if self.stop_requested:
                return None
            waiting.difference_update(self.answers.keys())  # cheap: C set operations
            waiting.difference_update(self.lost)
            if not waiting:  # then check in full (a robot may have been activated meanwhile)
                waiting = {i for i in np.flatnonzero(self.active).tolist()
                           if i not in self.answers and i not in excused and i not in self.lost}
                if not waiting:
                    break
            now = time.monotonic()
            if now >= resend:  # a scan is best effort: a paused navigator may have lost it
                resend = now + RESEND_S
                for i in waiting:
                    self._republish(i)
            if now >= check:
                check = now + WRITER_CHECK_S
                for i in waiting:
                    if self._cmd_subs[i].get_publisher_count() == 0:
                        self._lose(i, "its cmd_vel has no writer")
                if now - since >= (reported + 1) * self.settings.stall_report:
                    reported += 1
                    self._report_stall(now - since, ", ".join(
                        self.namespaces[i] for i in sorted(waiting - self.lost)))
            executor.spin_once(timeout_sec=0.05)
        v = np.zeros(self.n)
        w = np.zeros(self.n)
        now = time.monotonic()
        for i, (vi, wi, _) in self.manual.items():
            v[i], w[i] = vi, wi
        for i, (vi, wi) in self.answers.items():
            manual = self.manual.get(i)
            if manual is not None:
                if now - manual[2] < MANUAL_PRIORITY_S:
                    continue  # teleop outranks the navigator while it keeps coming
                del self.manual[i]
            v[i], w[i] = vi, wi
        if self.faults is not None:
            for i in self._drops.cmd_vel:  # a lost command: the drive keeps the last one
                if i in self.answers:
                    v[i], w[i] = self._last_cmd[i]
            self._last_cmd[:, 0], self._last_cmd[:, 1] = v, w
        late = []
        for i in np.flatnonzero(self.active):
            if i in self.answers or i in excused:
                continue
            # gone: stopped for this tick and, until it answers again, not waited for
            self.late_ticks[i] += 1
            self.active[i] = False
            ns = self.namespaces[i]
            late.append(self._status("late", i, f"{ns} late at t = {self.t_ns / NS_PER_S:.1f} "
                                     "s (navigator gone); stopped"))
            self._event("fault", i, f"{ns} stopped answering; robot stopped")
        self._publish_events(late)  # live late ticks (the dashboard's KPI), one message a tick
        self.answers.clear()
        return v, w

    def step(self, v: np.ndarray, w: np.ndarray) -> None:
        """Step the world one tick and publish the collision episodes that started."""
        held = self.faults.held_still() if self.faults is not None else None
        events = self.engine.step(v, w, held)
        self.t_ns += self.period_ns
        self._scans = None
        self.standstills.update(self.t_ns / NS_PER_S, self.engine.poses)
        statuses = []
        for ev in events:
            a = self.namespaces[ev.robot]
            other = self.namespaces[ev.other] if isinstance(ev.other, int) else ev.other
            statuses.append(self._status(
                "collision", ev.robot, f"{ev.kind.replace('_', '-')} collision: {a} and {other}",
                xy=(ev.x, ev.y), values={"other": other, "kind": ev.kind}))
            self.get_logger().warning(
                f"collision {a} / {other} at ({ev.x:.2f}, {ev.y:.2f}), t = {ev.t:.1f} s")
        self._publish_events(statuses)

    def _reader_matched(self, deadline: float) -> bool:
        """Whether the ``wait_for_reader`` node has ``reader_subscriptions`` subscriptions to
        this node's topics and all of them are matched by their publishers, and (with a
        ``record_window``) the recorder's progress writer is matched here (True without such a
        node, or after ``deadline``)."""
        name = self.settings.wait_for_reader
        if name is None or time.monotonic() > deadline:
            return True
        if self._progress_sub is not None and self._progress_sub.get_publisher_count() < 1:
            return False  # the record window's progress comes from the recorder too
        ns, _, base = name.rpartition("/")
        try:
            topics = self.get_subscriber_names_and_types_by_node(base, ns or "/")
        except NodeNameNonExistentError:  # not discovered yet
            return False
        pubs = {pub.topic_name: pub for pub in self.publishers}
        mine = [pubs[t] for t, _ in topics if t in pubs]
        return len(mine) >= max(1, self.settings.reader_subscriptions) and all(
            pub.get_subscription_count() >= self.count_subscribers(pub.topic_name)
            for pub in mine)

    def wait_for_robots(self, executor) -> None:
        """The start gate: hold the first tick, re-publishing it every 0.5 s wall, until
        ``wait_for`` robots have answered it (navigators that start late still see it) and the
        ``wait_for_reader`` node's subscriptions are matched (a recorder then gets every tick; a
        reader that never matches is given up ``READER_GRACE_S`` wall s after the robots)."""
        want = min(self.settings.wait_for, self.n)
        announced = -1
        deadline = math.inf
        while rclpy.ok() and not self.stop_requested:
            if int(self.active.sum()) >= want:
                deadline = min(deadline, time.monotonic() + READER_GRACE_S)
                if self._reader_matched(deadline):
                    break
            if int(self.active.sum()) != announced:
                announced = int(self.active.sum())
                self.get_logger().info(f"start gate: {announced}/{want} robots answering")
            self.publish_tick()
            until = time.monotonic() + 0.5
            while time.monotonic() < until and not self.stop_requested:
                executor.spin_once(timeout_sec=0.05)
                if int(self.active.sum()) >= want and self._reader_matched(deadline):
                    break

    def run(self, executor) -> None:
        """Run until ``duration`` simulated seconds have passed (forever if None)."""
        s = self.settings
        # Tick 0 is stepped silently so that no tick carries the zero stamp of manual commands.
        self.step(np.zeros(self.n), np.zeros(self.n))
        self.wait_for_robots(executor)
        wall0 = time.monotonic()
        sim0_ns = self.t_ns
        end_ns = None if s.duration is None else round(s.duration * NS_PER_S)
        while rclpy.ok() and not self.stop_requested and (end_ns is None or self.t_ns < end_ns):
            if self.faults is not None:
                self.apply_faults(executor)
            self.wait_for_recorder(executor)
            self.publish_tick()
            if self._rejoin:
                self.wait_for_rejoin(executor)
            commands = self.collect_commands(executor)
            if commands is None:
                break
            self.step(*commands)
            if self.t_ns >= (len(self.wall_timeline) + 1) * NS_PER_S:
                self.wall_timeline.append(round(time.monotonic() - wall0, 3))
            if s.rtf > 0.0:  # pace: keep servicing callbacks until the wall clock catches up
                due = wall0 + (self.t_ns - sim0_ns) / NS_PER_S / s.rtf
                while (left := due - time.monotonic()) > 0.0 and not self.stop_requested:
                    executor.spin_once(timeout_sec=min(left, 0.1))
            else:
                executor.spin_once(timeout_sec=0.0)
        self.wall_s = time.monotonic() - wall0

    def summary_record(self, wall_s: float, spawn: str | None = None,
                       world_skipped: tuple[str, ...] = ()) -> SimSummary:
        """The run's figures for ``--summary`` (:mod:`swarm_common.sim_summary`).

        Args:
            wall_s: [s] wall time of the simulation loop.
            spawn: where the robots went (:func:`prepare`'s ``spawned``), the extra ``spawn``.
            world_skipped: the world's skip report (``World.skipped``), the extra
                ``world_skipped``.
        """
        eng = self.engine
        sim_s = self.t_ns / NS_PER_S
        # wall_timeline_s[k]: wall seconds from the start gate to simulated second k + 1, for
        # comparing the speed of two runs of one seed second by second (their
        # simulated work is the same, so the ratio shows what else differed)
        fleet: dict[str, int] = {}  # model name -> robots of it, in order of first robot
        for model in eng.models:
            fleet[model.name] = fleet.get(model.name, 0) + 1
        extras = {"wall_timeline_s": list(self.wall_timeline),
                  "fleet": fleet,
                  "spawn": spawn,
                  "world_skipped": list(world_skipped),
                  "standstills": [{"robot": self.namespaces[e.robot], "start_s": e.start_s,
                                   "duration_s": e.duration_s, "x": e.x, "y": e.y,
                                   "open": e.open} for e in self.standstills.finish()]}
        if self.faults is not None:
            extras["faults"] = {
                "injected": [f.label() for f in self.faults.faults],
                "messages_dropped": {str(k): v for k, v in self.faults.dropped.items()},
                "log": self.fault_log,
            }
        per_robot = {
            ns: RobotSummary(distance_m=round(float(eng.distance[i]), 3),
                             collisions=int(eng.collisions[i]),
                             late_ticks=int(self.late_ticks[i]))
            for i, ns in enumerate(self.namespaces)
        }
        return SimSummary(
            robots=self.n,
            ticks=int(eng.ticks),
            sim_time_s=round(sim_s, 3),
            wall_time_s=round(wall_s, 3),
            rtf=round(sim_s / wall_s, 3) if wall_s > 0 else None,
            robot_ticks_per_s=round(self.n * eng.ticks / wall_s, 1) if wall_s > 0 else None,
            late_ticks=int(self.late_ticks.sum()),
            dropped_messages=self.dropped,
            collisions=CollisionCounts(**eng.collision_counts),
            min_separation_m=(round(eng.min_separation, 4)
                              if math.isfinite(eng.min_separation) else None),
            per_robot=per_robot,
            extras=extras,
        )



# -- command line ------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-sim`` argument parser."""
    p = cli.ArgumentParser(
        prog="swarm-sim",
        description="The swarm simulator node (/swarm_sim): loads a Gazebo world and a URDF "
        "robot, spawns N robots and publishes /clock, /map, /<ns>/scan, /<ns>/odom, "
        "/<ns>/ground_truth and /swarm/events; drives robots from /<ns>/cmd_vel "
        "(geometry_msgs/TwistStamped).",
        epilog="ROS arguments may follow --ros-args. Exit codes: 0 success, 2 bad input, "
        "1 runtime failure.")
    cli.add_shared(p, "--world",
                   help="world name under worlds/ or path to a .world/.sdf [slim_blockage]")
    cli.add_shared(p, "--robot",
                   help="robot name under robots/ or path to a .urdf/.xacro; or a mixed fleet "
                   "NAME:COUNT,NAME:COUNT,... whose counts add up to --swarm-size, or a fleet "
                   ".yaml file; the models are interleaved over the robot numbers "
                   "[turtlebot3_waffle]")
    cli.add_shared(p, "--swarm-size", default=5, help="number of robots [5]")
    cli.add_shared(p, "--name-prefix",
                   help=f"namespace prefix, a ROS name ({cli.ROS_NAME_RULE}) [Srobot]")
    cli.add_shared(p, "--seed", help="random seed (lidar noise) [0]")
    p.add_argument("--rtf", type=cli.non_negative_float, default=1.0, metavar="X",
                   help="real-time factor to pace to; 0 = as fast as possible [1.0]")
    p.add_argument("--duration", type=cli.positive_float, default=None, metavar="SEC",
                   help="simulated seconds to run [until Ctrl-C]")
    p.add_argument("--map", default=None, metavar="PATH",
                   help="map_server YAML to publish on /map [maps/<world>.yaml, else rasterised]")
    p.add_argument("--summary", default=None, metavar="PATH",
                   help="write a JSON summary of the run here at exit")
    p.add_argument("--control-rate", type=cli.positive_float, default=10.0, metavar="HZ",
                   help="control ticks per simulated second [10]")
    p.add_argument("--stall-report", type=cli.positive_float, default=10.0, metavar="SEC",
                   help="a tick that has waited this many wall seconds for its answers (or a "
                   "fault's acknowledgement) says which; it goes on waiting: no wall-clock "
                   "timeout decides anything simulated [10]")
    p.add_argument("--wait-for", type=cli.non_negative_int, default=0, metavar="K",
                   help="hold simulated time at the first tick until K robots answer it [0]")
    p.add_argument("--wait-for-reader", default=None, metavar="NODE",
                   help="also hold the first tick until NODE's subscriptions to the simulator's "
                   f"topics are matched (given up after {READER_GRACE_S:g} s) [none]")
    p.add_argument("--reader-subscriptions", type=cli.positive_int, default=1, metavar="K",
                   help="with --wait-for-reader: wait until NODE has K subscriptions to the "
                   "simulator's topics, all matched [1]")
    p.add_argument("--record-window", type=cli.non_negative_int, default=0, metavar="TICKS",
                   help="hold each tick until the recorder's /swarm/record/progress is at most "
                   "TICKS ticks behind (swarm-up --record passes "
                   f"{topics.RECORD_WINDOW_TICKS}); 0: never [0]")
    p.add_argument("--faults", default=None, metavar="SPEC",
                   help="inject faults at simulated times: KIND[:TARGET]@TIME[+DURATION],... "
                   "or a YAML file (kinds kill-nav, kill-robot, freeze, drop, kill-coordinator; "
                   "see docs/guides/faults.md) [none]")
    p.add_argument("--gui", action="store_true",
                   help="open the PyBullet window (default headless)")
    p.add_argument("--headless", action="store_true", help="run without a window (the default)")
    return p


def parse_settings(argv: list[str]) -> SimSettings:
    """Parse and validate ``swarm-sim`` flags (ROS arguments already removed).

    Raises:
        InputError: a flag's value is malformed or out of range.
    """
    a = build_parser().parse_args(argv)
    return SimSettings(
        world=a.world, robot=a.robot, swarm_size=a.swarm_size, name_prefix=a.name_prefix,
        seed=a.seed, rtf=a.rtf, duration=a.duration, map_path=a.map, summary=a.summary,
        control_rate=a.control_rate, stall_report=a.stall_report, wait_for=a.wait_for,
        wait_for_reader=a.wait_for_reader, reader_subscriptions=a.reader_subscriptions,
        record_window=a.record_window, gui=a.gui, faults=a.faults,
    )


def prepare(settings: SimSettings):
    """Load everything and spawn, before ROS starts, so bad input fails fast and quietly.

    Returns:
        ``(engine, occ, namespaces, spawned, world)``: ``spawned`` says where the robots went
        (:func:`swarm_scene.spawn.describe_spawn`); ``world`` is the loaded world, whose
        ``skipped`` names what of it is not simulated.

    Raises:
        InputError: a missing or malformed world, robot, map or points of interest, bad prefix, or
            more robots than fit.
    """
    from swarm_common.paths import default_map_for
    from swarm_scene.fleet import describe_fleet, fleet_models
    from swarm_scene.map_io import load_map
    from swarm_scene.poi import poi_for_world
    from swarm_scene.rasterize import rasterize_world
    from swarm_scene.robot_model import load_robot
    from swarm_scene.spawn import describe_spawn, spawn_poses, spawn_poses_free
    from swarm_scene.world import load_world, resolve_world, world_polygons
    from swarm_sim.engine import EngineConfig, SimEngine

    if not cli.is_ros_name(settings.name_prefix):
        raise InputError(f"--name-prefix: must be a ROS name ({cli.ROS_NAME_RULE}), got "
                         f"{settings.name_prefix!r}")
    world_path = resolve_world(settings.world)
    world = load_world(world_path)
    try:
        names = fleet_models(settings.robot, settings.swarm_size)
    except InputError as exc:
        raise InputError(f"--robot: {exc}") from None
    robots = {name: load_robot(name) for name in dict.fromkeys(names)}
    robot = robots[names[0]] if len(robots) == 1 else [robots[name] for name in names]
    radius = max(model.radius for model in robots.values())  # [m] spaced for the largest
    poi = poi_for_world(world_path)
    default_map = default_map_for(world_path)
    if settings.map_path is not None:
        occ = load_map(settings.map_path)
    elif default_map is not None:
        occ = load_map(default_map)
    else:
        occ = rasterize_world(world)
    polygons = world_polygons(world)
    from_spawn_area = poi is not None and poi.spawn is not None
    if from_spawn_area:
        poses = spawn_poses(poi.spawn, settings.swarm_size, radius, polygons,
                            where=f"spawn area of {world.name}")
    else:
        poses = spawn_poses_free(occ, settings.swarm_size, radius, polygons,
                                 where=f"largest free area of {world.name}")
    config = EngineConfig(control_period=1.0 / settings.control_rate)
    engine = SimEngine(world, robot, poses, seed=settings.seed, config=config, gui=settings.gui)
    namespaces = [f"{settings.name_prefix}{i + 1}" for i in range(settings.swarm_size)]
    spawned = describe_spawn(engine.poses, from_spawn_area,
                             None if poi is None or poi.source is None else poi.source.name)
    if len(robots) > 1:
        spawned += f"; robots: {describe_fleet(names)}"
    return engine, occ, namespaces, spawned, world


@contextlib.contextmanager
def held_warnings():
    """Hold back log records of the loaders; emit them only if the block succeeds."""
    records: list[logging.LogRecord] = []

    class _Hold(logging.Handler):
        def emit(self, record):
            records.append(record)

    root = logging.getLogger()
    hold = _Hold(logging.WARNING)
    root.addHandler(hold)
    try:
        yield
    finally:
        root.removeHandler(hold)
    for record in records:
        print(f"swarm-sim: warning: {record.getMessage()}", file=sys.stderr)


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def main(args=None) -> int:
    """Entry point of ``swarm-sim``."""
    argv = list(sys.argv if args is None else args)
    from rclpy.utilities import remove_ros_args

    user_args = remove_ros_args(argv)[1:]
    holder: dict = {}

    def body():
        settings = parse_settings(user_args)
        with held_warnings():  # bad input: only the one error line, not the loaders' warnings
            holder["engine"], occ, namespaces, spawned, world = prepare(settings)
        engine = holder["engine"]
        faults = ()
        if settings.faults is not None:
            try:
                faults = parse_faults(settings.faults, tuple(namespaces), settings.name_prefix,
                                      settings.duration)
            except InputError as exc:
                raise InputError(f"--faults: {exc}") from None
        skipped = describe_skipped(world)
        if skipped is not None:  # once, as swarm-map warns: what of the world is not simulated
            print(f"swarm-sim: warning: {skipped}", file=sys.stderr, flush=True)
        print(f"spawned {len(namespaces)} robots in {settings.world} "
              f"({namespaces[0]}..{namespaces[-1]}) {spawned}", flush=True)
        # Until the node runs, Ctrl-C and SIGTERM raise KeyboardInterrupt (not rclpy's handler,
        # which would invalidate the context mid-tick); then they only ask the loop to stop at the
        # next check (<= 0.1 s): an exception raised inside the executor's C++ dispatch of a
        # callback comes out as pybind11's "Unable to convert call argument" RuntimeError.
        signal.signal(signal.SIGTERM, _raise_interrupt)
        signal.signal(signal.SIGINT, signal.default_int_handler)  # even if started ignoring it
        with node_session(argv, signal_handler_options=SignalHandlerOptions.NO) as nodes:
            node = SimulatorNode(settings, engine, occ, namespaces, faults)
            nodes.append(node)
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, node.request_stop)
            node.set_parameters([Parameter("use_sim_time", value=False)])
            executor = EventsExecutor()
            executor.add_node(node)
            wall0 = time.monotonic()
            try:
                node.publish_spawns()
                node.run(executor)
            finally:  # also on Ctrl-C (then the session ends it quietly)
                wall_s = time.monotonic() - wall0
                node.wait_for_acks()
                summary = node.summary_record(wall_s, spawned, world.skipped)
                if settings.summary:
                    summary.write(settings.summary)
                c = summary.collisions
                print(f"simulated {summary.sim_time_s:.1f} s in {wall_s:.1f} s wall "
                      f"(RTF {summary.rtf}), collisions robot-robot {c.robot_robot} "
                      f"robot-wall {c.robot_wall}, late ticks {summary.late_ticks}",
                      flush=True)
                executor.shutdown()
        return 0

    try:
        return run_cli("swarm-sim", body)
    finally:
        if "engine" in holder:
            holder["engine"].close()


if __name__ == "__main__":
    sys.exit(main())
