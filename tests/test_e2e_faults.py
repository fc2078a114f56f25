"""End-to-end tests of ``swarm-up --faults`` (issue 11, item 2), run as a user runs them.

One 4-robot run with commanders, 120 simulated s, carries every kind of fault: a navigator
killed (restarted 2 s later), a robot killed, a robot frozen, a robot's scans and commands
thinned out, and a coordinator kill (in decentralized mode there is none: the fault is announced,
acknowledged, and nothing else happens). Checked:

1. every fault takes effect at its simulated time (the simulator's log and the metrics);
2. killing a robot leaves the others' tasks going; the killed robot completes nothing after;
3. the killed navigator is restarted and its robot reaches goals again;
4. the same command gives the same simulated figures, and so does the same run with its robots
   in group processes (where a navigator is killed in-process);
5. a bad spec exits 2 with one line naming ``--faults``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.test_e2e_swarm_up import SWARM_UP, _diff, _run_to_end, _simulated

pytestmark = pytest.mark.e2e

SPEC = ("kill-nav:2@10,kill-robot:1@20,freeze:3@30+10,drop:4/scan:0.5@30+10,"
        "drop:4/cmd_vel:0.3@45+5,kill-coordinator@50+5")
ARGS = ["--swarm-size", "4", "--commanders", "--rtf", "0", "--duration", "120",
        "--faults", SPEC, "--processes", "per-robot"]  # a killed navigator is its own process
EXPECTED_LOG = [
    (1, "kill-nav", "start", "Srobot2", 10.0),
    (1, "kill-nav", "end", "Srobot2", 12.0),
    (2, "kill-robot", "start", "Srobot1", 20.0),
    (3, "freeze", "start", "Srobot3", 30.0),
    (4, "drop", "start", "Srobot4", 30.0),
    (3, "freeze", "end", "Srobot3", 40.0),
    (4, "drop", "end", "Srobot4", 40.0),
    (5, "drop", "start", "Srobot4", 45.0),
    (5, "drop", "end", "Srobot4", 50.0),
    (6, "kill-coordinator", "start", None, 50.0),
    (6, "kill-coordinator", "end", None, 55.0),
]
LAYOUT_KEYS = ("processes", "restarts")  # differ between per-robot and group processes


@pytest.fixture(scope="module")
def fault_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("faults")
    _, metrics, diag = _run_to_end(ARGS, tmp, "first", 120)
    return metrics, diag, tmp / "first"


def _msg(m, diag):
    return f"metrics: {json.dumps(m, indent=1)}\n{diag}"


def test_each_fault_takes_effect_at_its_simulated_time(fault_run):
    m, diag, _ = fault_run
    msg = _msg(m, diag)
    log = [(e["fault"], e["kind"], e["phase"], e["robot"], e["t"]) for e in m["fault_log"]]
    assert log == EXPECTED_LOG, msg
    assert m["faults"] == 6, msg
    assert m["faults_by_kind"] == {"kill-nav": 1, "kill-robot": 1, "freeze": 1, "drop": 2,
                                   "kill-coordinator": 1}, msg
    # 50 lidar ticks in 10 s at 5 Hz, half lost; 50 control ticks in 5 s, 30 % lost: ~40.
    assert 25 <= m["fault_messages_dropped"] <= 60, msg
    assert m["late_ticks"] == 0 and m["goal_wait_timeouts"] == 0, msg
    assert m["reproducible"] is True, msg


def test_killing_a_robot_leaves_the_others_tasks_going(fault_run):
    m, diag, run_dir = fault_run
    msg = _msg(m, diag)
    per = m["per_robot"]
    assert all(t < 20.0 for t in per["Srobot1"]["task_times_s"]), msg
    for ns in ("Srobot2", "Srobot3", "Srobot4"):
        after = [t for t in per[ns]["task_times_s"] if t > 20.0]
        assert after, f"{ns} completed no task after Srobot1 died at 20 s\n{msg}"
    assert "robot Srobot1 dead at t = 20 s" in (run_dir.parent / "first.stdout").read_text()


def test_killed_navigator_is_restarted_and_reaches_goals_again(fault_run):
    m, diag, run_dir = fault_run
    msg = _msg(m, diag)
    assert m["restarts"] == 1, msg
    assert [t for t in m["per_robot"]["Srobot2"]["task_times_s"] if t > 12.0], msg
    log = (run_dir / "logs" / "nav_Srobot2.log").read_text(errors="replace")
    assert "--- swarm-up: restart 1 of nav_Srobot2" in log, msg
    assert "Traceback" not in log, msg


def test_fault_runs_are_reproducible_in_both_process_layouts(fault_run, tmp_path):
    first, diag1, _ = fault_run
    _, second, diag2 = _run_to_end(ARGS, tmp_path, "second", 120)
    grouped_args = ARGS[:ARGS.index("--processes")] + ["--processes", "2"]
    _, grouped, diag3 = _run_to_end(grouped_args, tmp_path, "grouped", 120)
    for other, diag in ((second, diag2), (grouped, diag3)):
        assert other["reproducible"] is True, diag
    a, b = _simulated(first), _simulated(second)
    assert a["tasks_completed"] > 0, diag1
    diffs = _diff(a, b)
    assert not diffs, "same run, different figures:\n  " + "\n  ".join(diffs) + f"\n{diag2}"
    g = _simulated(grouped)
    for key in LAYOUT_KEYS:
        a.pop(key), g.pop(key)
    diffs = _diff(a, g)
    assert not diffs, ("per-robot and group processes differ:\n  " + "\n  ".join(diffs)
                       + f"\n{diag3}")


BAD_SPECS = [
    ("kill-robot:9@60", "no robot '9'"),
    ("kill-robot:2", "is not KIND[:TARGET]@TIME[+DURATION]"),
    ("melt:2@60", "unknown fault kind 'melt'"),
    ("drop:2/scan:2@60", "the fraction must be in (0, 1]"),
    ("freeze:2@600", "starts at or after the end of the run"),
    ("missing.yaml", "missing.yaml"),
]


@pytest.mark.parametrize(("spec", "words"), BAD_SPECS, ids=[s for s, _ in BAD_SPECS])
def test_bad_fault_specs_exit_2_with_one_line(spec, words, tmp_path):
    argv = [str(SWARM_UP), "--swarm-size", "3", "--duration", "300", "--faults", spec,
            "--run-dir", str(tmp_path / "run")]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("swarm-up: error: --faults: ") and words in lines[0], lines[0]
    assert not (tmp_path / "run").exists()  # nothing started


def test_swarm_sim_rejects_a_bad_spec_with_one_line(tmp_path):
    sim = Path(sys.executable).parent / "swarm-sim"
    proc = subprocess.run([str(sim), "--swarm-size", "2", "--faults", "freeze:3@5"],
                          capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == ["swarm-sim: error: --faults: 'freeze:3@5': no robot '3' (robots are "
                     "numbers 1..2 or their namespaces Srobot1...)"], proc.stderr
