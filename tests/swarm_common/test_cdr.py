"""The CDR readers of :mod:`swarm_common.cdr` against rclpy's own serializer."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, TwistStamped
from nav_msgs.msg import Odometry, Path
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from swarm_common.cdr import (
    CmdVelBatchWriter,
    LaserScanWriter,
    OdometryWriter,
    PathWriter,
    PoseArrayWriter,
    TFMessageWriter,
    TwistStampedWriter,
    cmd_vel_batch,
    diagnostic_status,
    header_stamp,
    odom_pose,
    odometry_pose,
    path_points,
    pose_array,
    scan_ranges,
    string_data,
    twist_stamped,
)


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
                                    twist_stamped, cmd_vel_batch])
@pytest.mark.parametrize("buf", [b"", b"\x00\x00\x00\x00" + bytes(200), b"\x00\x01\x00\x00\x05"])
def test_malformed_bytes_are_a_value_error(reader, buf):
    with pytest.raises(ValueError):
        reader(buf)


# --------------------------------------------------------------------------------- writers
# Held against rclpy's own deserializer (its serializer leaves alignment padding undefined, so
# the bytes are compared through the message, field by field), for frames of every length mod 4
# and 8.
FRAMES = ["", "a", "ab", "abc", "Srobot7/odom", "Srobot10/odom", "map", "ü/odom"]


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("child", ["", "Srobot7/base_footprint", "Srobot100/base_footprint"])
def test_odometry_writer_reads_back_with_rclpy(frame, child):
    buf = OdometryWriter(frame, child).write(12_345_000_001, 1.25, -3.5, 0.3, -0.95, 0.26, -1.8)
    msg = deserialize_message(buf, Odometry)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 345_000_001)
    assert (msg.header.frame_id, msg.child_frame_id) == (frame, child)
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    assert (p.x, p.y, p.z, q.x, q.y, q.z, q.w) == (1.25, -3.5, 0.0, 0.0, 0.0, 0.3, -0.95)
    t = msg.twist.twist
    assert (t.linear.x, t.linear.y, t.linear.z) == (0.26, 0.0, 0.0)
    assert (t.angular.x, t.angular.y, t.angular.z) == (0.0, 0.0, -1.8)
    assert not np.any(msg.pose.covariance) and not np.any(msg.twist.covariance)
    assert len(buf) == len(serialize_message(msg))
    assert odom_pose(buf)[:3] == (12_345_000_001, 1.25, -3.5)


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("n", [0, 1, 360])
def test_laser_scan_writer_reads_back_with_rclpy(frame, n):
    ranges = np.linspace(0.2, 3.4, n).astype(np.float32)
    if n:
        ranges[0] = np.inf
    writer = LaserScanWriter(frame, 0.0, 6.2657, 0.017453, 0.2, 0.12, 3.5)
    buf = writer.write(3_100_000_000, ranges)
    msg = deserialize_message(buf, LaserScan)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (
        3, 100_000_000, frame)
    assert (msg.angle_min, msg.angle_max, msg.angle_increment, msg.time_increment,
            msg.scan_time, msg.range_min, msg.range_max) == pytest.approx(
        (0.0, 6.2657, 0.017453, 0.0, 0.2, 0.12, 3.5))
    np.testing.assert_array_equal(np.asarray(msg.ranges, dtype=np.float32), ranges)
    assert len(msg.intensities) == 0
    assert len(buf) == len(serialize_message(msg))
    np.testing.assert_array_equal(scan_ranges(buf)[5], ranges)


@pytest.mark.parametrize("frame", FRAMES)
def test_twist_stamped_writer_reads_back_with_rclpy(frame):
    buf = TwistStampedWriter(frame).write(41_200_000_000, 0.26, -1.5)
    msg = deserialize_message(buf, TwistStamped)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (
        41, 200_000_000, frame)
    t = msg.twist
    assert (t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z) == (
        0.26, 0.0, 0.0, 0.0, 0.0, -1.5)
    assert len(buf) == len(serialize_message(msg))
    assert twist_stamped(buf) == (41_200_000_000, frame, 0.26, -1.5)


@pytest.mark.parametrize("name", FRAMES)
@pytest.mark.parametrize("values", [{}, {"a": ""}, {"state": "DRIVING", "goal_id": "12.300000000",
                                                   "reason": "ü", "abc": "de"}])
def test_diagnostic_status_reads_back_with_rclpy(name, values):
    buf = diagnostic_status(2, name, "ABORTED", "Srobot12", values)
    msg = deserialize_message(buf, DiagnosticStatus)
    assert (msg.level, msg.name, msg.message, msg.hardware_id) == (
        bytes((2,)), name, "ABORTED", "Srobot12")
    assert {kv.key: kv.value for kv in msg.values} == values
    assert [kv.key for kv in msg.values] == list(values)
    assert len(buf) == len(serialize_message(msg))


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("n", [0, 1, 100])
def test_pose_array_writer_reads_back_with_rclpy(frame, n):
    rng = np.random.default_rng(n)
    poses = np.column_stack((rng.uniform(-9, 9, n), rng.uniform(-5, 9, n),
                             rng.uniform(-math.pi, math.pi, n)))
    buf = PoseArrayWriter(frame).write(7_000_000_123, poses)
    msg = deserialize_message(buf, PoseArray)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (
        7, 123, frame)
    assert len(msg.poses) == n
    for p, (x, y, yaw) in zip(msg.poses, poses, strict=True):
        assert (p.position.x, p.position.y, p.position.z) == (x, y, 0.0)
        q = p.orientation
        assert (q.x, q.y) == (0.0, 0.0)
        assert (q.z, q.w) == pytest.approx((math.sin(yaw / 2), math.cos(yaw / 2)), abs=1e-15)
    assert len(buf) == len(serialize_message(msg))
    stamp, got = pose_array(buf)
    assert stamp == 7_000_000_123
    np.testing.assert_allclose(got, poses.reshape(-1, 3), atol=1e-12)


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("n", [0, 1, 2, 3, 301])
def test_path_writer_reads_back_with_rclpy(frame, n):
    rng = np.random.default_rng(n)
    points = np.column_stack((rng.uniform(-9, 9, n), rng.uniform(-5, 9, n)))
    buf = PathWriter(frame).write(12_500_000_000, points)
    msg = deserialize_message(buf, Path)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (
        12, 500_000_000, frame)
    assert len(msg.poses) == n
    for ps, (x, y) in zip(msg.poses, points, strict=True):
        assert (ps.header.stamp.sec, ps.header.stamp.nanosec, ps.header.frame_id) == (
            12, 500_000_000, frame)
        p, q = ps.pose.position, ps.pose.orientation
        assert (p.x, p.y, p.z, q.x, q.y, q.z, q.w) == (x, y, 0.0, 0.0, 0.0, 0.0, 1.0)
    assert len(buf) == len(serialize_message(msg))
    np.testing.assert_array_equal(path_points(buf), points.reshape(-1, 2))


@pytest.mark.parametrize("text", ["", "a", "abc", '{"robot": "Srobot1", "kind": "ready"}', "ä€"])
def test_string_data_matches_the_message(text):
    assert string_data(serialize_message(String(data=text))) == text


def test_string_data_of_a_truncated_message_is_a_value_error():
    with pytest.raises(ValueError):
        string_data(serialize_message(String(data="abcdef"))[:9])


def test_header_stamp_of_a_header_and_of_a_clock():
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 300_000_000
    assert header_stamp(serialize_message(msg)) == 12_300_000_000
    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = 7, 5
    assert header_stamp(serialize_message(clock)) == 7_000_000_005


def test_odometry_pose_is_the_full_pose():
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = "Srobot1/odom", "Srobot1/base_footprint"
    msg.header.stamp.sec = 3
    p = msg.pose.pose
    p.position.x, p.position.y, p.position.z = 1.5, -2.0, 0.25
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = 0.1, 0.2, 0.3, 0.9
    assert odometry_pose(serialize_message(msg)) == (
        3_000_000_000, (1.5, -2.0, 0.25, 0.1, 0.2, 0.3, 0.9))


@pytest.mark.parametrize("names", [[], ["S1"], ["Srobot1", "Srobot12", "Srobot100"],
                                   ["a", "ab", "abc", "abcd", "abcde"]])
def test_tf_message_writer_writes_what_rclpy_serializes(names):
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    frames = [(f"{ns}/odom", f"{ns}/base_footprint") for ns in names]
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(-9, 9, len(names)), rng.uniform(-9, 9, len(names)),
                             rng.uniform(-math.pi, math.pi, len(names))])
    stamp = 12_345_678_901
    msg = TFMessage()
    for (parent, child), (x, y, yaw) in zip(frames, poses, strict=True):
        t = TransformStamped()
        t.header.stamp.sec, t.header.stamp.nanosec = 12, 345_678_901
        t.header.frame_id, t.child_frame_id = parent, child
        t.transform.translation.x, t.transform.translation.y = x, y
        t.transform.rotation.z, t.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        msg.transforms.append(t)
    writer = TFMessageWriter(frames)
    ours = writer.write(stamp, poses)
    # the same layout (rclpy's serializer leaves padding bytes unset, so bytes may differ there)
    assert len(ours) == len(serialize_message(msg))
    assert deserialize_message(ours, TFMessage) == msg
    # the template is filled afresh each time: a second tick's bytes are that tick's
    back = deserialize_message(writer.write(stamp + 100_000_000, poses[::-1] if names else poses),
                               TFMessage)
    assert [t.header.stamp.nanosec for t in back.transforms] == [445_678_901] * len(names)


# Robots' names of every length mod 4, so that every string's padding is exercised.
BATCH_NAMES = [[], ["S"], ["Srobot1", "Srobot22", "Srobot333", "Srobot4444", "ü"],
               [f"Srobot{i}" for i in range(1, 51)]]


@pytest.mark.parametrize("names", BATCH_NAMES)
def test_cmd_vel_batch_writer_reads_back_with_rclpy(names):
    n = len(names)
    vw = np.column_stack((np.linspace(-0.26, 0.26, n), np.linspace(1.8, -1.8, n)))
    msg = deserialize_message(CmdVelBatchWriter().write(41_200_000_007, names, vw),
                              MultiDOFJointTrajectory)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (41, 200_000_007)
    assert msg.header.frame_id == "" and list(msg.joint_names) == names
    (point,) = msg.points
    assert len(point.transforms) == 0 and len(point.accelerations) == 0
    assert (point.time_from_start.sec, point.time_from_start.nanosec) == (0, 0)
    got = [(t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z)
           for t in point.velocities]
    assert got == [(v, 0.0, 0.0, 0.0, 0.0, w) for v, w in vw.tolist()]


@pytest.mark.parametrize("names", BATCH_NAMES)
@pytest.mark.parametrize("transforms", [0, 2])
def test_cmd_vel_batch_matches_the_message(names, transforms):
    from geometry_msgs.msg import Transform, Twist

    msg = MultiDOFJointTrajectory(joint_names=names)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 100_000_000
    msg.header.frame_id = "map"
    point = MultiDOFJointTrajectoryPoint(transforms=[Transform() for _ in range(transforms)])
    for k in range(len(names)):
        twist = Twist()
        twist.linear.x, twist.linear.y, twist.angular.z = 0.1 * k, 9.0, -0.2 * k
        point.velocities.append(twist)
    msg.points = [point, MultiDOFJointTrajectoryPoint()]
    stamp, got_names, vw = cmd_vel_batch(serialize_message(msg))
    assert (stamp, got_names) == (7_100_000_000, names)
    assert vw.shape == (len(names), 2)
    assert vw.tolist() == [[0.1 * k, -0.2 * k] for k in range(len(names))]


def test_cmd_vel_batch_refuses_names_without_their_velocities():
    msg = MultiDOFJointTrajectory(joint_names=["Srobot1", "Srobot2"])
    msg.points = [MultiDOFJointTrajectoryPoint()]
    with pytest.raises(ValueError, match="2 joint names and 0 velocities"):
        cmd_vel_batch(serialize_message(msg))
    msg.points = []
    with pytest.raises(ValueError, match="no point"):
        cmd_vel_batch(serialize_message(msg))
    with pytest.raises(ValueError, match="2 names and 1 velocities"):
        CmdVelBatchWriter().write(0, ["a", "b"], [(0.0, 0.0)])
