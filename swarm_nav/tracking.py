"""Following the global path: where along it the robot is, what lies ahead, and what blocks it.

:class:`PathTracker` holds one robot's path, its arc lengths and the progress index (the path
point nearest the robot, searched only a few points ahead of the last one, so a path that doubles
back is followed in order). The navigator (:mod:`swarm_nav.core`) asks it for the local stretch
handed to the DWA, the deviation that triggers a replan, the stretch ahead checked for blockage
and congestion, and the distance still to drive. Pure: numpy, no ROS.
"""

from __future__ import annotations

import numpy as np

from swarm_nav import core_kernels
from swarm_nav.config import NavigatorConfig
from swarm_nav.costmap import INSCRIBED, Costmap
from swarm_nav.perception import ObstacleSet

LOCAL_WINDOW = 3.0  # [m] of path handed to the DWA
SEARCH_AHEAD = 40   # path points searched ahead of the progress index
SPIN_LOOKAHEAD = 5  # path points ahead of the progress index that choose a spin's direction
NEAR_PATH_SLACK = 0.5  # [m] robots centred farther than the checked distance plus this are
#                        not looked at for the path ahead (a cheap pre-filter)


class PathTracker:
    """The path one robot follows, and its progress along it.

    Args:
        cfg: ``blocked_check_distance`` [m], ``stationary_replan_time`` and
            ``blocked_replan_time`` [s], ``costmap.robot_radius`` [m] and
            ``holding.moving_speed`` [m/s].

    Attributes:
        path, s: (N, 2) x, y [m] in ``map`` (or ``None``), and (N,) each point's arc length
            [m] from the first.
        to_goal: whether the path leads to the goal (not to a holding point or a retreat).
        version: incremented whenever a path is set.
        idx: the progress index into ``path``.
    """

    def __init__(self, cfg: NavigatorConfig):
        self.cfg = cfg
        self.path: np.ndarray | None = None
        self.s: np.ndarray | None = None
        self.to_goal = False
        self.version = 0
        self.idx = 0
        self._blocked_since: float | None = None
        self._lethal_key: tuple | None = None
        self._lethal_mask = np.zeros(0, dtype=bool)

    def set(self, path: np.ndarray, to_goal: bool) -> None:
        """Follow ``path`` (N, 2) [m] from its start; ``to_goal``: it leads to the goal."""
        self.path = np.asarray(path, dtype=float)
        seg = np.hypot(*np.diff(self.path, axis=0).T) if len(self.path) > 1 else np.zeros(0)
        self.s = np.concatenate(([0.0], np.cumsum(seg)))
        self.to_goal = to_goal
        self.version += 1
        self.idx = 0

    def advance(self, pose: np.ndarray) -> None:
        """Move the progress index to the nearest of the next ``SEARCH_AHEAD`` points."""
        hi = min(len(self.path), self.idx + SEARCH_AHEAD)
        d = np.hypot(*(self.path[self.idx:hi] - pose[:2]).T)
        self.idx += int(np.argmin(d))

    def deviation(self, pose: np.ndarray) -> float:
        """Distance [m] from the robot to the path point at the progress index."""
        return float(np.hypot(*(self.path[self.idx] - pose[:2])))

    def local(self) -> np.ndarray:
        """(K, 2) the next ``LOCAL_WINDOW`` of path, from the progress index (at least a point)."""
        s0 = self.s[self.idx]
        hi = int(np.searchsorted(self.s, s0 + LOCAL_WINDOW, side="right"))
        return self.path[self.idx:max(hi, self.idx + 1)]

    def ahead(self, distance: float) -> np.ndarray:
        """(K, 2) the path points from the progress index up to ``distance`` [m] along it
        (exclusive; at least one)."""
        s0 = self.s[self.idx]
        hi = int(np.searchsorted(self.s, s0 + distance))
        return self.path[self.idx:max(hi, self.idx + 1)]

    def spin_target(self) -> np.ndarray:
        """(2,) the path point ``SPIN_LOOKAHEAD`` ahead of the progress index (or the last)."""
        return self.path[min(self.idx + SPIN_LOOKAHEAD, len(self.path) - 1)]

    def remaining(self, pose: np.ndarray) -> float:
        """Distance [m] still to drive along the path: to the point at the progress index, then
        along the path to its end."""
        i = min(self.idx, len(self.path) - 1)
        return float(np.hypot(*(self.path[i] - pose[:2])) + self.s[-1] - self.s[i])

    def lethal(self, costmap: Costmap) -> np.ndarray:
        """(N,) whether each path point lies in an inscribed or lethal cell of the static
        costmap (kept per path and costmap)."""
        key = self._lethal_key
        if key is None or key[0] != self.version or key[1] is not costmap:
            self._lethal_mask = costmap.cost_at(self.path) >= INSCRIBED
            self._lethal_key = (self.version, costmap)
        return self._lethal_mask

    def robots_on(self, obs: ObstacleSet, pose: np.ndarray, distance: float, radius: float,
                  now: float) -> np.ndarray:
        """(J,) indices of the robots seen (``obs.seen``, a fresh scan only) with a point within
        ``radius`` [m] of the next ``distance`` [m] of path (all robots' points checked at
        once)."""
        seen = obs.seen
        if self.path is None or not len(seen.centres) or not obs.fresh(now):
            return np.zeros(0, dtype=int)
        ahead = self.ahead(distance)
        return core_kernels.robots_near_path(
            seen.centres, seen.points, seen.starts, seen.sizes, np.ascontiguousarray(ahead[:, 0]),
            np.ascontiguousarray(ahead[:, 1]), float(pose[0]), float(pose[1]),
            distance + NEAR_PATH_SLACK, radius)

    def unblock(self) -> None:
        """Forget since when the path has been blocked (a replan was tried)."""
        self._blocked_since = None

    def blocked(self, costmap: Costmap, obs: ObstacleSet, pose: np.ndarray, now: float) -> bool:
        """Whether to replan around what blocks the next ``blocked_check_distance`` of path: a
        cell of the static costmap at once; a robot seen standing on it after
        ``stationary_replan_time``; anything else seen on it after ``blocked_replan_time``."""
        cfg = self.cfg
        ahead = self.ahead(cfg.blocked_check_distance)
        if len(ahead) > 1 and self.lethal(costmap)[self.idx + 1:self.idx + len(ahead)].any():
            return True
        blockers = self.robots_on(obs, pose, cfg.blocked_check_distance,
                                  cfg.costmap.robot_radius, now)
        if not len(blockers):
            self._blocked_since = None
            return False
        if self._blocked_since is None:
            self._blocked_since = now
        seen = obs.seen
        standing = bool((seen.known[blockers]
                         & (seen.speed[blockers] < cfg.holding.moving_speed)).any())
        wait = cfg.stationary_replan_time if standing else cfg.blocked_replan_time
        return now - self._blocked_since >= wait
