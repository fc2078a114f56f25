"""The live view's pure core: workstation states, the KPIs, the page's messages (no ROS)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from swarm_common.nav_status import NavState
from swarm_metrics.aggregate import RunRecorder
from swarm_scene.poi import Workstation
from swarm_viz.fleet_view import (
    PATH_TOLERANCE,
    WS_FREE,
    WS_HELD,
    WS_OCCUPIED,
    FleetState,
    KpiTracker,
    ScanSample,
    ViewConfig,
    decimate,
    encode_hello,
    encode_paths,
    encode_robot,
    encode_robots,
    simplify,
    workstation_states,
)

WS = np.array([[-7.75, -3.58], [-7.75, -1.39], [-7.75, 0.97]])
NAN2 = [np.nan, np.nan]


@pytest.mark.parametrize(("robots", "states", "goals", "want_ws", "want_holding"), [
    # nobody near, nobody holding
    ([[0.0, 0.0]], [NavState.DRIVING], [[-7.75, -3.58]], [WS_FREE] * 3, []),
    # docked 0.29 m from loader1 (inside 0.3 m) -> occupied; 0.31 m from loader2 -> free
    ([[-7.46, -3.58], [-7.75, -1.08]], [NavState.SUCCEEDED, NavState.DRIVING], [NAN2, NAN2],
     [WS_OCCUPIED, WS_FREE, WS_FREE], []),
    # robot 1 docked at loader2, robot 0 holding for it -> held (wins over occupied)
    ([[-7.75, -2.48], [-7.75, -1.39]], [NavState.HOLDING, NavState.SUCCEEDED],
     [[-7.75, -1.39], [-7.75, -1.39]], [WS_FREE, WS_HELD, WS_FREE], [0]),
    # holding for a goal 6 cm from loader3 (beyond the 5 cm tolerance): not held
    ([[5.0, 5.0]], [NavState.HOLDING], [[-7.75, 1.03]], [WS_FREE] * 3, [0]),
    # an unknown pose (NaN) occupies nothing
    ([NAN2], [None], [NAN2], [WS_FREE] * 3, []),
    # no robots
    (np.zeros((0, 2)), [], np.zeros((0, 2)), [WS_FREE] * 3, []),
])
def test_workstation_states(robots, states, goals, want_ws, want_holding):
    got, holding = workstation_states(WS, np.array(robots, dtype=float), states,
                                      np.array(goals, dtype=float))
    assert got == want_ws
    assert holding == want_holding


def test_workstation_states_without_workstations():
    assert workstation_states(np.zeros((0, 2)), np.zeros((1, 2)), [None], [NAN2]) == ([], [])


def test_kpis_are_the_recorders_counts_and_rtf_over_the_window():
    rec = RunRecorder(robots=("Srobot1", "Srobot2"))
    rec.on_status("Srobot1", {"state": "IDLE", "goal_id": ""}, 1.0)
    rec.on_status("Srobot1", {"state": "SUCCEEDED", "goal_id": "1.000000000"}, 2.0)
    rec.on_status("Srobot1", {"state": "SUCCEEDED", "goal_id": "1.000000000"}, 2.5)  # once
    rec.on_status("Srobot2", {"state": "ABORTED", "goal_id": "2.000000000"}, 3.0)
    rec.on_event("collision", {"robot": "Srobot1", "other": "Srobot2"})
    rec.on_event("collision", {"robot": "Srobot2", "other": "wall::link::box"})
    rec.on_event("late", {"robot": "Srobot2"})
    rec.on_event("late", {"robot": "Srobot2"})
    kpi = KpiTracker(ViewConfig(rtf_window=5.0))
    assert kpi.figures(rec, 100.0)["sim_time_s"] is None  # no /clock yet
    rec.on_clock(10.0)
    first = kpi.figures(rec, 100.0)
    assert first["rtf"] is None  # one sample
    rec.on_clock(30.0)
    fig = kpi.figures(rec, 104.0)  # 20 simulated s in 4 wall s
    assert fig == {"sim_time_s": 30.0, "rtf": 5.0, "tasks": 1, "throughput_per_hour": 120.0,
                   "goals_aborted": 1, "collisions": 2, "late_ticks": 2, "robots": 2,
                   "ready": 2}
    # samples older than the window are dropped: 10 s more in the next 10 wall s -> RTF 1
    for k in range(1, 11):
        rec.on_clock(30.0 + k)
        fig = kpi.figures(rec, 104.0 + k)
    assert fig["rtf"] == pytest.approx(1.0)


def test_fleet_state_and_messages():
    fleet = FleetState(("Srobot1", "Srobot2"))
    fleet.set_pose(0, 200, 1.23456, -2.0, 0.5)
    fleet.set_pose(0, 100, 9.0, 9.0, 0.0)  # older: ignored
    fleet.set_path(0, np.array([[1.0, 2.0], [1.004, 2.996]]))
    fleet.set_status(0, {"state": "DRIVING", "goal_x": "3.0"}, NavState.DRIVING, (3.0, 4.0, 0.0))
    assert encode_robots(fleet) == [[1.235, -2.0, 0.5, "DRIVING"], None]
    assert encode_paths(fleet, [0, 1]) == {"0": [[1.0, 2.0], [1.0, 3.0]], "1": []}
    np.testing.assert_array_equal(fleet.goals, [[3.0, 4.0], NAN2])
    ranges = np.array([1.0, np.inf, 0.05, 2.0], dtype=np.float32)
    fleet.set_scan(0, ScanSample(1_500_000_000, np.array([1.0, 2.0, 0.0]), 0.0, math.pi / 2,
                                 0.12, 3.5, ranges))
    msg = encode_robot(fleet, 0, np.array([-0.064, 0.0, 0.0]), with_scan=True)
    assert msg["scan"]["ranges"] == [1.0, None, None, 2.0]  # inf and < range_min: no return
    assert msg["scan"]["stamp"] == 1.5 and msg["scan"]["range_max"] == 3.5
    assert msg["status"] == {"state": "DRIVING", "goal_x": "3.0"} and msg["message"] == "DRIVING"
    assert encode_robot(fleet, 1, np.zeros(3), with_scan=True)["scan"] is None
    ws = Workstation(name="loader1", pose=np.array([-7.7, -3.5, math.pi]),
                     holding=np.array([[-7.7, -4.45]]))
    hello = encode_hello(world="w", robots=fleet.robots, footprint=np.array([[0.1, 0.2]]),
                         map_info={"url": "/map.png"}, workstations=[ws], rate_hz=10.0,
                         robot=None)
    assert hello["workstations"] == [{"name": "loader1", "x": -7.7, "y": -3.5, "yaw": 3.1416,
                                      "holding": [[-7.7, -4.45]]}]
    json.dumps([hello, msg])  # JSON-serialisable


@pytest.mark.parametrize(("n", "max_points"), [(5, 100), (100, 100), (101, 100), (1000, 100),
                                               (7, 3)])
def test_decimate_keeps_the_ends_and_the_limit(n, max_points):
    path = np.column_stack((np.arange(n, dtype=float), np.zeros(n)))
    out = decimate(path, max_points)
    assert len(out) <= max_points
    assert out[0, 0] == 0 and out[-1, 0] == n - 1
    assert np.all(np.diff(out[:, 0]) > 0)


def _segment_distance(pts: np.ndarray, line: np.ndarray) -> np.ndarray:
    """(N,) distance of each point to the polyline ``line`` (brute force over its segments)."""
    best = np.full(len(pts), np.inf)
    for p, q in zip(line[:-1], line[1:], strict=True):
        d = q - p
        t = np.clip((pts - p) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.hypot(*(pts - p - t[:, None] * d).T))
    return best


def test_simplify_keeps_a_plans_corners_and_drops_the_points_between():
    # three straight runs resampled every 5 cm, as a navigator's plan
    corners = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 2.0], [5.5, 4.5]])
    runs = [np.linspace(a, b, int(round(np.hypot(*(b - a)) / 0.05)) + 1)[:-1]
            for a, b in zip(corners[:-1], corners[1:], strict=True)]
    path = np.vstack(runs + [corners[-1:]])
    out = simplify(path, PATH_TOLERANCE)
    np.testing.assert_allclose(out, corners, atol=1e-12)
    assert len(path) > 150


def test_simplify_bounds_the_deviation_of_every_dropped_point():
    rng = np.random.default_rng(4)
    path = np.cumsum(rng.normal(0.0, 0.05, size=(400, 2)), axis=0)
    for tol in (0.0, 0.01, 0.1):
        out = simplify(path, tol)
        assert np.array_equal(out[0], path[0]) and np.array_equal(out[-1], path[-1])
        assert len(out) < len(path) or tol == 0.0
        assert _segment_distance(path, out).max() <= tol + 1e-12
    # a run that turns back on itself keeps its far end (distance to the segment, not the line)
    back = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 0.0]])
    np.testing.assert_array_equal(simplify(back, 0.01), [[0.0, 0.0], [2.0, 0.0], [1.0, 0.0]])


def test_fleet_state_keeps_the_simplified_plan():
    fleet = FleetState(("Srobot1",))
    line = np.column_stack((np.linspace(0.0, 10.0, 201), np.full(201, 2.0)))
    fleet.set_path(0, line)
    np.testing.assert_array_equal(fleet.paths[0], [[0.0, 2.0], [10.0, 2.0]])


def test_a_mixed_fleet_shows_every_robots_own_outline_and_lidar():
    fleet = FleetState(("Srobot1", "Srobot2"))
    for i in (0, 1):
        fleet.set_scan(i, ScanSample(1_000_000_000, np.zeros(3), 0.0, 1.0, 0.1, 3.5,
                                     np.ones(2, dtype=np.float32)))
    mounts = np.array([[-0.064, 0.0, 0.0], [0.0, 0.0, 0.0]])
    assert [encode_robot(fleet, i, mounts, with_scan=True)["scan"]["lidar"]
            for i in (0, 1)] == [[-0.064, 0.0, 0.0], [0.0, 0.0, 0.0]]
    square, hexagon = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), np.ones((6, 2))
    hello = encode_hello(world="w", robots=fleet.robots, footprint=square, map_info={},
                         workstations=[], rate_hz=10.0, robot=None,
                         footprints=[square, hexagon])
    assert [len(f) for f in hello["footprints"]] == [4, 6]
    assert "footprints" not in encode_hello(world="w", robots=fleet.robots, footprint=square,
                                            map_info={}, workstations=[], rate_hz=10.0,
                                            robot=None)


def test_markers_draw_every_robots_own_outline():
    from builtin_interfaces.msg import Time

    from swarm_viz.markers import fleet_markers

    fleet = FleetState(("Srobot1", "Srobot2"))
    fleet.set_pose(0, 1, 0.0, 0.0, 0.0)
    fleet.set_pose(1, 1, 5.0, 0.0, 0.0)
    small = np.array([[-0.1, -0.07], [0.04, -0.07], [0.04, 0.07], [-0.1, 0.07]])
    big = np.array([[-0.2, -0.13], [0.07, -0.13], [0.07, 0.13], [-0.2, 0.13]])
    out = fleet_markers(fleet, [small, big], (), [], Time())
    outlines = [m for m in out.markers if m.ns == "footprint"]
    xs = [sorted({round(p.x, 3) for p in m.points}) for m in outlines]
    assert xs == [[-0.1, 0.04], [4.8, 5.07]]
