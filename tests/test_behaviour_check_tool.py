"""``tools/behaviour_check.py``: the behaviour rule of a navigator change, on records it reads."""

from __future__ import annotations

import json
import subprocess
import sys

from swarm_common.paths import ROOT

SCRIPT = ROOT / "tools" / "behaviour_check.py"


def _record(seed: int, tasks_after_warmup: int, idle: int = 0, collisions: int = 0,
            aborted: int = 0) -> dict:
    times = [100.0] + [300.0 + 600.0 * (i + 1) / (tasks_after_warmup + 1)
                       for i in range(tasks_after_warmup)]
    return {"label": "decentralized-n20", "variant": "decentralized", "size": 20, "seed": seed,
            "role": "main", "exit_code": 0, "commit": "abcdef0123", "cpu_per_robot": 0.005,
            "metrics": {"robots": 20, "sim_time_s": 900.0, "task_times_s": times,
                        "tasks_per_robot": {"without_task": idle, "min": 0},
                        "collisions": {"robot_robot": collisions, "robot_wall": 0},
                        "goals_aborted": aborted}}


def _write(directory, records) -> None:
    (directory / "records").mkdir(parents=True)
    for r in records:
        (directory / "records" / f"decentralized-n20-s{r['seed']}.json").write_text(json.dumps(r))


def _run(before, after):
    return subprocess.run([sys.executable, str(SCRIPT), str(before), str(after)],
                          capture_output=True, text=True)


def test_a_change_that_keeps_the_figures_passes(tmp_path):
    _write(tmp_path / "a", [_record(s, 100 + s) for s in range(5)])
    _write(tmp_path / "b", [_record(s, 101 + s + (s % 2)) for s in range(5)])
    out = _run(tmp_path / "a", tmp_path / "b")
    assert out.returncode == 0, out.stdout + out.stderr
    assert "20 robots, seeds [0, 1, 2, 3, 4]" in out.stdout
    assert "FAIL" not in out.stdout


def test_lower_throughput_a_collision_or_more_idle_robots_fail(tmp_path):
    _write(tmp_path / "a", [_record(s, 100 + s) for s in range(5)])
    _write(tmp_path / "b", [_record(s, 90 + s - (s % 2), idle=1 if s == 0 else 0,
                                    collisions=1 if s == 3 else 0) for s in range(5)])
    out = _run(tmp_path / "a", tmp_path / "b")
    assert out.returncode == 1
    failed = [line.strip() for line in out.stdout.splitlines() if line.strip().startswith("FAIL")]
    assert failed == ["FAIL 0 collisions",
                      "FAIL throughput not lower (paired t, one-sided p >= 0.05)",
                      "FAIL robots without a task not more"], out.stdout


def test_a_directory_without_records_is_one_line_and_exit_2(tmp_path):
    out = _run(tmp_path, tmp_path)
    assert out.returncode == 2
    assert out.stderr.strip() == f"behaviour_check: {tmp_path}: no records/ directory"
