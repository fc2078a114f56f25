"""The global planner: optimal cost, valid paths, NavFn-like goal tolerance, distinct failures."""

import dataclasses
import heapq
import math

import numpy as np
import pytest

from swarm_nav import planner
from swarm_nav.config import CostmapConfig, PlannerConfig
from swarm_nav.costmap import INSCRIBED, add_keepout, build_costmap, overlay_obstacles
from swarm_nav.planner import path_length, plan_path, resample_path
from tests.swarm_nav.helpers import grid_map, random_grid, slim_blockage_map

PCFG = PlannerConfig()
SMALL = CostmapConfig(robot_radius=0.1, inflation_radius=0.35, cost_scaling_factor=3.0)


def brute_force_cost(costs: np.ndarray, start, goal, penalty: float, res: float) -> float:
    """Plain Dijkstra over the 8-connected grid, written from the cost definition alone.

    A move into cell c costs length * (1 + penalty * cost(c) / 252); cells >= 253 are blocked;
    a diagonal move needs both cells beside it free.
    """
    h, w = costs.shape

    def free(r, c):
        return 0 <= r < h and 0 <= c < w and costs[r, c] < 253

    best = {tuple(start): 0.0}
    heap = [(0.0, tuple(start))]
    while heap:
        d, (r, c) = heapq.heappop(heap)
        if (r, c) == tuple(goal):
            return d
        if d > best[(r, c)]:
            continue
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if (dr, dc) == (0, 0) or not free(r + dr, c + dc):
                    continue
                if dr and dc and not (free(r + dr, c) and free(r, c + dc)):
                    continue
                nd = d + math.hypot(dr, dc) * res * (1 + penalty * costs[r + dr, c + dc] / 252)
                if nd < best.get((r + dr, c + dc), math.inf):
                    best[(r + dr, c + dc)] = nd
                    heapq.heappush(heap, (nd, (r + dr, c + dc)))
    return math.inf


def assert_valid_path(cm, path, start, goal, resolution=0.1, skip_first=False):
    assert np.allclose(path[0], start) and np.allclose(path[-1], goal)
    assert path_length(path) >= np.hypot(*(np.asarray(goal) - start)) - 1e-9
    gaps = np.hypot(*np.diff(path, axis=0).T)
    assert gaps.max() <= resolution + 1e-9
    pts = path
    if skip_first:  # the escape from the inscribed zone: check from the first free point on
        pts = path[int(np.argmax(cm.cost_at(path) < INSCRIBED)):]
    # sample every segment finely: no point in a lethal or inscribed cell
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        t = np.linspace(0, 1, 25)[:, None]
        assert np.all(cm.cost_at(a + t * (b - a)) < INSCRIBED), (a, b)


def assert_costs_match_brute_force(cm, cfg: PlannerConfig, rng, check, queries: int = 4):
    """Plan between random free cells; the cost must equal :func:`brute_force_cost` (or the
    planner says "no path"), and ``check(result, start_xy, goal_xy)`` holds for each path."""
    free = np.argwhere(cm.costs < INSCRIBED)
    for _ in range(queries):
        s, g = free[rng.choice(len(free), 2, replace=False)]
        want = brute_force_cost(cm.costs, s, g, cfg.cost_penalty, cm.resolution)
        res = plan_path(cm, cm.cell_to_world(s), cm.cell_to_world(g), cfg)
        if math.isinf(want):
            assert res.path is None and res.reason == "no path"
        else:
            assert res.reason == ""
            assert res.cost == pytest.approx(want, rel=1e-9, abs=1e-9)
            check(res, cm.cell_to_world(s), cm.cell_to_world(g))


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("penalty", [0.0, 2.0, 10.0])
def test_cost_equals_brute_force_dijkstra(seed, penalty):
    rng = np.random.default_rng(seed)
    occ = random_grid(rng, 22, 27, 0.12)
    cm = build_costmap(occ, SMALL)
    cfg = PlannerConfig(cost_penalty=penalty)
    check = lambda res, s, g: assert_valid_path(cm, res.path, s, g)  # noqa: E731
    assert_costs_match_brute_force(cm, cfg, rng, check)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("penalty", [0.0, 3.0])
