"""The simulator's side of fault injection (pure: no ROS): which robots are dead, frozen, without
a navigator, or losing messages at a tick (docs/ARCHITECTURE.md, "Faults").

:class:`SimFaults` walks a schedule of :class:`swarm_common.faults.Fault` in simulated time.  The
simulator calls :meth:`SimFaults.advance` once per tick, before it publishes the tick, announces
the transitions it returns, and asks the queries below what to publish, whom to wait for and
whom to hold still.  Everything depends on the tick and the seed alone, never on the wall clock:

- ``kill-robot``: the robot is *silenced* (no ``odom``/``scan`` published, its ``cmd_vel``
  ignored, never waited for) and held still for the rest of the run; its body stays in the
  world, in the physics and in every other robot's lidar.
- ``kill-nav``: the robot is silenced and stopped for the outage; at its end it *rejoins*: the
  simulator holds that tick until the robot's new navigator answers it.
- ``freeze``: the robot is held still (its twist forced to zero) while its navigator keeps
  receiving ``odom`` and ``scan`` and answering: it sees itself stuck.
- ``drop``: each message of the robot's topic in the interval is lost with probability
  ``fraction`` (one seeded draw per tick, on lidar ticks only for ``scan``).  A lost ``odom`` or
  ``scan`` means the navigator cannot answer that tick: the robot is *excused* (not waited for,
  stopped for the tick, not counted late).  A lost ``cmd_vel`` means the robot keeps its previous
  command for the tick, as a drive base holds its last twist.
- ``kill-coordinator``: nothing here; the simulator only announces it and waits for the ack.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from swarm_common.faults import (
    DROP,
    END,
    FREEZE,
    KILL_NAV,
    KILL_ROBOT,
    START,
    Fault,
    FaultEvent,
    drop_rng,
)
from swarm_common.stamps import NS_PER_S


@dataclass
class TickDrops:
    """The messages lost at one tick: robot indices per topic."""

    scan: set[int] = field(default_factory=set)
    odom: set[int] = field(default_factory=set)
    cmd_vel: set[int] = field(default_factory=set)

    @property
    def excused(self) -> set[int]:
        """Robots whose navigator cannot answer this tick (lost ``odom`` or ``scan``)."""
        return self.scan | self.odom


class SimFaults:
    """A fault schedule walked in simulated time.

    Args:
        faults: the schedule (:func:`swarm_common.faults.parse_faults`).
        namespaces: robot namespaces without ``/``, index-aligned with the engine.
        seed: the run's seed (the ``drop`` draws, :func:`swarm_common.faults.drop_rng`).
    """

    def __init__(self, faults, namespaces: list[str], seed: int = 0):
        self.faults = tuple(faults)
        self.index = {ns: i for i, ns in enumerate(namespaces)}
        self.n = len(namespaces)
        transitions = []
        for f in self.faults:
            transitions.append((f.at_ns, 0, f.index, f, START))
            if f.end_ns is not None and f.kind != KILL_ROBOT:
                transitions.append((f.end_ns, 1, f.index, f, END))
        # Ends before starts at one tick (a freeze ending as another begins), then by id.
        transitions.sort(key=lambda tr: (tr[0], -tr[1], tr[2]))
        self._transitions = [(t, f, phase) for t, _, _, f, phase in transitions]
        self._next = 0
        self.dead = np.zeros(self.n, dtype=bool)
        self._frozen: dict[int, set[int]] = {}  # robot -> ids of the freezes holding it
        self._down: dict[int, Fault] = {}  # robot -> the kill-nav it is out for
        self._drops: dict[int, tuple[Fault, np.random.Generator]] = {}
        self._rngs = {f.index: drop_rng(seed, f) for f in self.faults if f.kind == DROP}
        self.dropped: dict[int, int] = {f.index: 0 for f in self.faults if f.kind == DROP}
        """Messages lost so far, per ``drop`` fault id."""

    def robot(self, fault: Fault) -> int:
        """The engine index of a fault's robot."""
        return self.index[fault.robot]

    def advance(self, t_ns: int) -> list[tuple[Fault, str]]:
        """Apply the transitions due at tick ``t_ns`` (every one with a time <= ``t_ns`` not
        applied yet) and return them, ``(fault, START | END)``, in order."""
        due = []
        while self._next < len(self._transitions) and self._transitions[self._next][0] <= t_ns:
            _, f, phase = self._transitions[self._next]
            self._next += 1
            self._apply(f, phase)
            due.append((f, phase))
        return due

    def _apply(self, f: Fault, phase: str) -> None:
        if f.robot is None:
            return
        i = self.robot(f)
        start = phase == START
        if f.kind == KILL_ROBOT:
            self.dead[i] = True
            self._down.pop(i, None)
        elif f.kind == KILL_NAV:
            if start:
                self._down[i] = f
            else:
                self._down.pop(i, None)
        elif f.kind == FREEZE:
            held = self._frozen.setdefault(i, set())
            if start:
                held.add(f.index)
            else:
                held.discard(f.index)
        elif f.kind == DROP:
            if start:
                self._drops[f.index] = (f, self._rngs[f.index])
            else:
                self._drops.pop(f.index, None)

    def log_entry(self, f: Fault, phase: str, t_ns: int, poses: np.ndarray) -> dict:
        """The summary's record of a transition at tick ``t_ns`` [ns]: ``fault``, ``kind``,
        ``phase``, ``robot``, ``t`` [s] and, for a robot's fault, ``x``, ``y`` [m] where it was
        (a dead robot's body stays there); ``poses`` (N, 3) in ``map``."""
        entry = {"fault": f.index, "kind": f.kind, "phase": phase, "robot": f.robot,
                 "t": round(t_ns / NS_PER_S, 3)}
        if f.robot is not None:
            x, y = poses[self.robot(f), :2]
            entry["x"], entry["y"] = round(float(x), 3), round(float(y), 3)
        return entry

    def event(self, f: Fault, phase: str, t_ns: int, poses: np.ndarray) -> tuple[dict, str]:
        """The ``/swarm/events`` status announcing a transition at tick ``t_ns`` [ns]: its
        values (:class:`swarm_common.faults.FaultEvent`, and ``x``, ``y`` [m] of the robot) and
        its message."""
        t = t_ns / NS_PER_S
        values = FaultEvent(fault=f.index, kind=f.kind, phase=phase, robot=f.robot or "", t=t,
                            duration=f.duration, topic=f.topic or "",
                            fraction=f.fraction).encode()
        if f.robot is not None:
            x, y = poses[self.robot(f), :2]
            values["x"], values["y"] = f"{x:.3f}", f"{y:.3f}"
        verb = "starts" if phase == START else "ends"
        return values, f"fault {f.index} {f.label()} {verb} at t = {t:.1f} s"

    # -- queries -------------------------------------------------------------------------------

    def held_still(self) -> np.ndarray:
        """(N,) bool: robots that must not move this tick (dead or frozen)."""
        mask = self.dead.copy()
        for i, held in self._frozen.items():
            if held:
                mask[i] = True
        return mask

    def silenced(self) -> set[int]:
        """Robots without a navigator now (dead, or a killed navigator's outage): nothing is
        published to them, their commands are ignored, nobody waits for them."""
        return {int(i) for i in np.flatnonzero(self.dead)} | set(self._down)

    def draw_drops(self, lidar_tick) -> TickDrops:
        """Decide which messages the active ``drop`` faults lose at this tick (call once per
        tick, after :meth:`advance`).

        Args:
            lidar_tick: whether the robots' lidars scan at this tick: a bool for all, or (N,)
                bool per robot (a mixed fleet's lidars differ in rate); a scan that is not due
                cannot be lost.
        """
        out = TickDrops()
        for f, rng in self._drops.values():
            if f.topic == "scan" and not (lidar_tick if np.ndim(lidar_tick) == 0
                                          else lidar_tick[self.robot(f)]):
                continue
            if rng.random() < f.fraction:
                getattr(out, f.topic).add(self.robot(f))
                self.dropped[f.index] += 1
        return out
