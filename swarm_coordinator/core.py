"""The coordinator's logic: a task scheduler with first-come-first-served reservations (pure).

No ROS here (STYLE.md rule 1): :class:`CoordinatorCore` takes decoded
:class:`~swarm_common.coordination.Request` records and returns the
:class:`~swarm_common.coordination.Assignment` records to send and the
:class:`~swarm_common.coordination.CoordinatorEvent` records to publish; the node
(:mod:`swarm_coordinator.node`) only converts messages and decides when a batch is complete.

The model is Open-RMF's reservation node (``rmf_reservation``: a robot asks for a resource, the
first to ask gets it, later askers are queued and parked at a waiting spot until it frees up):

- Every robot has its own route: the same seeded order of workstations the decentralized
  commander would visit (:func:`swarm_commander.route.build_route`), so both modes do the same
  tasks. When a robot asks for its next task (``ready`` or ``done``) the core takes the next
  workstation W of its route.
- W free (and nobody queued for it): W is reserved for the robot, which is sent there (``go``).
- W taken (or, ``nearest-free``, W is where the robot stands: its route's next stop after it
  was sent elsewhere), assignment ``nearest-free`` (:data:`ASSIGN_NEAREST_FREE`, the
  default): the robot is sent to the free workstation of W's kind
  (:func:`~swarm_nav.holding.workstation_kind`, the kinds the decentralized navigators'
  ``swap_range`` swaps within) nearest to where it is by path length on the map (ties: the
  workstation's order in the world), other than the one it has just left, if there is one.
  This is the scheduler the decentralized side's goal flexibility is matched with: it alone
  knows which workstations are free.
- Otherwise the robot joins W's queue (first come, first served: ordered by the simulated time
  of its request, then by robot number) and is sent to a free waiting spot (``wait``), reserved
  for it: W's own holding spot first, else the free spot nearest W (straight line) among the
  world's waiting spots near the workstations (``waiting`` of the points of interest; the
  coordinator's ``--waiting-spots near``) and the parking spots on the spawn grid (the hall).
  No two robots are ever sent to one spot.
- Moving up: when a holding spot frees up, the first robot of its workstation's queue that waits
  farther away moves up to it, so the next hand-over is a short drive.
- A robot that reports ``done`` at W leaves it: W is released at the request's stamp t and
  handed over to the first robot of W's queue; with nobody queued for W, ``nearest-free`` hands
  it to the nearest robot (path length from where it waits) of those queued for another
  workstation of W's kind, one that has not just left W if there is one. The hand-over's goal
  is stamped
  ``t + period`` (``handover_ticks``), the tick at which the batch is handled, so it moves off
  its spot at tick ``t + 2 period``, whatever the wall-clock latency: the node sends the batch's
  answers, which the simulator waits for at ``t + period``, only once that robot's navigator
  has the goal (:mod:`swarm_coordinator.node`).
- Service time (``service_time_ns``, the world's ``service_time``): a robot that reached its
  workstation at t stays there until t + service; the workstation is released and handed over
  then, and the robot's next goal is stamped then (every stamp is known at t: reproducible).
- A goal that failed or was canceled releases its workstation too; the robot moves on to the next
  stop of its route (as the decentralized commander does).
- A dead robot loses what it holds: one the ``alive`` predicate of :meth:`CoordinatorCore.handle`
  says is dead (a ``kill-robot`` fault, the supervisor's word) at the batch's time, and one that
  has held a workstation for ``silence_timeout_ns`` of simulated time without a word (its
  navigator would have said ``done`` long before; Open-RMF's reservation node likewise expires a
  reservation). Its workstation and spot are released and handed over; a silent robot that
  speaks again is taken at its word (its task still counts).
- A robot the core has not heard from (a coordinator restarted with empty tables) is taken at its
  word: the resources it reports are reserved for it if free; a workstation held by another robot
  meanwhile sends it to a waiting spot instead. What every such robot of a batch holds is taken
  over, and then the waiting ones queued, before any request of the batch is answered.

**Pipelined** (``policy`` :data:`POLICY_PIPELINED`; ``swarm-up --policy pipelined``): what a
warehouse fleet manager does beyond Open-RMF's reservations (VDA 5050 releases a route piece by
piece; zones are leased, and released on exit). Nothing is held from dispatch to arrival:

- When a robot asks for its next task at t (leaving at t + service), it is booked on a
  workstation: its route's, if its *time window* there would begin on its arrival (and it has
  not just left it), else (``nearest-free``) the one of its route's kind where its window would
  begin first (:meth:`CoordinatorCore.choose_window`). Its ETA is t + the path length on the map
  from where it stands (the workstation it left, or its spawn pose) over ``eta_speed``; a
  workstation's windows are its booked robots in order of ETA (hand-over by arrival time, not
  by who asked first), each beginning at its ETA, when the one before ends or now, whichever is
  latest, and lasting the service time plus ``dock_clear_ns``.
- ``queue_at`` :data:`QUEUE_AT_HOLDING`: the robot is sent there at once (``go``). Who docks
  first, and the queue in front of the workstation, are the navigators' own rules (the holding
  pattern: first come, first served among robots that see each other, the queue rule, the
  congestion rule); swarm-up turns only ``swap_range`` off (the coordinator chose the
  workstation). Nothing is reserved.
- ``queue_at`` :data:`QUEUE_AT_SPOTS`: the robot is sent there at once when it is first in
  line, or its window begins on its arrival and nobody ahead of it in line is past their ETA;
  else it waits in line at a spot (the workstation's holding spot first, as the reserve
  policy's queues) and is sent on when it is first in line (the one before it said ``done``),
  one hand-over later; a freed holding spot is taken by the first in line waiting farther away.
  The spots are reserved; the navigators' queue rules are off, as under the reserve policy.
- A robot's ``done`` ends its window. No fault schedule is read: a robot sent to its
  workstation that has not spoken for ``lease_ns`` after its window began loses the window (a
  dead robot no longer delays the others'); a task it completes after all still counts.
- What the coordinator knows of a robot's position is where it stood when it asked (the
  workstation it left, its spawn pose or its spot), exact then; ETAs are not updated from live
  positions on the way.

Requests of one batch are handled in order of (stamp, robot number), never in arrival order, so
one batch gives the same answers whatever order its messages came in.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from swarm_common.coordination import (
    EVENT_LAPSE,
    EVENT_RESERVATION,
    EVENT_TASK,
    Assignment,
    CoordinatorEvent,
    Request,
    spot_resource,
    workstation_resource,
)
from swarm_common.stamps import NS_PER_S, format_stamp_ns


@dataclass(frozen=True)
class Station:
    """A workstation: its name and docking pose (3,) x [m], y [m], yaw [rad] in ``map``."""

    name: str
    pose: tuple[float, float, float]


@dataclass(frozen=True)
class Spot:
    """A waiting spot.

    Attributes:
        id: ``<workstation>.<i>`` for the i-th holding point of a workstation, ``park<k>`` for a
            parking spot.
        xy: (x [m], y [m]) in ``map``.
        near: the workstation whose holding spot it is, or ``""`` for a parking spot.
        yaw: [rad] heading to park with (a holding spot faces its workstation).
    """

    id: str
    xy: tuple[float, float]
    near: str = ""
    yaw: float = 0.0


POLICY_RESERVE = "reserve"
POLICY_PIPELINED = "pipelined"
POLICIES = (POLICY_RESERVE, POLICY_PIPELINED)
QUEUE_AT_SPOTS = "spots"
QUEUE_AT_HOLDING = "holding"
QUEUES_AT = (QUEUE_AT_SPOTS, QUEUE_AT_HOLDING)
ASSIGN_ROUTE = "route"
ASSIGN_NEAREST_FREE = "nearest-free"
ASSIGNMENTS = (ASSIGN_NEAREST_FREE, ASSIGN_ROUTE)
SILENCE_TIMEOUT_S = 600.0
"""[s] simulated: a robot that holds a workstation this long without a word has died. Five times
the longest time to task of a run at 100 robots on slim_blockage (decentralized p95 109 s, 120 s
run), so a robot stuck in traffic keeps its reservation."""
ETA_SPEED = 0.4
"""[m/s] pipelined: the speed of an ETA (see :class:`CoordinatorConfig`). Tuned with
:data:`DOCK_CLEAR_S` on slim_blockage, 50 robots, ``--queue-at holding``, 600 s, seeds 0 and 1,
over 0.15 / 0.25 / 0.4 m/s x 2 / 8 s: the highest Jain's index among the settings within 5 % of
the best throughput (docs/results/experiments.md, "Tuning the pipelined arm"). Faster than the
robots drive: an ETA is an order of arrival more than a time."""
DOCK_CLEAR_S = 2.0
"""[s] simulated, pipelined: a window's length beyond the service (tuned with
:data:`ETA_SPEED`)."""
LEASE_S = 300.0
"""[s] simulated, pipelined: a window lapses this long after it began without a ``done``."""


@dataclass(frozen=True)
class CoordinatorConfig:
    """Settings of the coordinator's core.

    Attributes:
        assignment: :data:`ASSIGN_NEAREST_FREE` or :data:`ASSIGN_ROUTE` (the module doc).
        silence_timeout_ns: [ns] simulated; 0: never expire a reservation for silence.
        period_ns: [ns] the simulator's control tick.
        handover_ticks: a goal handed to a waiting robot is stamped this many ticks after the
            release, the tick at which the batch is handled (so it takes effect one tick later
            still, see the module doc): the simulator cannot pass that tick before the robot has
            the goal (the node holds the batch's answers until it is delivered).
    """

    period_ns: int = NS_PER_S // 10
    handover_ticks: int = 1  # [ticks] a handed-over goal's stamp after the release
    assignment: str = ASSIGN_NEAREST_FREE
    silence_timeout_ns: int = round(SILENCE_TIMEOUT_S * NS_PER_S)
    service_time_ns: int = 0
    policy: str = POLICY_RESERVE
    eta_speed: float = ETA_SPEED
    dock_clear_ns: int = round(DOCK_CLEAR_S * NS_PER_S)
    lease_ns: int = round(LEASE_S * NS_PER_S)
    queue_at: str = "spots"

    def __post_init__(self) -> None:
        if self.assignment not in ASSIGNMENTS:
            raise ValueError(f"assignment must be one of {ASSIGNMENTS}, got {self.assignment!r}")
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if self.queue_at not in QUEUES_AT:
            raise ValueError(f"queue_at must be one of {QUEUES_AT}, got {self.queue_at!r}")
        if not self.eta_speed > 0.0:
            raise ValueError(f"eta_speed must be > 0 [m/s], got {self.eta_speed!r}")


def spots_from_poi(poi, parking: np.ndarray | None = None,
                   near: bool = True) -> tuple[Spot, ...]:
    """The waiting spots of a world: every holding point of every workstation, the world's
    waiting spots, then parking.

    Args:
        poi: a :class:`swarm_scene.poi.PointsOfInterest` (workstations with ``holding``,
            ``waiting``).
        parking: (K, 2) or (K, 3) parking spots x, y [, yaw] in ``map`` (e.g. the spawn grid:
            free of walls by construction), or None.
        near: include the points of interest's ``waiting`` spots (``--waiting-spots near``);
            False: only holding spots and parking (``hall``).

    Returns:
        The spots, holding spots first (``loader1.0`` ...), then ``wait1`` ... (``near``), then
        ``park1`` ... ``parkK``.
    """
    spots = []
    for w in poi.workstations:
        wx, wy = float(w.pose[0]), float(w.pose[1])
        for i, (x, y) in enumerate(np.asarray(w.holding, float).reshape(-1, 2)):
            spots.append(Spot(f"{w.name}.{i}", (float(x), float(y)), w.name,
                              math.atan2(wy - y, wx - x)))
    if near:
        for k, row in enumerate(np.asarray(getattr(poi, "waiting", ()), float).reshape(-1, 3),
                                start=1):
            spots.append(Spot(f"wait{k}", (float(row[0]), float(row[1])), "", float(row[2])))
    if parking is not None:
        for k, row in enumerate(np.asarray(parking, float), start=1):
            yaw = float(row[2]) if len(row) > 2 else 0.0
            spots.append(Spot(f"park{k}", (float(row[0]), float(row[1])), "", yaw))
    return tuple(spots)


@dataclass
class _Robot:
    index: int
    known: bool = False  # heard from since this core started
    workstation: str = ""  # reserved workstation
    spot: str = ""  # reserved spot
    waits_for: str = ""
    since_ns: int = 0
    task_start_ns: int = 0
    last_seq: int = 0  # last request answered
    last_answer: Assignment | None = None
    sent: int = 0  # assignments sent
    xy: tuple[float, float] | None = None  # where it is, as far as we know (map, m)
    left: str = ""  # the workstation it left last (a task's end)
    held_since_ns: int = 0  # when it got its workstation
    heard_ns: int = 0  # its latest request's stamp
    lapsed: str = ""  # the workstation it lost for silence (its task still counts)
    dead: bool = False  # it lost what it held for good (dead at a batch's time)
    eta_ns: int = 0  # pipelined: when it is reckoned to reach its workstation
    dispatched: bool = True  # pipelined: sent to its workstation (not waiting at a spot)


@dataclass
class _Out:
    assignments: list[Assignment] = field(default_factory=list)
    events: list[CoordinatorEvent] = field(default_factory=list)


class CoordinatorCore:
    """Assignments and reservations for one swarm (see the module doc).

    Args:
        robots: the namespaces without ``/``, in robot order (ties are broken by this order).
        stations: the workstations.
        spots: the waiting spots (:func:`spots_from_poi`); there should be at least as many as
            robots, or a robot may find no spot (it then waits where it is, see
            :meth:`handle`).
        next_stop: ``next_stop(robot)`` -> the name of the robot's next workstation.
        cfg: the settings.
        epoch: this coordinator's run id, copied into its messages.
        distance: ``distance(xy, workstation)`` -> [m] the path length from ``xy`` (x, y in
            ``map``) to a workstation's docking pose (:func:`swarm_coordinator.node.build_core`
            plans it on the map); None: the straight line.
        start_xy: robot -> (x, y) [m] where it starts (its spawn pose), for the first
            ``nearest-free`` choice; a robot without one is taken to stand at its route's first
            workstation.

    Raises:
        ValueError: no workstations, or duplicate names.
    """

    def __init__(self, robots: Sequence[str], stations: Sequence[Station],
                 spots: Sequence[Spot], next_stop: Callable[[str], str],
                 cfg: CoordinatorConfig = CoordinatorConfig(), epoch: str = "",
                 distance: Callable[[tuple[float, float], str], float] | None = None,
                 start_xy: dict[str, tuple[float, float]] | None = None):
        if not stations:
            raise ValueError("the coordinator needs at least one workstation")
        self.stations: dict[str, Station] = {s.name: s for s in stations}
        self.spots: dict[str, Spot] = {s.id: s for s in spots}
        if len(self.stations) != len(stations) or len(self.spots) != len(spots):
            raise ValueError("duplicate workstation or spot names")
        self.robots: dict[str, _Robot] = {ns: _Robot(i) for i, ns in enumerate(robots)}
        self.cfg = cfg
        self.epoch = epoch
        self._next_stop = next_stop
        self._alive: Callable[[str, int], bool] = lambda ns, t: True
        self.holder: dict[str, str] = {}  # resource -> robot
        self.queues: dict[str, list[str]] = {name: [] for name in self.stations}
        self._distance = distance or self._straight
        for ns, xy in (start_xy or {}).items():
            if ns in self.robots:
                self.robots[ns].xy = (float(xy[0]), float(xy[1]))
        from swarm_nav.holding import workstation_kind

        self.kind = {name: workstation_kind(name) for name in self.stations}
        self.bookings: dict[str, list[str]] = {name: [] for name in self.stations}
        """Pipelined: the robots sent to each workstation that have not said ``done``."""
        self.expired = 0  # reservations released because their robot fell silent or died

    # ------------------------------------------------------------------------------ queries
    def holder_of(self, resource: str) -> str | None:
        """The robot holding ``resource`` (``workstation:W`` / ``spot:S``), or None."""
        return self.holder.get(resource)

    def queue(self, workstation: str) -> tuple[str, ...]:
        """The robots waiting for ``workstation``, first in line first."""
        return tuple(self.queues.get(workstation, ()))

    def _straight(self, xy: tuple[float, float], name: str) -> float:
        wx, wy = self.stations[name].pose[:2]
        return math.hypot(xy[0] - wx, xy[1] - wy)

    @property
    def pipelined(self) -> bool:
        """Whether the policy is :data:`POLICY_PIPELINED`."""
        return self.cfg.policy == POLICY_PIPELINED

    @property
    def heard(self) -> set[str]:
        """The robots heard from since this core started."""
        return {ns for ns, r in self.robots.items() if r.known}

    # ------------------------------------------------------------------------------ input
    def order(self, requests: Sequence[Request]) -> list[Request]:
        """The order a batch is handled in: stamp, then robot number, then sequence."""
        big = len(self.robots)
        return sorted(requests, key=lambda r: (
            r.stamp_ns, self.robots[r.robot].index if r.robot in self.robots else big,
            r.robot, r.seq))

    def handle(self, requests: Sequence[Request],
               alive: Callable[[str, int], bool] | None = None
               ) -> tuple[list[Assignment], list[CoordinatorEvent]]:
        """Handle one batch of requests.

        Args:
            requests: decoded requests, in any order; unknown robots are ignored.
            alive: ``alive(robot, t_ns)`` says whether a robot is alive at simulated time
                ``t_ns`` (a ``kill-robot`` fault kills it): a workstation is never handed to a
                dead robot, which is dropped from its queue. None: every robot lives.

        Returns:
            ``(assignments, events)`` in the order they must be sent: a workstation handed
            over to a waiting robot comes before the answer to the robot that freed it.
        """
        out = _Out()
        # pipelined: no oracle; a robot that stops talking loses its window by lease
        self._alive = alive if alive is not None and not self.pipelined else (lambda ns, t: True)
        ordered = self.order(requests)
        self._adopt_batch(ordered, out)
        if ordered:
            self._expire(ordered[0].stamp_ns, {r.robot for r in ordered}, out)
        answered = set()
        for req in ordered:
            rob = self.robots.get(req.robot)
            if rob is None:
                continue
            if req.kind != "report" and req.seq <= rob.last_seq:
                if req.seq == rob.last_seq and rob.last_answer is not None \
                        and req.robot not in answered:
                    out.assignments.append(rob.last_answer)  # a re-sent request
                    answered.add(req.robot)
                continue
            answered.add(req.robot)
            rob.heard_ns = max(rob.heard_ns, req.stamp_ns)
            if req.kind == "report":
                continue
            rob.last_seq = req.seq
            t = req.stamp_ns
            if req.kind == "done":
                t = self._done(req, rob, out)
            self._next_task(req.robot, rob, t, req.seq, out)
        return out.assignments, out.events

    # ------------------------------------------------------------------------------ steps
    def _adopt_batch(self, ordered: Sequence[Request], out: _Out) -> None:
        """Take over what the robots of a batch we have not heard from hold, then queue those
        that wait, before any of the batch's requests is answered.

        Robot by robot, a restarted coordinator answered a request stamped before another
        robot's report with the spot that robot reported standing on (10 robots, seed 2, the
        coordinator killed at 180 s and restarted at 210 s: Srobot10's ``done`` of 194.6 s got
        loader5's holding spot, where Srobot4 had waited since 125 s, and Srobot4 completed no
        task to the end; taken over first, Srobot10 was parked in the hall and Srobot4 got
        loader5 at 284 s).
        """
        fresh = []
        for req in ordered:
            rob = self.robots.get(req.robot)
            if rob is not None and not rob.known:
                rob.known = True
                fresh.append((req, rob))
        claimed = [self._adopt_holdings(req, rob, out) for req, rob in fresh]
        for (req, rob), taken in zip(fresh, claimed, strict=True):
            for name in taken:  # someone holds it meanwhile: wait for it
                self._queue_or_go(req.robot, rob, name, req.stamp_ns, 0, out)
        waiting = [(req, rob) for req, rob in fresh if self._adopt_waiting(req, rob)]
        # Only with every waiter queued in its order: a free workstation goes to the robot that
        # has waited longest, not to the first of the batch (10 robots, seed 2, restart at
        # 210 s: loader5 went to a robot parked in the hall since 124.5 s over the one on its
        # holding spot since 105 s).
        t = max((req.stamp_ns for req, _ in waiting), default=0)
        if self.pipelined:
            for name in dict.fromkeys(req.waits_for for req, _ in waiting):
                self._dispatch_head(name, t, out)
            return
        for name in dict.fromkeys(rob.waits_for for _, rob in waiting):
            if self.queues[name] and self.holder.get(workstation_resource(name)) is None:
                self._hand_over(name, t, out)

    def _adopt_holdings(self, req: Request, rob: _Robot, out: _Out) -> list[str]:
        """Reserve what a robot we have not heard from says it holds, where still free.

        Returns:
            The workstations a ``report`` claims that another robot holds meanwhile.
        """
        t = req.stamp_ns
        rob.task_start_ns = req.task_start_ns
        taken = []
        for res in req.holds:
            kind, _, name = res.partition(":")
            if kind == "workstation" and name in self.stations and self.pipelined:
                if req.robot not in self.bookings[name]:  # its window: reckoned from now
                    self.bookings[name].append(req.robot)
                rob.workstation, rob.held_since_ns, rob.eta_ns = name, t, t
                rob.dispatched = True
            elif kind == "workstation" and name in self.stations:
                if self.holder.get(res) in (None, req.robot):
                    self._reserve(req.robot, res, t, out)
                    rob.workstation, rob.held_since_ns = name, t
                elif req.kind == "report":
                    taken.append(name)
            elif kind == "spot" and name in self.spots:
                if self.holder.get(res) in (None, req.robot):
                    self._reserve(req.robot, res, t, out)
                    rob.spot = name
        return taken

    def _adopt_waiting(self, req: Request, rob: _Robot) -> bool:
        """Queue a robot we have not heard from for the workstation it says it waits for.

        Returns:
            Whether it was queued (:meth:`_adopt_batch` hands free workstations over after).
        """
        want = req.waits_for
        if self.pipelined:
            if want in self.stations and req.robot not in self.bookings[want]:
                self.bookings[want].append(req.robot)  # in line by when it began to wait
                rob.workstation, rob.eta_ns, rob.dispatched = want, req.since_ns, False
                return True
            return False
        if want in self.stations and not rob.workstation and req.robot not in self.queues[want]:
            rob.waits_for, rob.since_ns = want, req.since_ns
            self._enqueue(req.robot, want)
            return True
        return False

    def _done(self, req: Request, rob: _Robot, out: _Out) -> int:
        """A task's goal ended: count the task, release the workstation, hand it over.

        Returns:
            [ns] when the robot leaves: the request's stamp, plus the service time after a
            goal that succeeded (the workstation is released and handed over then).
        """
        t = req.stamp_ns
        leave = t + (self.cfg.service_time_ns if req.outcome == "succeeded" else 0)
        name = req.target
        if name in self.stations:
            rob.left, rob.xy = name, tuple(self.stations[name].pose[:2])
        if rob.lapsed and rob.lapsed == name and not rob.workstation:
            if req.outcome == "succeeded":  # it got there after all: the task counts
                out.events.append(CoordinatorEvent(EVENT_TASK, req.robot, t, {
                    "workstation": name, "t_start": format_stamp_ns(rob.task_start_ns),
                    "duration_s": f"{(t - rob.task_start_ns) / NS_PER_S:.3f}"}, self.epoch))
            rob.lapsed = ""
            return leave
        if rob.workstation and rob.workstation == name:
            if req.outcome == "succeeded":
                out.events.append(CoordinatorEvent(EVENT_TASK, req.robot, t, {
                    "workstation": name, "t_start": format_stamp_ns(rob.task_start_ns),
                    "duration_s": f"{(t - rob.task_start_ns) / NS_PER_S:.3f}"}, self.epoch))
            rob.workstation = ""
            if self.pipelined:
                self.bookings[name].remove(req.robot)
                self._dispatch_head(name, leave, out)
                return leave
            self._release(req.robot, workstation_resource(name), leave, out)
            self._hand_over(name, leave, out)
        return leave

    def _next_task(self, ns: str, rob: _Robot, t: int, reply_to: int, out: _Out) -> None:
        name = self._next_stop(ns)
        if name not in self.stations:
            raise ValueError(f"route of {ns} names an unknown workstation {name!r}")
        rob.task_start_ns = t
        if self.pipelined:
            self._book(ns, rob, name, t, reply_to, out)
        else:
            self._queue_or_go(ns, rob, name, t, reply_to, out)

    def _free(self, name: str, ns: str) -> bool:
        """Whether workstation ``name`` may go to robot ``ns`` now: nobody else holds it and
        nobody is queued for it."""
        return self.holder.get(workstation_resource(name)) in (None, ns) \
            and not self.queues[name]

    def choose(self, ns: str, name: str) -> str:
        """The workstation robot ``ns`` is sent to when its route says ``name`` (the module
        doc): ``name`` if free, else (``nearest-free``) the nearest free one of its kind other
        than the one it has just left, else ``name`` (it queues there). ``name`` itself when the
        robot has just left it (its route's stop after a diversion) counts as taken."""
        rob = self.robots[ns]
        if self.cfg.assignment == ASSIGN_ROUTE or (self._free(name, ns) and name != rob.left):
            return name
        xy = rob.xy if rob.xy is not None else tuple(self.stations[name].pose[:2])
        free = [w for w in self.stations if self.kind[w] == self.kind[name] and w != rob.left
                and self._free(w, ns)]
        if not free:
            return name
        order = {w: i for i, w in enumerate(self.stations)}
        return min(free, key=lambda w: (self._distance(xy, w), order[w]))

    def _queue_or_go(self, ns: str, rob: _Robot, name: str, t: int, reply_to: int,
                     out: _Out) -> None:
        name = self.choose(ns, name)
        res = workstation_resource(name)
        if self._free(name, ns):
            if self.holder.get(res) is None:
                self._reserve(ns, res, t, out)
            rob.workstation, rob.held_since_ns = name, t
            self._send(ns, rob, "go", name, self.stations[name].pose, t, reply_to, "", out)
            return
        rob.waits_for, rob.since_ns = name, t
        self._enqueue(ns, name)
        spot = self._free_spot(name)
        if spot is None:  # no spot left: the robot waits where it stands (no goal)
            rob.last_answer = None
            return
        self._reserve(ns, spot_resource(spot.id), t, out)
        rob.spot, rob.xy = spot.id, spot.xy
        self._send(ns, rob, "wait", spot.id, (*spot.xy, spot.yaw), t, reply_to, name, out)

    def next_waiter(self, name: str, t: int) -> str | None:
        """The robot a free workstation ``name`` goes to at simulated time ``t`` [ns] (the
        module doc), or None; dead robots are dropped from the queues on the way."""
        kinds = [name] if self.cfg.assignment == ASSIGN_ROUTE else [
            w for w in self.stations if self.kind[w] == self.kind[name]]
        for w in kinds:
            self.queues[w] = [ns for ns in self.queues[w] if self._alive(ns, t)]
        waiters = [ns for w in kinds for ns in self.queues[w]]
        if not waiters:
            return None
        own = [ns for ns in self.queues[name] if ns in waiters]
        if self.cfg.assignment == ASSIGN_ROUTE or own:
            return min(own or waiters, key=self._fifo)
        others = [ns for ns in waiters if self.robots[ns].left != name] or waiters
        here = tuple(self.stations[name].pose[:2])
        return min(others, key=lambda ns: (self._distance(self.robots[ns].xy or here, name),
                                           *self._fifo(ns)))

    def _fifo(self, ns: str) -> tuple[int, int]:
        """Queue order: when the robot began to wait, then its number."""
        return self.robots[ns].since_ns, self.robots[ns].index

    def _hand_over(self, name: str, t: int, out: _Out) -> None:
        """Give a free workstation to the next waiter (:meth:`next_waiter`), with a goal one
        tick later."""
        start = t + self.cfg.handover_ticks * self.cfg.period_ns
        if self.holder.get(workstation_resource(name)) is not None:
            return
        ns = self.next_waiter(name, start)
        if ns is None:
            return
        rob = self.robots[ns]
        self.queues[rob.waits_for].remove(ns)
        freed = self.spots.get(rob.spot)
        if rob.spot:
            self._release(ns, spot_resource(rob.spot), start, out)
            rob.spot = ""
        self._reserve(ns, workstation_resource(name), start, out)
        rob.workstation, rob.waits_for, rob.since_ns = name, "", 0
        rob.held_since_ns = start
        self._send(ns, rob, "go", name, self.stations[name].pose, start, 0, "", out)
        if freed is not None and freed.near:
            self._move_up(freed.near, freed, start, out)

    def _move_up(self, name: str, freed: Spot, t: int, out: _Out) -> None:
        """The first robot of ``name``'s queue that waits farther away moves up to the
        workstation's freed holding spot, so the next hand-over is a short drive."""
        for ns in self.queues[name]:
            rob = self.robots[ns]
            if rob.spot and self.spots[rob.spot].near != name and self._alive(ns, t):
                self._release(ns, spot_resource(rob.spot), t, out)
                self._reserve(ns, spot_resource(freed.id), t, out)
                rob.spot, rob.xy = freed.id, freed.xy
                self._send(ns, rob, "wait", freed.id, (*freed.xy, freed.yaw), t, 0, name, out)
                return

    # ------------------------------------------------------------------------------ pipelined
    def windows(self, name: str, extra: tuple[str, int] | None = None, now: int = 0
                ) -> list[tuple[int, int, str]]:
        """Pipelined: the time windows of workstation ``name``, ``(start [ns], end [ns],
        robot)`` in order of arrival: each robot booked on it in order of its ETA (then robot
        number), its window beginning at its ETA or when the one before ends, whichever is
        later, and lasting the service time plus ``dock_clear_ns``. A robot past its ETA that
        has not said ``done`` is reckoned to arrive at ``now`` at the earliest.

        Args:
            extra: (robot, ETA [ns]) of a robot not booked, to see where its window would be.
            now: [ns] simulated: the time of the question.
        """
        etas = [(self.robots[ns].eta_ns, self.robots[ns].index, ns) for ns in self.bookings[name]]
        if extra is not None:
            etas.append((extra[1], self.robots[extra[0]].index, extra[0]))
        length = self.cfg.service_time_ns + self.cfg.dock_clear_ns
        out, free = [], 0
        for eta, _, ns in sorted(etas):
            start = max(eta, free, now)
            free = start + length
            out.append((start, free, ns))
        return out

    def _eta(self, xy: tuple[float, float], name: str, t: int) -> int:
        """[ns] when a robot at ``xy`` leaving at ``t`` is reckoned to reach ``name``."""
        return t + round(self._distance(xy, name) / self.cfg.eta_speed * NS_PER_S)

    def choose_window(self, ns: str, name: str, t: int) -> tuple[str, int, int]:
        """Pipelined: the workstation robot ``ns`` is sent to when its route says ``name`` and
        it leaves at ``t`` [ns]: ``name`` if its window there would begin on its arrival (and
        it has not just left it), else (``nearest-free``) of ``name`` and the other
        workstations of its kind but the one it has just left, the one where its window would
        begin first (ties: ``name``, then the world's order). As the reserve policy's
        :meth:`choose` keeps to the route where it can.

        Returns:
            (workstation, ETA [ns], window start [ns]).
        """
        rob = self.robots[ns]
        cands = [name]
        if self.cfg.assignment != ASSIGN_ROUTE:
            cands = [w for w in self.stations if self.kind[w] == self.kind[name]
                     and w != rob.left] or [name]
        xy = rob.xy if rob.xy is not None else tuple(self.stations[name].pose[:2])
        order = {w: i for i, w in enumerate(self.stations)}
        best = None
        tried = ([name] if name != rob.left else []) + [w for w in cands if w != name]
        for w in tried or [name]:
            eta = self._eta(xy, w, t)
            start = next(s for s, _, r in self.windows(w, (ns, eta), t) if r == ns)
            if w == name and start <= eta:
                return w, eta, start
            key = (start, w != name, order[w])
            if best is None or key < best[0]:
                best = (key, w, eta, start)
        return best[1], best[2], best[3]

    def _book(self, ns: str, rob: _Robot, name: str, t: int, reply_to: int,
              out: _Out) -> None:
        """Pipelined: book the robot on the workstation of :meth:`choose_window`; send it
        there at once when its window begins on its arrival (nobody is reckoned to be there
        then, and no robot ahead of it in line is past its own ETA) or it is first in line, else
        to a waiting spot near it (its holding spot first) until it is first in line."""
        w, eta, start = self.choose_window(ns, name, t)
        rob.workstation, rob.eta_ns = w, eta
        self.bookings[w].append(ns)
        if self.cfg.queue_at == QUEUE_AT_HOLDING:  # the navigators queue: no line to wait in
            self._dispatch(ns, rob, t, reply_to, out)
            return
        line = [r for _, _, r in self.windows(w)]
        ahead = line[:line.index(ns)]
        # no overtaking a robot in line that is past its ETA: where it is, nobody knows
        late = any(self.robots[r].eta_ns <= t for r in ahead)
        if not ahead or (start <= eta and not late):
            self._dispatch(ns, rob, t, reply_to, out)
            return
        rob.dispatched = False
        spot = self._free_spot(w)
        if spot is None:  # no spot left: it waits where it stands (no goal)
            rob.last_answer = None
            return
        self._reserve(ns, spot_resource(spot.id), t, out)
        rob.spot, rob.xy = spot.id, spot.xy
        self._send(ns, rob, "wait", spot.id, (*spot.xy, spot.yaw), t, reply_to, w, out)

    def _dispatch(self, ns: str, rob: _Robot, t: int, reply_to: int, out: _Out) -> None:
        """Pipelined: send a booked robot to its workstation (from its spot, if it waits)."""
        freed = self.spots.get(rob.spot)
        if rob.spot:
            self._release(ns, spot_resource(rob.spot), t, out)
            rob.spot = ""
        rob.dispatched, rob.held_since_ns = True, t
        name = rob.workstation
        self._send(ns, rob, "go", name, self.stations[name].pose, t, reply_to, "", out)
        if freed is not None and freed.near:
            self._move_up_window(freed.near, freed, t, out)

    def _dispatch_head(self, name: str, t: int, out: _Out) -> None:
        """Pipelined: the first in line of ``name``, if it waits at a spot, goes now (a goal
        stamped one hand-over after ``t``)."""
        line = self.windows(name)
        if not line:
            return
        ns = line[0][2]
        rob = self.robots[ns]
        if not rob.dispatched:
            self._dispatch(ns, rob, t + self.cfg.handover_ticks * self.cfg.period_ns, 0, out)

    def _move_up_window(self, name: str, freed: Spot, t: int, out: _Out) -> None:
        """Pipelined: the first in line of ``name`` that waits farther away moves up to its
        freed holding spot."""
        for _, _, ns in self.windows(name):
            rob = self.robots[ns]
            if not rob.dispatched and rob.spot and self.spots[rob.spot].near != name:
                self._release(ns, spot_resource(rob.spot), t, out)
                self._reserve(ns, spot_resource(freed.id), t, out)
                rob.spot, rob.xy = freed.id, freed.xy
                self._send(ns, rob, "wait", freed.id, (*freed.xy, freed.yaw), t, 0, name, out)
                return

    def _expire_windows(self, t: int, speaking: set[str], out: _Out) -> None:
        """Pipelined: a robot sent to its workstation whose window began ``lease_ns`` before
        ``t`` and that has not spoken since loses it (its task still counts if it gets there
        after all); the next in line goes."""
        if self.cfg.lease_ns <= 0:
            return
        for name, booked in self.bookings.items():
            starts = {r: s for s, _, r in self.windows(name)}
            lapsed = False
            for ns in list(booked):
                rob = self.robots[ns]
                if ns in speaking or not rob.dispatched or t - max(
                        starts[ns], rob.heard_ns, rob.held_since_ns) < self.cfg.lease_ns:
                    continue
                booked.remove(ns)
                rob.lapsed, rob.workstation = name, ""
                self.expired += 1
                out.events.append(CoordinatorEvent(EVENT_LAPSE, ns, t, {
                    "workstation": name, "reason": "lease"}, self.epoch))
                lapsed = True
            if lapsed:
                self._dispatch_head(name, t, out)

    def _expire(self, t: int, speaking: set[str], out: _Out) -> None:
        """Release what dead and silent robots hold at simulated time ``t`` [ns] (the module
        doc), then hand the freed workstations over; ``speaking``: the robots of this batch."""
        if self.pipelined:
            self._expire_windows(t, speaking, out)
            return
        freed = []
        for ns, rob in self.robots.items():
            if rob.dead or not (rob.workstation or rob.spot or rob.waits_for):
                continue
            dead = not self._alive(ns, t)
            silent = (self.cfg.silence_timeout_ns > 0 and ns not in speaking
                      and rob.workstation
                      and t - max(rob.held_since_ns, rob.heard_ns) >= self.cfg.silence_timeout_ns)
            if not (dead or silent):
                continue
            rob.dead = dead
            out.events.append(CoordinatorEvent(EVENT_LAPSE, ns, t, {
                "workstation": rob.workstation, "reason": "dead" if dead else "silence"},
                self.epoch))
            if rob.workstation:
                self.expired += 1
                rob.lapsed = rob.workstation
                self._release(ns, workstation_resource(rob.workstation), t, out)
                freed.append(rob.workstation)
                rob.workstation = ""
            if dead:
                if rob.spot:
                    self._release(ns, spot_resource(rob.spot), t, out)
                    rob.spot = ""
                if rob.waits_for and ns in self.queues[rob.waits_for]:
                    self.queues[rob.waits_for].remove(ns)
                rob.waits_for = ""
        for name in freed:
            self._hand_over(name, t, out)

    # ------------------------------------------------------------------------------ helpers
    def _enqueue(self, ns: str, name: str) -> None:
        q = self.queues[name]
        if ns in q:
            return
        q.append(ns)
        q.sort(key=lambda r: (self.robots[r].since_ns, self.robots[r].index))

    def _free_spot(self, name: str) -> Spot | None:
        free = [s for s in self.spots.values() if spot_resource(s.id) not in self.holder]
        own = [s for s in free if s.near == name]
        if own:
            return own[0]
        parking = [s for s in free if not s.near]
        if not parking:
            return None
        wx, wy = self.stations[name].pose[:2]
        return min(parking, key=lambda s: (math.hypot(s.xy[0] - wx, s.xy[1] - wy), s.id))

    def _reserve(self, ns: str, res: str, t: int, out: _Out) -> None:
        self.holder[res] = ns
        out.events.append(CoordinatorEvent(EVENT_RESERVATION, ns, t, {
            "action": "reserve", "resource": res}, self.epoch))

    def _release(self, ns: str, res: str, t: int, out: _Out) -> None:
        if self.holder.get(res) == ns:
            del self.holder[res]
            out.events.append(CoordinatorEvent(EVENT_RESERVATION, ns, t, {
                "action": "release", "resource": res}, self.epoch))

    def _send(self, ns: str, rob: _Robot, kind: str, target: str, pose, t: int, reply_to: int,
              waits_for: str, out: _Out) -> None:
        rob.sent += 1
        a = Assignment(robot=ns, seq=rob.sent, reply_to=reply_to, kind=kind, target=target,
                       pose=tuple(float(v) for v in pose), stamp_ns=t, waits_for=waits_for,
                       task_start_ns=rob.task_start_ns, epoch=self.epoch)
        if reply_to:
            rob.last_answer = a
        out.assignments.append(a)

