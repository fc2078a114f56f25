"""``swarm-coordinator``: the central coordinator of ``swarm-up --coordination centralized``.

::

    swarm-coordinator --swarm-size N [--name-prefix Srobot] [--world NAME|PATH] [--seed S]
                      [--robot NAME|PATH] [--control-period SEC] [--faults FILE]
                      [--policy reserve|pipelined] [--assignment nearest-free|route]
                      [--waiting-spots near|hall] [--silence-timeout SEC] [--eta-speed M_PER_S]
                      [--dock-clear SEC] [--lease SEC] [--queue-at spots|holding]
                      [--service-time SEC]
                      [--stall-report SEC] [--ros-args ...]

A thin ROS 2 shell (node ``/swarm_coordinator``) around
:class:`swarm_coordinator.core.CoordinatorCore`; the contract (topics, JSON records, events) is
:mod:`swarm_common.coordination`. It subscribes ``/swarm/coordinator/request``, publishes each
robot's ``/<ns>/coordinator/assignment``, its latched ``/swarm/coordinator/state`` and the
reservation and task events on ``/swarm/events``.

When a batch is complete (docs/ARCHITECTURE.md, "Coordination"); no wall-clock timeout decides
it, so the same seed gives the same answers on a busy machine too:

- *sync*: right after (re)starting it answers nothing until every robot alive has been heard
  from (its ``ready``, ``done`` or ``report``; a robot a ``kill-robot`` fault of ``--faults`` has
  killed is not waited for), and the metrics' reader of ``/swarm/events`` is matched. The whole
  first batch is then handled in (stamp, robot) order, whatever the arrival order.
- *then*: every request is acknowledged at once (an ``ack`` assignment); the navigator of a robot
  whose goal ended holds that tick until its commander has the acknowledgement
  (``hold_goal_end``), so once the simulator publishes a later tick on ``/clock`` every request
  stamped up to it is here: they are handled together, in (stamp, robot) order.
- a workstation handed to a robot waiting at a spot (or a move up to a freed holding spot) goes
  out first; the answers of the batch, which the simulator waits for, follow only once every
  such robot's commander says its navigator has the goal (``delivered``), so it takes effect at a
  fixed tick.
"""

from __future__ import annotations

import math
import sys
import time
import uuid
from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy._rclpy_pybind11 import RCLInvalidROSArgsError
from rclpy.clock import Clock as RclpyClock
from rclpy.clock import ClockType
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from swarm_common import cli, topics
from swarm_common.coordination import (
    COORDINATOR_NODE,
    EVENT_COORDINATOR,
    METRICS_NODE,
    Assignment,
    ContractError,
    CoordinatorEvent,
    decode_request,
    encode_assignment,
    encode_state,
)
from swarm_common.errors import InputError, run_cli
from swarm_common.stall import StallReport
from swarm_common.stamps import NS_PER_S
from swarm_common.supervision import LOST, RobotsLost
from swarm_coordinator.core import CoordinatorConfig, CoordinatorCore
from swarm_ros.messages import key_values
from swarm_ros.qos import publisher, subscription
from swarm_ros.session import node_session, spin_forever

PROG = "swarm-coordinator"
NODE_NAME = COORDINATOR_NODE
SYNC_POLL_S = 0.05  # [s] wall: how often the sync checks discovery (the graph has no callback)
METRICS_MATCH_GRACE_S = 2.0  # [s] wall: discovery matches a reader well within this
# [s] wall: without swarm-up (no metrics node at all) the first answers go out this long after
# every robot was heard; only what is recorded depends on it, not what is simulated
METRICS_ABSENT_S = 10.0
# [s] wall: the writer may match a reader before that reader has matched the writer; a volatile
# reader drops what a writer sent before it knew the writer (a restarted coordinator's "up" event
# lost once in CI, when the metrics' reader was volatile). Discovery completes both sides in this.
METRICS_SETTLE_S = 0.5


