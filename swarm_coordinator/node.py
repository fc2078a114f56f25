"""``swarm-coordinator``: the central coordinator of ``swarm-up --coordination centralized``.

::

    swarm-coordinator --swarm-size N [--name-prefix Srobot] [--world NAME|PATH] [--seed S]
                      [--robot NAME|PATH] [--batch-window SEC] [--start-timeout SEC]
                      [--restart-timeout SEC] [--ros-args ...]

A thin ROS 2 shell (node ``/swarm_coordinator``) around
:class:`swarm_coordinator.core.CoordinatorCore`; the contract (topics, JSON records, events) is
:mod:`swarm_common.coordination`. It subscribes ``/swarm/coordinator/request``, publishes each
robot's ``/<ns>/coordinator/assignment``, its latched ``/swarm/coordinator/state`` and the
reservation and task events on ``/swarm/events``.

When a batch is complete (docs/ARCHITECTURE.md, "Coordination"):

- *sync*: right after (re)starting it answers nothing until every robot has been heard from
  (its ``ready``, ``done`` or ``report``), or ``--start-timeout`` wall seconds after the first
  ``ready`` (a fresh start: robots come up one by one), or ``--restart-timeout`` after the first
  other request (a restart: every commander reports at once when it sees the new ``state``). The
  whole first batch is then handled in (stamp, robot) order, whatever the arrival order.
- *then*: a request opens a batch that is closed ``--batch-window`` wall seconds later; requests
  stamped with the same simulated tick normally arrive within that window, and a batch is
  handled in (stamp, robot) order. The window costs the simulator that much wall time whenever
  a goal ends (the robot's navigator holds its next tick until the answer is there).
"""

from __future__ import annotations

import sys
import time
import uuid

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy._rclpy_pybind11 import RCLInvalidROSArgsError
from rclpy.clock import Clock, ClockType
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from std_msgs.msg import String

from swarm_common import cli, topics
from swarm_common.coordination import (
    COORDINATOR_NODE,
    EVENT_COORDINATOR,
    METRICS_NODE,
    ContractError,
    CoordinatorEvent,
    decode_request,
    encode_assignment,
    encode_state,
)
from swarm_common.errors import InputError, run_cli
from swarm_common.stamps import NS_PER_S
from swarm_coordinator.core import CoordinatorConfig, CoordinatorCore
from swarm_ros.qos import publisher, subscription
from swarm_ros.session import node_session, spin_forever

PROG = "swarm-coordinator"
NODE_NAME = COORDINATOR_NODE
SYNC_POLL_S = 0.05  # [s] wall
METRICS_MATCH_GRACE_S = 2.0  # [s] wall: discovery matches a reader well within this
# [s] wall: the writer may match a reader before that reader has matched the writer; a volatile
# reader drops what a writer sent before it knew the writer (a restarted coordinator's "up" event
# lost once in CI, when the metrics' reader was volatile). Discovery completes both sides in this.
METRICS_SETTLE_S = 0.5


