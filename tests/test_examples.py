"""Smoke test of the examples ladder (``examples/0X_*.py``), each run as a user runs it.

01 drives by hand, so it runs against ``swarm-sim`` alone (a navigator's stamped commands replace
manual ones). 02-04 run in order against one ``swarm-up --swarm-size 3 --rtf 0`` for the module;
after each, the robots' true poses (``/<ns>/ground_truth``) are checked against the goals.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest
import rclpy
from nav_msgs.msg import Odometry

from tests.support.ros import ros_context, spin_until, start, stop

pytestmark = [pytest.mark.e2e, pytest.mark.node]

ROOT = Path(__file__).resolve().parents[1]
GOAL_TOLERANCE = 0.25  # [m] nav2's xy_goal_tolerance, the navigator's default
LOADER = {1: (-7.74575, -3.57766), 2: (-7.74575, -1.38526), 3: (-7.74575, 0.97297)}  # [m]


def run_example(script: str, *args: str, timeout: float) -> subprocess.CompletedProcess:
    """Run ``examples/<script>`` with the venv's Python; fail the test after ``timeout`` [s]."""
    argv = [sys.executable, str(ROOT / "examples" / script), *args]
    try:
        return subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=timeout,
                              env=os.environ.copy())
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout
        pytest.fail(f"{script} did not end within {timeout:g} s; its output:\n{out}")


def check_ok(proc: subprocess.CompletedProcess, *lines: str) -> None:
    """Exit code 0, no traceback, and every one of ``lines`` in stdout."""
    text = f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    assert proc.returncode == 0, text
    assert "Traceback" not in proc.stderr, text
    out = proc.stdout.splitlines()
    for line in lines:
        assert line in out, f"missing line {line!r}\n{text}"


def true_positions(namespaces, timeout: float = 10.0) -> dict[str, tuple[float, float]]:
    """The latest (x, y) [m] in ``map`` of each robot, from ``/<ns>/ground_truth``."""
    seen = {}
    with ros_context() as (ctx, executor):
        node = rclpy.create_node("examples_probe", context=ctx)
        for ns in namespaces:
            node.create_subscription(
                Odometry, f"/{ns}/ground_truth",
                lambda m, ns=ns: seen.update({ns: (m.pose.pose.position.x,
                                                   m.pose.pose.position.y)}), 10)
        executor.add_node(node)
        spin_until(executor, lambda: len(seen) == len(namespaces), timeout, "ground truth")
        node.destroy_node()
    return seen


def assert_at(namespace: str, position, goal) -> None:
    dist = math.dist(position, goal)
    assert dist <= GOAL_TOLERANCE + 0.05, f"{namespace} at {position}, {dist:.2f} m from {goal}"


def process_tree(pid: int) -> list[psutil.Process]:
    """``pid`` and its descendants (swarm-up's children run in sessions of their own)."""
    try:
        me = psutil.Process(pid)
        return [me, *me.children(recursive=True)]
    except psutil.NoSuchProcess:
        return []


def survivors(procs: list[psutil.Process], timeout: float) -> list[str]:
    """Wait up to ``timeout`` [s] for ``procs`` to end; SIGKILL and name those that did not."""
    deadline = time.monotonic() + timeout
    alive = procs
    while alive and time.monotonic() < deadline:
        time.sleep(0.1)
        alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    names = []
    for p in alive:
        try:
            names.append(" ".join(p.cmdline()[:3]))
            p.kill()
        except psutil.NoSuchProcess:
            pass
    return names


@pytest.fixture(scope="module")
def swarm(tmp_path_factory):
    """``swarm-up --swarm-size 3 --rtf 0`` (no commanders, no duration), up until the module
    ends; then Ctrl-C, and every process it started must be gone."""
    tmp = tmp_path_factory.mktemp("examples")
    log = tmp / "swarm-up.log"
    proc = start(["swarm-up", "--swarm-size", "3", "--rtf", "0", "--run-dir", str(tmp / "run"),
                  "--ready-timeout", "60"], log)
    try:
        deadline = time.monotonic() + 75.0
        while "navigators ready in" not in log.read_text():
            assert proc.poll() is None, f"swarm-up exited ({proc.returncode}):\n{log.read_text()}"
            assert time.monotonic() < deadline, f"swarm-up not ready:\n{log.read_text()}"
            time.sleep(0.2)
        yield log
    finally:
        tree = process_tree(proc.pid)
        code = stop(proc, timeout=10.0)
        left = survivors(tree, timeout=5.0)
    assert code == 0, f"swarm-up exited with {code} on Ctrl-C:\n{log.read_text()}"
    assert not left, f"still running after swarm-up ended: {left}"


def test_01_drive_by_hand(tmp_path):
    sim = start(["swarm-sim", "--swarm-size", "1"], tmp_path / "sim.log")
    try:
        proc = run_example("01_drive_by_hand.py", "--timeout", "30", timeout=45.0)
    finally:
        tree = process_tree(sim.pid)
        code = stop(sim)
        left = survivors(tree, timeout=5.0)
    check_ok(proc)
    assert any(line.startswith("odom: x ") for line in proc.stdout.splitlines()), proc.stdout
    moved = re.search(r"^stopped after (\d+\.\d+) m$", proc.stdout, re.MULTILINE)
    assert moved, proc.stdout
    assert 0.3 <= float(moved.group(1)) < 1.0  # [m] at rtf 1: stopped within a few ticks
    assert code == 0 and not left, (tmp_path / "sim.log").read_text()


def test_02_go_to_pose(swarm):
    check_ok(run_example("02_go_to_pose.py", "--timeout", "60", timeout=90.0),
             "result: SUCCEEDED")
    assert_at("Srobot1", true_positions(["Srobot1"])["Srobot1"], LOADER[3])


def test_03_follow_waypoints(swarm):
    check_ok(run_example("03_follow_waypoints.py", "--timeout", "60", timeout=90.0),
             "executing waypoint 1/3", "executing waypoint 2/3", "executing waypoint 3/3",
             "result: SUCCEEDED")
    assert_at("Srobot2", true_positions(["Srobot2"])["Srobot2"], (-2.5, 8.4))


def test_04_custom_route_several_robots(swarm):
    check_ok(run_example("04_custom_route_several_robots.py", timeout=90.0),
             "Srobot1 arrived at loader2", "Srobot1 arrived at loader1",
             "Srobot2 arrived at unload", "Srobot2 arrived at shipping",
             "Srobot3 arrived at east", "Srobot3 arrived at centre")
    at = true_positions(["Srobot1", "Srobot2", "Srobot3"])
    assert_at("Srobot1", at["Srobot1"], LOADER[1])
    assert_at("Srobot2", at["Srobot2"], (7.01559, 6.99901))
    assert_at("Srobot3", at["Srobot3"], (3.0, 3.0))
