"""The live view of the fleet: what the dashboard and ``/swarm/markers`` show, and the page's
message contract.

Pure: no ROS import.  :class:`FleetState` holds the latest pose, plan, ``nav_status`` and (for
robots someone watches) scan of every robot; the ROS shell (:mod:`swarm_viz.node`) writes
into it under its lock.  :func:`workstation_states` says which workstations are free, occupied
or held.  :class:`KpiTracker` turns the metrics recorder (:mod:`swarm_metrics.aggregate`, the same
object that writes ``--metrics``) into the live figures.  The ``encode_*`` functions build the
JSON messages the page (``swarm_viz/web/dashboard.js``) reads; they are the contract between the
two, written once here:

``hello`` (first message on a WebSocket)::

    {"type": "hello", "world": str, "robots": [ns, ...],
     "footprint": [[x, y], ...] (base_footprint, m),
     "footprints": [[[x, y], ...], ...] (a mixed fleet only: every robot's own),
     "map": {"url": "/map.png", "resolution": m/cell, "origin": [x, y] (m, lower-left corner),
             "width": cells, "height": cells},
     "workstations": [{"name", "x", "y", "yaw", "holding": [[x, y], ...]}, ...],
     "rate_hz": frames per wall second, "robot": ns or null (the page's own robot)}

``frame`` (``rate_hz`` times a second, the same bytes for every browser)::

    {"type": "frame", "seq": int, "kpi": {"sim_time_s", "rtf", "tasks", "throughput_per_hour",
     "goals_aborted", "collisions", "late_ticks", "robots", "ready"},
     "robots": [[x, y, yaw, state] or null, ...] (index of hello.robots; m, rad, NavState name),
     "ws": ["free" | "occupied" | "held", ...] (index of hello.workstations),
     "holding": [robot index, ...],
     "paths": {robot index: [[x, y], ...] (m, map; [] = no path)} (the plans changed since the
              previous frame; every plan in a browser's first frame)}

``robot`` (to a browser that watches a robot, when its scan or status changed)::

    {"type": "robot", "robot": index, "status": {nav_status values} | null, "message": state,
     "scan": {"stamp": s, "pose": [x, y, yaw], "angle_min": rad, "angle_increment": rad,
              "range_max": m,
              "lidar": [x, y, yaw] (mount in base_footprint), "ranges": [m or null, ...]} | null}

A browser sends ``{"watch": [ns, ...]}`` to choose the robots whose ``robot`` messages it gets
(at most :data:`MAX_WATCH`); their scans are subscribed to only while someone watches them.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from swarm_common.nav_status import NavState

WS_FREE, WS_OCCUPIED, WS_HELD = "free", "occupied", "held"
MAX_WATCH = 8
"""Robots one browser may watch at once (each costs a scan subscription)."""
MAX_PATH_POINTS = 100
"""A plan is drawn as a marker with at most this many points (every k-th; the last always)."""
PATH_TOLERANCE = 0.01
"""[m] a plan is kept as its polyline without the points that lie this close to it
(:func:`simplify`): a navigator's plan is a few straight runs resampled every 5 cm, so at 100
robots the page drew and the server encoded some 30,000 points a frame instead of about 1,000."""


@dataclass(frozen=True)
class ViewConfig:
    """Settings of the live view.

    Attributes:
        rate_hz: frames sent to the browsers per wall second [Hz].
        markers_hz: ``/swarm/markers`` messages per wall second, and how often the live view
            checks whether anyone looks [Hz].
        dock_radius: a robot this close to a workstation's docking pose occupies it [m].
        goal_tolerance: a holding robot whose goal is this close to a workstation holds for it [m].
        rtf_window: wall time over which the live real-time factor is measured [s].
        path_decimals: decimals of the path coordinates sent to the page (2: 1 cm) [-].
        idle_grace_s: the poses and plans stay subscribed this long after the last browser
            left, ``/swarm/markers`` lost its last subscriber or ``/api/state`` was read (a page
            reload does not resubscribe 100 topics) [s].
    """

    # 6 Hz: >= 5 updates a second with a margin for jitter; a browser's CPU grows with the rate
    # (headless Chromium, 100 robots: 0.11 core at 10 Hz, 0.066 at 6 Hz, 0.02 at 1 Hz).
    rate_hz: float = 6.0  # [Hz]
    markers_hz: float = 2.0  # [Hz]
    dock_radius: float = 0.3  # [m]
    goal_tolerance: float = 0.05  # [m]
    rtf_window: float = 5.0  # [s]
    path_decimals: int = 2  # [-]
    idle_grace_s: float = 10.0  # [s]


def workstation_states(ws_xy: np.ndarray, robot_xy: np.ndarray, states, goals: np.ndarray,
                       cfg: ViewConfig | None = None) -> tuple[list[str], list[int]]:
    """Which workstations are free, occupied or held, and which robots hold.

    A workstation is *held* when a robot in ``HOLDING`` has it as its goal (the robot waits for
    it to free up), else *occupied* when a robot stands within ``cfg.dock_radius`` of its
    docking pose, else *free*.

    Args:
        ws_xy: (W, 2) docking positions in ``map`` [m].
        robot_xy: (N, 2) robot positions in ``map`` [m]; NaN rows are unknown robots.
        states: N robot states (:class:`NavState` or None).
        goals: (N, 2) each robot's goal in ``map`` [m]; NaN rows have none.
        cfg: the tolerances (default :class:`ViewConfig`).

    Returns:
        ``(states, holding)``: one of :data:`WS_FREE`, :data:`WS_OCCUPIED`, :data:`WS_HELD` per
        workstation, and the indices of the robots in ``HOLDING``.
    """
    cfg = cfg or ViewConfig()
    ws_xy = np.asarray(ws_xy, dtype=float).reshape(-1, 2)
    robot_xy = np.asarray(robot_xy, dtype=float).reshape(-1, 2)
    goals = np.asarray(goals, dtype=float).reshape(-1, 2)
    holding = [i for i, s in enumerate(states) if s == NavState.HOLDING]
    out = [WS_FREE] * len(ws_xy)
    if len(ws_xy) == 0:
        return out, holding
    with np.errstate(invalid="ignore"):
        if len(robot_xy):
            d = np.hypot(*(robot_xy[None, :, :] - ws_xy[:, None, :]).transpose(2, 0, 1))
            occupied = np.any(d <= cfg.dock_radius, axis=1)
        else:
            occupied = np.zeros(len(ws_xy), dtype=bool)
        held = np.zeros(len(ws_xy), dtype=bool)
        if holding:
            g = goals[holding]
            dg = np.hypot(*(g[None, :, :] - ws_xy[:, None, :]).transpose(2, 0, 1))
            held = np.any(dg <= cfg.goal_tolerance, axis=1)
    for k in range(len(ws_xy)):
        out[k] = WS_HELD if held[k] else (WS_OCCUPIED if occupied[k] else WS_FREE)
    return out, holding


@dataclass
class ScanSample:
    """One robot's latest scan, with the robot's pose at that time.

    Attributes:
        stamp_ns: the scan's stamp [ns] simulated.
        pose: (3,) x, y, yaw of base_footprint in ``map`` when it arrived [m, rad].
        angle_min: first beam's angle in the lidar frame [rad].
        angle_increment: step between beams [rad].
        range_min: shortest valid range [m].
        range_max: longest valid range [m].
        ranges: (M,) float32 [m].
    """

    stamp_ns: int
    pose: np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray


class FleetState:
    """The latest known state of every robot (not thread-safe: the caller holds a lock).

    Args:
        robots: namespaces without ``/``.
    """

    def __init__(self, robots: tuple[str, ...]):
        self.robots = tuple(robots)
        self.index = {ns: i for i, ns in enumerate(self.robots)}
        n = len(self.robots)
        self.poses = np.full((n, 3), np.nan)  # x, y, yaw in map [m, rad]
        self.pose_stamp_ns = np.zeros(n, dtype=np.int64)
        self.paths: list[np.ndarray | None] = [None] * n  # (M, 2) in map [m]
        self.path_version = np.zeros(n, dtype=np.int64)
        self.states: list[NavState | None] = [None] * n
        self.status_values: list[dict[str, str] | None] = [None] * n
        self.status_version = np.zeros(n, dtype=np.int64)
        self.goals = np.full((n, 2), np.nan)  # the current goal in map [m]
        self.scans: dict[int, ScanSample] = {}
        self.scan_version = np.zeros(n, dtype=np.int64)

    def set_pose(self, i: int, stamp_ns: int, x: float, y: float, yaw: float) -> None:
        """Robot ``i``'s pose in ``map`` [m, rad] at ``stamp_ns``; an older stamp is ignored."""
        if stamp_ns < self.pose_stamp_ns[i]:
            return
        self.pose_stamp_ns[i] = stamp_ns
        self.poses[i] = (x, y, yaw)

    def set_path(self, i: int, path: np.ndarray) -> None:
        """Robot ``i``'s global plan, (M, 2) in ``map`` [m] (M = 0: none), kept as
        :func:`simplify` of it with :data:`PATH_TOLERANCE`."""
        self.paths[i] = simplify(np.asarray(path, dtype=float).reshape(-1, 2), PATH_TOLERANCE)
        self.path_version[i] += 1

    def set_status(self, i: int, values: dict[str, str], state: NavState | None,
                   goal: tuple[float, float, float] | None) -> None:
        """Robot ``i``'s latest ``nav_status``: its values, decoded state and goal."""
        self.status_values[i] = dict(values)
        self.states[i] = state
        self.goals[i] = (goal[0], goal[1]) if goal is not None else (np.nan, np.nan)
        self.status_version[i] += 1

    def set_scan(self, i: int, sample: ScanSample) -> None:
        """Robot ``i``'s latest scan."""
        self.scans[i] = sample
        self.scan_version[i] += 1

    def drop_scan(self, i: int) -> None:
        """Forget robot ``i``'s scan (nobody watches it any more)."""
        self.scans.pop(i, None)


