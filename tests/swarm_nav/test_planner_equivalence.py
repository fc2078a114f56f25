"""The compiled line-of-sight shortcuts (swarm_nav.planner_kernels) give exactly the paths of the
numpy implementation they replaced.

The reference below is ``swarm_nav.planner.shortcut_path`` and ``swarm_nav.costmap.
segment_profile`` before they were compiled (commit 005dbd3).  The new code must keep exactly the
same points (``==``) on random cell paths over random costmaps (with unknown cells allowed and
not, a start escaping the inscribed zone, exact starts and goals off the cell centres) and on
cross-map plans of slim_blockage.  The compiled Dijkstra of a replan around robots must give
scipy's distances and predecessors to the last bit.
"""

import math

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra as scipy_dijkstra

from swarm_nav import costmap_kernels, planner, planner_kernels
from swarm_nav.config import CostmapConfig, PlannerConfig
from swarm_nav.costmap import INSCRIBED, UNKNOWN, build_costmap, overlay_obstacles, segment_profile
from swarm_nav.planner import cell_path, plan_path, shortcut_path
from tests.swarm_nav.helpers import random_grid, slim_blockage_map

_UNKNOWN_AS = 126


def ref_segment_profile(costmap, a, b):
    a = np.asarray(a, dtype=float)[:2]
    b = np.asarray(b, dtype=float)[:2]
    d = b - a
    res = costmap.resolution
    ts = [np.array([0.0, 1.0])]
    for k in (0, 1):
        if abs(d[k]) > 1e-12:
            lo, hi = sorted(((a[k] - costmap.origin[k]) / res, (b[k] - costmap.origin[k]) / res))
            lines = np.arange(math.floor(lo) + 1, math.ceil(hi))
            ts.append((costmap.origin[k] + lines * res - a[k]) / d[k])
    t = np.unique(np.concatenate(ts))
    if len(t) < 2:
        return np.zeros(1), costmap.cost_at(a[None, :])
    mids = 0.5 * (t[:-1] + t[1:])
    return np.diff(t) * float(np.hypot(*d)), costmap.cost_at(a + mids[:, None] * d)


def ref_shortcut_path(costmap, pts, cfg, keep_first=False):
    n = len(pts)
    if n <= 2:
        return pts.copy()

    def profile(a, b, strict=True):
        lengths, costs = ref_segment_profile(costmap, a, b)
        c = costs.astype(float)
        unknown = costs == UNKNOWN
        blocked = (costs >= INSCRIBED) & ~unknown
        if unknown.any():
            c[unknown] = _UNKNOWN_AS
            blocked |= unknown & (not cfg.allow_unknown)
        if blocked.any():
            if strict:
                return math.inf, int(costs.max())
            c = np.minimum(c, INSCRIBED - 1)
        return float(lengths @ (1.0 + cfg.cost_penalty * c / (INSCRIBED - 1))), int(c.max())

    cell_cost = costmap.cost_at(pts).astype(int)
    if cfg.allow_unknown:
        cell_cost = np.where(cell_cost == UNKNOWN, _UNKNOWN_AS, cell_cost)
    mult = 1.0 + cfg.cost_penalty * np.minimum(cell_cost, INSCRIBED - 1) / (INSCRIBED - 1)
    seg = np.hypot(*np.diff(pts, axis=0).T) * 0.5 * (mult[:-1] + mult[1:])
    for k in {0, 1, n - 2}:
        seg[k] = profile(pts[k], pts[k + 1], strict=False)[0]
    cum = np.concatenate(([0.0], np.cumsum(seg)))

    def better(a, b):
        weighted, worst = profile(pts[a], pts[b])
        limit = max(cfg.shortcut_max_cost, int(cell_cost[a:b + 1].max()))
        return worst <= limit and weighted <= cum[b] - cum[a] + 1e-9

    out = [pts[0]]
    i = 0
    if keep_first:
        out.append(pts[1])
        i = 1
    while i < n - 1:
        good, step, bad = i + 1, 1, None
        while good < n - 1:
            j = min(good + step, n - 1)
            if not better(i, j):
                bad = j
                break
            good, step = j, step * 2
        if bad is not None:
            while bad - good > 1:
                mid = (good + bad) // 2
                if better(i, mid):
                    good = mid
                else:
                    bad = mid
        out.append(pts[good])
        i = good
    return np.asarray(out)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("allow_unknown", [False, True])
