"""Synthetic worlds for the navigator's tests: grids, the slim_blockage wall table, a 2D lidar and
a closed-loop unicycle simulation.  Pure numpy; no ROS, no PyBullet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarm_common.geometry import transform_points, wrap_angle
from swarm_scene.occupancy import OccupancyMap

# shared/reference/seed_facts.md, world slim_blockage: xmin, xmax, ymin, ymax [m]
SLIM_BLOCKAGE_WALLS = np.array([
    [-8.475, 9.525, -4.974, -4.824],   # bottom
    [-8.475, 9.525, 9.376, 9.526],     # top
    [-8.475, -8.325, -4.974, 9.526],   # left
    [9.375, 9.525, -4.974, 9.526],     # right
    [-5.262, -5.112, -3.016, 7.484],   # blockage, left side
    [-3.912, -3.762, -3.016, 7.484],   # blockage, right side
    [-5.262, -3.762, -3.016, -2.866],  # blockage, bottom
    [-5.262, -3.762, 7.334, 7.484],    # blockage, top
    [3.909, 4.059, -4.912, -1.412],    # pocket, vertical
    [3.909, 9.409, -1.562, -1.412],    # pocket, horizontal
])

SLIM_BLOCKAGE_LOOP = np.array([[-5.990370, 8.674410], [-2.706150, 8.674410],
                               [-2.706150, -3.947350], [-5.990370, -3.947350]])
LOADERS_Y = (-3.577660, -1.385260, 0.972970, 3.203130, 5.784420, 8.363370)

# TurtleBot3 waffle: base collision box 0.266 x 0.266 centred x = -0.064 in base_footprint
WAFFLE_FOOTPRINT = np.array([[-0.197, -0.133], [0.069, -0.133], [0.069, 0.133], [-0.197, 0.133]])
WAFFLE_LIDAR_X = -0.064


def rasterize_boxes(boxes: np.ndarray, resolution: float = 0.05, pad: float = 0.0
                    ) -> OccupancyMap:
    """Occupancy map (0 free / 100 occupied) of axis-aligned boxes; a cell overlapping a box is
    occupied.  The grid spans the boxes' bounding box plus ``pad`` [m]."""
    x0, y0 = boxes[:, 0].min() - pad, boxes[:, 2].min() - pad
    w = int(round((boxes[:, 1].max() + pad - x0) / resolution))
    h = int(round((boxes[:, 3].max() + pad - y0) / resolution))
    data = np.zeros((h, w), dtype=np.int8)
    xs = x0 + np.arange(w) * resolution
    ys = y0 + np.arange(h) * resolution
    eps = 1e-9
    for bx0, bx1, by0, by1 in boxes:
        cols = (xs + resolution > bx0 + eps) & (xs < bx1 - eps)
        rows = (ys + resolution > by0 + eps) & (ys < by1 - eps)
        data[np.ix_(rows, cols)] = 100
    return OccupancyMap(data, resolution, np.array([x0, y0, 0.0]))


def slim_blockage_map(resolution: float = 0.05) -> OccupancyMap:
    """The slim_blockage world rasterised from the wall table."""
    return rasterize_boxes(SLIM_BLOCKAGE_WALLS, resolution)


def grid_map(data, resolution: float = 0.1, origin=(0.0, 0.0)) -> OccupancyMap:
    """An OccupancyMap from a small int array (row 0 at the bottom)."""
    return OccupancyMap(np.asarray(data, dtype=np.int8), resolution,
                        np.array([origin[0], origin[1], 0.0]))


def random_grid(rng: np.random.Generator, h: int, w: int, p_occ: float) -> OccupancyMap:
    """A random h x w grid with obstacle probability ``p_occ`` and resolution 0.1 m."""
    data = np.where(rng.random((h, w)) < p_occ, 100, 0).astype(np.int8)
    return grid_map(data, 0.1)


def box_segments(boxes: np.ndarray) -> np.ndarray:
    """(4 * B, 4) segments x0, y0, x1, y1 of axis-aligned boxes xmin, xmax, ymin, ymax."""
    segs = []
    for x0, x1, y0, y1 in boxes:
        segs += [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]]
    return np.asarray(segs, dtype=float).reshape(-1, 4)


