"""Micro-benchmark of the simulator core (not a test): step and lidar time per tick.

Spawns N robots on slim_blockage (no ROS), drives them for a few ticks so that they are not on
their grid, then times ``SimEngine.step`` (kinematics, PyBullet contacts, separation) and
``SimEngine.scans`` (every robot's planar lidar).

Usage: ``python tools/sim_microbench.py [--robots 20 100] [--repeats 50]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from swarm_scene.poi import poi_for_world
from swarm_scene.robot_model import load_robot
from swarm_scene.spawn import spawn_poses
from swarm_scene.world import load_world, resolve_world, world_polygons
from swarm_sim.engine import SimEngine


def measure(n: int, repeats: int) -> tuple[float, float]:
    """Median step and scan times [ms] for ``n`` robots."""
    world = load_world("slim_blockage")
    robot = load_robot("turtlebot3_waffle")
    poi = poi_for_world(resolve_world("slim_blockage"))
    poses = spawn_poses(poi.spawn, n, robot.radius, world_polygons(world))
    engine = SimEngine(world, robot, poses, seed=0)
    try:
        v, w = np.full(n, 0.2), np.linspace(-1.0, 1.0, n)
        for _ in range(10):
            engine.step(v, w)
        steps, scans = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            engine.step(v, w)
            t1 = time.perf_counter()
            engine.scans()
            t2 = time.perf_counter()
            steps.append(t1 - t0)
            scans.append(t2 - t1)
        return statistics.median(steps) * 1e3, statistics.median(scans) * 1e3
    finally:
        engine.close()


def main() -> None:
    """Print a table of the median times."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[20, 100])
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()
    print(f"{'robots':>6} {'step [ms]':>10} {'lidar [ms]':>11}")
    for n in args.robots:
        step_ms, scan_ms = measure(n, args.repeats)
        print(f"{n:>6} {step_ms:>10.2f} {scan_ms:>11.2f}")


if __name__ == "__main__":
    main()
