"""End-to-end tests of ``swarm-up --coordination centralized`` (issue 11), as a user runs it.

1. 4 robots, both modes: no collision, every robot completes tasks; centralized: no two robots
   ever hold one reservation (the coordinator's events, checked by the metrics), no late goal,
   and the same command twice gives the same simulated figures;
2. the coordinator frozen (SIGSTOP: silent but alive) and then killed (SIGKILL): no other
   process crashes or restarts, the robots follow the documented rule (a robot whose goal ended
   re-sends its request with backoff and waits; its navigator holds the tick at which the goal
   ended until the coordinator has the request, so simulated time waits for the coordinator, as
   long as it takes: nothing is late and no wait times out), the supervisor restarts the
   coordinator (child ``coordinator``), which rebuilds its tables from the robots' reports, and
   tasks go on with no double reservation. The crash and restart are wall-clock events: the
   run says it is not reproducible.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import re
import signal
import time
from pathlib import Path

import psutil
import pytest

from tests.test_e2e_swarm_up import (
    EXIT_SLACK_S,
    READY_TIMEOUT_S,
    SwarmUp,
    _diff,
    _run_to_end,
    _simulated,
)

pytestmark = pytest.mark.e2e

DURATION = 150
ARGS = ["--swarm-size", "4", "--commanders", "--rtf", "0", "--duration", str(DURATION)]


def _check_clean(m: dict, diag: str) -> None:
    msg = f"metrics: {json.dumps({k: v for k, v in m.items() if k != 'comm'}, indent=1)}\n{diag}"
    assert m["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
    assert m["goals_aborted"] == 0, msg
    lazy = {ns: f["tasks"] for ns, f in m["per_robot"].items() if f["tasks"] < 1}
    assert not lazy, f"robots that completed no task: {lazy}\n{msg}"
    assert m["late_ticks"] == 0 and m["late_goals"] == 0, msg
    assert m["comm"]["by_topic"]["map"]["messages"] == 4, msg


@pytest.fixture(scope="module")
def centralized_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("central")
    _, metrics, diag = _run_to_end(ARGS + ["--coordination", "centralized"], tmp, "first",
                                   DURATION)
    return metrics, diag


def test_decentralized_small_swarm_runs_clean(tmp_path):
    _, m, diag = _run_to_end(ARGS, tmp_path, "dec", DURATION)
    _check_clean(m, diag)
    assert m["coordination"] == "decentralized"
    assert m["tasks_completed"] == m["goals_reached"]
    assert m["reservation_events"] == 0 and m["coordinator_starts"] == 0
    assert set(m["comm"]["by_topic"]) == {"map"}  # no coordinator traffic


def test_centralized_small_swarm_runs_clean_without_double_reservations(centralized_run):
    m, diag = centralized_run
    _check_clean(m, diag)
    assert m["coordination"] == "centralized"
    assert m["coordinator_starts"] == 1, diag
    assert m["reservation_events"] >= 2 * m["tasks_completed"] > 0, diag
    assert m["reservation_conflicts"] == 0, diag
    assert m["reproducible"] is True, diag
    by_topic = m["comm"]["by_topic"]
    # every task is one request and at least one assignment; 4 start-ups: 4 ready requests
    assert by_topic["request"]["messages"] >= m["tasks_completed"] + 4, by_topic
    assert by_topic["assignment"]["messages"] >= by_topic["request"]["messages"], by_topic
    assert by_topic["state"]["messages"] == 4, by_topic
    logs = Path(m["run_dir"]) / "logs"
    assert (logs / "coordinator.log").read_text().count("up (epoch") == 1


def test_centralized_same_seed_gives_same_simulated_figures(centralized_run, tmp_path):
    first, diag1 = centralized_run
    _, second, diag2 = _run_to_end(ARGS + ["--coordination", "centralized"], tmp_path,
                                   "second", DURATION)
    assert second["reproducible"] is True, diag2
    diffs = [d for d in _diff(_simulated(first), _simulated(second))
             if not d.startswith("comm.per_robot") or "bytes" in d or "messages" in d]
    assert not diffs, "simulated figures differ:\n  " + "\n  ".join(diffs) + f"\n{diag2}"
    assert first["task_times_s"] == second["task_times_s"]


def test_pipelined_policy_with_a_service_time_runs_clean(tmp_path):
    """``--policy pipelined --service-time 10``: every robot completes tasks, no collision, no
    late goal, a reproducible run; each task's robot stayed docked 10 s (its next task started
    no earlier: the coordinator's task records)."""
    _, m, diag = _run_to_end(ARGS + ["--coordination", "centralized", "--policy", "pipelined",
                                     "--service-time", "10"], tmp_path, "pipelined", DURATION)
    _check_clean(m, diag)
    assert m["service_time_s"] == 10.0, diag
    assert m["reservation_conflicts"] == 0 and m["reproducible"] is True, diag
    log = (Path(m["run_dir"]) / "logs" / "coordinator.log").read_text()
    assert "policy pipelined" in log and "service time 10 s" in log, log
    for ns, robot in m["per_robot"].items():
        times = robot["task_times_s"]
        assert all(b - a >= 10.0 for a, b in itertools.pairwise(times)), (ns, times)


