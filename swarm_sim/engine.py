"""The simulated world without ROS: PyBullet bodies, differential drives, contacts and lidars.

Robots are kinematic: each control tick their commanded twist is limited by the drive's
velocity and acceleration limits and integrated exactly (:mod:`swarm_sim.kinematics`); PyBullet
holds the static world and the robots' bodies and finds the contacts.  A robot whose new pose
penetrates a wall or another robot is put back where it was and stopped (a bumper), so bodies
never pass through each other; every robot–robot and robot–wall contact *episode* (from the first
penetration until the two are more than ``contact_release`` apart) is one collision event.

Frames: everything here is in ``map`` (= the world frame); robot ``i``'s pose is ``poses[i]``,
(3,) x [m], y [m], yaw [rad] of its ``base_footprint``.

A mixed fleet (robot ``i`` of model ``models[i]``) gives each robot its own body, drive limits
and lidar (beams, range, rate, mounting, scan height); every lidar sees every other robot by its
own footprint.  Footprints with fewer vertices than the largest are padded by repeating their last
vertex (a zero-length edge, which neither the lidar nor the separation kernel counts).  With one
model the arrays and operations are those of a one-model engine, so its runs stay the same to the
last bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarm_scene.world import World, obstacle_shapes
from swarm_sim import separation_kernels
from swarm_sim.kinematics import DriveLimits, integrate_unicycle, limit_twist
from swarm_sim.lidar import PlanarLidar, counter_clockwise
from swarm_sim.sensors import SwarmSensors, pad_polygons, planar_lidar

__all__ = ["CollisionEvent", "EngineConfig", "SimEngine", "pad_polygons", "polygon_distances"]


def _import_pybullet():
    """Import pybullet without the "pybullet build time" line it prints on the console."""
    import os
    import sys

    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        import pybullet as module
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)
    return module


pybullet = _import_pybullet()


@dataclass(frozen=True)
class EngineConfig:
    """Settings of the simulated world.

    Attributes:
        control_period: simulated time between control ticks [s]; nav2's controller runs at
            20 Hz and TurtleBot3's drive at 30 Hz, we default to 10 Hz (see docs/ARCHITECTURE.md).
        physics_substeps: kinematic integration and contact checks per control tick [-].
        contact_release: separation that ends a contact episode [m].
    """

    control_period: float = 0.1  # [s]
    physics_substeps: int = 2  # [-]
    contact_release: float = 0.02  # [m]


@dataclass(frozen=True)
class CollisionEvent:
    """The start of one contact episode.

    Attributes:
        t: simulated time [s].
        kind: ``"robot_robot"`` or ``"robot_wall"``.
        robot: index of the robot (the lower index for robot–robot).
        other: index of the other robot, or the wall shape's name.
        x, y: contact point in ``map`` [m].
    """

    t: float
    kind: str
    robot: int
    other: int | str
    x: float
    y: float


def polygon_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances [m] between pairs of convex polygons given as (P, K, 2) vertex arrays.

    The distance of two disjoint convex polygons is the least vertex-to-edge distance either
    way; overlapping ones (a vertex of one inside the other) give 0. Compiled
    (:func:`swarm_sim.separation_kernels.pair_distances`): the engine measures every pair of
    nearby robots every tick.
    """
    return separation_kernels.pair_distances(np.ascontiguousarray(a, dtype=float),
                                             np.ascontiguousarray(b, dtype=float))


