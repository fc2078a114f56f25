"""``swarm-experiment``: its arithmetic (Student's t, windows, fault dips), flags, and a tiny
real sweep that writes the report directory."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from swarm_bench.experiment import (
    build_parser,
    fault_effect,
    run_figures,
    t_interval,
    validate,
    window_counts,
)

SWARM_EXPERIMENT = Path(sys.executable).parent / "swarm-experiment"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_t_interval_matches_the_student_t_table():
    mean, half = t_interval([10.0, 12.0, 14.0])
    # s = 2, n = 3, t(0.975, 2) = 4.3027: 4.3027 * 2 / sqrt(3) = 4.968
    assert mean == 12.0 and half == pytest.approx(4.968, abs=1e-3)
    assert t_interval([5.0]) == (5.0, None)
    assert t_interval([]) == (None, None)


def test_window_counts_and_fault_effect():
    assert window_counts([1.0, 29.9, 30.0, 95.0, 200.0], 120.0) == [2, 1, 0, 2]
    base = [float(t) for t in range(5, 300, 10)]  # one task per 10 s: 3 per window
    hit = [t for t in base if not 100 <= t < 160]  # nothing from 100 to 160 s
    eff = fault_effect(base, hit, fault_s=100.0, duration_s=300.0)
    assert eff["tasks_lost"] == 6
    assert eff["recovery_s"] == pytest.approx(80.0)  # window [180, 210) is the first full one
    assert fault_effect(base, base, 100.0, 300.0) == {"tasks_lost": 0, "recovery_s": 0.0}


def test_run_figures_of_a_record():
    m = {"robots": 4, "sim_time_s": 300.0, "task_times_s": [50.0, 130.0, 200.0, 290.0],
         "time_to_task_mean_s": 40.0, "time_to_task_p95_s": 70.0, "holding_time_s": 8.0,
         "coordinator_wait_s": 12.0, "collisions": {"robot_robot": 1, "robot_wall": 0},
         "late_ticks": 0, "rtf": 5.0, "tasks_completed": 4, "reproducible": True,
         "reservation_conflicts": 0,
         "tasks_per_robot": {"min": 0, "median": 1.0, "max": 2, "without_task": 1},
         "comm": {"messages_per_s": 0.5, "bytes_per_s": 1000.0,
                  "by_topic": {"map": {"messages": 4, "bytes": 240000},
                               "request": {"messages": 30, "bytes": 6000},
                               "assignment": {"messages": 60, "bytes": 12000}}}}
    f = run_figures({"exit_code": 0, "metrics": m, "cpu_per_robot": 0.02}, warmup_s=120.0)
    assert f["throughput"] == pytest.approx(3 / (180 / 3600))  # 3 tasks after 120 s
    assert f["holding_per_robot"] == pytest.approx(5.0)
    assert (f["idle_robots"], f["min_tasks"]) == (1, 0)
    assert f["collisions"] == 1 and f["cpu_per_robot_ms"] == pytest.approx(20.0)
    assert f["coord_msgs"] == pytest.approx(90 / 300) and f["coord_bytes"] == 60.0
    assert f["comm_bytes_per_robot"] == 250.0
    assert run_figures({"exit_code": 1, "metrics": m}, 120.0) is None


def test_defaults_and_cells(tmp_path):
    cfg = validate(build_parser().parse_args(["--output", str(tmp_path / "x")]))
    assert cfg.sizes == (5, 10, 20, 40) and cfg.runs == 3 and cfg.duration_s == 300.0
    assert cfg.warmup_s == 120.0 and cfg.fault_size == 10
    # by default a robot dies, and the coordinator dies (and is restarted), after the warm-up
    assert cfg.faults == ("kill-robot:3@180", "kill-coordinator@180+30")
    assert cfg.fault_times == (180.0, 180.0)
    labels = [c.label for c in cfg.cells()]
    assert labels[:2] == ["decentralized-n5", "centralized-n5"]
    # the coordinator's death runs only where there is a coordinator
    assert labels[8:] == ["decentralized-n10-f1", "centralized-n10-f1", "centralized-n10-f2"]
    cfg = validate(build_parser().parse_args(["--output", str(tmp_path / "y"), "--sizes", "5",
                                              "--fault-spec", "freeze:2@10+5",
                                              "--fault-size", "7"]))
    assert [c.label for c in cfg.cells()][2:] == [
        "decentralized-n7", "centralized-n7", "decentralized-n7-f1", "centralized-n7-f1"]
    assert cfg.fault_times == (10.0,)
    at = validate(build_parser().parse_args([
        "--output", str(tmp_path / "z"), "--fault-spec", "kill-nav:2@90,kill-robot:1@50"]))
    assert at.fault_times == (50.0,)  # the spec's earliest fault
    none = validate(build_parser().parse_args(["--output", str(tmp_path / "w"), "--no-faults"]))
    assert none.faults == () and [c.label for c in none.cells()][-1] == "centralized-n40"


@pytest.mark.parametrize(("args", "flag"), [
    (["--sizes", "0"], "--sizes"),
    (["--runs", "0"], "--runs"),
    (["--modes", "central"], "--modes"),
    (["--world", "nowhere"], "--world"),
    (["--warmup", "400"], "--warmup"),
    (["--fault-spec", " "], "--fault-spec"),
    (["--fault-spec", "kill_robot Srobot2 at 300"], "--fault-spec"),
    (["--fault-spec", "kill-robot:11@60"], "--fault-spec"),  # 10 robots in the fault runs
    (["--fault-spec", "kill-robot:3@400"], "--fault-spec"),  # after the 300 s run
    (["--fault-spec", "kill-coordinator@60", "--modes", "decentralized"], "--fault-spec"),
    (["--fault-spec", "kill-robot:3@60", "--no-faults"], "--no-faults"),
    (["--bogus"], "--bogus"),
])
def test_bad_flag_exits_2_with_one_line(args, flag, tmp_path):
    res = subprocess.run([str(SWARM_EXPERIMENT), *args], capture_output=True, text=True,
                         cwd=tmp_path, timeout=60)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and flag in lines[0] and "Traceback" not in res.stderr, res.stderr


def test_help_exits_0():
    res = subprocess.run([str(SWARM_EXPERIMENT), "--help"], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 0 and "--fault-spec" in res.stdout


@pytest.mark.e2e
def test_tiny_sweep_writes_the_report(tmp_path):
    out = tmp_path / "report"
    argv = [str(SWARM_EXPERIMENT), "--sizes", "2,3", "--duration", "15", "--runs", "2",
            "--warmup", "5", "--output", str(out), "--fault-spec", "kill-coordinator@8+3",
            "--fault-size", "2"]
    res = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path, timeout=1500)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    doc = json.loads((out / "experiment.json").read_text())
    assert len(doc["records"]) == 10 and doc["exit_code"] == 0
    assert {r["cell"] for r in doc["records"]} == {"decentralized-n2", "centralized-n2",
                                                   "decentralized-n3", "centralized-n3",
                                                   "centralized-n2-f1"}
    assert [r["seed"] for r in doc["records"][:2]] == [0, 1]
    assert all(r["metrics"]["coordination"] == r["mode"] for r in doc["records"])
    faulted = [r["metrics"] for r in doc["records"] if r["cell"] == "centralized-n2-f1"]
    assert all(m["faults"] == 1 and m["restarts"] == 1 for m in faulted)  # killed, restarted
    assert len(doc["summary"]) == 5 and all(s["runs_ok"] == 2 for s in doc["summary"])
    report = (out / "report.md").read_text()
    assert "decentralized: not run (no coordinator to kill)" in report
    assert "centralized: tasks lost against the no-fault run of the same seed" in report
    assert "swarm-experiment --sizes 2,3" in report and doc["git"]["commit"] in report
    for png in ("throughput.png", "ttt_mean.png", "comm_bytes.png", "cpu_per_robot_ms.png"):
        assert (out / png).read_bytes()[:8] == PNG_MAGIC
        assert f"]({png})" in report
    assert "report:" in res.stdout and "mean ± 95 % interval" in res.stdout
