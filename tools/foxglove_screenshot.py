"""A screenshot of a live run in Foxglove Studio, the real client, in headless Chromium.

    python tools/foxglove_screenshot.py                       # docs/guides/img/foxglove_live.png
    python tools/foxglove_screenshot.py --swarm-size 20 --sim-seconds 180 --out shot.png

The client is Foxglove Studio 1.48.0, the last open-source release of the app, whose core
npm publishes built (``@foxglove/studio-base``: the whole app, React left to the page); the
page ``tools/foxglove_screenshot/index.html`` mounts it with ``docs/foxglove_layout.json`` as its
only layout and the Foxglove WebSocket data source, as the app's own web build does. This script
fetches the packages once (``npm pack``, into ``--cache``), serves the page, starts
``swarm-up --foxglove`` on the bundled default world, opens the page in headless Chromium over the
DevTools protocol once the run is up, and saves a screenshot after ``--sim-seconds`` simulated
seconds.

Two things stand between Studio 1.48 and a current server, and both are bridged here, not in the
product: Studio asks for the WebSocket subprotocol under its old name, ``foxglove.websocket.v1``,
while ``foxglove-sdk`` servers accept only ``foxglove.sdk.v1`` (the same protocol renamed:
Foxglove's discussion 1131; Lichtblick accepts both since its PR 819), so the page connects
through a relay that renames it (:func:`relay`); and Studio 1.48 registers the Log panel under its
older type name, ``RosOut`` (the page renames the layout's ``Log!`` panel). A current Foxglove app
or Lichtblick connects to ``swarm-up --foxglove`` directly.

Needs ``npm`` and ``chromium`` (Debian's); ``aiohttp`` is a dependency of the workbench. Exit 2
with one line when one is missing; the run's own output goes to ``RUN_DIR/swarm-up.log``.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import contextlib
import functools
import http.server
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tarfile
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "tools" / "foxglove_screenshot" / "index.html"
LAYOUT = ROOT / "docs" / "foxglove_layout.json"
PACKAGES = ("@foxglove/studio-base@1.48.0", "react@17.0.2", "react-dom@17.0.2")
OLD_SUBPROTOCOL, NEW_SUBPROTOCOL = "foxglove.websocket.v1", "foxglove.sdk.v1"
PROGRESS = re.compile(r"t = ([0-9.]+) / ")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="foxglove_screenshot.py",
        description="Run swarm-up --foxglove and save a screenshot of Foxglove Studio 1.48 (the "
        "open-source app, from npm) showing it live, with docs/foxglove_layout.json.")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "guides" / "img" /
                   "foxglove_live.png", help="the PNG [docs/guides/img/foxglove_live.png]")
    p.add_argument("--swarm-size", type=int, default=10, help="robots [10]")
    p.add_argument("--sim-seconds", type=float, default=120.0,
                   help="simulated seconds before the screenshot [120]")
    p.add_argument("--rtf", type=float, default=1.0, help="swarm-up --rtf [1]")
    p.add_argument("--port", type=int, default=8765, help="swarm-up --foxglove PORT [8765]")
    p.add_argument("--size", default="1920,1080", help="window WIDTH,HEIGHT [1920,1080]")
    p.add_argument("--cache", type=Path,
                   default=Path.home() / ".cache" / "swarm-workbench" / "foxglove-studio-1.48.0",
                   help="where the npm packages are kept")
    p.add_argument("--chromium", default="chromium", help="the browser [chromium]")
    return p


def fail(message: str) -> None:
    print(f"foxglove_screenshot.py: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def site(cache: Path) -> Path:
    """The served directory: Studio's assets, React's UMD builds, the page and the layout."""
    root = cache / "site"
    if not (root / "assets" / "index.js").exists():
        if shutil.which("npm") is None:
            fail("npm not found: it fetches @foxglove/studio-base (apt install npm)")
        cache.mkdir(parents=True, exist_ok=True)
        print(f"fetching {', '.join(PACKAGES)} into {cache}", flush=True)
        subprocess.run(["npm", "pack", "--silent", *PACKAGES], cwd=cache, check=True,
                       stdout=subprocess.DEVNULL)
        unpacked = cache / "unpacked"
        for name, tgz in (("studio-base", "foxglove-studio-base-1.48.0.tgz"),
                          ("react", "react-17.0.2.tgz"), ("react-dom", "react-dom-17.0.2.tgz")):
            with tarfile.open(cache / tgz) as tar:
                tar.extractall(unpacked / name, filter="data")
        root.mkdir(exist_ok=True)
        shutil.copytree(unpacked / "studio-base" / "package" / "assets", root / "assets",
                        dirs_exist_ok=True)
        shutil.copy(unpacked / "react" / "package" / "umd" / "react.production.min.js", root)
        shutil.copy(unpacked / "react-dom" / "package" / "umd" / "react-dom.production.min.js",
                    root)
    shutil.copy(PAGE, root / "index.html")
    shutil.copy(LAYOUT, root / "foxglove_layout.json")
    return root


def serve(directory: Path) -> int:
    """Serve ``directory`` on a free local port (a daemon thread); returns the port."""
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Quiet, directory=str(directory)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server.server_address[1]


async def relay(upstream: str):
    """A WebSocket relay on a free local port that accepts Studio 1.48's subprotocol name and
    speaks the new one upstream, passing every frame unchanged; returns (runner, port)."""
    import aiohttp
    from aiohttp import web

    async def handle(request):
        client = web.WebSocketResponse(protocols=(OLD_SUBPROTOCOL,), max_msg_size=0)
        await client.prepare(request)
        async with aiohttp.ClientSession() as session, session.ws_connect(
                upstream, protocols=(NEW_SUBPROTOCOL,), max_msg_size=0) as server:
            async def pump(src, dst):
                async for msg in src:
                    if msg.type == aiohttp.WSMsgType.TEXT:
                        await dst.send_str(msg.data)
                    elif msg.type == aiohttp.WSMsgType.BINARY:
                        await dst.send_bytes(msg.data)
                    else:
                        break
                await dst.close()

            await asyncio.gather(pump(client, server), pump(server, client),
                                 return_exceptions=True)
        return client

    app = web.Application()
    app.router.add_get("/", handle)
    runner = web.AppRunner(app)
    await runner.setup()
    site_ = web.TCPSite(runner, "127.0.0.1", 0)
    await site_.start()
    return runner, site_._server.sockets[0].getsockname()[1]


class Run:
    """``swarm-up --foxglove`` in its own process group; follows its simulated time."""

    def __init__(self, args, run_dir: Path):
        exe = Path(sys.executable).parent / "swarm-up"
        if not exe.exists():
            fail(f"{exe} not found: install the workbench (pip install -e .) in this Python")
        self.log = run_dir / "swarm-up.log"
        self.fh = open(self.log, "w")  # noqa: SIM115 - closed by stop()
        self.proc = subprocess.Popen(
            [str(exe), "--swarm-size", str(args.swarm_size), "--commanders", "--rtf",
             str(args.rtf), "--duration", str(args.sim_seconds + 600), "--foxglove",
             str(args.port), "--run-dir", str(run_dir / "run")],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
        self.sim_t = 0.0
        self.serving = threading.Event()
        threading.Thread(target=self._follow, daemon=True).start()

    def _follow(self):
        for line in self.proc.stdout:
            self.fh.write(line)
            self.fh.flush()
            if "foxglove: ws://" in line:
                self.serving.set()
            m = PROGRESS.search(line)
            if m:
                self.sim_t = float(m.group(1))

    def stop(self):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGINT)
        try:
            self.proc.wait(60)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)
        self.fh.close()


async def screenshot(args, url: str, run: Run) -> bytes:
    """Open ``url`` in headless Chromium and capture it once ``run`` is ``--sim-seconds`` in."""
    import aiohttp

    width, height = (int(v) for v in args.size.split(","))
    profile = tempfile.mkdtemp(prefix="foxglove-shot-")
    chrome = subprocess.Popen(
        [args.chromium, "--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
         "--enable-unsafe-swiftshader", f"--window-size={width},{height}",
         "--remote-debugging-port=0", f"--user-data-dir={profile}", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        port_file = Path(profile) / "DevToolsActivePort"
        deadline = time.monotonic() + 60
        while not port_file.exists() or not port_file.read_text().strip():
            if time.monotonic() > deadline or chrome.poll() is not None:
                fail(f"{args.chromium} did not start its DevTools server")
            await asyncio.sleep(0.2)
        port = int(port_file.read_text().split()[0])
        async with aiohttp.ClientSession() as session:
            async with session.get(f"http://127.0.0.1:{port}/json/list") as r:
                page = next(t for t in await r.json() if t["type"] == "page")
            async with session.ws_connect(page["webSocketDebuggerUrl"], max_msg_size=0) as ws:
                ids = iter(range(1, 1 << 30))

                async def call(method, **params):
                    mid = next(ids)
                    await ws.send_json({"id": mid, "method": method, "params": params})
                    async for msg in ws:
                        d = json.loads(msg.data)
                        if d.get("id") == mid:
                            if "error" in d:
                                raise RuntimeError(f"{method}: {d['error']}")
                            return d.get("result", {})
                    raise RuntimeError("Chromium closed the DevTools connection")

                await call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                           deviceScaleFactor=1, mobile=False)
                await call("Page.navigate", url=url)
                while run.sim_t < args.sim_seconds:
                    if run.proc.poll() is not None:
                        fail(f"swarm-up exited with {run.proc.returncode}: see {run.log}")
                    await call("Runtime.evaluate", expression="1")  # keep the page served
                    await asyncio.sleep(1.0)
                # the 3D panel's first-use tip covers its corner: close it
                await call("Runtime.evaluate", expression="""
                    for (const el of document.querySelectorAll('*')) {
                      if (el.childElementCount === 0 &&
                          (el.textContent || '').startsWith('Open settings to configure')) {
                        const box = el.closest('div');
                        const button = box && box.parentElement &&
                                       box.parentElement.querySelector('button');
                        if (button) button.click();
                      }
                    }""")
                await asyncio.sleep(1.0)
                shot = await call("Page.captureScreenshot", format="png")
                return base64.b64decode(shot["data"])
    finally:
        chrome.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            chrome.wait(10)
        shutil.rmtree(profile, ignore_errors=True)


async def main_async(args) -> int:
    if shutil.which(args.chromium) is None:
        fail(f"--chromium {args.chromium}: not found (apt install chromium)")
    root = site(args.cache)
    http_port = serve(root)
    runner, relay_port = await relay(f"ws://127.0.0.1:{args.port}")
    run_dir = Path(tempfile.mkdtemp(prefix="foxglove-run-"))
    print(f"starting swarm-up --foxglove {args.port} ({args.swarm_size} robots); log "
          f"{run_dir / 'swarm-up.log'}", flush=True)
    run = Run(args, run_dir)
    try:
        while not run.serving.wait(1.0):
            if run.proc.poll() is not None:
                fail(f"swarm-up exited with {run.proc.returncode}: see {run.log}")
        url = (f"http://127.0.0.1:{http_port}/index.html?ds=foxglove-websocket"
               f"&ds.url=ws://127.0.0.1:{relay_port}&layoutId=swarm")
        print(f"opening Foxglove Studio 1.48 on it: {url}", flush=True)
        png = await screenshot(args, url, run)
    finally:
        run.stop()
        await runner.cleanup()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(png)
    print(f"wrote {args.out} ({len(png) // 1024} KiB) at t = {run.sim_t:.0f} s simulated",
          flush=True)
    return 0


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        _width, _height = (int(v) for v in args.size.split(","))
    except ValueError:
        fail(f"--size {args.size}: expected WIDTH,HEIGHT in pixels")
    if args.swarm_size < 1 or args.sim_seconds <= 0 or args.rtf <= 0:
        fail("--swarm-size, --sim-seconds and --rtf must be positive")
    return asyncio.run(main_async(args))


if __name__ == "__main__":
    sys.exit(main())
