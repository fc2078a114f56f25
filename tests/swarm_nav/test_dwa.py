"""The local planner: dynamic window, exact rollouts, and never a colliding trajectory."""

import math

import numpy as np
import pytest

from swarm_nav.config import DwaConfig
from swarm_nav.dwa import (
    Command,
    Footprint,
    RobotState,
    dwa_command,
    dynamic_window,
    footprint_gaps,
    linspace,
    rotation_is_safe,
)
from tests.swarm_nav.helpers import WAFFLE_FOOTPRINT, rollout, unicycle_step

CFG = DwaConfig()
FP = Footprint.from_polygon(WAFFLE_FOOTPRINT)
DT = 0.1


def straight_path(pose, length=3.0, heading=None):
    h = pose[2] if heading is None else heading
    s = np.linspace(0.0, length, int(length / 0.1) + 1)
    return np.column_stack((pose[0] + s * math.cos(h), pose[1] + s * math.sin(h)))


def box_gap_exact(pose, pts, fp=FP):
    """Signed Chebyshev gap of points to the footprint box, written independently."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = np.asarray(pts) - pose[:2]
    lx = c * d[:, 0] + s * d[:, 1]
    ly = -s * d[:, 0] + c * d[:, 1]
    gx = np.maximum(fp.x_min - lx, lx - fp.x_max)
    gy = np.maximum(fp.y_min - ly, ly - fp.y_max)
    return np.maximum(gx, gy).min()


def test_footprint_of_the_waffle():
    assert (FP.x_min, FP.x_max, FP.y_min, FP.y_max) == (-0.197, 0.069, -0.133, 0.133)
    assert FP.centre == pytest.approx((-0.064, 0.0))
    assert FP.radius == pytest.approx(math.hypot(0.197, 0.133))


@pytest.mark.parametrize("v, w, window", [
    (0.0, 0.0, (0.0, 0.25, -0.32, 0.32)),
    (0.26, 0.9, (0.01, 0.26, 0.58, 1.0)),
    (0.1, -1.0, (0.0, 0.26, -1.0, -0.68)),
])
def test_dynamic_window(v, w, window):
    got = dynamic_window(RobotState(np.zeros(3), v, w), CFG, DT)
    assert got == pytest.approx(window)


def test_rollout_matches_integrated_kinematics():
    pose = np.array([1.0, -2.0, 2.5])
    v = np.array([0.2, 0.26, 0.0, 0.1])
    w = np.array([0.0, -0.8, 1.0, 0.3])
    times = np.array([0.5, 1.0, 1.7])
    x, y, th = rollout(pose, v, w, times)
    for i in range(len(v)):
        p = pose.copy()
        t = 0.0
        for k, tk in enumerate(times):
            while t < tk - 1e-9:  # fine integration at the commanded speed
                p, _, _ = unicycle_step(p, v[i], w[i], v[i], w[i], 0.001, w_lim=9.0)
                t += 0.001
            assert x[i, k] == pytest.approx(p[0], abs=1e-6)
            assert y[i, k] == pytest.approx(p[1], abs=1e-6)
            assert math.remainder(th[i, k] - p[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_footprint_gaps_against_an_independent_computation(seed):
    rng = np.random.default_rng(seed)
    poses = rng.uniform([-1, -1, -math.pi], [1, 1, math.pi], size=(20, 3))
    pts = rng.uniform(-1.5, 1.5, size=(40, 2))
    got = footprint_gaps(poses[:, 0], poses[:, 1], poses[:, 2], pts, FP)
    want = [box_gap_exact(p, pts) for p in poses]
    assert got == pytest.approx(want, abs=1e-12)


def _check_rollout_clear(state, cmd: Command, pts, cfg=CFG, need=None):
    """Roll the chosen command out independently, finely, and check every pose."""
    need = cfg.footprint_padding if need is None else need
    p = np.asarray(state.pose, dtype=float)
    for _ in range(int(round(cfg.sim_time / 0.01))):
        p, _, _ = unicycle_step(p, cmd.v, cmd.w, cmd.v, cmd.w, 0.01, w_lim=9.0)
        assert box_gap_exact(p, pts) >= need - 0.003  # what 10 ms steps may skip over


@pytest.mark.parametrize("seed", range(30))
def test_never_picks_a_colliding_trajectory_in_random_clouds(seed):
    rng = np.random.default_rng(seed)
    pose = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
    state = RobotState(pose, rng.uniform(0.0, 0.26), rng.uniform(-1.0, 1.0))
    pts = rng.uniform(-1.5, 1.5, size=(int(rng.integers(50, 400)), 2))
    pts = pts[[box_gap_exact(pose, p[None]) > 0.06 for p in pts]]  # the robot starts clear
    path = straight_path(pose, heading=rng.uniform(-math.pi, math.pi))
    cmd = dwa_command(state, path, pts, CFG, footprint=FP, dt=DT)
    v_lo, v_hi, w_lo, w_hi = dynamic_window(state, CFG, DT)
    assert v_lo - 1e-12 <= cmd.v <= v_hi + 1e-12
    assert w_lo - 1e-12 <= cmd.w <= w_hi + 1e-12 or (not cmd.ok and (cmd.v, cmd.w) == (0, 0))
    if cmd.ok:
        _check_rollout_clear(state, cmd, pts)
        assert cmd.min_gap >= CFG.footprint_padding
    elif cmd.w != 0.0:
        assert rotation_is_safe(pose, math.copysign(0.5, cmd.w), pts, FP, CFG.footprint_padding)


def test_free_space_full_speed_along_the_path():
    pose = np.array([0.0, 0.0, 0.0])
    cmd = dwa_command(RobotState(pose, 0.26, 0.0), straight_path(pose), np.zeros((0, 2)), CFG,
                      footprint=FP, dt=DT)
    assert cmd.ok and cmd.v == pytest.approx(0.26) and cmd.w == pytest.approx(0.0)


def test_turns_toward_a_path_to_the_left():
    pose = np.array([0.0, 0.0, 0.0])
    cmd = dwa_command(RobotState(pose, 0.1, 0.0), straight_path(pose, heading=math.pi / 2),
                      np.zeros((0, 2)), CFG, footprint=FP, dt=DT)
    assert cmd.ok and cmd.w > 0.2


def test_boxed_in_robot_stops():
    pose = np.array([0.0, 0.0, 0.0])
    xs = np.linspace(FP.x_min - 0.045, FP.x_max + 0.045, 30)
    ys = np.linspace(FP.y_min - 0.045, FP.y_max + 0.045, 30)
    pts = np.vstack([np.column_stack((xs, np.full(30, ys[0]))),
                     np.column_stack((xs, np.full(30, ys[-1]))),
                     np.column_stack((np.full(30, xs[0]), ys)),
                     np.column_stack((np.full(30, xs[-1]), ys))])  # 4.5 cm around the box
    cmd = dwa_command(RobotState(pose, 0.0, 0.0), straight_path(pose), pts, CFG, footprint=FP,
                      dt=DT)
    assert not cmd.ok and (cmd.v, cmd.w) == (0.0, 0.0)


def test_wall_ahead_rotates_in_place_if_that_is_all_that_is_safe():
    pose = np.array([0.0, 0.0, 0.0])
    y = np.linspace(-1.0, 1.0, 81)
    pts = np.column_stack((np.full_like(y, 0.069 + 0.05), y))   # a wall 5 cm ahead
    cmd = dwa_command(RobotState(pose, 0.0, 0.0), straight_path(pose, heading=math.pi / 2), pts,
                      CFG, footprint=FP, dt=DT)
    assert cmd.v <= 0.02
    if cmd.ok:
        _check_rollout_clear(RobotState(pose, 0.0, 0.0), cmd, pts)


def test_brakes_in_front_of_a_wall_in_closed_loop():
    """Driving at full speed at a wall across the path: it stops before it, never touches it."""
    y = np.linspace(-2.0, 2.0, 161)
    pts = np.column_stack((np.full_like(y, 1.5), y))
    pose, v, w = np.array([0.0, 0.0, 0.0]), 0.26, 0.0
    path = straight_path(pose, length=4.0)
    for _ in range(150):
        cmd = dwa_command(RobotState(pose, v, w), path, pts, CFG, footprint=FP, dt=DT)
        pose, v, w = unicycle_step(pose, v, w, cmd.v, cmd.w, DT)
        assert box_gap_exact(pose, pts) > 0.0
    assert box_gap_exact(pose, pts) >= CFG.footprint_padding - 0.01


def test_already_too_close_only_moves_away():
    pose = np.array([0.0, 0.0, 0.0])
    pts = np.array([[0.069 + 0.02, y] for y in np.linspace(-0.5, 0.5, 21)])  # 2 cm ahead
    state = RobotState(pose, 0.0, 0.0)
    cmd = dwa_command(state, straight_path(pose), pts, CFG, footprint=FP, dt=DT)
    if cmd.ok:
        _check_rollout_clear(state, cmd, pts, need=box_gap_exact(pose, pts))


def test_is_deterministic():
    rng = np.random.default_rng(7)
    pts = rng.uniform(-2, 2, size=(300, 2))
    pts = pts[np.hypot(*(pts - [-0.064, 0]).T) > 0.35]
    state = RobotState(np.array([0.0, 0.0, 0.3]), 0.1, 0.2)
    a = dwa_command(state, straight_path(state.pose), pts, CFG, footprint=FP, dt=DT)
    b = dwa_command(state, straight_path(state.pose), pts, CFG, footprint=FP, dt=DT)
    assert (a.v, a.w, a.ok, a.cost) == (b.v, b.w, b.ok, b.cost)


def test_rotation_is_safe():
    pose = np.array([0.0, 0.0, 0.0])
    assert rotation_is_safe(pose, math.pi, np.zeros((0, 2)), FP, 0.04)
    side = np.array([[0.0, 0.2], [-0.1, 0.2], [0.1, 0.2]])   # 7 cm left of the box
    assert not rotation_is_safe(pose, -math.pi / 2, side, FP, 0.04)  # the rear swings left
    assert rotation_is_safe(pose, -math.pi / 2, side + [0.0, 0.1], FP, 0.04)


def test_linspace_equals_numpys_bit_for_bit():
    rng = np.random.default_rng(11)
    for _ in range(20000):
        lo = float(rng.normal() * rng.choice([1e-3, 1.0, 10.0]))
        hi = lo + float(abs(rng.normal()) * rng.choice([0.0, 1e-300, 1e-9, 1e-3, 1.0, 10.0]))
        if rng.random() < 0.3:
            lo, hi = hi, lo
        num = int(rng.integers(1, 30))
        np.testing.assert_array_equal(linspace(lo, hi, num), np.linspace(lo, hi, num))
        assert linspace(lo, hi, num).dtype == np.float64
