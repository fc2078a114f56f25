"""``swarm-up --foxglove [PORT]``: the run, live, over the Foxglove WebSocket protocol.

A server of the ``foxglove-sdk`` package (https://docs.foxglove.dev/docs/sdk) in ``swarm-up``'s
own process, fed by the live view's :class:`~swarm_viz.fleet_view.FleetState` (the same poses,
plans, scans and ``nav_status`` as the dashboard, read by :class:`swarm_viz.node.FleetNode`).
Foxglove, or its open fork Lichtblick, connects to ``ws://127.0.0.1:PORT``.

Channels (Foxglove's own schemas, protobuf-encoded by the SDK, unless said JSON):

=======================  ==========================  ========================================
topic                    schema                      what
=======================  ==========================  ========================================
``/map``                 ``foxglove.Grid``           the occupancy grid (0 free ... 100
                                                     occupied, 255 unknown) in ``map``; sent
                                                     again to a client that subscribes
``/tf``                  ``foxglove.FrameTransforms``  ``map`` -> ``<ns>/base_footprint`` ->
                                                     ``<ns>/base_scan`` for every robot
``/swarm/poses``         ``foxglove.PosesInFrame``   every robot's pose in ``map``
``/swarm/footprints``    ``foxglove.SceneUpdate``    each robot's outline and heading
                                                     (frame-locked to its base_footprint)
``/swarm/plans``         ``foxglove.SceneUpdate``    each robot's global plan in ``map``
``/swarm/workstations``  ``foxglove.SceneUpdate``    each workstation, coloured by state
                                                     (free, occupied, held), and its name
``/<ns>/scan``           ``foxglove.LaserScan``      the robot's latest scan, in ``map``
                                                     (posed where the robot was)
``/swarm/collisions``    ``foxglove.Event``          one per collision (robot, other, kind,
                                                     x, y)
``/swarm/log``           ``foxglove.Log``            each collision as a warning line
``/<ns>/nav_status``     ``swarm_workbench/NavStatus`` (JSON)  ``state``, ``goal``, values
``/swarm/kpi``           ``swarm_workbench/Kpi`` (JSON)  tasks, throughput, collisions, RTF
=======================  ==========================  ========================================

Every timestamp is simulated time, and the server's clock is too (``broadcast_time``,
capability ``time``): Foxglove's time line shows the simulated seconds.  A client may publish
(capability ``clientPublish``, encoding ``json``) a ``geometry_msgs/msg/PoseStamped`` on
``/<ns>/goal_pose``: ``swarm-up`` publishes it on that robot's ``goal_pose``, and its navigator
drives there (a new goal replaces the current one; its commander, if any, sends the next one
when it ends).

With no client subscribed, nothing is built and nothing is subscribed to on the ROS side (the
live view's demand, :meth:`swarm_viz.node.FleetNode.demand`): the swarm runs as without
``--foxglove``.  Frames are sent ``ViewConfig.rate_hz`` times a wall second (the pacing of a view,
not of anything simulated).
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from collections.abc import Callable

import numpy as np

from swarm_viz.fleet_view import FleetState, KpiTracker, ViewConfig

HOST = "127.0.0.1"
WARN_EVERY_S = 5.0  # [s] wall: at most one warning about malformed goals this often
DEFAULT_PORT = 8765  # Foxglove's default for its WebSocket protocol
STATE_COLOURS = {  # RGBA of a workstation by state
    "free": (0.2, 0.7, 0.3, 0.8),
    "occupied": (0.9, 0.5, 0.1, 0.9),
    "held": (0.8, 0.2, 0.2, 0.9),
}
GOAL_SCHEMA = "geometry_msgs/msg/PoseStamped"
# JSON Schemas of one type per field (a list of types, or an object without "properties", is
# refused by the clients' parseJsonSchema, @foxglove/mcap-support); a field not yet known is null.
NAV_STATUS_SCHEMA = ("swarm_workbench/NavStatus", {
    "type": "object", "properties": {
        "state": {"type": "string", "description": "idle, driving, holding, ... (null: none yet)"},
        "goal": {"type": "array", "items": {"type": "number"},
                 "description": "x, y of the current goal in map [m] (null: none)"},
        "values": {"type": "object", "properties": {},
                   "description": "the nav_status key/values"}}})
KPI_SCHEMA = ("swarm_workbench/Kpi", {
    "type": "object", "properties": {
        "sim_time_s": {"type": "number"}, "rtf": {"type": "number"},
        "tasks": {"type": "integer"}, "throughput_per_hour": {"type": "number"},
        "goals_aborted": {"type": "integer"}, "collisions": {"type": "integer"},
        "late_ticks": {"type": "integer"}, "robots": {"type": "integer"},
        "ready": {"type": "integer"}}})


def _json_schema(named):
    from foxglove import Schema

    name, schema = named
    return Schema(name=name, encoding="jsonschema", data=json.dumps(schema).encode())


def _quat(yaw: float):
    from foxglove.messages import Quaternion

    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def _stamp(ns: int):
    from foxglove.messages import Timestamp

    return Timestamp(sec=int(ns // 1_000_000_000), nsec=int(ns % 1_000_000_000))


def _vec(x: float, y: float, z: float = 0.0):
    from foxglove.messages import Vector3

    return Vector3(x=x, y=y, z=z)


def _pose(x: float, y: float, yaw: float, z: float = 0.0):
    from foxglove.messages import Pose

    return Pose(position=_vec(float(x), float(y), z), orientation=_quat(float(yaw)))


def goal_from_json(data: bytes) -> tuple[float, float, float, str]:
    """A ``PoseStamped`` as Foxglove's Publish panel sends it in JSON -> ``(x, y, yaw, frame)``.

    Raises:
        ValueError: not JSON, or no finite ``pose.position`` x and y.
    """
    try:
        msg = json.loads(data)
        pose = msg["pose"]
        x, y = float(pose["position"]["x"]), float(pose["position"]["y"])
        q = pose.get("orientation") or {}
        qz, qw = float(q.get("z", 0.0)), float(q.get("w", 1.0))
        frame = str((msg.get("header") or {}).get("frame_id", "map") or "map")
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"not a {GOAL_SCHEMA} in JSON: {exc}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ValueError("goal position is not finite")
    return x, y, 2.0 * math.atan2(qz, qw), frame


class FoxgloveView:
    """The Foxglove WebSocket server of one run (see the module docstring).

    Args:
        fleet: the live view's fleet state, guarded by ``fleet_lock``.
        fleet_lock: the lock.
        recorder: the metrics recorder (``/swarm/kpi``), guarded by ``recorder_lock``.
        recorder_lock: its lock.
        occ: the map (:class:`swarm_scene.occupancy.OccupancyMap`).
        workstations: :class:`swarm_scene.poi.Workstation` records.
        footprint: (K, 2) outline in base_footprint [m], or a list of every robot's.
        lidar_pose: (3,) lidar mount x, y, yaw in base_footprint [m, rad], or (N, 3).
        ws_states: callable -> ``(states, holders)`` (the caller holds ``fleet_lock``).
        on_demand: called with the number of clients that subscribe to anything, when it
            changes (:meth:`swarm_viz.node.FleetNode.demand`).
        on_watch: called with the robots whose scan channel someone subscribes to.
        on_goal: called with ``(ns, x, y, yaw, frame)`` for a goal a client published.
        port: TCP port on :data:`HOST` (0: any free one).
        cfg: the view's settings.
    """

    def __init__(self, *, fleet: FleetState, fleet_lock, recorder, recorder_lock, occ,
                 workstations, footprint, lidar_pose, ws_states: Callable,
                 on_demand: Callable[[int], None], on_watch: Callable[[frozenset[int]], None],
                 on_goal: Callable[[str, float, float, float, str], None], port: int,
                 cfg: ViewConfig | None = None):
        self.fleet = fleet
        self.fleet_lock = fleet_lock
        self.recorder = recorder
        self.recorder_lock = recorder_lock
        self.occ = occ
        self.workstations = tuple(workstations)
        n = len(fleet.robots)
        self.footprints = (list(footprint) if isinstance(footprint, list)
                           else [np.asarray(footprint, dtype=float)] * n)
        lp = np.asarray(lidar_pose, dtype=float)
        self.lidar_pose = lp if lp.ndim == 2 else np.tile(lp, (n, 1))
        self.ws_states = ws_states
        self.on_demand = on_demand
        self.on_watch = on_watch
        self.on_goal = on_goal
        self.port = port
        self.cfg = cfg = cfg or ViewConfig()
        self.kpi = KpiTracker(cfg)
        self.server = None
        self.frames_sent = 0
        self.goals_published = 0
        self.malformed_goals = 0
        self._subs: dict[int, set[int]] = {}  # channel id -> subscribed client ids
        self._client_channels: dict[tuple[int, int], str] = {}  # (client, channel) -> robot
        self._sent_paths = np.zeros(n, dtype=np.int64)
        self._sent_scans = np.zeros(n, dtype=np.int64)
        self._sent_status = np.zeros(n, dtype=np.int64)
        self._collisions_sent = 0
        self._map_pending = False
        self._last_warning = -math.inf
        self._state_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.ctx = None

    # -- server --------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The address a client opens."""
        return f"ws://{HOST}:{self.port}"

    def start(self) -> None:
        """Start the server and its sending thread.

        Raises:
            OSError: the port cannot be listened on.
        """
        import foxglove
        from foxglove import Capability, Context
        from foxglove import channels as ch

        self.ctx = ctx = Context()
        robots = self.fleet.robots
        self.ch_map = ch.GridChannel("/map", context=ctx)
        self.ch_tf = ch.FrameTransformsChannel("/tf", context=ctx)
        self.ch_poses = ch.PosesInFrameChannel("/swarm/poses", context=ctx)
        self.ch_footprints = ch.SceneUpdateChannel("/swarm/footprints", context=ctx)
        self.ch_plans = ch.SceneUpdateChannel("/swarm/plans", context=ctx)
        self.ch_ws = ch.SceneUpdateChannel("/swarm/workstations", context=ctx)
        self.ch_events = ch.EventChannel("/swarm/collisions", context=ctx)
        self.ch_log = ch.LogChannel("/swarm/log", context=ctx)
        self.ch_kpi = foxglove.Channel("/swarm/kpi", schema=_json_schema(KPI_SCHEMA),
                                       message_encoding="json", context=ctx)
        self.ch_scans = [ch.LaserScanChannel(f"/{ns}/scan", context=ctx) for ns in robots]
        self.ch_status = [foxglove.Channel(f"/{ns}/nav_status",
                                           schema=_json_schema(NAV_STATUS_SCHEMA),
                                           message_encoding="json", context=ctx)
                          for ns in robots]
        self._scan_index = {c.id(): i for i, c in enumerate(self.ch_scans)}
        self.server = foxglove.start_server(
            name="swarm-workbench", host=HOST, port=self.port, context=ctx,
            capabilities=[Capability.ClientPublish, Capability.Time],
            supported_encodings=["json"], server_listener=_Listener(self))
        self.port = self.server.port
        self._thread = threading.Thread(target=self._run, name="foxglove", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop sending and close the server."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
        if self.server is not None:
            self.server.stop()

    # -- what clients want -----------------------------------------------------------------------
    def _subscribed(self, client: int, channel: int, on: bool) -> None:
        with self._state_lock:
            clients = self._subs.setdefault(channel, set())
            (clients.add if on else clients.discard)(client)
            if on and channel == self.ch_map.id():
                self._map_pending = True
            watching = frozenset(i for c, i in self._scan_index.items() if self._subs.get(c))
            active = len(set().union(*self._subs.values())) if self._subs else 0
        self.on_demand(active)
        self.on_watch(watching)

    def _wanted(self, channel) -> bool:
        return bool(self._subs.get(channel.id()))

    def _advertised(self, client: int, channel_id: int, topic: str, encoding: str,
                    schema_name: str) -> None:
        ns = topic.strip("/").rsplit("/", 1)[0] if topic.endswith("/goal_pose") else None
        if ns in self.fleet.index and encoding == "json":
            self._client_channels[(client, channel_id)] = ns

    def _message(self, client: int, channel_id: int, data: bytes) -> None:
        ns = self._client_channels.get((client, channel_id))
        if ns is None:
            return
        try:
            x, y, yaw, frame = goal_from_json(data)
        except ValueError as exc:
            self.malformed_goals += 1
            now = time.monotonic()
            if now - self._last_warning >= WARN_EVERY_S:  # throttled
                self._last_warning = now
                print(f"swarm-up: warning: foxglove: a goal on /{ns}/goal_pose dropped: {exc} "
                      f"({self.malformed_goals} so far)", file=sys.stderr, flush=True)
            return
        self.goals_published += 1
        self.on_goal(ns, x, y, yaw, frame)

    # -- sending -------------------------------------------------------------------------------
    def _run(self) -> None:
        period = 1.0 / self.cfg.rate_hz
        while not self._stop.wait(period):
            if any(self._subs.values()):
                self.send_frame()

    def send_frame(self) -> None:
        """Build and send what is subscribed to (the sending thread; callable from tests)."""
        from foxglove.messages import SceneUpdate

        with self.fleet_lock:
            f = self.fleet
            poses = f.poses.copy()
            stamps = f.pose_stamp_ns.copy()
            paths = {i: f.paths[i] for i in np.flatnonzero(f.path_version != self._sent_paths)}
            self._sent_paths[:] = f.path_version
            scans = {i: f.scans[i] for i in np.flatnonzero(f.scan_version != self._sent_scans)
                     if i in f.scans}
            self._sent_scans[:] = f.scan_version
            status = {i: (f.states[i], f.goals[i].copy(), dict(f.status_values[i] or {}))
                      for i in np.flatnonzero(f.status_version != self._sent_status)}
            self._sent_status[:] = f.status_version
            ws_states, _ = (self.ws_states() if self.workstations and self._wanted(self.ch_ws)
                            else ([], []))
        with self.recorder_lock:
            kpi = self.kpi.figures(self.recorder, time.monotonic())
            collisions = list(self.recorder.collision_log[self._collisions_sent:])
            self._collisions_sent += len(collisions)
        known = np.isfinite(poses[:, 0])
        t_ns = int(stamps[known].max()) if known.any() else 0
        if kpi["sim_time_s"] is not None:
            t_ns = max(t_ns, int(round(kpi["sim_time_s"] * 1e9)))
        self.server.broadcast_time(t_ns)
        stamp = _stamp(t_ns)
        if self._map_pending:
            self._map_pending = False
            self.ch_map.log(self._grid(), log_time=t_ns)
        if known.any():
            self._send_robots(poses, stamps, known, t_ns)
        if paths and self._wanted(self.ch_plans):
            self.ch_plans.log(SceneUpdate(entities=[
                self._plan(i, p, stamp) for i, p in paths.items()]), log_time=t_ns)
        if self.workstations and self._wanted(self.ch_ws):
            self.ch_ws.log(SceneUpdate(entities=[
                self._workstation(w, s, stamp) for w, s in zip(self.workstations, ws_states,
                                                               strict=True)]), log_time=t_ns)
        self._send_scans(scans)
        for i, (state, goal, values) in status.items():
            if self._wanted(self.ch_status[i]):
                self.ch_status[i].log({
                    "state": None if state is None else state.name.lower(),
                    "goal": None if not np.isfinite(goal).all() else [float(goal[0]),
                                                                       float(goal[1])],
                    "values": values}, log_time=t_ns)
        self._send_collisions(collisions)
        if self._wanted(self.ch_kpi):
            self.ch_kpi.log(kpi, log_time=t_ns)
        self.frames_sent += 1

    def _send_robots(self, poses: np.ndarray, stamps: np.ndarray, known: np.ndarray,
                     t_ns: int) -> None:
        """The robots' transforms, poses and footprints (those with a known pose)."""
        from foxglove.messages import FrameTransform, FrameTransforms, PosesInFrame, SceneUpdate

        robots, stamp = self.fleet.robots, _stamp(t_ns)
        if self._wanted(self.ch_tf):
            tfs = []
            for i in np.flatnonzero(known):
                x, y, yaw = poses[i]
                ts = _stamp(int(stamps[i]))
                tfs.append(FrameTransform(
                    timestamp=ts, parent_frame_id="map",
                    child_frame_id=f"{robots[i]}/base_footprint",
                    translation=_vec(float(x), float(y)), rotation=_quat(float(yaw))))
                lx, ly, lyaw = self.lidar_pose[i]
                tfs.append(FrameTransform(
                    timestamp=ts, parent_frame_id=f"{robots[i]}/base_footprint",
                    child_frame_id=f"{robots[i]}/base_scan",
                    translation=_vec(float(lx), float(ly)), rotation=_quat(float(lyaw))))
            self.ch_tf.log(FrameTransforms(transforms=tfs), log_time=t_ns)
        if self._wanted(self.ch_poses):
            self.ch_poses.log(PosesInFrame(
                timestamp=stamp, frame_id="map",
                poses=[_pose(*poses[i]) if known[i] else _pose(0.0, 0.0, 0.0)
                       for i in range(len(robots))]), log_time=t_ns)
        if self._wanted(self.ch_footprints):
            self.ch_footprints.log(SceneUpdate(entities=[
                self._footprint(i, stamp) for i in np.flatnonzero(known)]), log_time=t_ns)

    def _send_scans(self, scans: dict) -> None:
        """The new scans, each in ``map`` at its lidar's pose."""
        from foxglove.messages import LaserScan

        for i, sample in scans.items():
            if self._wanted(self.ch_scans[i]):
                lx, ly, lyaw = self.lidar_pose[i]
                x, y, yaw = sample.pose
                c, s = math.cos(yaw), math.sin(yaw)
                n = len(sample.ranges)
                self.ch_scans[i].log(LaserScan(
                    timestamp=_stamp(sample.stamp_ns), frame_id="map",
                    pose=_pose(x + c * lx - s * ly, y + s * lx + c * ly, yaw + lyaw),
                    start_angle=float(sample.angle_min),
                    end_angle=float(sample.angle_min + sample.angle_increment * (n - 1)),
                    ranges=[float(r) if sample.range_min <= r <= sample.range_max
                            else float("inf") for r in np.asarray(sample.ranges).tolist()],
                    intensities=[]), log_time=int(sample.stamp_ns))

    def _send_collisions(self, collisions: list[dict]) -> None:
        """Each new collision as an event and a warning line, at its simulated time."""
        from foxglove.messages import Event, KeyValuePair, Log, LogLevel

        for ev in collisions:
            at = int(round(ev["t"] * 1e9))
            text = (f"collision ({ev['kind']}): {ev['robot']} and {ev['other']} at "
                    f"({ev['x']:.2f}, {ev['y']:.2f})")
            self.ch_events.log(Event(
                start_time=_stamp(at), end_time=_stamp(at),
                metadata=[KeyValuePair(key=k, value=str(ev[k]))
                          for k in ("robot", "other", "kind", "x", "y")]), log_time=at)
            self.ch_log.log(Log(timestamp=_stamp(at), level=LogLevel.Warning, message=text,
                                name="swarm_sim"), log_time=at)

    def _grid(self):
        from foxglove.messages import (
            Grid,
            PackedElementField,
            PackedElementFieldNumericType,
            Vector2,
        )

        occ = self.occ
        grid = np.asarray(occ.data, dtype=np.int8)  # row 0 at origin y, as Grid's row 0
        h, w = grid.shape
        ox, oy, oyaw = occ.origin
        return Grid(
            timestamp=_stamp(0), frame_id="map", pose=_pose(ox, oy, oyaw, z=-0.01),
            column_count=w, cell_size=Vector2(x=occ.resolution, y=occ.resolution),
            row_stride=w, cell_stride=1,
            fields=[PackedElementField(name="occupancy", offset=0,
                                       type=PackedElementFieldNumericType.Uint8)],
            data=grid.astype(np.uint8).tobytes())

    def _footprint(self, i: int, stamp):
        from foxglove.messages import ArrowPrimitive, Color, LinePrimitive, Point3, SceneEntity
        from foxglove.messages import LinePrimitiveLineType as LineType

        ns = self.fleet.robots[i]
        outline = self.footprints[i]
        length = float(np.abs(outline[:, 0]).max()) if len(outline) else 0.2
        return SceneEntity(
            timestamp=stamp, frame_id=f"{ns}/base_footprint", id=ns, frame_locked=True,
            lines=[LinePrimitive(type=LineType.LineLoop, pose=_pose(0.0, 0.0, 0.0),
                                 thickness=0.03, scale_invariant=False,
                                 points=[Point3(x=float(px), y=float(py), z=0.05)
                                         for px, py in outline],
                                 color=Color(r=0.1, g=0.4, b=0.9, a=1.0))],
            arrows=[ArrowPrimitive(pose=_pose(0.0, 0.0, 0.0, z=0.05), shaft_length=length,
                                   shaft_diameter=0.03, head_length=0.08, head_diameter=0.08,
                                   color=Color(r=0.1, g=0.4, b=0.9, a=1.0))])

    def _plan(self, i: int, path, stamp):
        from foxglove.messages import Color, LinePrimitive, Point3, SceneEntity
        from foxglove.messages import LinePrimitiveLineType as LineType

        ns = self.fleet.robots[i]
        pts = [] if path is None else [Point3(x=float(x), y=float(y), z=0.02)
                                        for x, y in np.asarray(path)[:, :2].tolist()]
        return SceneEntity(
            timestamp=stamp, frame_id="map", id=f"{ns}/plan",
            lines=[LinePrimitive(type=LineType.LineStrip, pose=_pose(0.0, 0.0, 0.0),
                                 thickness=0.02, scale_invariant=False, points=pts,
                                 color=Color(r=0.2, g=0.8, b=0.2, a=0.8))] if pts else [])

    def _workstation(self, ws, state: str, stamp):
        from foxglove.messages import Color, CubePrimitive, SceneEntity, TextPrimitive, Vector3

        x, y, yaw = ws.pose
        r, g, b, a = STATE_COLOURS.get(state, (0.5, 0.5, 0.5, 0.8))
        return SceneEntity(
            timestamp=stamp, frame_id="map", id=f"workstation/{ws.name}",
            metadata=[],
            cubes=[CubePrimitive(pose=_pose(x, y, yaw, z=0.01),
                                 size=Vector3(x=0.3, y=0.3, z=0.02),
                                 color=Color(r=r, g=g, b=b, a=a))],
            texts=[TextPrimitive(pose=_pose(x, y, 0.0, z=0.3), billboard=True, font_size=12.0,
                                 scale_invariant=True, color=Color(r=1.0, g=1.0, b=1.0, a=1.0),
                                 text=f"{ws.name} ({state})")])


class _Listener:
    """The server's callbacks (foxglove-sdk threads), handed to the view."""

    def __init__(self, view: FoxgloveView):
        self.view = view

    def on_subscribe(self, client, channel) -> None:
        self.view._subscribed(client.id, channel.id, True)

    def on_unsubscribe(self, client, channel) -> None:
        self.view._subscribed(client.id, channel.id, False)

    def on_client_advertise(self, client, channel) -> None:
        self.view._advertised(client.id, channel.id, channel.topic, channel.encoding,
                              channel.schema_name)

    def on_client_unadvertise(self, client, client_channel_id) -> None:
        self.view._client_channels.pop((client.id, client_channel_id), None)

    def on_message_data(self, client, client_channel_id, data) -> None:
        self.view._message(client.id, client_channel_id, data)
