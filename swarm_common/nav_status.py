"""The navigator's status contract: what ``/<ns>/nav_status`` carries, written once.

The navigator (:mod:`swarm_nav.node`) publishes it; the commander
(:mod:`swarm_commander.robot_navigator`) and the metrics recorder (:mod:`swarm_metrics.aggregate`)
read it. All three go through this module (STYLE.md rule 15); docs/ARCHITECTURE.md describes
the topic (QoS, rate, ``name``/``hardware_id``).

The message is a ``diagnostic_msgs/DiagnosticStatus``: ``message`` is the state's name,
``level`` is :func:`level_of` the state, and ``values`` (all strings, in this order) is
:func:`encode` of a :class:`NavStatusRecord`:

============================  ===============================================================
key                           value
============================  ===============================================================
``state``                     a :class:`NavState` name
``goal_id``                   the goal's id: its ``header.stamp`` as ``"<sec>.<nanosec:09d>"``
                              (:func:`swarm_common.stamps.format_stamp`); ``""`` before any goal
``stamp``                     simulated time of the tick this status describes, same format
``goal_x`` ``goal_y``         the goal in ``map`` [m], 3 decimals (only while there is a goal)
``goal_yaw``                  [rad], 4 decimals (only while there is a goal)
``distance_remaining_m``      [m] still to drive, 3 decimals
``navigation_time_s``         [s] since the goal was accepted (frozen at its end), 3 decimals
``recoveries``                recovery behaviours run for this goal (integer)
``holding_time_s``            [s] spent holding for this goal, 3 decimals
``goal_wait_timeouts``        goal-wait timeouts since the navigator started (integer)
``pending_goal_id``           the id of a goal that has arrived and awaits its tick (only then):
                              the navigator says so at once, so that a commander knows its goal
                              is there (the coordinator's hand-over, docs/ARCHITECTURE.md)
``reason``                    why the goal was aborted (or a note on success), else ``""``;
                              on success at another workstation than the goal sent (the
                              navigator's ``swap_range``) it begins with :data:`TOOK_ANOTHER`
============================  ===============================================================

:func:`decode` is tolerant, because a reader must never crash on another process's message:
a missing or malformed value decodes to ``None`` (``""`` for the texts), the rest of the message
is still used. Pure: no ROS import (the level is the ``diagnostic_msgs`` byte as an int).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum

from swarm_common.stamps import format_stamp_ns, parse_stamp

__all__ = [
    "ERROR",
    "OK",
    "OUTCOMES",
    "TERMINAL",
    "TOOK_ANOTHER",
    "WARN",
    "NavState",
    "NavStatusRecord",
    "decode",
    "encode",
    "level_of",
]


class NavState(StrEnum):
    """The navigator's state, as published in ``nav_status``."""

    IDLE = "IDLE"
    PLANNING = "PLANNING"
    DRIVING = "DRIVING"
    HOLDING = "HOLDING"
    RECOVERING = "RECOVERING"
    SUCCEEDED = "SUCCEEDED"
    ABORTED = "ABORTED"
    CANCELED = "CANCELED"


OUTCOMES = (NavState.SUCCEEDED, NavState.ABORTED, NavState.CANCELED)
"""The states that end a goal."""

TERMINAL = (NavState.IDLE, *OUTCOMES)
"""The states in which no goal is being driven to."""

TOOK_ANOTHER = "took the workstation at "
"""How the reason of a goal reached at another workstation than the one sent begins: the
navigator took a free one of its kind while the goal was taken (``swap_range``); the goal's
``goal_x``/``goal_y`` are then the workstation reached."""

OK, WARN, ERROR = 0, 1, 2
"""``diagnostic_msgs/DiagnosticStatus`` levels (its ``OK``, ``WARN``, ``ERROR`` bytes)."""

_LEVEL = {
    NavState.ABORTED: ERROR,
    NavState.HOLDING: WARN,
    NavState.RECOVERING: WARN,
    NavState.CANCELED: WARN,
}


def level_of(state: NavState) -> int:
    """The status ``level`` of a state: ERROR when aborted, WARN when holding, recovering or
    canceled, else OK."""
    return _LEVEL.get(state, OK)


