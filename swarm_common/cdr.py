"""Read the few fields a node needs straight from serialized ROS messages (CDR bytes), and write
the messages that are published every tick the same way.

Why: rclpy's deserialization builds a Python object per nested message.  A 300-pose
``nav_msgs/Path`` took 8 ms to deserialize and an ``nav_msgs/Odometry`` 72 us (its two 36-double
covariances become arrays) on this machine.  Every tick the navigators read their robot's
odometry (and scan), the simulator every robot's ``cmd_vel``, the dashboard the fleet's poses and
every new plan.  With ``raw=True`` subscriptions they get the bytes and this module picks out
the fields (a few ``struct`` reads, ~2 us; the scan's ranges as one array).  The writers
(:class:`OdometryWriter`, :class:`LaserScanWriter`, :class:`TwistStampedWriter`) go the other
way for what is published every tick: ``Publisher.publish`` takes bytes, and a message whose
frames and constants are laid out once costs a ``struct.pack`` and a join per tick instead of
rclpy's conversion of a Python message object (about 25 us of the ~90 us of CPU a publish
took; the rest is Fast DDS's).

Format: the OMG CDR (XCDR1) encoding that rmw_fastrtps writes: a 4-byte encapsulation header
(``00 01`` = little endian), then the fields in order, each primitive aligned to its own size
counted from the end of that header; a string is a ``uint32`` length (with the NUL) and the
bytes; a sequence is a ``uint32`` count and the elements (OMG CDR 1.x, section 9.3 "CDR Transfer
Syntax"; DDS-XTypes 1.3 section 7.4.3.5 "XCDR Version 1").  Only little-endian CDR is read; any
other encapsulation is a :class:`ValueError`.  The tests hold every reader against rclpy's own
serializer (``tests/swarm_common/test_cdr.py``).

Pure: no ROS import.
"""

from __future__ import annotations

import math
import struct

import numpy as np

from swarm_common.geometry import quaternion_to_yaw

__all__ = ["ODOM_PUBLISHED", "ROBOT_STATE", "SCAN_PUBLISHED", "CmdVelBatchWriter",
           "LaserScanWriter", "OdometryWriter", "PathWriter", "PoseArrayWriter",
           "RobotStatesWriter", "TwistStampedWriter", "cmd_vel_batch", "diagnostic_status",
           "header_stamp", "odom_pose", "odom_reading", "odometry_pose", "path_points",
           "pose_array", "robot_states", "scan_ranges", "scan_reading", "string_data",
           "tf_message", "twist_stamped"]

_CDR_LE = b"\x00\x01"
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")  # builtin_interfaces/Time: sec, nanosec
_POSE = struct.Struct("<3d4d")  # position x, y, z; orientation x, y, z, w
_TWIST_AT = 56 + 36 * 8  # pose (7 doubles) + its covariance, before the twist [bytes]
_TWIST = struct.Struct("<3d3d")  # linear x, y, z; angular x, y, z
_SCAN = struct.Struct("<7f")  # angle_min, angle_max, angle_increment, time_increment, scan_time,
# range_min, range_max


def _body(buf) -> memoryview:
    """The message without its encapsulation header; ValueError if not little-endian CDR."""
    view = memoryview(buf)
    if len(view) < 4 or bytes(view[:2]) != _CDR_LE:
        raise ValueError("not a little-endian CDR message")
    return view[4:]


def _decoded(read, buf):
    """``read`` (a reader of the message body) applied to ``buf``; a truncated message is a
    ValueError."""
    try:
        return read(_body(buf))
    except struct.error as exc:
        raise ValueError(f"truncated message: {exc}") from None


def _stamp_ns(body: memoryview) -> int:
    """The header stamp [ns] at the start of a message body."""
    sec, nanosec = _STAMP.unpack_from(body, 0)
    return sec * 1_000_000_000 + nanosec


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) & ~(n - 1)


def _skip_string(body: memoryview, pos: int) -> int:
    """The position after the string at ``pos`` (aligned to 4 first)."""
    pos = _align(pos, 4)
    (length,) = _U32.unpack_from(body, pos)
    end = pos + 4 + length
    if end > len(body):
        raise ValueError("string runs past the end of the message")
    return end


def _after_header(body: memoryview, pos: int = 0) -> int:
    """The position after a ``std_msgs/Header`` (stamp, frame_id) at ``pos``."""
    return _skip_string(body, _align(pos, 4) + 8)


