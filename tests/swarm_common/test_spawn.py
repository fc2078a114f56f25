"""Spawn placement (swarm_common.spawn): exactly N poses on the grid, clear of walls, or an
error that says how many fit."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from swarm_common.errors import InputError
from swarm_common.occupancy import OccupancyMap
from swarm_common.poi import SpawnArea, poi_for_world
from swarm_common.robot_model import load_robot
from swarm_common.spawn import spawn_poses, spawn_poses_free
from swarm_common.world import load_world, world_polygons

# shared/reference/seed_facts.md, slim_blockage's wall table as boxes xmin, xmax, ymin, ymax [m]
# (the same table as tests/swarm_sim/test_lidar.py)
SLIM_WALLS = np.array([
    [-8.475, 9.525, -4.974, -4.824],
    [-8.475, 9.525, 9.376, 9.526],
    [-8.475, -8.325, -4.974, 9.526],
    [9.375, 9.525, -4.974, 9.526],
    [-5.262, -5.112, -3.016, 7.484],
    [-3.912, -3.762, -3.016, 7.484],
    [-5.262, -3.762, -3.016, -2.866],
    [-5.262, -3.762, 7.334, 7.484],
    [3.909, 4.059, -4.912, -1.412],
    [3.909, 9.409, -1.562, -1.412],
])


def box_clearance(xy, boxes) -> float:
    """Distance [m] from a point to the nearest of some axis-aligned boxes."""
    dx = np.maximum(np.maximum(boxes[:, 0] - xy[0], xy[0] - boxes[:, 1]), 0.0)
    dy = np.maximum(np.maximum(boxes[:, 2] - xy[1], xy[1] - boxes[:, 3]), 0.0)
    return float(np.hypot(dx, dy).min())


@pytest.fixture(scope="module")
def slim():
    return load_world("slim_blockage")


@pytest.fixture(scope="module")
def waffle():
    return load_robot("turtlebot3_waffle")


@pytest.mark.parametrize("n, first", [
    (1, [(0, 0)]),
    (5, [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0)]),
    (11, [(i, 0) for i in range(10)] + [(-1, 0)]),
    (13, [(i, 0) for i in range(10)] + [(-1, 0), (-2, 0), (0, 1)]),
    (100, [(i, 0) for i in range(10)] + [(-1, 0), (-2, 0)] + [(i, 1) for i in range(10)]),
])
def test_spawn_gives_exactly_n_free_poses(slim, waffle, n, first):
    spawn = poi_for_world(slim.source).spawn
    poses = spawn_poses(spawn, n, waffle.radius, world_polygons(slim))
    assert poses.shape == (n, 3)
    np.testing.assert_array_equal(poses[:len(first), :2], np.array(first, dtype=float))
    np.testing.assert_array_equal(poses[:, 2], np.full(n, 3.14159265))
    # On the 1 m grid, inside the area, each robot once, clear of every wall.
    np.testing.assert_array_equal(poses[:, :2], np.rint(poses[:, :2]))
    assert len({tuple(p) for p in poses[:, :2]}) == n
    assert np.all((poses[:, 0] >= -2.0) & (poses[:, 0] <= 9.0))
    assert np.all((poses[:, 1] >= -1.0) & (poses[:, 1] <= 8.0))
    clearance = [box_clearance(p, SLIM_WALLS) for p in poses[:, :2]]
    assert min(clearance) >= waffle.radius + 0.05
    if n > 1:
        gaps = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=2)
        assert gaps[np.triu_indices(n, 1)].min() == pytest.approx(1.0)


def test_spawn_the_whole_grid_and_no_more(slim, waffle):
    spawn = poi_for_world(slim.source).spawn
    polygons = world_polygons(slim)
    assert spawn_poses(spawn, 120, waffle.radius, polygons).shape == (120, 3)
    with pytest.raises(InputError) as err:
        spawn_poses(spawn, 121, waffle.radius, polygons)
    assert str(err.value) == (
        "--swarm-size: 121 robots do not fit in the spawn area; at most 120 fit")


@pytest.mark.parametrize("clearance, xs", [
    (0.05, [8.1, 7.1, 6.1, 5.1]),
    (0.0, [9.1, 8.1, 7.1, 6.1, 5.1]),
])
def test_spawn_keeps_clear_of_walls(slim, waffle, clearance, xs):
    # A row x = 9.1, 8.1, ... 5.1 at y = 3 starting at x = 9.1, which is 0.275 m from the right
    # wall's face: more than the waffle's radius 0.238 m, less than radius + 0.05 m.
    row = SpawnArea(origin=np.array([9.1, 3.0]), spacing=1.0, yaw=0.0,
                    area=np.array([5.1, 3.0, 9.1, 3.0]))
    polygons = world_polygons(slim)
    poses = spawn_poses(row, len(xs), waffle.radius, polygons, clearance=clearance)
    np.testing.assert_allclose(poses, [(x, 3.0, 0.0) for x in xs], atol=1e-12)
    with pytest.raises(InputError, match=f"at most {len(xs)} fit"):
        spawn_poses(row, len(xs) + 1, waffle.radius, polygons, clearance=clearance)


def test_spawn_rejects_a_grid_finer_than_the_robot(slim):
    spawn = poi_for_world(slim.source).spawn
    big = 0.6  # [m] radius: 2 * 0.6 + 0.05 > 1 m spacing
    with pytest.raises(InputError, match="spacing 1 m is too small"):
        spawn_poses(spawn, 1, big, world_polygons(slim))


def test_free_area_spawn_keeps_to_the_region_of_the_clearest_cell(waffle):
    # A 10 x 10 m map at 0.1 m/cell: free left room (x < 4 m) and a closed free pocket on the
    # right (x > 6 m, 4 m wide) behind a wall; the clearest cell is in the left room's middle.
    data = np.full((100, 100), 100, dtype=np.int8)
    data[1:99, 1:40] = 0      # left room, 3.9 x 9.8 m
    data[40:60, 70:90] = 0    # right pocket, 2 x 2 m
    occ = OccupancyMap(data=data, resolution=0.1, origin=np.array([0.0, 0.0, 0.0]))
    poses = spawn_poses_free(occ, 6, waffle.radius, [])
    assert poses.shape == (6, 3)
    assert np.all(poses[:, 0] < 4.0) and np.all(poses[:, 2] == 0.0)
    gaps = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=2)
    assert gaps[np.triu_indices(6, 1)].min() == pytest.approx(1.0)


def test_spawn_module_is_pure():
    """swarm-up checks --swarm-size with this module: it must not pull in the simulator."""
    import swarm_common.spawn as mod

    tree = ast.parse(Path(mod.__file__).read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
    assert not {m for m in imported if m.startswith(("pybullet", "swarm_sim", "rclpy"))}
