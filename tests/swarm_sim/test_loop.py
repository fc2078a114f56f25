"""The simulator's loop (swarm_sim/loop.py) on a fake world and fake ROS ports: the waits the
node's loop runs, without ROS (the node's own tests run it as a process)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from swarm_common.faults import parse_faults
from swarm_sim.faults import SimFaults
from swarm_sim.loop import SimLoop

P = 100_000_000  # [ns] 10 Hz


class FakeEngine:
    """Robots on a line; each step moves robot i by v[i] * 0.1 s along x."""

    def __init__(self, n: int):
        self.poses = np.array([[float(i), 0.0, 0.0] for i in range(n)])
        self.v = np.zeros(n)
        self.w = np.zeros(n)
        self.ticks = 0
        self.commands: list[list[float]] = []

    def step(self, v, w, held=None):
        v = np.where(held, 0.0, v) if held is not None else v
        self.v, self.w = np.asarray(v, float), np.asarray(w, float)
        self.poses[:, 0] += self.v * 0.1
        self.ticks += 1
        self.commands.append(self.v.tolist())
        return []

    def lidar_due(self):
        return True

    def lidar_due_mask(self):
        return np.ones(len(self.poses), dtype=bool)


class FakePorts:
    """Navigators that answer every tick they are sent (each ``spin``), with switches."""

    def __init__(self, n: int, answering=None, max_spins=100_000):
        self.n = n
        self.answering = set(range(n)) if answering is None else set(answering)
        self.writers = set(range(n))  # robots whose cmd_vel has a writer
        self.published: list[int] = []  # ticks published (t_ns), re-publications included
        self.republished: list[tuple[int, int]] = []
        self.logs: list[tuple[str, str]] = []
        self.late: list[tuple[int, list[int]]] = []
        self.faults: list[tuple[int, str]] = []
        self.progress = True
        self.on_spin = []  # callables run each spin (a test's script)
        self.spins = 0
        self.max_spins = max_spins
        self.loop: SimLoop | None = None

    def spin(self, timeout_s):
        self.spins += 1
        if self.spins > self.max_spins:
            raise AssertionError("the loop does not end")
        time.sleep(0.001)  # the wall time a real spin takes
        gate = self.loop.gate
        for fn in self.on_spin:
            fn(self.loop)
        for i in sorted(self.answering):
            gate.answer(i, gate.t_ns, 0.1 * (i + 1), 0.0, time.monotonic())

    def stopped(self):
        return False

    def publish_tick(self):
        self.published.append(self.loop.gate.t_ns)

    def republish(self, i):
        self.republished.append((self.loop.gate.t_ns, i))

    def cmd_writer(self, i):
        return i in self.writers

    def progress_writer(self):
        return self.progress

    def reader_matched(self, deadline_s):
        return True

    def announce_faults(self, due):
        self.faults += [(f.index, phase) for f, phase in due]

    def announce_late(self, robots):
        if robots:
            self.late.append((self.loop.gate.t_ns, list(robots)))

    def stepped(self, events):
        self.steps = getattr(self, "steps", 0) + 1

    def log(self, level, text):
        self.logs.append((level, text))


def make(n=3, wait_for=None, faults=None, stall_report=10.0, record_window=0, **kw):
    engine = FakeEngine(n)
    ports = FakePorts(n, **kw)
    names = [f"Srobot{i + 1}" for i in range(n)]
    sim_faults = None
    if faults:
        sim_faults = SimFaults(parse_faults(faults, tuple(names)), names, seed=0)
    loop = SimLoop(engine, ports, names, P, stall_report,
                   n if wait_for is None else wait_for, record_window, sim_faults)
    ports.loop = loop
    return loop, engine, ports


def test_every_tick_waits_for_every_answer_and_applies_it():
    loop, engine, ports = make(3)
    loop.run(duration_s=1.0)
    assert loop.gate.t_ns == 10 * P and engine.ticks == 10  # tick 0 stepped silently
    assert engine.commands[0] == [0.0, 0.0, 0.0]
    assert all(c == pytest.approx([0.1, 0.2, 0.3]) for c in engine.commands[1:])
    assert loop.gate.late_ticks.sum() == 0
    assert len(loop.log.wall_timeline) == 1  # one simulated second


def test_the_start_gate_holds_tick_one_until_wait_for_robots_answer():
    loop, engine, ports = make(3, answering={0})

    def late_starters(lp):
        if ports.spins == 700:  # about 0.7 s wall
            ports.answering |= {1, 2}

    ports.on_spin.append(late_starters)
    loop.run(duration_s=0.2)
    assert ports.spins >= 700
    assert engine.commands[1] == pytest.approx([0.1, 0.2, 0.3])  # all from the first tick
    assert ports.logs[0] == ("info", "start gate: 0/3 robots answering")
    assert ports.published.count(P) >= 2  # the first tick, again every RESEND_S


def test_a_robot_whose_cmd_vel_loses_its_writer_is_late_once_then_not_awaited():
    loop, engine, ports = make(3)

    def crash(lp):
        if lp.gate.t_ns == 4 * P and 1 in ports.answering:
            ports.answering.discard(1)
            ports.writers.discard(1)

    ports.on_spin.append(crash)
    loop.run(duration_s=1.0)
    assert ports.late == [(4 * P, [1])]
    assert loop.gate.late_ticks.tolist() == [0, 1, 0]
    assert any("Srobot2: navigator gone (its cmd_vel has no writer)" in t for _, t in ports.logs)
    assert engine.commands[-1] == pytest.approx([0.1, 0.0, 0.3])
    assert loop.gate.t_ns == 10 * P


def test_a_silent_robot_with_a_writer_is_waited_for_and_resent_its_tick():
    loop, engine, ports = make(2, stall_report=0.2)

    def pause(lp):  # robot 2 pauses at tick 3 for about half a second of wall time
        if lp.gate.t_ns == 3 * P:
            if not hasattr(pause, "since"):
                pause.since = time.monotonic()
                ports.answering.discard(1)
            elif time.monotonic() - pause.since > 0.6:
                ports.answering.add(1)
        time.sleep(0.01)

    ports.on_spin.append(pause)
    loop.run(duration_s=0.5)
    assert loop.gate.late_ticks.sum() == 0  # waited, never dropped: no wall-clock timeout
    assert (3 * P, 1) in ports.republished  # its scan and odometry sent again
    assert any(level == "warning" and "t = 0.3 s: waited" in text and "for Srobot2" in text
               for level, text in ports.logs)


def test_the_record_window_holds_until_the_recorder_catches_up_or_is_gone():
    loop, engine, ports = make(2, record_window=2)
    recorded = []

    def recorder(lp):  # the recorder takes a tick every third spin, until it is gone at 0.8 s
        if lp.gate.t_ns >= 8 * P:
            ports.progress = False
        elif ports.spins % 3 == 0 and ports.published:
            recorded.append(ports.published[-1])
            lp.window.progress(ports.published[-1])

    ports.on_spin.append(recorder)
    seen = []
    publish = ports.publish_tick

    def publish_tick():
        if loop.gate.ticks > 1:
            seen.append((loop.gate.t_ns, loop.window.recorded_ns))
        publish()

    ports.publish_tick = publish_tick
    loop.run(duration_s=1.2)
    assert loop.gate.t_ns == 12 * P
    # held: no tick after the start gate was published more than two ticks ahead of what the
    # recorder had taken, until it was gone
    assert seen and all(t - taken <= 2 * P for t, taken in seen if t < 8 * P)
    assert any(t - taken == 2 * P for t, taken in seen)  # and it did hold
    assert loop.window.window == 0  # given up once its progress had no writer
    assert ("warning", "the recorder is gone; ticks no longer wait for it") in ports.logs


def test_a_killed_navigator_rejoins_after_its_ack_and_its_first_answer():
    loop, engine, ports = make(2, faults="kill-nav:2@0.3+0.3")
    events = []

    def navigator(lp):
        t = lp.gate.t_ns
        if (1, "start") in ports.faults and t < 6 * P:
            ports.answering.discard(1)
        if t == 6 * P and (1, "start") not in loop.acks:
            events.append(("ack", t))
            loop.acks.add((1, "start"))  # swarm-up killed the old navigator
        if t == 6 * P and (1, "start") in loop.acks and 1 not in ports.answering:
            ports.answering.add(1)  # the successor answers

    ports.on_spin.append(navigator)
    loop.run(duration_s=1.0)
    assert ports.faults == [(1, "start"), (1, "end")]
    assert events == [("ack", 6 * P)]
    cmds = engine.commands
    assert [c[1] for c in cmds[3:6]] == [0.0] * 3  # silenced during the outage (ticks 3-5)
    assert cmds[6][1] == pytest.approx(0.2)  # answered the rejoin tick
    assert loop.gate.late_ticks.sum() == 0
    assert [e["phase"] for e in loop.log.fault_log] == ["start", "end"]


def test_a_stop_ends_the_run_without_stepping_the_waiting_tick():
    loop, engine, ports = make(2, answering={0})
    ports.stopped = lambda: ports.spins > 5
    loop.run(duration_s=1.0)
    assert engine.ticks == 1 and loop.gate.t_ns == P  # only tick 0
