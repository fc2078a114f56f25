"""The coordinator's logic: task assignment and first-come-first-served reservations (pure).

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
- W free: W is reserved for the robot, which is sent there (``go``).
- W reserved by another robot: the robot joins W's queue (first come, first served: ordered by
  the simulated time of its request, then by robot number) and is sent to a free waiting spot
  (``wait``), reserved for it: W's own holding spots first, then the parking spots nearest W.
  No two robots are ever sent to one spot. When a holding spot of W frees up, the first robot
  of W's queue that waits at a parking spot moves up to it (the next hand-over is short).
- A robot that reports ``done`` at W leaves it: W is released at the request's stamp t, and the
  first robot of W's queue that lives gets W (its spot is released) with a goal stamped
  ``t + period`` (``handover_ticks``), the tick at which the batch is handled, so it moves off
  its spot at tick ``t + 2 period``, whatever the wall-clock latency: the node sends the batch's
  answers, which the simulator waits for at ``t + period``, only once that robot's navigator
  has the goal (:mod:`swarm_coordinator.node`).
- A goal that failed or was canceled releases its workstation too; the robot moves on to the next
  stop of its route (as the decentralized commander does).
- A robot the core has not heard from (a coordinator restarted with empty tables) is taken at its
  word: the resources it reports are reserved for it if free; a workstation held by another robot
  meanwhile sends it to a waiting spot instead. What every such robot of a batch holds is taken
  over, and then the waiting ones queued, before any request of the batch is answered.

Requests of one batch are handled in order of (stamp, robot number), never in arrival order, so
one batch gives the same answers whatever order its messages came in.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from swarm_common.coordination import (
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


@dataclass(frozen=True)
class CoordinatorConfig:
    """Settings of the coordinator's core.

    Attributes:
        period_ns: [ns] the simulator's control tick.
        handover_ticks: a goal handed to a waiting robot is stamped this many ticks after the
            release, the tick at which the batch is handled (so it takes effect one tick later
            still, see the module doc): the simulator cannot pass that tick before the robot has
            the goal (the node holds the batch's answers until it is delivered).
    """

    period_ns: int = NS_PER_S // 10
    handover_ticks: int = 1  # [ticks] a handed-over goal's stamp after the release


def spots_from_poi(poi, parking: np.ndarray | None = None) -> tuple[Spot, ...]:
    """The waiting spots of a world: every holding point of every workstation, then parking.

    Args:
        poi: a :class:`swarm_common.poi.PointsOfInterest` (workstations with ``holding``).
        parking: (K, 2) or (K, 3) parking spots x, y [, yaw] in ``map`` (e.g. the spawn grid:
            free of walls by construction), or None.

    Returns:
        The spots, holding spots first (``loader1.0`` ...), then ``park1`` ... ``parkK``.
    """
    spots = []
    for w in poi.workstations:
        wx, wy = float(w.pose[0]), float(w.pose[1])
        for i, (x, y) in enumerate(np.asarray(w.holding, float).reshape(-1, 2)):
            spots.append(Spot(f"{w.name}.{i}", (float(x), float(y)), w.name,
                              math.atan2(wy - y, wx - x)))
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

    Raises:
        ValueError: no workstations, or duplicate names.
    """

    def __init__(self, robots: Sequence[str], stations: Sequence[Station],
                 spots: Sequence[Spot], next_stop: Callable[[str], str],
                 cfg: CoordinatorConfig = CoordinatorConfig(), epoch: str = ""):
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

    # ------------------------------------------------------------------------------ queries
    def holder_of(self, resource: str) -> str | None:
        """The robot holding ``resource`` (``workstation:W`` / ``spot:S``), or None."""
        return self.holder.get(resource)

    def queue(self, workstation: str) -> tuple[str, ...]:
        """The robots waiting for ``workstation``, first in line first."""
        return tuple(self.queues.get(workstation, ()))

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
        self._alive = alive or (lambda ns, t: True)
        ordered = self.order(requests)
        self._adopt_batch(ordered, out)
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
            if req.kind == "report":
                continue
            rob.last_seq = req.seq
            if req.kind == "done":
                self._done(req, rob, out)
            self._next_task(req.robot, rob, req.stamp_ns, req.seq, out)
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
            if kind == "workstation" and name in self.stations:
                if self.holder.get(res) in (None, req.robot):
                    self._reserve(req.robot, res, t, out)
                    rob.workstation = name
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
        if want in self.stations and not rob.workstation and req.robot not in self.queues[want]:
            rob.waits_for, rob.since_ns = want, req.since_ns
            self._enqueue(req.robot, want)
            return True
        return False

    def _done(self, req: Request, rob: _Robot, out: _Out) -> None:
        """A task's goal ended: count the task, release the workstation, hand it over."""
        t = req.stamp_ns
        name = req.target
        if rob.workstation and rob.workstation == name:
            if req.outcome == "succeeded":
                out.events.append(CoordinatorEvent(EVENT_TASK, req.robot, t, {
                    "workstation": name, "t_start": format_stamp_ns(rob.task_start_ns),
                    "duration_s": f"{(t - rob.task_start_ns) / NS_PER_S:.3f}"}, self.epoch))
            self._release(req.robot, workstation_resource(name), t, out)
            rob.workstation = ""
            if self.queues[name]:
                self._hand_over(name, t, out)

    def _next_task(self, ns: str, rob: _Robot, t: int, reply_to: int, out: _Out) -> None:
        name = self._next_stop(ns)
        if name not in self.stations:
            raise ValueError(f"route of {ns} names an unknown workstation {name!r}")
        rob.task_start_ns = t
        self._queue_or_go(ns, rob, name, t, reply_to, out)

    def _queue_or_go(self, ns: str, rob: _Robot, name: str, t: int, reply_to: int,
                     out: _Out) -> None:
        res = workstation_resource(name)
        if self.holder.get(res) in (None, ns) and not self.queues[name]:
            if self.holder.get(res) is None:
                self._reserve(ns, res, t, out)
            rob.workstation = name
            self._send(ns, rob, "go", name, self.stations[name].pose, t, reply_to, "", out)
            return
        rob.waits_for, rob.since_ns = name, t
        self._enqueue(ns, name)
        spot = self._free_spot(name)
        if spot is None:  # no spot left: the robot waits where it stands (no goal)
            rob.last_answer = None
            return
        self._reserve(ns, spot_resource(spot.id), t, out)
        rob.spot = spot.id
        self._send(ns, rob, "wait", spot.id, (*spot.xy, spot.yaw), t, reply_to, name, out)

    def _hand_over(self, name: str, t: int, out: _Out) -> None:
        """Give a free workstation to the first robot of its queue that lives (goal one tick
        later); dead ones are dropped from the queue."""
        start = t + self.cfg.handover_ticks * self.cfg.period_ns
        while self.queues[name] and not self._alive(self.queues[name][0], start):
            self.queues[name].pop(0)
        if not self.queues[name]:
            return
        ns = self.queues[name].pop(0)
        rob = self.robots[ns]
        freed = self.spots.get(rob.spot)
        if rob.spot:
            self._release(ns, spot_resource(rob.spot), start, out)
            rob.spot = ""
        self._reserve(ns, workstation_resource(name), start, out)
        rob.workstation, rob.waits_for, rob.since_ns = name, "", 0
        self._send(ns, rob, "go", name, self.stations[name].pose, start, 0, "", out)
        if freed is not None and freed.near == name:
            self._move_up(name, freed, start, out)

    def _move_up(self, name: str, freed: Spot, t: int, out: _Out) -> None:
        """The first robot of ``name``'s queue that waits farther away (parking) moves up to
        the workstation's freed holding spot, so the next hand-over is a short drive."""
        for ns in self.queues[name]:
            rob = self.robots[ns]
            if rob.spot and self.spots[rob.spot].near != name and self._alive(ns, t):
                self._release(ns, spot_resource(rob.spot), t, out)
                self._reserve(ns, spot_resource(freed.id), t, out)
                rob.spot = freed.id
                self._send(ns, rob, "wait", freed.id, (*freed.xy, freed.yaw), t, 0, name, out)
                return

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

