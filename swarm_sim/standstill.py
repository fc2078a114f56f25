"""Where robots stand still: episodes of a robot staying within a small circle for a long time.

A jam shows as robots that do not move for minutes; issue 9 asks where that happens (a holding
spot, a corridor, a workstation). The simulator feeds :class:`StandstillTracker` every robot's
true pose each control tick; an *episode* starts when a robot's position comes to rest (its
anchor) and ends at the first tick the robot is more than ``radius`` from that anchor. Episodes
of at least ``min_duration`` are kept, with the anchor's position; turning in place is standing
still. An episode still open at the end of the run is closed there (``open: true``).

Frames: positions in ``map`` [m], times in simulated seconds. Pure numpy (no ROS, no PyBullet).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STANDSTILL_RADIUS_M = 0.10  # [m] moving less than this from where it stopped is standing still
STANDSTILL_MIN_S = 60.0  # [s] simulated: issue 9's "standing still for more than 60 s"


@dataclass(frozen=True)
class Standstill:
    """One episode of a robot standing still.

    Attributes:
        robot: the robot's index (0-based, spawn order).
        start_s: simulated time it came to rest [s].
        duration_s: how long it stayed within the radius [s].
        x, y: where it stood (its position at ``start_s``) in ``map`` [m].
        open: True when the run ended before the robot moved on.
    """

    robot: int
    start_s: float
    duration_s: float
    x: float
    y: float
    open: bool = False


class StandstillTracker:
    """Finds every standstill of at least ``min_duration`` of every robot.

    Args:
        poses: (N, 3) the robots' poses x, y [m], yaw [rad] in ``map`` at ``t0``.
        t0: simulated time of those poses [s].
        radius: a robot within this distance [m] of its anchor is standing still.
        min_duration: the shortest episode kept [s].
    """

    def __init__(self, poses: np.ndarray, t0: float = 0.0,
                 radius: float = STANDSTILL_RADIUS_M, min_duration: float = STANDSTILL_MIN_S):
        self.radius = float(radius)
        self.min_duration = float(min_duration)
        self._anchor = np.array(poses, dtype=float)[:, :2].copy()
        self._since = np.full(len(self._anchor), float(t0))
        self._t = float(t0)
        self.episodes: list[Standstill] = []

    def update(self, t: float, poses: np.ndarray) -> None:
        """Take the poses of the tick at simulated time ``t`` [s] ((N, 3) in ``map``)."""
        xy = np.asarray(poses, dtype=float)[:, :2]
        d = xy - self._anchor
        moved = np.flatnonzero(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] > self.radius ** 2)
        for i in moved.tolist():  # (few per tick: only robots that just left their anchor)
            self._close(i, self._t, open_=False)
            self._anchor[i] = xy[i]
            self._since[i] = t
        self._t = float(t)

    def finish(self) -> list[Standstill]:
        """Close the episodes still open at the last update; return every episode, by start."""
        for i in range(len(self._anchor)):
            self._close(i, self._t, open_=True)
            self._since[i] = self._t
        self.episodes.sort(key=lambda e: (e.start_s, e.robot))
        return self.episodes

    def _close(self, i: int, end: float, open_: bool) -> None:
        duration = end - float(self._since[i])
        if duration >= self.min_duration:
            x, y = (round(float(c), 3) for c in self._anchor[i])
            self.episodes.append(Standstill(i, round(float(self._since[i]), 3),
                                            round(duration, 3), x, y, open_))
