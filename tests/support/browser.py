"""Headless Chromium driven over the DevTools protocol (for the dashboard's tests and probes).

Chromium (Debian package ``chromium``) is started with ``--headless --no-sandbox --disable-gpu``
and ``--remote-debugging-port=0``; the port it chose is read from ``DevToolsActivePort`` in its
profile directory.  :meth:`Chromium.evaluate` runs a JavaScript expression in the page and
returns its value (``Runtime.evaluate`` with ``returnByValue``); :meth:`Chromium.screenshot`
writes a PNG (``Page.captureScreenshot``).  The DevTools WebSocket is spoken with aiohttp's
client, the library the dashboard is served with.

The browser runs with the priority a desktop user's browser has.  Started as root (as in CI),
Chromium raises its browser and GPU processes to nice -8 (its "display critical" threads), ahead
of the simulation it watches on the same cores, which an unprivileged user's browser cannot do;
so as root it is started through util-linux's ``setpriv`` without ``CAP_SYS_NICE``, where that
is available, and stays at nice 0.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """The Chromium executable on PATH, or None."""
    for name in CANDIDATES:
        found = shutil.which(name)
        if found:
            return found
    return None


def require_chromium() -> str:
    """The Chromium executable; without one, a test failure under ``CI=true``, else a skip."""
    import pytest

    found = find_chromium()
    if found:
        return found
    why = ("no headless browser: install Debian's 'chromium' (apt-get install -y chromium); "
           ".ci/run does")
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(why)
    pytest.skip(why)


def _user_priority() -> list[str]:
    """The prefix that starts a program without the right to raise its priority (as root)."""
    setpriv = shutil.which("setpriv")
    if os.geteuid() != 0 or setpriv is None:
        return []
    return [setpriv, "--bounding-set", "-sys_nice"]


class Chromium:
    """One headless Chromium showing ``url``; use as a context manager.

    Args:
        url: the page to open.
        size: window size [px] (width, height).
        exe: the browser (default: :func:`find_chromium`).
    """

    def __init__(self, url: str, size: tuple[int, int] = (1400, 900), exe: str | None = None):
        self.exe = exe or find_chromium()
        if self.exe is None:
            raise FileNotFoundError("chromium not found")
        self._profile = tempfile.TemporaryDirectory(prefix="swarm_wb_chromium_")
        self._log = open(Path(self._profile.name) / "chromium.log", "wb")  # noqa: SIM115
        # Chromium makes its singleton socket's directory under TMPDIR and leaves it behind when
        # stopped by a signal: keep it in the profile, which close() removes.
        tmp = Path(self._profile.name) / "tmp"
        tmp.mkdir()
        self.proc = subprocess.Popen(
            [*_user_priority(), self.exe, "--headless", "--no-sandbox", "--disable-gpu",
             "--no-first-run", "--no-default-browser-check", "--disable-extensions",
             "--mute-audio", "--remote-debugging-port=0", "--remote-allow-origins=*",
             f"--user-data-dir={self._profile.name}", f"--window-size={size[0]},{size[1]}",
             url],
            stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
            start_new_session=True, env={**os.environ, "TMPDIR": str(tmp)})
        self.port = self._devtools_port(timeout=30.0)
        self._page_ws: str | None = None

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _devtools_port(self, timeout: float) -> int:
        active = Path(self._profile.name) / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"chromium exited with code {self.proc.returncode}: "
                                   f"{self.log()[-2000:]}")
            with contextlib.suppress(OSError, ValueError, IndexError):
                return int(active.read_text().split()[0])
            time.sleep(0.1)
        raise RuntimeError(f"chromium gave no DevTools port in {timeout} s: {self.log()[-2000:]}")

    def log(self) -> str:
        """What the browser printed."""
        self._log.flush()
        return (Path(self._profile.name) / "chromium.log").read_text(errors="replace")

    async def _page_socket(self, session) -> str:
        if self._page_ws is None:
            async with session.get(f"http://127.0.0.1:{self.port}/json/list") as resp:
                targets = await resp.json(content_type=None)
            pages = [t for t in targets if t.get("type") == "page"]
            if not pages:
                raise RuntimeError(f"no page target in {targets}")
            self._page_ws = pages[0]["webSocketDebuggerUrl"]
        return self._page_ws

    async def _call(self, method: str, params: dict, timeout: float) -> dict:
        import aiohttp

        async with aiohttp.ClientSession() as session:
            url = await self._page_socket(session)
            async with session.ws_connect(url, max_msg_size=0) as ws:
                await ws.send_str(json.dumps({"id": 1, "method": method, "params": params}))
                async with asyncio.timeout(timeout):
                    async for msg in ws:
                        data = json.loads(msg.data)
                        if data.get("id") == 1:
                            if "error" in data:
                                raise RuntimeError(f"{method}: {data['error']}")
                            return data["result"]
        raise RuntimeError(f"{method}: no answer")

    def call(self, method: str, params: dict | None = None, timeout: float = 20.0) -> dict:
        """One DevTools command on the page; its ``result``."""
        return asyncio.run(self._call(method, params or {}, timeout))

    def evaluate(self, expression: str, timeout: float = 20.0):
        """The value of a JavaScript expression in the page (JSON-serialisable).

        Raises:
            RuntimeError: the expression threw.
        """
        result = self.call("Runtime.evaluate", {"expression": expression,
                                                "returnByValue": True}, timeout)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout: float, poll_s: float = 0.25):
        """Evaluate ``expression`` until it is truthy; its value. AssertionError on timeout."""
        deadline = time.monotonic() + timeout
        value = None
        while time.monotonic() < deadline:
            with contextlib.suppress(RuntimeError):
                value = self.evaluate(expression)
                if value:
                    return value
            time.sleep(poll_s)
        raise AssertionError(f"timed out after {timeout} s waiting for {expression} "
                             f"(last value {value!r})")

    def screenshot(self, path: Path) -> Path:
        """Write the page as a PNG."""
        data = self.call("Page.captureScreenshot", {"format": "png"})["data"]
        path = Path(path)
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self) -> None:
        """Stop the browser and remove its profile (idempotent)."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(2.0)
        if not self._log.closed:
            self._log.close()
        with contextlib.suppress(OSError):
            self._profile.cleanup()
