"""Goal-occupied detection from the robots seen, first come first served, the holding pattern."""

import dataclasses
import math

import numpy as np
import pytest

from swarm_nav.config import CostmapConfig, HoldingConfig
from swarm_nav.costmap import build_costmap
from swarm_nav.holding import (
    goal_crowded,
    goal_occupied,
    goal_site,
    goal_visible,
    holding_points_for,
    holding_sites_from_poi,
    path_congested,
    someone_came_first,
    staging_point,
)
from swarm_nav.holding_behaviour import HoldingPattern, HoldingPhase
from swarm_nav.perception import SeenRobot
from tests.swarm_nav.helpers import (
    SLIM_BLOCKAGE_LOOP,
    grid_map,
)

CFG = HoldingConfig()


def robot_at(x, y, vx=0.0, vy=0.0, n=12):
    """A robot seen as points on its near side (a 0.27 m segment facing -x)."""
    pts = np.column_stack((np.full(n, x - 0.13), np.linspace(y - 0.13, y + 0.13, n)))
    return SeenRobot(np.array([x, y]), pts, np.array([vx, vy]))


@pytest.mark.parametrize("robot, occupied", [
    (robot_at(0.1, 0.0), True),                       # standing on the goal
    (robot_at(0.1, 0.0, vx=np.nan, vy=np.nan), True),  # unknown motion counts as staying
    (robot_at(0.1, 0.0, vx=0.2), False),              # leaving it
    (robot_at(0.1, 0.0, vx=-0.2), True),              # driving onto it
    (robot_at(0.8, 0.0), False),                      # beside it
])
def test_goal_occupied(robot, occupied):
    assert goal_occupied([robot], [0.0, 0.0], CFG) is occupied


def test_goal_occupied_needs_enough_points():
    r = robot_at(0.1, 0.0, n=2)
    assert not goal_occupied([r], [0.0, 0.0], CFG)
    assert not goal_occupied([], [0.0, 0.0], CFG)


@pytest.mark.parametrize("robot, mine, first", [
    (robot_at(0.5, 0.0, vx=-0.2), [2.0, 0.0], True),    # nearer and heading for it
    (robot_at(0.5, 0.0), [2.0, 0.0], False),            # nearer but standing (not its goal)
    (robot_at(0.5, 0.0, vx=0.2), [2.0, 0.0], False),    # nearer but leaving
    (robot_at(0.5, 0.0, vx=-0.2), [0.6, 0.0], False),   # not nearer by the margin
    (robot_at(1.5, 0.0, vx=-0.2), [2.5, 0.0], False),   # outside the yield radius
])
def test_first_come_first_served(robot, mine, first):
    assert someone_came_first([robot], mine, [0.0, 0.0], CFG) is first


@pytest.mark.parametrize("robots, mine, crowded", [
    ([robot_at(0.6, 0.3), robot_at(0.5, -0.6)], [2.0, 0.0], True),   # two stand about it
    ([robot_at(0.6, 0.3)], [2.0, 0.0], False),                        # one is no queue
    ([robot_at(0.6, 0.3), robot_at(0.5, -0.6, vx=0.2)], [2.0, 0.0], False),  # one drives off
    ([robot_at(0.6, 0.3), robot_at(0.5, -0.6, vx=np.nan, vy=np.nan)], [2.0, 0.0], True),
    ([robot_at(0.6, 0.3), robot_at(1.5, 0.0)], [2.0, 0.0], False),    # one too far from it
    ([robot_at(0.6, 0.3), robot_at(0.5, -0.6)], [0.4, 0.0], False),   # we are the nearest
    ([robot_at(0.6, 0.3), robot_at(0.5, -0.6)], [0.7, 0.0], False),   # we are second nearest
])
def test_a_goal_that_robots_stand_about_is_a_queue_to_hold_back_from(robots, mine, crowded):
    two = dataclasses.replace(CFG, crowd_limit=2)
    assert goal_crowded(robots, mine, [0.0, 0.0], two) is crowded
    off = dataclasses.replace(CFG, crowd_limit=0)
    assert goal_crowded(robots, mine, [0.0, 0.0], off) is False