def test_replans_around_overlaid_points_equal_brute_force_dijkstra(seed, penalty):
    """An overlay's search graph is its base's, patched around the points (not rebuilt): the
    costs must equal a search written from the definition on the overlay's costs, including
    windows at the map's edge."""
    rng = np.random.default_rng(100 + seed)
    occ = random_grid(rng, 24, 30, 0.08)
    base = build_costmap(occ, SMALL)
    cfg = PlannerConfig(cost_penalty=penalty, overlay_astar=False)  # the repair's paths
    plan_path(base, base.cell_to_world(np.argwhere(base.costs < INSCRIBED)[0]),
              base.cell_to_world(np.argwhere(base.costs < INSCRIBED)[-1]), cfg)  # base graph
    extent = np.array([occ.width, occ.height]) * occ.resolution
    points = rng.uniform(0.0, 1.0, size=(rng.integers(1, 6), 2)) * extent
    cm = overlay_obstacles(base, points, SMALL)
    assert cm.base is base and cm.changed is not None
    with planner._search_graph(cm, cfg) as graph:
        dense_p = graph.toarray()
    rebuilt = planner._build_graph(cm, cfg)[0]
    plain = dataclasses.replace(cm, base=None, changed=None, _cache={})  # searched on `rebuilt`
    check = lambda res, s, g: np.testing.assert_array_equal(  # noqa: E731
        res.path, plan_path(plain, s, g, cfg).path)
    assert_costs_match_brute_force(cm, cfg, rng, check)
    # the same graph as a rebuild, bar the slots of forbidden moves (infinite in the patch)
    dense_r = rebuilt.toarray()
    finite = np.isfinite(dense_p) & (dense_p > 0)
    assert np.array_equal(finite, dense_r > 0)
    assert np.allclose(dense_p[finite], dense_r[finite], rtol=0, atol=1e-12)
    # the scratch graph the patch was written into holds its base's costs again
    base_graph, _, scratch = planner._shared_graph(base, cfg)
    np.testing.assert_array_equal(scratch.data, base_graph.data)


def test_cross_map_plan_on_slim_blockage():
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    start, goal = np.array([8.5, 8.5]), np.array([-7.74575, -3.57766])
    res = plan_path(cm, start, goal, PCFG)
    assert res.reason == "" and res.goal_shift == 0.0
    assert_valid_path(cm, res.path, start, goal)
    # around the blockage, never through it
    inside = ((res.path[:, 0] > -5.262) & (res.path[:, 0] < -3.762)
              & (res.path[:, 1] > -3.016) & (res.path[:, 1] < 7.484))
    assert not inside.any()
    assert path_length(res.path) < 1.25 * res.cost + 1e-9


def test_path_keeps_to_the_middle_of_the_passage():
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    res = plan_path(cm, [-6.5, -3.9], [-2.5, -3.9], PCFG)
    under = res.path[(res.path[:, 0] > -5.2) & (res.path[:, 0] < -3.8)]
    assert len(under) > 5
    centre = (-4.824 + -3.016) / 2
    assert np.all(np.abs(under[:, 1] - centre) < 0.15)


@pytest.mark.parametrize("goal, reason", [
    ((20.0, 0.0), "goal outside map"),
    ((6.5, -3.0), "no path"),             # the closed pocket
    ((-4.5, 2.0), "no path"),             # inside the closed blockage
    ((-5.187, 2.0), "goal in obstacle"),  # in the blockage's 0.15 m wall
    ((0.0, -4.9), "goal in obstacle"),    # in the bottom wall
])
def test_bad_goals_on_slim_blockage(goal, reason):
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    res = plan_path(cm, [0.0, 0.0], goal, PCFG)
    assert res.path is None and res.reason == reason and math.isinf(res.cost)


def _block_map():
    data = np.zeros((40, 40), dtype=np.int8)
    data[10:30, 10:30] = 100   # a 2 m x 2 m block
    return build_costmap(grid_map(data, 0.1), CostmapConfig())


def test_goal_deep_in_an_obstacle():
    res = plan_path(_block_map(), [0.5, 0.5], [2.0, 2.0], PCFG)
    assert res.path is None and res.reason == "goal in obstacle"


def test_goal_just_inside_the_inflation_plans_to_the_nearest_free_cell():
    cm = _block_map()
    goal = np.array([0.87, 2.0])   # 0.13 m from the block's face: inscribed
    assert cm.cost_at(goal) == INSCRIBED
    res = plan_path(cm, [0.2, 2.0], goal, PCFG)
    assert res.reason == ""
    assert 0.0 < res.goal_shift <= PCFG.tolerance
    assert cm.cost_at(res.path[-1]) < INSCRIBED
    assert res.goal_shift == pytest.approx(np.hypot(*(res.path[-1] - goal)))


def test_tolerance_zero_refuses_a_blocked_goal():
    res = plan_path(_block_map(), [0.2, 2.0], [0.87, 2.0], PlannerConfig(tolerance=0.0))
    assert res.reason == "goal in obstacle"


@pytest.mark.parametrize("start, reason", [((-1.0, 0.5), "start outside map"),
                                           ((2.0, 2.0), "start in obstacle")])