class CoordinatorNode(Node):
    """The coordinator's ROS shell (see the module doc).

    Args:
        core: the assignment and reservation logic.
        batch_window: [s] wall a batch stays open after its first request.
        start_timeout: [s] wall the first sync waits after the first ``ready``.
        restart_timeout: [s] wall the first sync waits after the first other request.
        **kwargs: passed to :class:`rclpy.node.Node`.
    """

    def __init__(self, core: CoordinatorCore, batch_window: float = 0.03,
                 start_timeout: float = 120.0, restart_timeout: float = 5.0, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        # state
        self.core = core
        self._batch_window = batch_window
        self._start_timeout = start_timeout
        self._restart_timeout = restart_timeout
        self._pending = []
        self._syncing = True
        self._sync_deadline: float | None = None
        self._metrics_seen: float | None = None  # time.monotonic() the metrics' reader appeared
        self._matched_since: float | None = None  # time.monotonic() every reader was matched
        self._batch_timer = None
        self._warned = 0.0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        # publishers, subscribers
        self._assign_pubs = {ns: publisher(self, String, topics.ASSIGNMENT, ns)
                             for ns in core.robots}
        self._events_pub = publisher(self, DiagnosticArray, topics.EVENTS,
                                     qos=topics.EVENTS_COORDINATOR_WRITER_QOS)
        self._state_pub = publisher(self, String, topics.COORDINATOR_STATE)
        subscription(self, String, topics.COORDINATOR_REQUEST, self._on_request,
                     qos=topics.COORDINATOR_REQUEST_READER_QOS)
        # timers
        self._sync_timer = self.create_timer(SYNC_POLL_S, self._on_sync_poll, clock=self._steady)
        self._state_pub.publish(String(data=encode_state(core.epoch, len(core.robots))))
        # Announced on /swarm/events with the first batch: a message published now, before
        # discovery has matched the readers of a volatile topic, would be lost.
        self._up_event: CoordinatorEvent | None = CoordinatorEvent(
            EVENT_COORDINATOR, "", 0, {"state": "up"}, core.epoch)
        self.get_logger().info(f"up: epoch {core.epoch}, {len(core.robots)} robots, "
                               f"{len(core.stations)} workstations, {len(core.spots)} spots")

    # -- callbacks --------------------------------------------------------------------------
    def _on_request(self, msg: String) -> None:
        try:
            req = decode_request(msg.data)
        except ContractError as exc:
            self._warn(f"dropped a malformed request: {exc}")
            return
        if req.robot not in self.core.robots:
            self._warn(f"dropped a request of unknown robot {req.robot!r}")
            return
        self._pending.append(req)
        if self._syncing:
            if self._sync_deadline is None:
                wait = self._start_timeout if req.kind == "ready" else self._restart_timeout
                self._sync_deadline = time.monotonic() + wait
            self._on_sync_poll()
        elif self._batch_timer is None:
            self._batch_timer = self.create_timer(self._batch_window, self._on_batch_timer,
                                                  clock=self._steady)

    def _on_sync_poll(self) -> None:
        if not self._syncing:
            return
        heard = self.core.heard | {r.robot for r in self._pending}
        late = self._sync_deadline is not None and time.monotonic() >= self._sync_deadline
        watched = self._metrics_matched()
        heard_all = heard >= set(self.core.robots)
        if (heard_all and watched) or late:
            if not heard_all:
                missing = sorted(set(self.core.robots) - heard)
                self.get_logger().warning(f"sync: no word from {len(missing)} robot(s) "
                                          f"({', '.join(missing[:5])}); going on without them")
            if not watched:
                self.get_logger().warning(f"sync: the metrics' reader of {topics.EVENTS.name} "
                                          "is not matched; this start and the first answers may "
                                          "go unrecorded")
            self._syncing = False
            self.destroy_timer(self._sync_timer)
            self._flush()

    def _metrics_matched(self) -> bool:
        """Whether the metrics' reader of ``/swarm/events`` is discovered and matched.

        The first batch carries the "up" event and the reservations rebuilt after a restart;
        the metrics' reader is transient local and gets from the writer's history (depth 100)
        what went out before it matched, but a reader that never matches loses it (and its
        conflict check would see releases of unknown reservations). Other readers (the fault
        nodes of the group processes, a recorder) may match first, so the metrics node is looked
        for by name, and every reader the graph knows must be matched; a reader that never
        matches (incompatible QoS, e.g. a ``ros2 topic echo`` asking for deadline or liveliness
        this writer does not offer) is given up on :data:`METRICS_MATCH_GRACE_S` after the
        metrics' reader appeared.
        The writer's side of a match comes first; the readers' side is given
        :data:`METRICS_SETTLE_S` more.
        """
        readers = self.get_subscriptions_info_by_topic(topics.EVENTS.name)
        if not any(r.node_name == METRICS_NODE for r in readers):
            return False
        now = time.monotonic()
        if self._metrics_seen is None:
            self._metrics_seen = now
        if self._events_pub.get_subscription_count() < len(readers):
            self._matched_since = None
            return now - self._metrics_seen >= METRICS_MATCH_GRACE_S
        if self._matched_since is None:
            self._matched_since = now
        return now - self._matched_since >= METRICS_SETTLE_S

    def _on_batch_timer(self) -> None:
        if self._batch_timer is not None:
            self.destroy_timer(self._batch_timer)
            self._batch_timer = None
        self._flush()

    # -- output -----------------------------------------------------------------------------
    def _flush(self) -> None:
        batch, self._pending = self._pending, []
        if not batch:
            return
        assignments, events = self.core.handle(batch)
        if self._up_event is not None:
            t = min(r.stamp_ns for r in batch)
            events.insert(0, CoordinatorEvent(EVENT_COORDINATOR, "", t, self._up_event.fields,
                                              self.core.epoch))
            self._up_event = None
        for a in assignments:
            self._assign_pubs[a.robot].publish(String(data=encode_assignment(a)))
        self._publish_events(events)

    def _publish_events(self, events) -> None:
        if not events:
            return
        msg = DiagnosticArray()
        t = max(e.t_ns for e in events)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, NS_PER_S)
        for e in events:
            msg.status.append(DiagnosticStatus(
                level=DiagnosticStatus.OK, name=e.kind, message=e.message(),
                hardware_id=e.robot,
                values=[KeyValue(key=k, value=v) for k, v in e.values().items()]))
        self._events_pub.publish(msg)

    def _warn(self, text: str) -> None:
        now = time.monotonic()
        if now - self._warned >= 5.0:
            self._warned = now
            self.get_logger().warning(text)


