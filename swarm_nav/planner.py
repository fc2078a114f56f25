"""The global planner: cost-aware 8-connected grid search, then shortcut and resample.

Step cost (in metres of weighted length) of a move into cell ``c``::

    length * (1 + cost_penalty * cost(c) / 252)

(``length`` = 1 or sqrt(2) cells times the resolution), so paths keep away from walls through the
inflation gradient, like nav2's NavFn (neutral cost 50 + 0.8 * cost) and Smac 2D
(``cost_penalty``).
Cells of cost 253 (inscribed) and 254 (lethal) are impassable; unknown cells (255) too unless
``allow_unknown``, in which case they cost as much as a cell of cost 126.  Diagonal moves never cut
between two cells (both orthogonal neighbours must be traversable).

The search is Dijkstra from the goal (compiled, :func:`swarm_nav.planner_kernels.settle`: scipy's
``csgraph.dijkstra`` to the last bit), which returns the optimal path (the cost an A* with an
admissible heuristic would find): the detour around a blockage defeats the octile heuristic,
and the cost-to-go is reused by replans to the same goal (measured:
docs/design/navigator.md#replanning).  It is kept between plans and goes only as far as the
starts asked about so far (:class:`CostToGo`). A replan around the robots seen (an overlay,
searched once) is an A* from the start guided by the static search to the same goal
(``overlay_astar``, the default), or starts from that search and searches again, compiled, only
the cells whose path to the goal used a move the overlay made dearer, until the start is settled
(:func:`swarm_nav.planner_kernels.repair_dijkstra`, scipy's whole-map result to the last bit).
Reachability is decided before any search from the 4-connected components of the traversable
cells (the connectivity of moves that cut no corner), so an unreachable goal (a closed pocket)
fails in about a millisecond with ``"no path"``.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix

from swarm_common.geometry import Path2D
from swarm_nav import planner_kernels as kernels
from swarm_nav.config import PlannerConfig
from swarm_nav.costmap import INSCRIBED, LETHAL, UNKNOWN, Costmap

_UNKNOWN_AS = kernels.UNKNOWN_AS
_MOVES = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))
_MOVE_ARRAY = np.array(_MOVES, dtype=np.int64)


@dataclass(frozen=True)
class PlanResult:
    """What :func:`plan_path` found.

    Attributes:
        path: (N, 2) x, y [m] in ``map`` from the start to the goal (or to the free cell that
            replaced a blocked goal), points ``path_resolution`` apart; ``None`` on failure.
        cost: weighted length [m] of the optimal cell path (``inf`` on failure).
        reason: ``""`` on success, else one of ``"goal outside map"``, ``"start outside map"``,
            ``"goal in obstacle"``, ``"start in obstacle"``, ``"no path"``.
        goal_shift: distance [m] from the requested goal to the path's end (> 0 when the goal was
            in an obstacle or the inflation and the tolerance moved it).
    """

    path: Path2D | None
    cost: float
    reason: str
    goal_shift: float = 0.0


def step_multipliers(costs: np.ndarray, cfg: PlannerConfig) -> np.ndarray:
    """(H, W) float multiplier of a step's length into each cell of ``costs`` (a costmap's
    costs, or a window of them): ``1 + cost_penalty * cost / 252`` where the cell is traversable
    (``cost_penalty`` [-]; unknown counts as ``_UNKNOWN_AS`` with ``allow_unknown``), 0 where not.
    """
    unknown = costs == UNKNOWN
    c = costs.astype(float)
    c[unknown] = _UNKNOWN_AS
    mult = 1.0 + cfg.cost_penalty * c / (INSCRIBED - 1)
    ok = costs < INSCRIBED  # Costmap.traversable
    if cfg.allow_unknown:
        ok |= unknown
    mult[~ok] = 0.0
    return mult


def plan_path(costmap: Costmap, start, goal, cfg: PlannerConfig) -> PlanResult:
    """Plan a path from ``start`` to ``goal`` on the costmap.

    A start inside the inscribed zone (e.g. a robot pushed against a wall, or a robot seen in the
    scan overlaid on the costmap) first escapes to the nearest traversable cell within
    ``start_escape_radius``.  A goal in a lethal cell (inside an obstacle) is ``"goal in
    obstacle"``, as docs/reference/contract.md#s5-navigation wants; a goal in the inflation
    (inscribed or unknown, not lethal) is replaced by the nearest reachable traversable cell
    within ``tolerance``, as NavFn does, and is ``"goal in obstacle"`` when there is none; a goal
    in a free cell that is not reachable is ``"no path"``, never moved across a wall.

    Args:
        costmap: the costmap (usually :func:`~swarm_nav.costmap.build_costmap`'s).
        start: (2,) x, y [m] or a (3,) Pose2D in ``map``.
        goal: (2,) x, y [m] (or (3,), yaw ignored) in ``map``.
        cfg: the planner settings.

    Returns:
        A :class:`PlanResult`; its ``reason`` says why when ``path`` is ``None``.
    """
    start_xy = np.asarray(start, dtype=float).ravel()[:2]
    goal_xy = np.asarray(goal, dtype=float).ravel()[:2]
    if start_xy.shape != (2,) or goal_xy.shape != (2,):
        raise ValueError("plan_path: start and goal need x and y")
    s_rc = costmap.world_to_cell(start_xy)
    g_rc = costmap.world_to_cell(goal_xy)
    if not costmap.in_bounds(g_rc):
        return _fail("goal outside map")
    if not costmap.in_bounds(s_rc):
        return _fail("start outside map")
    ok = costmap.traversable(cfg.allow_unknown)
    labels = costmap.components(cfg.allow_unknown)

    escaped = not ok[s_rc[0], s_rc[1]]
    if escaped:
        s_rc = _nearest_cell(costmap, ok, start_xy, cfg.start_escape_radius, None)
    if costmap.costs[g_rc[0], g_rc[1]] == LETHAL:
        return _fail("goal in obstacle")
    goal_free = bool(ok[g_rc[0], g_rc[1]])
    if goal_free:
        t_rc = g_rc
    else:
        t_rc = _nearest_cell(costmap, ok, goal_xy, cfg.tolerance, None)
        if t_rc is None:
            return _fail("goal in obstacle")
    if s_rc is None:
        return _fail("start in obstacle")
    comp = labels[s_rc[0], s_rc[1]]
    if labels[t_rc[0], t_rc[1]] != comp:
        if goal_free:
            return _fail("no path")
        t_rc = _nearest_cell(costmap, ok, goal_xy, cfg.tolerance, labels == comp)
        if t_rc is None:
            return _fail("no path")

    cells, cost = cell_path(costmap, (int(s_rc[0]), int(s_rc[1])),
                            (int(t_rc[0]), int(t_rc[1])), cfg)
    pts = costmap.cell_to_world(np.asarray(cells)).reshape(-1, 2)
    if goal_free:
        pts[-1] = goal_xy
    if escaped:
        pts = np.vstack((start_xy, pts))
    else:
        pts[0] = start_xy
    path = resample_path(shortcut_path(costmap, pts, cfg, keep_first=escaped),
                         cfg.path_resolution)
    shift = float(np.hypot(*(path[-1] - goal_xy)))
    return PlanResult(path, float(cost), "", shift)


def cell_path(costmap: Costmap, start_rc: tuple[int, int], goal_rc: tuple[int, int],
              cfg: PlannerConfig) -> tuple[list[tuple[int, int]], float]:
    """The cheapest 8-connected cell path between two traversable cells.

    Dijkstra from the goal over the reversed cell graph gives the cells' cost-to-go up to the
    start (:class:`CostToGo`); the path follows the predecessors from the start.  The graph is
    built once per costmap and the cost-to-go searched once per goal cell, both shared by all the
    robots of a process that use the same map, so a replan to the same goal from no farther away
    (the robot left its path) only walks the predecessors.  On an overlay of a shareable
    costmap (a replan around robots seen, used once) the base's cost-to-go is repaired where the
    overlay's rises change it, and the repair stops once it has settled the start
    (:func:`swarm_nav.planner_kernels.repair_dijkstra`): the start's path is the same, to the
    last bit, as the whole-map search's on the overlay. With ``cfg.overlay_astar`` an overlay
    is searched by A* from the start instead, guided by the base's cost-to-go
    (:func:`_overlay_astar`): a path of the same cost, not always the same path among those of
    equal cost.

    Args:
        costmap: the costmap.
        start_rc, goal_rc: ``(row, col)`` of the start cell and of the goal cell.
        cfg: ``cost_penalty``, ``allow_unknown`` and ``overlay_astar``.

    Returns:
        The cells ``(row, col)`` from start to goal, and the path's weighted length [m];
        ``([], inf)`` when the goal cannot be reached.
    """
    w = costmap.width
    s = int(start_rc[0]) * w + int(start_rc[1])
    t = int(goal_rc[0]) * w + int(goal_rc[1])
    if cfg.overlay_astar:
        found = _overlay_astar(costmap, s, t, cfg)
        if found is not None:
            cells, cost = found
            return [(int(c) // w, int(c) % w) for c in cells], cost
    togo, nxt = _overlay_cost_to_go(costmap, s, t, cfg)
    if togo is None:
        field = _cost_to_go(costmap, t, cfg).reach(s)
        togo, nxt = field.dist, field.pred
    if not np.isfinite(togo[s]):
        return [], math.inf
    cells = [s]
    while cells[-1] != t:
        cells.append(int(nxt[cells[-1]]))
    return [(c // w, c % w) for c in cells], float(togo[s])


# Process-wide caches of what shareable costmaps derive (robots of one process share a map):
# key -> search graph (with the slot index of every move, and a scratch copy that an overlay's
# search patches and restores), and (key, goal cell) -> cost-to-go (sizes:
# docs/design/navigator.md#replanning).
_GRAPHS: OrderedDict = OrderedDict()
_TOGO: OrderedDict = OrderedDict()
_GRAPHS_MAX = 2
# A replan's repair searches again the cells of static cost-to-go up to 1.5 x the start's + 2 m
# (and all of them when the start's new cost lies beyond; why these bounds:
# docs/design/navigator.md#replanning).
_REPAIR_BOUND = (1.5, 2.0)
_TOGO_MIN = 16
# An overlay's A* first settles the static cost-to-go up to 1.5 x the start's + 2 m: enough for
# the detours around robots seen, most of the time (a longer one searches once more).
_ASTAR_BOUND = (1.5, 2.0)
_togo_max = _TOGO_MIN


def share_cost_to_go(robots: int) -> None:
    """Size this process's cache of static cost-to-go fields for ``robots`` navigators sharing
    it: one field per robot, at least 16.

    A field is a whole-map search from a goal cell, asked for by every plan and replan toward
    that goal. The targets are the workstations, their holding spots and each robot's own
    staging points and retreat places, so fewer fields than robots let the staging points push the
    workstations' fields out (measured: docs/design/navigator.md#replanning). The fields are the
    same either way; only when they are searched changes.

    Args:
        robots: the navigators this process runs (>= 1).
    """
    global _togo_max
    _togo_max = max(_TOGO_MIN, int(robots))
    while len(_TOGO) > _togo_max:
        _TOGO.popitem(last=False)


def lru(cache: OrderedDict, key, make, size: int):
    """``cache[key]``, made by ``make()`` on a miss; the least recently used entry goes once
    ``cache`` holds more than ``size`` (the process-wide caches of planner and navigator)."""
    if key in cache:
        cache.move_to_end(key)
        return cache[key]
    value = make()
    cache[key] = value
    while len(cache) > size:
        cache.popitem(last=False)
    return value


def _overlay_cost_to_go(costmap: Costmap, s: int, t: int, cfg: PlannerConfig
                        ) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
    """An overlay's cost-to-go to ``t``, searched only until the start ``s`` is settled.

    Returns ``(None, None)`` when the costmap is no overlay of a shareable one; the base's
    cost-to-go when ``s`` cannot reach ``t`` on the base (nor, then, on the overlay, which only
    raises costs).  Otherwise the distances and next cells are scipy's whole-map search's for
    ``s`` and every cell on its path, not for the cells settled after ``s``: the result is cached
    per start.  The base's search is repaired below the moves the overlay's patch made dearer
    (:func:`swarm_nav.planner_kernels.repair_dijkstra`, bounded by :data:`_REPAIR_BOUND`, a
    third of the time of the search from the goal stopped at the start); an overlay
    without a patch is searched whole (:func:`swarm_nav.planner_kernels.dijkstra`, stopped at
    the start).
    """
    base = costmap.base
    if costmap.shareable or base is None or not base.shareable:
        return None, None
    field = _cost_to_go(base, t, cfg).reach(s)
    static = field.dist, field.pred
    if not math.isfinite(float(static[0][s])):
        return static
    key = ("togo-to", s, t, cfg.cost_penalty, cfg.allow_unknown)
    if key not in costmap._cache:
        with _search_graph(costmap, cfg) as graph:
            patch = costmap._cache.get(_patch_key(cfg))
            if patch is None:  # no patched copy of the base's graph: search it all
                costmap._cache[key] = kernels.dijkstra(graph.data, graph.indices, graph.indptr,
                                                       t, s, math.inf)
            else:
                field.reach(bound=math.inf)  # the repair reads the whole base search
                costmap._cache[key] = kernels.repair_dijkstra(
                    graph.data, _shared_graph(base, cfg)[0].data, graph.indices, graph.indptr,
                    static[0], static[1], patch[0], patch[2], t, s,
                    _REPAIR_BOUND[0] * float(static[0][s]) + _REPAIR_BOUND[1])
    return costmap._cache[key]


_OPPOSITE = np.array([_MOVES.index((-dr, -dc)) for dr, dc in _MOVES], dtype=np.int64)


def _overlay_astar(costmap: Costmap, s: int, t: int, cfg: PlannerConfig
                   ) -> tuple[np.ndarray, float] | None:
    """``planner.overlay_astar``: a cheapest cell path from ``s`` to ``t`` on an overlay, by A*
    guided by its base's cost-to-go to ``t`` (:func:`swarm_nav.planner_kernels.astar`; the
    base's cost-to-go never exceeds the overlay's, which only raises costs).

    Returns None when the costmap is no overlay of a shareable one (then the planner searches
    as without the option); else ``(cells, cost)``, ``(empty, inf)`` when ``t`` cannot be
    reached (cached per start, like :func:`_overlay_cost_to_go`).
    """
    base = costmap.base
    if costmap.shareable or base is None or not base.shareable or costmap.changed is None:
        return None
    key = ("astar-to", s, t, cfg.cost_penalty, cfg.allow_unknown)
    if key not in costmap._cache:
        field = _cost_to_go(base, t, cfg)
        slots = _shared_graph(base, cfg)[1]
        with _search_graph(costmap, cfg) as graph:
            costmap._cache[key] = astar_on_field(graph.data, slots, costmap.width, field, s, t)
    cells, cost = costmap._cache[key]
    return cells, float(cost)


def astar_on_field(data: np.ndarray, slots: np.ndarray, width: int, field: CostToGo, s: int,
                   t: int) -> tuple[np.ndarray, float]:
    """:func:`swarm_nav.planner_kernels.astar` from ``s`` to ``t`` guided by a static cost-to-go
    to ``t`` settled only as far as needed: the same path and cost as with the whole field.

    The field is first settled up to ``_ASTAR_BOUND`` of the start's cost-to-go. A search that
    returns a cost below the field's :attr:`CostToGo.radius` read only final values where it
    mattered: every entry it popped has f <= cost, and an unsettled cell's value (an upper bound
    or ``inf``) is at least the radius, so such a cell pops no earlier with its final value; the
    pops, and so the path, are those of the search on the whole field.  Otherwise the field is
    settled up to that cost (to the end when there is none) and the search runs again, once.

    Args:
        data: (E,) the overlay graph's move costs; ``slots``, ``width``: as for the kernel.
        field: the base's cost-to-go to ``t`` (settled further here).
        s, t: flat start and goal cells.

    Returns:
        ``(cells, cost)``: (K,) int64 the cells from ``s`` to ``t`` and the cost [m]; an empty
        path and ``inf`` when ``t`` cannot be reached.
    """
    field.reach(s)
    field.reach(bound=_ASTAR_BOUND[0] * float(field.dist[s]) + _ASTAR_BOUND[1])
    while True:
        cells, cost = kernels.astar(data, slots, _OPPOSITE, _MOVE_ARRAY, width, field.dist, s, t)
        if cost < field.radius or field.radius == math.inf:
            return cells, cost
        field.reach(bound=cost)


class CostToGo:
    """The static cost-to-go to one goal cell, searched only as far as it has been asked for.

    Dijkstra's search from the goal over the reversed cell graph, kept between the questions
    (:func:`swarm_nav.planner_kernels.settle`): a plan from a start settles the cells up to the
    start, a later plan from farther away goes on from there, so a goal planned to from nearby
    (a holding spot, a retreat place) costs a small disc of the map, not the whole map. The
    settled cells' values are scipy's whole-map search's to the last bit
    (``tests/swarm_nav/test_planner_equivalence.py``).

    Attributes:
        dist: (H*W,) cost-to-go [m]; final where settled, an upper bound or ``inf`` elsewhere.
        pred: (H*W,) int32 next cell toward the goal (final where settled).
    """

    __slots__ = ("dist", "pred", "_graph", "_heap", "_size")

    def __init__(self, graph: csr_matrix, t: int):
        n = graph.shape[0]
        self._graph = graph
        self.dist = np.full(n, np.inf)
        self.pred = np.full(n, kernels.NO_PREDECESSOR, dtype=np.int32)
        self.dist[t] = 0.0
        self._heap = np.empty((4096, 2))
        self._heap[0] = (0.0, t)
        self._size = 1

    @property
    def radius(self) -> float:
        """[m] every cell whose cost-to-go is below this is settled (``inf``: all are)."""
        return float(self._heap[0, 0]) if self._size else math.inf

    def reach(self, stop: int = -1, bound: float = -math.inf) -> CostToGo:
        """Settle cell ``stop`` (-1: none) and every cell within ``bound`` [m] (``inf``: all)."""
        if self._size and (bound >= self.radius or (stop >= 0 and not
                                                    self.dist[stop] < self.radius)):
            g = self._graph
            self._heap, self._size = kernels.settle(g.data, g.indices, g.indptr, self.dist,
                                                    self.pred, self._heap, self._size, stop,
                                                    bound, math.inf)
        return self


def _cost_to_go(costmap: Costmap, t: int, cfg: PlannerConfig) -> CostToGo:
    """The static cost-to-go to flat cell ``t`` (cached; settled as far as asked before)."""
    def make():
        with _search_graph(costmap, cfg) as graph:
            field = CostToGo(graph, t)
            if not costmap.shareable:  # searched whole while its graph is the one yielded
                field.reach(bound=math.inf)
            return field

    if costmap.shareable:
        key = (costmap.key, t, cfg.cost_penalty, cfg.allow_unknown)
        return lru(_TOGO, key, make, _togo_max)
    key = ("togo", t, cfg.cost_penalty, cfg.allow_unknown)
    if key not in costmap._cache:
        for k in [k for k in costmap._cache if isinstance(k, tuple) and k[0] == "togo"]:
            del costmap._cache[k]
        costmap._cache[key] = make()
    return costmap._cache[key]


@contextmanager
def _search_graph(costmap: Costmap, cfg: PlannerConfig) -> Iterator[csr_matrix]:
    """The reversed cell graph, for the duration of one search: entry (v, u) is the cost [m] of
    the move u -> v.

    Built row by row without sorting: each cell's 8 neighbour slots in a fixed order, invalid
    moves masked out (cached per costmap).  An overlay of a shareable costmap (``costmap.base``)
    is its base's graph re-costed in the rows its changed window touches: an overlay only raises
    costs, so its valid moves are a subset of the base's, and a move it forbids keeps its slot
    with an infinite cost (which Dijkstra never relaxes).  The new costs are written into a
    scratch copy of the base's graph kept for the purpose and the base's costs written back
    after the search: the same graph as a patched copy, without copying the whole graph's costs
    for every replan around robots.
    """
    if costmap.shareable:
        yield _shared_graph(costmap, cfg)[0]
        return
    if costmap.base is None or not costmap.base.shareable or costmap.changed is None:
        key = ("graph", cfg.cost_penalty, cfg.allow_unknown)
        if key not in costmap._cache:
            costmap._cache[key] = _build_graph(costmap, cfg)[0]
        yield costmap._cache[key]
        return
    base, _, scratch = _shared_graph(costmap.base, cfg)
    key = _patch_key(cfg)
    if key not in costmap._cache:
        costmap._cache[key] = _patch(costmap, cfg)
    at, cost, _ = costmap._cache[key]
    scratch.data[at] = cost
    try:
        yield scratch
    finally:
        scratch.data[at] = base.data[at]


def _patch_key(cfg: PlannerConfig) -> tuple:
    """The key of an overlay's patch (:func:`_patch`) in its ``_cache``."""
    return ("patch", cfg.cost_penalty, cfg.allow_unknown)


