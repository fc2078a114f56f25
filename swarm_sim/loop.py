"""The simulator's control loop: the world, the tick gate and the waits, without ROS.

Each control tick (docs/ARCHITECTURE.md, "Synchronous control loop"): start and end the faults
due, wait for the recorder (the record window), publish the tick, wait for rejoining robots,
wait for the answers of every awaited robot, apply the commands, step the world.  Who is awaited
and what is applied is :class:`swarm_sim.tick.TickGate`; every wait is
:func:`swarm_common.stall.wait_until`: no wall-clock deadline, a stall reported every
``stall_report`` wall seconds.  The ROS side (messages, the executor, the logger) is behind
:class:`Ports`, which :class:`swarm_sim.node.SimulatorNode` implements and the tests fake
(tests/swarm_sim/test_loop.py).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from swarm_common.faults import END, KILL_COORDINATOR, KILL_NAV, KILL_ROBOT, START
from swarm_common.stall import wait_until
from swarm_common.stamps import NS_PER_S
from swarm_sim.faults import TickDrops
from swarm_sim.sim_control import SimControl
from swarm_sim.standstill import StandstillTracker
from swarm_sim.summary import RunLog
from swarm_sim.tick import RecordWindow, TickCommands, TickGate

RESEND_S = 0.5  # [s] wall: a tick not yet answered is published again this often
WRITER_CHECK_S = 0.5  # [s] wall: how often a waiting tick checks its robots still have a writer
READER_GRACE_S = 10.0  # [s] wall: how long the start gate waits for --wait-for-reader to match
SPIN_S = 0.05  # [s] wall: one round of a wait


class Ports(Protocol):
    """What the loop asks of its ROS shell."""

    def spin(self, timeout_s: float) -> None:
        """Service the callbacks ready within ``timeout_s`` [s] wall (they feed the gate)."""

    def stopped(self) -> bool:
        """A stop was asked (a signal, the context shut down)."""

    def publish_tick(self) -> None:
        """Publish the current tick (``/clock``, odometry, scans)."""

    def republish(self, i: int) -> None:
        """Publish robot ``i``'s odometry and scan of the current tick again."""

    def cmd_writer(self, i: int) -> bool:
        """Whether robot ``i``'s ``cmd_vel`` has a writer."""

    def progress_writer(self) -> bool:
        """Whether the recorder's progress topic has a writer."""

    def reader_matched(self, deadline_s: float) -> bool:
        """Whether ``--wait-for-reader``'s subscriptions are matched (True after
        ``deadline_s`` [s] wall, or without such a reader)."""

    def announce_faults(self, due: list) -> None:
        """Announce fault transitions ``(fault, phase)`` due at this tick."""

    def announce_late(self, robots: list[int]) -> None:
        """Announce robots found late at this tick."""

    def stepped(self, events: list) -> None:
        """The world was stepped; ``events``: the collision episodes that started."""

    def log(self, level: str, text: str) -> None:
        """A line for the operator (``info`` or ``warning``)."""


