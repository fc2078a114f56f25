"""What live /tf costs a run: RTF and CPU with --no-tf, with /tf on and nobody listening, and with
/tf on and one subscriber (as RViz2's TF display), back to back, interleaved over rounds.

    .venv/bin/python tools/tf_cost.py --sizes 20,100 --duration 200 --rounds 2 --out tf_cost.json

Each run is ``swarm-up --swarm-size N --world slim_blockage --commanders --rtf 0 --duration D
--seed 3`` in a ROS domain of its own (``--domain``); the listener is a separate rclpy process
that subscribes to ``/tf`` with tf2's dynamic QoS and counts what it gets.  The figures are
``metrics.json``'s ``rtf`` and ``cpu_percent`` (every process of the run, the listener not
included).  Runs are sequential: never two at once.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIN = Path(sys.executable).parent
LISTENER = r"""
import signal, sys, rclpy
from rclpy.qos import QoSProfile
from tf2_msgs.msg import TFMessage
rclpy.init()
node = rclpy.create_node("tf_listener")
got = [0, 0]
def on_tf(msg):
    got[0] += 1
    got[1] += len(msg.transforms)
node.create_subscription(TFMessage, "/tf", on_tf, QoSProfile(depth=100))
signal.signal(signal.SIGTERM, lambda *a: (print(f"{got[0]} {got[1]}", flush=True), sys.exit(0)))
while True:
    rclpy.spin_once(node, timeout_sec=0.1)
"""
MODES = ("no-tf", "tf, no reader", "tf, one reader")


def one_run(size: int, duration: float, mode: str, domain: int, work: Path) -> dict:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    run_dir = Path(tempfile.mkdtemp(prefix="tfcost-", dir=work))
    listener = None
    if mode == "tf, one reader":
        listener = subprocess.Popen([sys.executable, "-c", LISTENER], env=env,
                                    stdout=subprocess.PIPE, text=True)
    cmd = [str(BIN / "swarm-up"), "--swarm-size", str(size), "--world", "slim_blockage",
           "--commanders", "--rtf", "0", "--duration", str(duration), "--seed", "3",
           "--run-dir", str(run_dir)]
    if mode == "no-tf":
        cmd.append("--no-tf")
    t0 = time.monotonic()
    done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                          check=False)
    wall = time.monotonic() - t0
    heard = None
    if listener is not None:
        listener.send_signal(signal.SIGTERM)
        out, _ = listener.communicate(timeout=30)
        heard = [int(v) for v in out.split()[:2]] if out.strip() else None
    m = json.loads((run_dir / "metrics.json").read_text())
    return {"size": size, "mode": mode, "exit": done.returncode, "rtf": m["rtf"],
            "cpu_percent": m.get("cpu_percent"), "tasks": m["tasks_completed"],
            "collisions": m["collisions"], "wall_s": round(wall, 1),
            "tf_messages_heard": heard, "run_dir": str(run_dir)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="20,100")
    p.add_argument("--duration", type=float, default=200.0)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--domain", type=int, default=95)
    p.add_argument("--out", type=Path, default=Path("tf_cost.json"))
    args = p.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="tfcost-"))
    rows = []
    for size in (int(s) for s in args.sizes.split(",")):
        for r in range(args.rounds):
            for mode in MODES:
                row = one_run(size, args.duration, mode, args.domain, work)
                row["round"] = r
                rows.append(row)
                print(json.dumps(row), flush=True)
                args.out.write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
