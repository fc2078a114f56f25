"""End-to-end runs of the worlds written as people publish them (issue 9, item 4).

``swarm-up`` as a user runs it (the installed console script, see tests/test_e2e_swarm_up.py for
the harness) on the two bundled worlds in those styles, and on a world without points of
interest:

1. warehouse_slab (a floor slab, included and nested shelf models, ``relative_to`` poses) and
   narrow_aisles (a Gazebo-saved world, 2.4 m aisles): 10 robots with commanders, 90 simulated
   s at ``--rtf 0``: no collision (the slab is floor, not a wall), no aborted goal, goals reached.
2. warehouse_slab copied without its ``.yaml``: the robots spawn in its largest enclosed free
   region and
   the run ends cleanly with no collision; the simulator's log, the metrics (``spawn``) and the
   summary say where they went.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from swarm_common.paths import WORLDS_DIR
from tests.test_e2e_swarm_up import EXIT_SLACK_S, READY_TIMEOUT_S, SwarmUp

pytestmark = pytest.mark.e2e


def _run(args: list[str], tmp_path: Path, name: str, duration_s: float) -> tuple[dict, str]:
    with SwarmUp(args, tmp_path, name) as run:
        code = run.wait(READY_TIMEOUT_S + duration_s + EXIT_SLACK_S)
        diag = run.diagnostics()
        assert code == 0, f"swarm-up exited with {code}\n{diag}"
        return run.metrics(), f"{run.stdout()}\n{diag}"


@pytest.mark.parametrize("world", ["warehouse_slab", "narrow_aisles"])
def test_ten_robots_with_commanders_run_clean(world, tmp_path):
    metrics, diag = _run(["--world", world, "--swarm-size", "10", "--commanders", "--rtf", "0",
                          "--duration", "90"], tmp_path, world, 90)
    msg = f"metrics: {json.dumps(metrics, indent=1)}\n{diag}"
    assert metrics["world"] == world and metrics["robots"] == 10, msg
    assert metrics["sim_time_s"] == 90, msg
    assert metrics["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
    assert metrics["goals_aborted"] == 0, msg
    assert metrics["goals_reached"] >= 5, msg
    assert metrics["late_ticks"] == 0, msg
    assert "skipped" not in diag, msg  # the bundled worlds load whole


def test_world_without_points_of_interest_spawns_in_the_largest_free_region(tmp_path):
    hall = tmp_path / "hall"
    hall.mkdir()
    shutil.copy(WORLDS_DIR / "warehouse_slab.world", hall / "bare_slab.world")
    shutil.copytree(WORLDS_DIR / "models", hall / "models")  # model://warehouse_shelf
    metrics, diag = _run(["--world", str(hall / "bare_slab.world"), "--swarm-size", "4",
                          "--rtf", "0", "--duration", "20"], tmp_path, "bare", 20)
    msg = f"metrics: {json.dumps(metrics, indent=1)}\n{diag}"
    assert metrics["robots"] == 4 and metrics["sim_time_s"] == 20, msg
    assert metrics["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
    assert metrics["goals_aborted"] == 0, msg
    # the simulator says where they went: the hall is walled all round, so the largest enclosed
    # free region; its clearest point is in the open south-east of the hall, right of the
    # shelves (x > -1.4 m)
    sim_log = (tmp_path / "bare" / "logs" / "sim.log").read_text()
    (line,) = [ln for ln in sim_log.splitlines() if ln.startswith("spawned 4 robots")]
    assert "in the largest enclosed free region (" in line, msg
    x_lo = float(line.split(", x ")[1].split("..")[0])
    assert x_lo > -1.4, msg
    # ... and so do the metrics and the summary (the world loads whole: no skip row)
    assert metrics["spawn"].startswith(
        "in the largest enclosed free region ("), msg
    assert "touch the map's edge; no points-of-interest file), x " in metrics["spawn"], msg
    assert line.endswith(") " + metrics["spawn"]), msg
    assert metrics["world_skipped"] == [], msg
    assert "│ spawned " in diag and "world elements skipped" not in diag, msg
