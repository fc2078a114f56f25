"""End-to-end: worlds built of Collada meshes as the ROS world publishes them (issue 41), run by
``swarm-up`` as a user runs them: 10 robots, 120 simulated s, commanders, no collision.

- an arena like ROBOTIS' ``turtlebot3_world``: one hexagonal wall band (a single non-convex
  Collada mesh, in centimetres, declaring Y_UP over z-up data as SketchUp exports do) and
  nine pillars (one Collada file of nine parts), the
  files found through ``model://`` on ``GAZEBO_MODEL_PATH``;
- a warehouse like AWS RoboMaker's small warehouse: outer walls and two rows of shelving, each a
  ``.DAE`` (upper case) found through ``package://`` on ``AMENT_PREFIX_PATH``.

Each world's map must enclose its robots (no free path from the spawn area out of the walls),
and the run must end with tasks done and 0 collisions.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tests.swarm_scene.test_collada import box, collada, enclosed, hexagon_band
from tests.test_e2e_swarm_up import _run_to_end

pytestmark = pytest.mark.e2e

DURATION = 120


def _prism(cx: float, cy: float, r: float, h: float, sides: int = 8):
    ang = 2 * math.pi * (np.arange(sides) + 0.5) / sides
    ring = np.column_stack((cx + r * np.cos(ang), cy + r * np.sin(ang)))
    v = np.vstack([np.column_stack((ring, np.zeros(sides))),
                   np.column_stack((ring, np.full(sides, h)))])
    f = []
    for i in range(sides):
        j = (i + 1) % sides
        f += [(i, j, sides + j), (i, sides + j, sides + i)]
    f += [(0, k + 1, k) for k in range(1, sides - 1)]
    f += [(sides, sides + k, sides + k + 1) for k in range(1, sides - 1)]
    return v, f


def _to_cm(v: np.ndarray) -> np.ndarray:
    """z-up metres -> centimetres, still z up: the file declares Y_UP over it, as ROBOTIS's
    SketchUp exports do, and the loader ignores the declaration as Gazebo does."""
    return v * 100.0


def _arena(tmp: Path) -> Path:
    models = tmp / "models"
    for name in ("tb3_wall", "tb3_pillars"):
        (models / name / "meshes").mkdir(parents=True)
    v, f = hexagon_band(radius=5.0, thick=0.2, height=0.5)
    (models / "tb3_wall" / "meshes" / "wall.dae").write_text(
        collada([(_to_cm(v), f)], unit=0.01, up="Y_UP"))
    pillars = [_prism(x, y, 0.15, 0.5) for x in (-1.1, 0.0, 1.1) for y in (-1.1, 0.0, 1.1)]
    (models / "tb3_pillars" / "meshes" / "hexagon.dae").write_text(collada(pillars))
    meshes = "".join(
        f"<model name='{name}'><static>true</static><link name='l'><collision name='c'>"
        f"<geometry><mesh><uri>model://{name}/meshes/{file}</uri></mesh></geometry>"
        "</collision></link></model>"
        for name, file in (("tb3_wall", "wall.dae"), ("tb3_pillars", "hexagon.dae")))
    world = tmp / "tb3_like.world"
    world.write_text(f'<?xml version="1.0"?><sdf version="1.6"><world name="tb3_like">'
                     f"{meshes}</world></sdf>")
    (tmp / "tb3_like.yaml").write_text(
        "workstations:\n"
        "  - {name: station1, x: -3.2, y: 0.0, yaw: 3.14159}\n"
        "  - {name: station2, x: -1.6, y: 2.8, yaw: 2.0}\n"
        "  - {name: station3, x: -1.6, y: -2.8, yaw: -2.0}\n"
        "  - {name: station4, x: 0.0, y: 3.6, yaw: 1.5708}\n"
        "spawn: {origin: [1.8, -2.0], spacing: 1.0, yaw: 3.14159, area: [1.8, -2.0, 2.8, 2.0]}\n")
    return world


def _warehouse(tmp: Path) -> Path:
    share = tmp / "install" / "share"
    (share / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (share / "ament_index" / "resource_index" / "packages" / "wh_models").write_text("")
    (share / "wh_models" / "meshes").mkdir(parents=True)
    # outer walls, 14 x 10 m, one piece (a rectangular band)
    outer = [box((-7.0, -5.0, 0.0), (7.0, -4.8, 2.5)), box((-7.0, 4.8, 0.0), (7.0, 5.0, 2.5)),
             box((-7.0, -4.8, 0.0), (-6.8, 4.8, 2.5)), box((6.8, -4.8, 0.0), (7.0, 4.8, 2.5))]
    (share / "wh_models" / "meshes" / "walls.DAE").write_text(collada(outer))
    units = [box((-5.0 + 1.6 * k, -0.4, 0.0), (-3.6 + 1.6 * k, 0.4, 2.2)) for k in range(4)]
    (share / "wh_models" / "meshes" / "shelves.DAE").write_text(collada(units))
    rows = "".join(
        f"<model name='shelves{i}'><static>true</static><pose>0 {y} 0 0 0 0</pose>"
        "<link name='l'><collision name='c'><geometry><mesh>"
        "<uri>package://wh_models/meshes/shelves.DAE</uri></mesh></geometry></collision>"
        "</link></model>" for i, y in enumerate((-2.0, 2.0)))
    walls = ("<model name='walls'><static>true</static><link name='l'><collision name='c'>"
             "<geometry><mesh><uri>package://wh_models/meshes/walls.DAE</uri></mesh>"
             "</geometry></collision></link></model>")
    world = tmp / "wh_like.world"
    world.write_text(f'<?xml version="1.0"?><sdf version="1.6"><world name="wh_like">'
                     f"{walls}{rows}</world></sdf>")
    (tmp / "wh_like.yaml").write_text(
        "workstations:\n"
        "  - {name: shelf1, x: -4.3, y: -3.0, yaw: 1.5708}\n"
        "  - {name: shelf2, x: -1.1, y: -3.0, yaw: 1.5708}\n"
        "  - {name: shelf3, x: -4.3, y: 3.0, yaw: -1.5708}\n"
        "  - {name: shelf4, x: -1.1, y: 3.0, yaw: -1.5708}\n"
        "  - {name: shelf5, x: -2.7, y: 0.0, yaw: 1.5708}\n"
        "spawn: {origin: [3.5, -2.0], spacing: 1.0, yaw: 3.14159, area: [3.5, -2.0, 4.5, 2.0]}\n")
    return world


@pytest.mark.parametrize("kind", ["turtlebot3_world_like", "warehouse_like"])
def test_ten_robots_run_a_collada_world_without_a_collision(kind, tmp_path, monkeypatch):
    from swarm_scene.rasterize import rasterize_world
    from swarm_scene.spawn import choose_free_region
    from swarm_scene.world import load_world

    if kind == "turtlebot3_world_like":
        monkeypatch.setenv("GAZEBO_MODEL_PATH", str(tmp_path / "models"))
        world, inside, outside = _arena(tmp_path), (2.3, 0.0), (6.0, 0.0)
    else:
        monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "install"))
        world, inside, outside = _warehouse(tmp_path), (4.0, 0.0), (7.6, 0.0)
    loaded = load_world(world)
    assert loaded.skipped == (), loaded.skipped
    occ = rasterize_world(loaded, resolution=0.05, padding=1.0)
    assert enclosed(occ, inside, outside), "the walls do not enclose the spawn area"
    # without its spawn area the robots would start in the arena too, not outside its wall
    region = choose_free_region(occ)
    cell = occ.world_to_cell(np.array([inside]))[0]
    assert region.enclosed and region.mask[cell[0], cell[1]], region.describe()
    args = ["--swarm-size", "10", "--world", str(world), "--commanders", "--rtf", "0",
            "--duration", str(DURATION)]
    _, m, diag = _run_to_end(args, tmp_path, kind, DURATION)
    msg = f"{ {k: m[k] for k in ('collisions', 'goals_reached', 'goals_aborted')} }\n{diag}"
    assert m["world_skipped"] == [], msg
    assert m["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
    assert m["goals_reached"] >= 5, msg
