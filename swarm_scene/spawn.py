"""Where the robots start: spawn poses on a world's spawn grid, or in its chosen free region (the
largest enclosed free region, else the largest free region).

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
    """Where robots spawn in a world without a spawn area (:func:`choose_free_region`).

    Attributes:
        origin: (2,) x, y [m] in ``map`` of the region's clearest cell (the first robot).
        clearance: distance [m] from ``origin`` to the nearest cell outside the region (an
            obstacle, an unknown cell or the map's edge).
        area: the region's area [m^2].
        mask: (H, W) bool, the region's cells in the map's layout (row 0 at the bottom).
        distance: (H, W) float, distance [m] from each cell's centre to the nearest cell
            centre outside the region (0 outside it).
        enclosed: the region touches no edge of the map (walls, or unknown cells, close it).
        open_area: [m^2] the largest free region that touches the map's edge (0 if none): the
            space outside the walls when ``enclosed``.
    """

    origin: np.ndarray
    clearance: float
    area: float
    mask: np.ndarray
    distance: np.ndarray
    enclosed: bool = False
    open_area: float = 0.0

    def describe(self, why: str = "") -> str:
        """The rule that chose the region and its size, for a log line, with ``why`` (a reason
        for using it) at the end of the brackets: e.g. ``"the largest enclosed free region (269
        m^2; 36 m^2 of free space touch the map's edge; no points-of-interest file)"``."""
        notes = [f"{self.area:.0f} m^2"]
        if not self.enclosed:
            notes.append("none is enclosed")
        elif self.open_area > 0:
            notes.append(f"{self.open_area:.0f} m^2 of free space touch the map's edge")
        if why:
            notes.append(why)
        kind = "enclosed free region" if self.enclosed else "free region"
        return f"the largest {kind} ({'; '.join(notes)})"


def choose_free_region(occ) -> FreeRegion:
    """The free region robots spawn in, and its clearest cell.

    The spawn rule of a world without a spawn area (docs/reference/contract.md#s4: "spawn in the
    largest free area", made precise): label the 4-connected regions of free cells (value 0);
    if some region touches no edge of the map (an arena closed by its walls), take the enclosed
    region with the most cells, never one that touches the edge (the space between a world's
    outer wall and the map's edge); otherwise the region with the most cells. Then the cell of
    that region farthest from anything outside it (Euclidean distance transform, the map's edge
    counting as outside). Ties go to the first in row-major order.

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
    edge = np.unique(np.concatenate((labels[0], labels[-1], labels[:, 0], labels[:, -1])))
    touches = np.zeros(count, dtype=bool)
    touches[edge[edge > 0] - 1] = True
    enclosed = not touches.all()
    pick = np.where(touches, -1, sizes) if enclosed else sizes
    region = labels == int(np.argmax(pick)) + 1
    res = float(occ.resolution)
    open_cells = int(sizes[touches].max()) if touches.any() else 0
    clear = ndimage.distance_transform_edt(np.pad(region, 1))[1:-1, 1:-1] * res
    best = np.unravel_index(int(np.argmax(clear)), clear.shape)
    origin = occ.cell_to_world(np.array(best))
    for array in (origin, region, clear):
        array.setflags(write=False)
    return FreeRegion(origin=origin, clearance=float(clear[best]),
                      area=float(region.sum()) * res * res, mask=region, distance=clear,
                      enclosed=enclosed, open_area=open_cells * res * res)


def spawn_poses_free(occ, n: int, radius: float, polygons, clearance: float = 0.05,
                     where: str = "largest free area", region: FreeRegion | None = None
                     ) -> np.ndarray:
    """Spawn for a world without a spawn area: a grid in its chosen free region.

    The grid (spacing 1 m, or the robot's diameter plus twice ``clearance`` if larger) starts at
    the clearest cell of the chosen free region (:func:`choose_free_region`: the largest
    enclosed free region, else the largest free region) and keeps to that region, so every robot
    can reach every other's start: a node is used only when the robot's circle plus
    ``clearance`` stays inside the region (clear of obstacles, unknown cells
    and the map's edge, to the map's resolution) and of every world polygon. Robots take the grid
    nodes nearest the start first (the order of :func:`spawn_poses`) and face +x (yaw 0).

    Args:
        occ: the world's :class:`swarm_scene.occupancy.OccupancyMap`.
        n, radius, polygons, clearance, where: as :func:`spawn_poses`.
        region: ``choose_free_region(occ)`` when the caller has it already.

    Returns:
        (n, 3) poses in ``map``.

    Raises:
        InputError: the robots do not fit; the message says how many fit.
    """
    free = choose_free_region(occ) if region is None else region
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


def describe_spawn(poses: np.ndarray, from_spawn_area: bool, poi_file: str | None = None,
                   region: FreeRegion | None = None) -> str:
    """Where the robots went, for a log line and the run's summary: the rule used and the block
    they stand in.

    Args:
        poses: (N, 3) spawn poses x, y [m], yaw [rad] in ``map``.
        from_spawn_area: True when they came from the world's spawn area (its ``.yaml``),
            False when from :func:`spawn_poses_free`.
        poi_file: the name of the world's points-of-interest file (``"slim_blockage.yaml"``),
            None when the world has none.
        region: the :func:`choose_free_region` they stand in (not from the spawn area), to name it.

    Returns:
        e.g. ``"in the largest enclosed free region (269 m^2; 36 m^2 of free space touch the
        map's edge; no points-of-interest file), x 4.73..7.73 m, y 0.48..0.48 m, first at
        (4.73, 0.48)"``.
    """
    if from_spawn_area:
        rule = f"in the spawn area of {poi_file or 'its points of interest'}"
    else:
        why = ("no points-of-interest file" if poi_file is None
               else f"{poi_file} has no spawn area")
        rule = (f"in the largest free area ({why})" if region is None
                else f"in {region.describe(why)}")
    x, y = poses[:, 0], poses[:, 1]
    return (f"{rule}, x {x.min():.2f}..{x.max():.2f} m, y {y.min():.2f}..{y.max():.2f} m, "
            f"first at ({x[0]:.2f}, {y[0]:.2f})")