def _coordinator(run: SwarmUp) -> psutil.Process:
    for p in run.track():
        with contextlib.suppress(psutil.Error):
            if any(Path(c).name == "swarm-coordinator" for c in p.cmdline()[:2]):
                return p
    raise AssertionError(f"no swarm-coordinator process\n{run.diagnostics()}")


def _wait_log(run: SwarmUp, pattern: str, timeout: float, names=("cmd_",)) -> re.Match:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for path in sorted(run.logs.glob("*.log")):
            if path.name.startswith(names):
                m = re.search(pattern, path.read_text(errors="replace"))
                if m:
                    return m
        assert run.proc.poll() is None, f"swarm-up ended\n{run.diagnostics()}"
        time.sleep(0.2)
    raise AssertionError(f"no {pattern!r} in the logs after {timeout:g} s\n{run.diagnostics()}")


def test_silent_then_killed_coordinator_follows_the_rule(tmp_path):
    args = ["--swarm-size", "4", "--commanders", "--rtf", "0", "--duration", "600",
            "--coordination", "centralized"]
    with SwarmUp(args, tmp_path) as run:
        run.wait_for_stdout(r"all 4 navigators ready", READY_TIMEOUT_S)
        _wait_log(run, r"task 1: reached", 120)
        coord = _coordinator(run)
        others = {p.pid for p in run.track() if p.pid != coord.pid}
        # 1. silent: frozen, alive (no restart). A robot whose task ends waits and re-sends.
        os.kill(coord.pid, signal.SIGSTOP)
        try:
            _wait_log(run, r"no answer from the coordinator to request \d+ \(done\); sending "
                      r"it again \(next try in 2 s\)", 120)
            _wait_log(run, r"next try in 4 s", 30)  # the backoff doubles
        finally:
            os.kill(coord.pid, signal.SIGCONT)
        tasks_before = len(re.findall(r"task \d+: reached", _all_cmd_logs(run)))
        _wait_until(lambda: len(re.findall(r"task \d+: reached", _all_cmd_logs(run)))
                    > tasks_before + 1, 120, run, "tasks after the coordinator woke up")
        # 2. killed: the supervisor restarts it; robots report; tasks go on.
        os.kill(coord.pid, signal.SIGKILL)
        _wait_until(lambda: "coordinator exited with code -9; restarted" in run.stderr(), 30,
                    run, "restart warning")
        _wait_until(lambda: (run.logs / "coordinator.log").read_text().count("up (epoch") == 2,
                    30, run, "a second coordinator")
        tasks_before = len(re.findall(r"task \d+: reached", _all_cmd_logs(run)))
        _wait_until(lambda: len(re.findall(r"task \d+: reached", _all_cmd_logs(run)))
                    > tasks_before + 1, 180, run, "tasks after the coordinator's restart")
        alive_others = {p.pid for p in run.track()}
        assert others <= alive_others, (f"processes other than the coordinator died: "
                                        f"{others - alive_others}\n{run.diagnostics()}")
        os.kill(run.proc.pid, signal.SIGINT)
        assert run.wait(30 + EXIT_SLACK_S) == 0, run.diagnostics()
        m = run.metrics()
    diag = run.diagnostics()
    assert m["restarts"] == 1, f"only the coordinator restarts: {m['restarts']}\n{diag}"
    assert m["coordinator_starts"] == 2, diag
    assert m["reservation_conflicts"] == 0, diag
    assert m["collisions"] == {"robot_robot": 0, "robot_wall": 0}, diag
    # The robot that waited held its tick (the lockstep): no wait ran out, nothing was late.
    assert (m["goal_wait_timeouts"], m["late_ticks"], m["late_goals"]) == (0, 0, 0), diag
    assert m["reproducible"] is False, diag  # the coordinator's crash: a wall-clock event


def _all_cmd_logs(run: SwarmUp) -> str:
    return "".join(p.read_text(errors="replace") for p in sorted(run.logs.glob("cmd_*.log")))


def _wait_until(cond, timeout: float, run: SwarmUp, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert run.proc.poll() is None, f"swarm-up ended\n{run.diagnostics()}"
        assert time.monotonic() < deadline, f"no {what} after {timeout:g} s\n{run.diagnostics()}"
        time.sleep(0.3)
