"""Differential-drive kinematics: exact unicycle arcs, yaw wrap, dynamic window, wheel speeds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_scene.robot_model import RobotLimits
from swarm_sim.kinematics import DriveLimits, integrate_unicycle, limit_twist, wheel_speeds

WAFFLE = DriveLimits()  # TurtleBot3 waffle: 0.26 m/s, 1.82 rad/s, 2.5 m/s^2, 3.2 rad/s^2


def _one(pose, v, w, dt):
    return integrate_unicycle(np.array([pose], dtype=float), [v], [w], dt)[0]


# -- integrate_unicycle ------------------------------------------------------------------------


@pytest.mark.parametrize("pose, v, dt", [
    ((0.0, 0.0, 0.0), 0.2, 5.0),
    ((1.0, -2.0, math.pi / 2), 0.26, 2.0),
    ((-3.0, 4.0, math.pi), 0.1, 3.0),
    ((2.5, 0.5, -2.5), 0.22, 1.5),
    ((0.0, 0.0, 0.7), -0.26, 4.0),  # reversing
])
def test_straight_line(pose, v, dt):
    x0, y0, yaw = pose
    got = _one(pose, v, 0.0, dt)
    assert got == pytest.approx(
        [x0 + v * dt * math.cos(yaw), y0 + v * dt * math.sin(yaw), yaw], abs=1e-12)


@pytest.mark.parametrize("yaw0, w, dt, yaw1", [
    (0.0, 1.0, 1.0, 1.0),
    (0.5, -1.82, 0.5, 0.5 - 0.91),
    (-1.0, 0.3, 2.0, -0.4),
    (2.0, 1.0, 1.0, 3.0),
])
def test_pure_rotation(yaw0, w, dt, yaw1):
    got = _one((1.5, -0.5, yaw0), 0.0, w, dt)
    assert got == pytest.approx([1.5, -0.5, yaw1], abs=1e-12)


@pytest.mark.parametrize("v, w", [(0.2, 0.5), (0.26, 1.82), (0.1, 0.25), (0.3, -0.6),
                                  (-0.2, 0.4)])
def test_half_circle_closed_form(v, w):
    # After t = pi / |w| a unicycle starting at the origin with yaw 0 has turned by pi about the
    # centre (0, v / w): it is at (0, 2 v / w) heading backwards.
    got = _one((0.0, 0.0, 0.0), v, w, math.pi / abs(w))
    assert got[:2] == pytest.approx([0.0, 2.0 * v / w], abs=1e-12)
    assert abs(got[2]) == pytest.approx(math.pi, abs=1e-12)


@pytest.mark.parametrize("v, w", [(0.2, 0.5), (0.26, -1.82), (0.05, 0.1)])
def test_quarter_and_full_circle(v, w):
    r = v / w
    quarter = _one((0.0, 0.0, 0.0), v, w, 0.5 * math.pi / abs(w))
    assert quarter == pytest.approx([abs(r), r, math.copysign(math.pi / 2, w)], abs=1e-12)
    full = _one((3.0, -1.0, 0.4), v, w, 2.0 * math.pi / abs(w))
    assert full == pytest.approx([3.0, -1.0, 0.4], abs=1e-12)


@pytest.mark.parametrize("pose, v, w", [
    ((0.0, 0.0, 0.0), 0.2, 0.5),
    ((1.0, 2.0, 3.0), 0.26, -1.0),
    ((-4.0, 0.5, -2.8), 0.15, 1.82),
])
def test_arcs_compose_exactly(pose, v, w):
    # The arc is the exact solution: 100 steps of 0.01 s land where one 1 s step lands.
    many = np.array([pose], dtype=float)
    for _ in range(100):
        many = integrate_unicycle(many, [v], [w], 0.01)
    one = _one(pose, v, w, 1.0)
    assert many[0, :2] == pytest.approx(one[:2], abs=1e-12)
    assert math.remainder(many[0, 2] - one[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("w", [1e-10, -1e-10, 1e-8])
def test_nearly_straight_arc_is_continuous(w):
    # Below the straight-line threshold and just above it, the result is the straight line to
    # within the arc's sagitta (v t)^2 w / (2 v) [m].
    v, dt = 0.26, 1.0
    got = _one((0.0, 0.0, 0.3), v, w, dt)
    assert got[:2] == pytest.approx([v * math.cos(0.3), v * math.sin(0.3)], abs=1e-9)
    assert got[2] == pytest.approx(0.3 + w * dt, abs=1e-15)


@pytest.mark.parametrize("yaw0, w, dt, yaw1", [
    (3.0, 1.0, 0.5, 3.5 - 2 * math.pi),        # through +pi
    (-3.0, -1.0, 0.5, -3.5 + 2 * math.pi),     # through -pi
    (math.pi / 2, math.pi / 2, 1.0, math.pi),   # exactly +pi stays +pi
    (-math.pi / 2, -math.pi / 2, 1.0, math.pi),  # exactly -pi is reported as +pi
    (0.0, 1.82, 10.0, 18.2 - 6 * math.pi),      # several turns
])
def test_yaw_wraps_into_minus_pi_pi(yaw0, w, dt, yaw1):
    got = _one((0.0, 0.0, yaw0), 0.0, w, dt)
    assert got[2] == pytest.approx(yaw1, abs=1e-12)
    assert -math.pi < got[2] <= math.pi


def test_yaw_wrap_while_driving_an_arc():
    # From yaw 3.0 turning left by 1 rad: the position follows the unwrapped arc.
    v, w, dt = 0.2, 0.5, 2.0
    got = _one((0.0, 0.0, 3.0), v, w, dt)
    r = v / w
    assert got == pytest.approx([r * (math.sin(4.0) - math.sin(3.0)),
                                 -r * (math.cos(4.0) - math.cos(3.0)),
                                 4.0 - 2 * math.pi], abs=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_vectorised_equals_per_robot(seed):
    rng = np.random.default_rng(seed)
    n = 64
    poses = rng.uniform([-10, -10, -math.pi], [10, 10, math.pi], size=(n, 3))
    v = rng.uniform(-0.26, 0.26, n)
    w = rng.uniform(-1.82, 1.82, n)
    w[::5] = 0.0  # straight lines mixed in with arcs
    v[::7] = 0.0  # and rotations on the spot
    got = integrate_unicycle(poses, v, w, 0.1)
    assert got.shape == (n, 3)
    each = np.array([_one(poses[i], v[i], w[i], 0.1) for i in range(n)])
    np.testing.assert_allclose(got, each, rtol=0.0, atol=1e-12)


def test_scalar_twist_broadcasts_over_the_swarm():
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, math.pi / 2], [2.0, -1.0, -math.pi / 2]])
    got = integrate_unicycle(poses, 0.2, 0.0, 1.0)
    np.testing.assert_allclose(got, [[0.2, 0.0, 0.0], [1.0, 1.2, math.pi / 2],
                                     [2.0, -1.2, -math.pi / 2]], atol=1e-12)
    np.testing.assert_array_equal(poses[0], [0.0, 0.0, 0.0])  # the input is not modified


# -- limit_twist: the dynamic window (Fox et al. 1997) -------------------------------------------


def test_drive_limits_from_the_robot_parameters():
    lim = DriveLimits.from_robot_limits(RobotLimits(
        max_vel_x=0.22, min_vel_x=-0.1, max_vel_theta=2.84, acc_lim_x=2.0, acc_lim_theta=3.0))
    assert (lim.max_vel_x, lim.min_vel_x, lim.max_vel_theta, lim.acc_lim_x,
            lim.acc_lim_theta) == (0.22, -0.1, 2.84, 2.0, 3.0)


@pytest.mark.parametrize("cmd, now, dt, expected", [
    ((0.1, 0.5), (0.1, 0.5), 0.1, (0.1, 0.5)),          # reachable: unchanged
    ((0.26, 1.82), (0.0, 0.0), 0.05, (0.125, 0.16)),    # acceleration-limited from rest
    ((0.26, 1.82), (0.0, 0.0), 0.1, (0.25, 0.32)),
    ((0.0, 0.0), (0.26, 1.82), 0.05, (0.135, 1.66)),    # deceleration-limited
    ((1.0, 9.0), (0.25, 1.8), 1.0, (0.26, 1.82)),       # velocity-limited
    ((-1.0, -9.0), (-0.25, -1.8), 1.0, (-0.26, -1.82)),
    ((-0.26, 0.0), (0.26, 0.0), 0.1, (0.01, 0.0)),      # reversing takes more than one step
    ((0.2, -0.3), (0.18, -0.25), 0.1, (0.2, -0.3)),
])
def test_limit_twist_values(cmd, now, dt, expected):
    v, w = limit_twist([cmd[0]], [cmd[1]], [now[0]], [now[1]], WAFFLE, dt)
    assert (v[0], w[0]) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("limits", [
    WAFFLE,
    DriveLimits(max_vel_x=0.22, min_vel_x=0.0, max_vel_theta=2.84, acc_lim_x=1.0,
                acc_lim_theta=2.0),
    DriveLimits(max_vel_x=0.4, min_vel_x=-0.4, max_vel_theta=1.8, acc_lim_x=2.5,
                acc_lim_theta=3.2),
])
@pytest.mark.parametrize("dt", [0.05, 0.1, 0.5])
def test_limit_twist_stays_inside_the_dynamic_window(limits, dt):
    rng = np.random.default_rng(7)
    n = 500
    v_now = rng.uniform(limits.min_vel_x, limits.max_vel_x, n)
    w_now = rng.uniform(-limits.max_vel_theta, limits.max_vel_theta, n)
    v_cmd = rng.uniform(-2.0, 2.0, n)
    w_cmd = rng.uniform(-5.0, 5.0, n)
    v, w = limit_twist(v_cmd, w_cmd, v_now, w_now, limits, dt)
    tol = 1e-12
    assert np.all(v >= limits.min_vel_x - tol) and np.all(v <= limits.max_vel_x + tol)
    assert np.all(np.abs(w) <= limits.max_vel_theta + tol)
    assert np.all(np.abs(v - v_now) <= limits.acc_lim_x * dt + tol)
    assert np.all(np.abs(w - w_now) <= limits.acc_lim_theta * dt + tol)
    # The reached twist is the window's point nearest the command.
    v_lo = np.maximum(limits.min_vel_x, v_now - limits.acc_lim_x * dt)
    v_hi = np.minimum(limits.max_vel_x, v_now + limits.acc_lim_x * dt)
    w_lo = np.maximum(-limits.max_vel_theta, w_now - limits.acc_lim_theta * dt)
    w_hi = np.minimum(limits.max_vel_theta, w_now + limits.acc_lim_theta * dt)
    np.testing.assert_allclose(v, np.clip(v_cmd, v_lo, v_hi), rtol=0.0, atol=tol)
    np.testing.assert_allclose(w, np.clip(w_cmd, w_lo, w_hi), rtol=0.0, atol=tol)


def test_ramp_to_full_speed_takes_max_over_acc():
    # 0 -> 0.26 m/s at 2.5 m/s^2 in 0.05 s steps: 0.125, 0.25, 0.26, 0.26.
    v, w = np.zeros(1), np.zeros(1)
    seen = []
    for _ in range(4):
        v, w = limit_twist([1.0], [0.0], v, w, WAFFLE, 0.05)
        seen.append(v[0])
    assert seen == pytest.approx([0.125, 0.25, 0.26, 0.26], abs=1e-12)


# -- wheel_speeds ------------------------------------------------------------------------------


@pytest.mark.parametrize("v, w, sep, r, left, right", [
    (0.2, 0.0, 0.287, 0.033, 0.2 / 0.033, 0.2 / 0.033),
    (0.0, 1.0, 0.287, 0.033, -0.1435 / 0.033, 0.1435 / 0.033),
    (0.26, 1.82, 0.287, 0.033, (0.26 - 1.82 * 0.1435) / 0.033, (0.26 + 1.82 * 0.1435) / 0.033),
    (-0.1, 0.5, 0.16, 0.033, -0.14 / 0.033, -0.06 / 0.033),
    (0.4, -1.8, 0.26, 0.045, (0.4 + 0.234) / 0.045, (0.4 - 0.234) / 0.045),
])
def test_wheel_speeds_closed_form(v, w, sep, r, left, right):
    wl, wr = wheel_speeds(v, w, sep, r)
    assert (float(wl), float(wr)) == pytest.approx((left, right), abs=1e-12)
    # ... and the forward kinematics give the twist back.
    assert r * (wl + wr) / 2 == pytest.approx(v, abs=1e-12)
    assert r * (wr - wl) / sep == pytest.approx(w, abs=1e-12)


def test_wheel_speeds_vectorised():
    v = np.array([0.0, 0.1, 0.2])
    w = np.array([1.0, 0.0, -1.0])
    wl, wr = wheel_speeds(v, w, 0.2, 0.05)
    np.testing.assert_allclose(wl, [-2.0, 2.0, 6.0], atol=1e-12)
    np.testing.assert_allclose(wr, [2.0, 2.0, 2.0], atol=1e-12)
