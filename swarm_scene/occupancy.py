"""The occupancy map as every part of the project holds it in memory.

The layout is ``nav_msgs/OccupancyGrid``'s, so converting to and from the message is a copy:
``data[row, col]`` with row 0 at the map's *bottom* (``y = origin[1]``), column 0 at its left;
values ``-1`` unknown, ``0`` free, ``100`` occupied (``0..100`` in between for scale mode).
A map_server image has row 0 at the *top*; :mod:`swarm_scene.map_io` flips it on load and save.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UNKNOWN = -1
FREE = 0
OCCUPIED = 100


class GridGeometry:
    """Cell <-> ``map`` conversions of a grid with ``resolution``, ``origin``, ``height`` and
    ``width`` (row 0 at ``y = origin[1]``, as ``nav_msgs/OccupancyGrid``); a mixin of
    :class:`OccupancyMap` and the navigator's costmap."""

    def world_to_cell(self, xy) -> np.ndarray:
        """Convert (..., 2) points x, y [m] in ``map`` to integer (..., 2) cells ``(row, col)``.

        Cells outside the grid are returned as they are; use :meth:`in_bounds` to check.
        """
        xy = np.asarray(xy, dtype=float)
        col = np.floor((xy[..., 0] - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((xy[..., 1] - self.origin[1]) / self.resolution).astype(int)
        return np.stack((row, col), axis=-1)

    def cell_to_world(self, rc) -> np.ndarray:
        """Convert (..., 2) cells ``(row, col)`` to the (..., 2) x, y [m] of their centres."""
        rc = np.asarray(rc)
        x = self.origin[0] + (rc[..., 1] + 0.5) * self.resolution
        y = self.origin[1] + (rc[..., 0] + 0.5) * self.resolution
        return np.stack((x, y), axis=-1)

    def in_bounds(self, rc) -> np.ndarray:
        """Boolean (...,) mask of cells ``(row, col)`` that lie inside the grid."""
        rc = np.asarray(rc)
        return (rc[..., 0] >= 0) & (rc[..., 0] < self.height) & (rc[..., 1] >= 0) & (
            rc[..., 1] < self.width
        )


@dataclass(frozen=True)
class OccupancyMap(GridGeometry):
    """A 2D occupancy grid in the ``map`` frame.

    Attributes:
        data: (H, W) int8 array, -1 unknown / 0 free / 100 occupied; row 0 at ``y = origin[1]``.
        resolution: cell size [m/cell].
        origin: (3,) pose of cell (0, 0)'s lower-left corner in ``map``: x [m], y [m], yaw [rad]
            (map_server's ``origin``; yaw is carried but, as in nav2, not applied).
    """

    data: np.ndarray
    resolution: float
    origin: np.ndarray

    @property
    def height(self) -> int:
        """Number of rows (cells along y)."""
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        """Number of columns (cells along x)."""
        return int(self.data.shape[1])
