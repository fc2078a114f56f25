"""The costmap: nav2's static and inflation layers, numbers against nav2's formula."""

import math

import numpy as np
import pytest

from swarm_nav.config import CostmapConfig
from swarm_nav.costmap import (
    INSCRIBED,
    LETHAL,
    UNKNOWN,
    build_costmap,
    inflation_cost,
    overlay_obstacles,
    segment_max_cost,
)
from tests.swarm_nav.helpers import grid_map, random_grid, slim_blockage_map


def nav2_compute_cost(distance_cells: float, resolution: float, cfg: CostmapConfig) -> int:
    """nav2_costmap_2d InflationLayer::computeCost, transcribed (cells -> cost)."""
    if distance_cells == 0:
        return 254
    if distance_cells * resolution <= cfg.robot_radius:
        return 253
    euclidean = distance_cells * resolution
    factor = math.exp(-1.0 * cfg.cost_scaling_factor * (euclidean - cfg.robot_radius))
    return int((253 - 1) * factor)


@pytest.mark.parametrize("res", [0.05, 0.1])
@pytest.mark.parametrize("cfg", [
    CostmapConfig(),
    CostmapConfig(robot_radius=0.1, inflation_radius=1.0, cost_scaling_factor=10.0),
    CostmapConfig(robot_radius=0.3, inflation_radius=0.3),
])
def test_inflation_matches_nav2_formula(res, cfg):
    n = 41
    data = np.zeros((n, n), dtype=np.int8)
    data[20, 20] = 100
    cm = build_costmap(grid_map(data, res), cfg)
    assert cm.costs.dtype == np.uint8 and cm.costs.shape == (n, n)
    for r in range(n):
        for c in range(n):
            d = math.hypot(r - 20, c - 20)
            cell_inflation_radius = math.ceil(cfg.inflation_radius / res)  # nav2 cellDistance
            want = nav2_compute_cost(d, res, cfg) if d <= cell_inflation_radius else 0
            assert cm.costs[r, c] == want, (r, c, d * res)


def test_inflation_cost_values():
    cfg = CostmapConfig()
    d = np.array([0.0, 0.1, 0.22, 0.3, 0.55, 0.56])
    want = [254, 253, 253, int(252 * math.exp(-3.0 * 0.08)), int(252 * math.exp(-3.0 * 0.33)), 0]
    assert inflation_cost(d, cfg).tolist() == want


def test_cost_is_max_over_obstacles():
    """Two obstacles: each cell's cost is that of the nearer (nav2 keeps the maximum)."""
    data = np.zeros((30, 30), dtype=np.int8)
    data[10, 10] = data[12, 17] = 100
    cfg = CostmapConfig()
    cm = build_costmap(grid_map(data, 0.05), cfg)
    rr, cc = np.mgrid[0:30, 0:30]
    d = np.minimum(np.hypot(rr - 10, cc - 10), np.hypot(rr - 12, cc - 17)) * 0.05
    assert np.array_equal(cm.costs, inflation_cost(d, cfg, 0.05))
    assert np.allclose(cm.obstacle_distance, d)


def test_unknown_cells():
    data = np.zeros((20, 20), dtype=np.int8)
    data[:, 15:] = -1
    data[5, 2] = 100
    tracked = build_costmap(grid_map(data, 0.05), CostmapConfig(track_unknown_space=True))
    assert np.all(tracked.costs[:, 15:] == UNKNOWN)
    assert not tracked.traversable(False)[:, 15:].any()
    assert tracked.traversable(True)[:, 15:].all()
    free = build_costmap(grid_map(data, 0.05), CostmapConfig(track_unknown_space=False))
    assert np.all(free.costs[:, 15:] == 0)


def test_lethal_threshold_and_scale_values():
    data = np.zeros((10, 10), dtype=np.int8)
    data[2, 2] = 99
    data[7, 7] = 100
    cm = build_costmap(grid_map(data, 0.05), CostmapConfig(lethal_cost_threshold=100))
    assert cm.costs[7, 7] == LETHAL and cm.costs[2, 2] != LETHAL
    cm = build_costmap(grid_map(data, 0.05), CostmapConfig(lethal_cost_threshold=65))
    assert cm.costs[2, 2] == LETHAL