def test_compiled_shortcuts_equal_the_numpy_ones(seed, allow_unknown):
    rng = np.random.default_rng(400 + seed)
    checked = 0
    for _ in range(12):
        occ = random_grid(rng, 40, 50, 0.04)
        data = occ.data.copy()
        data[rng.random(data.shape) < 0.02] = -1  # a few unknown cells
        occ = type(occ)(data, occ.resolution, occ.origin)
        cm = build_costmap(occ, CostmapConfig(robot_radius=0.1, inflation_radius=0.4))
        cfg = PlannerConfig(allow_unknown=allow_unknown,
                            cost_penalty=float(rng.choice([0.0, 1.5, 3.0])),
                            shortcut_max_cost=int(rng.choice([0, 64, 128, 252])))
        ok = cm.traversable(allow_unknown)
        free = np.argwhere(ok)
        for _ in range(6):
            s, g = free[rng.integers(len(free), size=2)]
            cells, cost = cell_path(cm, tuple(s), tuple(g), cfg)
            if len(cells) < 3:
                continue
            pts = cm.cell_to_world(np.asarray(cells)).reshape(-1, 2)
            pts[0] += rng.uniform(-0.05, 0.05, 2)  # exact start and goal off the centres
            pts[-1] += rng.uniform(-0.05, 0.05, 2)
            keep_first = bool(rng.integers(2))
            got = shortcut_path(cm, pts, cfg, keep_first=keep_first)
            ref = ref_shortcut_path(cm, pts, cfg, keep_first=keep_first)
            assert np.array_equal(got, ref)
            checked += 1
    assert checked >= 20


def test_compiled_segment_profile_equals_the_numpy_one():
    """Lengths and costs of random segments, on and off the map, axis-parallel and points."""
    rng = np.random.default_rng(7)
    cm = build_costmap(random_grid(rng, 30, 30, 0.1), CostmapConfig())
    for _ in range(300):
        a, b = rng.uniform(-0.5, 3.5, size=(2, 2))  # also off the map
        if rng.random() < 0.2:
            b[int(rng.integers(2))] = a[int(rng.integers(2))]  # axis-parallel, or a point
        lengths, costs = costmap_kernels.segment_profile(
            cm.costs, cm.resolution, float(cm.origin[0]), float(cm.origin[1]), *a, *b)
        ref_l, ref_c = ref_segment_profile(cm, a, b)
        assert np.array_equal(lengths, ref_l) and np.array_equal(costs, ref_c)
        got_l, got_c = segment_profile(cm, a, b)  # the public wrapper
        assert np.array_equal(got_l, ref_l) and np.array_equal(got_c, ref_c)
        assert got_c.dtype == ref_c.dtype


def test_cross_map_plans_on_slim_blockage_equal_the_numpy_shortcuts():
    cm = build_costmap(slim_blockage_map(), CostmapConfig())
    cfg = PlannerConfig()
    for start, goal in [((8.5, 8.5), (-7.74575, -3.57766)), ((0.0, 0.0), (-7.74575, 5.78442)),
                        ((-7.7, 8.5), (3.0, -4.0)), ((7.0, 7.0), (-7.74575, 0.97297))]:
        res = plan_path(cm, start, goal, cfg)
        assert res.path is not None
        s_rc, g_rc = cm.world_to_cell(np.array(start)), cm.world_to_cell(np.array(goal))
        cells, _ = cell_path(cm, tuple(s_rc), tuple(g_rc), cfg)
        pts = cm.cell_to_world(np.asarray(cells)).reshape(-1, 2)
        pts[0], pts[-1] = start, goal
        assert np.array_equal(shortcut_path(cm, pts, cfg), ref_shortcut_path(cm, pts, cfg))


# The overlay replan's search (planner_kernels.dijkstra) against scipy.sparse.csgraph.dijkstra,
# whose result it must give to the last bit: every distance and predecessor of a whole search,
# with and without a limit, and the start's path and cost when it stops at the start.

