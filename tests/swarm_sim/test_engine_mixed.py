"""A mixed fleet in the simulated world: every robot's own outline (seen by the lidars, touched
by the contacts, measured by the separation), drive limits and lidar (rate, range, beams)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_scene.robot_model import load_robot
from swarm_sim.engine import pad_polygons, polygon_distances
from swarm_sim.lidar import cast_rays, counter_clockwise, polygons_to_segments

# Footprints about base_footprint (robots/*.urdf.xacro): x from -rear to front, y +- half width.
BURGER_FRONT, BURGER_HALF = 0.038, 0.07
LINO_REAR, LINO_HALF = 0.12, 0.1375
WAFFLE_FRONT = 0.069


def _outline(model, pose) -> np.ndarray:
    """(K, 2) a model's footprint at ``pose`` in ``map``, counter-clockwise."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    f = counter_clockwise(model.footprint)
    return np.column_stack((pose[0] + c * f[:, 0] - s * f[:, 1],
                            pose[1] + s * f[:, 0] + c * f[:, 1]))


def test_a_waffles_lidar_sees_a_burger_by_its_own_outline(empty, robots, make_engine):
    waffle, burger = robots["turtlebot3_waffle"], robots["turtlebot3_burger"]
    burger_pose = (1.5, 0.1, 0.4)
    engine = make_engine(empty, [waffle, burger], [(0.0, 0.0, 0.0), burger_pose], seed=2)
    assert engine.mixed and engine.kind.tolist() == [0, 1]
    lidar_pose = engine.lidar_poses()[0]
    true = engine.kind_lidars[0].true_ranges(lidar_pose[None], engine.footprints(), own=[0])[0]
    # brute force against the burger's outline alone (the room's walls are out of range)
    angles = lidar_pose[2] + engine.kind_lidars[0].pattern.angles
    dirs = np.column_stack((np.cos(angles), np.sin(angles)))
    expect = cast_rays(lidar_pose[:2], dirs,
                       polygons_to_segments([_outline(burger, burger_pose)]))
    hit = np.isfinite(expect)
    np.testing.assert_allclose(true[hit], expect[hit], atol=1e-9)
    assert np.all(np.isinf(true[~hit]))
    # a burger is smaller than a waffle: fewer beams hit it than would hit a waffle there
    as_waffle = cast_rays(lidar_pose[:2], dirs,
                          polygons_to_segments([_outline(waffle, burger_pose)]))
    assert 5 <= hit.sum() < np.isfinite(as_waffle).sum() - 3
    # the nearest return is about the burger's nearest corner
    corner = _outline(burger, burger_pose)
    assert true.min() == pytest.approx(np.hypot(*(corner - lidar_pose[:2]).T).min(), abs=0.01)
    # and the noisy scan agrees within 5 sigma
    scans = engine.scans()
    assert np.all(np.abs(scans[0][hit] - true[hit]) < 5 * waffle.lidar.noise_stddev)


def test_every_lidar_has_its_own_rate_range_and_beams(empty, robots, make_engine):
    waffle, lino = robots["turtlebot3_waffle"], robots["linorobot2_2wd"]
    # 5 m apart: beyond the LDS-01's 3.5 m, within the linorobot2 laser's 12 m
    engine = make_engine(empty, [waffle, lino], [(0.0, 0.0, 0.0), (5.0, 0.0, math.pi)])
    assert engine.lidar_periods.tolist() == [2, 1]  # 5 Hz and 10 Hz at a 10 Hz control tick
    due = []
    for _ in range(4):
        scans = engine.scans()
        due.append([s is not None for s in scans])
        engine.step([0.0, 0.0], [0.0, 0.0])
    assert due == [[True, True], [False, True], [True, True], [False, True]]
    scans = engine.scans()
    assert scans[0].shape == (360,) and scans[1].shape == (360,)
    assert np.all(np.isinf(scans[0]))  # the waffle sees nothing within 3.5 m
    # the linorobot2 laser (mounted at its base_footprint's origin) runs -pi..pi: the beam
    # straight ahead (angle 0) is in the middle, and it meets the waffle's front 5 - 0.069 m away
    ahead = int(np.argmin(np.abs(engine.kind_lidars[1].pattern.angles)))
    assert scans[1][ahead] == pytest.approx(5.0 - WAFFLE_FRONT, abs=0.05)


def test_drive_limits_clamp_every_robot_to_its_own(empty, robots, make_engine):
    names = ("turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd")
    engine = make_engine(empty, [robots[n] for n in names],
                         [(0.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 4.0, 0.0)])
    for _ in range(30):
        engine.step(np.full(3, 1.0), np.full(3, 5.0))
    np.testing.assert_array_equal(engine.v, [robots[n].limits.max_vel_x for n in names])
    np.testing.assert_array_equal(engine.w, [robots[n].limits.max_vel_theta for n in names])
    for _ in range(30):
        engine.step(np.full(3, -1.0), np.full(3, -5.0))
    np.testing.assert_array_equal(engine.v, [robots[n].limits.min_vel_x for n in names])
    # one tick from rest: every drive's acceleration limit
    engine = make_engine(empty, [robots[n] for n in names],
                         [(0.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 4.0, 0.0)])
    engine.step(np.full(3, 1.0), np.zeros(3))
    np.testing.assert_allclose(engine.v, [min(robots[n].limits.max_vel_x,
                                              robots[n].limits.acc_lim_x * 0.1) for n in names])


