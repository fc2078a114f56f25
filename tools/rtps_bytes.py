"""What crosses between hosts, by topic: bytes on the wire from a packet capture of a run's RTPS.

Reads a pcap written by ``tcpdump -i eth0 -w FILE`` on one host of a several-host run (for
instance ``python tools/host_traffic.py --pcap FILE``), puts IPv4 fragments back together, reads
each UDP datagram's RTPS messages (the OMG DDSI-RTPS 2.3 wire format: a 20-byte header, then
submessages of a 4-byte header each) and charges every datagram's bytes on the wire (IP and UDP
headers included) to the topics of its submessages, in proportion to their lengths. A data
submessage (``DATA``, ``DATA_FRAG``) or a ``HEARTBEAT``/``GAP`` belongs to its writer; an
``ACKNACK``/``NACK_FRAG`` to the writer it answers. The writers' topics come from the
capture's own discovery (the publications' ``PID_TOPIC_NAME`` and ``PID_ENDPOINT_GUID`` in
their SEDP data, DDSI-RTPS 2.3 section 9.6.2.2); the built-in endpoints are named by their
entity id (``[SPDP]``, ``[SEDP]``, ``[liveliness]``), a writer never announced in the capture
``[unknown]``. Robot topics (``rt/Srobot7/scan``) are merged as ``/*/scan``.

Usage::

    python tools/rtps_bytes.py CAPTURE.pcap --local 10.231.240.2 [--after UNIX_S]
        [--sim-s S --robots N] [--json OUT]

``--local`` is the capturing host's address: traffic from it is "out", to it "in".
"""

from __future__ import annotations

import argparse
import json
import re
import struct
import sys
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

import dpkt

BUILTIN = {0x000100C2: "[SPDP]", 0x000003C2: "[SEDP]", 0x000004C2: "[SEDP]",
           0x000200C2: "[liveliness]", 0x000300C3: "[type lookup]", 0x000301C3: "[type lookup]"}
# submessage ids (DDSI-RTPS 2.3 table 8.13)
ACKNACK, HEARTBEAT, GAP, INFO_SRC, INFO_DST = 0x06, 0x07, 0x08, 0x0C, 0x0E
NACK_FRAG, HEARTBEAT_FRAG, DATA, DATA_FRAG = 0x12, 0x13, 0x15, 0x16
PID_SENTINEL, PID_TOPIC_NAME, PID_ENDPOINT_GUID = 0x0001, 0x0005, 0x005A
ROBOT_TOPIC = re.compile(r"^rt/[A-Za-z]+\d+/")


def topic_key(name: str) -> str:
    """``rt/Srobot7/scan`` -> ``/*/scan``; ``rt/clock`` -> ``/clock``; ``rq/...`` kept."""
    name = ROBOT_TOPIC.sub("/*/", name)
    return name[2:] if name.startswith("rt/") else name


def sedp_endpoint(payload: bytes) -> tuple[bytes, str] | None:
    """(GUID, topic name) of a SEDP publication or subscription (a parameter list), or None."""
    if len(payload) < 4:
        return None
    little = payload[1] in (0x01, 0x03)  # CDR_LE / PL_CDR_LE
    end = "<" if little else ">"
    i, guid, topic = 4, None, None
    while i + 4 <= len(payload):
        pid, length = struct.unpack_from(end + "HH", payload, i)
        value = payload[i + 4:i + 4 + length]
        if pid == PID_SENTINEL:
            break
        if pid == PID_ENDPOINT_GUID and length >= 16:
            guid = value[:16]
        elif pid == PID_TOPIC_NAME and length >= 4:
            n = struct.unpack_from(end + "I", value)[0]
            topic = value[4:4 + n].rstrip(b"\0").decode(errors="replace")
        i += 4 + length
    return (guid, topic) if guid and topic else None