def test_bad_starts(start, reason):
    res = plan_path(_block_map(), start, [0.5, 0.5], PCFG)
    assert res.path is None and res.reason == reason


def test_start_in_the_inscribed_zone_escapes():
    cm = _block_map()
    start = np.array([0.9, 2.0])   # 0.1 m from the block
    assert cm.cost_at(start) == INSCRIBED
    res = plan_path(cm, start, [0.3, 3.8], PCFG)
    assert res.reason == ""
    assert np.allclose(res.path[0], start)
    assert_valid_path(cm, res.path, start, [0.3, 3.8], skip_first=True)


def test_accepts_a_pose_as_start():
    cm = _block_map()
    res = plan_path(cm, np.array([0.5, 0.5, 1.0]), [3.5, 3.5], PCFG)
    assert res.reason == "" and np.allclose(res.path[0], [0.5, 0.5])


def test_shortcut_makes_open_space_paths_straight():
    cm = build_costmap(grid_map(np.zeros((50, 50)), 0.1), CostmapConfig())
    start, goal = np.array([1.0, 1.0]), np.array([4.0, 2.7])
    res = plan_path(cm, start, goal, PCFG)
    u = (goal - start) / np.hypot(*(goal - start))
    d = (res.path[:, 0] - start[0]) * u[1] - (res.path[:, 1] - start[1]) * u[0]
    assert np.abs(d).max() < 1e-9
    assert path_length(res.path) == pytest.approx(np.hypot(*(goal - start)))


def test_resample_path_spacing():
    p = resample_path([[0.0, 0.0], [1.0, 0.0], [1.0, 0.55]], 0.1)
    assert np.allclose(p[0], [0, 0]) and np.allclose(p[-1], [1.0, 0.55])
    gaps = np.hypot(*np.diff(p, axis=0).T)
    assert np.all(gaps <= 0.1 + 1e-9)
    assert path_length(p) == pytest.approx(1.55, abs=0.02)


LOADERS = np.array([[-7.74575, y] for y in (-3.57766, -1.38526, 0.97297, 3.20313, 5.78442,
                                             8.36337)])


@pytest.mark.parametrize("start", [(-6.5, 6.0), (-8.1, 4.5), (-7.75, 7.0)])
def test_paths_keep_out_of_other_docks(start):
    """Keep-out discs about workstations: paths keep to the lane, also from a costly start."""
    cm = add_keepout(build_costmap(slim_blockage_map(), CostmapConfig()), LOADERS, 0.45, 180)
    assert cm.cost_at(LOADERS).tolist() == [180] * 6
    goal = LOADERS[0]
    res = plan_path(cm, start, goal, PCFG)
    assert res.reason == ""
    assert_valid_path(cm, res.path, start, goal, skip_first=True)
    t = np.linspace(0, 1, 20)[:, None]
    dense = np.vstack([a + t * (b - a) for a, b in zip(res.path[:-1], res.path[1:], strict=True)])
    far_from_start = np.hypot(*(dense - start).T) > 0.6
    d_other = np.hypot(dense[:, None, 0] - LOADERS[None, 1:, 0],
                       dense[:, None, 1] - LOADERS[None, 1:, 1]).min(axis=1)
    assert np.all(d_other[far_from_start] > 0.45)


def test_cost_to_go_cache_holds_one_field_per_robot_of_the_process():
    """``share_cost_to_go(n)``: the process keeps n static cost-to-go fields (at least 16), the
    least recently used going first; a field searched again gives the same plan."""
    cm = build_costmap(grid_map(np.zeros((30, 40), dtype=np.int8)), SMALL)
    start = (0.25, 0.25)
    goals = [(0.25 + 0.1 * i, 2.55) for i in range(30)]

    def fields() -> int:
        return sum(1 for k in planner._TOGO if k[0] == cm.key)

    def plan(goal):
        res = plan_path(cm, start, goal, PCFG)
        assert res.reason == "", res.reason
        return res

    first = plan(goals[0])
    try:
        planner.share_cost_to_go(1)  # a process of one navigator: the minimum
        for g in goals:
            plan(g)
        assert fields() == 16
        planner.share_cost_to_go(24)
        for g in goals:
            plan(g)
        assert fields() == 24
        planner.share_cost_to_go(20)  # shrinking drops the least recently used at once
        assert fields() == 20
        kept = set(planner._TOGO)
        again = plan(goals[0])  # searched again: it had gone, the oldest of the 30
        assert set(planner._TOGO) != kept and fields() == 20
        assert again.cost == first.cost and np.array_equal(again.path, first.path)
        kept = set(planner._TOGO)
        plan(goals[-1])  # the newest: kept, no search
        assert set(planner._TOGO) == kept
    finally:
        planner.share_cost_to_go(1)
    assert fields() <= 16