def odom_pose(buf) -> tuple[int, float, float, float, float, float]:
    """The stamp, pose and velocity of a serialized ``nav_msgs/Odometry``.

    Args:
        buf: the message's CDR bytes (a ``raw=True`` subscription's argument).

    Returns:
        ``(stamp_ns, x, y, yaw, v, w)``: header stamp [ns]; position in the message's frame [m];
        yaw [rad] in (-pi, pi], NaN if the quaternion is not finite; forward speed [m/s] and
        turn rate [rad/s] (the twist's ``linear.x`` and ``angular.z``).

    Raises:
        ValueError: not little-endian CDR, or too short.
    """
    return _decoded(_odom_pose, buf)


def _odom_pose(body: memoryview) -> tuple[int, float, float, float, float, float]:
    pos = _odom_pose_at(body)
    x, y, _, qx, qy, qz, qw = _POSE.unpack_from(body, pos)
    vx, _, _, _, _, wz = _TWIST.unpack_from(body, pos + _TWIST_AT)
    if math.isfinite(qx) and math.isfinite(qy) and math.isfinite(qz) and math.isfinite(qw):
        yaw = quaternion_to_yaw(qx, qy, qz, qw)
    else:  # atan2 of infinities can be finite: say plainly that there is no heading
        yaw = math.nan
    return _stamp_ns(body), x, y, yaw, vx, wz


def _odom_pose_at(body: memoryview) -> int:
    """Where ``pose.pose`` of an ``nav_msgs/Odometry`` body starts."""
    return _align(_skip_string(body, _after_header(body)), 8)  # after child_frame_id


def odometry_pose(buf) -> tuple[int, tuple[float, ...]]:
    """The stamp and full pose of a serialized ``nav_msgs/Odometry`` (``/tf`` is built from it).

    Args:
        buf: the message's CDR bytes.

    Returns:
        ``(stamp_ns, (x, y, z, qx, qy, qz, qw))``: header stamp [ns]; position [m] and
        orientation quaternion in the message's frame.

    Raises:
        ValueError: not little-endian CDR, or too short.
    """
    return _decoded(lambda body: (_stamp_ns(body), _POSE.unpack_from(body, _odom_pose_at(body))),
                    buf)


def header_stamp(buf) -> int:
    """The stamp [ns] of a serialized message whose first field is a ``std_msgs/Header`` (or a
    ``builtin_interfaces/Time``, as ``rosgraph_msgs/Clock``).

    Raises:
        ValueError: not little-endian CDR, or too short.
    """
    return _decoded(_stamp_ns, buf)


def string_data(buf) -> str:
    """The ``data`` of a serialized ``std_msgs/String`` (bytes that are not UTF-8 replaced).

    Raises:
        ValueError: not little-endian CDR, or truncated.
    """
    return _decoded(_string_data, buf)


def _string_data(body: memoryview) -> str:
    end = _skip_string(body, 0)
    return bytes(body[4:max(end - 1, 4)]).decode("utf-8", errors="replace")


def path_points(buf) -> np.ndarray:
    """The positions of a serialized ``nav_msgs/Path``.

    Args:
        buf: the message's CDR bytes.

    Returns:
        (N, 2) array of x, y [m] in the path's frame (N may be 0).

    Raises:
        ValueError: not little-endian CDR, or truncated.
    """
    return _decoded(_path_points, buf)


def _path_points(body: memoryview) -> np.ndarray:
    pos = _align(_after_header(body), 4)
    (count,) = _U32.unpack_from(body, pos)
    pos += 4
    if count * 68 > len(body) - pos:  # a PoseStamped takes at least 68 bytes
        raise ValueError("path runs past the end of the message")
    out = np.empty((count, 2))
    unpack_xy = struct.Struct("<2d").unpack_from
    for k in range(count):
        pos = _align(_after_header(body, pos), 8)
        out[k] = unpack_xy(body, pos)
        pos += 56
    return out


def pose_array(buf) -> tuple[int, np.ndarray]:
    """The stamp and poses of a serialized ``geometry_msgs/PoseArray`` (``/swarm/poses``).

    Args:
        buf: the message's CDR bytes.

    Returns:
        ``(stamp_ns, poses)``: header stamp [ns]; (N, 3) array of x [m], y [m] and yaw [rad] in
        (-pi, pi] in the message's frame, N >= 0.

    Raises:
        ValueError: not little-endian CDR, or truncated.
    """
    return _decoded(_pose_array, buf)