class Reader:
    """Walks the RTPS messages of a capture: learns writers' topics, sums bytes per topic."""

    def __init__(self, local: str):
        self.local = local
        self.topics: dict[bytes, str] = {}
        self.bytes: dict[tuple[str, str], float] = defaultdict(float)
        self.messages: dict[tuple[str, str], int] = defaultdict(int)
        self.frags: dict[tuple, list] = {}  # (src, dst, id) -> [wire bytes, pieces, last seen]
        self.clock: list[float] = []  # the simulated times [s] of the /clock samples counted
        self.last_clock_ts: float | None = None  # [Unix s] the last /clock datagram's capture

    def name(self, guid: bytes) -> str:
        entity = struct.unpack(">I", guid[12:16])[0]
        if entity in BUILTIN:
            return BUILTIN[entity]
        return topic_key(self.topics[guid]) if guid in self.topics else "[unknown]"

    def packet(self, ip: dpkt.ip.IP, wire: int, count: bool) -> None:
        """One IPv4 packet of ``wire`` bytes on the wire; fragments are gathered first."""
        more, offset = bool(ip.mf), ip.offset * 8
        if more or offset:
            key = (ip.src, ip.dst, ip.id)
            entry = self.frags.setdefault(key, [0, {}, False])
            entry[0] += wire
            entry[1][offset] = bytes(ip.data)
            entry[2] = entry[2] or not more
            if not entry[2] or 0 not in entry[1]:
                return
            data, pos = b"", 0
            for off in sorted(entry[1]):
                if off != pos:
                    return  # a fragment still missing
                data += entry[1][off]
                pos += len(entry[1][off])
            del self.frags[key]
            wire, udp_bytes = entry[0], data
        else:
            udp_bytes = bytes(ip.data)
        if ip.p != dpkt.ip.IP_PROTO_UDP or len(udp_bytes) < 8 + 20:
            return
        rtps = udp_bytes[8:]
        if rtps[:4] != b"RTPS":
            return
        direction = "out" if dpkt.utils.inet_to_str(ip.src) == self.local else "in"
        self.rtps(rtps, wire, direction, count)

    def rtps(self, msg: bytes, wire: int, direction: str, count: bool) -> None:
        src = dst = msg[8:20]
        i, parts = 20, []
        while i + 4 <= len(msg):
            sid, flags, length = msg[i], msg[i + 1], 0
            length = struct.unpack_from("<H" if flags & 1 else ">H", msg, i + 2)[0]
            body = msg[i + 4:i + 4 + length] if length else msg[i + 4:]
            end = "<" if flags & 1 else ">"
            if sid == INFO_SRC and len(body) >= 20:
                src = body[8:20]
            elif sid == INFO_DST and len(body) >= 12:
                dst = body[:12]
            elif sid in (DATA, DATA_FRAG) and len(body) >= 12:
                writer = src + body[8:12]
                parts.append((self.name(writer), 4 + len(body)))
                if sid == DATA and body[8:12] in (b"\x00\x00\x03\xc2", b"\x00\x00\x04\xc2"):
                    to_inline = struct.unpack_from(end + "H", body, 2)[0]
                    start = 4 + to_inline
                    if flags & 0x02:  # inline QoS: skip its parameter list
                        while start + 4 <= len(body):
                            pid, plen = struct.unpack_from(end + "HH", body, start)
                            start += 4 + plen
                            if pid == PID_SENTINEL:
                                break
                    found = sedp_endpoint(body[start:])
                    if found:
                        self.topics[found[0]] = found[1]
                elif sid == DATA and count and flags & 0x04 and parts[-1][0] == "/clock":
                    start = 4 + struct.unpack_from(end + "H", body, 2)[0]
                    if not flags & 0x02 and len(body) >= start + 12:  # CDR: sec, nanosec
                        little = body[start + 1] == 0x01
                        sec, nsec = struct.unpack_from("<iI" if little else ">iI", body,
                                                       start + 4)
                        self.clock.append(sec + nsec * 1e-9)
            elif sid in (HEARTBEAT, GAP, HEARTBEAT_FRAG) and len(body) >= 8:
                parts.append((self.name(src + body[4:8]), 4 + len(body)))
            elif sid in (ACKNACK, NACK_FRAG) and len(body) >= 8:
                parts.append((self.name(dst + body[4:8]), 4 + len(body)))
            if length == 0:
                break
            i += 4 + length
        if not count or not parts:
            return
        total = sum(n for _, n in parts)
        for name, n in parts:
            self.bytes[(name, direction)] += wire * n / total
        for name in {name for name, _ in parts}:
            self.messages[(name, direction)] += 1


