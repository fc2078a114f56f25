"""The coordination contract of ``swarm-up --coordination centralized``, written once.

The commanders (:mod:`swarm_commander.coordinated`), the coordinator
(:mod:`swarm_coordinator.node`) and the metrics recorder (:mod:`swarm_metrics.aggregate`) all go
through this module (STYLE.md rule 15). Pure: no ROS import. Standard message types only: every
message is a ``std_msgs/String`` whose ``data`` is one JSON object (:func:`encode_request`,
:func:`encode_assignment`, :func:`encode_state`); reservation and task events go onto
``/swarm/events`` as ``diagnostic_msgs/DiagnosticStatus`` entries whose ``values`` are
:class:`CoordinatorEvent`'s :meth:`~CoordinatorEvent.values`.

Topics (as ``ros2 topic list`` shows them)::

    /swarm/coordinator/request     robots -> coordinator  std_msgs/String  reliable
    /<ns>/coordinator/assignment   coordinator -> robot   std_msgs/String  reliable
    /swarm/coordinator/state       coordinator -> robots  std_msgs/String  reliable, latched

Writers of requests and assignments keep their last 10 messages (transient local) for readers
that match late (the metrics node); the coordinator and the commanders read them volatile (names
and QoS: :mod:`swarm_common.topics`).

Resources are named ``workstation:<name>`` and ``spot:<id>`` (:func:`workstation_resource`,
:func:`spot_resource`). Stamps are simulated times in integer nanoseconds inside, and the
``"<sec>.<nanosec:09d>"`` text of :mod:`swarm_common.stamps` on the wire.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from swarm_common.stamps import format_stamp_ns, parse_stamp

COORDINATOR_NODE = "swarm_coordinator"  # the coordinator's node name
METRICS_NODE = "swarm_up_metrics"  # swarm-up's node that records /swarm/events for the metrics

REQUEST_KINDS = ("ready", "done", "report", "delivered")
OUTCOMES = ("succeeded", "failed", "canceled", "")
ASSIGNMENT_KINDS = ("go", "wait", "ack")
EVENT_RESERVATION = "reservation"
EVENT_TASK = "task"
EVENT_COORDINATOR = "coordinator"
EVENT_LAPSE = "lapse"
LAPSE_REASONS = ("lease", "silence", "dead")
"""Why a robot lost its workstation (:data:`EVENT_LAPSE`): its window's ``lease`` ran out
(pipelined), it held the workstation in ``silence`` too long (reserve), or the supervisor said
it is ``dead`` (reserve: a ``kill-robot`` fault)."""


class ContractError(ValueError):
    """A message that does not follow the contract (the reader drops it and warns)."""


def workstation_resource(name: str) -> str:
    """The resource name of a workstation (``workstation:loader3``)."""
    return f"workstation:{name}"


def spot_resource(spot_id: str) -> str:
    """The resource name of a waiting spot (``spot:loader3.0``, ``spot:park4``)."""
    return f"spot:{spot_id}"


@dataclass(frozen=True)
class Request:
    """A robot's message to the coordinator.

    Attributes:
        robot: namespace without ``/``.
        seq: the robot's request number (1, 2, ...); a re-sent request keeps its number, so the
            coordinator answers it once and repeats that answer.
        kind: ``ready`` (first task), ``done`` (a task's goal ended: ``outcome`` says how),
            ``report`` (tells a new coordinator what it holds; no answer expected), or
            ``delivered`` (an unsolicited assignment, number ``delivered``, is with the robot's
            navigator, waiting for its tick; no answer expected).
        stamp_ns: [ns] simulated time of the robot's latest ``nav_status`` (the tick the goal
            ended at, for ``done``).
        outcome: for ``done``: ``succeeded`` | ``failed`` | ``canceled``.
        target: the workstation of the task that ended (``done``), else ``""``.
        holds: the resources the robot believes it holds (from its assignments).
        waits_for: the workstation it waits for at a spot, else ``""``.
        since_ns: [ns] when it began waiting (its place in the queue), else 0.
        task_start_ns: [ns] when its current task began (its first assignment to it).
        delivered: for ``delivered``: the assignment's ``seq``.
    """

    robot: str
    seq: int
    kind: str
    stamp_ns: int
    outcome: str = ""
    target: str = ""
    holds: tuple[str, ...] = ()
    waits_for: str = ""
    since_ns: int = 0
    task_start_ns: int = 0
    delivered: int = 0


@dataclass(frozen=True)
class Assignment:
    """The coordinator's message to one robot.

    Attributes:
        robot: namespace without ``/``.
        seq: the coordinator's assignment number for this robot (1, 2, ...); a robot applies
            each number once.
        reply_to: the request it answers (0: unsolicited, e.g. a workstation freed up).
        kind: ``go`` (to a workstation, reserved for the robot), ``wait`` (at a spot, reserved
            for the robot, until ``waits_for`` frees up), or ``ack`` (request ``reply_to`` has
            arrived; its answer follows once the simulator has passed its tick: no goal).
        target: the workstation's name (``go``) or the spot's id (``wait``).
        pose: (x [m], y [m], yaw [rad]) in ``map``.
        stamp_ns: [ns] the goal's stamp: the navigator applies the goal at its first tick after
            it (docs/ARCHITECTURE.md, goal handshake).
        waits_for: for ``wait``: the workstation the robot is queued for.
        task_start_ns: [ns] when the robot's current task began.
        epoch: the coordinator's run id (a restarted coordinator has a new one).
    """

    robot: str
    seq: int
    reply_to: int
    kind: str
    target: str
    pose: tuple[float, float, float]
    stamp_ns: int
    waits_for: str = ""
    task_start_ns: int = 0
    epoch: str = ""


@dataclass(frozen=True)
class CoordinatorEvent:
    """One reservation or task event, as it goes onto ``/swarm/events``.

    Attributes:
        kind: ``reservation`` | ``task`` | ``coordinator`` | ``lapse``.
        robot: namespace without ``/`` ("" for ``coordinator``).
        t_ns: [ns] simulated time the event takes effect.
        fields: the kind's own values, strings: ``reservation``: ``action`` (``reserve`` |
            ``release``), ``resource``; ``task``: ``workstation``, ``t_start``, ``duration_s``;
            ``coordinator``: ``state`` (``up``); ``lapse`` (the coordinator took a robot's
            workstation from it: how it noticed a robot that died or fell silent):
            ``workstation``, ``reason`` (:data:`LAPSE_REASONS`).
        epoch: the coordinator's run id.
    """

    kind: str
    robot: str
    t_ns: int
    fields: Mapping[str, str] = field(default_factory=dict)
    epoch: str = ""

    def values(self) -> dict[str, str]:
        """The event's ``values`` (``robot``, ``t``, ``epoch`` and the kind's own)."""
        return {"robot": self.robot, "t": format_stamp_ns(self.t_ns), "epoch": self.epoch,
                **{k: str(v) for k, v in self.fields.items()}}

    def message(self) -> str:
        """A human line for the ``DiagnosticStatus.message``."""
        if self.kind == EVENT_RESERVATION:
            return f"{self.robot} {self.fields.get('action')} {self.fields.get('resource')}"
        if self.kind == EVENT_TASK:
            return f"{self.robot} reached {self.fields.get('workstation')}"
        if self.kind == EVENT_LAPSE:
            return (f"{self.robot} lost {self.fields.get('workstation')} "
                    f"({self.fields.get('reason')})")
        return f"coordinator {self.fields.get('state', '')}"


# ------------------------------------------------------------------------------------ encoding
def _stamp(value, key: str) -> int:
    t = parse_stamp(value) if isinstance(value, str) else None
    if t is None:
        raise ContractError(f"{key}: expected a stamp '<sec>.<nanosec:09d>', got {value!r}")
    return t


def _text(data: Mapping, key: str, default: str | None = None) -> str:
    value = data.get(key, default)
    if not isinstance(value, str):
        raise ContractError(f"{key}: expected a string, got {value!r}")
    return value


def _choice(data: Mapping, key: str, allowed: tuple[str, ...], default: str | None = None) -> str:
    value = _text(data, key, default)
    if value not in allowed:
        raise ContractError(f"{key}: expected one of {allowed}, got {value!r}")
    return value


def _int(data: Mapping, key: str, default: int | None = None) -> int:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ContractError(f"{key}: expected an integer >= 0, got {value!r}")
    return value


def load_object(text: str, error: type[ValueError] = ContractError) -> dict:
    """The JSON object a ``std_msgs/String`` of a swarm contract carries.

    Raises:
        error: not JSON, or not an object.
    """
    try:
        data = json.loads(text)
    except (TypeError, ValueError):
        raise error("not JSON") from None
    if not isinstance(data, dict):
        raise error("not a JSON object")
    return data



def encode_request(req: Request) -> str:
    """The ``std_msgs/String.data`` of a request (compact JSON)."""
    return json.dumps({
        "robot": req.robot, "seq": req.seq, "kind": req.kind,
        "stamp": format_stamp_ns(req.stamp_ns), "outcome": req.outcome, "target": req.target,
        "holds": list(req.holds), "waits_for": req.waits_for,
        "since": format_stamp_ns(req.since_ns), "task_start": format_stamp_ns(req.task_start_ns),
        "delivered": req.delivered,
    }, separators=(",", ":"))


def decode_request(text: str) -> Request:
    """Parse a request.

    Raises:
        ContractError: malformed (names the key).
    """
    d = load_object(text)
    kind = _choice(d, "kind", REQUEST_KINDS)
    outcome = _choice(d, "outcome", OUTCOMES, "")
    holds = d.get("holds", [])
    if not isinstance(holds, list) or not all(isinstance(h, str) for h in holds):
        raise ContractError(f"holds: expected a list of strings, got {holds!r}")
    robot = _text(d, "robot")
    if not robot:
        raise ContractError("robot: empty")
    return Request(robot=robot, seq=_int(d, "seq"), kind=kind,
                   stamp_ns=_stamp(d.get("stamp"), "stamp"), outcome=outcome,
                   target=_text(d, "target", ""), holds=tuple(holds),
                   waits_for=_text(d, "waits_for", ""),
                   since_ns=_stamp(d.get("since", "0.000000000"), "since"),
                   task_start_ns=_stamp(d.get("task_start", "0.000000000"), "task_start"),
                   delivered=_int(d, "delivered", 0))


def encode_assignment(a: Assignment) -> str:
    """The ``std_msgs/String.data`` of an assignment (compact JSON)."""
    x, y, yaw = a.pose
    return json.dumps({
        "robot": a.robot, "seq": a.seq, "reply_to": a.reply_to, "kind": a.kind,
        "target": a.target, "x": round(float(x), 6), "y": round(float(y), 6),
        "yaw": round(float(yaw), 6), "stamp": format_stamp_ns(a.stamp_ns),
        "waits_for": a.waits_for, "task_start": format_stamp_ns(a.task_start_ns),
        "epoch": a.epoch,
    }, separators=(",", ":"))


def decode_assignment(text: str) -> Assignment:
    """Parse an assignment.

    Raises:
        ContractError: malformed (names the key).
    """
    d = load_object(text)
    kind = _choice(d, "kind", ASSIGNMENT_KINDS)
    pose = []
    for key in ("x", "y", "yaw"):
        value = d.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or value != value or value in (float("inf"), float("-inf")):
            raise ContractError(f"{key}: expected a finite number, got {value!r}")
        pose.append(float(value))
    return Assignment(robot=_text(d, "robot"), seq=_int(d, "seq"), reply_to=_int(d, "reply_to"),
                      kind=kind, target=_text(d, "target"), pose=tuple(pose),
                      stamp_ns=_stamp(d.get("stamp"), "stamp"),
                      waits_for=_text(d, "waits_for", ""),
                      task_start_ns=_stamp(d.get("task_start", "0.000000000"), "task_start"),
                      epoch=_text(d, "epoch", ""))


def encode_state(epoch: str, robots: int) -> str:
    """The coordinator's latched ``state`` message: it is up, with this epoch."""
    return json.dumps({"state": "up", "epoch": epoch, "robots": robots}, separators=(",", ":"))


