"""swarm-up's side of fault injection: killing, retiring and reviving children (with stand-in
processes, no ROS), and the fault figures of the metrics."""

import sys
import time

import pytest

from swarm_common.faults import FaultAck, FaultEvent
from swarm_common.sim_summary import SimSummary
from swarm_metrics.aggregate import RunFacts, RunRecorder, aggregate
from swarm_up.faults import ProcessFaults
from swarm_up.supervisor import ChildSpec, Supervisor

SLEEPER = (sys.executable, "-c", "import time; time.sleep(100)")


@pytest.fixture
def sup():
    s = Supervisor()
    yield s
    s.stop()


def _spec(tmp_path, name):
    return ChildSpec(name, SLEEPER, tmp_path / "logs" / f"{name}.log")


def _poll_until(sup, pred, timeout=5.0):
    deadline = time.monotonic() + timeout
    exits = []
    while time.monotonic() < deadline:
        exits += sup.poll()
        if pred():
            return exits
        time.sleep(0.02)
    raise AssertionError("condition not met")


def test_kill_with_restart_is_a_supervised_restart(sup, tmp_path):
    sup.start(_spec(tmp_path, "nav_a"))
    old = sup.pid("nav_a")
    assert sup.kill("nav_a", restart=True) == -9
    exits = _poll_until(sup, lambda: sup.alive("nav_a"))
    assert [(e.name, e.code, e.restarted) for e in exits] == [("nav_a", -9, True)]
    assert sup.pid("nav_a") != old and sup.restarts == 1


def test_retired_child_stays_dead_until_revived(sup, tmp_path):
    sup.start(_spec(tmp_path, "coordinator"))
    sup.start(_spec(tmp_path, "nav_b"))
    assert sup.kill("coordinator", restart=False) == -9
    time.sleep(0.3)
    assert sup.poll() == []  # neither reported nor restarted
    assert not sup.alive("coordinator") and sup.alive("nav_b")
    assert sup.kill("coordinator", restart=False) is None  # already dead
    assert sup.revive("coordinator")
    assert sup.alive("coordinator") and sup.restarts == 1
    assert not sup.revive("coordinator")  # running


def _ev(fault, kind, phase, robot="", t=60.0, duration=None):
    return FaultEvent(fault=fault, kind=kind, phase=phase, robot=robot, t=t, duration=duration)


def test_process_faults_kill_a_robot_and_its_navigator(sup, tmp_path):
    for name in ("nav_Srobot1", "cmd_Srobot1", "nav_Srobot2", "cmd_Srobot2", "nav_Srobot3"):
        sup.start(_spec(tmp_path, name))
    acks, lines = [], []
    pf = ProcessFaults(sup, ("Srobot1", "Srobot2"), acks.append, lines.append)
    pf.handle(_ev(1, "kill-robot", "start", "Srobot1"))
    pf.handle(_ev(1, "kill-robot", "start", "Srobot1"))  # a repeated announcement: once only
    pf.handle(_ev(2, "kill-nav", "start", "Srobot2", duration=2.0))
    pf.handle(_ev(3, "kill-nav", "start", "Srobot3", duration=2.0))  # in a group: not ours
    pf.handle(_ev(4, "freeze", "start", "Srobot2", duration=2.0))  # the simulator's business
    assert acks == [FaultAck(1, "start", "swarm-up"), FaultAck(2, "start", "swarm-up")]
    _poll_until(sup, lambda: sup.alive("nav_Srobot2"))
    time.sleep(0.3)
    sup.poll()
    assert not sup.alive("nav_Srobot1") and not sup.alive("cmd_Srobot1")
    assert sup.alive("cmd_Srobot2") and sup.alive("nav_Srobot3")
    assert sup.restarts == 1 and pf.fault_restarts == 1
    assert "robot Srobot1 dead at t = 60 s (killed nav_Srobot1, cmd_Srobot1)" in lines[0]


def test_process_faults_kill_and_restart_the_coordinator(sup, tmp_path):
    """A stand-in child named ``coordinator``: killed at the fault's start, started again at
    its end, each acknowledged."""
    sup.start(_spec(tmp_path, "coordinator"))
    sup.start(_spec(tmp_path, "nav_Srobot1"))
    acks, lines = [], []
    pf = ProcessFaults(sup, ("Srobot1",), acks.append, lines.append)
    pf.handle(_ev(1, "kill-coordinator", "start", duration=10.0))
    time.sleep(0.3)
    assert sup.poll() == []
    assert not sup.alive("coordinator") and sup.alive("nav_Srobot1")
    pf.handle(_ev(1, "kill-coordinator", "end", t=70.0, duration=10.0))
    assert sup.alive("coordinator")
    assert acks == [FaultAck(1, "start", "swarm-up"), FaultAck(1, "end", "swarm-up")]
    assert pf.fault_restarts == 1
    assert "killed the coordinator at t = 60 s" in lines[0] and "restarted at t = 70 s" in lines[0]