def _random_scene(seed):
    """A random costmap's search graph, an overlay's (its forbidden moves infinite), the graph's
    slot index of every (cell, move), the free cells and the generator that drew them."""
    rng = np.random.default_rng(seed)
    base = build_costmap(random_grid(rng, 40, 55, 0.1), CostmapConfig(
        robot_radius=0.1, inflation_radius=0.35, cost_scaling_factor=3.0))
    cfg = PlannerConfig(cost_penalty=float(rng.choice([0.0, 3.0])))
    graph, slots, _ = planner._shared_graph(base, cfg)
    extent = np.array([base.width, base.height]) * base.resolution
    overlay = overlay_obstacles(base, rng.uniform(0.0, 1.0, (4, 2)) * extent, CostmapConfig(
        robot_radius=0.1, inflation_radius=0.35, cost_scaling_factor=3.0))
    with planner._search_graph(overlay, cfg) as patched:
        patched = patched.copy()
    free = np.flatnonzero(base.costs.ravel() < INSCRIBED)
    return rng, free, graph, patched, slots, base.width


def _random_graphs(seed):
    """:func:`_random_scene`'s generator, free cells and (graph, overlay's graph)."""
    rng, free, graph, patched, _, _ = _random_scene(seed)
    return rng, free, (graph, patched)


def _walk(pred, s, t):
    cells = [s]
    while cells[-1] != t:
        cells.append(int(pred[cells[-1]]))
    return cells


@pytest.mark.parametrize("seed", range(6))
def test_compiled_dijkstra_equals_scipys_to_the_last_bit(seed):
    rng, free, graphs = _random_graphs(seed)
    for graph in graphs:
        for limit in (np.inf, float(rng.uniform(0.5, 3.0))):
            t = int(rng.choice(free))
            want_d, want_p = scipy_dijkstra(graph, directed=True, indices=t,
                                            return_predecessors=True, limit=limit)
            got_d, got_p = planner_kernels.dijkstra(graph.data, graph.indices, graph.indptr, t,
                                                    -1, limit)
            np.testing.assert_array_equal(got_d, want_d)
            np.testing.assert_array_equal(got_p, want_p)
            assert got_p.dtype == want_p.dtype


@pytest.mark.parametrize("seed", range(6))
def test_compiled_dijkstra_stopped_at_the_start_has_its_whole_search_path(seed):
    rng, free, graphs = _random_graphs(seed)
    for graph in graphs:
        t = int(rng.choice(free))
        want_d, want_p = scipy_dijkstra(graph, directed=True, indices=t,
                                        return_predecessors=True)
        reached = free[np.isfinite(want_d[free])]
        for s in rng.choice(reached, 20):
            got_d, got_p = planner_kernels.dijkstra(graph.data, graph.indices, graph.indptr, t,
                                                    int(s), np.inf)
            assert got_d[s] == want_d[s]
            assert _walk(got_p, int(s), t) == _walk(want_p, int(s), t)
        unreached = free[~np.isfinite(want_d[free])]
        if len(unreached):
            got_d, _ = planner_kernels.dijkstra(graph.data, graph.indices, graph.indptr, t,
                                                int(unreached[0]), np.inf)
            assert got_d[unreached[0]] == np.inf


@pytest.mark.parametrize("seed", range(6))
def test_cost_to_go_settled_in_steps_is_scipys_whole_search_where_settled(seed):
    """planner.CostToGo (planner_kernels.settle, the static cost-to-go kept between plans):
    asked for starts and bounds in any order, every cell below its radius has scipy's whole-map
    distance and predecessor, every start asked for is settled, and settled to the end it is
    scipy's whole result."""
    rng, free, graphs = _random_graphs(seed)
    for graph in graphs:
        t = int(rng.choice(free))
        want_d, want_p = scipy_dijkstra(graph, directed=True, indices=t,
                                        return_predecessors=True)
        field = planner.CostToGo(graph, t)
        radii = []
        for _ in range(12):
            if rng.uniform() < 0.7:
                s = int(rng.choice(free))
                field.reach(s)
                assert field.dist[s] == want_d[s]
                if np.isfinite(want_d[s]):
                    assert _walk(field.pred, s, t) == _walk(want_p, s, t)
            else:
                field.reach(bound=float(rng.uniform(0.0, 3.0)))
            radii.append(field.radius)
            settled = field.dist < field.radius
            assert settled.sum() > 0
            np.testing.assert_array_equal(field.dist[settled], want_d[settled])
            np.testing.assert_array_equal(field.pred[settled], want_p[settled])
        assert radii == sorted(radii)  # a field only grows
        field.reach(bound=np.inf)
        assert field.radius == np.inf
        np.testing.assert_array_equal(field.dist, want_d)
        np.testing.assert_array_equal(field.pred, want_p)


