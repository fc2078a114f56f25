"""The navigator's compiled kernels: compile (or load) them all before the robots need them.

The inner loops of the local planner, the perception, the planner's shortcuts and the costmap
geometry are compiled with numba (``swarm_nav.*_kernels``, ``cache=True``): the first process on a
machine compiles them, in about 15 s of CPU, and writes the machine code beside the sources;
every later process loads it in about half a second.  A navigator whose first tick compiled them
would answer that tick late by those 15 s (wall clock only: the lockstep waits, the simulated
run is the same), so every navigator process calls :func:`warm_up` at start, ``swarm-up`` runs
it once before the navigators start when the cache holds no kernels yet (so they do not all
compile at once), and the test session runs it at its start (``tests/conftest.py``).

:func:`warm_up` drives one :class:`~swarm_nav.core.NavigatorCore` through a small scene that
takes every compiled path with the argument types of a real run: a robot plans across a room,
perceives another robot standing on its path and one moving, replans around them (an overlay
replan with shortcuts), and holds short of a workstation that is taken; then it calls the entry
points the scene need not reach (``tests/swarm_nav/test_jit.py`` checks that every kernel the
Python code calls has been compiled).
"""

from __future__ import annotations

import math
import time

import numpy as np

_done = False  # warmed up in this process
_WALL = 100
_ROOM = (8.0, 6.0)  # [m] the scene's room, walls one cell thick
_RES = 0.05  # [m/cell]


def _scene_map():
    from swarm_scene.occupancy import OccupancyMap

    w, h = (int(round(v / _RES)) for v in _ROOM)
    data = np.zeros((h, w), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = _WALL
    data[: h // 2, int(3.0 / _RES)] = _WALL  # a wall half across the room
    return OccupancyMap(data, _RES, np.array([0.0, 0.0, 0.0]))


def _robot_points(x: float, y: float) -> np.ndarray:
    """(16, 2) points [m] of a 0.27 m square robot's outline seen by the lidar."""
    s = np.linspace(-0.135, 0.135, 4)
    edge = np.full(4, 0.135)
    return np.vstack([np.column_stack((x + a, y + b)) for a, b in
                      ((s, -edge), (s, edge), (-edge, s), (edge, s))])


def warm_up() -> float:
    """Compile, or load from numba's cache, every kernel the navigator calls.

    Once per process: later calls return at once.

    Returns:
        The wall time it took [s] (about 15 s the first time on a machine, well under 1 s after;
        0 when this process already warmed up).
    """
    global _done
    if _done:
        return 0.0
    t0 = time.perf_counter()
    from swarm_nav import planner_kernels
    from swarm_nav.config import NavigatorConfig
    from swarm_nav.core import NavigatorCore
    from swarm_nav.costmap import segment_max_cost

    footprint = np.array([[-0.197, -0.133], [0.069, -0.133], [0.069, 0.133], [-0.197, 0.133]])
    goal = np.array([6.5, 1.0, 0.0])
    holding = np.array([[6.0, 3.0], [6.5, 3.5], [7.0, 3.0]])
    core = NavigatorCore(NavigatorConfig(), footprint, [(goal, holding)])
    core.set_map(_scene_map())
    pose = np.array([1.0, 1.0, 0.0])
    v = w = 0.0
    dt = 0.1
    core.set_goal(goal, "warm-up", 0.0)
    for tick in range(80):
        now = tick * dt
        if tick % 2 == 0:  # the lidar's rate: one standing on the path, one crossing, one docked
            crossing = _robot_points(2.0, 1.0 + 0.02 * tick)
            docked = _robot_points(goal[0], goal[1])
            points = np.vstack((_robot_points(2.2, 4.5), crossing, docked))
            points = points[np.hypot(*(points - pose[:2]).T) < 3.5]
            core.on_scan(points, now)
        v, w = core.step(pose, v, w, now)
        pose = pose + np.array([v * math.cos(pose[2]) * dt, v * math.sin(pose[2]) * dt, w * dt])
    # entry points the scene need not reach: the holding pattern's line of sight, the
    # planner's whole search (an overlay without a patch is searched whole), its repair
    # (planner.overlay_astar false) and its A* (true)
    segment_max_cost(core.costmap, pose[:2], goal[:2])
    planner_kernels.dijkstra(np.zeros(0), np.zeros(0, dtype=np.int32),
                             np.zeros(2, dtype=np.int32), 0, 0, math.inf)
    planner_kernels.settle(np.zeros(0), np.zeros(0, dtype=np.int32), np.zeros(2, dtype=np.int32),
                           np.zeros(1), np.full(1, -9999, dtype=np.int32), np.zeros((1, 2)), 0,
                           -1, math.inf, math.inf)
    planner_kernels.repair_dijkstra(np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int32),
                                    np.zeros(2, dtype=np.int32), np.zeros(1),
                                    np.full(1, -9999, dtype=np.int32), np.zeros(0, dtype=np.int32),
                                    np.zeros(0, dtype=np.int64), 0, 0, math.inf)
    planner_kernels.astar(np.zeros(0), np.full((1, 8), -1, dtype=np.int32),
                          np.zeros(8, dtype=np.int64), np.zeros((8, 2), dtype=np.int64), 1,
                          np.zeros(1), 0, 0)
    _done = True
    return time.perf_counter() - t0


def main() -> int:
    """``python -m swarm_nav.jit``: warm up, say how long it took."""
    print(f"swarm_nav.jit: the navigator's kernels are ready ({warm_up():.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
