"""swarm_scene.rasterize: the map rasterised from a world reproduces the world."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

from swarm_common.errors import InputError
from swarm_common.paths import MAPS_DIR
from swarm_scene.map_io import load_map
from swarm_scene.occupancy import FREE, OCCUPIED
from swarm_scene.poi import poi_for_world
from swarm_scene.rasterize import rasterize_polygons, rasterize_world
from swarm_scene.world import World, load_world

from .test_world import SEED_WALLS

RES = 0.05  # [m/cell]


@pytest.fixture(scope="module")
def slim_map():
    return rasterize_world(load_world("slim_blockage"), resolution=RES)


def _value(occ, x, y) -> int:
    r, c = occ.world_to_cell([x, y])
    assert occ.in_bounds([r, c])
    return int(occ.data[r, c])


def _cells_overlapped(lo: float, hi: float, origin: float, res: float) -> int:
    """Cells of width res from origin that an interval [lo, hi] overlaps by more than 1 µm."""
    first = math.floor((lo - origin + 1e-6) / res)
    last = math.ceil((hi - origin - 1e-6) / res) - 1
    return last - first + 1


def test_map_covers_the_walls_plus_padding_on_a_snapped_origin(slim_map):
    # walls span x [-8.475, 9.525], y [-4.974, 9.526]; padding 0.5 m; origin on the 0.05 grid
    assert slim_map.origin == pytest.approx([-9.0, -5.5, 0.0])
    assert slim_map.resolution == RES
    assert slim_map.width == math.ceil((9.525 + 0.5 + 9.0) / RES - 1e-9)  # 381
    assert slim_map.height == math.ceil((9.526 + 0.5 + 5.5) / RES - 1e-9)  # 311
    assert set(np.unique(slim_map.data)) == {FREE, OCCUPIED}  # nothing unknown


@pytest.mark.parametrize("wall", sorted(SEED_WALLS))
def test_every_wall_centre_is_occupied(slim_map, wall):
    (x0, x1), (y0, y1) = SEED_WALLS[wall]
    assert _value(slim_map, (x0 + x1) / 2, (y0 + y1) / 2) == OCCUPIED


@pytest.mark.parametrize("wall", sorted(SEED_WALLS))
def test_wall_thickness_in_cells(slim_map, wall):
    """Across its 0.15 m, each wall is exactly the cells it overlaps: >= 3, no gap."""
    (x0, x1), (y0, y1) = SEED_WALLS[wall]
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    r, c = slim_map.world_to_cell([cx, cy])
    if x1 - x0 < y1 - y0:  # vertical wall: thickness along x, across row r
        line = slim_map.data[r, :]
        expected = _cells_overlapped(x0, x1, slim_map.origin[0], RES)
        centre = c
    else:
        line = slim_map.data[:, c]
        expected = _cells_overlapped(y0, y1, slim_map.origin[1], RES)
        centre = r
    lo = hi = centre
    while line[lo - 1] == OCCUPIED:
        lo -= 1
    while line[hi + 1] == OCCUPIED:
        hi += 1
    assert hi - lo + 1 == expected
    assert expected >= 3


def test_wall_cell_counts_for_two_walls(slim_map):
    # left wall x [-8.475, -8.325] from origin -9.0: cells 10.5 .. 13.5 → 10, 11, 12, 13
    r, _ = slim_map.world_to_cell([0.0, 2.0])
    assert np.flatnonzero(slim_map.data[r, :20] == OCCUPIED).tolist() == [10, 11, 12, 13]
    # blockage left side x [-5.262, -5.112]: cells 74.76 .. 77.76 → 74..77
    assert np.flatnonzero(slim_map.data[r, 70:82] == OCCUPIED).tolist() == [4, 5, 6, 7]


@pytest.mark.parametrize(("passage", "x", "y", "axis", "width"), [
    ("above the blockage", -4.512, (7.484 + 9.376) / 2, "y", 9.376 - 7.484),    # 1.89 m
    ("below the blockage", -4.512, (-4.824 - 3.016) / 2, "y", -3.016 + 4.824),  # 1.81 m
    ("left corridor", (-8.325 - 5.262) / 2, 2.234, "x", -5.262 + 8.325),         # 3.06 m
])
def test_passages_are_free_over_their_width(slim_map, passage, x, y, axis, width):
    assert _value(slim_map, x, y) == FREE
    r, c = slim_map.world_to_cell([x, y])
    line = slim_map.data[:, c] if axis == "y" else slim_map.data[r, :]
    i = r if axis == "y" else c
    lo = hi = i
    while line[lo - 1] == FREE:
        lo -= 1
    while line[hi + 1] == FREE:
        hi += 1
    free_cells = hi - lo + 1
    # walls take every cell they touch, so the free run is the width less < 1 cell per side
    assert width / RES - 2 <= free_cells <= width / RES
    assert free_cells * RES >= width - 2 * RES


def test_workstations_and_spawn_points_are_free(slim_map):
    poi = poi_for_world(load_world("slim_blockage").source)
    for ws in poi.workstations:
        assert _value(slim_map, *ws.pose[:2]) == FREE, ws.name
    for point in poi.spawn.grid_points():
        assert _value(slim_map, *point) == FREE


def test_closed_pocket_interior_is_free_but_walled_in(slim_map):
    assert _value(slim_map, 6.7, -3.2) == FREE
    r, c = slim_map.world_to_cell([6.7, -3.2])
    assert (slim_map.data[r, c:] == OCCUPIED).any() and (slim_map.data[r, :c] == OCCUPIED).any()
    assert (slim_map.data[r:, c] == OCCUPIED).any() and (slim_map.data[:r, c] == OCCUPIED).any()


@pytest.mark.parametrize("seed", range(5))
def test_thin_walls_anywhere_are_at_least_3_cells_and_gapless(seed):
    """A 0.15 m wall at a random sub-cell offset and angle: >= 3 cells thick, no holes."""
    rng = np.random.default_rng(seed)
    cx, cy = rng.uniform(-0.05, 0.05, 2)
    angle = rng.uniform(-math.pi, math.pi) if seed else 0.0
    half_len, half_t = 2.0, 0.075
    d = np.array([math.cos(angle), math.sin(angle)])
    n = np.array([-d[1], d[0]])
    poly = np.array([[cx, cy] + sx * half_len * d + sy * half_t * n
                     for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    data = rasterize_polygons([poly], RES, (-3.0, -3.0), (120, 120))
    # sample the wall's centre line densely: every sample must land in an occupied cell,
    # and across the wall there must be >= 3 occupied cells in a row (along x or y)
    for t in np.linspace(-half_len + 0.1, half_len - 0.1, 200):
        p = np.array([cx, cy]) + t * d
        r, c = (np.floor((p[::-1] + 3.0) / RES)).astype(int)
        assert data[r, c] == OCCUPIED
        axis = 0 if abs(n[1]) >= abs(n[0]) else 1  # walk across the wall
        run_lo = run_hi = (r, c)[axis]
        line = data[:, c] if axis == 0 else data[r, :]
        while line[run_lo - 1] == OCCUPIED:
            run_lo -= 1
        while line[run_hi + 1] == OCCUPIED:
            run_hi += 1
        assert run_hi - run_lo + 1 >= 3


def test_rotated_square_is_rasterised_conservatively_and_tightly():
    """Every cell the polygon overlaps is occupied; every occupied cell is touched by it."""
    poly = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]) + [0.013, 0.007]
    data = rasterize_polygons([poly], 0.1, (-1.5, -1.5), (30, 30))
    sub = (np.arange(11) / 10.0) * 0.1  # 11 x 11 samples per cell, edges included
    for r in range(30):
        for c in range(30):
            xs = -1.5 + c * 0.1 + sub
            ys = -1.5 + r * 0.1 + sub
            gx, gy = np.meshgrid(xs, ys)
            # strictly inside the diamond |x - x0| + |y - y0| < 1
            inside = np.abs(gx - 0.013) + np.abs(gy - 0.007) < 1.0 - 1e-9
            if inside[1:-1, 1:-1].any():
                assert data[r, c] == OCCUPIED, (r, c)
            if data[r, c] == OCCUPIED:
                # the cell's nearest point to the centre must be strictly inside
                nx = np.clip(0.013, xs[0], xs[-1])
                ny = np.clip(0.007, ys[0], ys[-1])
                assert abs(nx - 0.013) + abs(ny - 0.007) < 1.0, (r, c)


def test_rasterising_the_factory_is_fast():
    world = load_world("factory_floor")
    t0 = time.perf_counter()
    occ = rasterize_world(world)
    assert time.perf_counter() - t0 < 2.0  # [s], about 0.05 s on a laptop
    assert occ.width == 628 and occ.height == 428


@pytest.mark.parametrize("name", ["slim_blockage", "factory_floor", "empty", "warehouse_slab",
                                  "narrow_aisles"])
def test_bundled_maps_are_the_rasterised_worlds(name):
    """maps/<name>.yaml is what swarm-map writes today (regenerate with swarm-map if not)."""
    stored = load_map(MAPS_DIR / f"{name}.yaml")
    fresh = rasterize_world(load_world(name), resolution=RES)
    assert stored.resolution == pytest.approx(RES)
    assert stored.origin == pytest.approx(fresh.origin)
    np.testing.assert_array_equal(stored.data, fresh.data)


def test_nothing_in_the_band_is_an_input_error(tmp_path: Path):
    world = World("void", tmp_path / "void.world", ())
    with pytest.raises(InputError, match="no collision geometry between z = 0.05 and 2 m"):
        rasterize_world(world)


@pytest.mark.parametrize(("kwargs", "problem"), [
    ({"resolution": 0.0}, "resolution must be a positive number"),
    ({"resolution": -0.05}, "resolution must be a positive number"),
    ({"resolution": math.nan}, "resolution must be a positive number"),
    ({"padding": -1.0}, "padding must be a non-negative number"),
])
def test_bad_parameters_are_input_errors(kwargs, problem):
    with pytest.raises(InputError, match=problem):
        rasterize_world(load_world("empty"), **kwargs)


# ------------------------------------------------------------------ floor slabs and new worlds


@pytest.fixture(scope="module")
def warehouse_map():
    return rasterize_world(load_world("warehouse_slab"), resolution=RES)


def test_floor_slab_and_loading_plate_are_free_the_low_pallet_is_occupied(warehouse_map):
    occ = warehouse_map
    # the slab covers x [-10.2, 10.2], y [-7.2, 7.2], top at 0.02 m: the hall's inside is free
    # except the shelves, columns and the pallet (area in cells, 0.05 m each)
    inside = occ.data[occ.world_to_cell([-9.9, -6.9])[0]:occ.world_to_cell([9.9, 6.9])[0] + 1,
                      occ.world_to_cell([-9.9, -6.9])[1]:occ.world_to_cell([9.9, 6.9])[1] + 1]
    shelves = 4 * (3.0 * 0.8) / RES**2
    columns = 2 * math.pi * 0.2**2 / RES**2
    pallet = 1.2 * 0.8 / RES**2
    assert (inside == OCCUPIED).sum() == pytest.approx(shelves + columns + pallet, rel=0.06)
    assert _value(occ, 6.0, 3.0) == FREE     # loading plate, top at 0.04 m
    assert _value(occ, 0.0, 0.0) == FREE     # the slab anywhere
    assert _value(occ, -8.8, -6.2) == OCCUPIED  # the 0.10 m pallet on the slab
    assert _value(occ, -6.1, 3.5) == OCCUPIED   # a shelf


def test_the_slab_is_an_obstacle_only_if_the_band_starts_on_the_ground(tmp_path: Path):
    # swarm-map --z-min 0 takes the floor's 0.02 m above z = 0 as an obstacle: all occupied
    occ = rasterize_world(load_world("warehouse_slab"), resolution=0.1, z_min=0.0)
    assert _value(occ, 0.0, 0.0) == OCCUPIED and _value(occ, 6.0, 3.0) == OCCUPIED


def test_a_world_of_floor_alone_has_nothing_to_rasterise(tmp_path: Path):
    path = tmp_path / "slab.world"
    path.write_text('<sdf version="1.7"><world name="w"><model name="slab"><link name="l">'
                    '<collision name="c"><geometry><box><size>10 10 0.1</size></box></geometry>'
                    '</collision></link><pose>0 0 -0.05 0 0 0</pose></model></world></sdf>')
    with pytest.raises(InputError, match="no collision geometry between z = 0.05 and 2 m"):
        rasterize_world(load_world(path))


@pytest.mark.parametrize("name", ["warehouse_slab", "narrow_aisles"])
def test_new_worlds_docks_holding_spots_and_spawn_nodes_are_clear(name):
    """Every dock, holding spot and spawn node is free with a robot's radius around it."""
    occ = load_map(MAPS_DIR / f"{name}.yaml")
    poi = poi_for_world(load_world(name).source)
    assert len(poi.workstations) >= 6
    points = [ws.pose[:2] for ws in poi.workstations]
    points += [h for ws in poi.workstations for h in ws.holding]
    assert all(len(ws.holding) == 1 for ws in poi.workstations)
    points += list(poi.spawn.grid_points())
    radius = 0.22 + 0.1  # [m] the Waffle's radius and a margin
    offsets = [np.array([radius * math.cos(a), radius * math.sin(a)])
               for a in np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)]
    for p in points:
        for d in [np.zeros(2), *offsets]:
            assert _value(occ, *(p + d)) == FREE, (name, p, d)


def test_narrow_aisles_are_free_across_their_width(tmp_path: Path):
    occ = load_map(MAPS_DIR / "narrow_aisles.yaml")
    for x0, x1 in [(-8.0, -5.6), (-4.6, -2.2), (-1.2, 1.2), (2.2, 4.6), (5.6, 8.0)]:
        for y in (-2.5, 1.0, 4.5):
            xs = np.arange(x0 + RES / 2, x1, RES)
            values = [_value(occ, x, y) for x in xs]
            assert values.count(FREE) == len(xs) == 48  # 2.4 m at 0.05 m/cell
            assert _value(occ, x0 - RES / 2, y) == OCCUPIED
            assert _value(occ, x1 + RES / 2, y) == OCCUPIED
