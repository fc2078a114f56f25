"""The CDR readers of :mod:`swarm_common.cdr` against rclpy's own serializer."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, TwistStamped
from nav_msgs.msg import Odometry, Path
from rclpy.serialization import serialize_message
from sensor_msgs.msg import LaserScan

from swarm_common.cdr import odom_pose, path_points, pose_array, scan_ranges, twist_stamped


@pytest.mark.parametrize("ns", ["S", "Srobot1", "Srobot12", "Srobot100", "abc"])
@pytest.mark.parametrize("yaw", [0.0, 1.0, -2.5, math.pi])
def test_odom_pose_matches_the_message(ns, yaw):
    msg = Odometry()
    msg.header.frame_id = f"{ns}/odom"
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345_000_000
    msg.child_frame_id = f"{ns}/base_footprint"
    msg.pose.pose.position.x, msg.pose.pose.position.y = -7.25, 3.5
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = 0.26, -1.82
    stamp, x, y, got_yaw, v, w = odom_pose(serialize_message(msg))
    assert stamp == 12_345_000_000
    assert (x, y, v, w) == (-7.25, 3.5, 0.26, -1.82)
    assert math.isclose(math.remainder(got_yaw - yaw, math.tau), 0.0, abs_tol=1e-12)


@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan])
def test_odom_pose_of_a_non_finite_quaternion_has_no_yaw(bad):
    msg = Odometry()
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = bad, -math.inf
    assert math.isnan(odom_pose(serialize_message(msg))[3])


@pytest.mark.parametrize("frame", ["map", "m", "map12", ""])
@pytest.mark.parametrize("n", [0, 1, 2, 3, 301])
def test_path_points_match_the_message(frame, n):
    rng = np.random.default_rng(n)
    xy = rng.uniform(-10.0, 10.0, size=(n, 2))
    msg = Path()
    msg.header.frame_id = frame
    for x, y in xy:
        ps = PoseStamped()
        ps.header = msg.header
        ps.pose.position.x, ps.pose.position.y = float(x), float(y)
        ps.pose.orientation.w = 1.0
        msg.poses.append(ps)
    got = path_points(serialize_message(msg))
    assert got.shape == (n, 2)
    np.testing.assert_array_equal(got, xy)


def test_path_points_is_much_cheaper_than_deserializing():
    from rclpy.serialization import deserialize_message

    msg = Path()
    msg.header.frame_id = "map"
    for k in range(300):
        ps = PoseStamped()
        ps.header = msg.header
        ps.pose.position.x = 0.05 * k
        msg.poses.append(ps)
    buf = serialize_message(msg)
    t0 = time.perf_counter()
    for _ in range(5):
        path_points(buf)
    ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(5):
        deserialize_message(buf, Path)
    theirs = time.perf_counter() - t0
    assert ours < theirs / 3, (ours, theirs)


@pytest.mark.parametrize("frame", ["map", "m", "map12", ""])
@pytest.mark.parametrize("n", [0, 1, 2, 100])
def test_pose_array_matches_the_message(frame, n):
    rng = np.random.default_rng(n)
    xy = rng.uniform(-10.0, 10.0, size=(n, 2))
    yaw = rng.uniform(-math.pi, math.pi, size=n)
    msg = PoseArray()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 900_000_000
    for (x, y), a in zip(xy, yaw, strict=True):
        p = Pose()
        p.position.x, p.position.y = float(x), float(y)
        p.orientation.z, p.orientation.w = math.sin(a / 2), math.cos(a / 2)
        msg.poses.append(p)
    stamp, got = pose_array(serialize_message(msg))
    assert stamp == 7_900_000_000
    assert got.shape == (n, 3)
    np.testing.assert_array_equal(got[:, :2], xy)
    np.testing.assert_allclose(got[:, 2], yaw, atol=1e-12)


@pytest.mark.parametrize("frame", ["", "b", "Srobot7/base_footprint", "ü/base_link"])
def test_twist_stamped_matches_the_message(frame):
    msg = TwistStamped()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = 41, 200_000_000
    msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z = 0.26, 9.0, -1.5
    msg.twist.angular.x = 7.0
    assert twist_stamped(serialize_message(msg)) == (41_200_000_000, frame, 0.26, -1.5)
    msg.twist.linear.x = math.nan
    assert math.isnan(twist_stamped(serialize_message(msg))[2])


def test_scan_ranges_match_the_message():
    msg = LaserScan()
    msg.header.frame_id = "Srobot7/base_scan"
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 100_000_000
    msg.angle_min, msg.angle_max, msg.angle_increment = 0.0, 6.2657, 0.017453
    msg.range_min, msg.range_max = 0.12, 3.5
    ranges = np.linspace(0.2, 3.4, 360).astype(np.float32)
    ranges[10] = np.inf
    msg.ranges = ranges.tolist()
    stamp, a0, inc, rmin, rmax, got = scan_ranges(serialize_message(msg))
    assert stamp == 3_100_000_000
    assert (a0, rmin, rmax) == (0.0, pytest.approx(0.12), pytest.approx(3.5))
    assert inc == pytest.approx(0.017453)
    np.testing.assert_array_equal(got, ranges)


@pytest.mark.parametrize("reader", [odom_pose, path_points, pose_array, scan_ranges,
                                    twist_stamped])
@pytest.mark.parametrize("buf", [b"", b"\x00\x00\x00\x00" + bytes(200), b"\x00\x01\x00\x00\x05"])
def test_malformed_bytes_are_a_value_error(reader, buf):
    with pytest.raises(ValueError):
        reader(buf)
