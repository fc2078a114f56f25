"""Planar lidar: 2D ray casting against the world's outlines and the other robots' footprints.

PyBullet's ``rayTestBatch`` costs about 8 µs per ray on the target machine (≈ 300 ms for
100 robots × 360 beams), which alone caps a 100-robot swarm below real time.  A planar lidar only
needs the scan plane, so we intersect each beam with the 2D outline segments of everything that
crosses the lidar's height: static shapes (from :func:`swarm_scene.world.world_polygons`) and
robot bodies (their footprint polygons).  ``tests/swarm_sim/test_lidar.py`` checks the result
against ``rayTestBatch`` on the same geometry.

Ray–segment intersection: for a beam ``o + t d`` and a segment ``p + u e``,
``t = cross(p - o, e) / cross(d, e)`` and ``u = cross(p - o, d) / cross(d, e)``; a hit needs
``t >= 0`` and ``0 <= u <= 1`` (e.g. Ericson, *Real-Time Collision Detection*, §5.1.9).
Invalid readings follow REP 117: ``+inf`` when nothing is within ``range_max``, ``-inf`` when the
hit is closer than ``range_min``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_sim import lidar_kernels as kernels


@dataclass(frozen=True)
class ScanPattern:
    """The beams of one lidar, in the lidar's own frame.

    Attributes:
        angles: (B,) beam angles [rad], from ``angle_min`` to ``angle_max`` inclusive (Gazebo's
            convention: increment ``(max - min) / (samples - 1)``).
        range_min: shortest valid range [m].
        range_max: longest valid range [m].
        noise_stddev: standard deviation of the additive Gaussian range noise [m].
    """

    angles: np.ndarray
    range_min: float
    range_max: float
    noise_stddev: float

    @classmethod
    def from_spec(cls, spec) -> ScanPattern:
        """Build from a :class:`swarm_scene.robot_model.LidarSpec`."""
        n = int(spec.samples)
        angles = np.linspace(spec.angle_min, spec.angle_max, n) if n > 1 else np.array(
            [spec.angle_min]
        )
        return cls(angles, float(spec.range_min), float(spec.range_max), float(spec.noise_stddev))

    @property
    def angle_increment(self) -> float:
        """Angle between consecutive beams [rad] (0 for a single beam)."""
        return float(self.angles[1] - self.angles[0]) if self.angles.size > 1 else 0.0


def counter_clockwise(polygon) -> np.ndarray:
    """The (K, 2) polygon with its vertices in counter-clockwise order (positive signed area)."""
    poly = np.asarray(polygon, dtype=float).reshape(-1, 2)
    x, y = poly[:, 0], poly[:, 1]
    area2 = np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))
    return poly[::-1] if area2 < 0 else poly


def polygons_to_segments(polygons) -> np.ndarray:
    """Turn closed polygons into their edges, counter-clockwise (outward normal ``(ey, -ex)``).

    Args:
        polygons: iterable of (K, 2) vertex arrays x, y [m].

    Returns:
        (S, 4) array of segments ``x0, y0, x1, y1`` [m].
    """
    segs = [np.hstack((p, np.roll(p, -1, axis=0))) for p in map(counter_clockwise, polygons)
            if len(p) >= 2]
    return np.vstack(segs) if segs else np.zeros((0, 4))


def _point_segment_distance(points: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """(N, S) Euclidean distances [m] from (N, 2) points to (S, 4) segments."""
    p0 = segs[None, :, 0:2]
    e = segs[None, :, 2:4] - p0
    rel = points[:, None, :] - p0
    len2 = np.maximum(np.einsum("nsi,nsi->ns", e, e), 1e-18)
    u = np.clip(np.einsum("nsi,nsi->ns", rel, e) / len2, 0.0, 1.0)
    closest = p0 + u[..., None] * e
    return np.linalg.norm(points[:, None, :] - closest, axis=-1)


def cast_rays(origin: np.ndarray, directions: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Distance along each ray to the nearest segment.

    Args:
        origin: (2,) ray origin x, y [m].
        directions: (B, 2) unit direction vectors.
        segs: (S, 4) segments ``x0, y0, x1, y1`` [m].

    Returns:
        (B,) distances [m]; ``inf`` where a ray hits nothing.
    """
    if segs.shape[0] == 0:
        return np.full(directions.shape[0], np.inf)
    p = segs[:, 0:2] - origin  # (S, 2)
    e = segs[:, 2:4] - segs[:, 0:2]  # (S, 2)
    dx = directions[:, 0:1]
    dy = directions[:, 1:2]
    denom = dx * e[:, 1] - dy * e[:, 0]  # (B, S)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (p[:, 0] * e[:, 1] - p[:, 1] * e[:, 0]) / denom
        u = (p[:, 0] * dy - p[:, 1] * dx) / denom
    hit = (np.abs(denom) > 1e-12) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
    return np.where(hit, t, np.inf).min(axis=1)


