"""The tick gate: who a control tick waits for, what it applies, written once and pure.

The simulator holds every control tick until each robot it awaits has answered it
(docs/ARCHITECTURE.md, "Synchronous control loop"); that lockstep is what makes a seeded run
reproducible.  Its rules, which :class:`swarm_sim.node.SimulatorNode` and the messaging
baseline (:class:`swarm_bench.baseline_nodes.BaselineSimNode`) both follow through this module:

1. **Answers.** A ``cmd_vel`` stamped with the current tick is the robot's answer to it (from a
   silenced robot, a fault's victim, it is ignored); any other non-zero stamp answers an earlier
   tick: too late, ignored.  A robot that answers is *active* (awaited from then on) and no
   longer *lost*.
2. **Teleop priority.** A zero-stamped command is manual driving: applied at once and held until
   replaced; it outranks the navigator's answers for :data:`MANUAL_PRIORITY_S` wall seconds
   after it arrived, as teleop outranks navigation in twist_mux (whose default timeout is 0.5 s).
3. **Awaited.** A tick awaits every active robot that has not answered, is not *excused* (its
   odometry or scan was dropped by a fault this tick) and is not *lost* (its navigator is known
   to be gone: the supervisor's word, or its ``cmd_vel`` without a writer).  No wall-clock
   timeout removes a robot from the awaited set.
4. **Late.** When the awaited set is empty, an active robot that neither answered nor was excused
   (it was lost meanwhile) is *late*: it stops for this tick, its late ticks are counted, and it
   is not awaited until it answers again (then it is announced as answering again).
5. **The start gate.** Simulated time starts once ``want`` robots answer the first tick.
6. **Rejoin.** A robot whose killed navigator is restarted is awaited at the tick its outage
   ends, before the tick's answers are collected, unless the supervisor gave up on it for good.
7. **Faults.** A killed navigator's or robot's answers are ignored from the fault's start; a
   ``cmd_vel`` lost to a fault leaves the drive on the robot's previous command.
8. **The record window** (:class:`RecordWindow`): a tick is held until the recorder has taken
   the tick ``window`` ticks before.

Fed events (answers, the supervisor's word, faults), the gate returns decisions (the awaited
set, the commands and the late robots of a tick); waiting, messages and clocks stay in the ROS
shell.  Pure: no ROS import; tested in tests/swarm_sim/test_tick.py.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass, field

import numpy as np

MANUAL_PRIORITY_S = 0.5  # [s] wall: twist_mux's default timeout of a higher-priority input


@dataclass
class TickCommands:
    """The decision of one tick, once nothing is awaited any more.

    Attributes:
        v: (N,) [m/s] linear velocity of every robot.
        w: (N,) [rad/s] angular velocity of every robot.
        late: robots (indices) found late at this tick, in index order (rule 4).
    """

    v: np.ndarray
    w: np.ndarray
    late: list[int] = field(default_factory=list)


class TickGate:
    """The lockstep of ``n`` robots (the module docstring's rules 1-7).

    Args:
        n: number of robots N (indices 0..N-1).
        manual_priority_s: [s] wall, rule 2's window.

    Attributes:
        t_ns: [ns] the current tick's simulated time (its stamp).
        ticks: ticks stepped so far (the first, tick 0, is stepped before the start gate).
        active: (N,) bool, robots awaited at every tick (rule 1).
        late_ticks: (N,) int, late ticks per robot (rule 4).
        lost: robots whose navigator is gone (rule 3).
        for_good: lost robots whose navigator is not restarted (rule 6).
        silenced: robots whose answers are ignored at this tick (rule 7), set per tick.
        rejoin: robots awaited before the tick's answers are collected (rule 6).
    """

    def __init__(self, n: int, manual_priority_s: float = MANUAL_PRIORITY_S):
        self.n = int(n)
        self.manual_priority_s = float(manual_priority_s)
        self.t_ns = 0
        self.ticks = 0
        self.answers: dict[int, tuple[float, float]] = {}
        self.manual: dict[int, tuple[float, float, float]] = {}  # v, w, wall time received
        self.active = np.zeros(self.n, dtype=bool)
        self.late_ticks = np.zeros(self.n, dtype=int)
        self.lost: set[int] = set()
        self.for_good: set[int] = set()
        self.silenced: set[int] = set()
        self.rejoin: set[int] = set()
        self._last = np.zeros((self.n, 2))  # the commands applied at the tick before

    # -- events --------------------------------------------------------------------------------
    def answer(self, i: int, stamp_ns: int, v: float, w: float, now_s: float) -> bool:
        """Robot ``i``'s ``cmd_vel`` stamped ``stamp_ns`` arrived at wall time ``now_s`` [s].

        Returns:
            True if robot ``i`` answers again after it was late (announce it).
        """
        if stamp_ns == 0:  # manual driving: applied now, held until replaced
            self.manual[i] = (v, w, now_s)
            return False
        if stamp_ns != self.t_ns or i in self.silenced:
            return False  # an earlier tick's answer, or a fault's victim
        self.answers[i] = (v, w)
        self.lost.discard(i)  # (its successor) answers: awaited again
        self.for_good.discard(i)
        if self.active[i]:
            return False
        self.active[i] = True
        return self.ticks > 1 and bool(self.late_ticks[i])

    def lose(self, i: int, for_good: bool = False) -> bool:
        """Robot ``i``'s navigator is gone (``for_good``: it is not restarted): not awaited until
        it answers again.  Ignored for a robot that answered this tick.

        Returns:
            True if robot ``i`` was not lost before (announce it).
        """
        if i in self.answers:
            return False
        new = i not in self.lost
        self.lost.add(i)
        if for_good:
            self.for_good.add(i)
        return new

    def kill(self, i: int) -> None:
        """Robot ``i``'s navigator (or the robot) is killed by a fault: not awaited, and its
        answer to this tick, if any, is dropped."""
        self.active[i] = False
        self.answers.pop(i, None)

    # -- decisions -----------------------------------------------------------------------------
    def started(self, want: int) -> bool:
        """The start gate (rule 5): at least ``want`` robots answer."""
        return int(self.active.sum()) >= want

    def awaited(self, excused: Collection[int] = (), known: set[int] | None = None) -> set[int]:
        """The robots this tick still awaits (rule 3).

        Args:
            excused: robots not awaited at this tick (their messages were dropped).
            known: the set this returned last time, updated in place (set operations in C
                instead of a pass over every robot); it is recomputed in full once empty, as a
                robot may have been activated meanwhile.
        """
        if known:
            known.difference_update(self.answers.keys())
            known.difference_update(self.lost)
            if known:
                return known
        return {i for i in np.flatnonzero(self.active).tolist()
                if i not in self.answers and i not in excused and i not in self.lost}

    def rejoining(self) -> set[int]:
        """Rejoining robots that have not answered this tick (rule 6)."""
        return self.rejoin - self.answers.keys() - self.for_good

    def commands(self, now_s: float, excused: Collection[int] = (),
                 cmd_dropped: Iterable[int] = ()) -> TickCommands:
        """This tick's commands, once :meth:`awaited` is empty (rules 2, 4 and 7); the answers
        are consumed.

        Args:
            now_s: [s] wall, for the teleop window.
            excused: robots not awaited at this tick.
            cmd_dropped: robots whose ``cmd_vel`` a fault lost: they keep the command of the
                tick before.
        """
        v = np.zeros(self.n)
        w = np.zeros(self.n)
        for i, (vi, wi, _) in self.manual.items():
            v[i], w[i] = vi, wi
        for i, (vi, wi) in self.answers.items():
            manual = self.manual.get(i)
            if manual is not None:
                if now_s - manual[2] < self.manual_priority_s:
                    continue  # teleop outranks the navigator while it keeps coming
                del self.manual[i]
            v[i], w[i] = vi, wi
        for i in cmd_dropped:  # a lost command: the drive keeps the last one
            if i in self.answers:
                v[i], w[i] = self._last[i]
        self._last[:, 0], self._last[:, 1] = v, w
        late = []
        for i in np.flatnonzero(self.active).tolist():
            if i in self.answers or i in excused:
                continue
            self.late_ticks[i] += 1  # stopped for this tick; not awaited until it answers
            self.active[i] = False
            late.append(i)
        self.answers.clear()
        return TickCommands(v, w, late)

    def advance(self, period_ns: int) -> None:
        """The world was stepped: the next tick begins ``period_ns`` [ns] later."""
        self.t_ns += int(period_ns)
        self.ticks += 1


class RecordWindow:
    """Rule 8: hold each tick until the recorder has taken the tick ``window`` ticks before.

    Args:
        window: [ticks] how far the recorder may be behind; 0: never hold.
        period_ns: [ns] one tick.

    Attributes:
        recorded_ns: [ns] the latest tick the recorder reports taken; -1 before its first.
    """

    def __init__(self, window: int, period_ns: int):
        self.window = int(window)
        self.period_ns = int(period_ns)
        self.recorded_ns = -1

    def progress(self, t_ns: int) -> None:
        """The recorder reports tick ``t_ns`` [ns] taken (reports may come out of order)."""
        self.recorded_ns = max(self.recorded_ns, int(t_ns))

    def holds(self, t_ns: int) -> bool:
        """Whether tick ``t_ns`` [ns] must wait for the recorder."""
        return bool(self.window) and self.recorded_ns < t_ns - self.window * self.period_ns

    def give_up(self) -> None:
        """The recorder is gone: no tick waits for it any more."""
        self.window = 0
