"""Route planning and route files (pure: no ROS)."""

from __future__ import annotations

import ast
import itertools
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import swarm_commander.route as route_module
from swarm_commander.route import (
    FixedRoute,
    RandomRoute,
    RouteStop,
    build_route,
    load_route,
    route_rng,
    stops_from_workstations,
    visits,
)
from swarm_common.errors import InputError
from swarm_scene.poi import load_poi

POI_YAML = """\
frame_id: map
workstations:
  - {name: loader1, x: -7.5, y: -3.5, yaw: 3.14159, holding: [[-6.6, -3.0]]}
  - {name: loader2, x: -7.5, y: -1.5, yaw: 3.14159}
  - {name: unload, x: 5.0, y: 5.0, yaw: 0.0}
"""


@pytest.fixture
def workstations(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text(POI_YAML)
    return load_poi(path).workstations


def make_stops(n: int) -> tuple[RouteStop, ...]:
    return tuple(RouteStop(f"s{i}", np.array([float(i), 0.0, 0.0])) for i in range(n))


def test_route_module_is_pure():
    tree = ast.parse(Path(route_module.__file__).read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module.split(".")[0])
    assert not {m for m in imported if m == "rclpy" or m.endswith(("_msgs", "_srvs"))}


def test_stops_from_workstations(workstations):
    stops = stops_from_workstations(workstations)
    assert [s.name for s in stops] == ["loader1", "loader2", "unload"]
    np.testing.assert_allclose(stops[0].pose, [-7.5, -3.5, 3.14159])
    assert stops[0].pose.shape == (3,)


@pytest.mark.parametrize("n", [1, 2, 3, 6])
def test_random_route_every_loop_is_a_permutation_without_repeats(n):
    route = RandomRoute(make_stops(n), route_rng(7, "Srobot1"))
    previous = None
    for _ in range(200):
        loop = route.next_loop()
        assert sorted(s.name for s in loop) == sorted(f"s{i}" for i in range(n))
        if n > 1 and previous is not None:
            assert loop[0].name != previous[-1].name
        previous = loop


def test_random_route_is_uniform_over_allowed_orders():
    route = RandomRoute(make_stops(3), route_rng(0, "Srobot1"))
    counts = Counter()
    last = None
    for _ in range(6000):
        loop = tuple(s.name for s in route.next_loop())
        if last is not None:
            counts[(last, loop)] += 1
        last = loop[-1]
    for prev in ("s0", "s1", "s2"):
        allowed = [p for p in itertools.permutations(("s0", "s1", "s2")) if p[0] != prev]
        total = sum(counts[(prev, p)] for p in allowed)
        assert sum(v for (lp, _), v in counts.items() if lp == prev) == total
        for p in allowed:  # 4 allowed orders, each ~1/4
            assert counts[(prev, p)] == pytest.approx(total / 4, rel=0.2)


def test_random_route_is_deterministic_per_seed_and_namespace():
    def orders(seed, ns):
        route = RandomRoute(make_stops(5), route_rng(seed, ns))
        return [tuple(s.name for s in route.next_loop()) for _ in range(10)]

    assert orders(3, "Srobot1") == orders(3, "/Srobot1")
    assert orders(3, "Srobot1") != orders(4, "Srobot1")
    assert orders(3, "Srobot1") != orders(3, "Srobot2")
    loops = orders(3, "Srobot1")
    assert len(set(loops)) > 1  # a fresh permutation each loop


def test_route_rng_rejects_negative_seed():
    with pytest.raises(ValueError):
        route_rng(-1, "Srobot1")


def test_fixed_route_keeps_the_order():
    stops = make_stops(3)
    assert FixedRoute(stops).next_loop() == stops
    assert FixedRoute(stops).next_loop() == FixedRoute(stops).next_loop()


def test_visits_counts_loops():
    stops = make_stops(3)
    got = list(visits(FixedRoute(stops), loops=2))
    assert [(loop, s.name) for loop, s in got] == [
        (1, "s0"), (1, "s1"), (1, "s2"), (2, "s0"), (2, "s1"), (2, "s2")]
    forever = visits(RandomRoute(stops, route_rng(0, "a")), loops=0)
    assert len(list(itertools.islice(forever, 300))) == 300
    with pytest.raises(ValueError):
        next(visits(FixedRoute(stops), loops=-1))
    with pytest.raises(ValueError):
        RandomRoute([], route_rng(0, "a"))


def test_load_route_names_and_poses(tmp_path, workstations):
    path = tmp_path / "route.yaml"
    path.write_text("frame_id: map\nwaypoints:\n  - loader2\n"
                    "  - {name: dock, x: 1.5, y: -2, yaw: 1.5707963}\n"
                    "  - {x: 0, y: 0, yaw: 4.0}\n")
    stops = load_route(path, workstations)
    assert [s.name for s in stops] == ["loader2", "dock", "waypoint3"]
    np.testing.assert_allclose(stops[0].pose, [-7.5, -1.5, 3.14159])
    np.testing.assert_allclose(stops[1].pose, [1.5, -2.0, math.pi / 2])
    assert stops[2].pose[2] == pytest.approx(4.0 - 2 * math.pi)  # yaw wrapped into (-pi, pi]


def test_load_route_of_poses_needs_no_workstations(tmp_path):
    path = tmp_path / "route.yaml"
    path.write_text("waypoints: [{x: 1, y: 2, yaw: 0}]\n")
    assert [s.name for s in load_route(path)] == ["waypoint1"]


@pytest.mark.parametrize("text, expected", [
    ("waypionts: [loader1]\n", "unknown key 'waypionts' (did you mean 'waypoints'?)"),
    ("frame_id: map\n", "missing key 'waypoints'"),
    ("waypoints: []\n", "waypoints: expected a non-empty list"),
    ("waypoints: loader1\n", "waypoints: expected a non-empty list, got str"),
    ("- loader1\n", "expected a mapping with 'waypoints', got list"),
    ("", "expected a mapping with 'waypoints', got nothing"),
    ("waypoints: [loadr1]\n", "unknown workstation 'loadr1' (did you mean 'loader1'?)"),
    ("waypoints: [{x: 1, y: 2, yw: 0}]\n", "unknown key 'yw' (did you mean 'yaw'?)"),
    ("waypoints: [{x: 1, y: 2}]\n", "waypoints[1]: missing key 'yaw'"),
    ("waypoints: [{x: one, y: 2, yaw: 0}]\n", "x: expected a finite number, got 'one'"),
    ("waypoints: [{x: .nan, y: 2, yaw: 0}]\n", "x: expected a finite number"),
    ("waypoints: [{x: true, y: 2, yaw: 0}]\n", "x: expected a finite number, got True"),
    ("waypoints: [{name: '', x: 1, y: 2, yaw: 0}]\n", "name: expected a non-empty string"),
    ("waypoints: [loader1, 3]\n", "waypoints[2]: expected a workstation name or a mapping"),
    ("frame_id: odom\nwaypoints: [loader1]\n", "frame_id: only 'map' is supported"),
    ("waypoints: [loader1\n", "not valid YAML at line"),
])
def test_load_route_rejects_malformed_files(tmp_path, workstations, text, expected):
    path = tmp_path / "route.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_route(path, workstations)
    message = str(info.value)
    assert message.startswith(str(path) + ":")
    assert expected in message
    assert "\n" not in message


def test_load_route_names_without_workstations(tmp_path):
    path = tmp_path / "route.yaml"
    path.write_text("waypoints: [loader1]\n")
    with pytest.raises(InputError, match="names a workstation, but the world has none"):
        load_route(path, None)


def test_load_route_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such route file"):
        load_route(tmp_path / "nope.yaml")


def _names(route, loops=3):
    return [stop.name for _, stop in visits(route, loops)]


def test_build_route_random_is_seeded_per_robot_over_the_bundled_workstations():
    route = build_route("slim_blockage", 0, "Srobot3")
    assert isinstance(route, RandomRoute)
    names = _names(route)
    assert len(names) == 18  # six loaders, every one once per loop
    for loop in range(3):
        assert sorted(names[6 * loop:6 * loop + 6]) == [f"loader{i}" for i in range(1, 7)]
    assert _names(build_route("slim_blockage", 0, "Srobot3")) == names  # same seed, same order
    others = [_names(build_route("slim_blockage", 0, f"Srobot{i}")) for i in range(4, 9)]
    assert any(o != names for o in others)  # the namespace is mixed into the seed


def test_build_route_reads_a_route_file(tmp_path):
    path = tmp_path / "route.yaml"
    path.write_text("waypoints:\n  - loader2\n  - {x: 1.0, y: 2.0, yaw: 0.5}\n")
    route = build_route("slim_blockage", 0, "Srobot1", route=path)
    assert isinstance(route, FixedRoute)
    assert [s.name for s in route.stops][0] == "loader2"
    assert route.stops[1].pose[:2].tolist() == [1.0, 2.0]


def test_build_route_errors_name_the_flag():
    with pytest.raises(InputError, match=r"^--world: "):
        build_route("no_such_world", 0, "Srobot1")
    with pytest.raises(InputError, match=r"^--world: world empty has no workstations"):
        build_route("empty", 0, "Srobot1")