class CoordinatorNode(Node):
    """The coordinator's ROS shell (see the module doc).

    Args:
        core: the assignment and reservation logic.
        dead: robot -> [ns] simulated time a ``kill-robot`` fault kills it (from ``--faults``).
        stall_report: [s] wall: a sync or a hand-over that has waited this long is reported.
        **kwargs: passed to :class:`rclpy.node.Node`.
    """

    def __init__(self, core: CoordinatorCore, dead: dict[str, int] | None = None,
                 stall_report: float = 10.0, metrics_absent_s: float = METRICS_ABSENT_S,
                 **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        # state
        self.core = core
        self._dead = dict(dead or {})
        self._metrics_absent_s = metrics_absent_s
        self._heard_all: float | None = None  # time.monotonic() every robot was heard
        self._pending = []
        self._syncing = True
        self._clock_ns: int | None = None  # the latest simulated time on /clock
        self._awaiting: dict[str, int] = {}  # robot -> the unsolicited assignment not delivered
        self._held: tuple[list, list] = ([], [])  # a batch's answers and events, until delivered
        self._stall = StallReport(stall_report)  # the current sync's or hand-over's wait
        self._metrics_seen: float | None = None  # time.monotonic() the metrics' reader appeared
        self._matched_since: float | None = None  # time.monotonic() every reader was matched
        self._warned = 0.0
        # publishers, subscribers
        self._assign_pubs = {ns: publisher(self, String, topics.ASSIGNMENT, ns)
                             for ns in core.robots}
        self._events_pub = publisher(self, DiagnosticArray, topics.EVENTS,
                                     qos=topics.EVENTS_COORDINATOR_WRITER_QOS)
        self._state_pub = publisher(self, String, topics.COORDINATOR_STATE)
        subscription(self, String, topics.COORDINATOR_REQUEST, self._on_request,
                     qos=topics.COORDINATOR_REQUEST_READER_QOS)
        subscription(self, Clock, topics.CLOCK, self._on_clock,
                     qos=topics.CLOCK_COORDINATOR_READER_QOS)
        subscription(self, DiagnosticStatus, topics.SUPERVISION, self._on_supervision)
        # timers
        self._poll_timer = self.create_timer(
            SYNC_POLL_S, self._on_poll, clock=RclpyClock(clock_type=ClockType.STEADY_TIME))
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
        if req.kind == "delivered":
            if self._awaiting.get(req.robot, req.delivered + 1) <= req.delivered:
                del self._awaiting[req.robot]
                self._release_held()
            return
        if req.kind in ("ready", "done"):  # it is here: the robot's navigator may go on
            self._assign_pubs[req.robot].publish(String(data=encode_assignment(Assignment(
                robot=req.robot, seq=0, reply_to=req.seq, kind="ack", target="",
                pose=(0.0, 0.0, 0.0), stamp_ns=req.stamp_ns, epoch=self.core.epoch))))
        self._pending.append(req)
        self._handle_due()

    def _on_supervision(self, msg: DiagnosticStatus) -> None:
        """Robots whose navigator is gone for good (the supervisor gave up, a lost host): dead
        from now on, as a ``kill-robot`` fault's robot is (not waited for at a sync, never
        handed a workstation). A failure, not a schedule: such a run is not reproducible."""
        if msg.name != LOST:
            return
        word = RobotsLost.decode({kv.key: kv.value for kv in msg.values})
        if word is None or not word.for_good:
            return
        now = self._clock_ns or 0
        for ns in word.robots:
            if ns in self.core.robots and self._dead.get(ns, now + 1) > now:
                self._dead[ns] = now
                self.get_logger().warning(f"{ns} is gone for good ({word.reason})")
        self._handle_due()

    def _on_clock(self, msg: Clock) -> None:
        t = msg.clock.sec * NS_PER_S + msg.clock.nanosec
        if self._clock_ns is None or t > self._clock_ns:
            self._clock_ns = t
            self._handle_due()

    def _on_poll(self) -> None:
        if self._syncing:
            self._handle_due()
        waited = self._stall.due(time.monotonic())
        if waited is not None:
            unheard = self._unheard()
            if not self._syncing:
                what = f"the delivery of hand-overs to {', '.join(sorted(self._awaiting))}"
            elif unheard:
                what = f"every robot's first word (missing: {', '.join(unheard[:5])})"
            else:
                what = f"the metrics' reader of {topics.EVENTS.name} to be matched"
            self.get_logger().warning(f"waited {waited:.0f} s (wall) for {what}; still waiting "
                                      "(simulated time waits too)")

    # -- batches -----------------------------------------------------------------------------
    def _alive(self, ns: str, t_ns: int) -> bool:
        """Whether robot ``ns`` is alive at simulated time ``t_ns`` (not killed by the faults)."""
        return self._dead.get(ns, t_ns + 1) > t_ns

    def _unheard(self) -> list[str]:
        now = self._clock_ns or 0
        return [ns for ns in self.core.robots if ns not in self.core.heard
                and ns not in {r.robot for r in self._pending} and self._alive(ns, now)]

    def _handle_due(self) -> None:
        """Handle the requests whose batch is complete (see the module doc), unless a batch's
        hand-overs are still on their way."""
        if self._awaiting:
            return
        if self._syncing:
            self._stall.begin(time.monotonic())
            if self._unheard():
                return
            if self._heard_all is None:
                self._heard_all = time.monotonic()
            if not self._metrics_matched():
                return
            self._syncing = False
            self._stall.end()
            batch, self._pending = self._pending, []
        else:
            if self._clock_ns is None:
                return
            batch = [r for r in self._pending if r.stamp_ns < self._clock_ns]
            self._pending = [r for r in self._pending if r.stamp_ns >= self._clock_ns]
        if not batch:
            return
        assignments, events = self.core.handle(batch, alive=self._alive)
        if self._up_event is not None:
            t = min(r.stamp_ns for r in batch)
            events.insert(0, CoordinatorEvent(EVENT_COORDINATOR, "", t, self._up_event.fields,
                                              self.core.epoch))
            self._up_event = None
        unsolicited = [a for a in assignments if a.reply_to == 0]
        for a in unsolicited:
            self._assign_pubs[a.robot].publish(String(data=encode_assignment(a)))
            self._awaiting[a.robot] = a.seq
        self._held = ([a for a in assignments if a.reply_to != 0], events)
        if self._awaiting:
            self._stall.end()
            self._stall.begin(time.monotonic())
        self._release_held()

    def _release_held(self) -> None:
        """Send the held answers and events once every hand-over of their batch is delivered,
        then handle whatever has become due meanwhile."""
        if self._awaiting:
            return
        self._stall.end()
        answers, events = self._held
        self._held = ([], [])
        for a in answers:
            self._assign_pubs[a.robot].publish(String(data=encode_assignment(a)))
        self._publish_events(events)
        if answers or events:
            self._handle_due()

    def _metrics_matched(self) -> bool:
        """Whether the metrics' reader of ``/swarm/events`` is discovered and matched.

        The first batch carries the "up" event and the reservations rebuilt after a restart;
        the metrics' reader is transient local and gets from the writer's history what went out
        before it matched, but a reader that never matches loses it (and its conflict check
        would see releases of unknown reservations). Other readers (the fault nodes of the group
        processes, a recorder) may match first, so the metrics node is looked for by name, and
        every reader the graph knows must be matched; a reader that never matches (incompatible
        QoS, e.g. a ``ros2 topic echo`` asking for deadline or liveliness this writer does not
        offer) is given up on :data:`METRICS_MATCH_GRACE_S` after the metrics' reader appeared;
        with no metrics node at all (a coordinator without swarm-up) the first answers go out
        ``metrics_absent_s`` after every robot was heard.
        The writer's side of a match comes first; the readers' side is given
        :data:`METRICS_SETTLE_S` more. (Only when the first answers go out depends on this, not
        what they are: simulated time waits for them.)
        """
        readers = self.get_subscriptions_info_by_topic(topics.EVENTS.name)
        now = time.monotonic()
        if not any(r.node_name == METRICS_NODE for r in readers):
            # no swarm-up (a coordinator started by hand): go on after METRICS_ABSENT_S
            return (self._metrics_seen is None and self._heard_all is not None
                    and now - self._heard_all >= self._metrics_absent_s)
        if self._metrics_seen is None:
            self._metrics_seen = now
        if self._events_pub.get_subscription_count() < len(readers):
            self._matched_since = None
            return now - self._metrics_seen >= METRICS_MATCH_GRACE_S
        if self._matched_since is None:
            self._matched_since = now
        return now - self._matched_since >= METRICS_SETTLE_S

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
                values=key_values(e.values())))
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
    p.add_argument("--faults", default=None, metavar="SPEC",
                   help="the run's fault schedule (swarm-up's --faults, inline or a YAML file): "
                   "robots a kill-robot fault kills are not waited for (default: none)")
    add_policy_args(p)
    p.add_argument("--service-time", type=cli.non_negative_float, default=None, metavar="SEC",
                   help="simulated seconds a robot stays at a workstation it reached before it "
                   "leaves and the workstation is handed over (default: the world's "
                   "service_time, else 0)")
    p.add_argument("--stall-report", type=cli.positive_float, default=10.0, metavar="SEC",
                   help="wall seconds the first answers (every robot's first word) or a "
                   "hand-over's delivery may wait before it is reported; it goes on waiting, "
                   "as simulated time does (default: %(default)s)")
    return p


