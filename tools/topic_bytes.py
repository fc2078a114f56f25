"""Bytes per robot per simulated second, by topic, from a run's recording (docs/design/scaling.md).

Reads an MCAP recording written by ``swarm-up --record`` (every topic, the default) and sums
each message's serialized CDR payload per topic; a robot's own topics (``/Srobot7/scan``) are
summed over robots as ``/*/scan``. What a topic costs on the wire between hosts is this payload
times the number of hosts that read it, plus the RTPS headers (about 60-90 bytes a message).

Usage::

    python tools/topic_bytes.py RUN/recording.mcap [--robots N] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import defaultdict
from pathlib import Path

from mcap.reader import make_reader

ROBOT_TOPIC = re.compile(r"^/[A-Za-z]+\d+/")


def topic_bytes(path: Path) -> tuple[dict[str, dict[str, int]], float]:
    """Per topic (robot topics merged as ``/*/name``): ``{"messages": n, "bytes": b}``, and
    the recording's span of log times [s]."""
    totals: dict[str, dict[str, int]] = defaultdict(lambda: {"messages": 0, "bytes": 0})
    first = last = None
    with path.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            key = ROBOT_TOPIC.sub("/*/", channel.topic)
            totals[key]["messages"] += 1
            totals[key]["bytes"] += len(message.data)
            first = message.log_time if first is None else min(first, message.log_time)
            last = message.log_time if last is None else max(last, message.log_time)
    span = (last - first) / 1e9 if first is not None else 0.0
    return dict(totals), span


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mcap", type=Path)
    p.add_argument("--robots", type=int, required=True, help="robots in the run")
    p.add_argument("--sim-s", type=float, default=None,
                   help="simulated seconds recorded (default: the span of the log times)")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args()
    totals, span = topic_bytes(a.mcap)
    sim_s = a.sim_s or span
    rows = sorted(totals.items(), key=lambda kv: -kv[1]["bytes"])
    out = {"mcap": str(a.mcap), "robots": a.robots, "sim_s": sim_s, "topics": {}}
    print(f"{a.mcap}: {a.robots} robots, {sim_s:.1f} simulated s")
    print(f"{'topic':40s} {'msgs/robot/s':>12s} {'B/msg':>8s} {'B/robot/s':>10s}")
    total = 0.0
    for topic, t in rows:
        per_robot = t["bytes"] / a.robots / sim_s
        total += per_robot
        out["topics"][topic] = {**t, "bytes_per_robot_per_s": round(per_robot, 1)}
        print(f"{topic:40s} {t['messages'] / a.robots / sim_s:12.2f} "
              f"{t['bytes'] / max(t['messages'], 1):8.0f} {per_robot:10.0f}")
    out["total_bytes_per_robot_per_s"] = round(total, 1)
    print(f"{'total':40s} {'':12s} {'':8s} {total:10.0f}")
    if a.json:
        a.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
