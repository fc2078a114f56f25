"""CPU seconds per simulated second of each role of a run (docs/design/scaling.md).

Runs ``swarm-up`` with the given flags (``--rtf 0`` and a ``--duration`` belong in them), samples
every process of the run with psutil (swarm_bench/proc_cpu.py) twice a second, and splits the CPU
spent between "all navigators ready" and the end of the run by role: the simulator, the group
processes (navigators and commanders), per-robot navigators and commanders, the coordinator, the
recorder and swarm-up itself (the metrics listener and the supervisor). Prints the table and the
run's RTF; writes JSON with ``--json``.

Usage::

    python tools/cpu_by_role.py [--json OUT] [--swarm-up PATH] -- --swarm-size 100 --commanders \
        --rtf 0 --duration 120
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

from swarm_bench.ledger import role_of as role


def sample(root: psutil.Process, cpu: dict[int, tuple[str, float]]) -> None:
    """Largest CPU time seen per PID of root's tree, with the process's role."""
    try:
        procs = [root, *root.children(recursive=True)]
    except psutil.Error:
        return
    for proc in procs:
        try:
            with proc.oneshot():
                used = sum(proc.cpu_times()[:2])
                name = cpu[proc.pid][0] if proc.pid in cpu else role(" ".join(proc.cmdline()))
        except psutil.Error:
            continue
        cpu[proc.pid] = (name, max(used, cpu.get(proc.pid, ("", 0.0))[1]))


def by_role(cpu: dict[int, tuple[str, float]]) -> dict[str, float]:
    out: dict[str, float] = {}
    for name, used in cpu.values():
        out[name] = out.get(name, 0.0) + used
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--json", type=Path, default=None)
    p.add_argument("--swarm-up", type=Path, default=None, metavar="PATH",
                   help="the swarm-up program to run (default: this environment's)")
    p.add_argument("flags", nargs=argparse.REMAINDER, help="swarm-up flags, after --")
    a = p.parse_args()
    flags = [f for f in a.flags if f != "--"]
    run_dir = Path(tempfile.mkdtemp(prefix="cpu_by_role_"))
    swarm_up = str(a.swarm_up or Path(sys.executable).parent / "swarm-up")
    log = run_dir / "swarm-up.log"
    with log.open("w") as out:
        proc = subprocess.Popen([swarm_up, *flags, "--run-dir", str(run_dir / "run")],
                                stdout=out, stderr=subprocess.STDOUT)
    root = psutil.Process(proc.pid)
    cpu: dict[int, tuple[str, float]] = {}
    at_ready = None
    t0 = time.monotonic()
    while proc.poll() is None:
        sample(root, cpu)
        if at_ready is None and re.search(r"all \d+ navigators ready", log.read_text()):
            at_ready, t_ready = by_role(cpu), time.monotonic()
        time.sleep(0.5)
    t_end = time.monotonic()
    end = by_role(cpu)
    metrics = json.loads((run_dir / "run" / "metrics.json").read_text())
    sim_s, n = metrics["sim_time_s"], metrics["robots"]
    at_ready = at_ready or {}
    run = {k: end[k] - at_ready.get(k, 0.0) for k in end}
    result = {"flags": flags, "robots": n, "sim_time_s": sim_s, "rtf": metrics["rtf"],
              "wall_run_s": round(t_end - (t_ready if at_ready else t0), 1),
              "spawn_to_ready_s": metrics.get("spawn_to_ready_s"),
              "tasks": metrics["tasks_completed"], "collisions": metrics["collisions"],
              "goals_aborted": metrics["goals_aborted"], "reproducible": metrics["reproducible"],
              "cpu_s_per_sim_s": {k: round(v / sim_s, 4) for k, v in sorted(run.items())},
              "cpu_ms_per_robot_per_sim_s": {k: round(1000 * v / sim_s / n, 2)
                                             for k, v in sorted(run.items())}}
    print(f"swarm-up {' '.join(flags)}: exit {proc.returncode}, {n} robots, RTF "
          f"{metrics['rtf']:.2f}, {metrics['tasks_completed']} tasks, collisions "
          f"{metrics['collisions']}, reproducible {metrics['reproducible']}")
    for k, v in result["cpu_s_per_sim_s"].items():
        print(f"  {k:12s} {v:8.3f} CPU s per simulated s "
              f"({result['cpu_ms_per_robot_per_sim_s'][k]:.2f} ms per robot)")
    if a.json:
        a.json.write_text(json.dumps(result, indent=2))
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
