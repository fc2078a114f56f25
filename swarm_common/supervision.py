"""What ``swarm-up``'s supervisor tells the simulator: robots whose navigator process is gone.

The lockstep has no wall-clock timeout (docs/ARCHITECTURE.md, "Synchronous control loop"): the
simulator waits for every active robot's answer, however long it takes.  So a robot whose
navigator is gone must be named: the supervisor does it as soon as it reaps the process
(``/swarm/supervision``, a :class:`RobotsLost` in a ``diagnostic_msgs/DiagnosticStatus`` named
:data:`LOST`), and without a supervisor (``swarm-sim`` beside navigators started by hand) the
simulator sees it in DDS: the robot's ``cmd_vel`` has no writer any more (at once when the process
ended cleanly, after the participant's lease, 20 s by default, when it was killed).  A robot so
named is not waited for until it answers again (its successor, restarted).  An unplanned crash is
a wall-clock event: the run is then not reproducible, and the metrics say so.  A process that
is only paused or slow is not gone and is waited for.

Pure: no ROS import.
"""

from __future__ import annotations

from dataclasses import dataclass

LOST = "lost"
"""The ``name`` of a ``/swarm/supervision`` status that names lost robots."""


@dataclass(frozen=True)
class RobotsLost:
    """Robots whose navigator process is gone.

    Attributes:
        robots: their namespaces (without ``/``).
        reason: why, for logs (``"group_1 exited with code -9"``).
        for_good: True if no successor comes (the supervisor gave up restarting, or the run is
            ending); False if the supervisor restarts the process.
    """

    robots: tuple[str, ...]
    reason: str = ""
    for_good: bool = False

    def encode(self) -> dict[str, str]:
        """The status's values, as strings."""
        return {"robots": ",".join(self.robots), "reason": self.reason,
                "for_good": "1" if self.for_good else "0"}

    @classmethod
    def decode(cls, values: dict[str, str]) -> RobotsLost | None:
        """Read a status's values; None if malformed (no robots)."""
        robots = tuple(r for r in (values.get("robots") or "").split(",") if r.strip())
        if not robots:
            return None
        return cls(tuple(r.strip() for r in robots), values.get("reason", ""),
                   values.get("for_good") == "1")
