"""The wait without a wall-clock deadline, and its stall report: written once.

No wall-clock timeout decides anything simulated (docs/ARCHITECTURE.md, "Synchronous control
loop"): a process that waits for another (the simulator for a tick's answers, a fault's
acknowledgement, the recorder; a navigator for its commander; the coordinator for every
robot's first word; swarm-up for a restarted coordinator) waits however long it takes.  A wait
that lasts is only *reported*, after ``every_s`` wall seconds and again every as long, so that a
person sees which party holds the run.

- :class:`StallReport` counts one wait's reports; a process that waits across callbacks (a timer,
  a supervision cycle) asks it :meth:`StallReport.due` at each check.
- :func:`wait_until` is the loop of a process that waits in place: it spins the executor until a
  condition holds or a stop is asked, runs periodic duties (re-publishing, checking a writer)
  and reports the stall.

Pure: no ROS import; the caller passes its clock (``time.monotonic`` in the nodes, a fake one in
the tests) and its spin.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

STALL_REPORT_S = 10.0  # [s] wall: the default report period (every command's --stall-report)


class StallReport:
    """The reports of one wait: at ``every_s``, ``2 * every_s``, ... wall seconds after it began.

    Args:
        every_s: [s] wall, the report period (0: a report at every check).
        since_s: [s] wall (monotonic), when the wait began; None: not waiting yet.

    Raises:
        ValueError: ``every_s`` is negative or not a number.
    """

    def __init__(self, every_s: float = STALL_REPORT_S, since_s: float | None = None):
        if not every_s >= 0.0:
            raise ValueError(f"every_s must be 0 or more, got {every_s!r}")
        self.every_s = float(every_s)
        self.since_s = since_s
        self.reported = 0

    def begin(self, now_s: float) -> None:
        """A wait begins at ``now_s`` [s], unless one is already running."""
        if self.since_s is None:
            self.since_s, self.reported = now_s, 0

    def end(self) -> None:
        """The wait is over; the next :meth:`begin` starts a new one."""
        self.since_s, self.reported = None, 0

    def waited(self, now_s: float) -> float:
        """[s] wall waited by ``now_s`` (0 when not waiting)."""
        return 0.0 if self.since_s is None else now_s - self.since_s

    def due(self, now_s: float) -> float | None:
        """The seconds waited if a report is due at ``now_s`` (one per period, however late the
        check; a check that skipped periods reports once), else None."""
        waited = self.waited(now_s)
        if self.since_s is None or waited < (self.reported + 1) * self.every_s:
            return None
        self.reported = (math.floor(waited / self.every_s) if self.every_s
                         else self.reported + 1)
        return waited


def wait_until(done: Callable[[], bool], spin: Callable[[], None], *,
               report: Callable[[float], None] | None, every_s: float = STALL_REPORT_S,
               stopped: Callable[[], bool] = lambda: False,
               duties: Sequence[tuple[float, Callable[[], None]]] = (),
               clock: Callable[[], float] = time.monotonic) -> bool:
    """Spin until ``done()``, however long it takes; report a stall every ``every_s``.

    Each round: ``stopped()`` ends the wait, ``done()`` ends it too; each duty ``(period_s,
    fn)`` runs once ``period_s`` has passed since the wait began or it last ran; a due stall
    report calls ``report(waited_s)``; then ``spin()`` services the callbacks that may make
    ``done()`` true.

    Args:
        done: the condition waited for (checked before every spin).
        spin: one round of the executor (e.g. ``spin_once(timeout_sec=0.05)``).
        report: called with the wall seconds waited when a report is due; None: the caller
            reports progress its own way (a duty).
        every_s: [s] wall, the report period.
        stopped: a stop was asked (a signal, ``rclpy.ok()`` false): give up.
        duties: ``(period_s, fn)`` pairs, [s] wall.
        clock: [s] wall, monotonic.

    Returns:
        True once ``done()``; False if ``stopped()`` came first.
    """
    stall = StallReport(every_s, clock())
    due = [stall.since_s + period for period, _ in duties]
    while True:
        if stopped():
            return False
        if done():
            return True
        now = clock()
        for k, (period, fn) in enumerate(duties):
            if now >= due[k]:
                due[k] = now + period
                fn()
        waited = stall.due(now) if report is not None else None
        if waited is not None:
            report(waited)
        spin()