@dataclass(frozen=True)
class NavStatusRecord:
    """One ``nav_status`` message's ``values``, typed.

    ``None`` stands for a value that is absent (the encoder leaves its key out) or, after
    :func:`decode`, malformed.

    Attributes:
        state: the navigator's state; None if missing or not a :class:`NavState` name.
        goal_id: the current (or last) goal's id; ``""`` before any goal.
        stamp_ns: [ns] simulated time of the tick the status describes.
        goal: (x [m], y [m], yaw [rad]) of the goal in ``map``, or None without a goal.
        distance_remaining: [m] still to drive (0 without a goal).
        navigation_time: [s] since the goal was accepted (frozen when it ended).
        recoveries: recovery behaviours run for this goal, >= 0.
        holding_time: [s] spent holding for this goal.
        goal_wait_timeouts: ticks answered without the commander's next goal because the wait
            ran out, since the navigator started, >= 0.
        pending_goal_id: the id of the last goal that has arrived and awaits its tick; ``""``
            when none does.
        reason: why the goal was aborted (or a note on success); ``""`` otherwise.
    """

    state: NavState | None
    goal_id: str = ""
    stamp_ns: int | None = None
    goal: tuple[float, float, float] | None = None
    distance_remaining: float | None = None
    navigation_time: float | None = None
    recoveries: int | None = None
    holding_time: float | None = None
    goal_wait_timeouts: int | None = None
    pending_goal_id: str = ""
    reason: str = ""


def encode(record: NavStatusRecord) -> dict[str, str]:
    """The ``values`` of a status, as ordered ``key -> text`` (see the module docstring).

    Args:
        record: the status; its ``None`` fields are left out.

    Returns:
        The values in the order of the module docstring's table.
    """
    out: dict[str, str] = {}
    if record.state is not None:
        out["state"] = NavState(record.state).value
    out["goal_id"] = record.goal_id
    if record.stamp_ns is not None:
        out["stamp"] = format_stamp_ns(record.stamp_ns)
    if record.goal is not None:
        x, y, yaw = record.goal
        out.update(goal_x=f"{x:.3f}", goal_y=f"{y:.3f}", goal_yaw=f"{yaw:.4f}")
    for key, value, kind in (
        ("distance_remaining_m", record.distance_remaining, "f"),
        ("navigation_time_s", record.navigation_time, "f"),
        ("recoveries", record.recoveries, "d"),
        ("holding_time_s", record.holding_time, "f"),
        ("goal_wait_timeouts", record.goal_wait_timeouts, "d"),
    ):
        if value is not None:
            out[key] = f"{value:.3f}" if kind == "f" else str(int(value))
    if record.pending_goal_id:
        out["pending_goal_id"] = record.pending_goal_id
    out["reason"] = record.reason
    return out


def decode(values: Mapping[str, str], message: str = "") -> NavStatusRecord:
    """A status's ``values`` as a record; never raises on malformed input.

    Args:
        values: the message's ``values`` as ``key -> text``.
        message: the message's ``message`` (the state's name): the state if ``values`` has none.

    Returns:
        The record. The state is matched after stripping blanks and upper-casing; a number that
        is not a finite float (a count: not a finite float >= 0, truncated to an int), a stamp
        not in ``"<sec>.<nanosec:09d>"`` form and a goal lacking one finite coordinate are None.
    """
    goal = tuple(finite_float(values.get(k)) for k in ("goal_x", "goal_y", "goal_yaw"))
    return NavStatusRecord(
        state=_state(values.get("state") or message),
        goal_id=_text(values.get("goal_id")).strip(),
        stamp_ns=parse_stamp(_text(values.get("stamp"))),
        goal=None if None in goal else goal,
        distance_remaining=finite_float(values.get("distance_remaining_m")),
        navigation_time=finite_float(values.get("navigation_time_s")),
        recoveries=_count(values.get("recoveries")),
        holding_time=finite_float(values.get("holding_time_s")),
        goal_wait_timeouts=_count(values.get("goal_wait_timeouts")),
        pending_goal_id=_text(values.get("pending_goal_id")).strip(),
        reason=_text(values.get("reason")),
    )


def _text(value) -> str:
    return value if isinstance(value, str) else ""


def _state(text) -> NavState | None:
    try:
        return NavState(_text(text).strip().upper())
    except ValueError:
        return None


def finite_float(text) -> float | None:
    """A finite float from a text (or number), else None."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _count(text) -> int | None:
    """A count from a text: a finite float >= 0 truncated to an int, else None."""
    value = finite_float(text)
    return int(value) if value is not None and value >= 0 else None
