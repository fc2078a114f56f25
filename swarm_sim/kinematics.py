"""Differential-drive kinematics of the simulated robots, vectorised over the swarm.

Robots are driven as unicycles with the command ``(v, w)`` limited by the robot's velocity and
acceleration limits (``params/robots/<name>.yaml``), then integrated exactly along the arc
(closed form of the unicycle model, e.g. Siegwart & Nourbakhsh, *Introduction to Autonomous
Mobile Robots*, 2nd ed., §3.2).  Arrays: ``poses`` (N, 3) x [m], y [m], yaw [rad] in ``map``;
``v`` (N,) [m/s]; ``w`` (N,) [rad/s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_common.geometry import wrap_angle


@dataclass(frozen=True)
class DriveLimits:
    """Velocity and acceleration limits of a differential drive.

    Every field is a float, or an (N,) array of each robot's limit (a mixed fleet,
    :class:`swarm_sim.engine.SimEngine`); :func:`limit_twist` broadcasts either.

    Attributes:
        max_vel_x: forward speed limit [m/s].
        min_vel_x: reverse speed limit [m/s] (negative or zero).
        max_vel_theta: turn rate limit [rad/s].
        acc_lim_x: linear acceleration limit [m/s^2].
        acc_lim_theta: angular acceleration limit [rad/s^2].
    """

    max_vel_x: float = 0.26  # [m/s] TurtleBot3 waffle
    min_vel_x: float = -0.26  # [m/s]
    max_vel_theta: float = 1.82  # [rad/s]
    acc_lim_x: float = 2.5  # [m/s^2] nav2 DWB default
    acc_lim_theta: float = 3.2  # [rad/s^2] nav2 DWB default

    @classmethod
    def from_robot_limits(cls, limits) -> DriveLimits:
        """Build from a :class:`swarm_scene.robot_model.RobotLimits`."""
        return cls(
            max_vel_x=limits.max_vel_x,
            min_vel_x=limits.min_vel_x,
            max_vel_theta=limits.max_vel_theta,
            acc_lim_x=limits.acc_lim_x,
            acc_lim_theta=limits.acc_lim_theta,
        )


def limit_twist(v_cmd, w_cmd, v_now, w_now, limits: DriveLimits, dt: float):
    """Clamp commanded velocities to the velocity limits and the reachable window over ``dt``.

    Args:
        v_cmd, w_cmd: (N,) commanded linear [m/s] and angular [rad/s] velocities.
        v_now, w_now: (N,) current velocities.
        limits: the drive's limits (floats, or (N,) arrays per robot).
        dt: time over which the change happens [s].

    Returns:
        ``(v, w)``, two (N,) arrays: the velocities actually reached after ``dt``.
    """
    v = np.clip(np.asarray(v_cmd, dtype=float), limits.min_vel_x, limits.max_vel_x)
    w = np.clip(np.asarray(w_cmd, dtype=float), -limits.max_vel_theta, limits.max_vel_theta)
    dv = limits.acc_lim_x * dt
    dw = limits.acc_lim_theta * dt
    v = np.clip(v, np.asarray(v_now) - dv, np.asarray(v_now) + dv)
    w = np.clip(w, np.asarray(w_now) - dw, np.asarray(w_now) + dw)
    return v, w


def integrate_unicycle(poses, v, w, dt: float) -> np.ndarray:
    """Move unicycles for ``dt`` seconds at constant ``(v, w)``, exactly along the arc.

    Args:
        poses: (N, 3) x [m], y [m], yaw [rad].
        v: (N,) linear velocities [m/s].
        w: (N,) angular velocities [rad/s].
        dt: duration [s].

    Returns:
        (N, 3) new poses, yaw wrapped to (-pi, pi].
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    v = np.broadcast_to(np.asarray(v, dtype=float), poses.shape[:1])
    w = np.broadcast_to(np.asarray(w, dtype=float), poses.shape[:1])
    yaw = poses[:, 2]
    dyaw = w * dt
    straight = np.abs(dyaw) < 1e-9
    safe_w = np.where(straight, 1.0, w)
    # Arc: x' = x + v/w (sin(yaw + w dt) - sin yaw), y' = y - v/w (cos(yaw + w dt) - cos yaw)
    dx_arc = v / safe_w * (np.sin(yaw + dyaw) - np.sin(yaw))
    dy_arc = -v / safe_w * (np.cos(yaw + dyaw) - np.cos(yaw))
    mid = yaw + 0.5 * dyaw
    dx = np.where(straight, v * dt * np.cos(mid), dx_arc)
    dy = np.where(straight, v * dt * np.sin(mid), dy_arc)
    out = np.empty_like(poses)
    out[:, 0] = poses[:, 0] + dx
    out[:, 1] = poses[:, 1] + dy
    out[:, 2] = wrap_angle(yaw + dyaw)
    return out


def wheel_speeds(v, w, wheel_separation: float, wheel_radius: float):
    """Wheel angular speeds [rad/s] of a differential drive for body twist ``(v, w)``.

    Returns:
        ``(left, right)``: ``(v -/+ w L/2) / r`` with ``L`` the wheel separation [m] and ``r``
        the wheel radius [m].
    """
    half = 0.5 * wheel_separation
    v = np.asarray(v, dtype=float)
    w = np.asarray(w, dtype=float)
    return (v - w * half) / wheel_radius, (v + w * half) / wheel_radius