def read(path: Path, local: str, after: float | None) -> Reader:
    """Read a pcap twice: the first pass learns the writers' topics from the whole capture and
    finds the last ``/clock`` datagram; the second counts the bytes from ``after`` (Unix s,
    default the start) to that datagram (the run's end: the graph's changes at the shutdown are
    left out; to the capture's end when no ``/clock`` crossed)."""
    first = Reader(local)
    for ts, ip in _packets(path):
        n = len(first.clock)
        first.packet(ip, ip.len + 14, True)
        if len(first.clock) > n:
            first.last_clock_ts = ts
    last = first.last_clock_ts
    reader = Reader(local)
    reader.topics = dict(first.topics)
    for ts, ip in _packets(path):
        counted = (after is None or ts >= after) and (last is None or ts <= last)
        reader.packet(ip, ip.len + 14, counted)
    return reader


def _packets(path: Path) -> Iterator[tuple[float, dpkt.ip.IP]]:
    """(time [Unix s], IPv4 packet) of a pcap of Ethernet, Linux cooked or raw IP frames."""
    with path.open("rb") as f:
        pcap = dpkt.pcap.Reader(f)
        link = pcap.datalink()
        for ts, frame in pcap:
            if link == dpkt.pcap.DLT_EN10MB:
                ip = dpkt.ethernet.Ethernet(frame).data
            elif link == dpkt.pcap.DLT_LINUX_SLL:
                ip = dpkt.sll.SLL(frame).data
            else:
                ip = dpkt.ip.IP(frame)
            if isinstance(ip, dpkt.ip.IP):
                yield ts, ip


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("pcap", type=Path)
    p.add_argument("--local", required=True, help="the capturing host's IPv4 address")
    p.add_argument("--after", type=float, default=None,
                   help="count packets from this Unix time on (default: all)")
    p.add_argument("--sim-s", type=float, default=None,
                   help="simulated seconds counted (default: the span of the /clock samples "
                   "counted, if any crossed)")
    p.add_argument("--robots", type=int, default=None,
                   help="robots to divide by (e.g. the remote host's robots)")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args()
    if not a.pcap.is_file():
        print(f"rtps_bytes: {a.pcap}: no such file", file=sys.stderr)
        return 2
    r = read(a.pcap, a.local, a.after)
    if a.sim_s is None and len(r.clock) > 1:
        a.sim_s = max(r.clock) - min(r.clock)
        print(f"{a.sim_s:.1f} simulated s counted (from /clock)")
    per = (a.robots or 1) * (a.sim_s or 1)
    unit = "B per robot per sim s" if a.robots and a.sim_s else "bytes"
    rows = sorted({name for name, _ in r.bytes},
                  key=lambda n: -(r.bytes[(n, "in")] + r.bytes[(n, "out")]))
    print(f"{'topic':44s} {'in':>12s} {'out':>12s}   ({unit}; datagrams in/out)")
    out = {"pcap": str(a.pcap), "local": a.local, "after": a.after, "sim_s": a.sim_s,
           "robots": a.robots, "unit": unit, "topics": {}}
    for name in rows:
        b_in, b_out = r.bytes[(name, "in")] / per, r.bytes[(name, "out")] / per
        print(f"{name:44s} {b_in:12.1f} {b_out:12.1f}   "
              f"({r.messages[(name, 'in')]}/{r.messages[(name, 'out')]})")
        out["topics"][name] = {"in": b_in, "out": b_out,
                               "datagrams_in": r.messages[(name, "in")],
                               "datagrams_out": r.messages[(name, "out")]}
    tot_in = sum(v["in"] for v in out["topics"].values())
    tot_out = sum(v["out"] for v in out["topics"].values())
    print(f"{'total':44s} {tot_in:12.1f} {tot_out:12.1f}")
    if a.json:
        a.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