def _pose_array(body: memoryview) -> tuple[int, np.ndarray]:
    pos = _align(_after_header(body), 4)
    (count,) = _U32.unpack_from(body, pos)
    if count == 0:  # an empty sequence has no padding after its count
        return _stamp_ns(body), np.zeros((0, 3))
    pos = _align(pos + 4, 8)
    if pos + _POSE.size * count > len(body):
        raise ValueError("poses run past the end of the message")
    p = np.frombuffer(body, dtype="<f8", count=7 * count, offset=pos).reshape(count, 7)
    yaw = quaternion_to_yaw(p[:, 3], p[:, 4], p[:, 5], p[:, 6])
    return _stamp_ns(body), np.column_stack((p[:, 0], p[:, 1], yaw))


def scan_ranges(buf) -> tuple[int, float, float, float, float, np.ndarray]:
    """The geometry and ranges of a serialized ``sensor_msgs/LaserScan``.

    Args:
        buf: the message's CDR bytes.

    Returns:
        ``(stamp_ns, angle_min, angle_increment, range_min, range_max, ranges)``: stamp [ns];
        first beam's angle and the step [rad] in the scan's frame; valid range limits [m];
        ranges (M,) float32 [m] (inf or nan: no return).

    Raises:
        ValueError: not little-endian CDR, or truncated.
    """
    return _decoded(_scan_ranges, buf)


def _scan_ranges(body: memoryview) -> tuple[int, float, float, float, float, np.ndarray]:
    pos = _align(_after_header(body), 4)
    angle_min, _, inc, _, _, range_min, range_max = _SCAN.unpack_from(body, pos)
    pos += _SCAN.size
    (count,) = _U32.unpack_from(body, pos)
    pos += 4
    if pos + 4 * count > len(body):
        raise ValueError("ranges run past the end of the message")
    ranges = np.frombuffer(body, dtype="<f4", count=count, offset=pos).copy()
    return _stamp_ns(body), angle_min, inc, range_min, range_max, ranges


def twist_stamped(buf) -> tuple[int, str, float, float]:
    """The stamp, frame and planar velocity of a serialized ``geometry_msgs/TwistStamped``.

    Args:
        buf: the message's CDR bytes.

    Returns:
        ``(stamp_ns, frame_id, v, w)``: header stamp [ns]; header frame; ``twist.linear.x``
        [m/s] and ``twist.angular.z`` [rad/s].

    Raises:
        ValueError: not little-endian CDR, truncated, or a frame that is not UTF-8.
    """
    return _decoded(_twist_stamped, buf)


def _twist_stamped(body: memoryview) -> tuple[int, str, float, float]:
    end = _after_header(body)  # frame_id: a uint32 length (with the NUL) at 8, the bytes at 12
    try:
        frame = bytes(body[12:max(end - 1, 12)]).decode()
    except UnicodeDecodeError as exc:
        raise ValueError(f"frame_id is not UTF-8: {exc}") from None
    v, _, _, _, _, w = _TWIST.unpack_from(body, _align(end, 8))
    return _stamp_ns(body), frame, v, w


def cmd_vel_batch(buf) -> tuple[int, list[str], np.ndarray]:
    """The robots and planar velocities of a serialized ``trajectory_msgs/MultiDOFJointTrajectory``
    used as a batch of control-tick answers (:data:`swarm_common.topics.CMD_VEL_BATCH`).

    Args:
        buf: the message's CDR bytes.

    Returns:
        ``(stamp_ns, names, vw)``: header stamp [ns] (the tick answered); ``joint_names`` (the
        robots' namespaces); (N, 2) ``linear.x`` [m/s] and ``angular.z`` [rad/s] of the first
        point's ``velocities``, in the names' order ((0, 2) without a point).

    Raises:
        ValueError: not little-endian CDR, truncated, a name that is not UTF-8, or a point
            whose velocities do not match the names one for one.
    """
    return _decoded(_cmd_vel_batch, buf)


