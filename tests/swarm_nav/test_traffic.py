"""The traffic rules between robots that do not talk: keep right, and who yields."""

import math

import numpy as np
import pytest

from swarm_nav import traffic
from swarm_nav.config import CostmapConfig, PlannerConfig, TrafficConfig
from swarm_nav.costmap import build_costmap
from swarm_nav.perception import SeenRobot
from swarm_nav.planner import path_length
from swarm_nav.traffic import (
    Yield,
    YieldStep,
    keep_right,
    must_yield,
    plan_retreat,
    retreat_candidates,
    robots_ahead,
)
from tests.swarm_nav.helpers import grid_map, slim_blockage_map

CFG = TrafficConfig()


@pytest.mark.parametrize("seed", range(20))
def test_exactly_one_of_two_robots_yields(seed):
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(-5, 5, size=(2, 2))
    assert must_yield(a, b, CFG.yield_axis_angle) != must_yield(b, a, CFG.yield_axis_angle)


@pytest.mark.parametrize("d", [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)])
def test_yield_rule_is_unambiguous_in_axis_aligned_corridors(d):
    d = np.array(d)
    assert abs(d @ [math.cos(CFG.yield_axis_angle), math.sin(CFG.yield_axis_angle)]) > 0.25


def test_robots_ahead():
    pose = np.array([0.0, 0.0, math.pi / 2])
    centres = np.array([[0.0, 0.8], [0.0, -0.5], [0.1, 0.4], [2.0, 0.0], [0.0, 3.0]])
    assert robots_ahead(pose, centres, 1.0).tolist() == [2, 0]


def test_keep_right_shifts_to_the_right_of_travel():
    cm = build_costmap(grid_map(np.zeros((60, 60)), 0.1), CostmapConfig())
    path = np.column_stack((np.linspace(1.0, 5.0, 41), np.full(41, 3.0)))
    pose = np.array([1.0, 3.0, 0.0])
    assert np.array_equal(keep_right(path, pose, np.zeros((0, 2)), cm, CFG), path)
    shifted = keep_right(path, pose, np.array([[2.5, 3.05]]), cm, CFG)
    assert shifted[0] == pytest.approx(path[0])                     # starts where it was
    assert np.all(shifted[6:, 1] == pytest.approx(3.0 - CFG.keep_right_offset))  # right = -y
    assert np.all(shifted[:, 0] == pytest.approx(path[:, 0]))
    # going the other way, right is +y
    back = keep_right(path[::-1], np.array([5.0, 3.0, math.pi]), np.array([[3.5, 3.0]]), cm, CFG)
    assert back[-1, 1] == pytest.approx(3.0 + CFG.keep_right_offset)
    # a robot far off the path or behind does not count
    assert np.array_equal(keep_right(path, pose, np.array([[2.5, 4.5]]), cm, CFG), path)
    assert np.array_equal(keep_right(path, pose, np.array([[0.0, 3.0]]), cm, CFG), path)


def test_keep_right_leaves_room_to_walls():
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    y = -4.824 + 0.5   # a path 0.5 m from the bottom wall: no room for the whole offset
    path = np.column_stack((np.linspace(-2.0, 2.0, 41), np.full(41, y)))
    shifted = keep_right(path, np.array([-2.0, y, 0.0]), np.array([[0.0, y]]), cm, CFG)
    assert np.all(cm.cost_at(shifted) <= 200)
    assert shifted[10:, 1].max() < y


def test_retreat_candidates_are_off_the_line_and_not_beyond_the_other():
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    me, other = np.array([0.0, 0.0]), np.array([1.0, 0.0])
    cand = retreat_candidates(cm, me, other, CFG)
    assert len(cand) > 10
    assert np.all(np.abs(cand[:, 1]) >= CFG.yield_clearance - 1e-9)
    assert np.all(cand[:, 0] <= other[0] + 0.3 + 1e-9)
    assert np.all(cm.cost_at(cand) < 128)
    d = np.hypot(*(cand - me).T)
    assert np.all(np.diff(d) >= -1e-12)
    assert d[0] == pytest.approx(CFG.yield_clearance, abs=0.05)


