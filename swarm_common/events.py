"""The records of ``/swarm/events`` (``diagnostic_msgs/DiagnosticArray``), written once.

Every status of the array is one event: its ``name`` is the event's kind, its ``values`` the
record's fields as strings (``DiagnosticStatus`` carries only ``KeyValue`` strings), its
``message`` a line for a person.  The kinds and who writes them:

========================  ============================================  =====================
kind (status ``name``)    record                                        writer
========================  ============================================  =====================
``spawn``                 :class:`SpawnEvent`                           the simulator
``collision``             :class:`CollisionEvent`                       the simulator
``late``                  :class:`LateEvent`                            the simulator
``fault``                 :class:`RobotNotice` (a robot stops or        the simulator
                          answers again) or
                          :class:`swarm_common.faults.FaultEvent` (an
                          injected fault starts or ends)
``reservation``, ``task``, :class:`swarm_common.coordination.             the coordinator
``coordinator``           CoordinatorEvent`
========================  ============================================  =====================

The readers (the metrics, ``swarm-plot``, the live views, swarm-up's fault and host services)
decode with :func:`decode_robot_event` or the record's own ``decode``; a status that does not
follow its record decodes to None and is skipped.  Positions are in ``map`` [m], ``t`` is the
simulated time of the tick [s].  Pure: no ROS import.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from swarm_common.coordination import (
    EVENT_COORDINATOR,
    EVENT_LAPSE,
    EVENT_RESERVATION,
    EVENT_TASK,
)
from swarm_common.faults import EVENT_NAME as FAULT

SPAWN = "spawn"
COLLISION = "collision"
LATE = "late"
KINDS = (SPAWN, COLLISION, LATE, FAULT, EVENT_RESERVATION, EVENT_TASK, EVENT_COORDINATOR,
         EVENT_LAPSE)
"""Every event kind, i.e. every status ``name`` on ``/swarm/events``."""

ROBOT_ROBOT, ROBOT_WALL = "robot_robot", "robot_wall"
"""The kinds of collision (:attr:`CollisionEvent.kind`)."""


def _number(values: dict[str, str], key: str) -> float | None:
    try:
        return float(values[key])
    except (KeyError, TypeError, ValueError):
        return None


@dataclass(frozen=True)
class RobotEvent:
    """What every simulator event carries: whose, where and when.

    Attributes:
        robot: the robot's namespace without the leading slash (``Srobot3``).
        x: [m] position in ``map`` (the robot's, or the contact point's for a collision).
        y: [m] position in ``map``.
        t: [s] simulated time of the tick.
    """

    KIND: ClassVar[str] = ""
    robot: str
    x: float
    y: float
    t: float

    def encode(self) -> dict[str, str]:
        """The status's ``values`` (millimetres and milliseconds, as strings)."""
        out = {"robot": self.robot, "x": f"{self.x:.3f}", "y": f"{self.y:.3f}",
               "t": f"{self.t:.3f}"}
        out.update(self._extra())
        return out

    def _extra(self) -> dict[str, str]:
        return {}

    @classmethod
    def decode(cls, values: dict[str, str], lenient: bool = False):
        """The record of a status's ``values``, or None if a field is missing or malformed
        (the leading slash of a robot's name is dropped).

        Args:
            values: the status's values.
            lenient: a missing or malformed position or time reads as 0 instead (a reader
                that counts events, as the metrics do, counts one whose position is unknown);
                the robot is still required.
        """
        robot = str(values.get("robot", "")).strip().lstrip("/")
        x, y, t = (_number(values, k) for k in ("x", "y", "t"))
        if lenient:
            x, y, t = x or 0.0, y or 0.0, t or 0.0
        if not robot or x is None or y is None or t is None:
            return None
        return cls._build(values, robot, x, y, t)

    @classmethod
    def _build(cls, values, robot, x, y, t):
        return cls(robot, x, y, t)


@dataclass(frozen=True)
class SpawnEvent(RobotEvent):
    """A robot was spawned (published once for all robots before simulated time starts).

    Attributes:
        yaw: [rad] heading in ``map``.
    """

    KIND: ClassVar[str] = SPAWN
    yaw: float = 0.0

    def _extra(self) -> dict[str, str]:
        return {"yaw": f"{self.yaw:.4f}"}

    @classmethod
    def _build(cls, values, robot, x, y, t):
        return cls(robot, x, y, t, _number(values, "yaw") or 0.0)


@dataclass(frozen=True)
class CollisionEvent(RobotEvent):
    """A collision episode started (contact after none at the tick before).

    Attributes:
        other: the other robot's namespace (``kind`` :data:`ROBOT_ROBOT`), or the wall's name.
        kind: :data:`ROBOT_ROBOT` or :data:`ROBOT_WALL`.
    """

    KIND: ClassVar[str] = COLLISION
    other: str = ""
    kind: str = ROBOT_WALL

    def _extra(self) -> dict[str, str]:
        return {"other": self.other, "kind": self.kind}

    @classmethod
    def _build(cls, values, robot, x, y, t):
        return cls(robot, x, y, t, str(values.get("other", "")).strip().lstrip("/"),
                   str(values.get("kind", "")))


@dataclass(frozen=True)
class LateEvent(RobotEvent):
    """A robot's navigator did not answer a tick it was awaited for (it is gone): the robot is
    stopped for that tick and not awaited until it answers again."""

    KIND: ClassVar[str] = LATE


@dataclass(frozen=True)
class RobotNotice(RobotEvent):
    """A robot stopped answering, or answers again (kind ``fault`` without a fault index: the
    status's ``message`` says which)."""

    KIND: ClassVar[str] = FAULT


ROBOT_EVENTS = {cls.KIND: cls for cls in (SpawnEvent, CollisionEvent, LateEvent)}
"""The simulator's robot events by kind (a ``fault`` status is a :class:`RobotNotice` only
when it is not a :class:`swarm_common.faults.FaultEvent`)."""


def decode_robot_event(kind: str, values: dict[str, str]) -> RobotEvent | None:
    """The simulator's event of kind ``kind`` (``spawn``, ``collision``, ``late``), or None for
    another kind or a malformed status."""
    cls = ROBOT_EVENTS.get(kind)
    return None if cls is None else cls.decode(values)