# a corridor along y at x = 0, the goal at (0, 6): the path ahead runs from (0, 0) to (0, 3)
_AHEAD = np.column_stack((np.zeros(61), np.linspace(0.0, 3.0, 61)))
_GOAL = [0.0, 6.0]
_NARROW = 1.0  # [m] wall distance of a centre in the corridor


def congested(centres, standing=None, wall=None, avoid=None, ahead=_AHEAD, cfg=CFG):
    avoid = np.zeros((0, 2)) if avoid is None else avoid
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    standing = np.ones(len(centres), bool) if standing is None else np.asarray(standing)
    wall = np.full(len(centres), _NARROW) if wall is None else np.asarray(wall, dtype=float)
    return path_congested(centres, standing, ahead, _GOAL, avoid, wall, cfg)


@pytest.mark.parametrize("centres, standing, wall, avoid, is_congested", [
    # three stand in the corridor on the way: a queue to keep out of
    ([[0.3, 1.0], [-0.4, 1.8], [0.0, 2.6]], None, None, [], True),
    # two are no queue
    ([[0.3, 1.0], [-0.4, 1.8]], None, None, [], False),
    # one of the three drives: it is traffic, not a queue
    ([[0.3, 1.0], [-0.4, 1.8], [0.0, 2.6]], [True, False, True], None, [], False),
    # one stands beside the way, 1 m off it
    ([[0.3, 1.0], [-0.4, 1.8], [1.0, 2.6]], None, None, [], False),
    # one stands beyond the next 3 m of path
    ([[0.3, 1.0], [-0.4, 1.8], [0.0, 3.8]], None, None, [], False),
    # one stands in the open (1.6 m or more from every wall): the planner passes it
    ([[0.3, 1.0], [-0.4, 1.8], [0.0, 2.6]], None, [1.0, 1.0, 2.0], [], False),
    # one stands on a workstation or holding spot: where it should be
    ([[0.3, 1.0], [-0.4, 1.8], [0.0, 2.6]], None, None, [[0.05, 2.6]], False),
])
def test_robots_standing_on_the_way_in_a_corridor_congest_it(centres, standing, wall, avoid,
                                                           is_congested):
    assert congested(centres, standing, wall, np.asarray(avoid, float).reshape(-1, 2)) \
        is is_congested


def test_congestion_at_the_goal_itself_is_the_queue_rule_s_not_this_one():
    # the last 1.2 m (crowd_radius) to the goal: goal_crowded judges a queue there
    near_goal = np.column_stack((np.zeros(21), np.linspace(5.0, 6.0, 21)))
    queue = [[0.3, 5.2], [-0.4, 5.4], [0.0, 5.6]]
    assert congested(queue, ahead=near_goal) is False
    farther = np.column_stack((np.zeros(41), np.linspace(4.0, 6.0, 41)))
    assert congested([[0.3, 4.2], [-0.4, 4.4], [0.0, 4.6]], ahead=farther) is True
    assert congested([[0.3, 1.0], [-0.4, 1.8], [0.0, 2.6]],
                     cfg=dataclasses.replace(CFG, congestion_limit=0)) is False


def test_by_default_one_robot_standing_at_the_goal_ahead_of_us_is_a_queue():
    assert CFG.crowd_limit == 1
    assert goal_crowded([robot_at(0.6, 0.3)], [2.0, 0.0], [0.0, 0.0], CFG) is True
    assert goal_crowded([robot_at(0.6, 0.3, vx=0.2)], [2.0, 0.0], [0.0, 0.0], CFG) is False
    assert goal_crowded([robot_at(0.6, 0.3)], [0.4, 0.0], [0.0, 0.0], CFG) is False


def test_a_robot_on_another_workstations_spot_is_no_queue_for_this_goal():
    """Robots standing on another workstation or its holding spot (``elsewhere``) wait for that
    one; only within ``holding_arrive_tolerance`` of such a point are they left out."""
    spot = np.array([[0.0, 1.1]])  # the next workstation's holding spot, 1.1 m from our goal
    assert goal_crowded([robot_at(0.0, 1.1)], [0.0, -1.2], [0.0, 0.0], CFG) is True
    assert goal_crowded([robot_at(0.0, 1.1)], [0.0, -1.2], [0.0, 0.0], CFG, spot) is False
    assert goal_crowded([robot_at(0.3, 0.8)], [0.0, -1.2], [0.0, 0.0], CFG, spot) is True
    assert goal_crowded([robot_at(0.0, 1.1), robot_at(0.6, 0.3)], [2.0, 0.0], [0.0, 0.0],
                        CFG, spot) is True  # the other one still queues


