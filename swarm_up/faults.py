"""The process side of fault injection (docs/ARCHITECTURE.md, "Faults").

The simulator executes a fault schedule at simulated times and announces every fault's start
and end on ``/swarm/events`` (:mod:`swarm_common.faults`). Whoever owns the processes carries out
the process-side part and acknowledges it on ``/swarm/fault_acks``:

- :class:`ProcessFaults`, in ``swarm-up``: with one process per robot (``--processes
  per-robot``), ``kill-nav`` kills the robot's navigator process with SIGKILL and the supervisor
  restarts it as any crashed child; ``kill-robot`` kills its navigator and commander processes
  for good. ``kill-coordinator`` kills the child named ``coordinator`` (SIGKILL) and, with a
  duration, starts it again at the fault's end.
- :class:`GroupFaults`, in a group process (:mod:`swarm_up.group`): killing the group process
  would kill all its robots, so a robot's navigator "crashes" in-process: its node is destroyed,
  and recreated ``GROUP_RESTART_DELAY_S`` later (what the supervisor does for a process);
  ``kill-robot`` destroys its navigator and commander nodes for good.

The simulator makes the outcome independent of the wall clock: a killed navigator's robot gets no
odometry until the outage ends, and that tick waits for the acknowledgement of the kill and then
for the new navigator's answer; a coordinator kill holds its tick until acknowledged, and its
restart until the new coordinator serves (:meth:`ProcessFaults.poll`).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from swarm_common import topics
from swarm_common.faults import (
    ACK_NAME,
    COORDINATOR,
    EVENT_NAME,
    KILL_COORDINATOR,
    KILL_NAV,
    KILL_ROBOT,
    START,
    FaultAck,
    FaultEvent,
)
from swarm_common.stall import StallReport
from swarm_common.supervision import LOST, RobotsLost
from swarm_ros.messages import key_values
from swarm_ros.qos import publisher, subscription

GROUP_RESTART_DELAY_S = 0.5  # [s] wall: a group recreates a killed navigator this much later


def ack_status(ack: FaultAck) -> DiagnosticStatus:
    """The ``/swarm/fault_acks`` message of an acknowledgement."""
    return DiagnosticStatus(name=ACK_NAME, message=f"fault {ack.fault} {ack.phase} done",
                            hardware_id=ack.by,
                            values=key_values(ack.encode()))


class Announcer:
    """``swarm-up``'s words to the simulator from its main thread: fault acknowledgements
    (``/swarm/fault_acks``) and the supervisor's word on robots whose navigator is gone
    (``/swarm/supervision``, :mod:`swarm_common.supervision`).

    A node in a context of its own that is never spun (publishing needs no executor, and
    publishing from the thread that spins the metrics node's ``EventsExecutor`` is the known
    deadlock of these wheels). Both topics are transient local: a word published before the
    simulator's reader matched is delivered when it matches.
    """

    def __init__(self):
        self._context = rclpy.Context()
        rclpy.init(context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self._node = Node("swarm_up_announcer", context=self._context)
        self._acks = publisher(self._node, DiagnosticStatus, topics.FAULT_ACKS)
        self._lost = publisher(self._node, DiagnosticStatus, topics.SUPERVISION)

    def ack(self, ack: FaultAck) -> None:
        """Publish one fault acknowledgement."""
        self._acks.publish(ack_status(ack))

    def lost(self, word: RobotsLost) -> None:
        """Say that these robots' navigator is gone."""
        self._lost.publish(DiagnosticStatus(
            level=DiagnosticStatus.WARN, name=LOST, message=word.reason,
            hardware_id="swarm-up",
            values=key_values(word.encode())))

    def close(self) -> None:
        """Destroy the node and shut its context down (idempotent)."""
        if self._node is not None:
            self._node.destroy_node()
            self._node = None
        if self._context.ok():
            self._context.try_shutdown()