class KpiTracker:
    """The live figures of a run, read from the metrics recorder (:mod:`swarm_metrics.aggregate`).

    The recorder is the one ``swarm-up`` writes ``--metrics`` from, so ``tasks``,
    ``collisions``, ``goals_aborted`` and ``late_ticks`` are the same counts; the real-time
    factor is simulated over wall time across the last ``cfg.rtf_window`` wall seconds.

    Args:
        cfg: the view's settings.
    """

    def __init__(self, cfg: ViewConfig | None = None):
        self.cfg = cfg or ViewConfig()
        self._samples: deque[tuple[float, float]] = deque()  # (wall [s], sim [s])

    def figures(self, recorder, wall_s: float) -> dict:
        """The KPI dict of a ``frame`` message.

        Args:
            recorder: a :class:`swarm_metrics.aggregate.RunRecorder` (the caller holds its lock).
            wall_s: now, monotonic wall clock [s].

        Returns:
            ``sim_time_s`` [s] (None before the first ``/clock``), ``rtf`` (None until two
            clock samples), ``tasks``, ``throughput_per_hour`` [tasks per simulated hour],
            ``goals_aborted``, ``collisions`` (robot-robot + robot-wall), ``late_ticks``,
            ``robots``, ``ready``.
        """
        sim_s = recorder.last_sim_time_s
        reached, aborted = recorder.goal_totals()
        late = sum(r.late_events for r in recorder.per_robot.values())
        rtf = None
        if sim_s is not None:
            samples = self._samples
            if not samples or samples[-1][1] != sim_s or wall_s - samples[-1][0] > 0.5:
                samples.append((wall_s, sim_s))
            while len(samples) > 2 and wall_s - samples[1][0] >= self.cfg.rtf_window:
                samples.popleft()
            (w0, s0), (w1, s1) = samples[0], (wall_s, sim_s)
            if w1 - w0 > 0.2:
                rtf = (s1 - s0) / (w1 - w0)
        return {
            "sim_time_s": None if sim_s is None else round(sim_s, 2),
            "rtf": None if rtf is None else round(rtf, 3),
            "tasks": reached,
            "throughput_per_hour": (round(reached / (sim_s / 3600.0), 1)
                                    if sim_s else None),
            "goals_aborted": aborted,
            "collisions": sum(recorder.collision_events.values()),
            "late_ticks": late,
            "robots": len(recorder.robots),
            "ready": recorder.ready_count,
        }