def seen(x, y, vx, vy):
    return SeenRobot(np.array([x, y]), np.array([[x, y]]), np.array([vx, vy]))


def oncoming(robots, robot_xy, moving_speed):
    """traffic.oncoming_centres of SeenRobot objects (the rule read robot by robot)."""
    if not robots:
        return np.zeros((0, 2))
    return traffic.oncoming_centres(np.array([r.centre for r in robots], dtype=float),
                            np.array([r.velocity for r in robots], dtype=float),
                            robot_xy, moving_speed)


def test_oncoming_counts_robots_driving_toward_us():
    robots = [seen(2.0, 0.0, -0.2, 0.0),       # toward us at 0.2 m/s
              seen(2.0, 0.0, 0.2, 0.0),        # away
              seen(0.0, 2.0, 0.0, -0.05),      # toward us, slower than moving_speed
              seen(0.0, -2.0, 0.0, 0.1),       # toward us at 0.1 m/s from below
              seen(3.0, 3.0, np.nan, np.nan),  # unknown velocity
              seen(0.0, 0.0, -1.0, 0.0)]       # on top of us: no direction
    got = oncoming(robots, [0.0, 0.0], 0.08)
    assert got.tolist() == [[2.0, 0.0], [0.0, -2.0]]
    assert oncoming([], [0.0, 0.0], 0.08).shape == (0, 2)
    # the speed counted is the component toward us: 0.1 * sin(60 deg) = 0.0866
    slanted = seen(1.0, math.sqrt(3.0), 0.0, -0.1)
    assert len(oncoming([slanted], [0.0, 0.0], 0.08)) == 1
    assert len(oncoming([slanted], [0.0, 0.0], 0.09)) == 0


def test_plan_retreat_is_a_short_detour_off_the_line():
    assert (CFG.yield_detour_factor, CFG.yield_detour_slack, CFG.yield_retreat_tries) == (
        3.0, 1.0, 4)
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    me, other = np.array([0.0, 0.0]), np.array([1.0, 0.0])
    path = plan_retreat(cm, me, other, CFG, PlannerConfig())
    assert path is not None
    assert path[0] == pytest.approx(me, abs=0.1)
    end = path[-1]
    assert abs(end[1]) >= CFG.yield_clearance - 1e-9        # off the line the other comes along
    assert end[0] <= other[0] + 0.3 + 1e-9                   # not beyond it
    assert np.hypot(*(end - me)) <= CFG.yield_clearance + 0.1  # the nearest such place
    assert path_length(path) <= 3.0 * np.hypot(*(end - me)) + 1.0


def test_plan_retreat_none_without_room():
    data = np.full((30, 30), 100, dtype=np.int8)
    data[10:20, 5:25] = 0   # a 1 m wide corridor: nowhere 0.7 m off its axis
    cm = build_costmap(grid_map(data, 0.1), CostmapConfig())
    assert plan_retreat(cm, [1.0, 1.5], [1.8, 1.5], CFG, PlannerConfig()) is None


def _drive(v, w, moving, calls):
    def f():
        calls.append("drive")
        return v, w, moving
    return f


def _blocked(value, calls):
    def f():
        calls.append("blocked")
        return value
    return f