class ProcessFaults:
    """``swarm-up``'s part: kill (and restart) its children when the simulator announces a fault.

    Args:
        supervisor: the run's :class:`swarm_up.supervisor.Supervisor`.
        per_robot: the robots whose navigator (``nav_<ns>``) and commander (``cmd_<ns>``) are
            processes of their own (robots in group processes are their group's business).
        ack: publishes a :class:`FaultAck` (:meth:`Announcer.ack`).
        say: prints one status line.
        serving: returns the epochs of the coordinators that have announced themselves
            serving (their ``coordinator`` event on ``/swarm/events``, sent with their first
            answers; :attr:`swarm_metrics.aggregate.RunRecorder.coordinator_serving`). Given, a
            restarted coordinator's end of outage is acknowledged only once a new epoch is
            among them (:meth:`poll`), so the simulator holds that tick through the
            coordinator's start-up; None: acknowledged as soon as the process is started.
        stall_report: [s] wall: a restarted coordinator not serving after this long is
            reported (and again every as long); the acknowledgement still waits for it.
        coordinator: this ``swarm-up`` carries out ``kill-coordinator`` (rank 0: the
            coordinator is its child, or there is none); False on the other ranks of a run over
            several hosts.
    """

    def __init__(self, supervisor, per_robot: tuple[str, ...], ack: Callable[[FaultAck], None],
                 say: Callable[[str], None],
                 serving: Callable[[], frozenset[str]] | None = None,
                 stall_report: float = 10.0, coordinator: bool = True):
        self.sup = supervisor
        self.coordinator = coordinator
        self.per_robot = frozenset(per_robot)
        self.ack = ack
        self.say = say
        self.serving = serving
        self.stall_report = stall_report
        self.fault_restarts = 0
        """Restarts caused by faults (decided by the schedule, not by the wall clock)."""
        self._done: set[tuple[int, str]] = set()
        # a restarted coordinator not yet serving: (event, epochs serving before, monotonic start)
        self._awaiting: tuple[FaultEvent, frozenset[str], float] | None = None
        self._stall = StallReport(stall_report)  # the current wait's reports

    def handle(self, ev: FaultEvent) -> None:
        """Carry out one announced fault transition (each once; others are ignored)."""
        key = (ev.fault, ev.phase)
        if key in self._done:
            return
        if ev.kind == KILL_COORDINATOR:
            if self.coordinator:
                self._done.add(key)
                self._coordinator(ev)
        elif ev.kind in (KILL_NAV, KILL_ROBOT) and ev.phase == START \
                and ev.robot in self.per_robot:
            self._done.add(key)
            nav, cmd = f"nav_{ev.robot}", f"cmd_{ev.robot}"
            if ev.kind == KILL_NAV:
                code = self.sup.kill(nav, restart=True)
                self.fault_restarts += 1
                self.say(f"fault {ev.fault}: killed {nav} at t = {ev.t:g} s (code {code}); "
                         "the supervisor restarts it")
            else:
                killed = [name for name in (nav, cmd) if name in self.sup.children]
                for name in killed:
                    self.sup.kill(name, restart=False)
                self.say(f"fault {ev.fault}: robot {ev.robot} dead at t = {ev.t:g} s "
                         f"(killed {', '.join(killed)})")
            self.ack(FaultAck(ev.fault, START, "swarm-up"))

    def _coordinator(self, ev: FaultEvent) -> None:
        present = COORDINATOR in self.sup.children
        if ev.phase == START:
            if present:
                restart = ev.duration is not None
                code = self.sup.kill(COORDINATOR, restart=False)
                later = f"; restarted at t = {ev.t + ev.duration:g} s" if restart else \
                    "; not restarted"
                self.say(f"fault {ev.fault}: killed the coordinator at t = {ev.t:g} s "
                         f"(code {code}){later}")
            else:
                self.say(f"fault {ev.fault}: kill-coordinator at t = {ev.t:g} s, but this run "
                         "has no coordinator (decentralized)")
        elif present:
            before = self.serving() if self.serving is not None else None
            started = self.sup.revive(COORDINATOR)
            if started:
                self.fault_restarts += 1
            self.say(f"fault {ev.fault}: coordinator {'restarted' if started else 'NOT restarted'}"
                     f" at t = {ev.t:g} s")
            if started and before is not None:
                self._awaiting = (ev, before, time.monotonic())
                self._stall.end()
                self._stall.begin(self._awaiting[2])
                return  # acknowledged by poll() once it serves
        self.ack(FaultAck(ev.fault, ev.phase, "swarm-up"))

    def poll(self) -> None:
        """Acknowledge a restarted coordinator's end of outage once it serves (a new epoch
        announced), however long that takes; call it every supervision cycle.

        The simulator holds the fault's end tick until then, so the coordinator's start-up
        (process start, discovery, the sync with every robot's report) costs no simulated
        time (why: docs/HISTORY.md, 2026-11-25). A wait of ``stall_report`` s is reported.
        """
        if self._awaiting is None:
            return
        ev, before, since = self._awaiting
        new = self.serving() - before
        waited = time.monotonic() - since
        if not new:
            if self._stall.due(since + waited) is not None:
                self.say(f"fault {ev.fault}: the restarted coordinator does not serve yet after "
                         f"{waited:.0f} s wall; simulated time waits at t = {ev.t:g} s")
            return
        self._awaiting = None
        self._stall.end()
        self.say(f"fault {ev.fault}: the restarted coordinator serves (epoch {min(new)}) after "
                 f"{waited:.1f} s wall; simulated time goes on at t = {ev.t:g} s")
        self.ack(FaultAck(ev.fault, ev.phase, "swarm-up"))