def _cmd_vel_batch(body: memoryview) -> tuple[int, list[str], np.ndarray]:
    pos = _after_header(body)
    pos = _align(pos, 4)
    (n,) = _U32.unpack_from(body, pos)
    pos += 4
    names = []
    for _ in range(n):
        start = _align(pos, 4) + 4
        pos = _skip_string(body, pos)
        try:
            names.append(bytes(body[start:pos - 1]).decode())
        except UnicodeDecodeError as exc:
            raise ValueError(f"joint name is not UTF-8: {exc}") from None
    pos = _align(pos, 4)
    (points,) = _U32.unpack_from(body, pos)
    if points == 0:
        if n:
            raise ValueError(f"{n} joint names and no point")
        return _stamp_ns(body), names, np.zeros((0, 2))
    pos += 4
    (transforms,) = _U32.unpack_from(body, pos)  # geometry_msgs/Transform: 7 float64
    pos += 4
    if transforms:
        pos = _align(pos, 8) + 56 * transforms
    pos = _align(pos, 4)
    (count,) = _U32.unpack_from(body, pos)
    if count != n:
        raise ValueError(f"{n} joint names and {count} velocities")
    pos = _align(pos + 4, 8)
    if pos + 48 * count > len(body):
        raise ValueError("velocities run past the end of the message")
    twists = np.frombuffer(body, dtype="<f8", count=6 * count, offset=pos).reshape(count, 6)
    return _stamp_ns(body), names, twists[:, [0, 5]].copy()


def odom_reading(stamp_ns: int, x: float, y: float, yaw: float, v: float,
                 w: float) -> tuple[int, float, float, float, float, float]:
    """What :func:`odom_pose` reads from the odometry :class:`OdometryWriter` writes of this
    state (the simulator's ``swarm_ros.robot_topics.RobotTopics.publish_odom``), without the
    message: the yaw goes through the quaternion ``(0, 0, sin(yaw / 2), cos(yaw / 2))`` as there.

    Returns:
        ``(stamp_ns, x, y, yaw, v, w)`` as :func:`odom_pose` returns them.
    """
    qz, qw = math.sin(yaw / 2.0), math.cos(yaw / 2.0)
    if math.isfinite(qz) and math.isfinite(qw):
        yaw = quaternion_to_yaw(0.0, 0.0, qz, qw)
    else:
        yaw = math.nan
    return stamp_ns, x, y, yaw, v, w


def scan_reading(angle_min: float, angle_increment: float, range_min: float,
                 range_max: float) -> tuple[float, float, float, float]:
    """The geometry :func:`scan_ranges` reads from a scan :class:`LaserScanWriter` writes with
    these values (``float32`` fields): ``(angle_min, angle_increment, range_min, range_max)``."""
    return struct.unpack("<4f", struct.pack("<4f", angle_min, angle_increment, range_min,
                                            range_max))


ROBOT_STATE = np.dtype({"names": ["x", "y", "yaw", "v", "w", "published"],
                        "formats": ["<f8", "<f8", "<f8", "<f8", "<f8", "u1"],
                        "offsets": [0, 8, 16, 24, 32, 40], "itemsize": 48})
"""One robot's point of a :class:`RobotStatesWriter` cloud: its pose x [m], y [m], yaw [rad] in
``map`` and its velocity v [m/s], w [rad/s] (``float64``, the simulator's own values), and which
of its sensor messages the simulator writes at this tick (``published``: bit 0 its ``odom``,
bit 1 its ``scan``; a fault mutes them)."""
ODOM_PUBLISHED, SCAN_PUBLISHED = 1, 2
_POINT_FIELDS = (("x", 0, 8), ("y", 8, 8), ("yaw", 16, 8), ("v", 24, 8), ("w", 32, 8),
                 ("published", 40, 2))  # name, offset, PointField datatype (8 FLOAT64, 2 UINT8)


def robot_states(buf) -> tuple[int, np.ndarray]:
    """The tick and the robots' states of a serialized ``sensor_msgs/PointCloud2`` written by
    :class:`RobotStatesWriter` (:data:`swarm_common.topics.ROBOT_STATES`).

    Returns:
        ``(stamp_ns, states)``: the header stamp [ns] and (N,) :data:`ROBOT_STATE` records,
        robot ``i`` at ``i``.

    Raises:
        ValueError: not little-endian CDR, truncated, or fields other than
            :data:`ROBOT_STATE`'s.
    """
    return _decoded(_robot_states, buf)


