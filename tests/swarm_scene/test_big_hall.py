"""The bundled big_hall world (tools/make_big_hall.py): its files are the generator's, its map
the rasteriser's, and it holds 1,025 robots of the default model with every workstation reachable
and clear of the spawn grid."""

from __future__ import annotations

import importlib.util

import numpy as np

from swarm_common.paths import MAPS_DIR, ROOT, WORLDS_DIR
from swarm_scene.map_io import load_map
from swarm_scene.poi import load_poi
from swarm_scene.rasterize import rasterize_world
from swarm_scene.robot_model import load_robot
from swarm_scene.spawn import spawn_poses
from swarm_scene.world import load_world, world_polygons


def _generator():
    spec = importlib.util.spec_from_file_location("make_big_hall",
                                                  ROOT / "tools" / "make_big_hall.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_files_are_the_generators_and_the_map_the_rasterisers():
    gen = _generator()
    assert (WORLDS_DIR / "big_hall.world").read_text() == gen.world_text()
    assert (WORLDS_DIR / "big_hall.yaml").read_text() == gen.poi_text()
    bundled = load_map(MAPS_DIR / "big_hall.yaml")
    fresh = rasterize_world(load_world(WORLDS_DIR / "big_hall.world"), resolution=0.1)
    assert bundled.resolution == 0.1
    assert np.array_equal(bundled.origin[:2], fresh.origin[:2])
    assert np.array_equal(bundled.data == 100, fresh.data == 100)


def test_it_holds_1025_robots_of_the_default_model_and_24_workstations_of_two_kinds():
    poi = load_poi(WORLDS_DIR / "big_hall.yaml")
    names = [w.name for w in poi.workstations]
    assert len(names) == 24
    assert sum(n.startswith("loader") for n in names) == 12
    assert sum(n.startswith("unloader") for n in names) == 12
    robot = load_robot("turtlebot3_waffle")
    polygons = world_polygons(load_world(WORLDS_DIR / "big_hall.world"))
    poses = spawn_poses(poi.spawn, 1025, robot.radius, polygons)
    assert len(poses) == 1025
    occ = load_map(MAPS_DIR / "big_hall.yaml")
    for w in poi.workstations:  # docks and holding spots in free space, far from the grid
        for xy in [np.asarray(w.pose[:2]), *(np.asarray(h[:2]) for h in w.holding)]:
            r, c = occ.world_to_cell(xy[None, :])[0]
            k = int(np.ceil(robot.radius / occ.resolution))
            assert (occ.data[r - k:r + k + 1, c - k:c + k + 1] == 0).all(), (w.name, xy)
            assert np.min(np.hypot(*(poses[:, :2] - xy).T)) > 10.0