@pytest.mark.parametrize("bound", [None, 1.0, 1.2, 2.0])
@pytest.mark.parametrize("seed", range(8))
def test_repaired_search_gives_the_whole_search_path_of_every_start(seed, bound):
    """repair_dijkstra (the base's search, re-searched where the overlay's rises change it) gives
    every start the distance and path of scipy's whole search on the overlay, to the last bit,
    without a bound and with bounds the start's new cost often exceeds (searched again)."""
    rng, free, (graph, patched) = _random_graphs(seed)
    changed = np.flatnonzero(patched.data != graph.data)
    assert len(changed), "the overlay must raise some weights"
    rows = np.searchsorted(graph.indptr, changed, "right") - 1
    repaired = 0
    for t in rng.choice(free, 4):
        t = int(t)
        base_d, base_p = scipy_dijkstra(graph, directed=True, indices=t,
                                        return_predecessors=True)
        want_d, want_p = scipy_dijkstra(patched, directed=True, indices=t,
                                        return_predecessors=True)
        for s in free[np.isfinite(base_d[free])]:
            s = int(s)
            got_d, got_p = planner_kernels.repair_dijkstra(
                patched.data, graph.data, patched.indices, patched.indptr, base_d, base_p,
                changed, rows, t, s, np.inf if bound is None else bound * base_d[s])
            assert got_d[s] == want_d[s]
            if np.isfinite(want_d[s]):
                assert _walk(got_p, s, t) == _walk(want_p, s, t)
            repaired += got_d is not base_d
    assert repaired > 10  # starts below a risen edge: the repair itself is tested


def test_repaired_search_takes_every_edge_index_and_a_fall_searches_it_all():
    """Edge indices that did not change are skipped; a weight that fell (no overlay does that)
    makes the repair search the whole graph rather than give a wrong answer."""
    rng, free, (graph, patched) = _random_graphs(3)
    t, s = (int(v) for v in rng.choice(free, 2))
    base_d, base_p = scipy_dijkstra(graph, directed=True, indices=t, return_predecessors=True)
    want_d, want_p = scipy_dijkstra(patched, directed=True, indices=t, return_predecessors=True)
    every = np.arange(len(graph.data))
    rows = np.searchsorted(graph.indptr, every, "right") - 1
    got_d, got_p = planner_kernels.repair_dijkstra(
        patched.data, graph.data, patched.indices, patched.indptr, base_d, base_p, every, rows,
        t, s)
    assert got_d[s] == want_d[s]
    fell = graph.data.copy()
    k = int(np.flatnonzero(np.isfinite(fell))[0])
    fell[k] *= 0.5
    lower = csr_matrix((fell, graph.indices, graph.indptr), shape=graph.shape)
    want_d, want_p = scipy_dijkstra(lower, directed=True, indices=t, return_predecessors=True)
    got_d, got_p = planner_kernels.repair_dijkstra(
        fell, graph.data, graph.indices, graph.indptr, base_d, base_p, every, rows, t, s)
    assert got_d[s] == want_d[s]
    if np.isfinite(want_d[s]):
        assert _walk(got_p, s, t) == _walk(want_p, s, t)


def ref_patch(costmap, cfg):
    """planner._patch as numpy code (the compiled loop's definition): the changed window's
    moves as _edge_costs gives them, those whose cost differs from the base graph's."""
    base, slots, _ = planner._shared_graph(costmap.base, cfg)
    h, w = costmap.height, costmap.width
    r0, r1, c0, c1 = costmap.changed
    r0, r1, c0, c1 = max(r0 - 1, 0), min(r1 + 1, h), max(c0 - 1, 0), min(c1 + 1, w)
    pad = np.zeros((r1 - r0 + 2, c1 - c0 + 2))
    pr0, pc0 = r0 - 1, c0 - 1
    rs, cs = max(pr0, 0), max(pc0, 0)
    re, ce = min(r1 + 1, h), min(c1 + 1, w)
    pad[rs - pr0:re - pr0, cs - pc0:ce - pc0] = planner.step_multipliers(
        costmap.costs[rs:re, cs:ce], cfg)
    cost = planner._edge_costs(pad, costmap.resolution).reshape(-1)
    rows = (np.arange(r0, r1)[:, None] * w + np.arange(c0, c1)[None, :]).ravel()
    at = slots[rows].ravel()
    have = at >= 0
    at, cost, rows = at[have], cost[have], np.repeat(rows, 8)[have]
    risen = cost != base.data[at]
    return at[risen], cost[risen], rows[risen]


