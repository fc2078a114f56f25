"""``swarm-sim``: the simulator node ``/swarm_sim`` (docs/reference/contract.md#s2, #s3, #s5).

Loads a Gazebo world and a URDF robot, spawns exactly N robots, and runs the synchronous control
loop of docs/ARCHITECTURE.md: each control tick it publishes ``/clock``, every robot's state in
one ``/swarm/robot_states`` (from which group processes render their robots' sensors), and every
robot's ``odom``, ``ground_truth`` and, on lidar ticks, ``scan`` while that topic has a reader;
then waits for the ``cmd_vel`` each active
navigator computed from that tick's data (stamped with the tick; a group process's navigators
send theirs together on ``/swarm/cmd_vel_batch``), applies the commands and steps
the world.  ``--rtf 1`` paces simulated time to the wall clock, ``--rtf 0`` runs unpaced.

With the built ``tf2_msgs`` it also publishes ``/tf``, ``/tf_static`` and every robot's
``robot_description`` (:mod:`swarm_sim.tf_publisher`; ``--no-tf``: not), and with the built
``simulation_interfaces`` it serves the standard's services (:mod:`swarm_sim.sim_services`:
pause, step, entities).

This node is the ROS shell (:class:`swarm_sim.loop.Ports`) of the pure loop
:class:`swarm_sim.loop.SimLoop`, whose tick gate (:mod:`swarm_sim.tick`) decides who is
awaited and what is applied; the flags and the loading of the world are
:mod:`swarm_sim.settings`, the summary :mod:`swarm_sim.summary`.

Everything runs on one thread: ``EventsExecutor.spin_once`` services the subscriptions between
ticks (publishing from another thread while an ``EventsExecutor`` spins deadlocks this rclpy).
"""

from __future__ import annotations

import math
import signal
import sys
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray, TwistStamped
from nav_msgs.msg import OccupancyGrid
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.node import Node, NodeNameNonExistentError
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory

from swarm_common import topics
from swarm_common.cdr import (
    ODOM_PUBLISHED,
    SCAN_PUBLISHED,
    LaserScanWriter,
    PoseArrayWriter,
    RobotStatesWriter,
    cmd_vel_batch,
    twist_stamped,
)
from swarm_common.errors import run_cli
from swarm_common.events import COLLISION, CollisionEvent, LateEvent, RobotNotice, SpawnEvent
from swarm_common.faults import ACK_NAME, EVENT_NAME, FaultAck
from swarm_common.stamps import NS_PER_S
from swarm_common.supervision import LOST, RobotsLost
from swarm_ros.messages import key_values, occupancy_grid_msg, stamp_ns, time_msg
from swarm_ros.qos import publisher, subscription
from swarm_ros.robot_topics import RobotTopics, publish_sensors
from swarm_ros.session import node_session
from swarm_scene.world import describe_skipped
from swarm_sim.faults import SimFaults
from swarm_sim.loop import RESEND_S, SimLoop
from swarm_sim.settings import (
    SimSettings,
    fault_schedule,
    held_warnings,
    parse_settings,
    prepare,
)
from swarm_sim.sim_control import STOPPED
from swarm_sim.summary import summarize

ACK_WAIT_S = 1.0  # [s] wall: how long the simulator waits at exit for its last ticks' acks
_LEVELS = {COLLISION: DiagnosticStatus.ERROR, EVENT_NAME: DiagnosticStatus.WARN}