def test_a_restarted_coordinator_is_acknowledged_once_it_serves(sup, tmp_path):
    """With ``serving`` the end of the outage is acknowledged only when a new epoch announced
    itself (the simulator holds that tick through the coordinator's start-up), however long
    that takes: a wait is only reported."""
    sup.start(_spec(tmp_path, "coordinator"))
    serving = {"old"}
    acks, lines = [], []
    pf = ProcessFaults(sup, (), acks.append, lines.append, serving=lambda: frozenset(serving),
                       stall_report=0.0)
    pf.handle(_ev(1, "kill-coordinator", "start", duration=10.0))
    pf.handle(_ev(1, "kill-coordinator", "end", t=70.0, duration=10.0))
    assert sup.alive("coordinator")
    pf.poll()
    pf.poll()
    assert acks == [FaultAck(1, "start", "swarm-up")]  # started, not serving yet: no timeout
    assert "does not serve yet" in lines[-1]  # reported (stall_report 0: at every poll)
    serving.add("new")
    pf.poll()
    pf.poll()  # acknowledged once
    assert acks == [FaultAck(1, "start", "swarm-up"), FaultAck(1, "end", "swarm-up")]
    assert "serves (epoch new)" in lines[-1] and "t = 70 s" in lines[-1]


def test_kill_coordinator_without_one_is_acknowledged(sup, tmp_path):
    acks, lines = [], []
    pf = ProcessFaults(sup, (), acks.append, lines.append)
    pf.handle(_ev(1, "kill-coordinator", "start"))
    assert acks == [FaultAck(1, "start", "swarm-up")]
    assert "has no coordinator" in lines[0]


def test_metrics_count_faults_by_kind_and_keep_fault_restarts_reproducible():
    rec = RunRecorder(robots=("Srobot1", "Srobot2"))
    for ev in (_ev(1, "kill-nav", "start", "Srobot1", 10.0, 2.0),
               _ev(1, "kill-nav", "end", "Srobot1", 12.0, 2.0),
               _ev(2, "freeze", "start", "Srobot2", 20.0, 5.0)):
        rec.on_event("fault", ev.encode())
    rec.on_event("fault", {"robot": "Srobot2", "x": "0", "y": "0", "t": "3"})  # unresponsive
    # goals applied at the first tick after their stamp (stamp + 0.1 s), reached 5 s later
    for ns, goal, stamp in (("Srobot1", "25.400000000", "30.500000000"),
                            ("Srobot2", "9.100000000", "14.200000000")):
        rec.on_status(ns, {"state": "SUCCEEDED", "goal_id": goal, "stamp": stamp,
                           "navigation_time_s": "5.0"}, 1.0)
    summary = SimSummary(sim_time_s=60.0, late_ticks=0, extras={"faults": {
        "injected": ["kill-nav:Srobot1@10+2", "freeze:Srobot2@20+5", "drop:Srobot2/scan:0.5@1"],
        "messages_dropped": {"3": 12},
        "log": [{"fault": 3, "kind": "drop", "phase": "start", "robot": "Srobot2", "t": 1.0},
                {"fault": 1, "kind": "kill-nav", "phase": "start", "robot": "Srobot1", "t": 10.0},
                {"fault": 1, "kind": "kill-nav", "phase": "end", "robot": "Srobot1", "t": 12.0},
                {"fault": 2, "kind": "freeze", "phase": "start", "robot": "Srobot2", "t": 20.0}],
    }})
    m = aggregate(rec, summary, RunFacts(world="w", seed=0, coordination="decentralized",
                  wall_time_s=10.0, restarts=1, fault_restarts=1))
    assert m["faults"] == 3
    assert m["faults_by_kind"] == {"drop": 1, "kill-nav": 1, "freeze": 1}
    assert m["fault_messages_dropped"] == 12 and "fault_ack_timeouts" not in m
    assert m["unresponsive_events"] == 1
    assert m["task_times_s"] == [14.2, 30.5]
    assert m["reproducible"] is True and m["restarts"] == 1
    # Without the simulator's log: the announcements seen; a restart not caused by a fault makes
    # the run irreproducible (an unacknowledged fault cannot happen: the simulator waits).
    m = aggregate(rec, SimSummary(sim_time_s=60.0, late_ticks=0), RunFacts(world="w", seed=0,
                  coordination="decentralized", wall_time_s=10.0, restarts=2, fault_restarts=1))
    assert m["faults_by_kind"] == {"kill-nav": 1, "freeze": 1}
    assert [e["t"] for e in m["fault_log"]] == [10.0, 12.0, 20.0]
    assert m["reproducible"] is False