def _robot_states(body: memoryview) -> tuple[int, np.ndarray]:
    pos = _align(_after_header(body), 4)
    height, width, nfields = struct.unpack_from("<3I", body, pos)
    pos += 12
    fields = []
    for _ in range(nfields):
        start = _align(pos, 4) + 4
        pos = _skip_string(body, pos)
        name = bytes(body[start:pos - 1]).decode(errors="replace")
        pos = _align(pos, 4)
        offset, datatype = struct.unpack_from("<IB", body, pos)
        pos = _align(pos + 5, 4) + 4  # the count (uint32)
        fields.append((name, offset, datatype))
    if tuple(fields) != _POINT_FIELDS:
        raise ValueError(f"fields {fields} are not the robot states' {list(_POINT_FIELDS)}")
    pos += 1  # is_bigendian
    pos = _align(pos, 4)
    point_step, _, count = struct.unpack_from("<3I", body, pos)
    pos += 12
    n = height * width
    if point_step != ROBOT_STATE.itemsize or count != n * point_step:
        raise ValueError(f"{n} points of {point_step} bytes in {count} bytes of data")
    if pos + count > len(body):
        raise ValueError("data runs past the end of the message")
    return _stamp_ns(body), np.frombuffer(body, dtype=ROBOT_STATE, count=n, offset=pos).copy()


# ------------------------------------------------------------------------------------ writers
_ENCAPSULATION = b"\x00\x01\x00\x00"  # little-endian CDR, no options (what rmw_fastrtps writes)
_ZERO_COVARIANCE = bytes(36 * 8)
_EMPTY_SEQUENCE = bytes(4)


def _pad(pos: int, n: int) -> bytes:
    """Zero bytes that align ``pos`` (counted from the end of the encapsulation) to ``n``."""
    return bytes(_align(pos, n) - pos)


def _string(pos: int, text: str) -> bytes:
    """A CDR string at ``pos`` with its alignment padding: uint32 length (with the NUL), bytes,
    NUL."""
    data = text.encode() + b"\x00"
    return _pad(pos, 4) + _U32.pack(len(data)) + data


def _header_tail(frame_id: str) -> bytes:
    """What follows a ``std_msgs/Header``'s stamp: its ``frame_id``."""
    return _string(_STAMP.size, frame_id)


def _stamp(stamp_ns: int) -> bytes:
    return _STAMP.pack(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)


class OdometryWriter:
    """Serialized ``nav_msgs/Odometry`` of a planar robot with fixed frames.

    Args:
        frame_id: the header's frame (``<ns>/odom``, or ``map`` for ground truth).
        child_frame_id: the body frame (``<ns>/base_footprint``).

    The covariances are zero, as the simulator's message objects had them.
    """

    _POSE_TWIST = struct.Struct("<3d4d" + "288x" + "3d3d")  # pose, its covariance, twist

    def __init__(self, frame_id: str, child_frame_id: str):
        head = _header_tail(frame_id)
        pos = _STAMP.size + len(head)
        child = _string(pos, child_frame_id)
        pos += len(child)
        self._middle = head + child + _pad(pos, 8)

    def write(self, stamp_ns: int, x: float, y: float, qz: float, qw: float, v: float,
              w: float) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: header stamp [ns] (>= 0).
            x: position x [m] in ``frame_id``.
            y: position y [m].
            qz: orientation quaternion z (a rotation about z: ``sin(yaw / 2)``).
            qw: orientation quaternion w (``cos(yaw / 2)``).
            v: ``twist.linear.x`` [m/s] in ``child_frame_id``.
            w: ``twist.angular.z`` [rad/s].
        """
        return b"".join((_ENCAPSULATION, _stamp(stamp_ns), self._middle,
                         self._POSE_TWIST.pack(x, y, 0.0, 0.0, 0.0, qz, qw,
                                               v, 0.0, 0.0, 0.0, 0.0, w), _ZERO_COVARIANCE))


class LaserScanWriter:
    """Serialized ``sensor_msgs/LaserScan`` with fixed geometry and no intensities.

    Args:
        frame_id: the lidar's frame (``<ns>/base_scan``).
        angle_min: first beam [rad].
        angle_max: last beam [rad].
        angle_increment: between beams [rad].
        scan_time: between two scans [s].
        range_min: [m].
        range_max: [m].
        time_increment: between beams [s] (0: all beams at the stamp).
    """

    def __init__(self, frame_id: str, angle_min: float, angle_max: float,
                 angle_increment: float, scan_time: float, range_min: float, range_max: float,
                 time_increment: float = 0.0):
        head = _header_tail(frame_id)
        pos = _STAMP.size + len(head)
        self._middle = head + _pad(pos, 4) + _SCAN.pack(
            angle_min, angle_max, angle_increment, time_increment, scan_time, range_min,
            range_max)

    def write(self, stamp_ns: int, ranges: np.ndarray) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: header stamp [ns] (>= 0).
            ranges: (M,) ranges [m], written as float32 (inf: no return).
        """
        data = np.ascontiguousarray(ranges, dtype="<f4")
        return b"".join((_ENCAPSULATION, _stamp(stamp_ns), self._middle,
                         _U32.pack(len(data)), data.tobytes(), _EMPTY_SEQUENCE))


