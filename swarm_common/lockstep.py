"""The lockstep between a navigator and its commander: which tick waits for what, written once.

The simulator holds every tick until each navigator has answered it (docs/ARCHITECTURE.md,
"Synchronous control loop").  The commander (or the coordinator behind it) is a party of that
lockstep too: what it sends decides what is simulated, so a navigator holds its answer wherever
the commander's word is due, for as long as it takes.  Two waits, both per goal that ends:

1. **The end** (only with ``hold_goal_end``, the coordinated commanders of ``--coordination
   centralized``): the answer to the tick at which a goal ended waits until the commander has
   taken the end in: its next goal arrived, it said no goal is coming (``navigator/cancel``
   while no goal runs), or it said a goal is coming (``navigator/goal_coming``: the coordinator
   has its request).  So once the simulator has that tick's answers, every request stamped with
   it is with the coordinator, which answers a tick's requests together, whatever order they
   came in.
2. **The next goal**: the first tick answered after the goal ended (normally the next one; a
   later one when that tick's odometry or scan was lost) waits, once, for the commander's next
   goal, unless the commander said no goal is coming, or left (no ``goal_pose`` writer).

With the commander in the lockstep (``lockstep``: ``swarm-up --commanders`` sets it) neither wait
has a wall-clock limit: a commander that is alive but slow, paused or descheduled costs wall time,
not reproducibility, and a stall is only reported (every :data:`STALL_REPORT_S`).  Out of the
lockstep (a user's route script driving a navigator it did not start), wait 2 lasts at most
``timeout_s`` wall seconds, counted in :attr:`GoalHandshake.timeouts`: the run is then not
reproducible.

Used by :class:`swarm_nav.node.NavigatorNode` and the benchmark's mirror navigator
(:class:`swarm_bench.baseline_nodes.BaselineNavigatorNode`).  Pure: no ROS import, no clock of
its own (the caller passes the wall time).
"""

from __future__ import annotations

import math

from swarm_common.stall import STALL_REPORT_S, StallReport

POLL_S = 0.05  # [s] wall: how often a held tick checks that its commander is still there
POLL_STEPS = ((1.0, 0.05), (5.0, 0.25), (math.inf, 1.0))
"""([s] waited, [s] period) wall: a held tick polls every ``period`` until it has waited that
long; the period grows with the wait (:func:`poll_period`)."""


def poll_period(waited_s: float) -> float:
    """[s] wall: how often a tick that has waited ``waited_s`` [s] wall polls (:data:`POLL_STEPS`).

    A wait that lasts is a long one (a start gate waiting for discovery, a commander far behind):
    polling it 20 times a second cost a process of 500 waiting navigators 10,000 timer callbacks
    a second, more than it could run, and the executor's queue grew until no message was taken
    (1,000 robots in 2 group processes held at tick 0.2). Nothing simulated depends on the period:
    it only decides how soon, in wall time, a change without an event of its own (a reader or
    writer matched, a commander gone) is noticed.
    """
    for until, period in POLL_STEPS:
        if waited_s < until:
            return period
    return POLL_STEPS[-1][1]

NONE_COMING, COMING = "none", "coming"


