"""swarm_common.geometry: angles, rotations, transforms and the 2D convex hull, in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from swarm_common.geometry import (
    convex_hull_2d,
    matrix_to_pose,
    matrix_to_rpy,
    pose2d,
    pose_to_matrix,
    quaternion_to_matrix,
    quaternion_to_yaw,
    rpy_to_matrix,
    transform_points,
    wrap_angle,
    yaw_to_quaternion,
)

PI = math.pi

# ------------------------------------------------------------------------------------ angles


@pytest.mark.parametrize("angle, wrapped", [
    (0.0, 0.0), (PI, PI), (-PI, PI), (1.5 * PI, -0.5 * PI), (-1.5 * PI, 0.5 * PI),
    (2 * PI, 0.0), (7.0, 7.0 - 2 * PI), (-7.0, -7.0 + 2 * PI),
])
def test_wrap_angle_into_minus_pi_pi(angle, wrapped):
    assert wrap_angle(angle) == pytest.approx(wrapped, abs=1e-12)
    assert isinstance(wrap_angle(angle), float)


def test_wrap_angle_of_arrays_and_pose2d():
    got = wrap_angle(np.array([3 * PI, -3 * PI, 0.25]))
    assert got == pytest.approx([PI, PI, 0.25], abs=1e-12)
    assert pose2d(1, 2, 1.5 * PI) == pytest.approx([1.0, 2.0, -0.5 * PI])


@pytest.mark.parametrize("yaw", [0.0, 0.5, -2.0, PI, 3.5, -4.0])
def test_yaw_quaternion_round_trip_wraps(yaw):
    q = yaw_to_quaternion(yaw)
    assert q == pytest.approx((0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))
    assert math.hypot(*q) == pytest.approx(1.0)
    assert abs(wrap_angle(quaternion_to_yaw(*q) - yaw)) < 1e-12
    assert -PI < quaternion_to_yaw(*q) <= PI


# --------------------------------------------------------------------------------- rotations


@pytest.mark.parametrize("yaw", [0.0, 0.3, PI / 2, -2.5, PI, 1.5 * PI])
def test_rotation_about_z_closed_form(yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    expected = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(rpy_to_matrix(0.0, 0.0, yaw), expected, atol=1e-15)
    np.testing.assert_allclose(quaternion_to_matrix(*yaw_to_quaternion(yaw)), expected,
                               atol=1e-15)
    roll, pitch, back = matrix_to_rpy(expected)
    assert (roll, pitch) == (0.0, 0.0) or (abs(roll) < 1e-15 and abs(pitch) < 1e-15)
    assert back == pytest.approx(wrap_angle(yaw), abs=1e-12)   # 3 pi / 2 comes back as -pi / 2


def test_roll_and_pitch_closed_forms():
    a = 0.4
    c, s = math.cos(a), math.sin(a)
    np.testing.assert_allclose(rpy_to_matrix(a, 0.0, 0.0),
                               [[1, 0, 0], [0, c, -s], [0, s, c]], atol=1e-15)
    np.testing.assert_allclose(rpy_to_matrix(0.0, a, 0.0),
                               [[c, 0, s], [0, 1, 0], [-s, 0, c]], atol=1e-15)
    # fixed axes: R = Rz(yaw) Ry(pitch) Rx(roll)
    np.testing.assert_allclose(rpy_to_matrix(0.1, 0.2, 0.3),
                               rpy_to_matrix(0, 0, 0.3) @ rpy_to_matrix(0, 0.2, 0)
                               @ rpy_to_matrix(0.1, 0, 0), atol=1e-15)


@pytest.mark.parametrize("rpy", [(0.3, -0.4, 0.5), (-2.9, 1.2, 3.0), (0.0, 0.0, -math.pi),
                                 (1.0, math.pi / 2, 0.2)])
def test_rpy_matrix_round_trip(rpy):
    rot = rpy_to_matrix(*rpy)
    np.testing.assert_allclose(rot, Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rpy_to_matrix(*matrix_to_rpy(rot)), rot, atol=1e-9)



def test_gimbal_lock_puts_the_rotation_into_yaw():
    rot = rpy_to_matrix(0.3, PI / 2, 0.5)
    roll, pitch, yaw = matrix_to_rpy(rot)
    assert (roll, pitch) == (0.0, pytest.approx(PI / 2))
    assert yaw == pytest.approx(0.5 - 0.3)         # only yaw - roll is defined at pitch = pi/2
    np.testing.assert_allclose(rpy_to_matrix(roll, pitch, yaw), rot, atol=1e-9)


def test_quaternion_matrix_normalises_and_matches_scipy():
    q = (0.1, -0.2, 0.3, 0.9)
    n = math.sqrt(sum(v * v for v in q))
    np.testing.assert_allclose(quaternion_to_matrix(*(2.0 * v for v in q)),
                               Rotation.from_quat([v / n for v in q]).as_matrix(), atol=1e-12)
    np.testing.assert_array_equal(quaternion_to_matrix(0.0, 0.0, 0.0, 0.0), np.eye(3))


def test_pose_matrix_round_trip():
    pose = [1.0, -2.0, 0.5, 0.1, -0.2, 3.0]
    tf = pose_to_matrix(pose)
    np.testing.assert_allclose(tf[:3, :3], rpy_to_matrix(0.1, -0.2, 3.0), atol=0)
    assert tf[:3, 3].tolist() == [1.0, -2.0, 0.5]
    assert tf[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    assert matrix_to_pose(tf) == pytest.approx(pose, abs=1e-12)
    flat = matrix_to_pose(pose_to_matrix([0.0, 0.0, 0.0, 0.0, 0.0, -0.0]))
    assert all(math.copysign(1.0, v) == 1.0 for v in flat)    # no -0.0


# -------------------------------------------------------------------------------- transforms


def test_transform_points_closed_form():
    pose = np.array([1.0, 2.0, PI / 2])
    got = transform_points(pose, [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    assert got == pytest.approx(np.array([[1.0, 3.0], [0.0, 2.0], [1.0, 2.0]]), abs=1e-15)
    # a yaw of 3 pi / 2 is the same frame as -pi / 2
    a = transform_points(np.array([0.0, 0.0, 1.5 * PI]), [[2.0, 0.5]])
    b = transform_points(np.array([0.0, 0.0, -0.5 * PI]), [[2.0, 0.5]])
    assert a == pytest.approx(b, abs=1e-12) and a[0] == pytest.approx([0.5, -2.0], abs=1e-12)
    assert transform_points(pose, np.zeros((0, 2))).shape == (0, 2)
    assert transform_points(np.zeros(3), [3.0, 4.0]).tolist() == [[3.0, 4.0]]


# ------------------------------------------------------------------------------ convex hull


def test_hull_of_a_square_drops_inner_collinear_and_duplicate_points():
    pts = [[1, 1], [0, 0], [0.5, 0], [1, 0], [0, 1], [0.5, 0.5], [0, 0.5], [1, 1 + 1e-14]]
    hull = convex_hull_2d(np.array(pts, dtype=float))
    assert hull.tolist() == [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]   # CCW from min x


def test_hull_of_a_rotated_rectangle_and_a_triangle():
    corners = np.array([[-1.0, -0.5], [1.0, -0.5], [1.0, 0.5], [-1.0, 0.5]])
    rot = rpy_to_matrix(0.0, 0.0, 0.3)[:2, :2]
    pts = np.vstack((corners, np.random.default_rng(0).uniform(-0.4, 0.4, (50, 2)))) @ rot.T
    hull = convex_hull_2d(pts)
    assert len(hull) == 4
    x, y = hull[:, 0], hull[:, 1]
    assert 0.5 * (x @ np.roll(y, -1) - y @ np.roll(x, -1)) == pytest.approx(2.0)  # CCW: > 0
    turned = corners @ rot.T
    assert hull[0] == pytest.approx(turned[3])      # the lowest x, (-1, 0.5) turned, comes first
    assert hull[1] == pytest.approx(turned[0])      # then counter-clockwise
    tri = convex_hull_2d(np.array([[0.0, 0.0], [0.0, 2.0], [3.0, 0.0], [1.0, 0.5]]))
    assert tri.tolist() == [[0.0, 0.0], [3.0, 0.0], [0.0, 2.0]]


@pytest.mark.parametrize("pts", [
    [[0.0, 0.0], [1.0, 1.0]],                      # two points
    [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]],          # on a line
    [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]],          # one point
    [[0.0, 0.0], [1e-7, 0.0], [0.0, 1e-7]],        # an area of 5e-15 m^2
])
def test_hull_without_area_is_none(pts):
    assert convex_hull_2d(np.array(pts)) is None


def test_big_clouds_go_to_qhull_with_the_same_vertices():
    rng = np.random.default_rng(3)
    ang = rng.uniform(0, 2 * PI, 3000)
    r = np.sqrt(rng.uniform(0, 1, 3000))
    cloud = np.column_stack((r * np.cos(ang), r * np.sin(ang)))
    square = np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]])
    hull = convex_hull_2d(np.vstack((cloud, square)))
    assert sorted(map(tuple, hull.tolist())) == sorted(map(tuple, square.tolist()))
    x, y = hull[:, 0], hull[:, 1]
    assert 0.5 * (x @ np.roll(y, -1) - y @ np.roll(x, -1)) == pytest.approx(16.0)
    # below the threshold the monotone chain gives the same set
    small = convex_hull_2d(np.vstack((cloud[:500], square)))
    assert sorted(map(tuple, small.tolist())) == sorted(map(tuple, square.tolist()))
