"""The one array convention of the project, named once.

- ``Pose2D``: ``numpy.ndarray`` of shape (3,), ``x [m], y [m], yaw [rad]``, in the frame named by
  the caller (``map`` unless said otherwise); yaw in (-pi, pi].
- ``Path2D``: ``numpy.ndarray`` of shape (N, 2), ``x, y [m]`` in ``map``.
- ``Points2D``: ``numpy.ndarray`` of shape (M, 2), ``x, y [m]``.

Flat vectors, never (3, 1) columns.  Shapes are checked at public entry points only.

Also the rotation and outline maths that the world and robot loaders share: rotation matrices of
fixed-axis roll, pitch, yaw (SDF's and URDF's ``rpy``: R = Rz(yaw) Ry(pitch) Rx(roll)) and of
quaternions, (4, 4) homogeneous transforms of 6-DoF poses, and the 2D convex hull (Andrew's
monotone chain). Tests: tests/swarm_common/test_geometry.py.
"""

from __future__ import annotations

import math

import numpy as np

Pose2D = np.ndarray
Path2D = np.ndarray
Points2D = np.ndarray


def wrap_angle(angle):
    """Wrap an angle or an array of angles [rad] into (-pi, pi]."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def pose2d(x: float, y: float, yaw: float) -> Pose2D:
    """Build a ``Pose2D`` (3,) from ``x, y [m]`` and ``yaw [rad]`` (wrapped)."""
    return np.array([float(x), float(y), wrap_angle(yaw)])


def yaw_to_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """Quaternion ``(x, y, z, w)`` of a rotation by ``yaw [rad]`` about +z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(x, y, z, w):
    """Yaw [rad] in [-pi, pi] of a quaternion ``(x, y, z, w)`` (ZYX convention, as tf2's
    ``getYaw``): ``atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))``.

    The one copy of this formula: floats give a float (``math.atan2``), arrays of equal shape an
    array, element by element (``numpy.arctan2``).
    """
    atan2 = np.arctan2 if isinstance(z, np.ndarray) else math.atan2
    return atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def transform_points(pose: Pose2D, points: Points2D) -> Points2D:
    """Map (M, 2) points from the frame at ``pose`` into the parent frame of ``pose``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return np.column_stack(
        (pose[0] + c * pts[:, 0] - s * pts[:, 1], pose[1] + s * pts[:, 0] + c * pts[:, 1])
    )


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix (3, 3) of fixed-axis roll, pitch, yaw [rad]: Rz(yaw) Ry(pitch) Rx(roll).

    This is SDF's (and URDF's) ``rpy`` convention.
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def matrix_to_rpy(rot: np.ndarray) -> tuple[float, float, float]:
    """Fixed-axis roll, pitch, yaw [rad] of a (3, 3) rotation matrix (inverse of rpy_to_matrix).

    At gimbal lock (pitch = ±pi/2) roll is set to 0 and the rotation is put into yaw.
    """
    pitch = math.asin(max(-1.0, min(1.0, -rot[2, 0])))
    if abs(rot[2, 0]) < 1.0 - 1e-12:
        roll = math.atan2(rot[2, 1], rot[2, 2])
        yaw = math.atan2(rot[1, 0], rot[0, 0])
    else:
        roll = 0.0
        yaw = math.atan2(-rot[0, 1], rot[1, 1])
    return roll, pitch, yaw


def pose_to_matrix(pose) -> np.ndarray:
    """Homogeneous (4, 4) transform of a (6,) pose x, y, z [m], roll, pitch, yaw [rad]."""
    x, y, z, roll, pitch, yaw = (float(v) for v in pose)
    tf = np.eye(4)
    tf[:3, :3] = rpy_to_matrix(roll, pitch, yaw)
    tf[:3, 3] = (x, y, z)
    return tf


def matrix_to_pose(tf: np.ndarray) -> np.ndarray:
    """The (6,) pose x, y, z [m], roll, pitch, yaw [rad] of a homogeneous (4, 4) transform."""
    return np.array([*tf[:3, 3], *matrix_to_rpy(tf[:3, :3])], dtype=float) + 0.0  # no -0.0


def quaternion_to_matrix(qx: float, qy: float, qz: float, qw: float) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion ``(x, y, z, w)`` (normalised; zero: identity)."""
    n = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw) or 1.0
    x, y, z, w = qx / n, qy / n, qz / n, qw / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def convex_hull_2d(points: np.ndarray) -> np.ndarray | None:
    """Counter-clockwise convex hull of 2D points (Andrew's monotone chain).

    Args:
        points: (P, 2) x, y [m]; coordinates are rounded to 1e-12 m first (so that copies of a
            point that differ by rounding noise are one).

    Returns:
        (K, 2) the hull's vertices x, y [m], counter-clockwise, without collinear vertices,
        starting at the lowest x (then lowest y); ``None`` when it has no area (fewer than three
        distinct points, all on a line, or an area of at most 1e-12 m^2). More than 2000
        distinct points are handed to Qhull (``scipy.spatial.ConvexHull``: same vertices,
        counter-clockwise, but starting where Qhull starts).
    """
    pts = np.unique(np.round(np.asarray(points, dtype=float), 12), axis=0)
    if len(pts) < 3:
        return None
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]

    def half(seq):
        chain: list[np.ndarray] = []
        for p in seq:
            while len(chain) >= 2:
                a, b = chain[-2], chain[-1]
                if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 1e-15:
                    break
                chain.pop()
            chain.append(p)
        return chain

    if len(pts) > 2000:  # big meshes: let Qhull do it
        from scipy.spatial import ConvexHull, QhullError

        try:
            hull = ConvexHull(pts)
        except QhullError:
            return None
        return pts[hull.vertices]
    lower, upper = half(pts), half(pts[::-1])
    hull = np.array(lower[:-1] + upper[:-1])
    if len(hull) < 3:
        return None
    x, y = hull[:, 0], hull[:, 1]
    area = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return hull if area > 1e-12 else None
