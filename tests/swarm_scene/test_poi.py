"""swarm_scene.poi: the strict points-of-interest loader and the bundled worlds' POI."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from swarm_common.errors import InputError
from swarm_scene.occupancy import OCCUPIED
from swarm_scene.poi import PointsOfInterest, load_poi, poi_for_world
from swarm_scene.rasterize import rasterize_world
from swarm_scene.world import load_world, resolve_world, world_polygons

DATA = Path(__file__).resolve().parents[1] / "data"

# shared/reference/seed_facts.md
SEED_LOADER_Y = [-3.577660, -1.385260, 0.972970, 3.203130, 5.784420, 8.363370]
SEED_LOOP = [(-5.990370, 8.674410), (-2.706150, 8.674410), (-2.706150, -3.947350),
             (-5.990370, -3.947350)]
ROBOT_RADIUS = 0.22  # [m] TurtleBot3 waffle, nav2 robot_radius
CLEARANCE = 0.35  # [m] every POI at least this far from any wall


def _write(tmp_path: Path, text: str, name: str = "poi_test.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------- the loader


def test_fixture_loads_with_spot_loop_and_defaults():
    poi = load_poi(DATA / "poi_valid.yaml")
    assert [ws.name for ws in poi.workstations] == ["press", "drill", "bench"]
    press, drill, bench = poi.workstations
    assert press.pose.tolist() == [1.0, 2.0, pytest.approx(math.pi / 2)]
    assert press.holding.tolist() == [[1.0, 3.5]] and not press.is_loop  # a spot
    assert drill.holding.shape == (3, 2) and drill.is_loop  # a loop, in file order
    assert drill.holding.tolist() == [[4.0, 0.0], [5.0, 0.0], [5.0, 1.0]]
    assert bench.pose.tolist() == [-2.0, 0.5, 0.0]  # yaw defaults to 0
    assert bench.holding.shape == (0, 2)
    assert poi.spawn.origin.tolist() == [0.0, -3.0]
    assert poi.spawn.spacing == 0.5 and poi.spawn.yaw == pytest.approx(-math.pi / 2)
    assert poi.spawn.area.tolist() == [-1.0, -4.0, 1.0, -3.0]
    # 5 columns (x -1..1 step 0.5) x 3 rows (y -4..-3 step 0.5)
    assert len(poi.spawn.grid_points()) == 15
    assert poi.points["dock"].tolist() == [3.0, 3.0]
    assert poi.points["gate"].tolist() == [0.0, 4.0, pytest.approx(math.pi)]
    assert poi.workstation("drill") is drill


def test_two_point_holding_is_a_loop_and_a_bare_point_a_spot(tmp_path):
    poi = load_poi(_write(tmp_path, "workstations:\n"
                          "  - {name: a, x: 0, y: 0, holding: [[1, 1], [2, 2]]}\n"
                          "  - {name: b, x: 0, y: 0, holding: [3, 4]}\n"))
    assert poi.workstations[0].is_loop and poi.workstations[0].holding.shape == (2, 2)
    assert poi.workstations[1].holding.tolist() == [[3.0, 4.0]]


def test_loaded_arrays_are_read_only():
    poi = load_poi(DATA / "poi_valid.yaml")
    with pytest.raises(ValueError):
        poi.workstations[0].pose[0] = 9.0
    with pytest.raises(ValueError):
        poi.spawn.area[0] = 9.0


@pytest.mark.parametrize("text", ["", "# only a comment\n", "workstations: []\n"])
def test_empty_files_give_empty_poi(tmp_path, text):
    poi = load_poi(_write(tmp_path, text))
    assert poi.workstations == () and poi.spawn is None and poi.points == {}


@pytest.mark.parametrize(("text", "message"), [
    ("workstaions: []\n", "unknown key 'workstaions' (did you mean 'workstations'?)"),
    ("workstations:\n  - {name: a, x: 0, y: 0}\n  - {name: b, x: 0, y: 0}\n"
     "  - {name: c, xx: 0, y: 0}\n",
     "unknown key 'xx' in workstations[2] (did you mean 'x'?)"),
    ("workstations:\n  - {name: a, x: 0, y: 0, hold: [[1, 1]]}\n",
     "unknown key 'hold' in workstations[0] (did you mean 'holding'?)"),
    ("spawn: {origin: [0, 0], area: [0, 0, 1, 1], spaceing: 1}\n",
     "unknown key 'spaceing' in spawn (did you mean 'spacing'?)"),
    ("spawn: {origin: [0, 0], area: [0, 0, 1, 1], colour: red}\n",
     "unknown key 'colour' in spawn"),
])
def test_unknown_keys_are_errors_with_did_you_mean(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(InputError) as err:
        load_poi(path)
    assert str(err.value) == f"{path}: {message}"


@pytest.mark.parametrize(("text", "message"), [
    ("workstations:\n  - {x: 0, y: 0}\n", "workstations[0] is missing required key 'name'"),
    ("workstations:\n  - {name: a, y: 0}\n", "workstations[0] is missing required key 'x'"),
    ("workstations:\n  - {name: a, x: 0, y: north}\n",
     "workstations[0].y must be a number, got 'north'"),
    ("workstations:\n  - {name: a, x: true, y: 0}\n",
     "workstations[0].x must be a number, got True"),
    ("workstations:\n  - {name: 7, x: 0, y: 0}\n",
     "workstations[0].name must be a non-empty string, got 7"),
    ("workstations:\n  - {name: a, x: 0, y: 0, holding: [[1, 2, 3]]}\n",
     "workstations[0].holding[0] must be [x, y], got [1, 2, 3]"),
    ("workstations:\n  - {name: a, x: 0, y: 0, holding: 5}\n",
     "workstations[0].holding must be a list of [x, y] points, got 5"),
    ("workstations:\n  - {name: a, x: 0, y: 0}\n  - {name: a, x: 1, y: 1}\n",
     "workstations[1]: duplicate name 'a'"),
    ("workstations: {name: a}\n", "workstations must be a list, got {'name': 'a'}"),
    ("workstations:\n  - loader1\n", "workstations[0] must be a mapping of keys, got 'loader1'"),
    ("spawn: {area: [0, 0, 1, 1]}\n", "spawn is missing required key 'origin'"),
    ("spawn: {origin: [0, 0]}\n", "spawn is missing required key 'area'"),
    ("spawn: {origin: [0, 0, 0], area: [0, 0, 1, 1]}\n",
     "spawn.origin must be [x, y], got [0, 0, 0]"),
    ("spawn: {origin: [0, 0], area: [1, 0, 0, 1]}\n",
     "spawn.area must be [xmin, ymin, xmax, ymax] with xmin < xmax"),
    ("spawn: {origin: [5, 0], area: [0, 0, 1, 1]}\n",
     "spawn.origin [5.0, 0.0] is outside spawn.area"),
    ("spawn: {origin: [0, 0], area: [0, 0, 1, 1], spacing: 0}\n",
     "spawn.spacing must be positive [m], got 0"),
    ("points: {dock: [1]}\n", "points.dock must be [x, y] or [x, y, yaw], got [1]"),
    ("points: [1, 2]\n", "points must be a mapping of keys, got [1, 2]"),
    ("waiting: [[1]]\n", "waiting[0] must be [x, y] or [x, y, yaw], got [1]"),
    ("waiting: 5\n", "waiting must be a list of [x, y] or [x, y, yaw] points, got 5"),
    ("frame_id: odom\n", "frame_id must be 'map'"),
    ("service_time: -5\n", "service_time must be >= 0 [s], got -5"),
    ("service_time: soon\n", "service_time must be a number, got 'soon'"),
    ("- a\n- b\n", "the file must be a mapping of keys"),
    ("workstations: [unclosed\n", "invalid YAML at line"),
])
def test_bad_fields_name_file_and_field(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(InputError) as err:
        load_poi(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: {message}"), msg
    assert "\n" not in msg


def test_service_time_defaults_to_zero_and_is_read(tmp_path):
    assert load_poi(_write(tmp_path, "workstations: []\n")).service_time == 0.0
    assert load_poi(_write(tmp_path, "service_time: 15\n", "s.yaml")).service_time == 15.0


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such points-of-interest file"):
        load_poi(tmp_path / "nope.yaml")


def test_numbers_pyyaml_reads_as_strings_are_accepted(tmp_path):
    poi = load_poi(_write(tmp_path, "points: {far: [1e3, -2e1]}\n"))
    assert poi.points["far"].tolist() == [1000.0, -20.0]


def test_poi_for_world_finds_the_yaml_beside_the_world(tmp_path):
    world = tmp_path / "hall.world"
    world.write_text("<sdf/>")
    assert poi_for_world(world) is None
    (tmp_path / "hall.yaml").write_text("points: {a: [1, 2]}\n")
    poi = poi_for_world(world)
    assert isinstance(poi, PointsOfInterest) and poi.points["a"].tolist() == [1.0, 2.0]


# ------------------------------------------------------------------- the bundled worlds


def test_slim_blockage_poi_is_the_seed():
    poi = poi_for_world(resolve_world("slim_blockage"))
    assert [ws.name for ws in poi.workstations] == [f"loader{i}" for i in range(1, 7)]
    for ws, y in zip(poi.workstations, SEED_LOADER_Y, strict=True):
        assert ws.pose[:2].tolist() == [-7.745750, y]
        assert ws.pose[2] == pytest.approx(math.pi, abs=1e-7)
    assert poi.points["unload"].tolist() == [5.0, 5.0]
    assert poi.points["shipping"].tolist() == [7.015590, 6.999010]
    assert [tuple(poi.points[f"holding_loop_{i}"]) for i in range(1, 5)] == SEED_LOOP
    assert poi.spawn.origin.tolist() == [0.0, 0.0] and poi.spawn.spacing == 1.0
    assert poi.spawn.yaw == pytest.approx(math.pi, abs=1e-7)


def test_slim_blockage_holding_spots_leave_the_corridor_lane_free():
    poi = poi_for_world(resolve_world("slim_blockage"))
    docks = np.array([ws.pose[:2] for ws in poi.workstations])
    for ws in poi.workstations:
        (spot,) = ws.holding
        # the lane between a holding robot and the blockage's left side (x = -5.262)
        assert -5.262 - (spot[0] + ROBOT_RADIUS) >= 1.0
        # clear of every dock: >= 0.85 m centre to centre (>= 0.41 m between bodies)
        assert np.linalg.norm(docks - spot, axis=1).min() >= 0.85
        # and inside the left corridor, never in a passage
        assert -8.325 < spot[0] < -5.262 and -4.824 < spot[1] < 7.484


def test_slim_blockage_waiting_spots_leave_a_two_way_lane_beside_the_docks():
    poi = poi_for_world(resolve_world("slim_blockage"))
    assert poi.waiting.shape == (9, 3)
    docks = np.array([ws.pose[:2] for ws in poi.workstations])
    for x, y, _ in poi.waiting:
        # the lane between a docked robot (x <= -7.53) and a waiting one: two bodies pass
        assert (x - ROBOT_RADIUS) - (docks[0, 0] + ROBOT_RADIUS) >= 2 * 2 * ROBOT_RADIUS
        assert -5.262 - (x + ROBOT_RADIUS) >= 0.15  # clear of the blockage
        assert -4.824 < y < 7.484
    gaps = np.diff(np.sort(poi.waiting[:, 1]))
    assert gaps.min() >= 2 * ROBOT_RADIUS + 0.3  # no two waiting robots touch


def test_waiting_spots_default_yaw_and_empty(tmp_path):
    poi = load_poi(_write(tmp_path, "waiting:\n  - [1, 2]\n  - [3, 4, 1.5]\n"))
    assert poi.waiting.tolist() == [[1.0, 2.0, 0.0], [3.0, 4.0, 1.5]]
    assert load_poi(_write(tmp_path, "points: {a: [0, 0]}\n")).waiting.shape == (0, 3)


def test_slim_blockage_spawn_avoids_pocket_and_holds_100():
    poi = poi_for_world(resolve_world("slim_blockage"))
    grid = poi.spawn.grid_points()
    assert len(grid) == 120
    in_pocket = (grid[:, 0] >= 4.059 - CLEARANCE) & (grid[:, 1] <= -1.562 + CLEARANCE)
    assert not in_pocket.any()
    assert (grid[:, 0] > -3.762).all()  # right of the blockage


def _distance_to_polygon(p: np.ndarray, poly: np.ndarray) -> float:
    """Distance [m] from a point to a convex counter-clockwise polygon (0 inside)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ab, ap = b - a, p - a
    if (ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0] >= 0).all():
        return 0.0
    t = np.clip(np.einsum("ij,ij->i", ap, ab) / np.einsum("ij,ij->i", ab, ab), 0.0, 1.0)
    return float(np.linalg.norm(a + t[:, None] * ab - p, axis=1).min())


