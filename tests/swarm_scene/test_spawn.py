"""Spawn placement (swarm_scene.spawn): exactly N poses on the grid, clear of walls, or an
error that says how many fit."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from swarm_common.errors import InputError
from swarm_common.paths import MAPS_DIR
from swarm_scene.map_io import load_map
from swarm_scene.occupancy import OccupancyMap
from swarm_scene.poi import SpawnArea, poi_for_world
from swarm_scene.rasterize import rasterize_world
from swarm_scene.robot_model import load_robot
from swarm_scene.spawn import (
    choose_free_region,
    describe_spawn,
    spawn_poses,
    spawn_poses_free,
)
from swarm_scene.world import load_world, world_polygons

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
    import swarm_scene.spawn as mod

    tree = ast.parse(Path(mod.__file__).read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
    assert not {m for m in imported if m.startswith(("pybullet", "swarm_sim", "rclpy"))}


# ----------------------------------------------------------------- the largest free region


def test_choose_free_region_beats_a_clearer_but_smaller_room(waffle):
    # Left: a 2.5 x 8 m corridor-like room (20 m^2); right: a 4 x 4 m room (16 m^2) whose
    # centre is clearer (2 m vs 1.25 m). The larger region wins, at its own clearest cell.
    data = np.full((100, 100), 100, dtype=np.int8)
    data[10:90, 5:30] = 0     # 8 x 2.5 m
    data[30:70, 50:90] = 0    # 4 x 4 m
    occ = OccupancyMap(data=data, resolution=0.1, origin=np.array([0.0, 0.0, 0.0]))
    region = choose_free_region(occ)
    assert region.area == pytest.approx(20.0)
    assert region.origin[0] == pytest.approx(1.75, abs=0.051)  # the corridor's middle x
    assert region.clearance == pytest.approx(1.3, abs=0.051)
    poses = spawn_poses_free(occ, 4, waffle.radius, [])
    assert np.all(poses[:, 0] < 3.0)


def test_open_map_spawns_in_the_middle_not_at_a_corner(waffle):
    # No walls at all: the map's edge counts as outside, so the clearest cell is the centre.
    data = np.zeros((81, 81), dtype=np.int8)
    data[75, 75] = 100  # one post near a corner, at (3.55, 3.55)
    occ = OccupancyMap(data=data, resolution=0.1, origin=np.array([-4.0, -4.0, 0.0]))
    region = choose_free_region(occ)
    assert region.origin == pytest.approx([0.05, 0.05], abs=1e-9)
    assert region.clearance == pytest.approx(4.1, abs=1e-9)  # to the pad beyond the map edge
    poses = spawn_poses_free(occ, 9, waffle.radius, [])
    assert poses[0, :2] == pytest.approx(region.origin)
    # the row through the centre first: x = 0.05 + (0, 1, 2, 3, -1, -2, -3); x = +-3.95 would
    # put the robot (radius 0.22 m + 0.05 m) over the map's edge; then the next row up
    np.testing.assert_allclose(poses[:7, 0], [0.05, 1.05, 2.05, 3.05, -0.95, -1.95, -2.95])
    np.testing.assert_allclose(poses[7:, 1], 1.05)


def test_a_map_without_free_cells_is_an_input_error():
    occ = OccupancyMap(data=np.full((5, 5), 100, dtype=np.int8), resolution=0.1,
                       origin=np.zeros(3))
    with pytest.raises(InputError, match="no free cell"):
        choose_free_region(occ)


def test_an_enclosed_room_wins_over_a_larger_outside(waffle):
    # a 3 x 3 m room (9 m^2) walled all round, in a 10 x 10 m map: the 60 m^2 outside it
    # touches the map's edge, so the robots start in the room
    data = np.zeros((100, 100), dtype=np.int8)
    data[30:70, 30:70] = 100
    data[35:65, 35:65] = 0
    occ = OccupancyMap(data=data, resolution=0.1, origin=np.array([0.0, 0.0, 0.0]))
    region = choose_free_region(occ)
    assert region.enclosed
    assert region.area == pytest.approx(9.0)
    assert region.open_area == pytest.approx(100.0 - 16.0)
    assert region.describe() == ("the largest enclosed free region (9 m^2; 84 m^2 of free "
                                 "space touch the map's edge)")
    assert region.describe("why").endswith("touch the map's edge; why)")
    poses = spawn_poses_free(occ, 4, waffle.radius, [])
    assert np.all((poses[:, :2] > 3.5) & (poses[:, :2] < 6.5))
    with pytest.raises(InputError, match="at most 9 fit"):  # a 3 x 3 grid: the room, not
        spawn_poses_free(occ, 10, waffle.radius, [])    # the outside


def _walled_world(tmp_path: Path) -> Path:
    """A 4 x 4 m room of four box walls, and a post 12 m away that widens the map: the free
    space outside the room is larger than the room."""
    boxes = [(0.0, 2.0, 4.2, 0.2), (0.0, -2.0, 4.2, 0.2), (2.0, 0.0, 0.2, 4.2),
             (-2.0, 0.0, 0.2, 4.2), (12.0, 0.0, 0.5, 0.5)]
    models = "".join(
        f"<model name='b{k}'><static>true</static><pose>{x} {y} 0.5 0 0 0</pose><link name='l'>"
        f"<collision name='c'><geometry><box><size>{sx} {sy} 1</size></box></geometry>"
        "</collision></link></model>" for k, (x, y, sx, sy) in enumerate(boxes))
    path = tmp_path / "room.world"
    path.write_text(f'<?xml version="1.0"?><sdf version="1.6"><world name="room">{models}'
                    "</world></sdf>")
    return path


def test_a_walled_world_spawns_inside_its_walls_though_the_outside_is_larger(tmp_path, waffle):
    world = load_world(_walled_world(tmp_path))
    occ = rasterize_world(world)
    region = choose_free_region(occ)
    assert region.enclosed and region.open_area > 2 * region.area
    assert 12.0 < region.area < 16.0
    poses = spawn_poses_free(occ, 4, waffle.radius, world_polygons(world))
    assert np.all(np.abs(poses[:, :2]) < 1.9)
    text = describe_spawn(poses, False, None, region)
    assert text.startswith("in the largest enclosed free region (")
    assert "touch the map's edge; no points-of-interest file), x " in text


@pytest.mark.parametrize("name", ["warehouse_slab", "narrow_aisles", "slim_blockage"])
def test_world_without_poi_spawns_20_in_its_choose_free_region(tmp_path, waffle, name):
    """The world file alone (no .yaml beside it): 20 robots in the hall, clear of everything."""
    world = load_world(name)
    occ = load_map(MAPS_DIR / f"{name}.yaml")
    polygons = world_polygons(world)
    poses = spawn_poses_free(occ, 20, waffle.radius, polygons)
    assert poses.shape == (20, 3)
    region = choose_free_region(occ)
    rc = occ.world_to_cell(poses[:, :2])
    assert region.mask[rc[:, 0], rc[:, 1]].all()  # inside the hall, not the padding ring
    gaps = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=2)
    assert gaps[np.triu_indices(20, 1)].min() >= 1.0 - 1e-9
    assert np.linalg.norm(poses[:, :2] - region.origin, axis=1).min() == pytest.approx(0.0)


# ------------------------------------------------------------------------- the new worlds


@pytest.mark.parametrize(("name", "fit"), [("warehouse_slab", 36), ("narrow_aisles", 39)])
def test_new_worlds_spawn_20_robots_on_their_grid(waffle, name, fit):
    world = load_world(name)
    spawn = poi_for_world(world.source).spawn
    polygons = world_polygons(world)
    poses = spawn_poses(spawn, 20, waffle.radius, polygons)
    assert poses.shape == (20, 3)
    assert poses[0, :2] == pytest.approx(spawn.origin)
    assert np.all(poses[:, 2] == spawn.yaw)
    gaps = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=2)
    assert gaps[np.triu_indices(20, 1)].min() == pytest.approx(1.0)
    spawn_poses(spawn, fit, waffle.radius, polygons)  # every node fits ...
    with pytest.raises(InputError, match=f"at most {fit} fit"):
        spawn_poses(spawn, fit + 1, waffle.radius, polygons)  # ... and no more


@pytest.mark.parametrize(("from_spawn_area", "poi_file", "rule"), [
    (True, "slim_blockage.yaml", "in the spawn area of slim_blockage.yaml"),
    (False, "hall.yaml", "in the largest free area (hall.yaml has no spawn area)"),
    (False, None, "in the largest free area (no points-of-interest file)"),
])
def test_describe_spawn_names_the_rule_and_the_block(from_spawn_area, poi_file, rule):
    poses = np.array([[3.05, -2.95, 0.0], [4.05, -2.95, 0.0], [6.05, -0.95, 0.0]])
    assert describe_spawn(poses, from_spawn_area, poi_file) == (
        f"{rule}, x 3.05..6.05 m, y -2.95..-0.95 m, first at (3.05, -2.95)")
