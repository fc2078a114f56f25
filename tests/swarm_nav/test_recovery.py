"""Progress checking, recovery behaviours and the communication-free deadlock rules."""

import math

import numpy as np
import pytest

from swarm_nav.config import CostmapConfig, RecoveryConfig
from swarm_nav.costmap import build_costmap
from swarm_nav.dwa import Footprint
from swarm_nav.recovery import (
    ProgressChecker,
    Recovery,
    RecoveryKind,
    backup_is_safe,
    keep_right,
    must_yield,
    retreat_candidates,
    robots_ahead,
    wait_time,
)
from tests.swarm_nav.helpers import WAFFLE_FOOTPRINT, grid_map, slim_blockage_map, unicycle_step

CFG = RecoveryConfig()
FP = Footprint.from_polygon(WAFFLE_FOOTPRINT)


def test_progress_checker_is_nav2s():
    pc = ProgressChecker(CFG)
    pc.reset([0.0, 0.0], 0.0)
    assert pc.check([0.3, 0.0], 9.9)
    assert not pc.check([0.3, 0.0], 10.0)          # 0.3 m in 10 s: no progress
    assert pc.check([0.5, 0.0], 10.1)              # 0.5 m: re-anchored
    assert pc.check([0.6, 0.0], 20.0)
    assert not pc.check([0.6, 0.0], 20.1)


def run(rec, pose, obstacles, t0=0.0, limit=400):
    v = w = 0.0
    t = t0
    for _ in range(limit):
        v_cmd, w_cmd, done = rec.step(pose, obstacles, t)
        if done:
            return pose, t
        pose, v, w = unicycle_step(pose, v, w, v_cmd, w_cmd, 0.1)
        t += 0.1
    raise AssertionError("the recovery never ended")


def test_backup_drives_back_the_distance():
    pose = np.array([0.0, 0.0, 0.5])
    end, t = run(Recovery(RecoveryKind.BACKUP, pose, 0.0, CFG, FP, 0.04), pose, np.zeros((0, 2)))
    back = end[:2] - pose[:2]
    assert np.hypot(*back) == pytest.approx(CFG.backup_dist, abs=0.02)
    assert back @ [math.cos(0.5), math.sin(0.5)] < 0
    assert t == pytest.approx(CFG.backup_dist / CFG.backup_speed, abs=0.25)


def test_backup_stops_before_an_obstacle_behind():
    wall_x = -0.197 - 0.12   # a wall 12 cm behind the rear edge
    wall = np.column_stack((np.full(21, wall_x), np.linspace(-0.5, 0.5, 21)))
    pose = np.array([0.0, 0.0, 0.0])
    end, _ = run(Recovery(RecoveryKind.BACKUP, pose, 0.0, CFG, FP, 0.04), pose, wall)
    gap = (end[0] - 0.197) - wall_x
    assert 0.04 <= gap < 0.12                      # backed up, but kept the padding
    assert not backup_is_safe(pose, 0.1, wall + [0.09, 0.0], FP, 0.04)
    assert backup_is_safe(pose, 0.1, wall - [1.0, 0.0], FP, 0.04)


@pytest.mark.parametrize("index, factor", [(0, 1.0), (1, 1.5), (2, 2.0), (3, 1.0)])
def test_wait_is_staggered_by_the_robot_index(index, factor):
    assert wait_time(CFG, index) == pytest.approx(CFG.wait_duration * factor)
    pose = np.zeros(3)
    _, t = run(Recovery(RecoveryKind.WAIT, pose, 0.0, CFG, FP, 0.04, robot_index=index), pose,
               np.zeros((0, 2)))
    assert t == pytest.approx(CFG.wait_duration * factor, abs=0.11)


def test_spin_turns_the_angle_and_stops_when_blocked():
    pose = np.array([0.0, 0.0, 0.0])
    end, _ = run(Recovery(RecoveryKind.SPIN, pose, 0.0, CFG, FP, 0.04), pose, np.zeros((0, 2)))
    assert abs(math.remainder(end[2] - CFG.spin_dist, 2 * math.pi)) < 0.15
    side = np.array([[-0.2, -0.2], [-0.1, -0.2], [0.0, -0.2]])   # the rear swings into these
    end, _ = run(Recovery(RecoveryKind.SPIN, pose, 0.0, CFG, FP, 0.04), pose, side)
    assert abs(end[2]) < 0.5


def test_replan_is_immediate():
    rec = Recovery(RecoveryKind.REPLAN, np.zeros(3), 0.0, CFG, FP, 0.04)
    assert rec.step(np.zeros(3), np.zeros((0, 2)), 0.0) == (0.0, 0.0, True)


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
