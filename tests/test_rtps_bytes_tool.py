"""``tools/rtps_bytes.py``: bytes on the wire by topic, from a capture it has never seen."""

from __future__ import annotations

import struct
import subprocess
import sys

import dpkt
import pytest

from swarm_common.paths import ROOT
from tests.support.tools import load_tool

SCRIPT = ROOT / "tools" / "rtps_bytes.py"
HERE, THERE = "10.0.0.2", "10.0.0.1"
PREFIX_THERE, PREFIX_HERE = bytes(range(1, 13)), bytes(range(21, 33))
WRITER = b"\x00\x00\x12\x03"  # a user writer's entity id
MTU = 1500


@pytest.fixture(scope="module")
def tool():
    return load_tool("rtps_bytes")


def _rtps(prefix: bytes, *subs: bytes) -> bytes:
    return b"RTPS\x02\x03\x01\x0f" + prefix + b"".join(subs)


def _sub(sid: int, body: bytes, flags: int = 0x01) -> bytes:
    return struct.pack("<BBH", sid, flags, len(body)) + body


def _data(writer: bytes, payload: bytes, seq: int = 1) -> bytes:
    # extraFlags, octetsToInlineQos (16), readerId, writerId, writerSN, then the payload
    body = struct.pack("<HH", 0, 16) + bytes(4) + writer + struct.pack("<iI", 0, seq) + payload
    return _sub(0x15, body, flags=0x01 | 0x04)


def _sedp_publication(guid: bytes, topic: str) -> bytes:
    name = topic.encode() + b"\0"
    name_param = struct.pack("<I", len(name)) + name
    name_param += bytes(-len(name_param) % 4)
    params = (struct.pack("<HH", 0x005A, 16) + guid
              + struct.pack("<HH", 0x0005, len(name_param)) + name_param
              + struct.pack("<HH", 0x0001, 0))
    return _data(b"\x00\x00\x03\xc2", b"\x00\x03\x00\x00" + params)


def _frames(src: str, dst: str, rtps: bytes, ident: int) -> list[bytes]:
    """Ethernet frames of one UDP datagram, IP-fragmented at the MTU as Linux does it."""
    udp = dpkt.udp.UDP(sport=7400, dport=7411, data=rtps)
    udp.ulen = len(udp)
    whole = bytes(udp)
    step = (MTU - 20) // 8 * 8
    frames = []
    for off in range(0, len(whole), step):
        piece = whole[off:off + step]
        ip = dpkt.ip.IP(src=bytes(map(int, src.split("."))), dst=bytes(map(int, dst.split("."))),
                        p=dpkt.ip.IP_PROTO_UDP, id=ident, data=piece)
        ip.mf = int(off + step < len(whole))
        ip.offset = off // 8
        ip.len = 20 + len(piece)
        frames.append(bytes(dpkt.ethernet.Ethernet(src=b"\x02" * 6, dst=b"\x04" * 6,
                                                   type=dpkt.ethernet.ETH_TYPE_IP, data=ip)))
    return frames


def test_bytes_are_charged_to_the_topics_discovery_named(tool, tmp_path):
    guid = PREFIX_THERE + WRITER
    scan = b"\x00\x01\x00\x00" + bytes(3996)  # a 4 KB sample: three IP fragments
    acknack = _sub(0x06, bytes(4) + WRITER + struct.pack("<iII", 0, 2, 0) + struct.pack("<i", 1))
    datagrams = [  # (time, from, to, RTPS message)
        (1.0, THERE, HERE, _rtps(PREFIX_THERE, _sedp_publication(guid, "rt/Srobot7/scan"))),
        (2.0, THERE, HERE, _rtps(PREFIX_THERE, _data(WRITER, scan))),
        (2.5, HERE, THERE, _rtps(PREFIX_HERE, _sub(0x0E, PREFIX_THERE), acknack)),
        (3.0, THERE, HERE, _rtps(PREFIX_THERE, _data(b"\x00\x00\x99\x03", bytes(100)))),
    ]
    pcap = tmp_path / "capture.pcap"
    with pcap.open("wb") as f:
        writer = dpkt.pcap.Writer(f)
        for i, (ts, src, dst, msg) in enumerate(datagrams):
            for frame in _frames(src, dst, msg, 100 + i):
                writer.writepkt(frame, ts=ts)
    r = tool.read(pcap, HERE, after=1.5)
    wire = {i: sum(len(fr) for fr in _frames(s, d, m, 100 + i))
            for i, (_, s, d, m) in enumerate(datagrams)}
    assert r.bytes[("/*/scan", "in")] == pytest.approx(wire[1])  # all three fragments
    assert r.bytes[("/*/scan", "out")] == pytest.approx(wire[2])  # the reader's ACKNACK
    assert r.bytes[("[unknown]", "in")] == pytest.approx(wire[3])  # never announced
    assert ("[SEDP]", "in") not in r.bytes  # before --after: learnt, not counted
    assert r.messages[("/*/scan", "in")] == 1


def test_counting_ends_at_the_last_clock_and_spans_its_simulated_time(tool, tmp_path):
    clock = PREFIX_THERE + b"\x00\x00\x07\x03"
    stamp = b"\x00\x01\x00\x00" + struct.pack("<iI", 12, 500_000_000)
    datagrams = [
        (1.0, _rtps(PREFIX_THERE, _sedp_publication(clock, "rt/clock"))),
        (2.0, _rtps(PREFIX_THERE, _data(b"\x00\x00\x07\x03", b"\x00\x01\x00\x00"
                                         + struct.pack("<iI", 10, 0)))),
        (3.0, _rtps(PREFIX_THERE, _data(b"\x00\x00\x07\x03", stamp, seq=2))),
        (4.0, _rtps(PREFIX_THERE, _data(b"\x00\x00\x99\x03", bytes(100)))),  # the shutdown
    ]
    pcap = tmp_path / "capture.pcap"
    with pcap.open("wb") as f:
        writer = dpkt.pcap.Writer(f)
        for i, (ts, msg) in enumerate(datagrams):
            for frame in _frames(THERE, HERE, msg, i):
                writer.writepkt(frame, ts=ts)
    r = tool.read(pcap, HERE, after=None)
    assert r.clock == [10.0, 12.5]
    assert ("[unknown]", "in") not in r.bytes
    assert r.messages[("/clock", "in")] == 2


def test_a_missing_capture_is_one_line_and_exit_2(tmp_path):
    out = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path / "none.pcap"),
                          "--local", HERE], capture_output=True, text=True)
    assert out.returncode == 2
    assert out.stderr.strip() == f"rtps_bytes: {tmp_path / 'none.pcap'}: no such file"