class PlanarLidar:
    """Casts the scans of a whole swarm against static outlines and each other's bodies.

    Every (lidar, segment) pair within range is tested only on the beams inside the angle the
    segment subtends as seen from the lidar, so the work grows with what each lidar can see, not
    with beams × segments; the result equals the brute force :func:`cast_rays` (tested).  The
    loop over the pairs' beams is compiled (:mod:`swarm_sim.lidar_kernels`).

    Args:
        static_segments: (S, 4) outline segments of the static world at the lidar height [m],
            in ``map``.
        pattern: the beams of the lidar (every lidar cast by this object shares it; a mixed
            fleet has one object per model, :class:`swarm_sim.engine.SimEngine`).
    """

    def __init__(self, static_segments: np.ndarray, pattern: ScanPattern):
        self.static_segments = np.asarray(static_segments, dtype=float).reshape(-1, 4)
        self.pattern = pattern
        self._cos = np.cos(pattern.angles)
        self._sin = np.sin(pattern.angles)
        kernels.warm_up()

    def true_ranges(self, lidar_poses: np.ndarray, bodies: np.ndarray,
                    own: np.ndarray | None = None) -> np.ndarray:
        """Noise-free distances to the nearest hit for every robot's beams.

        Args:
            lidar_poses: (M, 3) lidar poses x [m], y [m], yaw [rad] in ``map``.
            bodies: (N, K, 2) convex, counter-clockwise footprint polygon of every robot in
                ``map`` [m] (fewer vertices padded by repeating one: zero-length edges are
                never hit); lidar ``j`` ignores body ``own[j]`` (its own).
            own: (M,) the body of each lidar's robot; None: lidar ``i`` is robot ``i``'s
                (M = N).

        Returns:
            (M, B) distances [m]; ``inf`` where nothing is hit (before ``range_max`` is applied).
        """
        lidar_poses = np.asarray(lidar_poses, dtype=float).reshape(-1, 3)
        n = lidar_poses.shape[0]
        n_beams = self.pattern.angles.size
        reach = self.pattern.range_max
        origins = lidar_poses[:, :2]
        # Candidate (lidar, segment) pairs: static segments within range ...
        pair_lidar = [np.zeros(0, dtype=int)]
        pair_segs = [np.zeros((0, 4))]
        if self.static_segments.shape[0]:
            li, si = np.nonzero(_point_segment_distance(origins, self.static_segments) <= reach)
            pair_lidar.append(li)
            pair_segs.append(self.static_segments[si])
        # ... and the edges of every other robot whose body may be within range.
        bodies = np.asarray(bodies, dtype=float)
        bodies = bodies.reshape(n if own is None else bodies.shape[0], -1, 2)
        if bodies.shape[0] > 1:
            k = bodies.shape[1]
            body_segs = np.concatenate((bodies, np.roll(bodies, -1, axis=1)), axis=2)
            centres = bodies.mean(axis=1)
            radius = np.linalg.norm(bodies - centres[:, None, :], axis=2).max(axis=1)
            dist = np.linalg.norm(origins[:, None, :] - centres[None, :, :], axis=2)
            near = dist <= reach + radius[None, :]
            if own is None:
                np.fill_diagonal(near, False)
            else:
                near[np.arange(n), np.asarray(own, dtype=int)] = False
            li, bj = np.nonzero(near)
            pair_lidar.append(np.repeat(li, k))
            pair_segs.append(body_segs[bj].reshape(-1, 4))
        lid = np.concatenate(pair_lidar)
        segs = np.concatenate(pair_segs)
        # Back-face culling: outlines are convex and counter-clockwise, so a beam from outside
        # meets a face whose outward normal (ey, -ex) points towards the lidar first.
        ex, ey = segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1]
        facing = ey * (segs[:, 0] - origins[lid, 0]) - ex * (segs[:, 1] - origins[lid, 1]) < 0.0
        lid, segs = lid[facing], segs[facing]
        out = np.full(n * n_beams, np.inf)
        if lid.size == 0:
            return out.reshape(n, n_beams)
        lo, hi = self._arcs(lidar_poses, lid, segs)
        yaw = lidar_poses[:, 2]
        kernels.cast_pairs(lo, hi, lid, np.ascontiguousarray(segs),
                           np.ascontiguousarray(origins[:, 0]),
                           np.ascontiguousarray(origins[:, 1]), np.cos(yaw), np.sin(yaw),
                           self._cos, self._sin,
                           float(self.pattern.angle_increment or 2.0 * np.pi), out)
        return out.reshape(n, n_beams)

    def _arcs(self, lidar_poses, lid, segs) -> tuple[np.ndarray, np.ndarray]:
        """(P,) start and end [rad] of the arc each (lidar, segment) pair's segment subtends as
        seen from the lidar (at most pi), as offsets from the first beam's angle, widened by
        1e-9 rad at each end: the beams inside are the only ones that can hit it."""
        amin = float(self.pattern.angles[0])
        o = lidar_poses[lid, :2]
        a0 = np.arctan2(segs[:, 1] - o[:, 1], segs[:, 0] - o[:, 0]) - lidar_poses[lid, 2]
        a1 = np.arctan2(segs[:, 3] - o[:, 1], segs[:, 2] - o[:, 0]) - lidar_poses[lid, 2]
        sweep = np.mod(a1 - a0 + np.pi, 2.0 * np.pi) - np.pi  # signed, in [-pi, pi)
        lo = np.mod(np.minimum(a0, a0 + sweep) - amin, 2.0 * np.pi) - 1e-9  # offset from amin
        hi = lo + np.abs(sweep) + 2e-9
        return lo, hi

    def draw_noise(self, m: int, rng: np.random.Generator) -> np.ndarray | None:
        """(M, B) range noise [m] of ``m`` scans from ``rng``, as :meth:`scan` draws it; None
        without noise (nothing is drawn)."""
        if self.pattern.noise_stddev <= 0.0:
            return None
        return rng.normal(0.0, self.pattern.noise_stddev, size=(m, self.pattern.angles.size))

    def scan(self, lidar_poses, bodies, rng: np.random.Generator,
             own: np.ndarray | None = None, noise: np.ndarray | None = None) -> np.ndarray:
        """Simulated scans: true ranges plus seeded Gaussian noise, REP 117 for invalid beams.

        Args:
            lidar_poses: (M, 3) lidar poses in ``map``.
            bodies: (N, K, 2) robot footprints in ``map`` (see :meth:`true_ranges`).
            rng: the simulator's seeded generator (same seed, same noise).
            own: (M,) each lidar's own body (see :meth:`true_ranges`); None: M = N.
            noise: (M, B) the noise [m] to add, drawn beforehand (:meth:`draw_noise`; ``rng``
                is then not used); None: drawn here.

        Returns:
            (M, B) float32 ranges [m]: ``+inf`` no return within ``range_max``, ``-inf`` closer
            than ``range_min``.
        """
        ranges = self.true_ranges(lidar_poses, bodies, own)
        if noise is None:
            noise = self.draw_noise(ranges.shape[0], rng)
        if noise is not None:
            ranges = ranges + noise
        ranges = np.where(ranges > self.pattern.range_max, np.inf, ranges)
        ranges = np.where(ranges < self.pattern.range_min, -np.inf, ranges)
        return ranges.astype(np.float32)