def _shared_graph(costmap: Costmap, cfg: PlannerConfig
                  ) -> tuple[csr_matrix, np.ndarray, csr_matrix]:
    """A shareable costmap's graph, its slot index, and a scratch copy (cached per process)."""
    def make():
        graph, slots = _build_graph(costmap, cfg)
        scratch = csr_matrix((graph.data.copy(), graph.indices, graph.indptr), shape=graph.shape,
                             copy=False)
        return graph, slots, scratch

    key = (costmap.key, cfg.cost_penalty, cfg.allow_unknown)
    return lru(_GRAPHS, key, make, _GRAPHS_MAX)


def _edge_costs(mult_pad: np.ndarray, resolution: float) -> np.ndarray:
    """(h, w, 8) cost [m] of the move from each neighbour (slot k: ``_MOVES[k]``) into each cell
    of the padded multipliers' interior; ``inf`` where the move is invalid.

    Args:
        mult_pad: (h + 2, w + 2) step multipliers (0 = impassable) with a one-cell margin.
        resolution: [m/cell].
    """
    h, w = mult_pad.shape[0] - 2, mult_pad.shape[1] - 2
    mult = mult_pad[1:-1, 1:-1]
    here = mult > 0.0
    cost = np.empty((h, w, 8))
    for k, (dr, dc) in enumerate(_MOVES):
        there = mult_pad[1 + dr:h + 1 + dr, 1 + dc:w + 1 + dc] > 0.0
        if dr and dc:
            there = there & (mult_pad[1 + dr:h + 1 + dr, 1:w + 1] > 0.0) & (
                mult_pad[1:h + 1, 1 + dc:w + 1 + dc] > 0.0)
        cost[..., k] = np.where(here & there, math.hypot(dr, dc) * resolution * mult, np.inf)
    return cost


