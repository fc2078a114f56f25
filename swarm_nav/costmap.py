"""The global costmap: nav2's static layer and inflation layer on an :class:`OccupancyMap`.

Costs are nav2's (``nav2_costmap_2d/cost_values.hpp``): 254 lethal, 253 inscribed (the robot's
centre there means a collision), 255 unknown, 0 free, and in between the inflation cost of
``InflationLayer::computeCost``::

    cost = (253 - 1) * exp(-cost_scaling_factor * (d - robot_radius))
                                        for robot_radius < d <= inflation_radius

with ``d`` [m] the distance from a cell's centre to the centre of the nearest lethal cell,
truncated to an integer as nav2 does; like nav2, the inflation reaches
``ceil(inflation_radius / resolution)`` cells (11 cells for 0.55 m at 0.05 m/cell).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from swarm_common.geometry import Points2D
from swarm_nav import costmap_kernels
from swarm_nav.config import CostmapConfig
from swarm_scene.occupancy import GridGeometry, OccupancyMap

LETHAL = CostmapConfig.LETHAL_OBSTACLE
INSCRIBED = CostmapConfig.INSCRIBED_INFLATED_OBSTACLE
UNKNOWN = CostmapConfig.NO_INFORMATION
FREE = CostmapConfig.FREE_SPACE

_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class Costmap(GridGeometry):
    """A 2D costmap in ``map``, in the layout of :class:`OccupancyMap` (row 0 at the bottom).

    Attributes:
        costs: (H, W) uint8 nav2 costs.
        resolution: cell size [m/cell].
        origin: (3,) x [m], y [m], yaw [rad] of cell (0, 0)'s lower-left corner in ``map``.
        obstacle_distance: (H, W) float32 distance [m] from each cell's centre to the nearest
            lethal cell's centre (``inf`` when the map has no lethal cell).
        shareable: whether planners may keep what they derive from this costmap (its search
            graph) in a process-wide cache shared by all robots with the same map; False for
            short-lived costmaps such as :func:`overlay_obstacles`'s.
        base: for :func:`overlay_obstacles`'s costmaps, the shareable costmap it was made from
            (None otherwise): a planner patches the base's search graph instead of building one.
        changed: with ``base``, the window ``(r0, r1, c0, c1)`` (rows ``r0:r1``, columns
            ``c0:c1``) outside which the costs equal the base's.
    """

    @property
    def key(self) -> bytes:
        """A digest of the costs, resolution and origin: equal for equal costmaps."""
        if "key" not in self._cache:
            h = hashlib.blake2b(self.costs.tobytes(), digest_size=16)
            h.update(np.asarray([self.resolution, *self.origin[:2], *self.costs.shape],
                                dtype=float).tobytes())
            self._cache["key"] = h.digest()
        return self._cache["key"]

    costs: np.ndarray
    resolution: float
    origin: np.ndarray
    obstacle_distance: np.ndarray
    shareable: bool = True
    base: Costmap | None = field(default=None, compare=False, repr=False)
    changed: tuple[int, int, int, int] | None = field(default=None, compare=False, repr=False)
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    height = property(lambda self: int(self.costs.shape[0]),
                      doc="Number of rows (cells along y).")
    width = property(lambda self: int(self.costs.shape[1]),
                     doc="Number of columns (cells along x).")

    def cost_at(self, xy) -> np.ndarray:
        """The (...,) uint8 costs at (..., 2) points x, y [m] in ``map``; ``LETHAL`` outside."""
        return self._lookup(self.costs, xy, LETHAL)

    def distance_at(self, xy) -> np.ndarray:
        """The (...,) distances [m] to the nearest lethal cell at (..., 2) points; 0 outside."""
        return self._lookup(self.obstacle_distance, xy, 0.0, float)

    def _lookup(self, grid: np.ndarray, xy, outside, dtype=None) -> np.ndarray:
        """``grid`` at the cells of (..., 2) points x, y [m], ``outside`` off the map."""
        rc = self.world_to_cell(xy)
        row, col = rc[..., 0], rc[..., 1]
        inside = self.in_bounds(rc)
        if inside.all():  # the usual case: one gather
            return np.asarray(grid[row, col], dtype=dtype or grid.dtype)
        out = np.full(rc.shape[:-1], outside, dtype=dtype or grid.dtype)
        out[inside] = grid[row[inside], col[inside]]
        return out

    def traversable(self, allow_unknown: bool) -> np.ndarray:
        """(H, W) bool mask of cells the robot's centre may occupy (cost < 253, or unknown)."""
        key = ("traversable", allow_unknown)
        if key not in self._cache:
            ok = self.costs < INSCRIBED
            if allow_unknown:
                ok |= self.costs == UNKNOWN
            self._cache[key] = ok
        return self._cache[key]

    def components(self, allow_unknown: bool) -> np.ndarray:
        """(H, W) int32 labels of the 4-connected components of :meth:`traversable` (0 = blocked).

        Two cells with the same non-zero label are connected by a path of traversable cells, which
        is exactly what the A* of :mod:`swarm_nav.planner` can find (its diagonal moves never cut
        between two cells, so they add no connectivity to the 4-connected one).
        """
        key = ("components", allow_unknown)
        if key not in self._cache:
            labels, _ = ndimage.label(self.traversable(allow_unknown))
            self._cache[key] = labels
        return self._cache[key]

    def boundary_points(self) -> Points2D:
        """(M, 2) x, y [m] in ``map`` of the centres of lethal cells that border a non-lethal one.

        The static map as an obstacle point cloud, for the local planner before and between scans.
        """
        if "boundary" not in self._cache:
            lethal = self.costs == LETHAL
            inner = ndimage.binary_erosion(lethal, structure=_EIGHT, border_value=1)
            rc = np.argwhere(lethal & ~inner)
            self._cache["boundary"] = self.cell_to_world(rc).reshape(-1, 2)
        return self._cache["boundary"]


