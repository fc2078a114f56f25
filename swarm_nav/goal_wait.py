"""The lockstep goal-wait handshake between a navigator and its commander, written once.

The simulator holds every tick until each navigator has answered it (docs/ARCHITECTURE.md).  When
a goal ends (a terminal state), the commander answers with its next goal at once, but that
message may arrive after the next tick's odometry: answered without it, the tick would drive on
the old state, and when the goal takes effect would depend on the wall clock.  So the first tick
answered after a goal ended waits (once) for the commander's next goal, unless no commander is
connected, the commander said no goal is coming (a cancel while no goal runs), or
``timeout_s`` wall seconds pass (counted: the run is then no longer reproducible).

:class:`swarm_nav.node.NavigatorNode` and the benchmark's mirror navigator
(:class:`swarm_bench.baseline_nodes.BaselineNavigatorNode`) both use :class:`GoalWait`, giving it
the means to start and stop the wall-clock timer that polls a wait.  Pure: no ROS import.
"""

from __future__ import annotations

from collections.abc import Callable

POLL_S = 0.05  # [s] wall: how often a waiting tick checks that its commander is still there


class GoalWait:
    """The state of the goal-wait handshake of one navigator.

    Args:
        timeout_s: [s] wall: how long a tick may wait for the commander's next goal.
        start_timer: ``start_timer(period_s, callback)`` starts a wall-clock timer and returns
            it (a node's ``create_timer`` on a steady clock).
        stop_timer: stops and destroys such a timer (a node's ``destroy_timer``).

    Attributes:
        timeouts: ticks answered without the commander's goal because the wait timed out.
    """

    def __init__(self, timeout_s: float, start_timer: Callable[[float, Callable], object],
                 stop_timer: Callable[[object], object]):
        self.timeout_s = timeout_s
        self.timeouts = 0
        self._start_timer = start_timer
        self._stop_timer = stop_timer
        self._timer = None  # polls the current wait
        self._terminal_ns: int | None = None  # tick at which the current terminal state began
        self._over_ns: int | None = None  # tick whose wait for a goal ended without one
        self._no_next_goal: int | None = None  # end tick of the goal after which none will come
        self._started_s = 0.0  # [s] wall (monotonic), when the current wait began

    def needed(self, t_ns: int, goal_pending: bool, commander: Callable[[], bool]) -> bool:
        """Whether the answer to tick ``t_ns`` must wait for the commander's next goal.

        Args:
            t_ns: the tick [ns].
            goal_pending: a goal has arrived and awaits its tick (then nothing is awaited).
            commander: whether a commander is connected (asked last: a middleware call).

        Returns:
            True on the first tick answered after the goal ended (normally the next one; a
            later one when that tick's odometry or scan was lost), once, while a commander is
            connected and has not said that no goal is coming.
        """
        if goal_pending or self._terminal_ns is None or t_ns <= self._terminal_ns:
            return False
        return ((self._over_ns is None or self._over_ns <= self._terminal_ns)
                and self._no_next_goal != self._terminal_ns and commander())

    def hold(self, t_ns: int, now_s: float, on_poll: Callable[[int], None]) -> None:
        """Tick ``t_ns`` waits: from wall time ``now_s`` [s] (monotonic), ``on_poll(t_ns)`` is
        called every :data:`POLL_S` until :meth:`release` (nothing if a wait is on already)."""
        if self._timer is None:
            self._started_s = now_s
            self._timer = self._start_timer(POLL_S, lambda: on_poll(t_ns))

    def must_wait(self, t_ns: int, waits: bool, now_s: float, on_poll: Callable[[int], None],
                  poll: bool = True) -> bool:
        """Whether tick ``t_ns`` must wait now (``waits``: :meth:`needed`, or the node's own
        start gate): then, with ``poll``, :meth:`hold` it; else :meth:`release`."""
        if waits:
            if poll:
                self.hold(t_ns, now_s, on_poll)
            return True
        self.release()
        return False

    def release(self) -> None:
        """No tick waits any more: stop the poll timer (if any)."""
        if self._timer is not None:
            self._stop_timer(self._timer)
            self._timer = None

    def poll(self, t_ns: int, now_s: float, commander: bool) -> bool:
        """Whether the wait of tick ``t_ns`` is over at wall time ``now_s`` [s] without a goal:
        the commander left, or ``timeout_s`` passed (counted in :attr:`timeouts`); then the
        timer is stopped.

        Args:
            t_ns: the waiting tick [ns].
            now_s: [s] wall (monotonic).
            commander: whether a commander is still connected.
        """
        if commander and now_s - self._started_s < self.timeout_s:
            return False
        if commander:
            self.timeouts += 1
        self._over_ns = t_ns
        self.release()
        return True

    def answered(self, t_ns: int, terminal: bool) -> None:
        """Tick ``t_ns`` was answered; ``terminal``: the goal is (still) ended."""
        if not terminal:
            self._terminal_ns = None
        elif self._terminal_ns is None:
            self._terminal_ns = t_ns

    def no_goal_coming(self) -> bool:
        """The commander said no next goal is coming (a cancel while no goal runs): the first
        tick after the goal that ended need not wait for one.

        Returns:
            Whether a goal had ended (else there is nothing to wait for anyway).
        """
        if self._terminal_ns is None:
            return False
        self._no_next_goal = self._terminal_ns
        return True
