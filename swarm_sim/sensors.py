"""The robots' footprints and lidars, from the static world and the poses alone: no PyBullet.

:class:`swarm_sim.engine.SimEngine` renders its scans with a :class:`SwarmSensors`, and so can any
process that knows the world, the fleet, the seed and every robot's pose at a tick (step 1 of
docs/design/scaling.md: the sensors where the robots are).  The scans are the same to the last
bit wherever they are rendered, and a process may render only some robots' (``rows``): a beam's
range depends only on its own lidar's pose and the footprints, and the lidar noise is drawn for
every robot in every process, in the engine's order, from one generator seeded alike.

Frames: ``map``; a pose is (3,) x [m], y [m], yaw [rad] of the robot's ``base_footprint``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from swarm_scene.world import World, world_polygons
from swarm_sim.lidar import PlanarLidar, ScanPattern, counter_clockwise, polygons_to_segments


def same_model_kinds(models) -> tuple[list, np.ndarray]:
    """The distinct models (by identity, in order of first robot) and each robot's index into
    them, (N,) int."""
    kinds: list = []
    kind = np.empty(len(models), dtype=int)
    for i, model in enumerate(models):
        for k, known in enumerate(kinds):
            if known is model:
                kind[i] = k
                break
        else:
            kind[i] = len(kinds)
            kinds.append(model)
    return kinds, kind


def pad_polygons(polygons) -> np.ndarray:
    """(P, K, 2) of polygons with up to K vertices, each padded to K by repeating its last vertex.

    Args:
        polygons: sequence of (K_p, 2) vertex arrays x, y [m].
    """
    k = max(len(p) for p in polygons)
    return np.stack([np.vstack((p, np.repeat(p[-1:], k - len(p), axis=0))) for p in polygons])


def planar_lidar(world: World, lidar) -> PlanarLidar:
    """The planar lidar of one model (a :class:`swarm_scene.robot_model.LidarSpec`): the
    world's outlines at its scan height."""
    return PlanarLidar(
        polygons_to_segments(world_polygons(world, lidar.z - 1e-3, lidar.z + 1e-3)),
        ScanPattern.from_spec(lidar),
    )