class PathWriter:
    """Serialized ``nav_msgs/Path`` of planar positions, every pose in the path's frame and at
    its stamp with the identity orientation (a navigator's ``plan``).

    Args:
        frame_id: the frame of the path and of its poses (``map``).
    """

    def __init__(self, frame_id: str):
        self._head = _header_tail(frame_id)
        # one PoseStamped after the first: 8-aligned, so always the same bytes but for its data
        head = len(self._head)
        self._dtype = np.dtype([("stamp", "<i4", 2), ("frame", f"V{head}"),
                                ("pad", f"V{_align(8 + head, 8) - 8 - head}"),
                                ("pose", "<f8", 7)])

    def write(self, stamp_ns: int, points: np.ndarray) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: stamp [ns] (>= 0) of the path and of every pose.
            points: (N, 2) x, y [m].
        """
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        stamp = _stamp(stamp_ns)
        pos = _STAMP.size + len(self._head)
        parts = [_ENCAPSULATION, stamp, self._head, _pad(pos, 4), _U32.pack(len(points))]
        pos = _align(pos, 4) + 4
        if len(points):
            x, y = points[0]
            first = stamp + self._head
            parts += [first, _pad(pos + len(first), 8),
                      _POSE.pack(x, y, 0.0, 0.0, 0.0, 0.0, 1.0)]
        if len(points) > 1:
            rest = np.zeros(len(points) - 1, dtype=self._dtype)
            rest["stamp"] = _STAMP.unpack(stamp)
            rest["frame"] = np.frombuffer(self._head, dtype=f"V{len(self._head)}")[0]
            rest["pose"][:, 0], rest["pose"][:, 1] = points[1:, 0], points[1:, 1]
            rest["pose"][:, 6] = 1.0
            parts.append(rest.tobytes())
        return b"".join(parts)


class PoseArrayWriter:
    """Serialized ``geometry_msgs/PoseArray`` of planar poses (``/swarm/poses``).

    Args:
        frame_id: the header's frame (``map``).
    """

    def __init__(self, frame_id: str):
        self._head = _header_tail(frame_id)

    def write(self, stamp_ns: int, poses: np.ndarray) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: header stamp [ns] (>= 0).
            poses: (N, 3) x [m], y [m], yaw [rad]; each written as a position with z = 0 and a
                rotation about z (quaternion ``(0, 0, sin(yaw / 2), cos(yaw / 2))``).
        """
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        pos = _STAMP.size + len(self._head)
        parts = [_ENCAPSULATION, _stamp(stamp_ns), self._head, _pad(pos, 4),
                 _U32.pack(len(poses))]
        if len(poses):  # an empty sequence has no padding after its count
            pos = _align(pos, 4) + 4
            body = np.zeros((len(poses), 7), dtype="<f8")
            body[:, 0], body[:, 1] = poses[:, 0], poses[:, 1]
            body[:, 5], body[:, 6] = np.sin(poses[:, 2] / 2.0), np.cos(poses[:, 2] / 2.0)
            parts += [_pad(pos, 8), body.tobytes()]
        return b"".join(parts)


