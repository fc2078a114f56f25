"""Where the robots start: spawn poses on a world's spawn grid, or in its largest free area.

Pure (numpy and scipy only), so ``swarm-up`` can check that ``--swarm-size`` robots fit without
loading the simulator or PyBullet, and ``swarm-sim`` places them with the same code.

Frames: poses are in ``map`` (= the world frame), (3,) x [m], y [m], yaw [rad] of each robot's
``base_footprint``; polygons are (K, 2) outlines in ``map``
(:func:`swarm_common.world.world_polygons`).
"""

from __future__ import annotations

import numpy as np

from swarm_common.errors import InputError
from swarm_common.poi import SpawnArea


def spawn_poses(spawn, n: int, radius: float, polygons, clearance: float = 0.05,
                where: str = "spawn area", keep=None) -> np.ndarray:
    """Place ``n`` robots on the spawn grid, nearest the grid origin first.

    Grid nodes are ``origin + spacing * (i, j)`` inside ``spawn.area``; robots take row ``j = 0``
    first, then ``j = 1, 2, ...``, then ``j = -1, -2, ...``, and within a row ``i = 0, 1, ...``
    then ``i = -1, -2, ...`` (so the default five robots of slim_blockage stand at (0..4, 0), as
    in the thesis).  A node is used only when a robot's circumscribed circle plus ``clearance``
    touches no world polygon.

    Args:
        spawn: a :class:`swarm_common.poi.SpawnArea`.
        n: number of robots (>= 1).
        radius: the robot's circumscribed radius [m].
        polygons: list of (K, 2) world outlines in ``map``.
        clearance: extra gap to walls [m].
        where: how to name the area in an error.
        keep: optional predicate, (M, 2) points -> (M,) bool, that a node must also pass.

    Returns:
        (n, 3) poses x, y, yaw in ``map``.

    Raises:
        InputError: the robots do not fit; the message says how many fit.
    """
    if spawn.spacing < 2.0 * radius + clearance:
        raise InputError(
            f"{where}: spacing {spawn.spacing:g} m is too small for robots of radius"
            f" {radius:.3f} m"
        )
    nodes = spawn.grid_points()
    segs = _edges(polygons)
    ok = np.ones(len(nodes), dtype=bool)
    if len(nodes) and len(segs):
        p0 = segs[None, :, 0:2]
        e = segs[None, :, 2:4] - p0
        rel = nodes[:, None, :] - p0
        u = np.clip(np.einsum("nsi,nsi->ns", rel, e) / np.maximum(
            np.einsum("nsi,nsi->ns", e, e), 1e-18), 0.0, 1.0)
        d = np.linalg.norm(rel - u[..., None] * e, axis=-1).min(axis=1)
        ok &= d >= radius + clearance
        for poly in polygons:  # a node inside an obstacle is not free either
            ok &= ~_inside_convex(nodes, poly)
    if keep is not None and len(nodes):
        ok &= keep(nodes)
    nodes = nodes[ok]
    if len(nodes) < n:
        raise InputError(
            f"--swarm-size: {n} robots do not fit in the {where}; at most {len(nodes)} fit"
        )
    ij = np.rint((nodes - spawn.origin) / spawn.spacing).astype(int)
    order = np.lexsort((np.abs(ij[:, 0]), ij[:, 0] < 0, np.abs(ij[:, 1]), ij[:, 1] < 0))
    chosen = nodes[order[:n]]
    return np.column_stack((chosen, np.full(n, float(spawn.yaw))))


def spawn_poses_free(occ, n: int, radius: float, polygons, clearance: float = 0.05,
                     where: str = "largest free area") -> np.ndarray:
    """Spawn for a world without a spawn area: a 1 m grid in its largest free region.

    The grid starts at the free cell farthest from any obstacle (distance transform of the map)
    and keeps to the connected free region around it, so no robot is shut in a closed pocket.
    Robots face +x (yaw 0).

    Args:
        occ: the world's :class:`swarm_common.occupancy.OccupancyMap`.
        n, radius, polygons, clearance, where: as :func:`spawn_poses`.

    Returns:
        (n, 3) poses in ``map``.

    Raises:
        InputError: the robots do not fit; the message says how many fit.
    """
    from scipy import ndimage

    free = occ.data == 0
    labels, _ = ndimage.label(free)
    clear = ndimage.distance_transform_edt(free)
    best = np.unravel_index(np.argmax(clear), clear.shape)
    origin = occ.cell_to_world(np.array(best))
    region = labels == labels[best]
    x0, y0 = occ.origin[0], occ.origin[1]
    area = np.array([x0, y0, x0 + occ.width * occ.resolution, y0 + occ.height * occ.resolution])
    spacing = max(1.0, 2.0 * radius + 2.0 * clearance)
    spawn = SpawnArea(origin=origin, spacing=spacing, yaw=0.0, area=area)

    def in_region(points):
        rc = occ.world_to_cell(points)
        inside = occ.in_bounds(rc)
        out = np.zeros(len(points), dtype=bool)
        out[inside] = region[rc[inside, 0], rc[inside, 1]]
        return out

    return spawn_poses(spawn, n, radius, polygons, clearance, where, keep=in_region)


def _inside_convex(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(M,) mask of points strictly inside a convex polygon (either winding)."""
    edges = np.roll(poly, -1, axis=0) - poly
    rel = points[:, None, :] - poly[None, :, :]
    cross = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]
    return np.all(cross > 1e-12, axis=1) | np.all(cross < -1e-12, axis=1)


def _edges(polygons) -> np.ndarray:
    """(S, 4) edges ``x0, y0, x1, y1`` [m] of closed polygons (any winding)."""
    segs = [np.hstack((p, np.roll(p, -1, axis=0)))
            for p in (np.asarray(q, dtype=float).reshape(-1, 2) for q in polygons) if len(p) >= 2]
    return np.vstack(segs) if segs else np.zeros((0, 4))