@pytest.mark.parametrize(("name", "min_workstations", "min_spawn"), [
    ("slim_blockage", 6, 100), ("factory_floor", 10, 100), ("empty", 0, 100)])
def test_bundled_poi_clear_of_walls(name, min_workstations, min_spawn):
    """Every dock, holding point, named point and spawn point is >= 0.35 m from any shape."""
    world = load_world(name)
    poi = poi_for_world(world.source)
    polygons = world_polygons(world)
    assert len(poi.workstations) >= min_workstations
    assert len(poi.spawn.grid_points()) >= min_spawn
    points = [ws.pose[:2] for ws in poi.workstations]
    points += [p for ws in poi.workstations for p in ws.holding]
    points += list(poi.spawn.grid_points())
    points += [p[:2] for p in poi.points.values()]
    points += [p[:2] for p in poi.waiting]
    for p in points:
        clearance = min(_distance_to_polygon(np.asarray(p), poly) for poly in polygons)
        assert clearance >= CLEARANCE, (name, p.tolist(), clearance)
    # and the rasterised map agrees: the cell of every point is free
    occ = rasterize_world(world, resolution=0.05)
    cells = occ.world_to_cell(np.array(points))
    assert (occ.data[cells[:, 0], cells[:, 1]] != OCCUPIED).all()