class TFMessageWriter:
    """Serialized ``tf2_msgs/TFMessage`` of planar transforms between fixed frame pairs (``/tf``).

    The frame names are fixed, so the bytes are laid out once; each :meth:`write` fills in the
    stamps and the transforms.

    Args:
        frames: (K) ``(frame_id, child_frame_id)`` of each transform, in order.
    """

    def __init__(self, frames):
        frames = list(frames)
        parts, pos = [_U32.pack(len(frames))], 4
        self._stamp_at: list[int] = []  # byte offset of each stamp (after the encapsulation)
        self._body_at: list[int] = []  # byte offset of each transform's 7 doubles
        for parent, child in frames:
            parts.append(_pad(pos, 4))
            pos = _align(pos, 4)
            self._stamp_at.append(pos)
            parts.append(bytes(_STAMP.size))
            pos += _STAMP.size
            for name in (parent, child):
                text = _string(pos, name)
                parts.append(text)
                pos += len(text)
            parts.append(_pad(pos, 8))
            pos = _align(pos, 8)
            self._body_at.append(pos)
            parts.append(bytes(_POSE.size))
            pos += _POSE.size
        self._template = bytes(b"".join(parts))

    def write(self, stamp_ns: int, transforms: np.ndarray) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: every transform's header stamp [ns] (>= 0).
            transforms: (K, 3) x [m], y [m], yaw [rad] of each child frame in its parent; each
                written as a translation with z = 0 and a rotation about z.
        """
        transforms = np.asarray(transforms, dtype=float).reshape(-1, 3)
        buf = bytearray(self._template)
        stamp = _stamp(stamp_ns)
        half = transforms[:, 2] / 2.0
        rows = np.zeros((len(transforms), 7))
        rows[:, 0], rows[:, 1] = transforms[:, 0], transforms[:, 1]
        rows[:, 5], rows[:, 6] = np.sin(half), np.cos(half)
        for k, (s_at, b_at) in enumerate(zip(self._stamp_at, self._body_at, strict=True)):
            buf[s_at:s_at + _STAMP.size] = stamp
            _POSE.pack_into(buf, b_at, *rows[k])
        return _ENCAPSULATION + bytes(buf)


class TwistStampedWriter:
    """Serialized ``geometry_msgs/TwistStamped`` of a planar command.

    Args:
        frame_id: the header's frame (``<ns>/base_footprint``).
    """

    def __init__(self, frame_id: str):
        head = _header_tail(frame_id)
        self._middle = head + _pad(_STAMP.size + len(head), 8)

    def write(self, stamp_ns: int, v: float, w: float) -> bytes:
        """The message's bytes: ``twist.linear.x`` = ``v`` [m/s], ``twist.angular.z`` = ``w``
        [rad/s], stamp [ns] (>= 0; 0 is "apply now" to the simulator)."""
        return b"".join((_ENCAPSULATION, _stamp(stamp_ns), self._middle,
                         _TWIST.pack(v, 0.0, 0.0, 0.0, 0.0, w)))


class CmdVelBatchWriter:
    """Serialized ``trajectory_msgs/MultiDOFJointTrajectory`` carrying one control tick's answers
    of several robots (:data:`swarm_common.topics.CMD_VEL_BATCH`): ``joint_names`` the robots'
    namespaces, one point whose ``velocities[i]`` is robot ``i``'s planar command in its own
    ``base_footprint`` (``linear.x``, ``angular.z``), no transforms or accelerations,
    ``time_from_start`` zero; the header's stamp is the tick answered, its frame empty (each
    velocity is in its own robot's frame).

    Each name's string is laid out once (:meth:`write` takes them by name).
    """

    def __init__(self):
        self._names: dict[str, bytes] = {}

    def _name(self, ns: str) -> bytes:
        """``ns`` as a CDR string padded to a multiple of 4 bytes (it starts aligned)."""
        chunk = self._names.get(ns)
        if chunk is None:
            data = ns.encode() + b"\x00"
            chunk = _U32.pack(len(data)) + data
            chunk += bytes(_align(len(chunk), 4) - len(chunk))
            self._names[ns] = chunk
        return chunk

    def write(self, stamp_ns: int, names, vw: np.ndarray) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: [ns] the tick answered (>= 0).
            names: (N) the robots' namespaces.
            vw: (N, 2) ``linear.x`` [m/s] and ``angular.z`` [rad/s], in the names' order.
        """
        vw = np.asarray(vw, dtype=float).reshape(-1, 2)
        if len(names) != len(vw):
            raise ValueError(f"{len(names)} names and {len(vw)} velocities")
        twists = np.zeros((len(vw), 6))
        twists[:, 0], twists[:, 5] = vw[:, 0], vw[:, 1]
        # header: stamp (8), empty frame_id (4 + 1, padded to 16); the names start aligned
        head = _stamp(stamp_ns) + _U32.pack(1) + b"\x00\x00\x00\x00"
        names_part = b"".join(map(self._name, names))
        pos = len(head) + 4 + len(names_part)
        # one point: no transforms, the velocities (aligned to 8), no accelerations, t = 0
        tail = _U32.pack(1) + _U32.pack(0) + _U32.pack(len(vw))
        pad = _pad(pos + len(tail), 8)
        return b"".join((_ENCAPSULATION, head, _U32.pack(len(names)), names_part, tail, pad,
                         twists.astype("<f8").tobytes(), _U32.pack(0), bytes(8)))


