"""Measure what crosses between hosts in a swarm over several hosts (docs/design/scaling.md).

Runs ``swarm-up --hosts H`` with every rank in a network namespace of its own on this machine
(tests/support/netns.py: a bridge, UDP only) and reads the kernel's byte and packet counters of
each namespace's interface: what went out of and came into every host, from the start to every
navigator ready (discovery and start-up) and from then to the end (the run), and the UDP
datagrams each host received and dropped for a full socket receive buffer (its loopback
traffic included: the processes of one host talk UDP too). Needs root.

Usage::

    python tools/host_traffic.py --hosts 2 --swarm-size 20 --duration 120 [--discovery-server]
        [--out traffic.json] [--pcap rank1.pcap] [-- extra swarm-up flags]

``--pcap`` also captures rank 1's interface with ``tcpdump`` (the Debian package) for
``tools/rtps_bytes.py``, which breaks the bytes down by topic (the JSON's ``ready_unix`` is the
moment every navigator was ready, for its ``--after``).

Prints a table per phase and host (bytes and packets out/in, per robot of the host per simulated
second for the run phase) and writes the figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.netns import Hosts  # noqa: E402


def counters(hosts: Hosts) -> list[dict]:
    """Per host: rx/tx bytes and packets of its interface."""
    out = []
    for ns in hosts.names:
        text = subprocess.run(["ip", "-n", ns, "-s", "-j", "link", "show", "eth0"],
                              capture_output=True, text=True, check=True).stdout
        stats = json.loads(text)[0]["stats64"]
        snmp = subprocess.run(["ip", "netns", "exec", ns, "nstat", "-az", "--json"],
                              capture_output=True, text=True, check=True).stdout
        kernel = json.loads(snmp)["kernel"]
        out.append({"rx_bytes": stats["rx"]["bytes"], "tx_bytes": stats["tx"]["bytes"],
                    "rx_packets": stats["rx"]["packets"], "tx_packets": stats["tx"]["packets"],
                    "udp_in": kernel["UdpInDatagrams"],
                    "udp_rcvbuf_errors": kernel["UdpRcvbufErrors"]})
    return out


def delta(a: list[dict], b: list[dict]) -> list[dict]:
    return [{k: y[k] - x[k] for k in x} for x, y in zip(a, b, strict=True)]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--hosts", type=int, default=2)
    p.add_argument("--swarm-size", type=int, default=20)
    p.add_argument("--duration", type=float, default=120.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--discovery-server", action="store_true")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--tag", type=int, default=240, help="namespace names and subnet")
    p.add_argument("--pcap", type=Path, default=None,
                   help="capture rank 1's interface into this pcap (tcpdump)")
    p.add_argument("extra", nargs="*", help="more swarm-up flags (after --)")
    a = p.parse_args()
    swarm_up = str(Path(sys.executable).parent / "swarm-up")
    run = ["--swarm-size", str(a.swarm_size), "--commanders", "--rtf", "0",
           "--duration", str(a.duration), "--seed", str(a.seed), "--hosts", str(a.hosts),
           *a.extra]
    tmp = Path(tempfile.mkdtemp(prefix="host_traffic_"))
    with Hosts(a.hosts, a.tag) as hosts:
        if a.discovery_server:
            run += ["--discovery-server", f"{hosts.addr[0]}:11811"]
        env = Hosts.env()
        procs = []
        dump = None
        if a.pcap:
            dump = subprocess.Popen(hosts.argv(1, ["tcpdump", "-q", "-i", "eth0", "-s", "0",
                                                   "-B", "65536", "-w", str(a.pcap)]),
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            time.sleep(1.0)
        c0 = counters(hosts)
        t0 = time.monotonic()
        for rank in reversed(range(a.hosts)):
            log = open(tmp / f"rank{rank}.log", "w")  # noqa: SIM115 - closed with the run
            procs.append(subprocess.Popen(
                hosts.argv(rank, [swarm_up, *run, "--host-rank", str(rank), "--run-dir",
                                  str(tmp / f"r{rank}")]), stdout=log, stderr=subprocess.STDOUT,
                env=env, start_new_session=True))
        leader_log = tmp / "rank0.log"
        ready = c_ready = t_ready = ready_unix = None
        while ready is None and procs[-1].poll() is None:
            m = re.search(r"all \d+ navigators ready in ([\d.]+) s", leader_log.read_text())
            if m:
                ready, c_ready, t_ready = float(m.group(1)), counters(hosts), time.monotonic()
                ready_unix = time.time()
            time.sleep(0.2)
        codes = [proc.wait() for proc in procs]
        c_end, t_end = counters(hosts), time.monotonic()
        if dump is not None:
            dump.terminate()
            dump.wait()
    if ready is None:  # never all ready: the whole run is the start
        print(f"not every navigator was ready: {leader_log.read_text().splitlines()[-1]}")
        c_ready, t_ready = c_end, t_end
    path = tmp / "r0" / "metrics.json"
    metrics = json.loads(path.read_text()) if path.is_file() else {}
    robots = [h["robots"] for h in metrics.get("hosts", [])]
    sim_s = metrics.get("sim_time_s")
    result = {"command": " ".join(["swarm-up", *run]), "exit_codes": codes, "tmp": str(tmp),
              "ready_s": ready, "ready_unix": ready_unix, "start_wall_s": round(t_ready - t0, 1),
              "run_wall_s": round(t_end - t_ready, 1), "sim_time_s": sim_s,
              "rtf": metrics.get("rtf"),
              "robots_per_host": robots, "start": delta(c0, c_ready),
              "run": delta(c_ready, c_end), "tasks": metrics.get("tasks_completed"),
              "collisions": metrics.get("collisions")}
    print(f"{result['command']}\nexit codes {codes}; all ready in {ready} s; RTF {result['rtf']};"
          f" {result['tasks']} tasks")
    for phase in ("start", "run"):
        print(f"{phase}:")
        for rank, c in enumerate(result[phase]):
            line = (f"  host {rank} ({robots[rank] if robots else '?'} robots): out "
                    f"{c['tx_bytes'] / 1e6:.2f} MB / {c['tx_packets']} pkts, in "
                    f"{c['rx_bytes'] / 1e6:.2f} MB / {c['rx_packets']} pkts; UDP datagrams "
                    f"received {c['udp_in']}, dropped (receive buffer full) "
                    f"{c['udp_rcvbuf_errors']}")
            if phase == "run" and robots and sim_s:
                per = (c["tx_bytes"] + c["rx_bytes"]) / robots[rank] / sim_s
                line += f"; {per:.0f} B per robot per simulated s (in + out)"
            print(line)
    if a.out:
        a.out.write_text(json.dumps(result, indent=2))
    return 0 if all(c == 0 for c in codes) else 1


if __name__ == "__main__":
    os.environ.setdefault("ROS_DOMAIN_ID", "88")
    sys.exit(main())