WAITING_SPOTS = ("near", "hall")


POLICY_FLAGS = ("policy", "assignment", "waiting_spots", "silence_timeout", "eta_speed",
                "dock_clear", "lease", "queue_at")


def add_policy_args(p, defaults: bool = True) -> None:
    """The coordinator's policy flags (``swarm-coordinator``'s, and ``swarm-up``'s, which passes
    them on: ``defaults=False`` leaves them None when not given): ``--policy``,
    ``--assignment``, ``--waiting-spots``, ``--silence-timeout``, ``--eta-speed``,
    ``--dock-clear``, ``--lease`` (attributes :data:`POLICY_FLAGS`)."""
    from swarm_coordinator.core import (
        ASSIGNMENTS,
        DOCK_CLEAR_S,
        ETA_SPEED,
        LEASE_S,
        POLICIES,
        QUEUES_AT,
        SILENCE_TIMEOUT_S,
    )

    p.add_argument("--policy", choices=POLICIES, default=POLICIES[0] if defaults else None,
                   help="centralized: reserve (default; Open-RMF-like) holds a workstation from "
                   "dispatch until its robot is done there, queueing the others at waiting "
                   "spots; pipelined sends every robot at once to the workstation where its "
                   "time window from ETAs begins first, holds nothing, and leaves the queue "
                   "at the workstation to the navigators' holding pattern")

    p.add_argument("--assignment", choices=ASSIGNMENTS,
                   default=ASSIGNMENTS[0] if defaults else None,
                   help="centralized: nearest-free (default) sends a robot whose route's "
                   "workstation is taken to the nearest free one of its kind (path length), and "
                   "a freed workstation to the longest waiter of its kind; route: only the "
                   "route's workstation, queued for it")
    p.add_argument("--waiting-spots", choices=WAITING_SPOTS,
                   default=WAITING_SPOTS[0] if defaults else None,
                   help="centralized: where queued robots wait after each workstation's holding "
                   "spot: near (default) the world's waiting spots (the points of interest's "
                   "'waiting'), then the spawn grid; hall: the spawn grid only")
    p.add_argument("--silence-timeout", type=cli.non_negative_float,
                   default=SILENCE_TIMEOUT_S if defaults else None,
                   metavar="SEC", help="centralized: simulated seconds a robot may hold a "
                   "workstation without a word before the coordinator frees it (0: never) "
                   f"(default: {SILENCE_TIMEOUT_S:g})")
    p.add_argument("--eta-speed", type=cli.positive_float,
                   default=ETA_SPEED if defaults else None, metavar="M_PER_S",
                   help="pipelined: the speed a robot's ETA is reckoned with: path length on "
                   f"the map over it (default: {ETA_SPEED:g})")
    p.add_argument("--dock-clear", type=cli.non_negative_float,
                   default=DOCK_CLEAR_S if defaults else None, metavar="SEC",
                   help="pipelined: simulated seconds a workstation's time window lasts beyond "
                   f"the service time (default: {DOCK_CLEAR_S:g})")
    p.add_argument("--queue-at", choices=QUEUES_AT, default=QUEUES_AT[0] if defaults else None,
                   help="pipelined: where a robot whose window does not begin on its arrival "
                   "waits: spots (default) in line at a spot near its workstation, sent on when "
                   "first in line; holding: it is sent to its workstation at once and queues in "
                   "the navigators' holding pattern (their queue rules on)")
    p.add_argument("--lease", type=cli.non_negative_float,
                   default=LEASE_S if defaults else None, metavar="SEC",
                   help="pipelined: simulated seconds after its window began that a silent "
                   f"robot keeps it (0: for ever) (default: {LEASE_S:g})")


