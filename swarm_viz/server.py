"""``swarm-up --dashboard`` and ``--markers``: the live view of a run, in ``swarm-up``'s process.

:class:`LiveView` wires three parts together:

- :class:`~swarm_viz.node.FleetNode`, attached to the metrics listener (same context and
  thread), keeps a :class:`~swarm_viz.fleet_view.FleetState` and publishes ``/swarm/markers``;
- :class:`DashboardServer`, an aiohttp application on ``127.0.0.1:PORT`` in a thread of its own
  with its own asyncio loop: the page and its assets (``swarm_viz/web/``, nothing from the
  internet), the map as a PNG, ``/api/state`` (the latest frame as JSON) and ``/ws``;
- the KPIs, read from the metrics recorder (:class:`~swarm_viz.fleet_view.KpiTracker`), so the
  page shows the figures ``--metrics`` will hold.

The server builds one ``frame`` (:mod:`swarm_viz.fleet_view`) ``rate_hz`` times a second, only
while a browser is connected, and sends the same text to every browser.  The fleet node reads
the poses and plans only while a browser is connected, ``/swarm/markers`` has a subscriber or
``/api/state`` was read, and for ``idle_grace_s`` after (:meth:`FleetNode.demand
<swarm_viz.node.FleetNode.demand>`): a dashboard nobody looks at costs the swarm nothing,
and the first ``/api/state`` after a quiet spell shows the poses and plans of when someone last
looked (none before anyone did).  A browser whose
previous frame is still being written is skipped for that frame (it gets every plan again in
its next one), so a slow browser never holds the others up, and a closed or silent one
(WebSocket heartbeat) is dropped with its scan subscriptions.

Why aiohttp: a maintained asyncio HTTP server with WebSockets and static files built in (no
second framework, no ASGI server process), wheels for our Python, and a client the tests use to
drive headless Chromium over the DevTools protocol.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import io
import json
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from swarm_common.errors import InputError
from swarm_viz.fleet_view import (
    MAX_WATCH,
    FleetState,
    KpiTracker,
    ViewConfig,
    encode_hello,
    encode_paths,
    encode_robot,
    encode_robots,
)

WEB_DIR = Path(__file__).resolve().parent / "web"
HOST = "127.0.0.1"
DEFAULT_PORT = 8080
SEND_TIMEOUT_S = 5.0  # a browser that takes longer to take one message is dropped [s]


def check_port(port: int, host: str = HOST, flag: str = "--dashboard") -> None:
    """Check that ``host:port`` can be listened on now (``flag``'s validation).

    Raises:
        InputError: the port is taken or not allowed (one line naming ``flag``).
    """
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            why = {errno.EADDRINUSE: "is in use", errno.EACCES: "needs privileges"}.get(
                exc.errno, f"cannot be used ({exc.strerror})")
            raise InputError(f"{flag}: port {port} on {host} {why}") from None


def map_png(occ) -> tuple[bytes, dict]:
    """The occupancy map as a PNG (row 0 at the top) and its placement.

    Args:
        occ: :class:`swarm_scene.occupancy.OccupancyMap`.

    Returns:
        ``(png, info)``: the image (free white, occupied dark, unknown grey) and the ``map``
        entry of the ``hello`` message (``url``, ``resolution`` [m/cell], ``origin`` [x, y] [m]
        of the lower-left corner, ``width``, ``height`` [cells]).
    """
    from PIL import Image

    data = np.asarray(occ.data)
    img = np.full(data.shape, 205, dtype=np.uint8)
    img[data == 0] = 250
    img[data >= 50] = 40
    buf = io.BytesIO()
    Image.fromarray(img[::-1]).save(buf, format="PNG")
    info = {"url": "/map.png", "resolution": float(occ.resolution),
            "origin": [float(occ.origin[0]), float(occ.origin[1])],
            "width": int(data.shape[1]), "height": int(data.shape[0])}
    return buf.getvalue(), info


@dataclass(eq=False)
class Client:
    """One connected browser."""

    ws: object
    robot: str | None = None
    watch: frozenset[int] = frozenset()
    needs_all_paths: bool = True
    busy: bool = False
    sent_status: dict[int, int] = field(default_factory=dict)  # robot -> status version sent
    sent_scan: dict[int, int] = field(default_factory=dict)  # robot -> scan version sent
    frames: int = 0
    skipped: int = 0


class DashboardServer:
    """The web server (see the module docstring).

    Args:
        fleet: the fleet state, guarded by ``fleet_lock``.
        fleet_lock: the lock.
        recorder: the metrics recorder, guarded by ``recorder_lock``.
        recorder_lock: its lock.
        hello: :func:`~swarm_viz.fleet_view.encode_hello` arguments except ``robot``.
        png: the map image.
        ws_states: callable returning ``(workstation states, holding robots)`` (caller holds
            ``fleet_lock``).
        on_watch: called with the set of robot indices whose scans someone watches.
        on_demand: called with the number of connected browsers when it changes, and with
            None when ``/api/state`` is read (:meth:`swarm_viz.node.FleetNode.demand`).
        lidar_pose: (3,) lidar mount in base_footprint [m, rad]; or (N, 3), every robot's
            (a mixed fleet).
        port: TCP port on :data:`HOST`.
        cfg: the view's settings.
    """

    def __init__(self, *, fleet: FleetState, fleet_lock, recorder, recorder_lock, hello: dict,
                 png: bytes, ws_states, on_watch, lidar_pose, port: int,
                 cfg: ViewConfig | None = None, on_demand=None):
        self.fleet = fleet
        self.fleet_lock = fleet_lock
        self.recorder = recorder
        self.recorder_lock = recorder_lock
        self.hello = hello
        self.png = png
        self.ws_states = ws_states
        self.on_watch = on_watch
        self.on_demand = on_demand or (lambda browsers: None)
        self.lidar_pose = np.asarray(lidar_pose, dtype=float)
        self.port = port
        self.cfg = cfg = cfg or ViewConfig()
        self.kpi = KpiTracker(cfg)
        self.clients: set[Client] = set()
        self.frames_built = 0
        self._seq = 0
        self._sent_paths = np.zeros(len(fleet.robots), dtype=np.int64)
        self._watched: frozenset[int] = frozenset()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._runner = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._stop: asyncio.Event | None = None

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{HOST}:{self.port}/"

    # -- life cycle ----------------------------------------------------------------------------
    def start(self, timeout_s: float = 10.0) -> None:
        """Listen and serve in a background thread.

        Raises:
            InputError: the port cannot be listened on (names ``--dashboard``).
        """
        self._thread = threading.Thread(target=self._run, name="swarm_up_dashboard", daemon=True)
        self._thread.start()
        self._ready.wait(timeout_s)
        if self._error is not None:
            exc, self._error = self._error, None
            self._thread.join(timeout=2.0)
            if isinstance(exc, OSError):
                raise InputError(f"--dashboard: cannot listen on {HOST}:{self.port} "
                                 f"({exc.strerror})") from None
            raise exc

    def stop(self) -> None:
        """Close every connection and stop the server (idempotent)."""
        if self._loop is not None and self._stop is not None:
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported by start() (bind errors) or lost at exit
            self._error = exc
        finally:
            self._ready.set()
            with contextlib.suppress(Exception):
                loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _serve(self) -> None:
        from aiohttp import web

        self._stop = asyncio.Event()
        app = web.Application()
        app.router.add_get("/", self._page)
        app.router.add_get("/robot/{ns}", self._page)
        app.router.add_get("/map.png", self._map)
        app.router.add_get("/api/state", self._state)
        app.router.add_get("/ws", self._websocket)
        app.router.add_static("/static/", WEB_DIR, show_index=False)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False)
        await self._runner.setup()
        try:
            await web.TCPSite(self._runner, HOST, self.port, reuse_address=True).start()
            self._ready.set()
            broadcaster = asyncio.create_task(self._broadcast())
            await self._stop.wait()
            broadcaster.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await broadcaster
            for client in list(self.clients):
                with contextlib.suppress(Exception):
                    await client.ws.close()
        finally:
            await self._runner.cleanup()

    # -- HTTP ----------------------------------------------------------------------------------
    async def _page(self, request):
        from aiohttp import web

        ns = request.match_info.get("ns")
        if ns is not None and ns not in self.fleet.index:
            raise web.HTTPNotFound(text=f"no robot '{ns}' in this run\n")
        return web.FileResponse(WEB_DIR / "index.html",
                                headers={"Cache-Control": "no-cache"})

    async def _map(self, request):
        from aiohttp import web

        return web.Response(body=self.png, content_type="image/png")

    async def _state(self, request):
        """``/api/state``: the current frame with every plan, as JSON (and a demand for the
        poses and plans, which the next reads within ``idle_grace_s`` see updated)."""
        from aiohttp import web

        self.on_demand(None)
        frame = self._frame(all_paths=True)
        return web.json_response(frame)

    async def _websocket(self, request):
        from aiohttp import WSMsgType, web

        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=64 * 1024)
        await ws.prepare(request)
        robot = request.query.get("robot")
        client = Client(ws=ws, robot=robot if robot in self.fleet.index else None)
        self.clients.add(client)
        self.on_demand(len(self.clients))
        try:
            await ws.send_str(json.dumps(dict(encode_hello(**self.hello, robot=client.robot))))
            async for msg in ws:
                if msg.type == WSMsgType.TEXT:
                    self._on_request(client, msg.data)
                elif msg.type == WSMsgType.ERROR:
                    break
        finally:
            self.clients.discard(client)
            self._update_watch()
            self.on_demand(len(self.clients))
        return ws

    def _on_request(self, client: Client, text: str) -> None:
        try:
            req = json.loads(text)
            names = req.get("watch", []) if isinstance(req, dict) else []
        except (ValueError, AttributeError):
            return
        if not isinstance(names, list):
            return
        index = self.fleet.index
        client.watch = frozenset([index[n] for n in names if isinstance(n, str) and n in index]
                                 [:MAX_WATCH])
        client.sent_scan.clear()
        client.sent_status.clear()
        self._update_watch()

    def _update_watch(self) -> None:
        watched = frozenset().union(*(c.watch for c in self.clients))
        if watched != self._watched:
            self._watched = watched
            self.on_watch(watched)

    # -- frames --------------------------------------------------------------------------------
    def _frame(self, all_paths: bool) -> dict:
        """The next ``frame`` message; the changed plans (or all of them)."""
        with self.fleet_lock:
            fleet = self.fleet
            robots = encode_robots(fleet)
            ws_states, holding = self.ws_states()
            if all_paths:
                changed = range(len(fleet.robots))
            else:
                changed = np.flatnonzero(fleet.path_version != self._sent_paths).tolist()
                self._sent_paths = fleet.path_version.copy()
            paths = encode_paths(fleet, changed, self.cfg.path_decimals)
        with self.recorder_lock:
            kpi = self.kpi.figures(self.recorder, time.monotonic())
        self._seq += 1
        return {"type": "frame", "seq": self._seq, "kpi": kpi, "robots": robots,
                "ws": ws_states, "holding": holding, "paths": paths}

    async def _broadcast(self) -> None:
        loop = asyncio.get_running_loop()
        period = 1.0 / self.cfg.rate_hz
        due = loop.time()
        while True:
            due += period
            delay = due - loop.time()
            if delay < 0:  # fell behind: start again from now rather than burst
                due, delay = loop.time(), 0.0
            await asyncio.sleep(delay)
            if not self.clients:
                continue
            frame = self._frame(all_paths=False)
            self.frames_built += 1
            text = json.dumps(frame, separators=(",", ":"))
            full = None
            for client in list(self.clients):
                if client.busy:
                    client.skipped += 1
                    client.needs_all_paths = True
                    continue
                messages = []
                if client.needs_all_paths:
                    if full is None:
                        with self.fleet_lock:
                            all_paths = encode_paths(self.fleet, range(len(self.fleet.robots)),
                                                     self.cfg.path_decimals)
                        full = json.dumps(dict(frame, paths=all_paths), separators=(",", ":"))
                    messages.append(full)
                    client.needs_all_paths = False
                else:
                    messages.append(text)
                messages += self._robot_messages(client)
                client.busy = True
                asyncio.create_task(self._send(client, messages))

    def _robot_messages(self, client: Client) -> list[str]:
        out = []
        with self.fleet_lock:
            fleet = self.fleet
            for i in sorted(client.watch):
                sv, cv = int(fleet.status_version[i]), int(fleet.scan_version[i])
                if client.sent_status.get(i) == sv and client.sent_scan.get(i) == cv:
                    continue
                with_scan = client.sent_scan.get(i) != cv
                out.append(json.dumps(encode_robot(fleet, i, self.lidar_pose, with_scan),
                                      separators=(",", ":")))
                client.sent_status[i], client.sent_scan[i] = sv, cv
        return out

    async def _send(self, client: Client, messages: list[str]) -> None:
        try:
            async with asyncio.timeout(SEND_TIMEOUT_S):
                for text in messages:
                    await client.ws.send_str(text)
            client.frames += 1
        except (TimeoutError, ConnectionError, RuntimeError):
            self.clients.discard(client)
            with contextlib.suppress(Exception):
                await client.ws.close()
            self._update_watch()
        finally:
            client.busy = False


class LiveView:
    """The dashboard, the Foxglove server and/or ``/swarm/markers`` of one ``swarm-up`` run.

    Args:
        cfg: the run (:class:`swarm_up.args.RunConfig`; ``dashboard_port``, ``foxglove_port``,
            ``markers``).
        listener: the run's :class:`swarm_metrics.listener.MetricsListener`, not started yet.
        view: the view's settings.
    """

    def __init__(self, cfg, listener, view: ViewConfig | None = None):
        from swarm_scene.map_io import load_map
        from swarm_scene.poi import load_poi
        from swarm_scene.robot_model import load_robot

        self.cfg = cfg
        self.listener = listener
        self.view = view = view or ViewConfig()
        self.fleet = FleetState(cfg.robots)
        self.lock = threading.Lock()
        models = {name: load_robot(name) for name in dict.fromkeys(cfg.models)}
        robots = [models[name] for name in cfg.models]
        mixed = len(models) > 1
        # a mixed fleet: every robot's own outline and lidar mounting
        self.footprint = [r.footprint for r in robots] if mixed else robots[0].footprint
        self.lidar_pose = (np.array([r.lidar.pose for r in robots]) if mixed
                           else robots[0].lidar.pose)
        poi = load_poi(cfg.poi_path) if cfg.poi_path is not None else None
        self.workstations = poi.workstations if poi is not None else ()
        self.node = None
        self.server = None
        self.foxglove = None
        self._demand = {"dashboard": 0, "foxglove": 0}
        listener.attach(self._make_node, on_status=self._on_status)
        foxglove_port = getattr(cfg, "foxglove_port", None)
        occ = load_map(cfg.map_path) if (cfg.dashboard_port is not None
                                          or foxglove_port is not None) else None
        if foxglove_port is not None:
            from swarm_viz.foxglove_view import FoxgloveView

            self.foxglove = FoxgloveView(
                fleet=self.fleet, fleet_lock=self.lock, recorder=listener.recorder,
                recorder_lock=listener.lock, occ=occ, workstations=self.workstations,
                footprint=self.footprint, lidar_pose=self.lidar_pose,
                ws_states=self._ws_states, on_demand=self._on_foxglove_demand,
                on_watch=self._on_foxglove_watch, on_goal=self._on_goal,
                port=foxglove_port, cfg=view)
        self._watch = {"dashboard": frozenset(), "foxglove": frozenset()}
        if cfg.dashboard_port is not None:
            png, info = map_png(occ)
            hello = {"world": cfg.world_name, "robots": cfg.robots,
                     "footprint": robots[0].footprint,
                     "footprints": self.footprint if mixed else None,
                     "map_info": info, "workstations": self.workstations,
                     "rate_hz": view.rate_hz}
            self.server = DashboardServer(
                fleet=self.fleet, fleet_lock=self.lock, recorder=listener.recorder,
                recorder_lock=listener.lock, hello=hello, png=png,
                ws_states=self._ws_states, on_watch=self._on_watch,
                on_demand=self._on_dashboard_demand,
                lidar_pose=self.lidar_pose, port=cfg.dashboard_port, cfg=view)

    def _make_node(self, context):
        from swarm_viz.node import FleetNode

        self.node = FleetNode(self.fleet, self.lock, workstations=self.workstations,
                              footprint=self.footprint, markers=True, cfg=self.view,
                              context=context)
        return self.node

    def _on_status(self, ns: str, values: dict, message: str) -> None:
        if self.node is not None:
            self.node.on_status(ns, values, message)

    def _ws_states(self):
        if self.node is None:
            return ["free"] * len(self.workstations), []
        return self.node.workstation_states()

    def _on_watch(self, indices: frozenset[int], who: str = "dashboard") -> None:
        self._watch[who] = frozenset(indices)
        both = self._watch["dashboard"] | self._watch["foxglove"]
        self.listener.call_soon(lambda: self.node is not None and self.node.watch(both))

    def _on_foxglove_watch(self, indices: frozenset[int]) -> None:
        self._on_watch(indices, "foxglove")

    def _on_dashboard_demand(self, browsers: int | None) -> None:
        if browsers is not None:
            self._demand["dashboard"] = browsers
        self._on_demand(None if browsers is None else sum(self._demand.values()))

    def _on_foxglove_demand(self, clients: int) -> None:
        self._demand["foxglove"] = clients
        self._on_demand(sum(self._demand.values()))

    def _on_demand(self, viewers: int | None) -> None:
        self.listener.call_soon(lambda: self.node is not None and self.node.demand(viewers))

    def _on_goal(self, ns: str, x: float, y: float, yaw: float, frame: str) -> None:
        self.listener.call_soon(
            lambda: self.node is not None and self.node.publish_goal(ns, x, y, yaw, frame))

    def start(self) -> str | None:
        """Start the web server (after the listener started); returns its URL, or None.

        Raises:
            InputError: the port cannot be listened on.
        """
        if self.foxglove is not None:
            try:
                self.foxglove.start()
            except (OSError, RuntimeError) as exc:
                raise InputError(f"--foxglove: port {self.foxglove.port} on {HOST} cannot be "
                                 f"used ({exc})") from None
        if self.server is None:
            return None
        self.server.start()
        return self.server.url

    def stop(self) -> None:
        """Stop the web server and the Foxglove server (the node stops with the listener)."""
        if self.server is not None:
            self.server.stop()
        if self.foxglove is not None:
            self.foxglove.stop()