def decode_state(text: str) -> str:
    """The epoch of a ``state`` message.

    Raises:
        ContractError: malformed.
    """
    return _text(load_object(text), "epoch")


def check_reservations(events: Sequence[Mapping[str, str]]) -> list[str]:
    """Check recorded reservation events: no resource is ever held by two robots at once.

    Args:
        events: the ``values`` of the ``reservation`` events in the order they were published
            (``robot``, ``action``, ``resource``, ``epoch``). A new epoch (a restarted
            coordinator) starts from empty tables.

    Returns:
        One line per violation (empty: none), e.g. ``"workstation:loader2 reserved by Srobot3
        while Srobot1 holds it"``.
    """
    problems = []
    holder: dict[str, str] = {}
    epoch = None
    for ev in events:
        if ev.get("epoch") != epoch:
            epoch, holder = ev.get("epoch"), {}
        res, robot, action = ev.get("resource", ""), ev.get("robot", ""), ev.get("action", "")
        if action == "reserve":
            other = holder.get(res)
            if other is not None and other != robot:
                problems.append(f"{res} reserved by {robot} while {other} holds it")
            holder[res] = robot
        elif action == "release":
            if holder.get(res) != robot:
                problems.append(f"{res} released by {robot}, held by {holder.get(res)}")
            holder.pop(res, None)
    return problems