def test_goal_visibility(costmap):
    loader1 = [-7.74575, -3.57766]
    assert goal_visible(costmap, [-6.0, -3.5], loader1, CFG)
    assert not goal_visible(costmap, [-3.0, -3.5], loader1, CFG)    # too far
    assert not goal_visible(costmap, [-4.5, -2.0], [-6.0, -2.0], CFG)  # behind the blockage wall


def test_holding_points_for_a_workstation_and_for_any_goal():
    ws = np.array([-7.74575, -3.57766, math.pi])
    sites = [(ws, SLIM_BLOCKAGE_LOOP), (np.array([5.0, 5.0, 0.0]), np.array([[4.0, 4.0]]))]
    pts, loop = holding_points_for(ws + [0.1, 0.1, 0.0], sites, None, CFG)
    assert loop and np.array_equal(pts, SLIM_BLOCKAGE_LOOP)
    pts, loop = holding_points_for([5.2, 5.0], sites, None, CFG)
    assert not loop and np.array_equal(pts, [[4.0, 4.0]])
    path = np.column_stack((np.linspace(0.0, 3.0, 31), np.zeros(31)))
    pts, loop = holding_points_for([3.0, 0.0], sites, path, CFG)
    assert not loop and pts[0] == pytest.approx([3.0 - CFG.holding_distance, 0.0])
    pts, _ = holding_points_for([1.0, 0.0], sites, path[:11], CFG)   # path shorter: its start
    assert pts[0] == pytest.approx([0.0, 0.0])


def test_goal_site_is_the_nearest_workstation_within_the_match_radius():
    sites = [(np.array([0.0, 0.0, 0.0]), np.zeros((0, 2))),          # no holding points
             (np.array([0.25, 0.0, 0.0]), np.array([[1.0, 1.0]])),
             (np.array([5.0, 5.0, 0.0]), np.array([[4.0, 4.0]]))]
    assert goal_site([0.05, 0.0], sites, CFG) == 0
    assert goal_site([0.05, 0.0], sites, CFG, with_points=True) == 1  # 0.2 m, within 0.3 m
    assert goal_site([5.1, 5.0, 1.0], sites, CFG) == 2
    assert goal_site([2.5, 2.5], sites, CFG) is None
    assert CFG.workstation_match_radius == pytest.approx(0.3)


# ---------------------------------------------------------------- the state machine
def spot():
    return HoldingPattern(np.array([[2.0, 0.0]]), False, CFG)


def test_approach_stays_while_the_goal_is_free_or_unseen():
    hp = spot()
    assert hp.update(0.0, [0, 0], None) == HoldingPhase.APPROACH
    assert hp.update(0.1, [0, 0], False) == HoldingPhase.APPROACH
    assert hp.target is None


@pytest.mark.parametrize("occupied, first", [(True, False), (False, True)])
def test_approach_to_hold_when_taken_or_someone_came_first(occupied, first):
    hp = spot()
    assert hp.update(0.0, [0, 0], occupied, first) == HoldingPhase.TO_HOLD
    assert hp.target == pytest.approx([2.0, 0.0])


def test_came_first_needs_the_goal_in_sight():
    hp = spot()
    assert hp.update(0.0, [0, 0], None, True) == HoldingPhase.APPROACH


def test_to_hold_to_wait_on_arrival_then_retry_when_free():
    hp = spot()
    hp.update(0.0, [0, 0], True)
    assert hp.update(1.0, [1.0, 0.0], True) == HoldingPhase.TO_HOLD
    assert hp.update(2.0, [1.9, 0.0], True) == HoldingPhase.WAIT
    assert hp.update(3.0, [1.9, 0.0], False) == HoldingPhase.WAIT      # free, not yet confirmed
    assert hp.update(3.5, [1.9, 0.0], False) == HoldingPhase.WAIT
    assert hp.update(4.0, [1.9, 0.0], False) == HoldingPhase.APPROACH  # free for 1 s
    assert hp.target is None