def inflation_cost(distance, cfg: CostmapConfig, resolution: float | None = None) -> np.ndarray:
    """nav2's ``InflationLayer::computeCost`` for distances [m] to the nearest lethal cell.

    Args:
        distance: array of distances [m] (cell centre to lethal cell centre, ``cells * resolution``
            as nav2 computes it).
        cfg: robot_radius [m], inflation_radius [m], cost_scaling_factor [1/m].
        resolution: the grid's [m/cell]; with it, the inflated extent is nav2's
            ``cellDistance(inflation_radius) = ceil(inflation_radius / resolution)`` cells, else
            exactly ``inflation_radius``.

    Returns:
        uint8 array of the same shape: 254 at 0, 253 up to robot_radius, the exponential decay
        (truncated) up to the inflated extent, 0 beyond.
    """
    d = np.asarray(distance, dtype=float)
    if resolution is None:
        extent = cfg.inflation_radius + 1e-9
    else:
        extent = max(0.0, math.ceil(cfg.inflation_radius / resolution)) * resolution + 1e-9
    with np.errstate(over="ignore"):
        decay = (INSCRIBED - 1) * np.exp(-1.0 * cfg.cost_scaling_factor * (d - cfg.robot_radius))
    cost = np.where(d <= extent, np.floor(decay), 0.0)
    cost = np.where(d <= cfg.robot_radius, INSCRIBED, cost)
    cost = np.where(d <= 0.0, LETHAL, cost)
    return cost.astype(np.uint8)


def build_costmap(occ: OccupancyMap, cfg: CostmapConfig) -> Costmap:
    """Build the inflated costmap of a static map.

    Cells whose occupancy is at least ``cfg.lethal_cost_threshold`` are lethal (254); around them
    the inflation cost of :func:`inflation_cost`.  Unknown cells (-1) that inflation does not make
    inscribed or lethal stay 255 when ``cfg.track_unknown_space`` (nav2's behaviour with
    ``inflate_unknown`` false), and are free otherwise.

    Args:
        occ: the occupancy map, (H, W) int8, row 0 at the bottom.
        cfg: the costmap settings.

    Returns:
        The :class:`Costmap`, in the same layout, resolution and origin as ``occ``.
    """
    data = np.asarray(occ.data)
    lethal = data >= cfg.lethal_cost_threshold
    unknown = data < 0
    if lethal.any():
        dist = ndimage.distance_transform_edt(~lethal) * occ.resolution
    else:
        dist = np.full(data.shape, np.inf)
    costs = inflation_cost(dist, cfg, occ.resolution)
    if cfg.track_unknown_space:
        costs[unknown & (costs < INSCRIBED)] = UNKNOWN
    return Costmap(costs, float(occ.resolution), np.asarray(occ.origin, dtype=float),
                   dist.astype(np.float32))