class GroupFaults:
    """A group process's part: kill its robots' navigators (and commanders) in-process.

    Call :meth:`service` from the group's spin loop after every ``spin_once`` (never from a
    callback: nodes are destroyed and created there).

    Args:
        executor: the group's executor.
        context: the group's rclpy context.
        label: the group's name (its first robot), for the node name and the acks.
        navigators: ``ns -> NavigatorNode`` of the group (updated in place).
        commanders: ``ns -> (BasicNavigator, CommanderRunner)`` (updated in place; may be empty).
        make_navigator: builds a fresh navigator node for ``ns`` (what a restart runs).
        on_node_gone: called with every node destroyed, ``on_node_new`` with every node made.
        emit: prints one line.
    """

    def __init__(self, executor, context, label: str, navigators: dict, commanders: dict,
                 make_navigator: Callable[[str], Node], on_node_gone: Callable[[Node], None],
                 on_node_new: Callable[[Node], None], emit: Callable[[str], None]):
        self.executor = executor
        self.navigators = navigators
        self.commanders = commanders
        self.make_navigator = make_navigator
        self.on_node_gone = on_node_gone
        self.on_node_new = on_node_new
        self.emit = emit
        self.by = f"group_{label}"
        self.node = Node(f"faults_{label}", context=context)
        self._pub = publisher(self.node, DiagnosticStatus, topics.FAULT_ACKS)
        # transient local, as the metrics' reader: a kill announced before this reader matched
        # the simulator's writer is still delivered (topics.EVENTS)
        subscription(self.node, DiagnosticArray, topics.EVENTS, self._on_events)
        self._todo: deque[FaultEvent] = deque()
        self._done: set[int] = set()
        self._restarts: list[tuple[float, str]] = []  # (monotonic due, ns)
        self._killed: list[Node] = []  # stopped nodes, destroyed by close()
        executor.add_node(self.node)

    def _on_events(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name != EVENT_NAME:
                continue
            ev = FaultEvent.decode({kv.key: kv.value for kv in status.values})
            if (ev is not None and ev.phase == START and ev.kind in (KILL_NAV, KILL_ROBOT)
                    and ev.robot in self.navigators and ev.fault not in self._done):
                self._done.add(ev.fault)
                self._todo.append(ev)

    def _destroy(self, node) -> None:
        """A killed node stops: it leaves the executor (no callback of it runs again) and the
        group's lists, and its DDS endpoints stay until the group ends, as a killed process's
        linger until their lease ends.  Deleting them at once took back what its writers had
        sent and a reader had not yet taken in: swarm-up's metrics listener, behind under load,
        lost a killed navigator's goal (1 of 4 runs of
        ``test_fault_runs_are_reproducible_in_both_process_layouts`` with two busy loops)."""
        self.executor.remove_node(node)
        self.on_node_gone(node)
        self._killed.append(node)

    def service(self) -> None:
        """Carry out the pending kills and the restarts that are due."""
        while self._todo:
            ev = self._todo.popleft()
            nav = self.navigators.pop(ev.robot, None)
            if nav is not None:
                self._destroy(nav)
            if ev.kind == KILL_NAV:
                self._restarts.append((time.monotonic() + GROUP_RESTART_DELAY_S, ev.robot))
                self.emit(f"fault {ev.fault}: killed {ev.robot}'s navigator at t = {ev.t:g} s; "
                          "restarting it")
            else:
                entry = self.commanders.pop(ev.robot, None)
                if entry is not None:
                    commander, runner = entry
                    runner.stop()
                    if runner.started:
                        self.emit(runner.summary())
                    self._destroy(commander)
                self.emit(f"fault {ev.fault}: robot {ev.robot} dead at t = {ev.t:g} s "
                          "(navigator and commander destroyed)")
            self._pub.publish(ack_status(FaultAck(ev.fault, START, self.by)))
        now = time.monotonic()
        due = [r for r in self._restarts if r[0] <= now]
        for r in due:
            self._restarts.remove(r)
            node = self.make_navigator(r[1])
            self.executor.add_node(node)
            self.navigators[r[1]] = node
            self.on_node_new(node)
            self.emit(f"{r[1]}'s navigator restarted")

    def close(self) -> None:
        """Destroy the fault node and the killed nodes."""
        for node in self._killed:
            node.destroy_node()
        self._killed.clear()
        self.executor.remove_node(self.node)
        self.node.destroy_node()
