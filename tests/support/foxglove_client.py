"""A minimal client of the Foxglove WebSocket protocol (``foxglove.sdk.v1``, the same protocol as
``foxglove.websocket.v1`` under the name foxglove-sdk servers accept), for tests:
written from the protocol's specification (https://github.com/foxglove/ws-protocol), with
``aiohttp`` for the socket and ``protobuf`` to decode messages by the schemas the server
advertises, so the server's own code is not used to read it."""

from __future__ import annotations

import asyncio
import base64
import json
import struct
from collections import defaultdict

import aiohttp
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01  # server -> client binary opcodes
TIME = 0x02
CLIENT_MESSAGE_DATA = 0x01  # client -> server


class FoxgloveClient:
    """Connects, keeps the advertised channels, subscribes and collects decoded messages.

    Attributes:
        info: the ``serverInfo`` message.
        channels: topic -> the advertised channel (``id``, ``encoding``, ``schemaName``, ...).
        messages: topic -> [(log time [ns], decoded message: a protobuf message or a dict)].
        times: every ``time`` the server broadcast [ns].
    """

    def __init__(self, url: str):
        self.url = url
        self.info: dict = {}
        self.channels: dict[str, dict] = {}
        self.messages: dict[str, list] = defaultdict(list)
        self.times: list[int] = []
        self._subs: dict[int, str] = {}
        self._classes: dict[str, type] = {}
        self._session = None
        self.ws = None
        self._reader = None

    async def connect(self, timeout: float = 30.0) -> None:
        self._session = aiohttp.ClientSession()
        self.ws = await self._session.ws_connect(self.url, protocols=(SUBPROTOCOL,))
        self._reader = asyncio.create_task(self._read())
        async with asyncio.timeout(timeout):
            while not self.info or not self.channels:
                await asyncio.sleep(0.05)

    async def close(self) -> None:
        if self.ws is not None:
            await self.ws.close()
        if self._reader is not None:
            self._reader.cancel()
        if self._session is not None:
            await self._session.close()

    async def subscribe(self, topics) -> None:
        subs = []
        for topic in topics:
            sub_id = len(self._subs) + 1
            self._subs[sub_id] = topic
            subs.append({"id": sub_id, "channelId": self.channels[topic]["id"]})
        await self.ws.send_str(json.dumps({"op": "subscribe", "subscriptions": subs}))

    async def advertise(self, channel_id: int, topic: str, schema_name: str) -> None:
        await self.ws.send_str(json.dumps({"op": "advertise", "channels": [{
            "id": channel_id, "topic": topic, "encoding": "json", "schemaName": schema_name}]}))

    async def publish(self, channel_id: int, message: dict) -> None:
        await self.ws.send_bytes(struct.pack("<BI", CLIENT_MESSAGE_DATA, channel_id)
                                 + json.dumps(message).encode())

    async def wait_for(self, predicate, timeout: float) -> None:
        async with asyncio.timeout(timeout):
            while not predicate():
                await asyncio.sleep(0.05)

    def _decode(self, channel: dict, payload: bytes):
        if channel["encoding"] == "json":
            return json.loads(payload)
        assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
        name = channel["schemaName"]
        cls = self._classes.get(name)
        if cls is None:
            fds = descriptor_pb2.FileDescriptorSet.FromString(
                base64.b64decode(channel["schema"]))
            pool = descriptor_pool.DescriptorPool()
            for f in fds.file:
                pool.Add(f)
            cls = self._classes[name] = message_factory.GetMessageClass(
                pool.FindMessageTypeByName(name))
        return cls.FromString(payload)

    async def _read(self) -> None:
        async for msg in self.ws:
            if msg.type == aiohttp.WSMsgType.TEXT:
                data = json.loads(msg.data)
                if data["op"] == "serverInfo":
                    self.info = data
                elif data["op"] == "advertise":
                    for ch in data["channels"]:
                        self.channels[ch["topic"]] = ch
            elif msg.type == aiohttp.WSMsgType.BINARY:
                raw = msg.data
                if raw[0] == MESSAGE_DATA:
                    sub_id, log_time = struct.unpack_from("<IQ", raw, 1)
                    topic = self._subs.get(sub_id)
                    if topic is not None:
                        self.messages[topic].append(
                            (log_time, self._decode(self.channels[topic], raw[13:])))
                elif raw[0] == TIME:
                    self.times.append(struct.unpack_from("<Q", raw, 1)[0])