def overlay_obstacles(costmap: Costmap, points: Points2D, cfg: CostmapConfig) -> Costmap:
    """Add obstacle points (e.g. robots seen in the scan) to a costmap, inflated as nav2 does.

    Only a window around the points is recomputed (a distance transform over the points' bounding
    box padded by the inflation radius), so a scan's worth of points costs about a millisecond.

    Args:
        costmap: the static costmap.
        points: (M, 2) x, y [m] in ``map`` of obstacle points; points outside the map are ignored.
        cfg: the costmap settings (robot_radius, inflation_radius, cost_scaling_factor).

    Returns:
        A new :class:`Costmap`: each cell the maximum of its static cost and the points' cost; the
        obstacle distance the minimum of both.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    rc = costmap.world_to_cell(pts)
    rc = rc[costmap.in_bounds(rc)]
    if len(rc) == 0:
        return costmap
    pad = int(np.ceil(cfg.inflation_radius / costmap.resolution)) + 2
    r0 = max(int(rc[:, 0].min()) - pad, 0)
    r1 = min(int(rc[:, 0].max()) + pad + 1, costmap.height)
    c0 = max(int(rc[:, 1].min()) - pad, 0)
    c1 = min(int(rc[:, 1].max()) + pad + 1, costmap.width)
    src = np.ones((r1 - r0, c1 - c0), dtype=bool)
    src[rc[:, 0] - r0, rc[:, 1] - c0] = False
    dist = ndimage.distance_transform_edt(src) * costmap.resolution
    costs = costmap.costs.copy()
    window = costs[r0:r1, c0:c1]
    new = inflation_cost(dist, cfg, costmap.resolution)
    known = window != UNKNOWN
    window[known] = np.maximum(window[known], new[known])
    window[~known & (new >= INSCRIBED)] = new[~known & (new >= INSCRIBED)]
    odist = costmap.obstacle_distance.copy()
    odist[r0:r1, c0:c1] = np.minimum(odist[r0:r1, c0:c1], dist)
    base = costmap if costmap.shareable else None
    return Costmap(costs, costmap.resolution, costmap.origin, odist, shareable=False, base=base,
                   changed=(r0, r1, c0, c1) if base is not None else None)


def add_keepout(costmap: Costmap, points, radius: float, cost: int) -> Costmap:
    """Raise the cost of discs about some points, so that paths pass them only when they must.

    Used for the workstations and holding spots of a factory floor: robots stop there, so paths
    to elsewhere should keep to the lanes.  A target inside such a disc stays reachable (the
    cost stays below the inscribed cost).

    Args:
        costmap: the static costmap.
        points: (K, 2) x, y [m] in ``map``.
        radius: the disc radius [m].
        cost: the cost (< 253) the discs get at least.

    Returns:
        A new :class:`Costmap` (lethal, inscribed and unknown cells unchanged).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or radius <= 0.0:
        return costmap
    cost = int(min(cost, INSCRIBED - 1))
    costs = costmap.costs.copy()
    centres = costmap.cell_to_world(np.argwhere(np.ones(costs.shape, dtype=bool))).reshape(
        costs.shape + (2,))
    inside = np.zeros(costs.shape, dtype=bool)
    for px, py in pts:
        inside |= (centres[..., 0] - px) ** 2 + (centres[..., 1] - py) ** 2 <= radius * radius
    raise_ = inside & (costs < cost)
    costs[raise_] = cost
    return Costmap(costs, costmap.resolution, costmap.origin, costmap.obstacle_distance)


def segment_profile(costmap: Costmap, a, b) -> tuple[np.ndarray, np.ndarray]:
    """The cells a segment passes through, exactly: the length in each and its cost.

    The segment is cut where it crosses grid lines; a cell only touched at a corner does not
    count.  Parts outside the map cost ``LETHAL``.

    Args:
        costmap: the costmap.
        a, b: (2,) x, y [m] in ``map`` of the segment's start and of its end.

    Returns:
        ``(lengths, costs)``: (P,) length [m] of each piece, in order, and (P,) its cell's cost.
    """
    a = np.asarray(a, dtype=float)[:2]
    b = np.asarray(b, dtype=float)[:2]
    return costmap_kernels.segment_profile(
        costmap.costs, float(costmap.resolution), float(costmap.origin[0]),
        float(costmap.origin[1]), float(a[0]), float(a[1]), float(b[0]), float(b[1]))


def segment_max_cost(costmap: Costmap, a, b) -> int:
    """The highest cost (0..255) of the cells the segment from ``a`` (2,) to ``b`` (2,) x, y [m]
    in ``map`` passes through, ``LETHAL`` if it leaves the map (exact: :func:`segment_profile`)."""
    return int(segment_profile(costmap, a, b)[1].max())