class SimEngine:
    """A PyBullet world with ``n`` differential-drive robots, of one model or a mix.

    Args:
        world: the static world.
        robot: the robot model (:class:`swarm_scene.robot_model.RobotModel`) of every robot,
            or a sequence of N models (robot ``i`` is ``robot[i]``; :mod:`swarm_scene.fleet`).
        poses: (N, 3) spawn poses in ``map``.
        seed: seed of the generator of lidar noise.
        config: engine settings.
        gui: open PyBullet's window instead of running headless (``DIRECT``).

    Raises:
        ValueError: a sequence of models whose length is not N.
    """

    def __init__(self, world: World, robot, poses: np.ndarray, seed: int = 0,
                 config: EngineConfig | None = None, gui: bool = False):
        self.config = config or EngineConfig()
        self.poses = np.array(poses, dtype=float).reshape(-1, 3)
        self.n = self.poses.shape[0]
        models = tuple(robot) if isinstance(robot, list | tuple) else (robot,) * self.n
        if len(models) != self.n:
            raise ValueError(f"{len(models)} robot models for {self.n} robots")
        self.models = models
        """The model of every robot, (N,) tuple."""
        self.sensors = SwarmSensors(world, models, seed, self.config.control_period)
        """The footprints and lidars (:class:`swarm_sim.sensors.SwarmSensors`)."""
        self.kind = self.sensors.kind
        kinds = list(self.sensors.kinds) or [robot]  # no robots
        self.kinds = tuple(kinds)
        """The distinct models, in order of first robot; ``kind[i]`` indexes robot i's."""
        self.mixed = len(kinds) > 1
        self.robot = kinds[0]
        """The model (with a mix: the first robot's)."""
        if self.mixed:
            limits = [DriveLimits.from_robot_limits(m.limits) for m in models]
            self.limits = DriveLimits(**{f: np.array([getattr(lim, f) for lim in limits])
                                         for f in DriveLimits.__dataclass_fields__})
        else:
            self.limits = DriveLimits.from_robot_limits(self.robot.limits)
        self.v = np.zeros(self.n)
        self.w = np.zeros(self.n)
        self.t = 0.0  # [s]
        self.ticks = 0
        self.distance = np.zeros(self.n)  # [m] travelled per robot
        self.collisions = np.zeros(self.n, dtype=int)  # episodes per robot
        self.collision_counts = {"robot_robot": 0, "robot_wall": 0}
        self.min_separation = math.inf  # [m] least footprint-to-footprint gap seen
        self.rng = self.sensors.rng
        """The generator of the lidar noise (the sensors')."""
        self._radius = max(float(m.radius) for m in kinds)  # [m] the largest robot's
        self._active_contacts: dict[tuple, bool] = {}

        self.kind_lidars = (self.sensors.kind_lidars
                            or (self._planar_lidar(world, self.robot.lidar),))
        """One :class:`PlanarLidar` per model (``kinds``)."""
        self.kind_periods = (self.sensors.kind_periods if self.n
                             else np.array([self._period(self.robot.lidar)], dtype=int))
        self.lidar_periods = self.sensors.lidar_periods
        """(N,) control ticks between two scans of each robot's lidar."""
        self.lidar = self.kind_lidars[0]
        self.lidar_period_ticks = int(self.kind_periods[0])
        """Control ticks between two scans (with a mix: the first robot's; see
        ``lidar_periods``)."""

        self.client = pybullet.connect(pybullet.GUI if gui else pybullet.DIRECT)
        self._wall_names: dict[int, str] = {}
        self._build_world(world)
        self._bodies = self._build_robots()
        self._body_index = {b: i for i, b in enumerate(self._bodies)}
        separation_kernels.warm_up()
        self._update_min_separation()

    # -- construction --------------------------------------------------------------------------

    def _period(self, lidar) -> int:
        """Control ticks between two scans of ``lidar`` (a LidarSpec), at least 1."""
        return max(1, round(1.0 / (lidar.rate_hz * self.config.control_period)))

    @staticmethod
    def _planar_lidar(world: World, lidar) -> PlanarLidar:
        """The planar lidar of one model: the world's outlines at its scan height."""
        return planar_lidar(world, lidar)

    def _build_world(self, world: World) -> None:
        """One static body per obstacle of the world; floor slabs, ground planes and heightmaps
        get none (:func:`swarm_scene.world.obstacle_shapes`): a robot driving on them touches
        nothing, so no robot-wall contact is counted."""
        p, cid = pybullet, self.client
        for shape in obstacle_shapes(world):
            kind, size = shape.kind, shape.size
            if kind == "mesh" and shape.mesh_path is not None:
                self._build_mesh(shape)
                continue
            if kind == "box":
                col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[s / 2 for s in size],
                                             physicsClientId=cid)
            elif kind == "cylinder":
                col = p.createCollisionShape(p.GEOM_CYLINDER, radius=size[0], height=size[1],
                                             physicsClientId=cid)
            elif kind == "sphere":
                col = p.createCollisionShape(p.GEOM_SPHERE, radius=size[0], physicsClientId=cid)
            else:
                continue
            if col < 0:
                continue
            x, y, z, roll, pitch, yaw = shape.pose
            body = p.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=col, basePosition=[x, y, z],
                baseOrientation=p.getQuaternionFromEuler([roll, pitch, yaw]),
                physicsClientId=cid)
            self._wall_names[body] = shape.name

    def _build_mesh(self, shape) -> None:
        """One static body per part of a mesh (:mod:`swarm_scene.meshes`): a convex part as
        its hull, a non-convex one as a concave triangle mesh (static bodies only)."""
        from swarm_scene.meshes import load_mesh

        p, cid = pybullet, self.client
        x, y, z, roll, pitch, yaw = shape.pose
        for part in load_mesh(shape.mesh_path).parts:
            kwargs = {"vertices": part.vertices.tolist(), "meshScale": list(shape.size)}
            if not part.convex:
                kwargs.update(indices=part.faces.ravel().tolist(),
                              flags=p.GEOM_FORCE_CONCAVE_TRIMESH)
            col = p.createCollisionShape(p.GEOM_MESH, physicsClientId=cid, **kwargs)
            if col < 0:
                continue
            body = p.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=col, basePosition=[x, y, z],
                baseOrientation=p.getQuaternionFromEuler([roll, pitch, yaw]),
                physicsClientId=cid)
            self._wall_names[body] = shape.name

    def _build_robots(self) -> list[int]:
        p, cid = pybullet, self.client
        # Robots are seen by every lidar: their bodies reach at least the highest scan plane.
        scan_top = max(float(m.lidar.z) for m in self.kinds) + 0.02
        shapes = []
        for model in self.kinds:
            foot = counter_clockwise(model.footprint)
            lo, hi = foot.min(axis=0), foot.max(axis=0)
            centre = (lo + hi) / 2.0
            height = max(float(model.height), scan_top)
            shapes.append(p.createCollisionShape(
                p.GEOM_BOX, halfExtents=[*((hi - lo) / 2.0), height / 2.0],
                collisionFramePosition=[centre[0], centre[1], height / 2.0],
                physicsClientId=cid))
        bodies = []
        for pose, kind in zip(self.poses, self.kind, strict=True):
            bodies.append(p.createMultiBody(
                baseMass=1.0, baseCollisionShapeIndex=shapes[kind],
                basePosition=[pose[0], pose[1], 0.0],
                baseOrientation=p.getQuaternionFromEuler([0.0, 0.0, pose[2]]),
                physicsClientId=cid))
        p.setGravity(0, 0, 0, physicsClientId=cid)
        return bodies

    # -- queries -------------------------------------------------------------------------------

    def footprints(self, poses: np.ndarray | None = None) -> np.ndarray:
        """(N, K, 2) footprint polygons of all robots in ``map`` [m], counter-clockwise (a mix:
        each robot's own, padded to K vertices by repeating the last)."""
        return self.sensors.footprints(self.poses if poses is None else poses)

    def lidar_poses(self) -> np.ndarray:
        """(N, 3) poses of every robot's lidar in ``map``."""
        return self.sensors.lidar_poses(self.poses)

    def lidar_due(self) -> bool:
        """True when the current tick is a lidar tick of some robot (every ``1 / rate_hz``
        simulated seconds of its lidar, from tick 0)."""
        return bool(self.lidar_due_mask().any())

    def lidar_due_mask(self) -> np.ndarray:
        """(N,) bool: whose lidar scans at the current tick."""
        return self.sensors.due_mask(self.ticks)

    def scans(self) -> np.ndarray | list:
        """Ranges [m] of the robots' lidars at the current poses (REP 117), float32
        (:meth:`swarm_sim.sensors.SwarmSensors.scans`).

        Returns:
            One model: (N, B) every robot's scan.  A mix: a list of N entries, robot i's (B_i,)
            scan if its lidar is due at this tick (:meth:`lidar_due_mask`), else None; the
            models cast in ``kinds`` order, each drawing its noise from the one generator.
        """
        return self.sensors.scans(self.poses, self.ticks)

    # -- stepping ------------------------------------------------------------------------------

    def step(self, v_cmd: np.ndarray, w_cmd: np.ndarray,
             held: np.ndarray | None = None) -> list[CollisionEvent]:
        """Advance one control tick with the commanded twists.

        Args:
            v_cmd: (N,) commanded linear velocities [m/s] in ``base_footprint``.
            w_cmd: (N,) commanded angular velocities [rad/s].
            held: (N,) bool, robots held still this tick whatever they are commanded (a frozen
                or dead robot, :mod:`swarm_sim.faults`): their twist is zero at once, without
                the deceleration limit. None: none.

        Returns:
            The collision episodes that started during this tick.
        """
        cfg = self.config
        dt = cfg.control_period / cfg.physics_substeps
        v_target = np.asarray(v_cmd, dtype=float)
        w_target = np.asarray(w_cmd, dtype=float)
        events: list[CollisionEvent] = []
        for _ in range(cfg.physics_substeps):
            self.v, self.w = limit_twist(v_target, w_target, self.v, self.w, self.limits, dt)
            if held is not None:
                self.v[held] = 0.0
                self.w[held] = 0.0
            new = integrate_unicycle(self.poses, self.v, self.w, dt)
            moved = np.flatnonzero(np.any(new != self.poses, axis=1))
            self._set_body_poses(new, moved)
            self.t += dt  # the time of the new poses, when a contact starts
            blocked, started = self._contacts(new)
            events += started
            stopped: set[int] = set()
            while blocked - stopped:
                # Put blocked robots back; one put back may now overlap a robot that moved on
                # (a follower close behind): check again until nobody else is blocked.
                idx = np.fromiter(blocked - stopped, dtype=int)
                stopped |= blocked
                new[idx] = self.poses[idx]
                self.v[idx] = 0.0
                self.w[idx] = 0.0
                self._set_body_poses(new, idx)
                blocked, started = self._contacts(new)
                events += started
            self.distance += np.hypot(new[:, 0] - self.poses[:, 0], new[:, 1] - self.poses[:, 1])
            self.poses = new
        self.t = (self.ticks + 1) * cfg.control_period  # no drift from summing substeps
        self.ticks += 1
        self._update_min_separation()
        return events

    def _set_body_poses(self, poses: np.ndarray, which) -> None:
        p, cid = pybullet, self.client
        for i in which:
            x, y, yaw = poses[i]
            p.resetBasePositionAndOrientation(
                self._bodies[i], [x, y, 0.0], [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)],
                physicsClientId=cid)

    def _contacts(self, poses: np.ndarray) -> tuple[set[int], list[CollisionEvent]]:
        """Find penetrations, start new episodes, end released ones; return robots to block."""
        p, cid = pybullet, self.client
        p.performCollisionDetection(physicsClientId=cid)
        seen: dict[tuple, float] = {}
        where: dict[tuple, tuple[float, float]] = {}
        for c in p.getContactPoints(physicsClientId=cid):
            a, b, dist = c[1], c[2], c[8]
            ia, ib = self._body_index.get(a), self._body_index.get(b)
            if ia is None and ib is None:
                continue
            if ia is not None and ib is not None:
                key = ("r", min(ia, ib), max(ia, ib))
            else:
                key = ("w", ia if ia is not None else ib, b if ia is not None else a)
            if dist < seen.get(key, math.inf):
                seen[key] = dist
                where[key] = (c[5][0], c[5][1])
        blocked: set[int] = set()
        started: list[CollisionEvent] = []
        for key, dist in seen.items():
            if dist >= 0.0:
                continue
            blocked.update(key[1:] if key[0] == "r" else key[1:2])
            if key not in self._active_contacts:
                self._active_contacts[key] = True
                x, y = where[key]
                if key[0] == "r":
                    kind, other = "robot_robot", key[2]
                    self.collisions[key[2]] += 1
                else:
                    kind, other = "robot_wall", self._wall_names.get(key[2], str(key[2]))
                self.collisions[key[1]] += 1
                self.collision_counts[kind] += 1
                started.append(CollisionEvent(self.t, kind, key[1], other, x, y))
        release = self.config.contact_release
        for key in list(self._active_contacts):
            if seen.get(key, math.inf) < release:
                continue
            # Not in the contact list: measure the gap itself before ending the episode.
            a = self._bodies[key[1]]
            b = self._bodies[key[2]] if key[0] == "r" else key[2]
            if not p.getClosestPoints(a, b, distance=release, physicsClientId=cid):
                del self._active_contacts[key]
        return blocked, started

    def _update_min_separation(self) -> None:
        if self.n < 2:
            return
        reach = 2.0 * self._radius + 1.0
        d = np.linalg.norm(self.poses[:, None, :2] - self.poses[None, :, :2], axis=2)
        ii, jj = np.nonzero(np.triu(d < reach, k=1))
        if ii.size == 0:
            return
        feet = self.footprints()
        gaps = polygon_distances(feet[ii], feet[jj])
        self.min_separation = min(self.min_separation, float(gaps.min()))

    def close(self) -> None:
        """Disconnect from PyBullet."""
        if self.client is not None and pybullet.isConnected(self.client):
            pybullet.disconnect(self.client)
        self.client = None
