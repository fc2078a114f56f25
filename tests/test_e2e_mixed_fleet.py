"""End-to-end: a mixed fleet as a user runs it (``swarm-up --robot NAME:COUNT,...``).

Six robots of the three bundled models (two each, interleaved) with commanders on slim_blockage
for 120 simulated s at ``--rtf 0``, in two group processes: no collision, no aborted goal, every
robot reaches a workstation, and every robot's navigator params file names its own model, radius
and speed limit (tests/test_e2e_swarm_up.py has the harness).
"""

from __future__ import annotations

import json

import pytest
import yaml

from swarm_scene.robot_model import load_robot
from tests.test_e2e_swarm_up import EXIT_SLACK_S, READY_TIMEOUT_S, SwarmUp

pytestmark = pytest.mark.e2e

MIX = "turtlebot3_waffle:2,turtlebot3_burger:2,linorobot2_2wd:2"
MODELS = ["turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd"] * 2  # interleaved
DURATION_S = 120


def test_six_robots_of_three_models_run_clean(tmp_path):
    args = ["--robot", MIX, "--commanders", "--rtf", "0", "--duration", str(DURATION_S),
            "--processes", "2"]
    with SwarmUp(args, tmp_path, "mixed") as run:
        code = run.wait(READY_TIMEOUT_S + DURATION_S + EXIT_SLACK_S)
        diag = run.diagnostics()
        assert code == 0, f"swarm-up exited with {code}\n{diag}"
        metrics, out = run.metrics(), run.stdout()
    msg = f"metrics: {json.dumps(metrics, indent=1)}\n{out}\n{diag}"
    assert metrics["robots"] == 6 and metrics["sim_time_s"] == DURATION_S, msg
    assert metrics["fleet"] == {"turtlebot3_waffle": 2, "turtlebot3_burger": 2,
                                "linorobot2_2wd": 2}, msg
    assert ("swarm-up: 6 robots (2 turtlebot3_waffle, 2 turtlebot3_burger, 2 linorobot2_2wd) "
            "in slim_blockage") in out, msg
    assert metrics["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
    assert metrics["goals_aborted"] == 0, msg
    per_robot = metrics["per_robot"]
    assert [per_robot[f"Srobot{i}"]["robot"] for i in range(1, 7)] == MODELS, msg
    assert all(r["goals_reached"] >= 1 for r in per_robot.values()), msg
    assert metrics["late_ticks"] == 0, msg
    for i, name in enumerate(MODELS, start=1):
        ns = f"Srobot{i}"
        params = yaml.safe_load((tmp_path / "mixed" / "params" / f"{ns}.yaml").read_text())
        params = params[f"/{ns}/navigator"]["ros__parameters"]
        model = load_robot(name)
        assert params["robot"] == name, msg
        assert params["robot_radius"] == model.costmap_radius, msg
        assert params["max_vel_x"] <= model.limits.max_vel_x, msg
