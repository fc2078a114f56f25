"""Compiled inner loops of the global planner's line-of-sight shortcuts (:mod:`swarm_nav.planner`),
with numba.

``shortcut_path`` tests a few dozen candidate segments per plan, each cut exactly at the grid lines
it crosses (:func:`swarm_nav.costmap_kernels.segment_profile`); with numpy that was some twenty
small array operations per segment (measured: docs/design/navigator.md#compiled-kernels).  They
do the same IEEE operations in the same order (the weighted length is the
same BLAS ``dot`` numpy's ``@`` calls), so the paths are the same to the last bit
(``tests/swarm_nav/test_planner_equivalence.py``); see :mod:`swarm_nav.dwa_kernels` for the
rules.  Compiled on first use and cached beside this file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from swarm_nav.costmap import INSCRIBED, UNKNOWN
from swarm_nav.costmap_kernels import segment_profile

UNKNOWN_AS = 126  # the cost an unknown cell counts as when unknown space is allowed


@njit(cache=True, nogil=True)
def _profile(costs, res, ox, oy, ax, ay, bx, by, penalty, allow_unknown, strict):
    """Weighted length [m] and highest cost of a segment; ``inf`` if ``strict`` and it crosses a
    blocked cell (else blocked cells count as the costliest free ones)."""
    lengths, cell = segment_profile(costs, res, ox, oy, ax, ay, bx, by)
    c = cell.astype(np.float64)
    blocked = False
    raw_max = 0
    for j in range(cell.shape[0]):
        raw_max = max(raw_max, int(cell[j]))
        if cell[j] == UNKNOWN:
            c[j] = UNKNOWN_AS
            if not allow_unknown:
                blocked = True
        elif cell[j] >= INSCRIBED:
            blocked = True
    if blocked:
        if strict:
            return math.inf, raw_max
        for j in range(c.shape[0]):
            c[j] = min(c[j], INSCRIBED - 1)
    mult = np.empty(c.shape[0])
    worst = 0.0
    for j in range(c.shape[0]):
        mult[j] = 1.0 + penalty * c[j] / (INSCRIBED - 1)
        worst = max(worst, c[j])
    return np.dot(lengths, mult), int(worst)


@njit(cache=True, nogil=True)
def shortcut_indices(costs, res, ox, oy, pts, cell_cost, penalty, allow_unknown, max_cost,
                     keep_first):
    """The points kept by :func:`swarm_nav.planner.shortcut_path` (its search, compiled).

    Args:
        costs, res, ox, oy: the costmap, as :func:`swarm_nav.costmap_kernels.segment_profile`.
        pts: (N, 2) path points x, y [m], N >= 3.
        cell_cost: (N,) int64 each point's cell cost (unknown already counted as ``UNKNOWN_AS``
            when allowed).
        penalty: ``cost_penalty`` [-]; allow_unknown: whether unknown cells are traversable.
        max_cost: ``shortcut_max_cost``; keep_first: keep the first segment as it is.

    Returns:
        (K,) int64 indices into ``pts`` of the points kept, first and last included.
    """
    n = pts.shape[0]
    mult = np.empty(n)
    for i in range(n):
        mult[i] = 1.0 + penalty * min(cell_cost[i], INSCRIBED - 1) / (INSCRIBED - 1)
    seg = np.empty(n - 1)
    for i in range(n - 1):
        seg[i] = math.hypot(pts[i + 1, 0] - pts[i, 0], pts[i + 1, 1] - pts[i, 1]) * 0.5 * (
            mult[i] + mult[i + 1])
    for k in (0, 1, n - 2):  # the exact start and goal are no cell centres
        seg[k] = _profile(costs, res, ox, oy, pts[k, 0], pts[k, 1], pts[k + 1, 0],
                          pts[k + 1, 1], penalty, allow_unknown, False)[0]
    cum = np.empty(n)
    cum[0] = 0.0
    acc = 0.0
    for i in range(n - 1):
        acc += seg[i]
        cum[i + 1] = acc
    out = np.empty(n, dtype=np.int64)
    out[0] = 0
    n_out = 1
    i = 0
    if keep_first:
        out[1] = 1
        n_out = 2
        i = 1
    while i < n - 1:
        good, step, bad = i + 1, 1, -1
        while good < n - 1:
            j = min(good + step, n - 1)
            if not _better(costs, res, ox, oy, pts, cell_cost, cum, i, j, penalty,
                           allow_unknown, max_cost):
                bad = j
                break
            good, step = j, step * 2
        if bad >= 0:
            while bad - good > 1:
                mid = (good + bad) // 2
                if _better(costs, res, ox, oy, pts, cell_cost, cum, i, mid, penalty,
                           allow_unknown, max_cost):
                    good = mid
                else:
                    bad = mid
        out[n_out] = good
        n_out += 1
        i = good
    return out[:n_out]


@njit(cache=True, nogil=True)
def _better(costs, res, ox, oy, pts, cell_cost, cum, a, b, penalty, allow_unknown, max_cost):
    """Whether the straight segment from point ``a`` to point ``b`` may replace the path
    between them."""
    weighted, worst = _profile(costs, res, ox, oy, pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1],
                               penalty, allow_unknown, True)
    limit = max_cost
    for i in range(a, b + 1):
        limit = max(limit, cell_cost[i])
    return worst <= limit and weighted <= cum[b] - cum[a] + 1e-9


NO_PREDECESSOR = -9999  # scipy.sparse.csgraph's predecessor of the source and unreached cells


@njit(cache=True, nogil=True)
def _before(d1, v1, d2, v2):
    """Whether heap entry ``(d1, v1)`` pops before ``(d2, v2)``: the smaller distance first,
    between equal distances the larger vertex index (scipy's ``std::priority_queue`` of
    ``(-distance, vertex)`` pairs pops its largest pair)."""
    return d1 < d2 or (d1 == d2 and v1 > v2)


@njit(cache=True, nogil=True)
def _sift_up(heap, i, d, v):
    """Put entry ``(d, v)`` into the 4-ary heap's hole at row ``i``, moving it up past every
    parent it pops before."""
    while i > 0:
        p = (i - 1) // 4
        if not _before(d, v, heap[p, 0], heap[p, 1]):
            break
        heap[i, 0], heap[i, 1] = heap[p, 0], heap[p, 1]
        i = p
    heap[i, 0], heap[i, 1] = d, v


@njit(cache=True, nogil=True)
def _pop(heap, size):
    """Take the first entry ``(d, v)`` off the 4-ary heap of ``size`` entries (the caller then
    has ``size - 1``): the hole goes down along the earliest child, the last entry back up."""
    d, v = heap[0, 0], heap[0, 1]
    size -= 1
    i = 0
    c = 1
    while c < size:
        b = c
        for k in range(c + 1, min(c + 4, size)):
            if _before(heap[k, 0], heap[k, 1], heap[b, 0], heap[b, 1]):
                b = k
        heap[i, 0], heap[i, 1] = heap[b, 0], heap[b, 1]
        i = b
        c = 4 * i + 1
    _sift_up(heap, i, heap[size, 0], heap[size, 1])
    return d, int(v)


@njit(cache=True, nogil=True)
def _push(heap, size, d, v):
    """Put ``(d, v)`` on the heap of ``size`` entries (the caller then has ``size + 1``); returns
    the heap, grown when it was full."""
    if size == heap.shape[0]:
        heap = np.concatenate((heap, np.empty((size, 2))))
    _sift_up(heap, size, d, float(v))
    return heap


@njit(cache=True, nogil=True)
def dijkstra(data, indices, indptr, source, stop, limit):
    """``scipy.sparse.csgraph.dijkstra(graph, indices=source, return_predecessors=True,
    limit=limit)`` to the last bit, optionally stopped once vertex ``stop`` is settled.

    scipy 1.17's search (``_dijkstra`` in ``_shortest_path.pyx``) pushes ``(-distance, vertex)``
    pairs onto a C++ ``std::priority_queue`` whenever a relaxation lowers a distance, skips popped
    pairs whose distance was lowered since, and relaxes ``next = distance + weight`` only when
    ``next <= limit``.  No pair is pushed twice, so the pop order is the total order of the
    pairs, whatever the heap's inner layout, and this search, popping in the same order from its
    own 4-ary heap and doing the same additions, gives every distance and predecessor scipy's
    gives.  Stopped at ``stop``, every vertex settled before it (its path to the source among
    them) has its final distance and predecessor already: the others are not final.

    Args:
        data: (E,) float64 the CSR graph's edge weights (>= 0; ``inf`` = no edge).
        indices: (E,) int32 column of each edge.
        indptr: (N + 1,) int32 row pointers.
        source: the vertex searched from.
        stop: the vertex to stop at once settled; -1 to settle everything within ``limit``.
        limit: the largest distance searched [the graph's unit] (``inf``: no limit).

    Returns:
        ``(dist, pred)``: (N,) float64 distance from ``source`` (``inf`` unreached) and (N,)
        int32 predecessor on the shortest path (:data:`NO_PREDECESSOR` for the source and the
        unreached), as scipy returns them (final only for the settled vertices when stopped).
    """
    n = indptr.shape[0] - 1
    dist = np.full(n, np.inf)
    pred = np.full(n, NO_PREDECESSOR, dtype=np.int32)
    heap = np.empty((4096, 2))  # rows (distance, vertex); the vertex as a float (exact < 2**53)
    dist[source] = 0.0
    heap[0, 0], heap[0, 1] = 0.0, source
    settle(data, indices, indptr, dist, pred, heap, 1, stop, np.inf if stop < 0 else -np.inf,
           limit)
    return dist, pred


@njit(cache=True, nogil=True)
def settle(data, indices, indptr, dist, pred, heap, size, stop, bound, limit):
    """Go on with a :func:`dijkstra` search from where it stands until vertex ``stop`` is
    settled and every vertex up to distance ``bound`` is: a search whose every step is one of
    the whole search's, in its order, so each settled vertex has scipy's whole-map distance and
    predecessor to the last bit, however many calls it took to get there (with the same
    ``limit`` in every call).

    The search's state is ``dist``, ``pred`` (updated in place) and its heap: a vertex whose
    ``dist`` is below the heap's first distance is settled (no later pop can lower it); an
    empty heap means the search is complete (what is still ``inf`` cannot be reached).

    Args:
        data, indices, indptr: the CSR graph, as for :func:`dijkstra`.
        dist: (N,) float64 the distances so far ([0] at the source, ``inf`` elsewhere to start).
        pred: (N,) int32 the predecessors so far (:data:`NO_PREDECESSOR` to start).
        heap: (M, 2) the heap's rows ``(distance, vertex)`` (to start: the source at 0).
        size: the heap's entries (1 to start).
        stop: the vertex to settle; -1 for none.
        bound: settle every vertex within this distance too (``inf``: complete the search;
            ``-inf``: none but ``stop``).
        limit: the largest distance searched, as :func:`dijkstra`'s (``inf``: no limit).

    Returns:
        ``(heap, size)``: the heap (grown when it was full) and its entries.
    """
    while size > 0:
        top = heap[0, 0]
        if top > bound and (stop < 0 or dist[stop] < top):
            break
        d, v = _pop(heap, size)
        size -= 1
        if dist[v] < d:
            continue  # lowered since this pair was pushed
        for j in range(indptr[v], indptr[v + 1]):
            u = indices[j]
            nd = d + data[j]
            if nd <= limit and dist[u] > nd:
                dist[u] = nd
                pred[u] = v
                heap = _push(heap, size, nd, u)
                size += 1
    return heap, size


@njit(cache=True, nogil=True)
def _rose(data, base_data, indices, indptr, v, p):
    """Whether the move entry ``(p, v)`` (row ``p``, column ``v``) weighs more than the base's."""
    for j in range(indptr[p], indptr[p + 1]):
        if indices[j] == v:
            return data[j] > base_data[j]
    return False


@njit(cache=True, nogil=True)
def repair_dijkstra(data, base_data, indices, indptr, base_dist, base_pred, changed, rows,
                    source, stop, bound=np.inf):
    """:func:`dijkstra` from ``source`` on a graph whose weights only rose from a base graph's,
    stopped once ``stop`` is settled, searching again only what the rise can change.

    A vertex whose branch of the base's shortest-path tree (its predecessors up to the source)
    uses no risen edge keeps its distance and predecessor: no path got cheaper (IEEE addition is
    monotonic), its own costs what it did, and every rival that tied with it still pops no
    earlier.  The others, the subtrees below the risen tree edges (the *affected* vertices), are
    searched again by Dijkstra's loop, which relaxes only into affected vertices and is fed the
    unaffected vertices next to them at their final distances, in pop order (sorted once, not
    pushed): every pop that can change an affected vertex comes in the whole search's order, so
    each affected vertex settled before ``stop`` gets the whole search's distance and predecessor
    to the last bit (``tests/swarm_nav/test_planner_equivalence.py`` holds it against scipy).
    The graph's pattern must be symmetric (``v`` in row ``u`` iff ``u`` in row ``v``), as an
    8-connected grid's is.

    Args:
        data: (E,) float64 the graph's weights (the base's pattern, some weights risen; ``inf``
            = no edge).
        base_data: (E,) float64 the base graph's weights.
        indices: (E,) int32 column of each edge (shared by both graphs).
        indptr: (N + 1,) int32 row pointers (shared).
        base_dist: (N,) float64 the base graph's whole search from ``source`` (scipy's).
        base_pred: (N,) int32 its predecessors.
        changed: (K,) int edge indices whose weight may differ from the base's (others do not).
        rows: (K,) int the row of each of them.
        source: the vertex searched from.
        stop: the vertex to stop at once settled.
        bound: search again only the affected vertices of base distance up to ``bound`` (none
            beyond can lie on ``stop``'s path when ``stop``'s new distance is within it, as
            distances only rose); when ``stop`` is not settled within it, all of them.

    Returns:
        ``(dist, pred)`` as :func:`dijkstra` stopped at ``stop`` gives them for ``stop`` and the
        vertices on its path (``base_dist`` and ``base_pred`` themselves when ``stop``'s branch
        did not rise; do not modify them).
    """
    dist, pred, done = _repair(data, base_data, indices, indptr, base_dist, base_pred, changed,
                               rows, source, stop, bound)
    if not done:  # the start lies beyond the bound: search again without one
        dist, pred, _ = _repair(data, base_data, indices, indptr, base_dist, base_pred, changed,
                                rows, source, stop, np.inf)
    return dist, pred


@njit(cache=True, nogil=True)
def _repair(data, base_data, indices, indptr, base_dist, base_pred, changed, rows, source, stop,
            bound):
    """:func:`repair_dijkstra` searching again only the affected vertices of base distance up
    to ``bound``; also whether that settled ``stop`` (always, without a bound)."""
    n = indptr.shape[0] - 1
    for k in changed:
        if data[k] < base_data[k]:  # not a rise: the premise fails, search it all
            dist, pred = dijkstra(data, indices, indptr, source, stop, np.inf)
            return dist, pred, True
    v = stop
    rose = False
    while base_pred[v] >= 0 and not rose:  # does stop's own branch use a risen edge?
        rose = _rose(data, base_data, indices, indptr, v, base_pred[v])
        v = base_pred[v]
    if not rose:
        return base_dist, base_pred, True
    affected = np.zeros(n, dtype=np.bool_)
    queue = np.empty(n, dtype=np.int32)
    count = 0
    for i in range(changed.shape[0]):
        k = changed[i]
        v = indices[k]
        if data[k] > base_data[k] and not affected[v] and base_pred[v] == rows[i]:
            affected[v] = True  # its tree edge rose: the root of an affected subtree
            queue[count] = v
            count += 1
    head = 0
    while head < count:  # down the base tree: v's children are the u of row v it precedes
        v = queue[head]
        head += 1
        for j in range(indptr[v], indptr[v + 1]):
            u = indices[j]
            if not affected[u] and base_pred[u] == v and base_dist[u] <= bound:
                affected[u] = True
                queue[count] = u
                count += 1
    dist = base_dist.copy()
    pred = base_pred.copy()
    fed = np.zeros(n, dtype=np.bool_)
    feed = np.empty(max(count, 64), dtype=np.int64)  # unaffected neighbours, at final distances
    n_feed = 0
    for i in range(count):
        x = queue[i]
        dist[x] = np.inf
        pred[x] = NO_PREDECESSOR
        for j in range(indptr[x], indptr[x + 1]):
            y = indices[j]
            if not affected[y] and not fed[y] and base_dist[y] < np.inf:
                fed[y] = True
                if n_feed == feed.shape[0]:
                    feed = np.concatenate((feed, np.empty(n_feed, dtype=np.int64)))  # > 0
                feed[n_feed] = y
                n_feed += 1
    feed = feed[:n_feed]
    feed = feed[np.argsort(-feed)]  # the larger vertex first between equal distances ...
    feed = feed[np.argsort(base_dist[feed], kind="mergesort")]  # ... the smaller distance first
    heap = np.empty((4096, 2))
    size = 0
    f = 0
    settled = False
    while size > 0 or f < n_feed:
        if f < n_feed and (size == 0 or _before(base_dist[feed[f]], feed[f], heap[0, 0],
                                                   heap[0, 1])):
            v = feed[f]
            d = base_dist[v]
            f += 1
        else:
            d, v = _pop(heap, size)
            size -= 1
            if dist[v] < d:
                continue  # lowered since this pair was pushed
        if d > bound:
            break  # past the bound: what follows may rest on vertices not searched again
        if v == stop:
            settled = True
            break
        for j in range(indptr[v], indptr[v + 1]):
            u = indices[j]
            nd = d + data[j]
            if affected[u] and dist[u] > nd:
                dist[u] = nd
                pred[u] = v
                heap = _push(heap, size, nd, u)
                size += 1
    return dist, pred, settled or bound == np.inf


@njit(cache=True, nogil=True)
def patch_moves(pad, steps, moves, r0, r1, c0, c1, width, slots, base_data):
    """The moves of an overlay's window whose cost differs from the base graph's (the loop of
    :func:`swarm_nav.planner._patch`, compiled; the costs :func:`swarm_nav.planner._edge_costs`
    gives, by the same IEEE operations).

    Args:
        pad: (r1 - r0 + 2, c1 - c0 + 2) float64 the overlay's step multipliers over rows
            ``r0 - 1 .. r1`` and columns ``c0 - 1 .. c1`` (0 = impassable, and outside the map).
        steps: (8,) float64 each move's length [m] (``hypot(dr, dc) * resolution``).
        moves: (8, 2) int64 each move's ``(dr, dc)`` from the neighbour into the cell.
        r0, r1, c0, c1: the window (cells moved into): first row, one past its last row, first
            column, one past its last column.
        width: the map's width [cells].
        slots: (H * W, 8) int32 the base graph's data index of each (cell, move), -1 if none.
        base_data: (E,) float64 the base graph's weights.

    Returns:
        ``(at, cost, rows)``: (K,) int32 data indices, (K,) float64 their new costs [m] (``inf``
        for a move the overlay forbids) and (K,) int64 their rows (the cells moved into).
    """
    n = (r1 - r0) * (c1 - c0) * 8
    at = np.empty(n, dtype=np.int32)
    cost = np.empty(n)
    rows = np.empty(n, dtype=np.int64)
    count = 0
    for r in range(r0, r1):
        i = r - r0 + 1
        for c in range(c0, c1):
            j = c - c0 + 1
            cell = r * width + c
            here = pad[i, j] > 0.0
            for k in range(8):
                slot = slots[cell, k]
                if slot < 0:
                    continue
                dr, dc = moves[k, 0], moves[k, 1]
                ok = here and pad[i + dr, j + dc] > 0.0
                if ok and dr != 0 and dc != 0:
                    ok = pad[i + dr, j] > 0.0 and pad[i, j + dc] > 0.0
                value = steps[k] * pad[i, j] if ok else np.inf
                if value != base_data[slot]:
                    at[count] = slot
                    cost[count] = value
                    rows[count] = cell
                    count += 1
    return at[:count], cost[:count], rows[:count]


@njit(cache=True, nogil=True)
def _first(f1, h1, v1, f2, h2, v2):
    """Whether A* heap entry ``(f1, h1, v1)`` pops before ``(f2, h2, v2)``: the smaller f, then
    the smaller h (the deeper entry: on a tie of f the one nearer the goal), then the larger
    vertex."""
    return f1 < f2 or (f1 == f2 and (h1 < h2 or (h1 == h2 and v1 > v2)))


@njit(cache=True, nogil=True)
def astar(data, slots, opposite, moves, width, heuristic, source, target):
    """A* from ``source`` to ``target`` over the grid graph, guided by ``heuristic``.

    The graph is the planner's reversed cell graph (:func:`swarm_nav.planner._build_graph`):
    ``slots[v, k]`` is the index in ``data`` of the cost [m] of the move into cell ``v`` from its
    neighbour ``v + moves[k]`` (-1: none), so the move ``u -> u + moves[j]`` costs
    ``data[slots[u + moves[j], opposite[j]]]``. With a heuristic that never exceeds the cost of a
    move plus its own value at the cell moved into (consistent: the static map's cost-to-go
    under an overlay that only raises costs), every cell is settled once and the path found is
    a cheapest one (Hart, Nilsson, Raphael 1968); among paths of equal cost it is not always
    the one Dijkstra's search from the goal would follow.

    Args:
        data: (E,) float64 move costs (``inf``: the move is forbidden).
        slots: (N, 8) int32 data index of each (cell, neighbour slot).
        opposite: (8,) int64 the slot of the move back.
        moves: (8, 2) int64 (row, column) offset of each slot.
        width: cells per row; N = rows * width.
        heuristic: (N,) float64 a lower bound of each cell's cost to ``target`` (``inf``: it
            cannot reach it).
        source, target: flat cell indices.

    Returns:
        ``(path, cost)``: (K,) int64 the cells from ``source`` to ``target`` and the path's
        cost [m]; an empty path and ``inf`` when ``target`` cannot be reached.
    """
    n = heuristic.shape[0]
    rows = n // width
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    hf = np.empty(1024)  # the binary heap, as three columns: f, h, vertex
    hh = np.empty(1024)
    hv = np.empty(1024, dtype=np.int64)
    size = 0
    if math.isfinite(heuristic[source]):
        g[source] = 0.0
        hf[0], hh[0], hv[0] = heuristic[source], heuristic[source], source
        size = 1
    found = False
    while size > 0:
        v = hv[0]
        size -= 1  # the last entry into the root's hole, sifted down
        lf, lh, lv = hf[size], hh[size], hv[size]
        i = 0
        while True:
            c = 2 * i + 1
            if c >= size:
                break
            if c + 1 < size and _first(hf[c + 1], hh[c + 1], hv[c + 1], hf[c], hh[c], hv[c]):
                c += 1
            if not _first(hf[c], hh[c], hv[c], lf, lh, lv):
                break
            hf[i], hh[i], hv[i] = hf[c], hh[c], hv[c]
            i = c
        hf[i], hh[i], hv[i] = lf, lh, lv
        if closed[v]:
            continue
        closed[v] = True
        if v == target:
            found = True
            break
        r, col = v // width, v % width
        gv = g[v]
        for j in range(8):
            rr, cc = r + moves[j, 0], col + moves[j, 1]
            if rr < 0 or rr >= rows or cc < 0 or cc >= width:
                continue
            u = rr * width + cc
            k = slots[u, opposite[j]]
            if k < 0 or closed[u]:
                continue
            ng = gv + data[k]
            hu = heuristic[u]
            if ng < g[u] and math.isfinite(hu):
                g[u] = ng
                parent[u] = v
                if size == hf.shape[0]:
                    hf = np.concatenate((hf, np.empty(size)))
                    hh = np.concatenate((hh, np.empty(size)))
                    hv = np.concatenate((hv, np.empty(size, dtype=np.int64)))
                nf = ng + hu
                i = size
                size += 1
                while i > 0:  # sift up
                    q = (i - 1) // 2
                    if not _first(nf, hu, u, hf[q], hh[q], hv[q]):
                        break
                    hf[i], hh[i], hv[i] = hf[q], hh[q], hv[q]
                    i = q
                hf[i], hh[i], hv[i] = nf, hu, u
    if not found:
        return np.empty(0, dtype=np.int64), np.inf
    count = 1
    v = target
    while v != source:
        v = parent[v]
        count += 1
    path = np.empty(count, dtype=np.int64)
    v = target
    for i in range(count - 1, -1, -1):
        path[i] = v
        v = parent[v]
    return path, g[target]
