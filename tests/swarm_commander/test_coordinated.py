"""The centralized commander's report to a restarted coordinator (:mod:`swarm_commander.
coordinated`): what it holds and since when it waits."""

from __future__ import annotations

from unittest.mock import MagicMock

from std_msgs.msg import String

from swarm_commander.coordinated import CoordinatedRunner
from swarm_common.coordination import Assignment, encode_assignment
from swarm_common.stamps import NS_PER_S

T = NS_PER_S


def runner() -> CoordinatedRunner:
    nav = MagicMock()
    nav.get_namespace.return_value = "/Srobot4"
    nav.go_to_pose_at.return_value = True
    nav.status_stamp_ns = 300 * T
    return CoordinatedRunner(nav, emit=lambda line: None)


def assign(r: CoordinatedRunner, seq: int, kind: str, target: str, t: float,
           waits_for: str = "", task_start: float = 95.0) -> None:
    a = Assignment("Srobot4", seq, 0, kind, target, (0.0, 0.0, 0.0), round(t * T), waits_for,
                   round(task_start * T), "e1")
    r._on_assignment(String(data=encode_assignment(a)))


def test_a_robot_moved_to_the_holding_spot_keeps_its_place_in_the_queue():
    # 10 robots, seed 2: parked at 105.3 s waiting for loader5, moved to its holding spot at
    # 125.2 s; reported as waiting since 125.2 s, a restarted coordinator put a robot parked
    # since 124.5 s first.
    r = runner()
    assign(r, 1, "wait", "park1", 105.3, "loader5")
    assign(r, 2, "wait", "loader5.0", 125.2, "loader5")
    report = r._make("report")
    assert (report.holds, report.waits_for, report.since_ns) == (
        ("spot:loader5.0",), "loader5", round(105.3 * T))


def test_a_new_wait_starts_a_new_place_in_the_queue():
    r = runner()
    assign(r, 1, "wait", "park1", 105.3, "loader5")
    assign(r, 2, "go", "loader5", 125.2)
    assign(r, 3, "wait", "park2", 150.0, "loader2", task_start=149.0)
    assert r._make("report").since_ns == round(150.0 * T)
    # the same workstation again, but a later task: a new wait too
    assign(r, 4, "go", "loader2", 160.0, task_start=149.0)
    assign(r, 5, "wait", "park1", 170.0, "loader5", task_start=169.0)
    assign(r, 6, "wait", "loader5.0", 180.0, "loader5", task_start=169.0)
    assert r._make("report").since_ns == round(170.0 * T)