def test_contacts_and_separation_use_the_real_bodies(empty, robots, make_engine):
    burger, lino = robots["turtlebot3_burger"], robots["linorobot2_2wd"]
    # side by side, 0.3 m apart: a burger and a linorobot2 leave 0.3 - 0.07 - 0.1375 m between
    # them (two waffles there would overlap)
    engine = make_engine(empty, [burger, lino], [(0.0, 0.0, 0.0), (0.0, 0.3, 0.0)])
    assert engine.min_separation == pytest.approx(0.3 - BURGER_HALF - LINO_HALF, abs=1e-9)
    # a burger drives into a standing linorobot2: it stops where its front meets the other's rear
    engine = make_engine(empty, [burger, lino], [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)])
    events = []
    for _ in range(80):
        events += engine.step([0.22, 0.0], [0.0, 0.0])
    assert [e.kind for e in events] == ["robot_robot"]
    front = engine.poses[0, 0] + BURGER_FRONT
    assert front == pytest.approx(1.0 - LINO_REAR, abs=0.22 * 0.05 + 1e-3)
    assert engine.min_separation < 0.012
    assert engine.poses[1, 0] == 1.0  # the one standing is not pushed


def test_a_lidar_cast_for_a_subset_equals_the_whole_fleets(empty, robots, make_engine):
    """``own`` names each lidar's body: casting robots 1 and 3 alone gives their rows of the
    cast for all, to the last bit."""
    waffle = robots["turtlebot3_waffle"]
    poses = [(0.0, 0.0, 0.3), (1.0, 0.2, 2.0), (0.4, 1.1, -1.0), (-0.8, 0.5, 3.0)]
    engine = make_engine(empty, waffle, poses)
    lidar, at, feet = engine.lidar, engine.lidar_poses(), engine.footprints()
    whole = lidar.true_ranges(at, feet)
    part = lidar.true_ranges(at[[1, 3]], feet, own=np.array([1, 3]))
    np.testing.assert_array_equal(part, whole[[1, 3]])


def test_one_model_given_as_a_list_is_the_one_model_engine(empty, robots, make_engine):
    waffle = robots["turtlebot3_waffle"]
    poses = [(0.0, 0.0, 0.0), (0.9, 0.1, 2.0), (0.3, 0.8, -1.0)]
    a = make_engine(empty, waffle, poses, seed=5)
    b = make_engine(empty, [waffle] * 3, poses, seed=5)
    assert not b.mixed and b.lidar_period_ticks == a.lidar_period_ticks == 2
    for k in range(20):
        if a.lidar_due():
            np.testing.assert_array_equal(a.scans(), b.scans())
        a.step(np.full(3, 0.2), np.full(3, 0.5 * math.sin(k)))
        b.step(np.full(3, 0.2), np.full(3, 0.5 * math.sin(k)))
    np.testing.assert_array_equal(a.poses, b.poses)


def test_footprints_of_different_vertex_counts(empty, robots, make_engine, repo_root):
    """A 16-gon base (a cylinder) beside 4-gons: padded by a repeated vertex, seen and measured
    as itself."""
    round_bot = load_robot(repo_root / "tests/data/robot_args.urdf.xacro")
    assert len(round_bot.footprint) == 16
    burger = robots["turtlebot3_burger"]
    engine = make_engine(empty, [burger, round_bot], [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)])
    feet = engine.footprints()
    assert feet.shape == (2, 16, 2)
    np.testing.assert_array_equal(feet[0, 4:], np.repeat(feet[0, 3:4], 12, axis=0))
    disc = _outline(round_bot, (1.0, 0.0, 0.0))
    gap = 1.0 - round_bot.radius - BURGER_FRONT
    assert engine.min_separation == pytest.approx(gap, abs=0.01)
    true = engine.kind_lidars[0].true_ranges(engine.lidar_poses()[:1], feet, own=[0])[0]
    assert true[0] == pytest.approx(disc[:, 0].min() - engine.lidar_poses()[0, 0], abs=0.01)


def test_padded_polygons_overlap_and_distance_as_themselves():
    square = counter_clockwise([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    hexa = counter_clockwise([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [0.5, 1.5]])
    padded = pad_polygons([square, np.vstack((hexa, hexa[:2]))])
    assert padded.shape == (2, 6, 2)
    far = padded[1] + 3.0
    d = polygon_distances(padded[[0, 0]], np.stack((padded[1], far)))
    assert d[0] == 0.0  # overlapping, found with the padding's zero-length edges skipped
    assert d[1] == pytest.approx(polygon_distances(square[None], (hexa + 3.0)[None])[0])
    inner = counter_clockwise([[0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]])
    both = pad_polygons([square, inner])
    assert polygon_distances(both[[1]], both[[0]])[0] == 0.0  # wholly inside, padded or not
