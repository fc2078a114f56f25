"""The one array convention of the project, named once.

- ``Pose2D``: ``numpy.ndarray`` of shape (3,), ``x [m], y [m], yaw [rad]``, in the frame named by
  the caller (``map`` unless said otherwise); yaw in (-pi, pi].
- ``Path2D``: ``numpy.ndarray`` of shape (N, 2), ``x, y [m]`` in ``map``.
- ``Points2D``: ``numpy.ndarray`` of shape (M, 2), ``x, y [m]``.

Flat vectors, never (3, 1) columns.  Shapes are checked at public entry points only.
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


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw [rad] of a quaternion ``(x, y, z, w)`` (ZYX convention, as tf2's ``getYaw``)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def transform_points(pose: Pose2D, points: Points2D) -> Points2D:
    """Map (M, 2) points from the frame at ``pose`` into the parent frame of ``pose``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return np.column_stack(
        (pose[0] + c * pts[:, 0] - s * pts[:, 1], pose[1] + s * pts[:, 0] + c * pts[:, 1])
    )