class SimLoop:
    """The control loop of one simulator (the module docstring).

    Args:
        engine: the world (:class:`swarm_sim.engine.SimEngine`), robots spawned.
        ports: the ROS shell (:class:`Ports`).
        names: (N) the robots' names in reports (their namespaces), index-aligned.
        period_ns: [ns] one control tick.
        stall_report: [s] wall, the stall report period.
        wait_for: robots that must answer before simulated time starts [-].
        record_window: [ticks] the record window (0: none).
        faults: the fault schedule walked in simulated time (:class:`SimFaults`), or None.

    Attributes:
        gate: the :class:`swarm_sim.tick.TickGate`.
        control: playing, paused, stepping (:class:`swarm_sim.sim_control.SimControl`).
        window: the :class:`swarm_sim.tick.RecordWindow`.
        log: what the summary reads besides the engine and the gate.
        drops: the messages the faults lose at this tick.
        acks: the fault acknowledgements received, ``(fault index, phase)``.
        opened: the start gate opened (False: a stop came first).
        opened_at: [s] wall (monotonic) when it opened, or None.
        wall_s: [s] wall, from the start gate's opening to the end of :meth:`run`.
        cpu_s: [s] this process's CPU time over the same span.
    """

    def __init__(self, engine, ports: Ports, names: Sequence[str], period_ns: int,
                 stall_report: float = 10.0, wait_for: int = 0, record_window: int = 0,
                 faults=None):
        self.engine = engine
        self.ports = ports
        self.names = list(names)
        self.period_ns = int(period_ns)
        self.stall_report = float(stall_report)
        self.wait_for = int(wait_for)
        self.faults = faults
        self.gate = TickGate(len(engine.poses))
        self.control = SimControl()
        self.window = RecordWindow(record_window, self.period_ns)
        self.log = RunLog(StandstillTracker(engine.poses))
        self.drops = TickDrops()
        self.acks: set[tuple[int, str]] = set()
        self.opened = False
        self.opened_at: float | None = None
        self.wall_s = 0.0
        self.cpu_s = 0.0

    # -- waits ---------------------------------------------------------------------------------
    def _wait(self, done, what, duties=(), report: bool = True) -> bool:
        """:func:`swarm_common.stall.wait_until` on the shell; ``what()`` names what the tick
        waits for in the stall report."""
        def stalled(waited: float) -> None:
            self.ports.log("warning", f"t = {self.gate.t_ns / NS_PER_S:.1f} s: waited "
                           f"{waited:.0f} s (wall) for {what()}; still waiting (a stall costs "
                           "wall time only)")

        return wait_until(done, lambda: self.ports.spin(SPIN_S),
                          report=stalled if report else None, every_s=self.stall_report,
                          duties=duties, stopped=self.ports.stopped)

    def wait_for_robots(self) -> None:
        """The start gate: hold the first tick, re-publishing it every ``RESEND_S``, until
        ``wait_for`` robots have answered it (navigators that start late still see it) and
        ``--wait-for-reader``'s subscriptions are matched (a recorder then gets every tick; a
        reader that never matches is given up ``READER_GRACE_S`` wall s after the robots).
        Its progress is said whenever the count of robots answering changes."""
        want = min(self.wait_for, self.gate.n)
        announced, grace = [-1], [math.inf]

        def done() -> bool:
            if not self.gate.started(want):
                return False
            grace[0] = min(grace[0], time.monotonic() + READER_GRACE_S)
            return self.ports.reader_matched(grace[0])

        def publish() -> None:
            count = int(self.gate.active.sum())
            if count != announced[0]:
                announced[0] = count
                self.ports.log("info", f"start gate: {count}/{want} robots answering")
            self.ports.publish_tick()

        if not done():
            publish()
            self._wait(done, lambda: "the start gate", ((RESEND_S, publish),), report=False)

    def wait_for_recorder(self) -> None:
        """The record window: hold this tick until the recorder has taken the tick
        ``record_window`` ticks before (a stalled recorder then loses nothing); not once the
        progress topic has no writer (checked every ``WRITER_CHECK_S``: the recorder is
        gone)."""
        def check_writer() -> None:
            if not self.ports.progress_writer():
                self.window.give_up()
                self.ports.log("warning", "the recorder is gone; ticks no longer wait for it")

        if self.window.holds(self.gate.t_ns):
            self._wait(lambda: not self.window.holds(self.gate.t_ns), lambda: "the recorder",
                       ((WRITER_CHECK_S, check_writer),))

    def hold_for_ack(self, fault, phase: str) -> None:
        """Hold simulated time until fault ``fault``'s ``phase`` is acknowledged."""
        self._wait(lambda: (fault.index, phase) in self.acks,
                   lambda: f"the acknowledgement of fault {fault.index} ({fault.label()}) "
                   f"{phase}")

    def wait_for_rejoin(self) -> None:
        """Hold this tick until every rejoining robot (a killed navigator's outage ended) has
        answered it, re-publishing its odometry and scan every ``RESEND_S`` for a navigator
        that subscribed late (rule 6 of :mod:`swarm_sim.tick`)."""
        gate = self.gate

        def resend() -> None:
            for i in gate.rejoin - gate.answers.keys():
                self.ports.republish(i)

        if self._wait(lambda: not gate.rejoining(), lambda: "the restarted navigator of "
                      + ", ".join(self.names[i] for i in sorted(gate.rejoin)),
                      ((RESEND_S, resend),)):
            gate.rejoin.clear()

    def collect_commands(self) -> TickCommands | None:
        """Wait for this tick's answers of the awaited robots, however long that takes, then
        decide the commands (:meth:`swarm_sim.tick.TickGate.commands`) and announce the late
        robots; None if a stop was asked meanwhile (the tick is neither stepped nor counted
        late).

        A robot is not awaited only once its navigator is known to be gone
        (:mod:`swarm_common.supervision`: the supervisor's word, or its ``cmd_vel`` without a
        writer, checked every ``WRITER_CHECK_S``).  The tick's scan and odometry are published
        again every ``RESEND_S`` to a robot not yet answered: scans are best effort
        (sensor-data QoS), and a navigator that was paused or busy may have lost one, which it
        waits for; a copy changes nothing simulated (the navigator answers a tick once).
        """
        gate, excused = self.gate, self.drops.excused
        waiting: set[int] = set()

        def done() -> bool:
            nonlocal waiting
            waiting = gate.awaited(excused, waiting)
            return not waiting

        def resend() -> None:
            for i in waiting:
                self.ports.republish(i)

        def check_writers() -> None:
            for i in list(waiting):
                if not self.ports.cmd_writer(i):
                    self.lose(i, "its cmd_vel has no writer")

        if not self._wait(done, lambda: ", ".join(
                self.names[i] for i in sorted(waiting - gate.lost)),
                ((RESEND_S, resend), (WRITER_CHECK_S, check_writers))):
            return None
        cmds = gate.commands(time.monotonic(), excused, self.drops.cmd_vel)
        self.ports.announce_late(cmds.late)
        return cmds

    def lose(self, i: int, reason: str, for_good: bool = False) -> None:
        """Robot ``i``'s navigator is gone: not awaited until it answers again."""
        if self.gate.lose(i, for_good):
            self.ports.log("warning", f"{self.names[i]}: navigator gone ({reason}); not "
                           "waited for until it answers again")

    def hold(self) -> None:
        """Hold between two ticks while paused (and no step is asked for): the shell answers
        the requests waiting for this boundary meanwhile (:mod:`swarm_sim.sim_control`)."""
        control = self.control
        control.at_boundary = True
        t0 = time.monotonic()
        try:
            self._wait(control.may_tick, lambda: "play or a step (paused)", report=False)
        finally:
            control.paused_wall_s += time.monotonic() - t0
            control.at_boundary = False

    # -- the tick ------------------------------------------------------------------------------
    def apply_faults(self) -> None:
        """Start and end the faults due at this tick, before it is published: announce each;
        hold the tick for the acknowledgements the protocol needs (a killed coordinator, its
        restart; a killed navigator before its robot rejoins); decide the messages lost at
        this tick."""
        t = self.gate.t_ns
        due = self.faults.advance(t)
        for f, phase in due:
            self.log.fault_log.append(self.faults.log_entry(f, phase, t, self.engine.poses))
        self.ports.announce_faults(due)
        for f, phase in due:
            i = self.faults.robot(f) if f.robot is not None else None
            if f.kind in (KILL_NAV, KILL_ROBOT) and phase == START:
                self.gate.kill(i)  # not awaited; its answers are ignored from now
            elif f.kind == KILL_NAV and phase == END:
                # The old navigator must be gone before its robot's odometry flows again, so
                # that the answer the tick waits for comes from its successor.
                self.hold_for_ack(f, START)
                self.gate.rejoin.add(i)
            elif f.kind == KILL_COORDINATOR:
                self.hold_for_ack(f, phase)
        self.gate.silenced = self.faults.silenced()
        self.drops = self.faults.draw_drops(self.engine.lidar_due_mask())

    def step(self, v: np.ndarray, w: np.ndarray) -> None:
        """Step the world one tick (``v`` (N,) [m/s], ``w`` (N,) [rad/s]) and announce the
        collision episodes that started."""
        held = self.faults.held_still() if self.faults is not None else None
        events = self.engine.step(v, w, held)
        self.gate.advance(self.period_ns)
        self.log.standstills.update(self.gate.t_ns / NS_PER_S, self.engine.poses)
        self.log.sample(self.gate.t_ns, self.engine.poses)
        self.ports.stepped(events)

    def run(self, duration_s: float | None = None, rtf: float = 0.0) -> None:
        """Run until ``duration_s`` simulated seconds have passed (None: until stopped).

        Args:
            duration_s: [s] simulated.
            rtf: real-time factor to pace to (callbacks are serviced while the wall clock
                catches up); 0: unpaced.
        """
        n = self.gate.n
        # Tick 0 is stepped silently so that no tick carries the zero stamp of manual commands.
        self.step(np.zeros(n), np.zeros(n))
        self.wait_for_robots()
        self.opened = not self.ports.stopped()
        wall0, cpu0 = time.monotonic(), time.process_time()
        self.opened_at = wall0
        sim0_ns = self.gate.t_ns
        end_ns = None if duration_s is None else round(duration_s * NS_PER_S)
        timeline = self.log.wall_timeline
        while not self.ports.stopped() and (end_ns is None or self.gate.t_ns < end_ns):
            if not self.control.may_tick():
                self.hold()
                if self.ports.stopped():
                    break
            if self.faults is not None:
                self.apply_faults()
            self.wait_for_recorder()
            self.ports.publish_tick()
            if self.gate.rejoin:
                self.wait_for_rejoin()
            cmds = self.collect_commands()
            if cmds is None:
                break
            self.step(cmds.v, cmds.w)
            self.control.ticked()
            if self.gate.t_ns >= (len(timeline) + 1) * NS_PER_S:
                timeline.append(round(time.monotonic() - wall0, 3))
            if rtf > 0.0:
                due = (wall0 + self.control.paused_wall_s  # a pause does not pace
                       + (self.gate.t_ns - sim0_ns) / NS_PER_S / rtf)
                while (left := due - time.monotonic()) > 0.0 and not self.ports.stopped():
                    self.ports.spin(min(left, 0.1))
            else:
                self.ports.spin(0.0)
        self.wall_s = time.monotonic() - wall0
        self.cpu_s = time.process_time() - cpu0

