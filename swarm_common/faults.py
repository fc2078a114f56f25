"""Fault injection: the ``--faults`` syntax, the fault schedule and its events (pure: no ROS).

One module for the contract between the processes that take part (STYLE.md point 15): the
simulator executes the faults of a schedule at simulated times and announces each on
``/swarm/events``; ``swarm-up`` and the group processes carry out the process-side part (killing
a navigator, a commander, the coordinator) and acknowledge it on ``/swarm/fault_acks``; the metrics
count the announcements.  docs/ARCHITECTURE.md ("Faults") describes the protocol.

The syntax (``swarm-up --faults SPEC``, ``swarm-sim --faults SPEC``): a comma-separated list ::

    KIND[:TARGET]@TIME[+DURATION]

    kill-nav:3@60          robot 3's navigator crashes at t = 60 s; restarted, it answers again
                           at 60 + 2 s (``+D`` sets the outage, default 2 s)
    kill-robot:Srobot3@60  robot 3 dies: navigator and commander gone for good, the body stays
    freeze:2@30+20         robot 2 does not move from 30 s to 50 s, whatever it is commanded
    drop:2/scan:0.5@30+20  half of robot 2's scans are lost from 30 s to 50 s (seeded);
                           topics scan, odom, cmd_vel; the fraction as 0.5 or 50%
    kill-coordinator@120   the coordinator dies at 120 s and is not restarted
    kill-coordinator@120+10  ... and is restarted at 130 s

TIME and DURATION are simulated seconds (an optional ``s`` suffix); a robot is its number
(1..N) or its namespace; without ``+D``, ``freeze`` and ``drop`` last to the end of the run.
SPEC may instead be a YAML file (``.yaml``/``.yml``), a list under ``faults:`` of mappings with
the keys ``kind``, ``robot``, ``topic``, ``fraction``, ``at`` [s] and ``for`` [s]::

    faults:
      - {kind: kill-robot, robot: 3, at: 60}
      - {kind: drop, robot: 2, topic: scan, fraction: 0.5, at: 30, for: 20}
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from swarm_common import topics
from swarm_common.errors import InputError, check_keys, did_you_mean
from swarm_common.stamps import NS_PER_S

KILL_NAV = "kill-nav"
KILL_ROBOT = "kill-robot"
FREEZE = "freeze"
DROP = "drop"
KILL_COORDINATOR = "kill-coordinator"
KINDS = (KILL_NAV, KILL_ROBOT, FREEZE, DROP, KILL_COORDINATOR)
ROBOT_KINDS = (KILL_NAV, KILL_ROBOT, FREEZE, DROP)
PROCESS_KINDS = (KILL_NAV, KILL_ROBOT, KILL_COORDINATOR)
"""Kinds with a process-side part, carried out by swarm-up or a group process."""
DROP_TOPICS = (topics.SCAN.name, topics.ODOM.name, topics.CMD_VEL.name)
"""The robot topics a ``drop`` fault can thin out (the simulator's own topics)."""
COORDINATOR = "coordinator"
"""The ``swarm-up`` child that ``kill-coordinator`` kills."""
DEFAULT_NAV_OUTAGE_S = 2.0  # [s] simulated: a killed navigator answers again this much later

START, END = "start", "end"
EVENT_NAME = "fault"
"""``name`` of a fault's ``DiagnosticStatus`` on ``/swarm/events``."""
ACK_NAME = "fault_ack"
"""``name`` of an acknowledgement on ``/swarm/fault_acks``."""
YAML_KEYS = ("kind", "robot", "topic", "fraction", "at", "for")


@dataclass(frozen=True)
class Fault:
    """One fault of a schedule.

    Attributes:
        index: its id, 1-based position in the schedule (events and acks name it).
        kind: one of :data:`KINDS`.
        at: simulated time it starts [s]; it takes effect at the first tick at or after it.
        duration: how long it lasts [s] simulated: ``freeze``/``drop`` None = to the end;
            ``kill-nav`` the navigator's outage (never None once parsed); ``kill-coordinator``
            the time until its restart, None = not restarted; ``kill-robot`` always None.
        robot: the robot's namespace without ``/`` (None for ``kill-coordinator``).
        topic: ``drop`` only: one of :data:`DROP_TOPICS`.
        fraction: ``drop`` only: the share of messages lost, in (0, 1] [-].
    """

    index: int
    kind: str
    at: float  # [s]
    duration: float | None = None  # [s]
    robot: str | None = None
    topic: str | None = None
    fraction: float | None = None

    @property
    def at_ns(self) -> int:
        """Start in integer nanoseconds of simulated time."""
        return round(self.at * NS_PER_S)

    @property
    def end_ns(self) -> int | None:
        """End in integer nanoseconds (None: lasts to the end of the run)."""
        return None if self.duration is None else round((self.at + self.duration) * NS_PER_S)

    def label(self) -> str:
        """The fault in the ``--faults`` syntax (what the user wrote, normalised)."""
        target = ""
        if self.kind == DROP:
            target = f":{self.robot}/{self.topic}:{self.fraction:g}"
        elif self.robot is not None:
            target = f":{self.robot}"
        span = "" if self.duration is None else f"+{self.duration:g}"
        return f"{self.kind}{target}@{self.at:g}{span}"

    def to_yaml(self) -> dict:
        """The fault as one entry of a faults YAML file (keys of :data:`YAML_KEYS`)."""
        out = {"kind": self.kind}
        if self.robot is not None:
            out["robot"] = self.robot
        if self.topic is not None:
            out["topic"] = self.topic
            out["fraction"] = self.fraction
        out["at"] = self.at
        if self.duration is not None:
            out["for"] = self.duration
        return out


# ------------------------------------------------------------------------------------ parsing
_ITEM = re.compile(r"^(?P<kind>[a-z-]+)(?::(?P<target>[^@]*))?@(?P<at>[^+]*)(?:\+(?P<dur>.*))?$")


def _seconds(text, what: str) -> float:
    raw = str(text).strip()
    raw = raw[:-1] if raw.endswith("s") else raw
    try:
        value = float(raw)
    except ValueError:
        raise InputError(f"{what} must be a number of simulated seconds, got {text!r}") from None
    if not math.isfinite(value) or value < 0.0:
        raise InputError(f"{what} must be a finite number of seconds >= 0, got {text!r}")
    return value


def _fraction(text) -> float:
    raw = str(text).strip()
    scale = 1.0
    if raw.endswith("%"):
        raw, scale = raw[:-1], 0.01
    try:
        value = float(raw) * scale
    except ValueError:
        raise InputError(f"the fraction must be a number in (0, 1] or a percentage, "
                         f"got {text!r}") from None
    if not (0.0 < value <= 1.0):
        raise InputError(f"the fraction must be in (0, 1] (or 1%..100%), got {text!r}")
    return value


def _robot(text, robots: tuple[str, ...], prefix: str) -> str:
    raw = str(text).strip().lstrip("/")
    name = f"{prefix}{int(raw)}" if raw.isdigit() else raw
    if name not in robots:
        span = f"1..{len(robots)}" if robots else "none"
        raise InputError(f"no robot {text!r} (robots are numbers {span} or their namespaces "
                         f"{robots[0] if robots else prefix + '1'}...)")
    return name


def _make(index: int, kind: str, *, robot=None, topic=None, fraction=None, at, duration,
          robots: tuple[str, ...], prefix: str) -> Fault:
    """Check one fault's fields and build it (``robot``, ``fraction`` as given by the user)."""
    if kind not in KINDS:
        raise InputError(f"unknown fault kind {kind!r}{did_you_mean(kind, KINDS)} "
                         f"(kinds: {', '.join(KINDS)})")
    at_s = _seconds(at, "the time")
    if at_s <= 0.0:
        raise InputError(f"the time must be > 0 s, got {at!r}")
    dur = None if duration is None else _seconds(duration, "the duration")
    if dur is not None and dur <= 0.0:
        raise InputError(f"the duration must be > 0 s, got {duration!r}")
    name = None
    if kind in ROBOT_KINDS:
        if robot is None or str(robot).strip() == "":
            example = "drop:2/scan:0.5@30+20" if kind == DROP else f"{kind}:3@60"
            raise InputError(f"{kind} needs a robot ({example})")
        name = _robot(robot, robots, prefix)
    elif robot is not None:
        raise InputError(f"{kind} takes no robot")
    if kind == DROP:
        if topic not in DROP_TOPICS:
            raise InputError(f"drop: topic must be one of {', '.join(DROP_TOPICS)}, got "
                             f"{topic!r}{did_you_mean(str(topic), DROP_TOPICS)} "
                             "(drop:2/scan:0.5@30+20)")
        if fraction is None:
            raise InputError("drop needs a fraction (drop:2/scan:0.5@30+20)")
        frac = _fraction(fraction)
    elif topic is not None or fraction is not None:
        raise InputError(f"{kind} takes no topic or fraction")
    else:
        frac = None
    if kind == KILL_ROBOT and dur is not None:
        raise InputError("kill-robot is for good: it takes no +DURATION")
    if kind == KILL_NAV and dur is None:
        dur = DEFAULT_NAV_OUTAGE_S
    return Fault(index=index, kind=kind, at=at_s, duration=dur, robot=name,
                 topic=topic if kind == DROP else None, fraction=frac)


def _parse_item(index: int, item: str, robots, prefix) -> Fault:
    m = _ITEM.match(item.strip())
    if m is None:
        raise InputError(f"'{item.strip()}' is not KIND[:TARGET]@TIME[+DURATION] "
                         "(e.g. kill-robot:3@60, freeze:2@30+20, drop:2/scan:0.5@30+20)")
    kind, target = m["kind"], m["target"]
    robot = topic = fraction = None
    if kind == DROP and target is not None:
        where, _, fraction = target.rpartition(":")
        if not where:
            where, fraction = target, None
        robot, _, topic = where.lstrip("/").partition("/")
        topic = topic or None
    else:
        robot = target
    try:
        return _make(index, kind, robot=robot, topic=topic, fraction=fraction, at=m["at"],
                     duration=m["dur"], robots=robots, prefix=prefix)
    except InputError as exc:
        raise InputError(f"'{item.strip()}': {exc}") from None


def _load_yaml(path: Path, robots, prefix) -> list[Fault]:
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise InputError(f"{path}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if isinstance(data, dict):
        unknown = set(data) - {"faults"}
        if unknown:
            key = sorted(unknown)[0]
            raise InputError(f"{path}: unknown key '{key}'{did_you_mean(key, ('faults',))}")
        data = data.get("faults")
    if data is None:
        return []
    if not isinstance(data, list):
        raise InputError(f"{path}: 'faults' must be a list of mappings")
    faults = []
    for i, entry in enumerate(data, start=1):
        where = f"{path}: fault {i}"
        if not isinstance(entry, dict):
            raise InputError(f"{where}: must be a mapping with keys {', '.join(YAML_KEYS)}")
        check_keys(where, entry, YAML_KEYS, ("kind", "at"))
        try:
            faults.append(_make(i, str(entry["kind"]), robot=entry.get("robot"),
                                topic=entry.get("topic"), fraction=entry.get("fraction"),
                                at=entry["at"], duration=entry.get("for"), robots=robots,
                                prefix=prefix))
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
    return faults


def _check_schedule(faults: list[Fault], duration: float | None) -> None:
    dead: dict[str, float] = {}
    for f in faults:
        if f.kind == KILL_ROBOT:
            dead[f.robot] = min(dead.get(f.robot, math.inf), f.at)
    for f in faults:
        if duration is not None and f.at >= duration:
            raise InputError(f"'{f.label()}' starts at or after the end of the run "
                             f"(--duration {duration:g})")
        if f.robot in dead and f.kind != KILL_ROBOT and f.at >= dead[f.robot]:
            raise InputError(f"'{f.label()}': {f.robot} is dead from t = {dead[f.robot]:g} s")
        if f.kind == KILL_ROBOT and f.at > dead[f.robot]:
            raise InputError(f"'{f.label()}': {f.robot} is already dead")
    navs = sorted((f for f in faults if f.kind == KILL_NAV), key=lambda f: (f.robot, f.at))
    for a, b in zip(navs, navs[1:], strict=False):
        if a.robot == b.robot and b.at_ns <= a.end_ns:
            raise InputError(f"'{b.label()}': {a.robot}'s navigator is still down "
                             f"('{a.label()}')")
    coords = sorted((f for f in faults if f.kind == KILL_COORDINATOR), key=lambda f: f.at)
    for a, b in zip(coords, coords[1:], strict=False):
        if a.end_ns is None or b.at_ns <= a.end_ns:
            raise InputError(f"'{b.label()}': the coordinator is still down ('{a.label()}')")


def parse_faults(spec: str, robots: tuple[str, ...], name_prefix: str = "Srobot",
                 duration: float | None = None) -> tuple[Fault, ...]:
    """Parse and check a ``--faults`` SPEC: the inline syntax, or a YAML file's path.

    Args:
        spec: ``kill-robot:3@60,freeze:2@30+20`` or ``PATH.yaml``.
        robots: the run's namespaces without ``/`` (robot ``i`` is ``robots[i - 1]``).
        name_prefix: the namespace prefix, for robots given by number.
        duration: the run's simulated duration [s] (None: until Ctrl-C); a fault starting at or
            after it is an error.

    Returns:
        The faults, numbered 1.. in the order given.

    Raises:
        InputError: a malformed item or file; the message is one line naming the item (the
            caller prefixes its flag).
    """
    text = spec.strip()
    if not text:
        raise InputError("empty fault list (e.g. kill-robot:3@60)")
    if text.endswith((".yaml", ".yml")) or Path(text).is_file():
        faults = _load_yaml(Path(text), robots, name_prefix)
    else:
        faults = [_parse_item(i, item, robots, name_prefix)
                  for i, item in enumerate(text.split(","), start=1)]
    _check_schedule(faults, duration)
    return tuple(faults)


def coordinator_outages(spec: str) -> tuple[tuple[int, int | None], ...]:
    """The ``kill-coordinator`` windows of a schedule (inline SPEC or YAML file, as
    :func:`parse_faults` reads it; its other faults are not checked: a commander knows no robot
    but its own): ``(start_ns, end_ns)`` pairs of simulated time [ns], ``end_ns`` None when the
    coordinator is not restarted. A coordinated commander asks no coordinator inside one
    (:mod:`swarm_commander.coordinated`).

    Raises:
        InputError: a malformed ``kill-coordinator`` item or file.
    """
    text = spec.strip()
    if text.endswith((".yaml", ".yml")) or Path(text).is_file():
        try:
            data = yaml.safe_load(Path(text).read_text()) or {}
        except (OSError, yaml.YAMLError) as exc:
            raise InputError(f"{text}: cannot read ({exc})") from None
        entries = data.get("faults") or [] if isinstance(data, dict) else data
        faults = [_make(i, KILL_COORDINATOR, at=e["at"], duration=e.get("for"), robots=(),
                        prefix="")
                  for i, e in enumerate(entries or [], start=1)
                  if isinstance(e, dict) and e.get("kind") == KILL_COORDINATOR and "at" in e]
    else:
        faults = [_parse_item(i, item, (), "") for i, item in enumerate(text.split(","), 1)
                  if item.strip().startswith(KILL_COORDINATOR)]
    return tuple((f.at_ns, f.end_ns) for f in faults)


def dump_faults(faults, path: Path) -> None:
    """Write a schedule as a faults YAML file (what :func:`parse_faults` reads back)."""
    path.write_text(yaml.safe_dump({"faults": [f.to_yaml() for f in faults]}, sort_keys=False))


# ----------------------------------------------------------------------- events and acks
@dataclass(frozen=True)
class FaultEvent:
    """A fault's start or end as announced on ``/swarm/events`` (a ``DiagnosticStatus`` named
    :data:`EVENT_NAME`; these are its ``values`` besides ``robot``, ``x``, ``y``, ``t``).

    Attributes:
        fault: the fault's id (:attr:`Fault.index`).
        kind: one of :data:`KINDS`.
        phase: :data:`START` or :data:`END`.
        robot: namespace without ``/``, or "" (the coordinator).
        t: simulated time of the tick it took effect at [s].
        duration: the fault's duration [s] ("" in the values when None).
        topic, fraction: of a ``drop``.
    """

    fault: int
    kind: str
    phase: str
    robot: str = ""
    t: float = 0.0
    duration: float | None = None
    topic: str = ""
    fraction: float | None = None

    def encode(self) -> dict[str, str]:
        """The values as strings (``robot`` and ``t`` included)."""
        return {"fault": str(self.fault), "kind": self.kind, "phase": self.phase,
                "robot": self.robot, "t": f"{self.t:.3f}",
                "duration": "" if self.duration is None else f"{self.duration:g}",
                "topic": self.topic,
                "fraction": "" if self.fraction is None else f"{self.fraction:g}"}

    @classmethod
    def decode(cls, values: dict[str, str]) -> FaultEvent | None:
        """Read an event's values; None if they are not an injected fault's (e.g. the
        simulator's "stopped answering" events, which have no ``kind``)."""
        kind, phase = values.get("kind", ""), values.get("phase", "")
        if kind not in KINDS or phase not in (START, END):
            return None
        try:
            fault = int(values.get("fault", ""))
            t = float(values.get("t", "nan"))
            dur = values.get("duration", "")
            frac = values.get("fraction", "")
            return cls(fault=fault, kind=kind, phase=phase,
                       robot=values.get("robot", "").strip().lstrip("/"), t=t,
                       duration=float(dur) if dur else None, topic=values.get("topic", ""),
                       fraction=float(frac) if frac else None)
        except ValueError:
            return None


@dataclass(frozen=True)
class FaultAck:
    """An acknowledgement on ``/swarm/fault_acks`` (``DiagnosticStatus`` named
    :data:`ACK_NAME`): the process-side part of fault ``fault``'s ``phase`` is done.

    Attributes:
        fault: the fault's id.
        phase: :data:`START` (the process is dead) or :data:`END` (restarted).
        by: who did it (``swarm-up``, ``group_2``), for logs.
    """

    fault: int
    phase: str
    by: str = ""

    def encode(self) -> dict[str, str]:
        """The values as strings."""
        return {"fault": str(self.fault), "phase": self.phase, "by": self.by}

    @classmethod
    def decode(cls, values: dict[str, str]) -> FaultAck | None:
        """Read an ack's values; None if malformed."""
        try:
            fault = int(values.get("fault", ""))
        except ValueError:
            return None
        phase = values.get("phase", "")
        if phase not in (START, END):
            return None
        return cls(fault=fault, phase=phase, by=values.get("by", ""))


def drop_rng(seed: int, fault: Fault) -> np.random.Generator:
    """The generator deciding which messages a ``drop`` fault loses: one per fault, from the
    run's seed and the fault's id, so the same seed and schedule lose the same messages."""
    return np.random.default_rng([int(seed), 0xFA017, int(fault.index)])