class SwarmSensors:
    """Every robot's footprint and lidar in one world.

    Args:
        world: the static world.
        models: (N) robot ``i``'s model (:class:`swarm_scene.robot_model.RobotModel`); the same
            object for robots of one model.
        seed: seed of the generator of lidar noise (the simulator's ``--seed``).
        control_period: [s] simulated time between control ticks (a lidar scans every
            ``round(1 / (rate_hz * control_period))`` ticks, at least 1, from tick 0).

    Attributes:
        kinds: the distinct models, in order of first robot; kind: (N,) each robot's index in them.
        kind_lidars: one :class:`PlanarLidar` per model.
        lidar_periods: (N,) control ticks between two scans of each robot's lidar.
        rng: the generator of the lidar noise.
    """

    def __init__(self, world: World, models: Sequence, seed: int, control_period: float):
        self.models = tuple(models)
        self.n = len(self.models)
        kinds, self.kind = same_model_kinds(self.models)
        self.kinds = tuple(kinds)
        self.mixed = len(kinds) > 1
        self.rng = np.random.default_rng(seed)
        first = kinds[0] if kinds else None
        self._footprint = None if first is None else counter_clockwise(first.footprint)
        # a mix: (N, K, 2) every robot's own footprint, padded to the most vertices
        self._feet = (np.ascontiguousarray(pad_polygons(
            [counter_clockwise(m.footprint) for m in kinds])[self.kind]) if self.mixed else None)
        self._mounts = (np.array([m.lidar.pose for m in self.models], dtype=float) if self.mixed
                        else None)
        self.kind_lidars = tuple(planar_lidar(world, m.lidar) for m in kinds)
        self.kind_periods = np.array(
            [max(1, round(1.0 / (m.lidar.rate_hz * control_period))) for m in kinds], dtype=int)
        self.lidar_periods = self.kind_periods[self.kind]

    def footprints(self, poses: np.ndarray) -> np.ndarray:
        """(N, K, 2) footprint polygons of all robots at ``poses`` (N, 3) in ``map`` [m],
        counter-clockwise (a mix: each robot's own, padded to K vertices by repeating the
        last)."""
        # transform_points for every robot at once, the same operations in the same order (its
        # cos and sin are the C library's, as there; numpy's SIMD ones may round differently)
        yaw = poses[:, 2].tolist()
        c = np.array([math.cos(a) for a in yaw])[:, None]
        s = np.array([math.sin(a) for a in yaw])[:, None]
        if self._feet is None:
            fx, fy = self._footprint[:, 0][None, :], self._footprint[:, 1][None, :]
        else:
            fx, fy = self._feet[:, :, 0], self._feet[:, :, 1]
        return np.stack((poses[:, 0:1] + c * fx - s * fy, poses[:, 1:2] + s * fx + c * fy),
                        axis=2)

    def lidar_poses(self, poses: np.ndarray) -> np.ndarray:
        """(N, 3) poses of every robot's lidar in ``map``, the robots at ``poses`` (N, 3)."""
        mount = self.kinds[0].lidar.pose if self._mounts is None else self._mounts.T
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        return np.column_stack((
            poses[:, 0] + c * mount[0] - s * mount[1],
            poses[:, 1] + s * mount[0] + c * mount[1],
            poses[:, 2] + mount[2],
        ))

    def due_mask(self, ticks: int) -> np.ndarray:
        """(N,) bool: whose lidar scans at control tick ``ticks``."""
        return ticks % self.lidar_periods == 0

    def skip(self, ticks: int) -> None:
        """Draw the noise of control tick ``ticks``'s scans without casting any (nothing when no
        lidar is due): a process that renders none of that tick's scans, or catches up with the
        ticks before its first, keeps the generator where the simulator's is."""
        due = self.due_mask(ticks)
        for k, lidar in enumerate(self.kind_lidars):
            m = self.n if not self.mixed else int(((self.kind == k) & due).sum())
            if m and due.any():
                lidar.draw_noise(m, self.rng)

    def scans(self, poses: np.ndarray, ticks: int, rows=None) -> np.ndarray | list:
        """Ranges [m] of the robots' lidars at ``poses`` (N, 3) (REP 117), float32; the noise of
        every due robot is drawn whatever ``rows`` asks for.

        Args:
            poses: (N, 3) every robot's pose.
            ticks: the control tick (for a mix: whose lidar is due).
            rows: the robots whose scans are wanted (indices, ascending); None: all.

        Returns:
            One model: (M, B) the scans of ``rows`` (of every robot: M = N); call it only at a
            tick where the lidar is due.  A mix: a list of M entries, robot ``rows[j]``'s (B_i,)
            scan if its lidar is due at this tick, else None; the models cast in ``kinds``
            order, each drawing its noise from the one generator.
        """
        feet = self.footprints(poses)
        at = self.lidar_poses(poses)
        if not self.mixed:
            if rows is None:
                return self.kind_lidars[0].scan(at, feet, self.rng)
            rows = np.asarray(rows, dtype=int)
            noise = self.kind_lidars[0].draw_noise(self.n, self.rng)
            return self.kind_lidars[0].scan(at[rows], feet, self.rng, own=rows,
                                            noise=None if noise is None else noise[rows])
        due = self.due_mask(ticks)
        wanted = np.ones(self.n, dtype=bool) if rows is None else np.zeros(self.n, dtype=bool)
        if rows is not None:
            wanted[np.asarray(rows, dtype=int)] = True
        out: list = [None] * self.n
        for k, lidar in enumerate(self.kind_lidars):
            idx = np.flatnonzero((self.kind == k) & due)
            if not idx.size:
                continue
            noise = lidar.draw_noise(idx.size, self.rng)
            keep = wanted[idx]
            if not keep.any():
                continue
            mine = idx[keep]
            for i, ranges in zip(mine.tolist(), lidar.scan(
                    at[mine], feet, self.rng, own=mine,
                    noise=None if noise is None else noise[keep]), strict=True):
                out[i] = ranges
        return out if rows is None else [out[i] for i in np.asarray(rows, dtype=int).tolist()]