class SimulatorNode(Node):
    """The ROS 2 shell around :class:`swarm_sim.loop.SimLoop` (its :class:`Ports`).

    Args:
        settings: validated flags.
        engine: the world, already built with the spawned robots.
        occ: the map published once on ``/map`` (transient local).
        namespaces: robot namespaces without the leading slash, index-aligned with the engine.
        faults: the fault schedule (:func:`swarm_common.faults.parse_faults`); empty: none.
        interfaces: the built interface packages available
            (:func:`swarm_ros.built_interfaces.ensure`): ``tf2_msgs`` gives ``/tf`` (unless
            ``settings.tf`` is off), ``simulation_interfaces`` the standard's services; None:
            neither.
    """

    def __init__(self, settings: SimSettings, engine, occ, namespaces: list[str],
                 faults=(), interfaces=None):
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
        self.names = namespaces
        sim_faults = SimFaults(faults, namespaces, settings.seed) if faults else None
        self.loop = SimLoop(engine, self, namespaces, round(NS_PER_S / settings.control_rate),
                            settings.stall_report, settings.wait_for, settings.record_window,
                            sim_faults)
        self.gate = self.loop.gate
        self.stop_requested = False
        """Set by :meth:`request_stop` (SIGINT/SIGTERM): the waits end at their next check."""
        self.executor_ = None  # the executor :meth:`spin` turns (set by :meth:`run`)
        self._last_warn = 0.0
        self._scans = (-1, None)  # (tick, scans): cast once a tick, re-publishing reuses them
        # Publishers and subscribers.
        self.clock_pub = publisher(self, Clock, topics.CLOCK)
        self.map_pub = publisher(self, OccupancyGrid, topics.MAP)
        self.events_pub = publisher(self, DiagnosticArray, topics.EVENTS)
        self.poses_pub = publisher(self, PoseArray, topics.POSES)
        self.states_pub = publisher(self, PointCloud2, topics.ROBOT_STATES)
        self._states_writer = RobotStatesWriter(len(namespaces))
        self._states_resent = -math.inf  # [s] monotonic: the states last sent again
        self.robots = [RobotTopics(self, ns, self._scan_writer(i, ns))
                       for i, ns in enumerate(namespaces)]
        self._cmd_subs = [subscription(
            self, TwistStamped, topics.CMD_VEL, lambda buf, i=i: self._on_cmd_vel(i, buf), ns,
            topics.CMD_VEL_READER_QOS, raw=True) for i, ns in enumerate(namespaces)]
        self._index = {ns: i for i, ns in enumerate(namespaces)}
        subscription(self, MultiDOFJointTrajectory, topics.CMD_VEL_BATCH,
                     self._on_cmd_vel_batch, qos=topics.CMD_VEL_BATCH_READER_QOS, raw=True)
        subscription(self, DiagnosticStatus, topics.SUPERVISION, self._on_supervision)
        self._progress_sub = (subscription(self, Clock, topics.RECORD_PROGRESS,
                              self._on_record_progress) if settings.record_window else None)
        if sim_faults is not None:
            # transient local (as swarm-up's writers): an acknowledgement sent before this
            # reader matched its writer comes from the writer's history, not lost
            subscription(self, DiagnosticStatus, topics.FAULT_ACKS, self._on_fault_ack)
        self._poses_writer = PoseArrayWriter("map")
        self.map_pub.publish(occupancy_grid_msg(occ, time_msg(0)))
        self.tf = None
        """/tf, /tf_static and robot_description (:mod:`swarm_sim.tf_publisher`), or None."""
        if settings.tf and interfaces is not None and interfaces.has("tf2_msgs"):
            from swarm_scene.robot_frames import robot_frames
            from swarm_sim.tf_publisher import SwarmTf

            # one parse per robot model, not per robot
            sources = dict.fromkeys(m.source for m in engine.models)
            by_source = {source: robot_frames(source) for source in sources}
            self.tf = SwarmTf(self, namespaces, [by_source[m.source] for m in engine.models])
        self.sim_services = None
        """The simulation_interfaces services (:mod:`swarm_sim.sim_services`), or None."""
        if interfaces is not None and interfaces.has("simulation_interfaces"):
            from swarm_sim.sim_services import SimServices

            self.sim_services = SimServices(self, [m.name for m in engine.models])

    def _scan_writer(self, i: int, ns: str) -> LaserScanWriter:
        """Robot ``i``'s ``LaserScan`` writer: its own model's lidar (frame, beams, rate)."""
        eng = self.engine
        pattern = eng.kind_lidars[eng.kind[i]].pattern
        lidar = eng.models[i].lidar
        return LaserScanWriter(f"{ns}/{lidar.frame}", float(pattern.angles[0]),
                               float(pattern.angles[-1]), float(pattern.angle_increment),
                               1.0 / float(lidar.rate_hz), float(pattern.range_min),
                               float(pattern.range_max))

    # -- callbacks: messages into the gate -----------------------------------------------------

    def _on_cmd_vel(self, i: int, buf: bytes) -> None:
        ns = self.names[i]
        try:
            stamp, frame, v, w = twist_stamped(buf)
        except ValueError as exc:
            self._drop(f"/{ns}/cmd_vel: malformed message ({exc})")
            return
        if not (math.isfinite(v) and math.isfinite(w)):
            self._drop(f"/{ns}/cmd_vel: non-finite velocity ({v}, {w})")
            return
        if frame not in ("", "base_footprint", "base_link", f"{ns}/base_footprint",
                         f"{ns}/base_link"):
            self._drop(f"/{ns}/cmd_vel: frame '{frame}' is not {ns}/base_footprint")
            return
        if self.gate.answer(i, stamp, v, w, time.monotonic()):
            self._notice(i, f"{ns} answers again")

    def _on_cmd_vel_batch(self, buf: bytes) -> None:
        """A group process's answers (:data:`swarm_common.topics.CMD_VEL_BATCH`): each one
        robot's ``cmd_vel`` stamped with the batch's tick."""
        try:
            stamp, names, vw = cmd_vel_batch(buf)
        except ValueError as exc:
            self._drop(f"{topics.CMD_VEL_BATCH.name}: malformed message ({exc})")
            return
        now = time.monotonic()
        for ns, (v, w) in zip(names, vw.tolist(), strict=True):
            i = self._index.get(ns)
            if i is None:
                self._drop(f"{topics.CMD_VEL_BATCH.name}: no robot '{ns}'")
            elif not (math.isfinite(v) and math.isfinite(w)):
                self._drop(f"{topics.CMD_VEL_BATCH.name}: {ns}: non-finite velocity ({v}, {w})")
            elif stamp == 0:
                self._drop(f"{topics.CMD_VEL_BATCH.name}: zero stamp (manual driving goes "
                           f"to /{ns}/cmd_vel)")
            elif self.gate.answer(i, stamp, v, w, now):
                self._notice(i, f"{ns} answers again")

    def _drop(self, why: str) -> None:
        self.loop.log.dropped += 1
        now = time.monotonic()
        if now - self._last_warn > 5.0:
            self._last_warn = now
            self.get_logger().warning(f"dropped a malformed message: {why}")

    def _on_record_progress(self, msg: Clock) -> None:
        self.loop.window.progress(stamp_ns(msg.clock))

    def _on_supervision(self, msg: DiagnosticStatus) -> None:
        if msg.name != LOST:
            return
        word = RobotsLost.decode({kv.key: kv.value for kv in msg.values})
        index = {ns: i for i, ns in enumerate(self.names)}
        for ns in word.robots if word is not None else ():
            if ns in index:
                self.loop.lose(index[ns], word.reason, word.for_good)

    def _on_fault_ack(self, msg: DiagnosticStatus) -> None:
        if msg.name != ACK_NAME:
            return
        ack = FaultAck.decode({kv.key: kv.value for kv in msg.values})
        if ack is not None:
            self.loop.acks.add((ack.fault, ack.phase))

    # -- events (swarm_common.events) ----------------------------------------------------------

    def _event(self, cls, i: int, message: str, xy=None, **fields) -> DiagnosticStatus:
        """The ``/swarm/events`` status of robot ``i``'s event ``cls`` at this tick (at ``xy``
        [m] in ``map``, else at the robot's pose)."""
        x, y = self.engine.poses[i, :2] if xy is None else xy
        event = cls(self.names[i], x, y, self.gate.t_ns / NS_PER_S, **fields)
        return DiagnosticStatus(level=_LEVELS.get(event.KIND, DiagnosticStatus.OK),
                                name=event.KIND, message=message, hardware_id=event.robot,
                                values=key_values(event.encode()))

    def _publish_events(self, statuses: list[DiagnosticStatus]) -> None:
        if statuses:
            msg = DiagnosticArray(status=statuses)
            msg.header.stamp = time_msg(self.gate.t_ns)
            self.events_pub.publish(msg)

    def _notice(self, i: int, message: str) -> None:
        self._publish_events([self._event(RobotNotice, i, message)])

    def publish_spawns(self) -> None:
        """Announce every robot's spawn pose on ``/swarm/events``."""
        self._publish_events([
            self._event(SpawnEvent, i, f"spawned {ns} at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f})",
                        yaw=p[2])
            for i, (ns, p) in enumerate(zip(self.names, self.engine.poses, strict=True))])

    def announce_late(self, robots: list[int]) -> None:
        late = []
        for i in robots:
            ns = self.names[i]
            late.append(self._event(LateEvent, i, f"{ns} late at t = "
                                    f"{self.gate.t_ns / NS_PER_S:.1f} s (navigator gone); "
                                    "stopped"))
            self._notice(i, f"{ns} stopped answering; robot stopped")
        self._publish_events(late)  # live late ticks (the dashboard's KPI), one message a tick

    def stepped(self, events: list) -> None:
        statuses = []
        for ev in events:
            a = self.names[ev.robot]
            other = self.names[ev.other] if isinstance(ev.other, int) else ev.other
            statuses.append(self._event(
                CollisionEvent, ev.robot, f"{ev.kind.replace('_', '-')} collision: {a} and "
                f"{other}", (ev.x, ev.y), other=other, kind=ev.kind))
            self.get_logger().warning(
                f"collision {a} / {other} at ({ev.x:.2f}, {ev.y:.2f}), t = {ev.t:.1f} s")
        self._publish_events(statuses)

    def announce_faults(self, due: list) -> None:
        faults, t_ns, poses = self.loop.faults, self.gate.t_ns, self.engine.poses
        statuses = []
        for f, phase in due:
            values, message = faults.event(f, phase, t_ns, poses)
            statuses.append(DiagnosticStatus(
                level=DiagnosticStatus.WARN, name=EVENT_NAME, message=message,
                hardware_id=f.robot or "coordinator",
                values=key_values(values)))
        self._publish_events(statuses)
        for f, phase in due:
            self.get_logger().warning(f"fault {f.index}: {f.label()} {phase} at "
                                      f"t = {t_ns / NS_PER_S:.1f} s")

    # -- the rest of the loop's ports ----------------------------------------------------------

    def spin(self, timeout_s: float) -> None:
        self.executor_.spin_once(timeout_sec=timeout_s)
        if self.sim_services is not None:
            self.sim_services.poll()

    def stopped(self) -> bool:
        return self.stop_requested or not rclpy.ok() or self.loop.control.state == STOPPED

    def log(self, level: str, text: str) -> None:
        if level == "warning":  # one call site per severity (rclpy's logger requires it)
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)

    def cmd_writer(self, i: int) -> bool:
        return self._cmd_subs[i].get_publisher_count() > 0

    def progress_writer(self) -> bool:
        return self._progress_sub is not None and self._progress_sub.get_publisher_count() > 0

    def _tick_scans(self):
        """This tick's scans (cast once a tick), or None when no lidar scans at this tick."""
        eng = self.engine
        if not eng.lidar_due():
            return None
        if self._scans[0] != eng.ticks:
            self._scans = (eng.ticks, eng.scans())
        return self._scans[1]

    def publish_tick(self) -> None:
        """Publish ``/clock``, odometry, ground truth and (on lidar ticks) scans for this tick,
        and ``/swarm/poses`` while it has a subscriber."""
        t_ns, eng = self.gate.t_ns, self.engine
        self.clock_pub.publish(Clock(clock=time_msg(t_ns)))
        silenced, drops = self.gate.silenced, self.loop.drops
        mute_odom, mute_scan = silenced | drops.odom, silenced | drops.scan
        self._publish_states(mute_odom, mute_scan)
        publish_sensors(self.robots, t_ns, eng.poses, eng.v, eng.w, self._tick_scans(),
                        mute_odom=mute_odom, mute_scan=mute_scan, lazy=True)
        if self.tf is not None:
            self.tf.publish(t_ns, eng.poses)
        if self.poses_pub.get_subscription_count():
            # written as CDR bytes: 100 rclpy Pose objects a tick were a millisecond of the
            # simulator's tick, on the lockstep's critical path, while a dashboard watched
            self.poses_pub.publish(self._poses_writer.write(t_ns, eng.poses))

    def _publish_states(self, mute_odom, mute_scan) -> None:
        """``/swarm/robot_states`` of this tick, while it has a reader (the group processes)."""
        if not self.states_pub.get_subscription_count():
            return
        eng = self.engine
        published = np.full(eng.n, ODOM_PUBLISHED | SCAN_PUBLISHED, dtype=np.uint8)
        published[list(mute_odom)] &= ~np.uint8(ODOM_PUBLISHED)
        published[list(mute_scan)] &= ~np.uint8(SCAN_PUBLISHED)
        self.states_pub.publish(self._states_writer.write(self.gate.t_ns, eng.poses, eng.v,
                                                          eng.w, published))

    def republish(self, i: int) -> None:
        """Robot ``i``'s tick again: its ``odom`` and ``scan`` to their readers, and the robots'
        states (once a wall-clock round of re-publishing, whichever robots it is for)."""
        eng, scans = self.engine, self._tick_scans()
        robot = self.robots[i]
        if scans is not None and scans[i] is not None and robot.scan_pub.get_subscription_count():
            robot.publish_scan(self.gate.t_ns, scans[i])
        if robot.odom_pub.get_subscription_count():
            robot.publish_odom(self.gate.t_ns, eng.poses[i].tolist(), float(eng.v[i]),
                               float(eng.w[i]), truth=False)
        now = time.monotonic()
        if now - self._states_resent > 0.5 * RESEND_S:
            self._states_resent = now
            silenced, drops = self.gate.silenced, self.loop.drops
            self._publish_states(silenced | drops.odom, silenced | drops.scan)

    def reader_matched(self, deadline_s: float) -> bool:
        """Whether the ``wait_for_reader`` node has ``reader_subscriptions`` subscriptions to
        this node's topics and all of them are matched by their publishers, and (with a
        ``record_window``) the recorder's progress writer is matched here (True without such a
        node, or after ``deadline_s``)."""
        name = self.settings.wait_for_reader
        if name is None or time.monotonic() > deadline_s:
            return True
        if self._progress_sub is not None and self._progress_sub.get_publisher_count() < 1:
            return False  # the record window's progress comes from the recorder too
        ns, _, base = name.rpartition("/")
        try:
            found = self.get_subscriber_names_and_types_by_node(base, ns or "/")
        except NodeNameNonExistentError:  # not discovered yet
            return False
        pubs = {pub.topic_name: pub for pub in self.publishers}
        mine = [pubs[t] for t, _ in found if t in pubs]
        return len(mine) >= max(1, self.settings.reader_subscriptions) and all(
            pub.get_subscription_count() >= self.count_subscribers(pub.topic_name)
            for pub in mine)

    # -- life ----------------------------------------------------------------------------------

    def run(self, executor) -> None:
        """Run the loop on ``executor`` until ``duration`` simulated seconds have passed."""
        self.executor_ = executor
        self.loop.run(self.settings.duration, self.settings.rtf)

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
        """Ask the loop to end after the current step (a signal handler: only sets a flag)."""
        self.stop_requested = True


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
        faults = fault_schedule(settings, namespaces)
        from swarm_ros.built_interfaces import ensure

        interfaces = ensure(packages=("tf2_msgs", "simulation_interfaces") if settings.tf
                            else ("simulation_interfaces",))
        if (skipped := describe_skipped(world)) is not None:  # what of it is not simulated
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
            node = SimulatorNode(settings, engine, occ, namespaces, faults, interfaces)
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
                if node.sim_services is not None:
                    node.sim_services.finish()  # requests still waiting (a stepping the end cut)
                node.wait_for_acks()
                summary = summarize(engine, node.gate, namespaces, node.loop.log,
                                    node.loop.faults, wall_s, spawned, world.skipped)
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