def test_yield_drives_to_the_place_then_waits_until_clear():
    y = Yield(np.array([1.0, 0.0]), 10.0, t_phase=10.0)
    calls = []
    # driving: the local planner's command passes through; blocked() is not asked
    assert y.step([0.0, 0.0], 10.1, CFG, 2.0, _drive(0.2, 0.1, True, calls),
                  _blocked(True, calls)) == (YieldStep.DRIVE, 0.2, 0.1)
    assert calls == ["drive"]
    # within yield_arrive_tolerance (0.3 m) of the place: arrived, the wait begins
    assert y.step([0.75, 0.0], 11.0, CFG, 2.0, _drive(0.2, 0.0, True, calls),
                  _blocked(True, calls)) == (YieldStep.ARRIVED, 0.0, 0.0)
    assert (y.phase, y.t_phase) == ("wait", 11.0) and calls == ["drive"]
    # waiting: the path is blocked, then clear from 12.0; clear for 1.5 s -> done at 13.5
    assert y.step([0.75, 0.0], 11.5, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(True, calls))[0] == YieldStep.WAIT
    assert y.step([0.75, 0.0], 12.0, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(False, calls))[0] == YieldStep.WAIT
    assert y.step([0.75, 0.0], 13.4, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(False, calls))[0] == YieldStep.WAIT
    assert y.step([0.75, 0.0], 13.5, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(False, calls)) == (YieldStep.DONE, 0.0, 0.0)
    assert "drive" not in calls[1:]


def test_yield_drive_ends_when_stuck_or_after_half_the_timeout():
    calls = []
    y = Yield(np.array([5.0, 0.0]), 0.0, t_phase=0.0)
    assert y.step([0.0, 0.0], 1.0, CFG, 2.0, _drive(0.0, 0.05, False, calls),
                  _blocked(False, calls)) == (YieldStep.DRIVE, 0.0, 0.05)
    assert y.still_since == 1.0
    assert y.step([0.0, 0.0], 2.9, CFG, 2.0, _drive(0.01, 0.0, False, calls),
                  _blocked(False, calls))[0] == YieldStep.DRIVE
    assert y.step([0.0, 0.0], 3.0, CFG, 2.0, _drive(0.01, 0.0, False, calls),
                  _blocked(False, calls))[0] == YieldStep.ARRIVED   # still for stuck_time
    y = Yield(np.array([5.0, 0.0]), 0.0, t_phase=0.0)
    assert y.step([0.0, 0.0], 9.9, CFG, 2.0, _drive(0.2, 0.0, True, calls),
                  _blocked(False, calls))[0] == YieldStep.DRIVE
    assert y.step([0.0, 0.0], 10.0, CFG, 2.0, _drive(0.2, 0.0, True, calls),
                  _blocked(False, calls))[0] == YieldStep.ARRIVED   # yield_timeout / 2


def test_a_yield_whose_retreat_cannot_start_ends_instead_of_waiting_where_it_stands():
    calls = []
    y = Yield(np.array([5.0, 0.0]), 0.0, t_phase=0.0, start=np.array([0.0, 0.0]))
    assert y.step([0.01, 0.0], 1.0, CFG, 2.0, _drive(0.0, 0.0, False, calls),
                  _blocked(True, calls))[0] == YieldStep.DRIVE
    assert y.step([0.02, 0.0], 3.0, CFG, 2.0, _drive(0.0, 0.0, False, calls),
                  _blocked(True, calls)) == (YieldStep.DONE, 0.0, 0.0)  # 2 cm: no retreat
    assert y.phase == "drive"
    # one that did get off its spot waits as before
    y = Yield(np.array([5.0, 0.0]), 0.0, t_phase=0.0, start=np.array([0.0, 0.0]))
    y.step([0.2, 0.0], 1.0, CFG, 2.0, _drive(0.0, 0.0, False, calls), _blocked(True, calls))
    assert y.step([0.2, 0.0], 3.0, CFG, 2.0, _drive(0.0, 0.0, False, calls),
                  _blocked(True, calls))[0] == YieldStep.ARRIVED
    assert y.phase == "wait"


