"""Where the robots start: spawn poses on a world's spawn grid, or in its largest free area.

Pure (numpy and scipy only), so ``swarm-up`` can check that ``--swarm-size`` robots fit without
loading the simulator or PyBullet, and ``swarm-sim`` places them with the same code.

Frames: poses are in ``map`` (= the world frame), (3,) x [m], y [m], yaw [rad] of each robot's
``base_footprint``; polygons are (K, 2) outlines in ``map``
(:func:`swarm_scene.world.world_polygons`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_common.errors import InputError
from swarm_scene.poi import SpawnArea


def spawn_poses(spawn, n: int, radius: float, polygons, clearance: float = 0.05,
                where: str = "spawn area", keep=None) -> np.ndarray:
    """Place ``n`` robots on the spawn grid, nearest the grid origin first.

    Grid nodes are ``origin + spacing * (i, j)`` inside ``spawn.area``; robots take row ``j = 0``
    first, then ``j = 1, 2, ...``, then ``j = -1, -2, ...``, and within a row ``i = 0, 1, ...``
    then ``i = -1, -2, ...`` (so the default five robots of slim_blockage stand at (0..4, 0), as
    in the thesis).  A node is used only when a robot's circumscribed circle plus ``clearance``
    touches no world polygon.

    Args:
        spawn: a :class:`swarm_scene.poi.SpawnArea`.
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
            f" {radius:.3f} m: neighbours would stand less than {clearance:g} m apart (at"
            f" least {2.0 * radius + clearance:.3f} m)"
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


@dataclass(frozen=True)
class FreeRegion:
    """Where robots spawn in a world without a spawn area (:func:`largest_free_region`).

    Attributes:
        origin: (2,) x, y [m] in ``map`` of the region's clearest cell (the first robot).
        clearance: distance [m] from ``origin`` to the nearest cell outside the region (an
            obstacle, an unknown cell or the map's edge).
        area: the region's area [m^2].
        mask: (H, W) bool, the region's cells in the map's layout (row 0 at the bottom).
        distance: (H, W) float, distance [m] from each cell's centre to the nearest cell
            centre outside the region (0 outside it).
    """

    origin: np.ndarray
    clearance: float
    area: float
    mask: np.ndarray
    distance: np.ndarray


def largest_free_region(occ) -> FreeRegion:
    """The largest connected free region of a map, and its clearest cell.

    The spawn rule of a world without points of interest (docs/reference/contract.md#s4:
    "spawn in the largest free area"): take the 4-connected region of free cells (value 0) with
    the most cells, then the cell of that region farthest from anything outside it (Euclidean
    distance transform, the map's edge counting as outside). Ties go to the first cell in
    row-major order.

    Args:
        occ: a :class:`swarm_scene.occupancy.OccupancyMap`.

    Returns:
        The :class:`FreeRegion`.

    Raises:
        InputError: the map has no free cell.
    """
    from scipy import ndimage

    free = occ.data == 0
    labels, count = ndimage.label(free)
    if count == 0:
        raise InputError("the map has no free cell: nowhere to spawn robots")
    sizes = np.bincount(labels.ravel())[1:]
    region = labels == int(np.argmax(sizes)) + 1
    res = float(occ.resolution)
    clear = ndimage.distance_transform_edt(np.pad(region, 1))[1:-1, 1:-1] * res
    best = np.unravel_index(int(np.argmax(clear)), clear.shape)
    origin = occ.cell_to_world(np.array(best))
    for array in (origin, region, clear):
        array.setflags(write=False)
    return FreeRegion(origin=origin, clearance=float(clear[best]),
                      area=float(region.sum()) * res * res, mask=region, distance=clear)


def spawn_poses_free(occ, n: int, radius: float, polygons, clearance: float = 0.05,
                     where: str = "largest free area") -> np.ndarray:
    """Spawn for a world without a spawn area: a grid in its largest free region.

    The grid (spacing 1 m, or the robot's diameter plus twice ``clearance`` if larger) starts at
    the clearest cell of the largest connected free region (:func:`largest_free_region`) and
    keeps to that region, so no robot is shut in a closed pocket: a node is used only when the
    robot's circle plus ``clearance`` stays inside the region (clear of obstacles, unknown cells
    and the map's edge, to the map's resolution) and of every world polygon. Robots take the grid
    nodes nearest the start first (the order of :func:`spawn_poses`) and face +x (yaw 0).

    Args:
        occ: the world's :class:`swarm_scene.occupancy.OccupancyMap`.
        n, radius, polygons, clearance, where: as :func:`spawn_poses`.

    Returns:
        (n, 3) poses in ``map``.

    Raises:
        InputError: the robots do not fit; the message says how many fit.
    """
    free = largest_free_region(occ)
    x0, y0 = occ.origin[0], occ.origin[1]
    area = np.array([x0, y0, x0 + occ.width * occ.resolution, y0 + occ.height * occ.resolution])
    spacing = max(1.0, 2.0 * radius + 2.0 * clearance)
    spawn = SpawnArea(origin=np.array(free.origin), spacing=spacing, yaw=0.0, area=area)

    def in_region(points):
        rc = occ.world_to_cell(points)
        inside = occ.in_bounds(rc)
        out = np.zeros(len(points), dtype=bool)
        # the distance is between cell centres: half a cell more keeps the robot off the edge
        need = radius + clearance + 0.5 * occ.resolution
        out[inside] = free.distance[rc[inside, 0], rc[inside, 1]] >= need
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


def describe_spawn(poses: np.ndarray, from_spawn_area: bool, poi_file: str | None = None) -> str:
    """Where the robots went, for a log line and the run's summary: the rule used and the block
    they stand in.

    Args:
        poses: (N, 3) spawn poses x, y [m], yaw [rad] in ``map``.
        from_spawn_area: True when they came from the world's spawn area (its ``.yaml``),
            False when from :func:`spawn_poses_free`.
        poi_file: the name of the world's points-of-interest file (``"slim_blockage.yaml"``),
            None when the world has none.

    Returns:
        e.g. ``"in the largest free area (no points-of-interest file), x 3.05..6.05 m, y
        -2.95..-0.95 m, first at (3.05, -2.95)"``.
    """
    if from_spawn_area:
        rule = f"in the spawn area of {poi_file or 'its points of interest'}"
    elif poi_file is None:
        rule = "in the largest free area (no points-of-interest file)"
    else:
        rule = f"in the largest free area ({poi_file} has no spawn area)"
    x, y = poses[:, 0], poses[:, 1]
    return (f"{rule}, x {x.min():.2f}..{x.max():.2f} m, y {y.min():.2f}..{y.max():.2f} m, "
            f"first at ({x[0]:.2f}, {y[0]:.2f})")