def test_free_must_be_continuous():
    hp = spot()
    hp.update(0.0, [0, 0], True)
    hp.update(1.0, [2.0, 0.0], False)
    hp.update(1.5, [2.0, 0.0], True)            # taken again
    assert hp.update(2.2, [2.0, 0.0], False) == HoldingPhase.WAIT
    assert hp.update(3.1, [2.0, 0.0], False) == HoldingPhase.WAIT
    assert hp.update(3.2, [2.0, 0.0], False) == HoldingPhase.APPROACH


def test_to_hold_back_to_approach_when_free_on_the_way():
    hp = spot()
    hp.update(0.0, [0, 0], True)
    hp.update(0.5, [0.5, 0], False)
    assert hp.update(1.5, [0.8, 0], False) == HoldingPhase.APPROACH


def test_wait_keeps_waiting_while_taken_and_retries_unseen_goal_after_the_period():
    hp = spot()
    hp.update(0.0, [0, 0], True)
    hp.update(1.0, [2.0, 0.0], True)                                    # WAIT from t = 1
    assert hp.update(7.0, [2.0, 0.0], True) == HoldingPhase.WAIT       # still taken: wait on
    assert hp.update(8.0, [2.0, 0.0], None) == HoldingPhase.WAIT       # unseen, 1 s since taken
    assert hp.update(12.0, [2.0, 0.0], None) == HoldingPhase.APPROACH  # unseen 5 s: go and look


def test_loop_drives_the_points_in_order_and_retries_when_free():
    hp = HoldingPattern(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]), True, CFG)
    hp.update(0.0, [1.9, 0.3], True)
    assert hp.phase == HoldingPhase.TO_HOLD and hp.target == pytest.approx([2.0, 0.0])
    hp.update(1.0, [2.0, 0.1], True)                                   # arrived: next point
    assert hp.target == pytest.approx([2.0, 2.0])
    hp.update(2.0, [2.0, 1.9], True)
    assert hp.target == pytest.approx([0.0, 2.0])
    hp.update(3.0, [0.1, 2.0], True)
    assert hp.target == pytest.approx([0.0, 0.0])                      # wraps around
    hp.update(4.0, [0.0, 0.1], None)                                   # 1 s since taken: on
    assert hp.phase == HoldingPhase.TO_HOLD and hp.target == pytest.approx([2.0, 0.0])
    hp.update(9.5, [2.0, 0.1], None)                                   # retry due, goal unseen
    assert hp.phase == HoldingPhase.APPROACH


def test_replace_target_for_a_taken_spot():
    hp = spot()
    hp.update(0.0, [0, 0], True)
    hp.replace_target([1.0, 1.0])
    assert hp.target == pytest.approx([1.0, 1.0])
    assert hp.update(1.0, [1.0, 1.1], True) == HoldingPhase.WAIT


def test_a_hold_back_waits_its_time_even_when_the_goal_is_seen_free():
    hp = spot()
    hp.hold_back([5.0, 5.0], 0.0, wait=20.0)
    assert hp.phase == HoldingPhase.TO_HOLD and hp.target == pytest.approx([5.0, 5.0])
    assert hp.rerouted and hp.held_back(19.9) and not hp.held_back(20.0)
    assert hp.update(5.0, [5.0, 5.1], None) == HoldingPhase.WAIT
    for t in np.arange(6.0, 20.0, 0.5):   # seen free, out of sight: holds on
        assert hp.update(float(t), [5.0, 5.1], False if t < 12 else None) == HoldingPhase.WAIT
    assert hp.update(20.0, [5.0, 5.1], None) == HoldingPhase.APPROACH  # its time is up


