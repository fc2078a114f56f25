"""What a robot sees of the others: dynamic points, clusters, centres and velocities."""

import math

import numpy as np
import pytest

from swarm_nav.config import PerceptionConfig
from swarm_nav.perception import (
    RobotTracker,
    SeenRobot,
    dynamic_points,
)
from tests.swarm_nav.helpers import (
    SLIM_BLOCKAGE_WALLS,
    Lidar,
    box_segments,
    footprint_polygon,
    polygon_segments,
)
from tests.swarm_nav.perception_steps import (
    cluster_centres,
    cluster_points,
    estimate_velocities,
    perceive_robots,
    robot_centres,
    seen_arrays_of,
)

PCFG = PerceptionConfig()


def test_dynamic_points_keep_only_what_the_map_does_not_explain(costmap):
    rng = np.random.default_rng(0)
    viewer = np.array([-6.5, -3.9, 0.0])
    other = np.array([-5.5, -3.9, math.pi])
    segs = np.vstack([box_segments(SLIM_BLOCKAGE_WALLS),
                      polygon_segments(footprint_polygon(other))])
    pts = Lidar().scan_points(viewer, segs, rng)
    dyn = dynamic_points(pts, costmap, PCFG.static_point_tolerance)
    assert 5 <= len(dyn) < len(pts)
    assert np.all(np.hypot(*(dyn - other[:2]).T) < 0.3)   # all of them are on the other robot
    robots = perceive_robots(dyn, viewer[:2])
    assert len(robots) == 1
    assert np.hypot(*(robots[0].centre - (other[:2] + [-0.064, 0]))) < 0.12
    assert np.all(np.isnan(robots[0].velocity))


def test_cluster_points_separates_robots():
    a = np.column_stack((np.linspace(0, 0.25, 10), np.zeros(10)))
    b = a + [1.0, 0.5]
    labels, n = cluster_points(np.vstack((a, b)))
    assert n == 2 and len(set(labels[:10])) == 1 and len(set(labels[10:])) == 1
    assert labels[0] != labels[10]
    assert cluster_points(np.zeros((0, 2)))[1] == 0


def test_estimate_velocities():
    now = np.array([[1.0, 0.0], [5.0, 5.0]])
    before = np.array([[0.8, 0.0], [9.0, 9.0]])
    v = estimate_velocities(now, before, 1.0)
    assert v[0] == pytest.approx([0.2, 0.0])
    assert np.all(np.isnan(v[1]))


def test_cluster_points_links_chains_and_big_clouds_agree():
    # a chain of points 0.15 m apart is one cluster, though its ends are far apart
    chain = np.column_stack((np.arange(10) * 0.15, np.zeros(10)))
    labels, n = cluster_points(chain)
    assert n == 1 and np.all(labels == 0)
    assert cluster_points(chain, link=0.1)[1] == 10
    # more than 400 points take the sparse path: same partition as the dense one
    rng = np.random.default_rng(1)
    blobs = np.vstack([c + rng.uniform(-0.1, 0.1, size=(150, 2))
                       for c in ([0.0, 0.0], [2.0, 0.0], [0.0, 2.0])])
    labels, n = cluster_points(blobs)
    assert n == 3
    assert [len(set(labels[k * 150:(k + 1) * 150])) for k in range(3)] == [1, 1, 1]
    dense, n_dense = cluster_points(blobs[::2])
    assert n_dense == 3
    assert np.array_equal(dense, labels[::2])


def test_cluster_centres_lie_behind_the_visible_side():
    side = np.column_stack((np.full(5, 1.0), np.linspace(-0.1, 0.1, 5)))
    c = cluster_centres(side, [0.0, 0.0])
    assert c.shape == (1, 2)
    assert c[0] == pytest.approx([1.1, 0.0])           # centroid (1, 0) pushed 0.1 m away
    c = cluster_centres(side, [1.0, -3.0], depth=0.25)
    assert c[0] == pytest.approx([1.0, 0.25])          # away from a viewer below it
    assert cluster_centres(np.zeros((0, 2)), [0.0, 0.0]).shape == (0, 2)


def test_estimate_velocities_gate_grows_with_the_time_between():
    now = np.array([[1.0, 0.0]])
    before = np.array([[0.0, 0.0]])
    assert np.all(np.isnan(estimate_velocities(now, before, 1.0, max_speed=0.5)))   # 1 > 0.8
    assert estimate_velocities(now, before, 2.0, max_speed=0.5)[0] == pytest.approx([0.5, 0.0])
    assert np.all(np.isnan(estimate_velocities(now, before, 0.0)))
    assert np.all(np.isnan(estimate_velocities(now, np.zeros((0, 2)), 1.0)))