class GoalHandshake:
    """The goal handshake of one navigator (see the module docstring).

    Args:
        lockstep: the commander is a party of the lockstep: no wait has a wall-clock limit.
        hold_goal_end: the tick at which a goal ended waits for the commander's word (wait 1).
        timeout_s: [s] wall: out of the lockstep, how long wait 2 lasts.

    Attributes:
        timeouts: ticks answered without the commander's next goal because wait 2 ran out (out
            of the lockstep only).
    """

    def __init__(self, lockstep: bool = True, hold_goal_end: bool = False,
                 timeout_s: float = 0.5):
        self.lockstep = bool(lockstep)
        self.hold_goal_end = bool(hold_goal_end)
        self.timeout_s = float(timeout_s)
        self.timeouts = 0
        self._end_ns: int | None = None  # tick at which the current terminal state began
        self._outcome = False  # ... because a goal ended (not IDLE)
        self._word: str | None = None  # NONE_COMING or COMING, said for the current end
        self._goal_since_end = False  # a goal arrived after the current end
        self._over_ns: int | None = None  # end tick whose wait 2 ended without a goal
        self._stall = StallReport(STALL_REPORT_S)  # the current wait (either), its reports

    # -- what the navigator tells it ---------------------------------------------------------
    def answered(self, t_ns: int, terminal: bool, outcome: bool = False,
                 goal_set: bool = False) -> None:
        """Tick ``t_ns`` was computed; ``terminal``: no goal runs (``outcome``: because one
        ended: SUCCEEDED, ABORTED or CANCELED; else IDLE, as at the start); ``goal_set``: a goal
        took effect at this tick (it may have ended at once: a new end all the same)."""
        if not terminal or goal_set:
            self._end_ns = None
        if terminal and self._end_ns is None:
            self._end_ns = t_ns
            self._outcome = outcome
            self._word = None
            self._goal_since_end = False

    def goal_arrived(self) -> None:
        """A goal arrived (it is the commander's word on the current end, and its next goal)."""
        self._goal_since_end = True

    def said(self, word: str) -> bool:
        """The commander's word on the goal that ended: :data:`NONE_COMING` (a cancel while no
        goal runs) or :data:`COMING`.

        Returns:
            Whether a goal had ended (else there is nothing to say it about).
        """
        if self._end_ns is None:
            return False
        self._word = word
        return True

    # -- what the navigator asks --------------------------------------------------------------
    def holds_end(self, t_ns: int, goal_pending: bool, commander) -> bool:
        """Wait 1: whether the answer to tick ``t_ns``, computed, must still wait.

        Args:
            t_ns: the tick [ns].
            goal_pending: a goal has arrived and awaits its tick.
            commander: ``commander()`` says whether a commander is connected (asked last: a
                middleware call).
        """
        return (self.hold_goal_end and self._end_ns == t_ns and self._outcome
                and self._word is None and not (goal_pending or self._goal_since_end)
                and commander())

    def awaits_goal(self, t_ns: int, goal_pending: bool, commander) -> bool:
        """Wait 2: whether the answer to tick ``t_ns`` must wait for the commander's next goal.

        Args:
            t_ns: the tick [ns].
            goal_pending: a goal has arrived and awaits its tick (then nothing is awaited).
            commander: ``commander()`` says whether a commander is connected (asked last).

        Returns:
            True on the first tick answered after the goal ended, once, while a commander is
            connected and has not said that no goal is coming.
        """
        if goal_pending or self._end_ns is None or t_ns <= self._end_ns:
            return False
        return (self._over_ns != self._end_ns and self._word != NONE_COMING
                and commander())

    def waiting(self, now_s: float) -> None:
        """A tick waits (either wait) from wall time ``now_s`` [s] on, unless one already does."""
        self._stall.begin(now_s)

    def released(self) -> None:
        """No tick waits any more."""
        self._stall.end()

    def waited(self, now_s: float) -> float:
        """[s] wall the current wait has lasted at ``now_s`` [s] (0 when no tick waits)."""
        return self._stall.waited(now_s)

    def poll(self, t_ns: int, now_s: float, commander: bool) -> tuple[bool, float | None]:
        """Check a waiting tick ``t_ns`` at wall time ``now_s`` [s].

        Args:
            t_ns: the waiting tick [ns].
            now_s: [s] wall (monotonic).
            commander: whether a commander is still connected.

        Returns:
            ``(over, stalled)``: ``over``, wait 2 ends without a goal: the commander left
            (counted in :attr:`timeouts` in the lockstep) or, out of the lockstep,
            ``timeout_s`` passed (counted); ``stalled``, the seconds waited when a stall is to
            be reported now, else None.
        """
        waited = self._stall.waited(now_s)
        ending = self._end_ns is not None and t_ns > self._end_ns
        if ending and (not commander or (not self.lockstep and waited >= self.timeout_s)):
            # counted: a timeout out of the lockstep, or a lockstep commander that left (it
            # crashed, or was stopped beyond DDS's participant lease): either way the tick is
            # answered without the goal the run would have had
            if commander or self.lockstep:
                self.timeouts += 1
            self._over_ns = self._end_ns
            self.released()
            return True, None
        return False, self._stall.due(now_s)
