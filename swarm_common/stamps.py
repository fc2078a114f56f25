"""Simulated time as integer nanoseconds, and its one text form ``"<sec>.<nanosec:09d>"``.

Every process keeps time as integer nanoseconds (``builtin_interfaces/Time`` is ``sec`` +
``nanosec``), so two runs with the same seed compare equal to the nanosecond. The text form is
part of the navigator's status contract (:mod:`swarm_common.nav_status`): a goal's id is the text
of its ``header.stamp``, and a status's ``stamp`` value is the simulated time it describes
(docs/ARCHITECTURE.md, "goal handshake"). Pure: no ROS import.
"""

from __future__ import annotations

import re

__all__ = ["NS_PER_S", "format_stamp", "format_stamp_ns", "parse_stamp"]

NS_PER_S = 1_000_000_000
"""Nanoseconds per second."""

_STAMP = re.compile(r"([0-9]+)\.([0-9]{9})")


def format_stamp(sec: int, nanosec: int) -> str:
    """The text of a stamp: ``"<sec>.<nanosec:09d>"``.

    Args:
        sec: [s] whole seconds (``builtin_interfaces/Time.sec``), >= 0.
        nanosec: [ns] the rest, 0 <= nanosec < 1e9.

    Returns:
        E.g. ``format_stamp(7, 5) == "7.000000005"``.

    Raises:
        ValueError: ``sec`` is negative or ``nanosec`` out of range.
    """
    sec, nanosec = int(sec), int(nanosec)
    if sec < 0 or not 0 <= nanosec < NS_PER_S:
        raise ValueError(f"stamp {sec} s {nanosec} ns: need sec >= 0 and 0 <= nanosec < 1e9")
    return f"{sec}.{nanosec:09d}"


def format_stamp_ns(t_ns: int) -> str:
    """:func:`format_stamp` of a time given in integer nanoseconds [ns] (>= 0)."""
    return format_stamp(*divmod(int(t_ns), NS_PER_S))


def parse_stamp(text: str) -> int | None:
    """The time [ns] of a stamp's text, or None if it is not ``"<sec>.<nanosec:09d>"``.

    Exactly nine digits after the point: ``"1.5"`` is malformed (it would be ambiguous between
    1.5 s and 1 s 5 ns), as are signs, spaces and an empty string.

    Args:
        text: e.g. ``"12.000000500"``.

    Returns:
        Integer nanoseconds (``12_000_000_500``), or None.
    """
    m = _STAMP.fullmatch(text) if isinstance(text, str) else None
    if m is None:
        return None
    return int(m.group(1)) * NS_PER_S + int(m.group(2))