@pytest.mark.parametrize("seed", range(6))
def test_compiled_patch_equals_the_numpy_one(seed):
    """The overlay's changed moves (planner_kernels.patch_moves) are the numpy code's, to the
    last bit, windows at the map's edge and unknown cells included."""
    rng = np.random.default_rng(300 + seed)
    cm_cfg = CostmapConfig(robot_radius=0.1, inflation_radius=0.35, cost_scaling_factor=3.0)
    base = build_costmap(random_grid(rng, 30, 44, 0.1), cm_cfg)
    cfg = PlannerConfig(cost_penalty=float(rng.choice([0.0, 3.0])),
                        allow_unknown=bool(seed % 2))
    extent = np.array([base.width, base.height]) * base.resolution
    moves = 0
    for _ in range(5):
        overlay = overlay_obstacles(base, rng.uniform(-0.1, 1.1, (rng.integers(1, 6), 2))
                                    * extent, cm_cfg)
        if overlay.changed is None:
            continue
        got = planner._patch(overlay, cfg)
        want = ref_patch(overlay, cfg)
        assert len(got) == len(want) == 3
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)
        moves += len(want[0])
    assert moves > 0


def _slim_blockage_overlays(cfg, count=12, seed=7):
    """``count`` replans around robots on slim_blockage: ``(overlay, s_rc, t_rc, s, t)``, robots
    standing on and beside a cross-map path between two free cells that the robots leave free."""
    rng = np.random.default_rng(seed)
    base = build_costmap(slim_blockage_map(), CostmapConfig())
    free = np.argwhere(base.costs == 0)
    w, made = base.width, 0
    while made < count:
        s_rc, t_rc = (tuple(int(v) for v in free[i]) for i in rng.choice(len(free), 2))
        cells, _ = cell_path(base, s_rc, t_rc, cfg)
        if len(cells) < 40:
            continue
        on_path = base.cell_to_world(np.asarray(cells[10:-10:15]))
        robots = on_path[rng.choice(len(on_path), min(3, len(on_path)), replace=False)]
        points = (robots[:, None, :] + 0.15 * np.stack(
            (np.cos(np.linspace(0, 6.2, 12)), np.sin(np.linspace(0, 6.2, 12))), -1)).reshape(-1, 2)
        overlay = overlay_obstacles(base, points, CostmapConfig())
        if overlay.costs[s_rc] >= INSCRIBED or overlay.costs[t_rc] >= INSCRIBED:
            continue
        yield overlay, s_rc, t_rc, s_rc[0] * w + s_rc[1], t_rc[0] * w + t_rc[1]
        made += 1


def test_replans_around_robots_on_slim_blockage_keep_the_whole_map_search_paths():
    """cell_path on overlays (robots standing on and beside cross-map paths) gives the path that
    scipy's whole-map search from the goal gives (the definition the navigator was built on)."""
    cfg = PlannerConfig(overlay_astar=False)  # the repair (the default searches by A*)
    for overlay, s_rc, t_rc, s, t in _slim_blockage_overlays(cfg):
        w = overlay.width
        with planner._search_graph(overlay, cfg) as graph:
            want_d, want_p = scipy_dijkstra(graph, directed=True, indices=t,
                                            return_predecessors=True)
        got_cells, got_cost = cell_path(overlay, s_rc, t_rc, cfg)
        if np.isfinite(want_d[s]):
            assert got_cost == want_d[s]
            assert [r * w + c for r, c in got_cells] == _walk(want_p, s, t)
        else:
            assert got_cells == [] and got_cost == math.inf


# planner.overlay_astar: A* guided by the base's cost-to-go gives a cheapest path on the overlay
# (the cost of scipy's whole search, up to the order of the additions), over moves the overlay
# allows, and no path exactly where the whole search has none.

