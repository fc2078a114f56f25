"""``swarm-experiment``: its arithmetic (Student's t, windows, fault dips), flags, and a tiny
real sweep that writes the report directory."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from swarm_up.experiment import (
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
         "comm": {"messages_per_s": 0.5, "bytes_per_s": 1000.0,
                  "by_topic": {"map": {"messages": 4, "bytes": 240000},
                               "request": {"messages": 30, "bytes": 6000},
                               "assignment": {"messages": 60, "bytes": 12000}}}}
    f = run_figures({"exit_code": 0, "metrics": m, "cpu_per_robot": 0.02}, warmup_s=120.0)
    assert f["throughput"] == pytest.approx(3 / (180 / 3600))  # 3 tasks after 120 s
    assert f["holding_per_robot"] == pytest.approx(5.0)
    assert f["collisions"] == 1 and f["cpu_per_robot_ms"] == pytest.approx(20.0)
    assert f["coord_msgs"] == pytest.approx(90 / 300) and f["coord_bytes"] == 60.0
    assert f["comm_bytes_per_robot"] == 250.0
    assert run_figures({"exit_code": 1, "metrics": m}, 120.0) is None


def test_defaults_and_cells(tmp_path):
    cfg = validate(build_parser().parse_args(["--output", str(tmp_path / "x"),
                                              "--fault-spec", "kill_robot Srobot2 at 300"]))
    assert cfg.sizes == (5, 10, 20, 40) and cfg.runs == 3 and cfg.duration_s == 300.0
    assert cfg.warmup_s == 120.0 and cfg.fault_size == 10 and cfg.fault_time_s == 300.0
    labels = [c.label for c in cfg.cells()]
    assert labels[:2] == ["decentralized-n5", "centralized-n5"]
    assert labels[-2:] == ["decentralized-n10-f1", "centralized-n10-f1"]
    cfg = validate(build_parser().parse_args(["--output", str(tmp_path / "y"), "--sizes", "5",
                                              "--fault-spec", "x at 10", "--fault-size", "7"]))
    at = validate(build_parser().parse_args([
        "--output", str(tmp_path / "z"), "--fault-spec", "kill-coordinator@50+5"]))
    assert at.fault_time_s == 50
    assert [c.label for c in cfg.cells()][2:] == [
        "decentralized-n7", "centralized-n7", "decentralized-n7-f1", "centralized-n7-f1"]


@pytest.mark.parametrize(("args", "flag"), [
    (["--sizes", "0"], "--sizes"),
    (["--runs", "0"], "--runs"),
    (["--modes", "central"], "--modes"),
    (["--world", "nowhere"], "--world"),
    (["--warmup", "400"], "--warmup"),
    (["--fault-spec", " "], "--fault-spec"),
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
            "--warmup", "5", "--output", str(out)]
    res = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path, timeout=1500)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    doc = json.loads((out / "experiment.json").read_text())
    assert len(doc["records"]) == 8 and doc["exit_code"] == 0
    assert {r["cell"] for r in doc["records"]} == {"decentralized-n2", "centralized-n2",
                                                   "decentralized-n3", "centralized-n3"}
    assert [r["seed"] for r in doc["records"][:2]] == [0, 1]
    assert all(r["metrics"]["coordination"] == r["mode"] for r in doc["records"])
    assert len(doc["summary"]) == 4 and all(s["runs_ok"] == 2 for s in doc["summary"])
    report = (out / "report.md").read_text()
    assert "swarm-experiment --sizes 2,3" in report and doc["git"]["commit"] in report
    for png in ("throughput.png", "ttt_mean.png", "comm_bytes.png", "cpu_per_robot_ms.png"):
        assert (out / png).read_bytes()[:8] == PNG_MAGIC
        assert f"]({png})" in report
    assert "report:" in res.stdout and "mean ± 95 % interval" in res.stdout