def footprint_polygon(pose, footprint=WAFFLE_FOOTPRINT) -> np.ndarray:
    """(4, 2) corners in map of a footprint at ``pose``."""
    return transform_points(np.asarray(pose, dtype=float), footprint)


def polygon_segments(poly: np.ndarray) -> np.ndarray:
    """(K, 4) edges of a closed polygon."""
    return np.hstack((poly, np.roll(poly, -1, axis=0)))


def ray_cast(origin, angles, segments, range_max: float) -> np.ndarray:
    """Distance [m] along each ray (angles [rad] in map) to the nearest segment; inf if none."""
    d = np.column_stack((np.cos(angles), np.sin(angles)))            # (N, 2)
    p = segments[:, :2]
    e = segments[:, 2:] - p                                          # (S, 2)
    q = p - np.asarray(origin)[None, :]                              # (S, 2)
    denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]   # (N, S)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (q[None, :, 0] * e[None, :, 1] - q[None, :, 1] * e[None, :, 0]) / denom
        u = (q[None, :, 0] * d[:, None, 1] - q[None, :, 1] * d[:, None, 0]) / denom
    hit = (np.abs(denom) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
    t = np.where(hit, t, np.inf).min(axis=1)
    return np.where(t <= range_max, t, np.inf)


@dataclass
class Lidar:
    """LDS-01: 360 samples over 0..2pi, 0.12-3.5 m, Gaussian noise."""

    samples: int = 360
    range_min: float = 0.12
    range_max: float = 3.5
    noise: float = 0.01
    x: float = WAFFLE_LIDAR_X

    def scan_points(self, pose, segments, rng: np.random.Generator | None) -> np.ndarray:
        """(M, 2) end points in map of the rays that hit something in range."""
        pose = np.asarray(pose, dtype=float)
        origin = transform_points(pose, [[self.x, 0.0]])[0]
        angles = pose[2] + np.arange(self.samples) * 2 * math.pi / self.samples
        r = ray_cast(origin, angles, segments, self.range_max)
        if rng is not None and self.noise > 0:
            r = r + rng.normal(0.0, self.noise, r.shape)
        ok = np.isfinite(r) & (r >= self.range_min)
        return origin + r[ok, None] * np.column_stack((np.cos(angles[ok]), np.sin(angles[ok])))


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex polygons (K, 2)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for ex, ey in edges:
            n = np.array([-ey, ex])
            pa, pb = a @ n, b @ n
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def polygon_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Minimum distance between two non-overlapping convex polygons (0 if they overlap)."""
    if boxes_overlap(a, b):
        return 0.0

    def pt_seg(p, s0, s1):
        e = s1 - s0
        t = np.clip(((p - s0) @ e) / (e @ e), 0.0, 1.0)
        return np.hypot(*(s0 + t * e - p))

    best = math.inf
    for p, q in ((a, b), (b, a)):
        for pt in p:
            for i in range(len(q)):
                best = min(best, pt_seg(pt, q[i], q[(i + 1) % len(q)]))
    return best


def unicycle_step(pose, v_cur, w_cur, v_cmd, w_cmd, dt, acc=2.5, acc_w=3.2,
                  v_lim=0.26, w_lim=1.82):
    """Differential drive within velocity and acceleration limits; exact arc over dt."""
    v = float(np.clip(v_cmd, v_cur - acc * dt, v_cur + acc * dt))
    w = float(np.clip(w_cmd, w_cur - acc_w * dt, w_cur + acc_w * dt))
    v = float(np.clip(v, -v_lim, v_lim))
    w = float(np.clip(w, -w_lim, w_lim))
    x, y, th = pose
    if abs(w) < 1e-9:
        x += v * dt * math.cos(th)
        y += v * dt * math.sin(th)
    else:
        x += v / w * (math.sin(th + w * dt) - math.sin(th))
        y -= v / w * (math.cos(th + w * dt) - math.cos(th))
    return np.array([x, y, wrap_angle(th + w * dt)]), v, w


@dataclass
class SimRobot:
    """One simulated robot: its navigator, its true state and its log."""

    core: object
    pose: np.ndarray
    v: float = 0.0
    w: float = 0.0
    log: list | None = None


def simulate(robots: list[SimRobot], walls: np.ndarray, duration: float, dt: float = 0.1,
             scan_every: int = 2, seed: int = 0, until_done: bool = True,
             lidar: Lidar | None = None, on_tick=None) -> dict:
    """The synchronous control loop of the simulator, in pure Python.

    Each tick: every robot (on lidar ticks) gets a scan of the walls and of the other robots'
    footprints, then every navigator answers ``step``; the commands are applied with the
    acceleration limits.  Returns min separation between footprints [m], wall contacts and the
    time [s] the run took.
    """
    rng = np.random.default_rng(seed)
    lidar = lidar or Lidar()
    wall_segs = box_segments(walls)
    min_sep = math.inf
    min_wall = math.inf
    contacts = 0
    t = 0.0
    n = int(round(duration / dt))
    for k in range(n):
        polys = [footprint_polygon(r.pose) for r in robots]
        if on_tick is not None:
            on_tick(t, robots)
        if k % scan_every == 0:
            for i, r in enumerate(robots):
                if r.core is None:
                    continue
                others = [polygon_segments(p) for j, p in enumerate(polys) if j != i]
                segs = np.vstack([wall_segs, *others]) if others else wall_segs
                r.core.on_scan(lidar.scan_points(r.pose, segs, rng), t)
        cmds = [(0.0, 0.0) if r.core is None else r.core.step(r.pose.copy(), r.v, r.w, t)
                for r in robots]
        for r, (v, w) in zip(robots, cmds, strict=True):
            r.pose, r.v, r.w = unicycle_step(r.pose, r.v, r.w, v, w, dt)
            if r.log is not None and r.core is not None:
                r.log.append((t, *r.pose, v, w, r.core.status.state.value))
        t += dt
        polys = [footprint_polygon(r.pose) for r in robots]
        for i in range(len(polys)):
            for j in range(i + 1, len(polys)):
                if np.hypot(*(robots[i].pose[:2] - robots[j].pose[:2])) > 1.0:
                    continue
                sep = polygon_distance(polys[i], polys[j])
                contacts += sep <= 0.0
                min_sep = min(min_sep, sep)
            min_wall = min(min_wall, _wall_gap(polys[i], walls))
        if until_done and all(r.core is None or r.core.status.state.value in (
                "SUCCEEDED", "ABORTED") for r in robots):
            break
    return {"min_separation": min_sep, "min_wall_gap": min_wall, "time": t,
            "contact_ticks": contacts}


def _wall_gap(poly: np.ndarray, walls: np.ndarray) -> float:
    """Smallest distance [m] from a footprint polygon to the axis-aligned wall boxes."""
    cx, cy = poly.mean(axis=0)
    best = math.inf
    for x0, x1, y0, y1 in walls:
        if x0 - 1.0 > cx or cx > x1 + 1.0 or y0 - 1.0 > cy or cy > y1 + 1.0:
            continue
        box = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        best = min(best, polygon_distance(poly, box))
    return best


def rollout(pose, v, w, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses along constant-velocity arcs (exact unicycle kinematics): the DWA's rollouts one
    (v, w) pair at a time, as :func:`swarm_nav.dwa_kernels.rollout_boxes` computes them.

    Args:
        pose: (3,) start x [m], y [m], yaw [rad] in ``map``.
        v: (S,) forward speeds [m/s].
        w: (S,) rotational speeds [rad/s].
        times: (T,) times [s] after the start.

    Returns:
        ``(x, y, yaw)``, each (S, T), in ``map`` (yaw not wrapped).
    """
    x0, y0, th0 = (float(c) for c in pose)
    v = np.asarray(v, dtype=float)[:, None]
    w = np.asarray(w, dtype=float)[:, None]
    t = np.asarray(times, dtype=float)[None, :]
    th = th0 + w * t
    straight = np.abs(w) < 1e-6
    w_safe = np.where(straight, 1.0, w)
    s0, c0 = math.sin(th0), math.cos(th0)
    sin_th, cos_th = np.sin(th), np.cos(th)
    x = np.where(straight, x0 + v * t * c0, x0 + v / w_safe * (sin_th - s0))
    y = np.where(straight, y0 + v * t * s0, y0 - v / w_safe * (cos_th - c0))
    return x, y, th