def _path_cost(graph, cells) -> float:
    """The summed move costs of a cell path on a reversed graph (entry (v, u): move u -> v)."""
    total = 0.0
    for u, v in zip(cells[:-1], cells[1:], strict=True):
        row = slice(graph.indptr[v], graph.indptr[v + 1])
        hit = np.flatnonzero(graph.indices[row] == u)
        assert len(hit) == 1, f"{u} -> {v} is no move of the graph"
        total += graph.data[row][hit[0]]
    return total


@pytest.mark.parametrize("seed", range(8))
def test_astar_on_an_overlay_finds_a_cheapest_path(seed):
    rng, free, graph, patched, slots, width = _random_scene(seed)
    found = 0
    for t in rng.choice(free, 4):
        t = int(t)
        base_d = scipy_dijkstra(graph, directed=True, indices=t)
        want_d = scipy_dijkstra(patched, directed=True, indices=t)
        for s in rng.choice(free[np.isfinite(base_d[free])], 25):
            s = int(s)
            cells, cost = planner_kernels.astar(patched.data, slots, planner._OPPOSITE,
                                                planner._MOVE_ARRAY, width, base_d, s, t)
            if not np.isfinite(want_d[s]):
                assert len(cells) == 0 and cost == math.inf
                continue
            assert cells[0] == s and cells[-1] == t
            assert cost == pytest.approx(want_d[s], rel=1e-12, abs=1e-12)
            assert _path_cost(patched, list(cells)) == pytest.approx(cost, rel=1e-12)
            found += 1
    assert found > 20


@pytest.mark.parametrize("first_bound", [(1.5, 2.0), (1.0, 0.0)])
@pytest.mark.parametrize("shared", [False, True])
@pytest.mark.parametrize("seed", range(8))
def test_astar_on_a_field_settled_as_needed_equals_astar_on_the_whole_field(
        seed, shared, first_bound, monkeypatch):
    """planner.astar_on_field (the overlay's A* guided by a static cost-to-go settled only as far
    as it needs) returns the cells and cost, to the last bit, of the A* guided by scipy's whole
    search, on a field fresh for each start or shared by the starts in turn; with the first
    bound at the start's own cost-to-go, some searches outrun it and search again."""
    rng, free, graph, patched, slots, width = _random_scene(seed)
    monkeypatch.setattr(planner, "_ASTAR_BOUND", first_bound)
    searches = []
    astar = planner_kernels.astar
    monkeypatch.setattr(planner_kernels, "astar",
                        lambda *args: searches.append(1) or astar(*args))
    retried = 0
    for t in rng.choice(free, 4):
        t = int(t)
        base_d = scipy_dijkstra(graph, directed=True, indices=t)
        field = planner.CostToGo(graph, t)
        for s in rng.choice(free, 25):
            s = int(s)
            want_cells, want_cost = planner_kernels.astar(
                patched.data, slots, planner._OPPOSITE, planner._MOVE_ARRAY, width, base_d, s, t)
            if not shared:
                field = planner.CostToGo(graph, t)
            searches.clear()
            got_cells, got_cost = planner.astar_on_field(patched.data, slots, width, field, s, t)
            np.testing.assert_array_equal(got_cells, want_cells)
            assert got_cost == want_cost
            assert len(searches) <= 2
            retried += len(searches) == 2
    if first_bound == (1.0, 0.0) and not shared:
        assert retried > 0


def test_replans_with_overlay_astar_on_slim_blockage_are_cheapest_paths():
    """cell_path with ``overlay_astar`` on overlays of slim_blockage (robots on cross-map paths):
    the cost of the whole-map search's path, by a path of the overlay's moves (on these long
    paths across the open hall, another of the many of equal cost)."""
    cfg = PlannerConfig(overlay_astar=True)
    for overlay, s_rc, t_rc, s, t in _slim_blockage_overlays(cfg):
        w = overlay.width
        with planner._search_graph(overlay, cfg) as graph:
            graph = graph.copy()
        want_d = scipy_dijkstra(graph, directed=True, indices=t)
        got_cells, got_cost = cell_path(overlay, s_rc, t_rc, cfg)
        if np.isfinite(want_d[s]):
            flat = [r * w + c for r, c in got_cells]
            assert got_cost == pytest.approx(want_d[s], rel=1e-12)
            assert _path_cost(graph, flat) == pytest.approx(got_cost, rel=1e-12)
        else:
            assert got_cells == [] and got_cost == math.inf
