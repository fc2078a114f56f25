"""The simulator's run summary: the file ``swarm-sim --summary PATH`` writes at exit, typed.

The simulator (:func:`swarm_sim.summary.summarize`) builds a :class:`SimSummary`
and writes its :meth:`~SimSummary.to_dict` as :meth:`~SimSummary.to_json` does; ``swarm-up``
reads it back (:func:`swarm_metrics.aggregate.load_sim_summary`) and merges its figures into
``--metrics``. Both go through this module (STYLE.md rule 15).

The file is one JSON object (2-space indent, a final newline), keys in the order of the fields
below, ``null`` for a figure that is unknown::

    {"robots": 20, "ticks": 3000, "sim_time_s": 300.0, "wall_time_s": 41.2, "rtf": 7.282,
     "robot_ticks_per_s": 1456.3, "late_ticks": 0, "dropped_messages": 0,
     "collisions": {"robot_robot": 0, "robot_wall": 0}, "min_separation_m": 0.1234,
     "per_robot": {"Srobot1": {"distance_m": 41.5, "collisions": 0, "late_ticks": 0}, ...}}

A number is kept as written (``3`` stays an int where a float is typed), so reading a file and
writing it back gives the same text. Reading is strict about types and tolerant about keys: a
value of the wrong type (a text where a count belongs, a non-finite number) or a file that is not
a JSON object raises :class:`SimSummaryError` naming the key; a missing key is ``None``; an
unknown top-level key is kept in :attr:`SimSummary.extras` (and written back), unknown keys
inside ``collisions`` and the per-robot entries are ignored. Pure: no ROS import.

The simulator's own extras: ``wall_timeline_s``, the wall seconds from the start gate to each
whole simulated second (``[k]`` for simulated time ``k + 1`` s), to compare two runs of one seed
second by second; ``standstills``, every episode of a robot standing within 0.1 m for 60 simulated
s or more (``robot``, ``start_s``, ``duration_s``, ``x``, ``y`` in ``map``, ``open`` when the run
ended first; :mod:`swarm_sim.standstill`); ``spawn``, where the robots went, the text of the
simulator's ``spawned N robots in ...`` line (:func:`swarm_scene.spawn.describe_spawn`);
``world_skipped``, the world's skip report (``World.skipped``: one text per element not simulated,
empty when the world loads whole); ``track``, every robot's position at each whole simulated
second (``period_s`` 1.0; ``xy[k][i]`` robot i's x, y [m] in ``map`` at k + 1 s, to the
centimetre), the ground truth of the metrics' waiting measure; ``faults`` when ``--faults`` was
given.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

__all__ = ["CollisionCounts", "RobotSummary", "SimSummary", "SimSummaryError"]


class SimSummaryError(ValueError):
    """The summary is malformed: not JSON, not an object, or a value of the wrong type.

    The message names the file (when read from one) and the key, e.g.
    ``"RUN/sim_summary.json: per_robot.Srobot1.distance_m: expected a number, got 'x'"``.
    """


@dataclass(frozen=True)
class CollisionCounts:
    """Collisions of the whole run, counted once per pair and contact episode.

    Attributes:
        robot_robot: robot-robot collisions.
        robot_wall: robot-obstacle collisions.
    """

    robot_robot: int | None = None
    robot_wall: int | None = None


@dataclass(frozen=True)
class RobotSummary:
    """One robot's figures.

    Attributes:
        distance_m: [m] travelled (true pose).
        collisions: collisions the robot took part in.
        late_ticks: ticks whose command from the robot's navigator came late.
    """

    distance_m: float | None = None
    collisions: int | None = None
    late_ticks: int | None = None


@dataclass(frozen=True)
class SimSummary:
    """The simulator's figures of one run; ``None`` where unknown.

    Attributes:
        robots: robots simulated.
        ticks: control ticks simulated.
        sim_time_s: [s] simulated time at the end.
        wall_time_s: [s] wall time of the simulation loop.
        rtf: real-time factor achieved, simulated over wall time.
        robot_ticks_per_s: robot-ticks per wall second (``robots * ticks / wall_time_s``).
        late_ticks: ticks stepped without every robot's command (summed over robots).
        dropped_messages: malformed messages the simulator dropped.
        collisions: the run's collisions by kind.
        min_separation_m: [m] least footprint-to-footprint gap seen between two robots (None
            with fewer than two robots).
        per_robot: namespace (without ``/``) -> that robot's figures.
        extras: top-level keys this record does not know, kept verbatim.
    """

    robots: int | None = None
    ticks: int | None = None
    sim_time_s: float | None = None
    wall_time_s: float | None = None
    rtf: float | None = None
    robot_ticks_per_s: float | None = None
    late_ticks: int | None = None
    dropped_messages: int | None = None
    collisions: CollisionCounts | None = None
    min_separation_m: float | None = None
    per_robot: Mapping[str, RobotSummary] | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)

    def robot(self, ns: str) -> RobotSummary:
        """Robot ``ns``'s figures (keyed ``ns`` or ``/ns`` in the file); all None if absent."""
        per = self.per_robot or {}
        return per.get(ns) or per.get("/" + ns) or RobotSummary()

    # ------------------------------------------------------------------ encode / decode
    def to_dict(self) -> dict[str, Any]:
        """The JSON object: every field (``None`` as ``null``), then :attr:`extras`."""
        out: dict[str, Any] = {}
        for f in fields(self):
            if f.name == "extras":
                continue
            value = getattr(self, f.name)
            if isinstance(value, CollisionCounts):
                value = _plain(value)
            elif f.name == "per_robot" and value is not None:
                value = {ns: _plain(r) for ns, r in value.items()}
            out[f.name] = value
        out.update(self.extras)
        return out

    @classmethod
    def from_dict(cls, data: Any) -> SimSummary:
        """The record of a decoded JSON object (see the module docstring).

        Raises:
            SimSummaryError: ``data`` is not an object, or a value has the wrong type.
        """
        if not isinstance(data, Mapping):
            raise SimSummaryError(f"expected a JSON object, got {type(data).__name__}")
        known = {f.name for f in fields(cls)} - {"extras"}
        extras = {k: v for k, v in data.items() if k not in known}
        per_robot = _object(data.get("per_robot"), "per_robot")
        if per_robot is not None:
            per_robot = {str(ns): _robot(entry, f"per_robot.{ns}")
                         for ns, entry in per_robot.items()}
        collisions = _object(data.get("collisions"), "collisions")
        return cls(
            robots=_int(data.get("robots"), "robots"),
            ticks=_int(data.get("ticks"), "ticks"),
            sim_time_s=_number(data.get("sim_time_s"), "sim_time_s"),
            wall_time_s=_number(data.get("wall_time_s"), "wall_time_s"),
            rtf=_number(data.get("rtf"), "rtf"),
            robot_ticks_per_s=_number(data.get("robot_ticks_per_s"), "robot_ticks_per_s"),
            late_ticks=_int(data.get("late_ticks"), "late_ticks"),
            dropped_messages=_int(data.get("dropped_messages"), "dropped_messages"),
            collisions=None if collisions is None else CollisionCounts(
                robot_robot=_int(collisions.get("robot_robot"), "collisions.robot_robot"),
                robot_wall=_int(collisions.get("robot_wall"), "collisions.robot_wall")),
            min_separation_m=_number(data.get("min_separation_m"), "min_separation_m"),
            per_robot=per_robot,
            extras=extras,
        )

    def to_json(self) -> str:
        """The file's text: :meth:`to_dict` as JSON, 2-space indent, final newline."""
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def from_json(cls, text: str) -> SimSummary:
        """The record of a file's text.

        Raises:
            SimSummaryError: not JSON, not an object, or a value has the wrong type.
        """
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise SimSummaryError(f"not JSON ({exc})") from None
        return cls.from_dict(data)

    def write(self, path: Path | str) -> None:
        """Write :meth:`to_json` to ``path``.

        Raises:
            OSError: the file cannot be written.
        """
        Path(path).write_text(self.to_json())

    @classmethod
    def read(cls, path: Path | str) -> SimSummary:
        """Read a summary file.

        Raises:
            FileNotFoundError: there is no such file.
            OSError: it cannot be read.
            SimSummaryError: it is malformed; the message starts with the path.
        """
        text = Path(path).read_text()
        try:
            return cls.from_json(text)
        except SimSummaryError as exc:
            raise SimSummaryError(f"{path}: {exc}") from None


def _plain(record) -> dict[str, Any]:
    return {f.name: getattr(record, f.name) for f in fields(record)}


def _robot(entry: Any, where: str) -> RobotSummary:
    entry = _object(entry, where)
    if entry is None:
        return RobotSummary()
    return RobotSummary(
        distance_m=_number(entry.get("distance_m"), f"{where}.distance_m"),
        collisions=_int(entry.get("collisions"), f"{where}.collisions"),
        late_ticks=_int(entry.get("late_ticks"), f"{where}.late_ticks"))


def _object(value: Any, where: str) -> Mapping | None:
    if value is None or isinstance(value, Mapping):
        return value
    raise SimSummaryError(f"{where}: expected an object, got {value!r}")


def _int(value: Any, where: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise SimSummaryError(f"{where}: expected an integer, got {value!r}")
    return value


def _number(value: Any, where: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise SimSummaryError(f"{where}: expected a finite number, got {value!r}")
    return value  # as written (an int stays an int), so a file reads back and writes unchanged