class RobotStatesWriter:
    """Serialized ``sensor_msgs/PointCloud2`` of every robot's state at a tick: one point per
    robot, in robot index order, of :data:`ROBOT_STATE`'s fields, in ``map``; height 1, dense.

    Args:
        n: the robots (the cloud's width).
    """

    def __init__(self, n: int):
        self.n = int(n)
        parts = [_header_tail("map")]
        pos = _STAMP.size + len(parts[0])
        parts.append(_pad(pos, 4) + struct.pack("<3I", 1, self.n, len(_POINT_FIELDS)))
        pos = _align(pos, 4) + 12
        for name, offset, datatype in _POINT_FIELDS:
            parts.append(_string(pos, name))
            pos += len(parts[-1])
            parts.append(_pad(pos, 4) + struct.pack("<IB", offset, datatype))
            pos = _align(pos, 4) + 5
            parts.append(_pad(pos, 4) + _U32.pack(1))
            pos = _align(pos, 4) + 4
        parts.append(b"\x00")  # is_bigendian
        pos += 1
        size = ROBOT_STATE.itemsize
        parts.append(_pad(pos, 4) + struct.pack("<3I", size, size * self.n, size * self.n))
        self._middle = b"".join(parts)
        self._states = np.zeros(self.n, dtype=ROBOT_STATE)

    def write(self, stamp_ns: int, poses: np.ndarray, v: np.ndarray, w: np.ndarray,
              published: np.ndarray) -> bytes:
        """The message's bytes.

        Args:
            stamp_ns: [ns] the tick.
            poses: (N, 3) x, y, yaw in ``map`` [m, m, rad].
            v: (N,) [m/s]; w: (N,) [rad/s].
            published: (N,) uint8, :data:`ODOM_PUBLISHED` | :data:`SCAN_PUBLISHED` per robot.
        """
        st = self._states
        st["x"], st["y"], st["yaw"] = poses[:, 0], poses[:, 1], poses[:, 2]
        st["v"], st["w"], st["published"] = v, w, published
        return b"".join((_ENCAPSULATION, _stamp(stamp_ns), self._middle, st.tobytes(),
                         b"\x01"))  # is_dense


def diagnostic_status(level: int, name: str, message: str, hardware_id: str,
                      values: dict[str, str]) -> bytes:
    """A serialized ``diagnostic_msgs/DiagnosticStatus`` (a navigator's ``nav_status``).

    Args:
        level: 0 OK, 1 WARN, 2 ERROR, 3 STALE (one byte).
        name: the status's name.
        message: its message.
        hardware_id: its hardware id.
        values: its ``KeyValue`` pairs, in order.
    """
    parts = [_ENCAPSULATION, bytes((level,))]
    pos = 1
    for text in (name, message, hardware_id):
        parts.append(_string(pos, text))
        pos += len(parts[-1])
    parts.append(_pad(pos, 4) + _U32.pack(len(values)))
    pos = _align(pos, 4) + 4
    for key, value in values.items():
        for text in (key, value):
            parts.append(_string(pos, text))
            pos += len(parts[-1])
    return b"".join(parts)


def tf_message(transforms) -> bytes:
    """A serialized ``tf2_msgs/msg/TFMessage`` (no ``tf2_msgs`` wheel exists to build one).

    Args:
        transforms: ``(stamp_ns, parent, child, (x, y, z), (qx, qy, qz, qw))`` per
            ``geometry_msgs/TransformStamped``: stamp [ns], header frame, child frame,
            translation [m] and rotation quaternion.

    Layout: ``uint32`` count, then per transform ``int32 sec, uint32 nanosec``, ``frame_id`` and
    ``child_frame_id`` as strings, padding to 8, seven ``float64``.
    """
    parts = [_ENCAPSULATION, _U32.pack(len(transforms))]
    pos = 4
    for stamp_ns, parent, child, translation, rotation in transforms:
        head = _pad(pos, 4) + _stamp(stamp_ns)
        pos += len(head)
        parent_s = _string(pos, parent)
        pos += len(parent_s)
        child_s = _string(pos, child)
        pos += len(child_s)
        pose = _pad(pos, 8) + _POSE.pack(*translation, *rotation)
        pos += len(pose)
        parts += [head, parent_s, child_s, pose]
    return b"".join(parts)
