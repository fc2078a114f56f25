"""The planar lidar: exact ranges, agreement with PyBullet's rayTestBatch and with brute force,
REP 117 readings, robots seeing each other (never themselves), seeded noise."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pybullet
import pytest

from swarm_common.geometry import transform_points
from swarm_scene.poi import poi_for_world
from swarm_scene.robot_model import load_robot
from swarm_scene.spawn import spawn_poses
from swarm_scene.world import load_world, world_polygons
from swarm_sim.lidar import (
    PlanarLidar,
    ScanPattern,
    cast_rays,
    counter_clockwise,
    polygons_to_segments,
)

# shared/reference/seed_facts.md, slim_blockage's wall table as boxes xmin, xmax, ymin, ymax [m]
# (walls 0.15 m thick): written out here so the lidar is checked against the source, not the
# loader.
SLIM_WALLS = np.array([
    [-8.475, 9.525, -4.974, -4.824],   # bottom, inner face y = -4.824
    [-8.475, 9.525, 9.376, 9.526],     # top, inner face y = 9.376
    [-8.475, -8.325, -4.974, 9.526],   # left, inner face x = -8.325
    [9.375, 9.525, -4.974, 9.526],     # right, inner face x = 9.375
    [-5.262, -5.112, -3.016, 7.484],   # blockage, left side
    [-3.912, -3.762, -3.016, 7.484],   # blockage, right side
    [-5.262, -3.762, -3.016, -2.866],  # blockage, bottom
    [-5.262, -3.762, 7.334, 7.484],    # blockage, top
    [3.909, 4.059, -4.912, -1.412],    # pocket, vertical
    [3.909, 9.409, -1.562, -1.412],    # pocket, horizontal
])
LDS01_RESOLUTION = 0.015  # [m] range resolution of the TurtleBot3's LDS-01


@pytest.fixture(scope="module")
def slim():
    return load_world("slim_blockage")


@pytest.fixture(scope="module")
def waffle():
    return load_robot("turtlebot3_waffle")


@pytest.fixture(scope="module")
def robots():
    return {name: load_robot(name)
            for name in ("turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd")}


def noiseless(pattern: ScanPattern) -> ScanPattern:
    return ScanPattern(pattern.angles, pattern.range_min, pattern.range_max, 0.0)


def static_lidar(world, robot, pattern: ScanPattern | None = None) -> PlanarLidar:
    z = robot.lidar.z
    segs = polygons_to_segments(world_polygons(world, z - 1e-3, z + 1e-3))
    return PlanarLidar(segs, pattern or ScanPattern.from_spec(robot.lidar))


def ray_box_ranges(origin, angles, boxes) -> np.ndarray:
    """(B,) distance along rays from ``origin`` to the nearest axis-aligned box (slab method),
    written independently of the caster; ``inf`` where a ray hits no box."""
    d = np.column_stack((np.cos(angles), np.sin(angles)))
    best = np.full(len(angles), np.inf)
    for x0, x1, y0, y1 in np.atleast_2d(boxes):
        near, far = np.full(len(angles), -np.inf), np.full(len(angles), np.inf)
        for axis, lo, hi in ((0, x0, x1), (1, y0, y1)):
            o, da = origin[axis], d[:, axis]
            with np.errstate(divide="ignore", invalid="ignore"):
                ta, tb = (lo - o) / da, (hi - o) / da
            inside = (lo < o) & (o < hi)  # a ray parallel to the slab: always in, or never
            ta = np.where(da == 0.0, np.where(inside, -np.inf, np.inf), ta)
            tb = np.where(da == 0.0, np.inf, tb)
            near = np.maximum(near, np.minimum(ta, tb))
            far = np.minimum(far, np.maximum(ta, tb))
        hit = (near <= far) & (near >= 0.0)
        best = np.where(hit, np.minimum(best, near), best)
    return best


def mount(robot, poses) -> np.ndarray:
    """(N, 3) lidar poses in ``map`` of robots at ``poses``."""
    m = robot.lidar.pose
    poses = np.atleast_2d(poses)
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    return np.column_stack((poses[:, 0] + c * m[0] - s * m[1], poses[:, 1] + s * m[0] + c * m[1],
                            poses[:, 2] + m[2]))


def feet(robot, poses) -> np.ndarray:
    fp = counter_clockwise(robot.footprint)
    return np.stack([transform_points(p, fp) for p in np.atleast_2d(poses)])


def aabb(poly) -> np.ndarray:
    return np.array([poly[:, 0].min(), poly[:, 0].max(), poly[:, 1].min(), poly[:, 1].max()])


def box_clearance(xy, boxes) -> float:
    """Distance [m] from a point to the nearest of some axis-aligned boxes."""
    dx = np.maximum(np.maximum(boxes[:, 0] - xy[0], xy[0] - boxes[:, 1]), 0.0)
    dy = np.maximum(np.maximum(boxes[:, 2] - xy[1], xy[1] - boxes[:, 3]), 0.0)
    return float(np.hypot(dx, dy).min())


def random_poses(rng, n, region, radius, walls=SLIM_WALLS) -> np.ndarray:
    """``n`` poses with uniform yaw in ``region`` (xmin, ymin, xmax, ymax) whose circles of
    ``radius`` overlap neither the walls nor each other."""
    out: list[np.ndarray] = []
    while len(out) < n:
        p = rng.uniform([region[0], region[1], -math.pi], [region[2], region[3], math.pi])
        if box_clearance(p[:2], walls) <= radius + 0.01:
            continue
        if any(math.hypot(*(p[:2] - q[:2])) <= 2 * radius + 0.01 for q in out):
            continue
        out.append(p)
    return np.array(out)


# -- the loaded world is the wall table --------------------------------------------------------


def test_slim_blockage_boxes_are_the_wall_table(slim):
    got = np.array([[s.pose[0] - s.size[0] / 2, s.pose[0] + s.size[0] / 2,
                     s.pose[1] - s.size[1] / 2, s.pose[1] + s.size[1] / 2] for s in slim.shapes])
    assert all(s.kind == "box" and s.pose[5] == 0.0 for s in slim.shapes)
    np.testing.assert_allclose(got, SLIM_WALLS, atol=1e-9)


# -- (1) ranges to walls against the analytic distance, Gazebo's angle convention --------------


@pytest.mark.parametrize("name, amin, amax, samples", [
    ("turtlebot3_waffle", 0.0, 6.28319, 360),
    ("turtlebot3_burger", 0.0, 6.28319, 360),
    ("linorobot2_2wd", -math.pi, math.pi, 360),
])
def test_beam_angles_are_angle_min_to_angle_max_inclusive(robots, name, amin, amax, samples):
    pattern = ScanPattern.from_spec(robots[name].lidar)
    assert pattern.angles.shape == (samples,)
    assert pattern.angles[0] == amin
    assert pattern.angles[-1] == pytest.approx(amax, abs=1e-12)
    assert pattern.angle_increment == pytest.approx((amax - amin) / (samples - 1), abs=1e-15)
    np.testing.assert_allclose(np.diff(pattern.angles), pattern.angle_increment, atol=1e-12)


def test_single_beam_pattern(waffle):
    spec = waffle.lidar
    one = ScanPattern.from_spec(dataclasses.replace(spec, samples=1))
    np.testing.assert_array_equal(one.angles, [spec.angle_min])
    assert one.angle_increment == 0.0


@pytest.mark.parametrize("lidar_pose, beam0", [
    ((7.0, 3.0, 0.0), 9.375 - 7.0),                 # facing the right wall
    ((6.0, 7.5, math.pi / 2), 9.376 - 7.5),         # facing the top wall
    ((-7.0, 0.0, math.pi), -7.0 + 8.325),           # facing the left wall
    ((0.0, -3.0, -math.pi / 2), -3.0 + 4.824),      # facing the bottom wall
    ((-4.512, 8.4, -math.pi / 2), 8.4 - 7.484),     # facing the top of the blockage
    ((6.0, -3.0, 0.0), 9.375 - 6.0),                # inside the closed pocket, facing right
    ((6.0, -3.0, math.pi), 6.0 - 4.059),            # ... facing the pocket's vertical wall
    ((-2.5, 2.0, math.pi), -2.5 + 3.762),           # facing the blockage's right side
    ((8.2, 8.1, math.pi / 4), (9.375 - 8.2) * math.sqrt(2)),  # into the top-right corner
])
def test_ranges_to_walls_are_exact(slim, waffle, lidar_pose, beam0):
    lidar = static_lidar(slim, waffle, noiseless(ScanPattern.from_spec(waffle.lidar)))
    pose = np.array(lidar_pose)
    got = lidar.true_ranges(pose[None], np.zeros((1, 4, 2)))[0]
    assert got[0] == pytest.approx(beam0, abs=1e-9)
    # Every beam: the slab-method distance to the wall table, inf beyond range_max.
    want = ray_box_ranges(pose[:2], pose[2] + lidar.pattern.angles, SLIM_WALLS)
    want[want > lidar.pattern.range_max] = np.inf
    got[got > lidar.pattern.range_max] = np.inf
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(got)], want[np.isfinite(want)], atol=1e-9)
    assert np.isfinite(got).sum() >= 60  # the pose is within range of a wall


# -- (2) agreement with PyBullet's rayTestBatch ------------------------------------------------


@pytest.fixture
def bullet():
    cid = pybullet.connect(pybullet.DIRECT)
    yield cid
    pybullet.disconnect(cid)


def bullet_ranges(cid, world, robot, poses) -> tuple[np.ndarray, np.ndarray]:
    """(N, B) ranges [m] of every robot's beams cast with ``rayTestBatch`` in a PyBullet world
    built here from the world's boxes and a box per robot, ``inf`` where nothing is hit; and the
    (N, B) mask of the beams that hit a robot."""
    p = pybullet
    for s in world.shapes:
        assert s.kind == "box"
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[v / 2 for v in s.size],
                                     physicsClientId=cid)
        p.createMultiBody(0.0, col, basePosition=list(s.pose[:3]),
                          baseOrientation=p.getQuaternionFromEuler(list(s.pose[3:])),
                          physicsClientId=cid)
    fp = counter_clockwise(robot.footprint)
    lo, hi = fp.min(axis=0), fp.max(axis=0)
    height = robot.lidar.z + 0.05  # the body crosses the scan plane
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[*((hi - lo) / 2), height / 2],
                                 collisionFramePosition=[*((hi + lo) / 2), height / 2],
                                 physicsClientId=cid)

    def place(body, pose):
        p.resetBasePositionAndOrientation(body, [pose[0], pose[1], 0.0],
                                          p.getQuaternionFromEuler([0.0, 0.0, pose[2]]),
                                          physicsClientId=cid)

    bodies = [p.createMultiBody(0.0, col, physicsClientId=cid) for _ in poses]
    for body, pose in zip(bodies, poses, strict=True):
        place(body, pose)
    spec = robot.lidar
    angles = ScanPattern.from_spec(spec).angles
    out, on_robot = [], []
    for i, (x, y, yaw) in enumerate(mount(robot, poses)):
        place(bodies[i], (1e3, 1e3, 0.0))  # a lidar does not see its own body
        a = yaw + angles
        ends = np.column_stack((x + spec.range_max * np.cos(a), y + spec.range_max * np.sin(a),
                                np.full(a.size, spec.z)))
        hits = p.rayTestBatch([[x, y, spec.z]] * a.size, ends.tolist(), physicsClientId=cid)
        out.append([h[2] * spec.range_max if h[0] >= 0 else np.inf for h in hits])
        on_robot.append([h[0] in bodies for h in hits])
        place(bodies[i], poses[i])
    return np.array(out), np.array(on_robot)


def grazing(origin, angles, polygons, reach, eps) -> np.ndarray:
    """(B,) mask of beams passing within ``eps`` of a polygon vertex before ``reach``: there the
    hit is ill-conditioned (0.4 mm sideways moves a hit along a face seen edge-on by
    centimetres) and two correct casters may differ."""
    verts = np.vstack(polygons) - origin
    d = np.column_stack((np.cos(angles), np.sin(angles)))
    along = d @ verts.T
    across = np.abs(d[:, 0:1] * verts[:, 1] - d[:, 1:2] * verts[:, 0])
    return np.any((across < eps) & (along > 0.0) & (along < reach + eps), axis=1)


@pytest.mark.parametrize("name", ["turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd"])
@pytest.mark.parametrize("seed, region", [
    (0, (5.0, 4.0, 9.3, 9.3)),      # top-right corner, robots among walls
    (1, (-8.3, -4.8, -5.1, 1.0)),   # the loaders' corridor
    (2, (4.1, -4.8, 9.3, -1.6)),    # the closed pocket
    (3, (-3.7, -1.5, 1.0, 3.0)),    # beside the blockage
])
def test_agrees_with_pybullet_raytestbatch(slim, robots, bullet, name, seed, region):
    robot = robots[name]
    spec = robot.lidar
    poses = random_poses(np.random.default_rng(seed), 8, region, robot.radius)
    lidar = static_lidar(slim, robot)
    ours = lidar.true_ranges(mount(robot, poses), feet(robot, poses))
    ours[ours > spec.range_max] = np.inf
    theirs, on_robot = bullet_ranges(bullet, slim, robot, poses)
    angles = lidar.pattern.angles
    outlines = world_polygons(slim)
    compared = 0
    for i, (x, y, yaw) in enumerate(mount(robot, poses)):
        others = [f for j, f in enumerate(feet(robot, poses)) if j != i]
        ok = ~grazing(np.array([x, y]), yaw + angles, outlines + others, spec.range_max, 2e-3)
        assert ok.mean() > 0.97  # only a few beams graze a corner
        hit = np.isfinite(theirs[i]) & ok
        # Same beams hit within range_max, at the same range to within the LDS-01's resolution.
        np.testing.assert_array_equal(np.isfinite(ours[i][ok]), np.isfinite(theirs[i][ok]))
        np.testing.assert_allclose(ours[i][hit], theirs[i][hit], rtol=0.0,
                                   atol=LDS01_RESOLUTION)
        compared += hit.sum()
    assert compared >= 8 * 50  # the scenes do put things within range ...
    assert on_robot.sum() >= 20  # ... robots among them


# -- (3) the culled caster equals brute force --------------------------------------------------


PATTERNS = {
    "turtlebot3_0_to_2pi": ScanPattern(np.linspace(0.0, 6.28319, 360), 0.12, 3.5, 0.0),
    "linorobot2_-pi_to_pi": ScanPattern(np.linspace(-math.pi, math.pi, 360), 0.08, 12.0, 0.0),
    "partial_-1_to_1": ScanPattern(np.linspace(-1.0, 1.0, 50), 0.12, 3.5, 0.0),
    "partial_backwards": ScanPattern(np.linspace(2.0, 4.5, 91), 0.1, 6.0, 0.0),
}


def brute_force(lidar: PlanarLidar, lidar_poses, bodies) -> np.ndarray:
    out = []
    for i, (x, y, yaw) in enumerate(lidar_poses):
        others = polygons_to_segments([b for j, b in enumerate(bodies) if j != i])
        segs = np.vstack((lidar.static_segments, others))
        a = yaw + lidar.pattern.angles
        out.append(cast_rays(np.array([x, y]), np.column_stack((np.cos(a), np.sin(a))), segs))
    return np.array(out)


def scene(slim, waffle, kind: str, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if kind == "grid":  # the 1 m spawn grid, full: 120 robots, random headings
        poses = spawn_poses(poi_for_world(slim.source).spawn, 120, waffle.radius,
                            world_polygons(slim))
        poses[:, 2] = rng.uniform(-math.pi, math.pi, len(poses))
        return poses
    if kind == "random":
        return random_poses(rng, 40, (-8.3, -4.8, 9.3, 9.3), waffle.radius)
    return random_poses(rng, 25, (5.5, 0.0, 9.3, 3.5), waffle.radius)  # a crowd


@pytest.mark.parametrize("pattern", PATTERNS.values(), ids=PATTERNS.keys())
@pytest.mark.parametrize("kind, seed", [("grid", 0), ("random", 2), ("random", 3), ("crowd", 4),
                                        ("crowd", 5)])
def test_culled_caster_equals_brute_force(slim, waffle, pattern, kind, seed):
    poses = scene(slim, waffle, kind, seed)
    lidar = static_lidar(slim, waffle, pattern)
    lidar_poses, bodies = mount(waffle, poses), feet(waffle, poses)
    got = lidar.true_ranges(lidar_poses, bodies)
    want = brute_force(lidar, lidar_poses, bodies)
    reach = pattern.range_max
    got[got > reach] = np.inf
    want[want > reach] = np.inf
    assert got.shape == (len(poses), pattern.angles.size)
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(got)], want[np.isfinite(want)], rtol=0.0,
                               atol=1e-9)
    assert np.isfinite(got).mean() > 0.1


@pytest.mark.parametrize("pattern", PATTERNS.values(), ids=PATTERNS.keys())
def test_culled_caster_with_corners_exactly_on_beams(pattern):
    # Box corners on beam bearings, including the first beam and, for 0..6.28319, the last one
    # (which lies 4.7e-6 rad past 2 pi): the angular culling must not drop them.
    # From (0, -3) the box below y = -3 shows only its left face, whose arc ends on beam 0.
    boxes = [np.array([[1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0]]),
             np.array([[-1.5, -2.0], [-1.0, -2.0], [-1.0, -1.0], [-1.5, -1.0]]),
             np.array([[0.5, -1.5], [1.5, -1.5], [1.5, -0.5], [0.5, -0.5]]),
             np.array([[1.0, -4.0], [2.0, -4.0], [2.0, -3.0], [1.0, -3.0]])]
    lidar = PlanarLidar(polygons_to_segments(boxes), pattern)
    lidar_poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -pattern.angles[0]],
                            [0.0, 0.0, math.pi / 2], [0.0, -1.0, pattern.angles[3]],
                            [0.0, -3.0, -pattern.angles[0]]])
    bodies = np.stack([np.array([[9.0, 9.0], [9.1, 9.0], [9.1, 9.1], [9.0, 9.1]])] * 5)
    got = lidar.true_ranges(lidar_poses, bodies)
    want = brute_force(lidar, lidar_poses, bodies)
    got[got > pattern.range_max] = np.inf
    want[want > pattern.range_max] = np.inf  # e.g. the far robot bodies
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(got)], want[np.isfinite(want)], atol=1e-9)


def test_last_turtlebot3_beam_past_two_pi_sees_the_wall():
    # Beam 359 of 0..6.28319 points 4.7e-6 rad above +x: from (0, 0) it meets the face x = 1
    # of a box whose corner lies on beam 0.
    pattern = PATTERNS["turtlebot3_0_to_2pi"]
    box = np.array([[1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0]])
    got = PlanarLidar(polygons_to_segments([box]), pattern).true_ranges(
        np.zeros((1, 3)), np.zeros((1, 4, 2)))[0]
    assert got[0] == pytest.approx(1.0, abs=1e-12)
    assert got[359] == pytest.approx(1.0 / math.cos(6.28319 - 2 * math.pi), abs=1e-12)
    assert math.isinf(got[358])  # 358 points just below +x, past the corner


# -- (4) REP 117 -------------------------------------------------------------------------------


@pytest.mark.parametrize("distance, reading", [
    (0.05, -math.inf),   # closer than range_min 0.12
    (0.119, -math.inf),
    (0.12, 0.12),
    (0.5, 0.5),
    (3.5, 3.5),
    (3.501, math.inf),   # beyond range_max 3.5
    (8.0, math.inf),
])
def test_rep117_invalid_readings(waffle, distance, reading):
    pattern = noiseless(ScanPattern.from_spec(waffle.lidar))
    wall = np.array([[distance, -5.0], [distance + 0.15, -5.0], [distance + 0.15, 5.0],
                     [distance, 5.0]])
    lidar = PlanarLidar(polygons_to_segments([wall]), pattern)
    scan = lidar.scan(np.zeros((1, 3)), np.zeros((1, 4, 2)), np.random.default_rng(0))[0]
    assert scan.dtype == np.float32
    if math.isfinite(reading):
        assert scan[0] == pytest.approx(reading, rel=1e-6)
    else:
        assert scan[0] == reading
    assert np.all(scan[170:190] == np.inf)  # facing away from the wall: nothing within range


def test_rep117_with_noise_keeps_in_range_readings_finite(slim, waffle):
    lidar = static_lidar(slim, waffle)  # noise 0.01 m
    poses = np.array([[7.0, 3.0, 0.0], [0.0, -3.0, -math.pi / 2]])
    scan = lidar.scan(poses, np.zeros((2, 4, 2)), np.random.default_rng(5))
    true = lidar.true_ranges(poses, np.zeros((2, 4, 2)))
    mid = (true > 0.3) & (true < 3.3)
    assert np.all(np.isfinite(scan[mid]))
    assert np.all(np.abs(scan[mid] - true[mid]) < 0.06)  # 6 sigma
    assert np.all(scan[true > 3.6] == np.inf)
    assert not np.any(np.isnan(scan))


# -- (5) robots see each other, never themselves -----------------------------------------------


def test_a_lone_robot_does_not_see_its_own_body(waffle):
    lidar = PlanarLidar(np.zeros((0, 4)), noiseless(ScanPattern.from_spec(waffle.lidar)))
    pose = np.array([[0.0, 0.0, 0.4]])
    got = lidar.true_ranges(mount(waffle, pose), feet(waffle, pose))
    assert np.all(np.isinf(got))
    scan = lidar.scan(mount(waffle, pose), feet(waffle, pose), np.random.default_rng(0))
    assert np.all(scan == np.inf)


@pytest.mark.parametrize("poses", [
    [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)],                       # one behind the other
    [(0.0, 0.0, 0.0), (1.0, 0.0, math.pi)],                   # face to face
    [(0.0, 0.0, math.pi), (0.0, 1.5, math.pi / 2), (-1.2, 0.0, 0.0), (0.0, -0.8, -math.pi / 2),
     (1.0, 0.0, math.pi)],                                    # a ring around robot 0
    [(0.0, 0.0, math.pi / 2), (0.6, 0.0, 0.0), (1.2, 0.0, 0.0), (1.8, 0.0, 0.0)],  # a row
])
def test_robots_see_each_other(waffle, poses):
    poses = np.array(poses)
    lidar = PlanarLidar(np.zeros((0, 4)), noiseless(ScanPattern.from_spec(waffle.lidar)))
    lp, bodies = mount(waffle, poses), feet(waffle, poses)
    got = lidar.true_ranges(lp, bodies)
    for i in range(len(poses)):
        boxes = [aabb(b) for j, b in enumerate(bodies) if j != i]  # headings are axis-aligned
        want = ray_box_ranges(lp[i, :2], lp[i, 2] + lidar.pattern.angles, boxes)
        np.testing.assert_array_equal(np.isinf(got[i]), np.isinf(want))
        np.testing.assert_allclose(got[i][np.isfinite(got[i])], want[np.isfinite(want)],
                                   atol=1e-9)
        assert np.isfinite(got[i]).sum() >= 5  # every robot sees a neighbour


def test_robot_behind_sees_the_rear_of_the_one_ahead(waffle):
    # Waffle footprint x in [-0.197, 0.069], lidar at x = -0.064: from (0, 0) the rear face of
    # the robot at (1, 0) is 1 - 0.197 + 0.064 = 0.867 m straight ahead; looking back, that
    # robot sees the front face of the first one at 0.936 - 0.069 = 0.867 m too.
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    lidar = PlanarLidar(np.zeros((0, 4)), noiseless(ScanPattern.from_spec(waffle.lidar)))
    got = lidar.true_ranges(mount(waffle, poses), feet(waffle, poses))
    assert got[0, 0] == pytest.approx(0.867, abs=1e-9)
    back = lidar.pattern.angles[180]
    assert got[1, 180] == pytest.approx(0.867 / abs(math.cos(back)), abs=1e-9)
    assert np.isinf(got[0, 180]) and np.isinf(got[1, 0])


# -- (6) seeded noise --------------------------------------------------------------------------


def test_same_seed_same_noisy_scan(slim, waffle):
    lidar = static_lidar(slim, waffle)
    poses = scene(slim, waffle, "grid", 0)[:30]
    lp, bodies = mount(waffle, poses), feet(waffle, poses)
    a = lidar.scan(lp, bodies, np.random.default_rng(42))
    b = lidar.scan(lp, bodies, np.random.default_rng(42))
    c = lidar.scan(lp, bodies, np.random.default_rng(43))
    np.testing.assert_array_equal(a, b)
    finite = np.isfinite(a) & np.isfinite(c)
    assert finite.sum() > 1000
    assert np.mean(a[finite] != c[finite]) > 0.99


def test_noise_is_gaussian_with_the_spec_stddev(slim, waffle):
    lidar = static_lidar(slim, waffle)
    poses = scene(slim, waffle, "grid", 1)
    lp, bodies = mount(waffle, poses), feet(waffle, poses)
    true = lidar.true_ranges(lp, bodies)
    scan = lidar.scan(lp, bodies, np.random.default_rng(9)).astype(float)
    mid = (true > 0.5) & (true < 3.0)
    err = scan[mid] - true[mid]
    n = err.size
    assert n > 5000
    sigma = waffle.lidar.noise_stddev
    assert sigma == 0.01
    assert abs(err.mean()) < 4 * sigma / math.sqrt(n)
    assert err.std() == pytest.approx(sigma, rel=0.05)


# -- (4) the compiled loop equals the numpy code it replaced, bit for bit ----------------------


def numpy_true_ranges(lidar: PlanarLidar, lidar_poses: np.ndarray, bodies: np.ndarray
                      ) -> np.ndarray:
    """A frozen copy of ``PlanarLidar.true_ranges`` as it was in numpy (before
    ``swarm_sim.lidar_kernels``): the reference the kernel must equal to the last bit."""
    from swarm_sim.lidar import _point_segment_distance

    n = lidar_poses.shape[0]
    n_beams = lidar.pattern.angles.size
    reach = lidar.pattern.range_max
    origins = lidar_poses[:, :2]
    pair_lidar, pair_segs = [np.zeros(0, dtype=int)], [np.zeros((0, 4))]
    if lidar.static_segments.shape[0]:
        li, si = np.nonzero(_point_segment_distance(origins, lidar.static_segments) <= reach)
        pair_lidar.append(li)
        pair_segs.append(lidar.static_segments[si])
    bodies = np.asarray(bodies, dtype=float).reshape(n, -1, 2)
    if n > 1:
        k = bodies.shape[1]
        body_segs = np.concatenate((bodies, np.roll(bodies, -1, axis=1)), axis=2)
        centres = bodies.mean(axis=1)
        radius = np.linalg.norm(bodies - centres[:, None, :], axis=2).max(axis=1)
        dist = np.linalg.norm(origins[:, None, :] - centres[None, :, :], axis=2)
        near = dist <= reach + radius[None, :]
        np.fill_diagonal(near, False)
        li, bj = np.nonzero(near)
        pair_lidar.append(np.repeat(li, k))
        pair_segs.append(body_segs[bj].reshape(-1, 4))
    lid, segs = np.concatenate(pair_lidar), np.concatenate(pair_segs)
    ex, ey = segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1]
    facing = ey * (segs[:, 0] - origins[lid, 0]) - ex * (segs[:, 1] - origins[lid, 1]) < 0.0
    lid, segs = lid[facing], segs[facing]
    out = np.full(n * n_beams, np.inf)
    if lid.size == 0:
        return out.reshape(n, n_beams)
    amin = float(lidar.pattern.angles[0])
    inc = lidar.pattern.angle_increment or 2.0 * np.pi
    o = lidar_poses[lid, :2]
    a0 = np.arctan2(segs[:, 1] - o[:, 1], segs[:, 0] - o[:, 0]) - lidar_poses[lid, 2]
    a1 = np.arctan2(segs[:, 3] - o[:, 1], segs[:, 2] - o[:, 0]) - lidar_poses[lid, 2]
    sweep = np.mod(a1 - a0 + np.pi, 2.0 * np.pi) - np.pi
    lo = np.mod(np.minimum(a0, a0 + sweep) - amin, 2.0 * np.pi) - 1e-9
    hi = lo + np.abs(sweep) + 2e-9
    starts, stops, owners = [], [], []
    for shift in (-2.0 * np.pi, 0.0, 2.0 * np.pi):
        k0 = np.maximum(np.ceil((lo - shift) / inc), 0).astype(int)
        k1 = np.minimum(np.floor((hi - shift) / inc), n_beams - 1).astype(int)
        ok = k1 >= k0
        starts.append(k0[ok])
        stops.append(k1[ok] + 1)
        owners.append(np.flatnonzero(ok))
    k0 = np.concatenate(starts)
    counts = np.concatenate(stops) - k0
    owner = np.concatenate(owners)
    pair = np.repeat(owner, counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    beam_k = np.repeat(k0, counts) + (np.arange(pair.size) - first)
    beam_lidar, beam_seg = lid[pair], pair
    yaw = lidar_poses[beam_lidar, 2]
    ca, sa = np.cos(lidar.pattern.angles)[beam_k], np.sin(lidar.pattern.angles)[beam_k]
    cy, sy = np.cos(yaw), np.sin(yaw)
    dx, dy = cy * ca - sy * sa, sy * ca + cy * sa
    seg = segs[beam_seg]
    px = seg[:, 0] - origins[beam_lidar, 0]
    py = seg[:, 1] - origins[beam_lidar, 1]
    ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (px * ey - py * ex) / denom
        u = (px * dy - py * dx) / denom
    hit = (np.abs(denom) > 1e-12) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
    np.minimum.at(out, beam_lidar[hit] * n_beams + beam_k[hit], t[hit])
    return out.reshape(n, n_beams)


@pytest.mark.parametrize("pattern", PATTERNS.values(), ids=PATTERNS.keys())
@pytest.mark.parametrize("kind, seed", [("grid", 0), ("random", 2), ("random", 3), ("crowd", 4),
                                        ("crowd", 5), ("random", 6), ("crowd", 7)])
def test_compiled_caster_equals_the_numpy_code_bit_for_bit(slim, waffle, pattern, kind, seed):
    poses = scene(slim, waffle, kind, seed)
    lidar = static_lidar(slim, waffle, pattern)
    lidar_poses, bodies = mount(waffle, poses), feet(waffle, poses)
    got = lidar.true_ranges(lidar_poses, bodies)
    want = numpy_true_ranges(lidar, lidar_poses, bodies)
    assert np.isfinite(want).sum() > 100  # the scenes hit things
    np.testing.assert_array_equal(got, want)
