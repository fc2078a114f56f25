"""Micro-benchmark of the navigator's pure core on slim_blockage (a benchmark, not a test).

Prints the median time of a DWA step (open scenes, a crowd of robots, a dense cloud), of the
footprint gap of a few predicted points, of a whole NavigatorCore tick, of a scan update, and of
cross-map global plans (fresh cost-to-go, and a replan to the same goal), as a small table.

The map is ``maps/slim_blockage.yaml`` when it exists and ``swarm_scene.map_io`` can load it,
else the world's wall table (``shared/reference/seed_facts.md``) rasterised at ``--resolution``.
Scans are synthetic: the map's obstacle boundary seen from the robot, one return per degree within
3.5 m (the LDS-01), plus another robot in front.

    python tools/nav_microbench.py [--repeat 200] [--resolution 0.05] [--map PATH]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from swarm_nav import planner  # noqa: E402
from swarm_nav.config import NavigatorConfig  # noqa: E402
from swarm_nav.core import NavigatorCore  # noqa: E402
from swarm_nav.costmap import build_costmap, overlay_obstacles  # noqa: E402
from swarm_nav.dwa import Footprint, RobotState, dwa_command, point_gaps  # noqa: E402
from swarm_nav.planner import plan_path  # noqa: E402
from swarm_scene.occupancy import OccupancyMap  # noqa: E402

# slim_blockage walls, xmin, xmax, ymin, ymax [m] (shared/reference/seed_facts.md)
WALLS = np.array([
    [-8.475, 9.525, -4.974, -4.824], [-8.475, 9.525, 9.376, 9.526],
    [-8.475, -8.325, -4.974, 9.526], [9.375, 9.525, -4.974, 9.526],
    [-5.262, -5.112, -3.016, 7.484], [-3.912, -3.762, -3.016, 7.484],
    [-5.262, -3.762, -3.016, -2.866], [-5.262, -3.762, 7.334, 7.484],
    [3.909, 4.059, -4.912, -1.412], [3.909, 9.409, -1.562, -1.412],
])
WAFFLE = np.array([[-0.197, -0.133], [0.069, -0.133], [0.069, 0.133], [-0.197, 0.133]])

# (pose x, y, yaw) of the DWA scenarios, each with another robot 0.7 m ahead: open floor, the
# 1.81 m passage, docked at loader 1 facing the wall, the corner above the blockage, beside the
# pocket wall
POSES = [(0.0, 0.0, math.pi), (-4.5, -3.9, 0.0), (-7.74575, -3.57766, math.pi),
         (-6.6, 8.5, 0.0), (6.0, -1.1, 0.0)]
# cross-map plans (start, goal)
PLANS = [((8.5, 8.5), (-7.74575, -3.57766)), ((0.0, 0.0), (-7.74575, 5.78442)),
         ((-7.7, 8.5), (3.0, -4.0)), ((7.0, 7.0), (-7.74575, 0.97297))]


def rasterize(resolution: float) -> OccupancyMap:
    """The wall table as an occupancy map (a cell overlapping a wall is occupied)."""
    x0, y0 = WALLS[:, 0].min(), WALLS[:, 2].min()
    w = int(round((WALLS[:, 1].max() - x0) / resolution))
    h = int(round((WALLS[:, 3].max() - y0) / resolution))
    data = np.zeros((h, w), dtype=np.int8)
    xs = x0 + np.arange(w) * resolution
    ys = y0 + np.arange(h) * resolution
    for bx0, bx1, by0, by1 in WALLS:
        cols = (xs + resolution > bx0 + 1e-9) & (xs < bx1 - 1e-9)
        rows = (ys + resolution > by0 + 1e-9) & (ys < by1 - 1e-9)
        data[np.ix_(rows, cols)] = 100
    return OccupancyMap(data, resolution, np.array([x0, y0, 0.0]))


def load(map_path: str | None, resolution: float) -> tuple[OccupancyMap, str]:
    path = Path(map_path) if map_path else ROOT / "maps" / "slim_blockage.yaml"
    if path.exists():
        try:
            from swarm_scene.map_io import load_map

            return load_map(path), str(path)
        except ImportError:
            pass
    return rasterize(resolution), f"wall table at {resolution} m"


def synthetic_scan(boundary: np.ndarray, pose, other=None) -> np.ndarray:
    """One return per degree: the nearest boundary point (and robot point) in each 1 deg bin.

    ``other`` is one robot's pose (3,), or (K, 3) poses of several, each seen as its front face.
    """
    pts = boundary
    if other is not None:
        s = np.linspace(-0.133, 0.133, 12)
        faces = [pts]
        for ox, oy, oyaw in np.asarray(other, dtype=float).reshape(-1, 3):
            c, si = math.cos(oyaw), math.sin(oyaw)
            faces.append(np.column_stack((ox + 0.069 * c - s * si, oy + 0.069 * si + s * c)))
        pts = np.vstack(faces)
    d = pts - pose[:2]
    r = np.hypot(d[:, 0], d[:, 1])
    keep = (r > 0.12) & (r < 3.5)
    d, r, pts = d[keep], r[keep], pts[keep]
    bins = np.floor(np.degrees(np.arctan2(d[:, 1], d[:, 0])) + 180).astype(int) % 360
    order = np.lexsort((r, bins))
    first = np.concatenate(([True], np.diff(bins[order]) != 0))
    return pts[order][first]


def median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="nav_microbench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=200, help="calls per DWA/tick figure [200]")
    ap.add_argument("--plans", type=int, default=5, help="repeats per cross-map plan [5]")
    ap.add_argument("--resolution", type=float, default=0.05,
                    help="[m/cell] of the rasterised wall table when no map file is used [0.05]")
    ap.add_argument("--map", default=None, help="a map_server YAML instead of slim_blockage")
    args = ap.parse_args(argv)

    occ, source = load(args.map, args.resolution)
    cfg = NavigatorConfig()
    t0 = time.perf_counter()
    cm = build_costmap(occ, cfg.costmap)
    t_costmap = 1e3 * (time.perf_counter() - t0)
    fp = Footprint.from_polygon(WAFFLE)
    boundary = cm.boundary_points()
    rows = [("map", f"{occ.width} x {occ.height} cells, {source}"),
            ("build_costmap", f"{t_costmap:.1f} ms")]

    def dwa_median(pose: np.ndarray, scan: np.ndarray) -> float:
        """Median ms of the DWA at ``pose`` driving 0.2 m/s along a 3 m straight path ahead."""
        x, y, yaw = pose
        s = np.linspace(0.0, 3.0, 31)
        path = np.column_stack((x + s * math.cos(yaw), y + s * math.sin(yaw)))
        state = RobotState(pose, 0.2, 0.1)
        return median_ms(lambda: dwa_command(state, path, scan, cfg.dwa, footprint=fp,
                                             dt=cfg.control_period), args.repeat)

    # DWA alone
    dwa_ms, n_pts = [], []
    for x, y, yaw in POSES:
        pose = np.array([x, y, yaw])
        other = pose + [0.7 * math.cos(yaw), 0.7 * math.sin(yaw), math.pi]
        scan = synthetic_scan(boundary, pose, other)
        n_pts.append(len(scan))
        dwa_ms.append(dwa_median(pose, scan))
    rows.append(("dwa_command median", f"{statistics.median(dwa_ms):.2f} ms "
                 f"(per scenario {', '.join(f'{m:.2f}' for m in dwa_ms)}; "
                 f"{min(n_pts)}-{max(n_pts)} scan points)"))
    # worst case: a dense random cloud of 400 points all around, the nearest 0.1 m off the box
    rng = np.random.default_rng(0)
    cloud = rng.uniform(-1.0, 1.0, size=(4000, 2))
    gap = np.maximum(np.abs(cloud[:, 0] + 0.064) - 0.133, np.abs(cloud[:, 1]) - 0.133)
    cloud = cloud[gap > 0.1][:400]
    state = RobotState(np.zeros(3), 0.2, 0.0)
    path = np.column_stack((np.linspace(0.0, 3.0, 31), np.zeros(31)))
    worst = median_ms(lambda: dwa_command(state, path, cloud, cfg.dwa, footprint=fp,
                                          dt=cfg.control_period), args.repeat)
    rows.append(("dwa_command, dense cloud", f"{worst:.2f} ms (400 points within 1 m)"))
    # a crowd: 8 robots 0.5-1.2 m around, facing us, in the open and in the passage
    crowd_ms = []
    for x, y, yaw in POSES[:2]:
        pose = np.array([x, y, yaw])
        ang = yaw + np.linspace(-2.5, 2.5, 8)
        r = 0.5 + 0.1 * np.arange(8)
        others = np.column_stack((x + r * np.cos(ang), y + r * np.sin(ang), ang + math.pi))
        crowd_ms.append(dwa_median(pose, synthetic_scan(boundary, pose, others)))
    rows.append(("dwa_command, crowd of 8", f"{statistics.median(crowd_ms):.2f} ms "
                 f"(per scenario {', '.join(f'{m:.2f}' for m in crowd_ms)})"))
    # the navigator filters each moving robot's predicted points with point_gaps, twice a tick
    face = cloud[:12]
    gaps_us = 1e3 * median_ms(lambda: point_gaps(np.array([0.0, 0.0, 0.3]), face, fp),
                              args.repeat * 5)
    rows.append(("point_gaps, 12 points", f"{gaps_us:.1f} us"))

    # the whole tick: on_scan at 5 Hz, step at 10 Hz
    core = NavigatorCore(cfg, WAFFLE)
    core.set_map(occ)
    pose = np.array([0.0, 0.0, math.pi])
    core.step(pose, 0.0, 0.0, 0.0)
    core.set_goal(np.array([-7.74575, -3.57766, math.pi]), "bench", 0.0)
    scan = synthetic_scan(boundary, pose, pose + [-1.2, 0.0, math.pi])
    scan_ms = median_ms(lambda: core.on_scan(scan, 0.0), args.repeat)
    clock = [0.0]

    def tick():
        clock[0] += 0.1
        core.step(pose, 0.2, 0.0, clock[0])
    step_ms = median_ms(tick, args.repeat)
    rows.append(("NavigatorCore.on_scan median", f"{scan_ms:.2f} ms"))
    rows.append(("NavigatorCore.step median", f"{step_ms:.2f} ms (driving, a robot ahead)"))

    # cross-map plans: fresh cost-to-go each time, then a replan to the same goal
    fresh, cached = [], []
    plan_path(cm, (0.0, 0.0), (1.0, 1.0), cfg.planner)   # builds the graph once per costmap
    for start, goal in PLANS:
        for _ in range(args.plans):
            planner._TOGO.clear()  # a fresh cost-to-go (Dijkstra) each time
            fresh.append(median_ms(lambda s=start, g=goal: plan_path(cm, s, g, cfg.planner), 1))
        cached.append(median_ms(lambda s=start, g=goal: plan_path(cm, s, g, cfg.planner), 3))
    planner._GRAPHS.clear()
    planner._TOGO.clear()
    t0 = time.perf_counter()
    fresh_cm = build_costmap(occ, cfg.costmap)
    plan_path(fresh_cm, PLANS[0][0], PLANS[0][1], cfg.planner)
    first = 1e3 * (time.perf_counter() - t0)
    rows.append(("plan_path cross-map median", f"{statistics.median(fresh):.1f} ms "
                 f"(max {max(fresh):.1f})"))
    rows.append(("plan_path replan, same goal", f"{statistics.median(cached):.1f} ms"))
    rows.append(("first plan on a new map", f"{first:.1f} ms (costmap + graph + search)"))
    res = plan_path(cm, (0.0, 0.0), (6.5, -3.0), cfg.planner)
    pocket = median_ms(lambda: plan_path(cm, (0.0, 0.0), (6.5, -3.0), cfg.planner), 5)
    rows.append(("plan_path into the closed pocket", f"{pocket:.2f} ms -> {res.reason!r}"))

    astar_cfg = replace(cfg.planner, overlay_astar=True)
    # replans around a robot standing on the path (a costmap with that robot overlaid), as the
    # navigator does when its path is blocked: a far goal, and a goal 3 m away
    for name, start, goal in (("far goal", (0.0, 0.0), (-7.74575, -3.57766)),
                              ("goal 3 m away", (-4.5, -3.9), (-1.5, -3.9))):
        res = plan_path(cm, start, goal, cfg.planner)
        blocker = res.path[min(20, len(res.path) - 1)]
        ring = blocker + 0.15 * np.column_stack((np.cos(np.linspace(0, 6.2, 24)),
                                                np.sin(np.linspace(0, 6.2, 24))))
        around = median_ms(lambda s=start, g=goal, r=ring: plan_path(
            overlay_obstacles(cm, r, cfg.costmap), s, g, cfg.planner), args.plans)
        guided = median_ms(lambda s=start, g=goal, r=ring: plan_path(
            overlay_obstacles(cm, r, cfg.costmap), s, g, astar_cfg), args.plans)
        rows.append((f"replan around a robot, {name}",
                     f"{around:.1f} ms (repair), {guided:.2f} ms (overlay_astar)"))

    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