def test_factory_floor_aisles_and_holding_bays():
    poi = poi_for_world(resolve_world("factory_floor"))
    names = [ws.name for ws in poi.workstations]
    assert len(names) == len(set(names)) == 14
    assert all(len(ws.holding) == 1 for ws in poi.workstations)  # one bay each
    docks = np.array([ws.pose[:2] for ws in poi.workstations])
    bays = np.array([ws.holding[0] for ws in poi.workstations])
    # no bay on top of a dock or of another bay: >= 1.0 m apart (0.56 m between bodies)
    everything = np.vstack((docks, bays))
    dist = np.linalg.norm(everything[:, None] - everything[None], axis=2)
    np.fill_diagonal(dist, np.inf)
    assert dist.min() >= 1.0 - 1e-9
    assert len(poi.spawn.grid_points()) == 117
    assert "shipping" in poi.points


def test_a_file_is_parsed_once_per_content(tmp_path):
    """A group process loads the same file for every navigator and commander: an unchanged file
    gives the same (immutable) object, a changed one is read again, a broken one still fails."""
    f = tmp_path / "poi.yaml"
    f.write_text("workstations:\n  - {name: a, x: 1.0, y: 2.0}\n")
    first = load_poi(f)
    assert load_poi(f) is first
    f.write_text("workstations:\n  - {name: a, x: 3.0, y: 2.0}\n")  # same size, new content
    second = load_poi(f)
    assert second is not first and second.workstations[0].pose[0] == 3.0
    f.write_text("workstations:\n  - {name: a, xx: 3.0, y: 2.0}\n")
    for _ in range(2):
        with pytest.raises(InputError, match="unknown key 'xx'"):
            load_poi(f)