def _build_graph(costmap: Costmap, cfg: PlannerConfig) -> tuple[csr_matrix, np.ndarray]:
    """The reversed graph and the (H*W, 8) data index of every (cell, move slot), -1 if none."""
    h, w = costmap.height, costmap.width
    pad = np.zeros((h + 2, w + 2))
    pad[1:-1, 1:-1] = step_multipliers(costmap.costs, cfg)
    cost = _edge_costs(pad, costmap.resolution)
    valid = np.isfinite(cost)
    idx = np.arange(h * w, dtype=np.int32).reshape(h, w)
    nbr = np.empty((h, w, 8), dtype=np.int32)
    for k, (dr, dc) in enumerate(_MOVES):
        nbr[..., k] = idx + dr * w + dc
    indptr = np.concatenate(([0], np.cumsum(valid.sum(axis=2).ravel()))).astype(np.int32)
    slots = np.full(h * w * 8, -1, dtype=np.int32)
    slots[valid.ravel()] = np.arange(int(indptr[-1]), dtype=np.int32)
    graph = csr_matrix((cost[valid], nbr[valid], indptr), shape=(h * w, h * w))
    return graph, slots.reshape(h * w, 8)


def _patch(costmap: Costmap, cfg: PlannerConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An overlay's changes to its base's graph: the data indices, their new costs [m] and their
    rows (the cells moved into) of the moves into the rows around its changed window whose cost
    changed."""
    base, slots, _ = _shared_graph(costmap.base, cfg)
    h, w = costmap.height, costmap.width
    r0, r1, c0, c1 = costmap.changed
    r0, r1, c0, c1 = max(r0 - 1, 0), min(r1 + 1, h), max(c0 - 1, 0), min(c1 + 1, w)
    pad = np.zeros((r1 - r0 + 2, c1 - c0 + 2))
    pr0, pc0 = r0 - 1, c0 - 1  # the padded window's first row/column in the map (may be -1)
    rs, cs = max(pr0, 0), max(pc0, 0)
    re, ce = min(r1 + 1, h), min(c1 + 1, w)
    pad[rs - pr0:re - pr0, cs - pc0:ce - pc0] = step_multipliers(costmap.costs[rs:re, cs:ce], cfg)
    steps = np.array([math.hypot(dr, dc) * costmap.resolution for dr, dc in _MOVES])
    return kernels.patch_moves(pad, steps, _MOVE_ARRAY, r0, r1, c0, c1, w, slots, base.data)


def shortcut_path(costmap: Costmap, pts: np.ndarray, cfg: PlannerConfig,
                  keep_first: bool = False) -> Path2D:
    """Replace runs of a cell path by straight segments where that is no worse.

    A segment from point ``i`` to point ``j`` may replace the points between them if every cell
    it crosses is traversable, costs no more than ``max(shortcut_max_cost, the costliest cell
    the path went through between i and j)``, and its weighted length (the length in each cell
    times ``1 + cost_penalty * cost / 252``) is no more than the path's between ``i`` and ``j``.
    So a shortcut never goes nearer to obstacles than the optimal cell path did, beyond the
    threshold, and never cuts through costly regions (keep-out zones, inflation) that the path
    went around.

    Args:
        costmap: the costmap.
        pts: (N, 2) x, y [m]: cell centres, except possibly the first and the last point.
        cfg: ``shortcut_max_cost``, ``cost_penalty`` and ``allow_unknown``.
        keep_first: keep the first segment as it is (a start escaping from the inscribed zone).

    Returns:
        (K, 2) x, y [m], K <= N, a subsequence of ``pts`` with the same first and last point.
    """
    n = len(pts)
    if n <= 2:
        return pts.copy()
    pts = np.ascontiguousarray(pts, dtype=float)
    cell_cost = costmap.cost_at(pts).astype(np.int64)
    if cfg.allow_unknown:
        cell_cost = np.where(cell_cost == UNKNOWN, _UNKNOWN_AS, cell_cost)
    keep = kernels.shortcut_indices(
        costmap.costs, float(costmap.resolution), float(costmap.origin[0]),
        float(costmap.origin[1]), pts, cell_cost, float(cfg.cost_penalty),
        bool(cfg.allow_unknown), int(cfg.shortcut_max_cost), bool(keep_first))
    return pts[keep]


def resample_path(path: Path2D, spacing: float) -> Path2D:
    """Points along a polyline, ``spacing`` [m] apart, keeping its first and last point.

    Args:
        path: (N, 2) x, y [m].
        spacing: the distance [m] between consecutive points (the last gap may be shorter).

    Returns:
        (K, 2) x, y [m] on the polyline.
    """
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    seg = np.hypot(*np.diff(path, axis=0).T)
    keep = np.concatenate(([True], seg > 1e-9))
    path, seg = path[keep], seg[seg > 1e-9]
    if len(path) < 2:
        return path.copy()
    s = np.concatenate(([0.0], np.cumsum(seg)))
    n = max(int(np.ceil(s[-1] / spacing)), 1)
    q = np.append(np.arange(n) * spacing, s[-1])
    if q[-1] - q[-2] < 1e-6:
        q = q[:-1]
        q[-1] = s[-1]
    return np.column_stack((np.interp(q, s, path[:, 0]), np.interp(q, s, path[:, 1])))


def path_length(path: Path2D) -> float:
    """Length [m] of a (N, 2) polyline."""
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    return float(np.hypot(*np.diff(path, axis=0).T).sum()) if len(path) > 1 else 0.0


def _nearest_cell(costmap: Costmap, ok: np.ndarray, xy: np.ndarray, radius: float,
                  extra: np.ndarray | None) -> np.ndarray | None:
    """The traversable cell (masked by ``extra``) nearest ``xy`` within ``radius`` [m]."""
    res = costmap.resolution
    n = int(np.ceil(radius / res)) + 1
    rc = costmap.world_to_cell(xy)
    r0, r1 = max(rc[0] - n, 0), min(rc[0] + n + 1, costmap.height)
    c0, c1 = max(rc[1] - n, 0), min(rc[1] + n + 1, costmap.width)
    if r0 >= r1 or c0 >= c1:
        return None
    win = ok[r0:r1, c0:c1]
    if extra is not None:
        win = win & extra[r0:r1, c0:c1]
    cand = np.argwhere(win) + (r0, c0)
    if len(cand) == 0:
        return None
    d = np.hypot(*(costmap.cell_to_world(cand) - xy).T)
    best = int(np.argmin(d))
    return cand[best] if d[best] <= radius + 1e-9 else None


def _fail(reason: str) -> PlanResult:
    return PlanResult(None, math.inf, reason)