def test_perceive_robots_with_an_earlier_scan():
    side = np.column_stack((np.full(5, 1.0), np.linspace(-0.1, 0.1, 5)))
    other = side + [3.0, 3.0]
    robots = perceive_robots(np.vstack((side, other)), [0.0, 0.0],
                             earlier=np.array([[1.0, 0.0]]), dt=0.5)
    assert len(robots) == 2
    assert robots[0].centre == pytest.approx([1.1, 0.0])
    assert robots[0].velocity == pytest.approx([0.2, 0.0])   # (1.1 - 1.0) / 0.5
    assert len(robots[0].points) == 5
    assert np.all(np.isnan(robots[1].velocity))             # nothing near it before
    assert robot_centres(robots) == pytest.approx(np.array([robots[0].centre, robots[1].centre]))
    assert robot_centres([]).shape == (0, 2)
    assert perceive_robots(np.zeros((0, 2)), [0.0, 0.0]) == []


def test_tracker_takes_velocities_over_about_the_baseline():
    assert (PCFG.velocity_baseline, PCFG.velocity_min_baseline, PCFG.velocity_history) == (
        1.0, 0.35, 1.5)
    tracker = RobotTracker(PCFG)
    side = np.column_stack((np.zeros(5), np.linspace(-0.1, 0.1, 5)))
    viewer = [-100.0, 0.0]   # far behind along -x: every centre is pushed by the same +0.1 m in x

    def x(t):
        return 0.1 * t * t   # accelerating, so the velocity tells which earlier scan was used

    seen = {}
    for i in range(21):
        t = i / 10.0
        seen[i] = tracker.update(side + [x(t), 0.0], viewer, t)[0][0].velocity
    assert np.all(np.isnan(seen[0])) and np.all(np.isnan(seen[3]))   # nothing 0.35 s old yet
    assert seen[4] == pytest.approx([(x(0.4) - x(0.0)) / 0.4, 0.0])  # the oldest: 0.4 s
    assert seen[12] == pytest.approx([(x(1.2) - x(0.2)) / 1.0, 0.0])  # 1 s back
    assert seen[20] == pytest.approx([(x(2.0) - x(1.0)) / 1.0, 0.0])
    # a gap in the scans longer than the history forgets the old centres
    assert np.all(np.isnan(tracker.update(side, viewer, 5.0)[0][0].velocity))
    assert math.isfinite(tracker.update(side, viewer, 5.5)[0][0].velocity[0])


def test_seen_arrays_lay_out_every_robots_points_in_order():
    robots = [SeenRobot(np.array([1.0, 2.0]), np.array([[1.0, 1.9], [1.1, 2.0]]),
                        np.array([0.3, -0.4])),
              SeenRobot(np.array([-3.0, 0.5]), np.array([[-3.1, 0.5]]),
                        np.array([np.nan, np.nan])),
              SeenRobot(np.array([0.0, -4.0]), np.array([[0.0, -3.9], [0.1, -3.9], [0.2, -4.0]]),
                        np.array([0.0, 0.05]))]
    seen = seen_arrays_of(robots)
    assert seen.centres.tolist() == [[1.0, 2.0], [-3.0, 0.5], [0.0, -4.0]]
    assert seen.known.tolist() == [True, False, True]
    assert seen.speed.tolist() == pytest.approx([0.5, 0.0, 0.05])
    assert seen.owner.tolist() == [0, 0, 1, 2, 2, 2]
    assert seen.starts.tolist() == [0, 2, 3]
    assert seen.sizes.tolist() == [2, 1, 3]
    for k, r in enumerate(robots):
        assert np.array_equal(seen.points[seen.owner == k], r.points)
    empty = seen_arrays_of([])
    assert empty.centres.shape == (0, 2) and empty.points.shape == (0, 2)
    assert len(empty.owner) == len(empty.starts) == len(empty.speed) == 0


def test_perceive_robots_centres_match_cluster_centres():
    rng = np.random.default_rng(4)
    blobs = [c + 0.05 * rng.standard_normal((12, 2)) for c in ([2.0, 0.0], [0.0, 3.0], [-2, -2])]
    pts = np.vstack(blobs)
    robots = perceive_robots(pts, [0.0, 0.0])
    assert len(robots) == 3
    assert np.array_equal(robot_centres(robots), cluster_centres(pts, [0.0, 0.0]))
