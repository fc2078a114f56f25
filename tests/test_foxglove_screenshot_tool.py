"""``tools/foxglove_screenshot.py``: its relay between Foxglove Studio 1.48 and a current server,
and its bad input. (The screenshot itself needs npm and Chromium: made by hand, for the guide.)"""

from __future__ import annotations

import asyncio
import subprocess
import sys

import aiohttp
import pytest
from aiohttp import web

from swarm_common.paths import ROOT
from tests.support.tools import load_tool

SCRIPT = ROOT / "tools" / "foxglove_screenshot.py"


def _tool():
    return load_tool("foxglove_screenshot")


def test_the_relay_renames_the_subprotocol_and_passes_frames_unchanged():
    tool = _tool()

    async def scenario():
        seen = []

        async def upstream(request):  # a server that, like foxglove-sdk's, knows the new name only
            ws = web.WebSocketResponse(protocols=(tool.NEW_SUBPROTOCOL,))
            await ws.prepare(request)
            seen.append(ws.ws_protocol)
            async for msg in ws:
                if msg.type == aiohttp.WSMsgType.TEXT:
                    await ws.send_str(msg.data.upper())
                elif msg.type == aiohttp.WSMsgType.BINARY:
                    await ws.send_bytes(msg.data[::-1])
            return ws

        app = web.Application()
        app.router.add_get("/", upstream)
        runner = web.AppRunner(app)
        await runner.setup()
        site = web.TCPSite(runner, "127.0.0.1", 0)
        await site.start()
        port = site._server.sockets[0].getsockname()[1]
        relay, relay_port = await tool.relay(f"ws://127.0.0.1:{port}")
        try:
            async with aiohttp.ClientSession() as s, s.ws_connect(
                    f"ws://127.0.0.1:{relay_port}", protocols=(tool.OLD_SUBPROTOCOL,)) as ws:
                assert ws.protocol == tool.OLD_SUBPROTOCOL
                await ws.send_str('{"op": "subscribe"}')
                assert (await ws.receive(timeout=10)).data == '{"OP": "SUBSCRIBE"}'
                await ws.send_bytes(b"\x01\x02\x03")
                assert (await ws.receive(timeout=10)).data == b"\x03\x02\x01"
        finally:
            await relay.cleanup()
            await runner.cleanup()
        assert seen == [tool.NEW_SUBPROTOCOL]

    asyncio.run(scenario())


@pytest.mark.parametrize(("args", "flag"), [(["--size", "wide"], "--size"),
                                            (["--swarm-size", "0"], "--swarm-size")])
def test_bad_input_exits_2_with_one_line(args, flag):
    res = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 2
    assert flag in res.stderr and len(res.stderr.strip().splitlines()) == 1, res.stderr