def policy_argv(args) -> tuple[str, ...]:
    """The policy flags given in ``args`` (a parsed namespace) as ``swarm-coordinator``
    arguments, in a fixed order; those not given (None) are left out."""
    out = []
    for key in POLICY_FLAGS:
        value = getattr(args, key, None)
        if value is not None:
            out += [f"--{key.replace('_', '-')}", f"{value:g}" if isinstance(value, float)
                    else str(value)]
    return tuple(out)


def path_lengths(world_path, stations) -> Callable[[tuple[float, float], str], float]:
    """``distance(xy, workstation)`` [m]: the global planner's path length on the world's map
    (:func:`swarm_nav.planner.plan_path` with the navigator's default costmap and planner
    settings), the straight line where there is no map or no path; cached per 0.5 m cell."""
    from swarm_common import paths
    from swarm_nav.config import CostmapConfig, PlannerConfig
    from swarm_nav.costmap import build_costmap
    from swarm_nav.planner import path_length, plan_path
    from swarm_scene.map_io import load_map

    map_path = paths.default_map_for(world_path)
    costmap = build_costmap(load_map(map_path), CostmapConfig()) if map_path else None
    poses = {s.name: s.pose for s in stations}
    cache: dict[tuple[int, int, str], float] = {}

    def distance(xy: tuple[float, float], name: str) -> float:
        key = (round(xy[0] * 2), round(xy[1] * 2), name)
        if key not in cache:
            goal = poses[name]
            res = plan_path(costmap, xy, goal[:2], PlannerConfig()) if costmap else None
            cache[key] = (path_length(res.path) if res is not None and res.path is not None
                          else math.hypot(xy[0] - goal[0], xy[1] - goal[1]))
        return cache[key]

    return distance


