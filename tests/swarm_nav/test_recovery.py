"""Progress checking and recovery behaviours."""

import math

import numpy as np
import pytest

from swarm_nav.config import RecoveryConfig
from swarm_nav.dwa import Footprint, footprint_gaps, point_gaps
from swarm_nav.recovery import (
    ProgressChecker,
    Recovery,
    RecoveryKind,
    backup_is_safe,
    escape_command,
    wait_time,
)
from tests.swarm_nav.helpers import WAFFLE_FOOTPRINT, unicycle_step

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


def _flank(side: float, gap: float, length: float = 0.3) -> np.ndarray:
    """Points of another robot's flank parallel to FP at pose (0, 0, 0), ``gap`` [m] off its
    left (side +1) or right (side -1) edge, over the same stretch of x."""
    y = FP.y_max + gap if side > 0 else FP.y_min - gap
    return np.column_stack((np.linspace(FP.x_min, FP.x_min + length, 31), np.full(31, y)))


def test_escape_slides_out_from_beside_a_robot_and_never_comes_nearer_than_its_padding():
    """Two robots side by side, 5 cm apart: driving straight keeps the gap, every turn closes
    it at first. The escape still gets out (the repulsion potential sees the flank shrink), and
    ends once the gap is escape_clearance."""
    other = _flank(+1, 0.05)
    pose = np.array([0.0, 0.0, 0.0])
    rec = Recovery(RecoveryKind.ESCAPE, pose, 0.0, CFG, FP, 0.05)
    v = w = 0.0
    gaps = []
    for k in range(200):
        v_cmd, w_cmd, done = rec.step(pose, other, k * 0.1)
        if done:
            break
        pose, v, w = unicycle_step(pose, v, w, v_cmd, w_cmd, 0.1)
        gaps.append(float(point_gaps(pose, other, FP).min()))
    else:
        raise AssertionError("the escape never ended")
    assert 0.0 < k * 0.1 <= CFG.time_allowance
    assert min(gaps) >= CFG.escape_padding - 0.005  # (the unicycle's acceleration lag)
    assert gaps[-1] >= CFG.escape_clearance - 0.01


def test_escape_does_nothing_with_room_or_without_a_way_out():
    pose = np.array([0.0, 0.0, 0.0])
    assert escape_command(pose, _flank(+1, CFG.escape_clearance + 0.01), FP, CFG) is None
    assert escape_command(pose, np.zeros((0, 2)), FP, CFG) is None
    # boxed in 1 cm off every side: no motion keeps escape_padding, so none is offered
    box = np.vstack([_flank(+1, 0.01, FP.x_max - FP.x_min), _flank(-1, 0.01, FP.x_max - FP.x_min),
                     np.column_stack((np.full(31, FP.x_min - 0.01), np.linspace(-0.2, 0.2, 31))),
                     np.column_stack((np.full(31, FP.x_max + 0.01), np.linspace(-0.2, 0.2, 31)))])
    assert escape_command(pose, box, FP, CFG) is None
    # robots on both flanks, 5 cm off: the escape drives along them, straight
    both = np.vstack([_flank(+1, 0.05), _flank(-1, 0.05)])
    v, w = escape_command(pose, both, FP, CFG)
    assert abs(v) == CFG.escape_speed and w == 0.0
    assert float(footprint_gaps(v * 0.5, 0.0, 0.0, both, FP)) >= 0.05 - 1e-9