def test_a_hold_back_on_a_loop_waits_at_its_place_rather_than_driving_the_loop():
    hp = HoldingPattern(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]), True, CFG)
    hp.hold_back([5.0, 5.0], 0.0, wait=10.0)
    assert hp.update(1.0, [5.0, 5.0], None) == HoldingPhase.WAIT
    assert hp.target == pytest.approx([5.0, 5.0])
    assert hp.update(9.0, [5.0, 5.0], None) == HoldingPhase.WAIT
    assert hp.update(10.0, [5.0, 5.0], None) == HoldingPhase.APPROACH


def test_relocate_from_wait():
    hp = spot()
    hp.update(0.0, [0, 0], True)
    hp.update(1.0, [2.0, 0.0], True)
    assert hp.phase == HoldingPhase.WAIT
    hp.relocate([5.0, 5.0], 2.0)
    assert hp.phase == HoldingPhase.TO_HOLD and hp.target == pytest.approx([5.0, 5.0])
    assert hp.update(3.0, [5.0, 5.1], True) == HoldingPhase.WAIT


def test_staging_point_keeps_away_from_the_goal_robots_and_workstations(costmap):
    goal = np.array([-7.74575, 0.97297])
    robot = np.array([-6.5, 0.5])
    centres = np.array([[-7.7, 1.0], [-6.8, -0.2], [-6.0, 1.5]])
    avoid = np.array([[-7.74575, y] for y in (-3.577660, -1.385260, 0.972970, 3.203130)])
    xy = staging_point(costmap, goal, robot, centres, avoid, CFG)
    assert xy is not None
    assert costmap.cost_at(xy) == 0
    assert np.hypot(*(xy - goal)) >= CFG.staging_distance
    assert np.hypot(*(centres - xy).T).min() >= CFG.staging_clearance
    assert np.hypot(*(avoid - xy).T).min() >= CFG.workstation_clearance
    assert np.hypot(*(xy - robot)) <= CFG.staging_search_radius
    # never inside the closed blockage, although it is near and free
    assert not (-5.112 < xy[0] < -3.912 and -2.866 < xy[1] < 7.334)


def test_staging_point_is_in_the_open_not_in_the_corridor_of_the_workstations(costmap):
    """slim_blockage: the six loaders share the 3 m corridor left of the blockage; a robot
    waiting there narrows the lane, so it waits in the open hall right of the blockage."""
    goal = np.array([-7.74575, 0.97297])
    robot = np.array([-6.5, -0.5])  # in the corridor, below its goal
    avoid = np.array([[-7.74575, y] for y in (-3.577660, -1.385260, 0.972970, 3.203130)])
    xy = staging_point(costmap, goal, robot, np.zeros((0, 2)), avoid, CFG)
    assert xy is not None and xy[0] > -4.0  # right of the blockage (x in -5.3 .. -4.3)
    assert costmap.distance_at(xy) >= CFG.staging_wall_clearance
    assert np.hypot(*(xy - robot)) <= CFG.staging_search_radius
    # without an open place in reach, a corridor place as before
    near = dataclasses.replace(CFG, staging_search_radius=2.0)
    xy = staging_point(costmap, goal, robot, np.zeros((0, 2)), avoid, near)
    assert xy is not None and -8.3 < xy[0] < -5.3
    assert costmap.cost_at(xy) == 0 and costmap.distance_at(xy) < CFG.staging_wall_clearance


def test_no_staging_point_in_a_tiny_room():
    data = np.full((20, 20), 100, dtype=np.int8)
    data[5:15, 5:15] = 0
    cm = build_costmap(grid_map(data, 0.1), CostmapConfig())
    assert staging_point(cm, [1.0, 1.0], [1.0, 1.0], np.zeros((0, 2)), np.zeros((0, 2)),
                         CFG) is None


def test_holding_sites_from_the_world_file(repo_root):
    from swarm_scene.poi import load_poi

    path = repo_root / "worlds" / "slim_blockage.yaml"
    if not path.exists():
        pytest.skip("worlds/slim_blockage.yaml not there yet")
    sites = holding_sites_from_poi(load_poi(path))
    assert len(sites) == 6
    for pose, points in sites:
        assert pose.shape == (3,) and points.ndim == 2 and points.shape[1] == 2
    assert sites[0][0][:2] == pytest.approx([-7.74575, -3.57766])
    assert holding_sites_from_poi(None) == []