def build_core(world: str, seed: int, robots: tuple[str, ...], robot_model: str,
               control_period: float, epoch: str, assignment: str = "nearest-free",
               waiting_spots: str = "near", silence_timeout: float | None = None,
               service_time: float | None = None, policy: str = "reserve",
               eta_speed: float | None = None, dock_clear: float | None = None,
               lease: float | None = None, queue_at: str = "spots") -> CoordinatorCore:
    """The core for a world: its workstations, holding spots, its waiting spots (``near``),
    parking on the spawn grid, each robot's route (:func:`swarm_commander.route.build_route`,
    as the commanders') and start (the spawn grid's pose of its number), and path lengths on
    the map (:func:`path_lengths`). ``service_time`` [s] simulated: None takes the world's.

    Raises:
        InputError: the world is unknown or has no workstations (names ``--world``).
    """
    from swarm_commander.route import build_route
    from swarm_coordinator.core import Station, spots_from_poi
    from swarm_scene.fleet import fleet_models
    from swarm_scene.poi import poi_for_world
    from swarm_scene.robot_model import load_robot
    from swarm_scene.spawn import spawn_poses
    from swarm_scene.world import load_world, resolve_world, world_polygons

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

    from swarm_coordinator.core import SILENCE_TIMEOUT_S

    timeout = SILENCE_TIMEOUT_S if silence_timeout is None else silence_timeout
    from swarm_coordinator.core import DOCK_CLEAR_S, ETA_SPEED, LEASE_S

    service = poi.service_time if service_time is None else service_time
    cfg = CoordinatorConfig(
        period_ns=round(control_period * NS_PER_S), assignment=assignment,
        silence_timeout_ns=round(timeout * NS_PER_S), service_time_ns=round(service * NS_PER_S),
        policy=policy, eta_speed=ETA_SPEED if eta_speed is None else eta_speed,
        dock_clear_ns=round((DOCK_CLEAR_S if dock_clear is None else dock_clear) * NS_PER_S),
        lease_ns=round((LEASE_S if lease is None else lease) * NS_PER_S), queue_at=queue_at)
    start = ({ns: (float(p[0]), float(p[1])) for ns, p in zip(robots, parking, strict=False)}
             if parking is not None else None)
    distance = path_lengths(path, stations) if assignment != "route" else None
    return CoordinatorCore(robots, stations,
                           spots_from_poi(poi, parking, near=waiting_spots == "near"),
                           next_stop, cfg, epoch=epoch, distance=distance, start_xy=start)