def test_yield_waits_at_least_the_minimum_and_at_most_the_timeout():
    calls = []
    y = Yield(np.array([0.0, 0.0]), 0.0, phase="wait", t_phase=5.0, clear_since=0.0)
    # clear for long enough, but the wait began only 0.9 s ago (yield_min_wait 1 s)
    assert y.step([0.0, 0.0], 5.9, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(False, calls))[0] == YieldStep.WAIT
    assert y.step([0.0, 0.0], 6.0, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(False, calls))[0] == YieldStep.DONE
    y = Yield(np.array([0.0, 0.0]), 0.0, phase="wait", t_phase=5.0)
    assert y.step([0.0, 0.0], 19.9, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(True, calls))[0] == YieldStep.WAIT
    assert y.step([0.0, 0.0], 20.0, CFG, 2.0, _drive(0, 0, True, calls),
                  _blocked(True, calls))[0] == YieldStep.DONE       # yield_timeout after t0


def test_oncoming_centres_is_oncoming_on_arrays():
    rng = np.random.default_rng(2)
    robots = [seen(*rng.uniform(-3, 3, 2), *rng.uniform(-0.3, 0.3, 2)) for _ in range(40)]
    robots += [seen(1.0, 1.0, np.nan, 0.1), seen(0.0, 0.0, -0.5, 0.0)]
    centres = np.array([r.centre for r in robots])
    velocities = np.array([r.velocity for r in robots])
    got = traffic.oncoming_centres(centres, velocities, [0.0, 0.0], 0.08)
    assert 0 < len(got) < len(robots)
    assert np.array_equal(got, oncoming(robots, [0.0, 0.0], 0.08))
    # the same robots, counted one by one as the rule reads
    one_by_one = [r.centre for r in robots
                  if np.hypot(*r.centre) > 1e-6 and np.all(np.isfinite(r.velocity))
                  and (r.velocity @ -r.centre) / np.hypot(*r.centre) > 0.08]
    assert np.allclose(got, np.array(one_by_one))


def test_compiled_keep_right_precheck_is_never_wrong_when_it_says_no_shift():
    """``core_kernels.may_keep_right`` lets the navigator skip :func:`keep_right` on most ticks:
    whenever it says False, ``keep_right`` of the oncoming robots must return the path
    unchanged; and it must say True for the shifts (random crowds around random paths, with
    robots exactly at the limits' edges too)."""
    from swarm_nav import core_kernels
    from swarm_nav.traffic import KEEP_RIGHT_LATERAL

    rng = np.random.default_rng(21)
    cm = build_costmap(grid_map(np.zeros((80, 80), dtype=np.int8), 0.05), CostmapConfig())
    cfg = TrafficConfig()
    said_no = shifted = 0
    for _ in range(3000):
        pose = np.array([*rng.uniform(1.0, 3.0, 2), rng.uniform(-4, 4)])
        heading = pose[2] + rng.normal(0.0, 0.3)
        n = int(rng.integers(1, 30))
        path = pose[:2] + np.outer(np.arange(n) * 0.05, [math.cos(heading), math.sin(heading)])
        k = int(rng.integers(0, 6))
        centres = pose[:2] + rng.uniform(-3.0, 3.0, (k, 2))
        velocities = rng.uniform(-0.3, 0.3, (k, 2))
        velocities[rng.random(k) < 0.2] = np.nan  # unknown velocity
        if k and rng.random() < 0.3:  # one robot exactly keep_right_distance away, dead ahead
            centres[0] = pose[:2] + cfg.keep_right_distance * np.array(
                [math.cos(pose[2]), math.sin(pose[2])])
            velocities[0] = -0.25 * np.array([math.cos(pose[2]), math.sin(pose[2])])
        oncoming = traffic.oncoming_centres(centres, velocities, pose[:2], 0.05)
        out = keep_right(path, pose, oncoming, cm, cfg)
        maybe = core_kernels.may_keep_right(
            centres, velocities, *pose, 0.05, cfg.keep_right_distance, math.pi / 2,
            np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1]),
            KEEP_RIGHT_LATERAL)
        if not maybe:
            said_no += 1
            assert np.array_equal(out, path)
        if not np.array_equal(out, path):
            shifted += 1
            assert maybe
    assert said_no > 500 and shifted > 100