# ------------------------------------------------------------------------------------------ cli
def build_parser() -> cli.ArgumentParser:
    """The ``swarm-coordinator`` argument parser."""
    p = cli.ArgumentParser(prog=PROG, description="The central coordinator of swarm-up "
                           "--coordination centralized: assigns every robot its next "
                           "workstation, reserves workstations and waiting spots first come, "
                           "first served, and tells robots where to wait.")
    cli.add_shared(p, "--swarm-size", required=True,
                   help="number of robots: <PREFIX>1 .. <PREFIX>N")
    cli.add_shared(p, "--name-prefix", help="prefix of robot namespaces (default: %(default)s)")
    cli.add_shared(p, "--world", help="world whose workstations and holding spots to use "
                   "(default: %(default)s)")
    cli.add_shared(p, "--seed",
                   help="seed of the robots' routes, as the commanders' (default: %(default)s)")
    cli.add_shared(p, "--robot",
                   help="robot model, or a mix NAME:COUNT,... as swarm-up's, for the parking "
                   "spots' clearance (the largest model's) (default: %(default)s)")
    p.add_argument("--control-period", type=cli.positive_float, default=0.1, metavar="SEC",
                   help="the simulator's control tick [s] (default: %(default)s)")
    p.add_argument("--batch-window", type=cli.non_negative_float, default=0.03, metavar="SEC",
                   help="wall seconds a batch of requests stays open (default: %(default)s)")
    p.add_argument("--start-timeout", type=cli.positive_float, default=120.0, metavar="SEC",
                   help="wall seconds the first answers wait for every robot's ready "
                   "(default: %(default)s)")
    p.add_argument("--restart-timeout", type=cli.positive_float, default=5.0, metavar="SEC",
                   help="after a restart, wall seconds to wait for every robot's report "
                   "(default: %(default)s)")
    return p


def build_core(world: str, seed: int, robots: tuple[str, ...], robot_model: str,
               control_period: float, epoch: str) -> CoordinatorCore:
    """The core for a world: its workstations, holding spots, parking on the spawn grid, and
    each robot's route (:func:`swarm_commander.route.build_route`, as the commanders').

    Raises:
        InputError: the world is unknown or has no workstations (names ``--world``).
    """
    from swarm_commander.route import build_route
    from swarm_common.fleet import fleet_models
    from swarm_common.poi import poi_for_world
    from swarm_common.robot_model import load_robot
    from swarm_common.spawn import spawn_poses
    from swarm_common.world import load_world, resolve_world, world_polygons
    from swarm_coordinator.core import Station, spots_from_poi

    routes = {ns: build_route(world, seed, ns) for ns in robots}  # InputError names --world
    path = resolve_world(world)
    poi = poi_for_world(path)
    parking = None
    if poi.spawn is not None:
        try:
            radius = max(load_robot(m).radius
                         for m in set(fleet_models(robot_model, len(robots))))
            parking = spawn_poses(poi.spawn, len(robots), radius,
                                  world_polygons(load_world(path)))
        except InputError:
            parking = None
    stations = [Station(w.name, tuple(float(v) for v in w.pose[:3])) for w in poi.workstations]
    loops = {ns: iter(()) for ns in robots}

    def next_stop(ns: str) -> str:
        stop = next(loops[ns], None)
        if stop is None:
            loops[ns] = iter(routes[ns].next_loop())
            stop = next(loops[ns])
        return stop.name

    return CoordinatorCore(robots, stations, spots_from_poi(poi, parking), next_stop,
                           CoordinatorConfig(period_ns=round(control_period * NS_PER_S)),
                           epoch=epoch)


def _run(argv: list[str]) -> int:
    try:
        plain = remove_ros_args([PROG, *argv])[1:]
    except RCLInvalidROSArgsError as exc:
        raise InputError(f"--ros-args: {str(exc).splitlines()[0]}") from None
    opts = build_parser().parse_args(plain)
    robots = tuple(f"{opts.name_prefix}{i}" for i in range(1, opts.swarm_size + 1))
    epoch = uuid.uuid4().hex[:12]  # fixed length: message sizes do not depend on it
    core = build_core(opts.world, opts.seed, robots, opts.robot, opts.control_period, epoch)
    with node_session([PROG, *argv]) as nodes:
        node = CoordinatorNode(core, opts.batch_window, opts.start_timeout,
                               opts.restart_timeout)
        nodes.append(node)
        print(f"{PROG}: up (epoch {epoch}): {len(robots)} robots, {len(core.stations)} "
              f"workstations, {len(core.spots)} waiting spots", flush=True)
        executor = EventsExecutor()
        executor.add_node(node)
        spin_forever(executor, node.context)
    return 0


def main(args: list[str] | None = None) -> int:
    """Entry point of ``swarm-coordinator``; 0 on Ctrl-C, 2 on bad input."""
    return run_cli(PROG, lambda: _run(list(sys.argv[1:] if args is None else args)))


if __name__ == "__main__":
    sys.exit(main())
