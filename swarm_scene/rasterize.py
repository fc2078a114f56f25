"""Rasterise a world's collision shapes into an occupancy grid (what ``swarm-map`` writes).

A cell is occupied when the plan-view outline of any obstacle (a shape in the robots' height
band; floor slabs, ground planes and heightmaps are not obstacles, see
:func:`swarm_scene.world.obstacle_shapes`) overlaps the cell's square by more than a micrometre
(conservative: a wall that touches a sliver of a cell takes the whole cell, so a 0.15 m wall is
at least 3 cells thick at 0.05 m/cell and never has a gap); every other cell is free. The test
is exact, per cell, by the separating axis theorem for two convex polygons (Gottschalk, Lin &
Manocha 1996, "OBBTree"), vectorised with numpy.
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.errors import InputError
from swarm_scene.occupancy import FREE, OCCUPIED, OccupancyMap
from swarm_scene.world import BAND_TOP, FLOOR_TOLERANCE, World, world_polygons

OVERLAP_EPS = 1e-6  # [m] a shape must overlap a cell by more than this to occupy it


def _snap_down(value: float, step: float) -> float:
    """Largest multiple of ``step`` at or below ``value`` (robust to float noise)."""
    return math.floor(round(value / step, 6)) * step


def rasterize_polygons(polygons: list[np.ndarray], resolution: float,
                       origin_xy: tuple[float, float], shape: tuple[int, int]) -> np.ndarray:
    """Occupancy (H, W) int8 grid of convex polygons: 100 where one overlaps a cell, else 0.

    Args:
        polygons: convex polygons, each (K, 2) x, y [m] in ``map``, counter-clockwise.
        resolution: cell size [m/cell].
        origin_xy: x, y [m] of the lower-left corner of cell (0, 0).
        shape: (H, W) rows (along y) and columns (along x); row 0 at ``origin_xy[1]``.

    Returns:
        (H, W) int8 array in :class:`OccupancyMap` layout (row 0 at the bottom).
    """
    height, width = shape
    data = np.full((height, width), FREE, dtype=np.int8)
    ox, oy = origin_xy
    half = resolution / 2.0
    for poly in polygons:
        poly = np.asarray(poly, dtype=float)
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        c0 = max(0, int(math.floor((lo[0] - ox + OVERLAP_EPS) / resolution)))
        c1 = min(width - 1, int(math.ceil((hi[0] - ox - OVERLAP_EPS) / resolution)) - 1)
        r0 = max(0, int(math.floor((lo[1] - oy + OVERLAP_EPS) / resolution)))
        r1 = min(height - 1, int(math.ceil((hi[1] - oy - OVERLAP_EPS) / resolution)) - 1)
        if c1 < c0 or r1 < r0:
            continue
        cols = np.arange(c0, c1 + 1)
        rows = np.arange(r0, r1 + 1)
        cx = ox + (cols + 0.5) * resolution  # cell centres
        cy = oy + (rows + 0.5) * resolution
        # Outward edge normals of a counter-clockwise polygon and their support values.
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.column_stack((edges[:, 1], -edges[:, 0]))
        lengths = np.hypot(normals[:, 0], normals[:, 1])
        keep = lengths > 1e-12
        normals = normals[keep] / lengths[keep, None]
        support = np.einsum("ij,ij->i", normals, poly[keep])
        # A cell overlaps iff on every polygon axis its nearest point lies inside the polygon's
        # support by more than OVERLAP_EPS (the cell axes are already handled by c0..r1).
        reach = half * (np.abs(normals[:, 0]) + np.abs(normals[:, 1]))
        inside = np.ones((len(rows), len(cols)), dtype=bool)
        for (nx, ny), d, h in zip(normals, support, reach, strict=True):
            inside &= (ny * cy[:, None] + nx * cx[None, :] - h) < d - OVERLAP_EPS
        block = data[r0:r1 + 1, c0:c1 + 1]
        block[inside] = OCCUPIED
    return data


def rasterize_world(world: World, resolution: float = 0.05, padding: float = 0.5,
                    z_min: float = FLOOR_TOLERANCE, z_max: float = BAND_TOP) -> OccupancyMap:
    """Rasterise a world into an occupancy map (free 0 / occupied 100, nothing unknown).

    Args:
        world: the loaded world.
        resolution: cell size [m/cell].
        padding: free margin [m] added around the bounding box of the shapes.
        z_min: bottom of the robots' height band [m]: shapes whose top is at or below it are
            floor (default :data:`swarm_scene.world.FLOOR_TOLERANCE`, 0.05 m; see
            :func:`swarm_scene.world.obstacle_shapes`).
        z_max: top of the robots' height band [m] (default ``BAND_TOP``, 2.0 m).

    Returns:
        The map; its origin (lower-left corner of cell (0, 0)) is snapped down to a multiple of
        ``resolution`` and its yaw is 0.

    Raises:
        InputError: a non-positive resolution, a negative padding, or no shape in the band.
    """
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise InputError(f"resolution must be a positive number [m/cell], got {resolution}")
    if not (math.isfinite(padding) and padding >= 0.0):
        raise InputError(f"padding must be a non-negative number [m], got {padding}")
    polygons = world_polygons(world, z_min, z_max)
    if not polygons:
        raise InputError(f"{world.source}: no collision geometry between z = {z_min:g} and "
                         f"{z_max:g} m: nothing to rasterise")
    pts = np.vstack(polygons)
    lo, hi = pts.min(axis=0) - padding, pts.max(axis=0) + padding
    ox, oy = _snap_down(lo[0], resolution), _snap_down(lo[1], resolution)
    width = max(1, int(math.ceil(round((hi[0] - ox) / resolution, 6))))
    height = max(1, int(math.ceil(round((hi[1] - oy) / resolution, 6))))
    data = rasterize_polygons(polygons, resolution, (ox, oy), (height, width))
    origin = np.array([round(ox, 9), round(oy, 9), 0.0])
    return OccupancyMap(data=data, resolution=float(resolution), origin=origin)
