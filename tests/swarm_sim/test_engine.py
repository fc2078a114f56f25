"""The simulated world: spawning, driving under the drive's limits, bump-stop contacts counted
once per episode, minimum separation, lidar cadence and determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_scene.poi import poi_for_world
from swarm_scene.spawn import spawn_poses
from swarm_scene.world import load_world, world_polygons
from swarm_sim.engine import EngineConfig, SimEngine, polygon_distances

# TurtleBot3 waffle footprint: x in [-0.197, 0.069], y in [-0.133, 0.133] about base_footprint.
REAR, FRONT, HALF_WIDTH = 0.197, 0.069, 0.133


@pytest.fixture(scope="module")
def slim():
    return load_world("slim_blockage")


@pytest.fixture(scope="module")
def waffle(robots):
    return robots["turtlebot3_waffle"]


def drive(engine: SimEngine, v, w, ticks: int) -> list:
    events = []
    for _ in range(ticks):
        events += engine.step(np.broadcast_to(np.asarray(v, float), engine.n),
                              np.broadcast_to(np.asarray(w, float), engine.n))
    return events


def ramped_distance(v: float, acc: float, dt: float, steps: int) -> float:
    """Distance [m] covered in ``steps`` substeps of ``dt`` accelerating from rest at ``acc``
    towards ``v`` (the speed after substep k is min(v, k acc dt), held for that substep)."""
    return sum(min(v, k * acc * dt) * dt for k in range(1, steps + 1))


# -- spawning ----------------------------------------------------------------------------------


def test_default_five_robots_start_on_the_row_facing_back(slim, waffle, make_engine):
    poses = spawn_poses(poi_for_world(slim.source).spawn, 5, waffle.radius, world_polygons(slim))
    engine = make_engine(slim, waffle, poses)
    np.testing.assert_allclose(engine.poses, [[i, 0.0, 3.14159265] for i in range(5)])
    assert engine.t == 0.0 and engine.ticks == 0
    # 1 m apart, each footprint 0.266 m long: 0.734 m between neighbours.
    assert engine.min_separation == pytest.approx(1.0 - REAR - FRONT, abs=1e-9)
    assert drive(engine, 0.0, 0.0, 5) == []
    np.testing.assert_array_equal(engine.poses[:, :2], poses[:, :2])


# -- driving -----------------------------------------------------------------------------------


def test_ramped_distance_of_the_waffle():
    # 0.2 m/s for 5 s in 0.05 s substeps at 2.5 m/s^2: the first substep runs at 0.125 m/s,
    # the other 99 at 0.2 m/s: 0.125 * 0.05 + 99 * 0.2 * 0.05 = 0.99625 m.
    assert ramped_distance(0.2, 2.5, 0.05, 100) == pytest.approx(0.99625, abs=1e-12)


@pytest.mark.parametrize("name", ["turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd"])
@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, math.pi, -2.5])
def test_commanded_twist_moves_the_expected_distance(empty, robots, make_engine, name, yaw):
    robot = robots[name]
    engine = make_engine(empty, robot, [(1.0, -2.0, yaw)])
    events = drive(engine, 0.2, 0.0, 50)  # 5 s at 10 Hz
    dt = engine.config.control_period / engine.config.physics_substeps
    d = ramped_distance(0.2, robot.limits.acc_lim_x, dt, 100)
    assert abs(d - 1.0) < 0.2 * 0.2 / robot.limits.acc_lim_x  # the ramp costs < v^2 / a
    assert events == []
    assert engine.t == pytest.approx(5.0, abs=1e-12) and engine.ticks == 50
    np.testing.assert_allclose(engine.poses[0], [1.0 + d * math.cos(yaw),
                                                 -2.0 + d * math.sin(yaw), yaw], atol=1e-12)
    assert engine.distance[0] == pytest.approx(d, abs=1e-12)
    assert engine.v[0] == pytest.approx(0.2) and engine.w[0] == 0.0


def test_turning_on_the_spot(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 0.0)])
    drive(engine, 0.0, 0.5, 50)
    # 3.2 rad/s^2: 0.16, 0.32, 0.48 rad/s, then 0.5 rad/s: 2.5 - 0.05 * (0.34 + 0.18 + 0.02).
    np.testing.assert_allclose(engine.poses[0], [0.0, 0.0, 2.473], atol=1e-12)
    assert engine.distance[0] == 0.0


def test_acceleration_and_velocity_limits(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 0.0)])
    v_seen, w_seen = [], []
    for v_cmd, w_cmd in [(1.0, 9.0)] * 7 + [(-1.0, -9.0)] * 4:
        engine.step([v_cmd], [w_cmd])
        v_seen.append(engine.v[0])
        w_seen.append(engine.w[0])
    # 2.5 m/s^2 and 3.2 rad/s^2 over 0.1 s: at most 0.25 m/s and 0.32 rad/s per tick, capped at
    # 0.26 m/s and 1.82 rad/s.
    assert v_seen == pytest.approx([0.25, 0.26, 0.26, 0.26, 0.26, 0.26, 0.26,
                                    0.01, -0.24, -0.26, -0.26], abs=1e-12)
    assert w_seen == pytest.approx([0.32, 0.64, 0.96, 1.28, 1.6, 1.82, 1.82,
                                    1.5, 1.18, 0.86, 0.54], abs=1e-12)


@pytest.mark.parametrize("name", ["turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd"])
def test_random_commands_stay_inside_the_limits(empty, robots, make_engine, name):
    robot = robots[name]
    lim = robot.limits
    rng = np.random.default_rng(11)
    poses = [(x, y, 0.0) for x in (-4.0, 0.0, 4.0) for y in (-4.0, 0.0, 4.0)]
    engine = make_engine(empty, robot, poses)
    v_prev, w_prev = engine.v.copy(), engine.w.copy()
    period = engine.config.control_period
    for _ in range(40):
        engine.step(rng.uniform(-1.0, 1.0, 9), rng.uniform(-4.0, 4.0, 9))
        assert np.all(np.abs(engine.v - v_prev) <= lim.acc_lim_x * period + 1e-12)
        assert np.all(np.abs(engine.w - w_prev) <= lim.acc_lim_theta * period + 1e-12)
        assert np.all((engine.v >= lim.min_vel_x - 1e-12) & (engine.v <= lim.max_vel_x + 1e-12))
        assert np.all(np.abs(engine.w) <= lim.max_vel_theta + 1e-12)
        v_prev, w_prev = engine.v.copy(), engine.w.copy()


# -- robot-robot contacts ----------------------------------------------------------------------


def footprint_gap(engine, i, j) -> float:
    feet = engine.footprints()
    return float(polygon_distances(feet[i:i + 1], feet[j:j + 1])[0])


@pytest.mark.parametrize("poses, v, gap", [
    # head on: fronts 2 - 2 * 0.069 apart, closing at 0.4 m/s
    ([(-1.0, 0.0, 0.0), (1.0, 0.0, math.pi)], [0.2, 0.2], 2.0 - 2 * FRONT),
    # rear-end: robot 0 drives into the back of robot 1 standing 1 m ahead
    ([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], [0.2, 0.0], 1.0 - REAR - FRONT),
    # from the side: robot 0 drives up (+y) into the flank of robot 1
    ([(0.0, -1.0, math.pi / 2), (0.0, 0.0, 0.0)], [0.2, 0.0], 1.0 - FRONT - HALF_WIDTH),
])
def test_two_robots_bump_once_and_stop(empty, waffle, make_engine, poses, v, gap):
    engine = make_engine(empty, waffle, poses)
    # Gaps are tracked between robots within 2 radius + 1 m of each other.
    near = gap < 1.0
    assert engine.min_separation == (pytest.approx(gap, abs=1e-9) if near else math.inf)
    events = drive(engine, v, 0.0, 80)
    assert [(e.kind, e.robot, e.other) for e in events] == [("robot_robot", 0, 1)]
    np.testing.assert_array_equal(engine.collisions, [1, 1])
    assert engine.collision_counts == {"robot_robot": 1, "robot_wall": 0}
    # The bodies end up touching, closer than one substep's travel, not through each other.
    assert 0.0 <= footprint_gap(engine, 0, 1) < 0.2 * 0.05
    assert 0.0 <= engine.min_separation < 0.2 * 0.05
    # The episode starts in the substep whose pose penetrates: a robot driving at 0.2 m/s
    # covers 0.01 k - 0.00375 m in k substeps (the first at 0.125 m/s).
    movers = sum(1 for x in v if x)
    k = math.floor((gap + movers * 0.00375) / (movers * 0.01)) + 1
    assert events[0].t == pytest.approx(k * 0.05, abs=1e-9)
    # Keep pushing: the robots stay put, the episode goes on.
    before = engine.poses.copy()
    assert drive(engine, v, 0.0, 30) == []
    np.testing.assert_array_equal(engine.poses, before)
    np.testing.assert_array_equal(engine.collisions, [1, 1])


def test_head_on_contact_point_is_between_the_robots(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(-1.0, 0.0, 0.0), (1.0, 0.0, math.pi)])
    (event,) = drive(engine, [0.2, 0.2], 0.0, 60)
    assert abs(event.x) < 0.01
    assert abs(event.y) <= HALF_WIDTH + 1e-9
    assert engine.poses[0, 0] + FRONT <= engine.poses[1, 0] - FRONT  # not through each other


def test_backing_off_and_hitting_again_is_a_second_episode(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)])
    first = drive(engine, [0.2, 0.0], 0.0, 60)
    assert drive(engine, [-0.2, 0.0], 0.0, 5) == []  # ~0.1 m back: the episode ends
    assert footprint_gap(engine, 0, 1) > engine.config.contact_release
    second = drive(engine, [0.2, 0.0], 0.0, 20)
    assert len(first) == 1 and len(second) == 1
    np.testing.assert_array_equal(engine.collisions, [2, 2])
    assert engine.collision_counts["robot_robot"] == 2


def test_a_robot_put_back_never_ends_up_inside_its_follower(empty, waffle, make_engine):
    # B drives into A head on while C follows A 5 mm behind. When A is put back to its previous
    # pose, C (which moved on) must not be left overlapping it.
    a = (0.0, 0.0, 0.0)
    b = (FRONT + 0.015 + FRONT, 0.0, math.pi)
    c = (-REAR - 0.005 - FRONT, 0.0, 0.0)
    engine = make_engine(empty, waffle, [a, b, c])
    events = drive(engine, 0.2, 0.0, 5)
    assert {(e.robot, e.other) for e in events} == {(0, 1), (0, 2)}
    rear_of_a = engine.poses[0, 0] - REAR
    front_of_c = engine.poses[2, 0] + FRONT
    assert front_of_c <= rear_of_a + 1e-12
    assert engine.min_separation >= 0.0
    # C can back away freely.
    drive(engine, [0.0, 0.0, -0.2], 0.0, 10)
    assert engine.poses[2, 0] < c[0] - 0.1


# -- robot-wall contacts -----------------------------------------------------------------------


@pytest.mark.parametrize("pose, v, wall, face", [
    ((8.0, 3.0, 0.0), 0.2, "slim_blockage::right::collision", ("x", 9.375, FRONT)),
    ((8.8, 3.0, math.pi), -0.2, "slim_blockage::right::collision", ("x", 9.375, REAR)),
    ((2.0, 8.5, math.pi / 2), 0.2, "slim_blockage::top::collision", ("y", 9.376, FRONT)),
    ((-2.5, 2.0, math.pi), 0.26, "slim_blockage::blockage_right::collision",
     ("x", -3.762, FRONT)),
    ((6.0, -2.5, math.pi / 2), 0.2, "slim_blockage::pocket_horizontal::collision",
     ("y", -1.562, FRONT)),
])
def test_wall_contact_is_one_episode_until_backed_off(slim, waffle, make_engine, pose, v, wall,
                                                      face):
    engine = make_engine(slim, waffle, [pose])
    axis, plane, reach = face
    k = 0 if axis == "x" else 1
    events = drive(engine, v, 0.0, 150)
    assert [(e.kind, e.robot, e.other) for e in events] == [("robot_wall", 0, wall)]
    contact = (events[0].x, events[0].y)[k]
    assert contact == pytest.approx(plane, abs=0.01)
    # Stopped at the wall, not through it.
    edge = engine.poses[0, k] + math.copysign(reach, plane - engine.poses[0, k])
    assert abs(edge - plane) < 0.015
    assert abs(edge - pose[k]) <= abs(plane - pose[k]) + 1e-9
    # Keep pushing: still one.
    assert drive(engine, v, 0.0, 50) == []
    # Back off 0.2 m and hit again: two.
    assert drive(engine, -v, 0.0, 10) == []
    again = drive(engine, v, 0.0, 30)
    assert [(e.kind, e.other) for e in again] == [("robot_wall", wall)]
    assert engine.collisions[0] == 2
    assert engine.collision_counts == {"robot_robot": 0, "robot_wall": 2}


def test_min_separation_is_the_least_gap_seen(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, math.pi), (1.0, 0.0, math.pi)])
    assert engine.min_separation == pytest.approx(0.734, abs=1e-9)
    drive(engine, [0.0, 0.1], 0.0, 30)    # robot 1 closes in by 0.1 m/s * 3 s (no ramp loss)
    drive(engine, [0.0, 0.0], 0.0, 1)     # and stops within one substep
    assert footprint_gap(engine, 0, 1) == pytest.approx(0.434, abs=1e-9)
    drive(engine, [0.0, -0.1], 0.0, 20)   # backs away again
    assert footprint_gap(engine, 0, 1) > 0.6
    assert engine.min_separation == pytest.approx(0.434, abs=1e-9)


def test_min_separation_of_a_lone_robot_is_infinite(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 0.0)])
    drive(engine, 0.2, 0.3, 10)
    assert engine.min_separation == math.inf


# -- lidar -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name, period, every", [
    ("turtlebot3_waffle", 0.1, 2),    # 5 Hz lidar, 10 Hz control
    ("turtlebot3_waffle", 0.05, 4),   # 5 Hz lidar, 20 Hz control
    ("linorobot2_2wd", 0.1, 1),       # 10 Hz lidar, 10 Hz control
    ("linorobot2_2wd", 0.05, 2),
])
def test_lidar_due_cadence(empty, robots, make_engine, name, period, every):
    engine = make_engine(empty, robots[name], [(0.0, 0.0, 0.0)],
                         config=EngineConfig(control_period=period))
    assert engine.lidar_period_ticks == every
    due = []
    for _ in range(12):
        due.append(engine.lidar_due())
        engine.step([0.0], [0.0])
    assert due == [k % every == 0 for k in range(12)]


def test_engine_scans_see_the_other_robot_not_their_own_body(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], seed=3)
    scans = engine.scans()
    assert scans.shape == (2, 360) and scans.dtype == np.float32
    # Robot 0's lidar (x = -0.064) sees robot 1's rear (x = 0.803) straight ahead.
    assert scans[0, 0] == pytest.approx(0.867, abs=5 * waffle.lidar.noise_stddev)
    # The room's walls are 10 m away, beyond range_max: everything else is +inf.
    assert np.isfinite(scans[0]).sum() < 40
    assert np.isinf(scans[1, 0]) and np.isfinite(scans[1, 180])
    assert not np.any(scans < 0.5)  # neither lidar sees its own body


def test_lone_robot_scan_is_all_no_return(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 1.0)])
    assert np.all(engine.scans() == np.inf)


# -- determinism -------------------------------------------------------------------------------


def run(world, robot, make_engine, seed: int, ticks: int = 100):
    poses = spawn_poses(poi_for_world(world.source).spawn, 12, robot.radius,
                        world_polygons(world))
    poses[1, :2] = [0.55, 0.0]  # close enough to robot 0 to bump into it
    engine = make_engine(world, robot, poses, seed=seed)
    i = np.arange(engine.n)
    scans, events = [], []
    for k in range(ticks):
        if engine.lidar_due():
            scans.append(engine.scans())
        events += engine.step(0.26 * np.sin(0.1 * k + i), 1.5 * np.cos(0.07 * k + 2 * i))
    return engine, np.array(scans), events


def test_same_seed_same_run(slim, waffle, make_engine):
    a, scans_a, events_a = run(slim, waffle, make_engine, seed=7)
    b, scans_b, events_b = run(slim, waffle, make_engine, seed=7)
    c, scans_c, events_c = run(slim, waffle, make_engine, seed=8)
    assert scans_a.shape == (50, 12, 360)
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(scans_a, scans_b)
    np.testing.assert_array_equal(a.distance, b.distance)
    assert events_a == events_b and len(events_a) >= 1
    assert a.min_separation == b.min_separation
    # The seed only drives the lidar noise: same motion, different noise.
    np.testing.assert_array_equal(a.poses, c.poses)
    assert events_a == events_c
    finite = np.isfinite(scans_a) & np.isfinite(scans_c)
    assert np.mean(scans_a[finite] != scans_c[finite]) > 0.99


def test_close_is_idempotent(empty, waffle):
    engine = SimEngine(empty, waffle, np.zeros((1, 3)))
    engine.close()
    engine.close()
    assert engine.client is None


# -- held robots (faults: freeze, a dead robot) --------------------------------------------------


def test_a_held_robot_stops_at_once_stays_put_and_is_still_seen(empty, waffle, make_engine):
    engine = make_engine(empty, waffle, [(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], seed=1)
    v = np.array([0.2, 0.0])
    w = np.array([0.5, 0.0])
    drive(engine, v, w, 20)
    assert engine.v[0] > 0.1
    held = np.array([True, False])
    where = engine.poses[0].copy()
    travelled = engine.distance[0]
    for _ in range(30):
        engine.step(v, w, held)
        assert engine.v[0] == 0.0 and engine.w[0] == 0.0  # at once, whatever commanded
    assert np.array_equal(engine.poses[0], where) and engine.distance[0] == travelled
    # Its body stays in the world: the other robot's lidar sees it, and bumps into it.
    x0, y0 = where[:2]
    bearing = math.atan2(y0 - 0.0, x0 - (3.0 + 0.064))  # robot 1's lidar, facing -x
    beam = round((bearing - math.pi) % (2 * math.pi) / (2 * math.pi / 360)) % 360
    assert engine.scans()[1, beam] < 3.2
    events = drive(engine, [0.0, 0.26], [0.0, 0.0], 200)
    assert any(e.kind == "robot_robot" for e in events)
    assert np.array_equal(engine.poses[0], where)
    # Released, it drives again.
    drive(engine, [-0.2, 0.0], [0.0, 0.0], 5)
    assert engine.v[0] < 0.0 and engine.poses[0, 0] < where[0]


def test_footprints_equal_transforming_each_robots_footprint_bit_for_bit(slim, waffle,
                                                                          make_engine):
    """All robots' footprints at once are what ``transform_points`` gives robot by robot (the
    lidar and the minimum separation see exactly the bodies they saw before)."""
    from swarm_common.geometry import transform_points
    from swarm_sim.lidar import counter_clockwise

    engine = make_engine(slim, waffle, [[0.0, 0.0, math.pi], [1.0, 0.0, 3.1], [2.0, 1.0, -2.9]])
    rng = np.random.default_rng(3)
    poses = np.column_stack((rng.uniform(-8, 9, 200), rng.uniform(-4, 9, 200),
                             rng.uniform(-4.0, 4.0, 200)))
    want = np.stack([transform_points(p, counter_clockwise(waffle.footprint)) for p in poses])
    np.testing.assert_array_equal(engine.footprints(poses), want)
    assert engine.footprints().shape == (3, len(waffle.footprint), 2)


def ref_polygon_distances(a, b):
    """``polygon_distances`` as it was in numpy before it was compiled (commit 3de94e0)."""
    def vert_edge(v, poly):
        p0 = poly
        e = np.roll(poly, -1, axis=1) - p0  # (P, K, 2)
        rel = v[:, :, None, :] - p0[:, None, :, :]  # (P, Kv, K, 2)
        len2 = np.maximum(np.einsum("pki,pki->pk", e, e), 1e-18)[:, None, :]
        u = np.clip(np.einsum("pvki,pki->pvk", rel, e) / len2, 0.0, 1.0)
        d = np.linalg.norm(rel - u[..., None] * e[:, None, :, :], axis=-1)
        cross = e[:, None, :, 0] * rel[..., 1] - e[:, None, :, 1] * rel[..., 0]
        inside = np.all(cross > 0, axis=2) | np.all(cross < 0, axis=2)  # (P, Kv)
        return d.min(axis=(1, 2)), inside.any(axis=1)

    dab, ia = vert_edge(a, b)
    dba, ib = vert_edge(b, a)
    return np.where(ia | ib, 0.0, np.minimum(dab, dba))


def test_compiled_polygon_distances_equal_the_numpy_ones():
    """:func:`polygon_distances` (compiled, the engine's per-tick minimum separation) against
    the numpy code it replaced: random boxes apart, touching and overlapping (0), every pair
    equal to the last bit."""
    rng = np.random.default_rng(11)
    box = np.array([[-0.197, -0.133], [0.069, -0.133], [0.069, 0.133], [-0.197, 0.133]])
    overlaps = 0
    for _ in range(200):
        n = int(rng.integers(2, 9))
        poses = np.column_stack((rng.uniform(-0.8, 0.8, (n, 2)), rng.uniform(-4, 4, n)))
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        feet = np.stack([box @ np.array([[ci, si], [-si, ci]]) + p[:2]
                         for ci, si, p in zip(c, s, poses, strict=True)])
        ii, jj = np.nonzero(np.triu(np.ones((n, n), dtype=bool), k=1))
        want = ref_polygon_distances(feet[ii], feet[jj])
        np.testing.assert_array_equal(polygon_distances(feet[ii], feet[jj]), want)
        overlaps += int((want == 0.0).sum())
    assert overlaps > 0
    assert polygon_distances(np.stack((box,)), np.stack((box + 0.05,))).tolist() == [0.0]
    assert polygon_distances(np.zeros((0, 4, 2)), np.zeros((0, 4, 2))).shape == (0,)