def test_layout_and_coordinates_follow_the_occupancy_map():
    occ = slim_blockage_map()
    cm = build_costmap(occ, CostmapConfig())
    assert cm.costs.shape == occ.data.shape
    assert cm.resolution == occ.resolution and np.allclose(cm.origin, occ.origin)
    # a point on the bottom wall (row 0 is at the bottom) is lethal; the room centre is free
    assert cm.cost_at([0.0, -4.9]) == LETHAL
    assert cm.cost_at([0.0, 2.0]) == 0
    assert cm.cost_at([0.0, -4.824 + 0.1]) == INSCRIBED
    assert cm.cost_at([100.0, 0.0]) == LETHAL  # outside the map


@pytest.mark.parametrize("seed", range(5))
def test_overlay_equals_building_with_the_points(seed):
    rng = np.random.default_rng(seed)
    occ = random_grid(rng, 60, 70, 0.02)
    cfg = CostmapConfig(robot_radius=0.2, inflation_radius=0.5)
    base = build_costmap(occ, cfg)
    pts = rng.uniform([0.0, 0.0], [7.0, 6.0], size=(25, 2))
    over = overlay_obstacles(base, pts, cfg)
    data = occ.data.copy()
    rc = base.world_to_cell(pts)
    data[rc[:, 0], rc[:, 1]] = 100
    want = build_costmap(grid_map(data, occ.resolution), cfg)
    assert np.array_equal(over.costs, want.costs)
    assert np.array_equal(base.costs, build_costmap(occ, cfg).costs)  # base untouched


def test_overlay_ignores_points_outside_the_map():
    cm = build_costmap(grid_map(np.zeros((10, 10)), 0.1), CostmapConfig())
    assert overlay_obstacles(cm, [[-5.0, -5.0]], CostmapConfig()) is cm


def test_boundary_points_are_lethal_cells_next_to_free_space():
    occ = slim_blockage_map()
    cm = build_costmap(occ, CostmapConfig())
    pts = cm.boundary_points()
    assert len(pts) > 1000
    assert np.all(cm.cost_at(pts) == LETHAL)
    rc = cm.world_to_cell(pts)
    lethal = np.pad(cm.costs == LETHAL, 1, constant_values=True)
    nb = np.zeros(len(rc), dtype=bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            nb |= ~lethal[rc[:, 0] + 1 + dr, rc[:, 1] + 1 + dc]
    assert nb.all()


def test_segment_max_cost():
    data = np.zeros((20, 20), dtype=np.int8)
    data[10, 10] = 100
    cm = build_costmap(grid_map(data, 0.1), CostmapConfig(robot_radius=0.1, inflation_radius=0.3))
    assert segment_max_cost(cm, [0.05, 1.05], [1.95, 1.05]) == LETHAL
    assert segment_max_cost(cm, [0.05, 0.05], [1.95, 0.05]) == 0
    assert segment_max_cost(cm, [0.05, 0.05], [5.0, 0.05]) == LETHAL  # leaves the map


@pytest.mark.parametrize("seed", range(3))
def test_lookups_equal_a_cell_by_cell_reading(seed):
    """cost_at / distance_at against reading each point's cell by hand (inside and outside)."""
    rng = np.random.default_rng(seed)
    cm = build_costmap(random_grid(rng, 40, 50, 0.05), CostmapConfig(robot_radius=0.2))
    for shape in ((), (7,), (3, 4)):
        for spread in (1.0, 3.0):  # all inside, or some outside the map
            xy = rng.uniform(-spread + 1.0, spread + 1.5, size=(*shape, 2))
            cost, dist = cm.cost_at(xy), cm.distance_at(xy)
            assert cost.shape == shape and cost.dtype == np.uint8
            assert dist.shape == shape and dist.dtype == np.float64
            for idx in np.ndindex(*shape):
                col = math.floor((xy[idx][0] - cm.origin[0]) / cm.resolution)
                row = math.floor((xy[idx][1] - cm.origin[1]) / cm.resolution)
                inside = 0 <= row < cm.height and 0 <= col < cm.width
                assert cost[idx] == (cm.costs[row, col] if inside else LETHAL)
                assert dist[idx] == (float(cm.obstacle_distance[row, col]) if inside else 0.0)