def _run(argv: list[str]) -> int:
    try:
        plain = remove_ros_args([PROG, *argv])[1:]
    except RCLInvalidROSArgsError as exc:
        raise InputError(f"--ros-args: {str(exc).splitlines()[0]}") from None
    opts = build_parser().parse_args(plain)
    robots = tuple(f"{opts.name_prefix}{i}" for i in range(1, opts.swarm_size + 1))
    epoch = uuid.uuid4().hex[:12]  # fixed length: message sizes do not depend on it
    core = build_core(opts.world, opts.seed, robots, opts.robot, opts.control_period, epoch,
                      opts.assignment, opts.waiting_spots, opts.silence_timeout,
                      opts.service_time, opts.policy, opts.eta_speed, opts.dock_clear,
                      opts.lease, opts.queue_at)
    dead = {}
    if opts.faults:
        from swarm_common.faults import KILL_ROBOT, parse_faults

        try:
            faults = parse_faults(opts.faults, robots, opts.name_prefix)
        except InputError as exc:
            raise InputError(f"--faults: {exc}") from None
        dead = {f.robot: f.at_ns for f in faults if f.kind == KILL_ROBOT}
    with node_session([PROG, *argv]) as nodes:
        node = CoordinatorNode(core, dead, opts.stall_report)
        nodes.append(node)
        print(f"{PROG}: up (epoch {epoch}): {len(robots)} robots, {len(core.stations)} "
              f"workstations, {len(core.spots)} waiting spots; policy {opts.policy}, "
              f"assignment {opts.assignment}, "
              f"waiting spots {opts.waiting_spots}, service time "
              f"{core.cfg.service_time_ns / NS_PER_S:g} s", flush=True)
        executor = EventsExecutor()
        executor.add_node(node)
        spin_forever(executor, node.context)
    return 0


def main(args: list[str] | None = None) -> int:
    """Entry point of ``swarm-coordinator``; 0 on Ctrl-C, 2 on bad input."""
    return run_cli(PROG, lambda: _run(list(sys.argv[1:] if args is None else args)))


if __name__ == "__main__":
    sys.exit(main())