def simplify(path: np.ndarray, tolerance: float) -> np.ndarray:
    """The polyline without the points that lie within ``tolerance`` of it: the
    Ramer-Douglas-Peucker algorithm (Ramer 1972; Douglas and Peucker 1973), iterative.

    Args:
        path: (N, 2) x, y [m].
        tolerance: [m] no dropped point lies farther than this from the simplified polyline.

    Returns:
        (K, 2), K <= N: a subsequence of ``path`` keeping its first and last point.
    """
    n = len(path)
    if n <= 2:
        return path
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        p, q = path[a], path[b]
        d = q - p
        rel = path[a + 1:b] - p
        dd = float(d @ d)
        t = np.clip(rel @ d / dd, 0.0, 1.0) if dd > 0.0 else np.zeros(len(rel))
        dist = np.hypot(rel[:, 0] - t * d[0], rel[:, 1] - t * d[1])  # to the segment p-q
        k = int(np.argmax(dist))
        if dist[k] > tolerance:
            m = a + 1 + k
            keep[m] = True
            stack.append((a, m))
            stack.append((m, b))
    return path[keep]


def decimate(path: np.ndarray, max_points: int = MAX_PATH_POINTS) -> np.ndarray:
    """Every k-th point of ``path`` (N, 2), keeping the last, so at most ``max_points`` remain."""
    n = len(path)
    if n <= max_points:
        return path
    step = -(-(n - 1) // (max_points - 1))
    idx = np.r_[np.arange(0, n - 1, step), n - 1]
    return path[idx]


# ------------------------------------------------------------------------------- messages
def _round_list(a: np.ndarray, decimals: int) -> list:
    return np.round(a, decimals).tolist()


def encode_hello(*, world: str, robots: tuple[str, ...], footprint: np.ndarray, map_info: dict,
                 workstations, rate_hz: float, robot: str | None,
                 footprints: list | None = None) -> dict:
    """The ``hello`` message (see the module docstring).

    Args:
        world: the world's name.
        robots: namespaces.
        footprint: (K, 2) polygon in base_footprint [m].
        map_info: ``url``, ``resolution`` [m/cell], ``origin`` [x, y] [m], ``width``, ``height``.
        workstations: :class:`swarm_scene.poi.Workstation` records.
        rate_hz: frames per wall second [Hz].
        robot: the robot of a per-robot page, or None.
        footprints: a mixed fleet: every robot's own (K_i, 2) polygon, in ``robots``' order
            (``footprints``, beside ``footprint``, the first robot's); None: one model.
    """
    extra = ({} if footprints is None else
             {"footprints": [_round_list(np.asarray(f, dtype=float), 3) for f in footprints]})
    return {
        "type": "hello",
        "world": world,
        "robots": list(robots),
        "footprint": _round_list(np.asarray(footprint, dtype=float), 3),
        "map": map_info,
        "workstations": [
            {"name": w.name, "x": round(float(w.pose[0]), 3), "y": round(float(w.pose[1]), 3),
             "yaw": round(float(w.pose[2]), 4),
             "holding": _round_list(np.asarray(w.holding, dtype=float).reshape(-1, 2), 3)}
            for w in workstations
        ],
        "rate_hz": rate_hz,
        "robot": robot,
        **extra,
    }


def encode_robots(fleet: FleetState) -> list:
    """The ``robots`` list of a frame: ``[x, y, yaw, state]`` per robot, None if unknown."""
    out = []
    for i, (x, y, yaw) in enumerate(fleet.poses.tolist()):
        if math.isnan(x):
            out.append(None)
        else:
            state = fleet.states[i]
            out.append([round(x, 3), round(y, 3), round(yaw, 3),
                        state.value if state is not None else None])
    return out


def encode_paths(fleet: FleetState, indices, decimals: int = 2) -> dict:
    """``{index: [[x, y], ...]}`` of the given robots' plans ([] when a robot has none)."""
    out = {}
    for i in indices:
        path = fleet.paths[i]
        out[str(i)] = [] if path is None else _round_list(path, decimals)
    return out


def _row(a: np.ndarray, i: int) -> np.ndarray:
    """``a`` itself if one row for all, else its row ``i``."""
    return a[i] if a.ndim == 2 else a


def encode_robot(fleet: FleetState, i: int, lidar_pose: np.ndarray, with_scan: bool) -> dict:
    """The ``robot`` message of robot ``i`` (see the module docstring).

    Args:
        fleet: the state.
        i: the robot's index.
        lidar_pose: (3,) the lidar's x, y, yaw in base_footprint [m, rad]; or (N, 3), every
            robot's (a mixed fleet).
        with_scan: include its latest scan (if any).
    """
    scan = fleet.scans.get(i) if with_scan else None
    scan_msg = None
    if scan is not None:
        r = scan.ranges.astype(float)
        ok = np.isfinite(r) & (r >= scan.range_min) & (r <= scan.range_max)
        ranges = [round(v, 3) if good else None for v, good in zip(r.tolist(), ok.tolist(),
                                                                     strict=True)]
        scan_msg = {"stamp": scan.stamp_ns / 1e9, "pose": _round_list(scan.pose, 4),
                    "angle_min": scan.angle_min, "angle_increment": scan.angle_increment,
                    "range_max": scan.range_max,
                    "lidar": _round_list(_row(np.asarray(lidar_pose, dtype=float), i), 4),
                    "ranges": ranges}
    values = fleet.status_values[i]
    state = fleet.states[i]
    return {"type": "robot", "robot": i, "status": values,
            "message": state.value if state is not None else None, "scan": scan_msg}
