"""The messaging baseline of ``swarm-bench --baseline`` (docs/reference/contract.md#s6).

How fast can the swarm's ROS traffic alone go?  The baseline relays the same messages as a
``swarm-up --commanders --rtf 0`` run, lockstep and unpaced, with nothing else to do, in the same
process layout; its real-time factor is the ceiling that the messaging sets, and
``swarm-bench`` reports every size's RTF as a percentage of it.

**Mirrored** (topic names, message types, QoS, sizes, rates, and the lockstep handshake of
``swarm_sim/node.py``, ``swarm_nav/node.py``, ``swarm_commander/robot_navigator.py``,
``swarm_metrics/listener.py``):

- simulator process: per control tick (10 Hz simulated) ``/clock``, every robot's ``odom`` and
  (while anyone subscribes to it, as the simulator) ``ground_truth`` (``nav_msgs/Odometry``,
  reliable, depth 10), on lidar ticks (5 Hz: every 2nd
  tick, from the robot's URDF) a ``sensor_msgs/LaserScan`` per robot with the URDF's beams (360)
  and fixed ranges (sensor-data QoS), robot after robot; then it waits until every awaited
  robot's ``geometry_msgs/TwistStamped`` ``cmd_vel`` stamped with that tick has arrived and
  steps; ``/map`` (the world's map, transient local) and the spawn events on ``/swarm/events``
  once; the start gate (the first tick is re-published every 0.5 s wall until every robot
  answered it); ``spin_once`` of an ``EventsExecutor`` between ticks.  The loop, its waits and
  its tick gate are the simulator's own (:class:`swarm_sim.loop.SimLoop`, :mod:`swarm_sim.tick`)
  and so are its sensor topics (:mod:`swarm_ros.robot_topics`): no wall-clock timeout, a robot
  not awaited only once its ``cmd_vel`` has no writer or the supervisor says it is gone.  As the
  simulator, it also publishes every robot's state in one ``/swarm/robot_states`` a tick and
  writes a robot's ``odom`` and ``scan`` only while that topic has a reader, and it takes a
  group's answers in one ``/swarm/cmd_vel_batch``.
- group process (several robots' navigators): as ``swarm_up.group``, it feeds its navigators
  the states' odometry and fixed-range scans (:class:`swarm_up.feed.SensorFeed`) instead of
  their subscribing to ``odom`` and ``scan``, and sends their answers in one batch
  (:mod:`swarm_up.answers`).
- navigator (one node ``/<ns>/navigator`` per robot, ``use_sim_time``; a process of its own
  subscribes to ``/clock`` itself, a group process once for all its nodes,
  :class:`swarm_up.clock.SharedClock`): subscribes ``/map``, ``scan``, ``odom``, ``goal_pose``;
  serves ``navigator/cancel``; answers each ``odom`` with one ``cmd_vel`` stamped with its tick, on
  lidar ticks only after that tick's scan arrived (converted to a numpy array, as the navigator
  does); publishes ``nav_status`` (``diagnostic_msgs/DiagnosticStatus`` with the real keys,
  reliable, transient local) at 2 Hz simulated and on every change of state, and a
  ``nav_msgs/Path`` ``plan`` of 200 poses (a typical A* path on a 0.05 m grid) per goal. Its first
  answer waits for a commander to connect, and the answer on the tick after a goal ended waits for
  the commander's next goal (up to 2.5 s wall), as with ``swarm-up --commanders``.
- commander (one node ``/<ns>/commander`` per robot, ``use_sim_time``): subscribes
  ``nav_status`` (depth 10), has the ``navigator/cancel`` client and the runner's 10 Hz wall-clock
  poll timer, and publishes the next ``goal_pose`` (stamped with the status's ``stamp``) when a
  goal ended.  A baseline goal "succeeds" ``goal_period_s`` simulated seconds after it was taken
  (default 180 s: about the 20 tasks per robot-hour that 20 robots reach on slim_blockage).
- orchestrator listener: a process with the metrics node's subscriptions (every ``nav_status``,
  ``/swarm/events``, ``/clock`` best effort).  In ``swarm-up`` it is a thread of the
  orchestrator; here it is a process of its own with an ``EventsExecutor`` (the bench process
  stays out of ROS), so the baseline carries its traffic but not the cost of ``swarm-up``'s
  ``SingleThreadedExecutor``.
- process layout: one simulator process, one listener, and the robots' nodes as ``swarm-up``
  lays them out: ``per-robot`` is one navigator process and one commander process per robot,
  ``K`` is K group processes each holding a contiguous group of robots' navigators and commanders
  (sizes differing by at most one, as ``swarm_up.args.split_groups``).  ``swarm-bench`` passes the
  layout the swarm-up run of that size reported (its metrics' ``processes``).

**Left out**: physics and collision checks, lidar ray casting and noise (the ranges are fixed),
every navigator computation (costmap, A*, DWA, holding, recovery: the answer is a zero twist),
replanning (one plan per goal), the navigators' parameter declarations, ``/swarm/events`` other
than the spawns (collisions, late ticks), the commander's route logic, and ``swarm-up``'s
supervision and resource sampling.

**Figures** (the ``sim`` process's summary; ``run_baseline`` adds the layout and CPU): ``ticks``
(control ticks stepped, the silent tick 0 included, so a complete run has ``duration * 10``),
``sim_time_s``, ``wall_time_s`` (from the start gate's opening to the end, as the simulator's
summary), ``rtf`` = sim / wall, ``robot_ticks_per_s`` = robots x ticks / wall, ``late_ticks``,
``cpu_s`` and ``cpu_per_robot`` = cpu_s / (robots x simulated seconds) [CPU s per robot per
simulated s, as :mod:`swarm_bench.bench`'s]: the CPU time of every baseline process while it
relayed traffic (the simulator from the gate's opening to the end; each other process from its
first tick, status or clock message until it was stopped, printed by itself as ``baseline:
cpu_s X``; None if a process had to be killed).

Usage: ``python -m swarm_bench.baseline run --swarm-size 20 --duration 60
[--processes per-robot|K]`` runs the baseline once and prints its figures as JSON;
``swarm-bench --baseline`` calls :func:`run_baseline`.  The processes it starts are
``python -m swarm_bench.baseline_nodes {sim,group,listener} --config ...``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from swarm_common import cli
from swarm_common.errors import InputError, run_cli
from swarm_up.args import default_processes, default_run_dir, processes_arg, split_groups
from swarm_up.run_config import PER_ROBOT

PROG = "swarm_bench.baseline"
NODES_PROG = "swarm_bench.baseline_nodes"  # the module every baseline process runs
DEFAULT_GOAL_PERIOD_S = 180.0  # [s] simulated
STOP_WAIT_S = 5.0  # [s] wall: SIGINT, then SIGKILL after this long
PROGRESS_RE = re.compile(r"t = ([\d.]+)(?: / [\d.]+)? s simulated, RTF ([\d.]+)")
CPU_RE = re.compile(r"^baseline: cpu_s ([\d.]+)$", re.MULTILINE)


@dataclass(frozen=True)
class BaselineConfig:
    """What every baseline process agrees on (written once as JSON, read by each process).

    Attributes:
        robots: namespaces without ``/``.
        duration_s: simulated seconds to run [s].
        summary_path: where the ``sim`` process writes its figures (JSON).
        map_yaml: the map_server map published on ``/map``.
        commanders: robots have commanders (the navigators wait for them, as with
            ``swarm-up --commanders``).
        control_rate_hz: control ticks per simulated second [Hz].
        lidar_every: a scan every this many ticks (from tick 0) [ticks].
        lidar_rate_hz: the lidar's rate [Hz] (``scan_time``).
        beams: beams per scan [-].
        angle_min: first beam's angle [rad].
        angle_max: last beam's angle [rad].
        range_min: shortest valid range [m].
        range_max: longest valid range [m].
        lidar_frame: the lidar's link name (``frame_id`` ``<ns>/<link>``).
        goal_period_s: simulated time a baseline goal takes [s].
        plan_poses: poses of the plan published per goal [-].
        goal_wait_timeout_s: wall time an answer waits for a commander's next goal [s].
    """

    robots: tuple[str, ...]
    duration_s: float
    summary_path: str
    map_yaml: str
    commanders: bool = True
    control_rate_hz: float = 10.0
    lidar_every: int = 2
    lidar_rate_hz: float = 5.0
    beams: int = 360
    angle_min: float = 0.0
    angle_max: float = 2.0 * math.pi
    range_min: float = 0.12
    range_max: float = 3.5
    lidar_frame: str = "base_scan"
    goal_period_s: float = DEFAULT_GOAL_PERIOD_S
    plan_poses: int = 200
    goal_wait_timeout_s: float = 2.5

    def encode(self) -> str:
        """The JSON text of this config."""
        return json.dumps(asdict(self), indent=2) + "\n"

    @classmethod
    def decode(cls, text: str) -> BaselineConfig:
        """Read :meth:`encode`'s text.

        Raises:
            InputError: not such a JSON object (unknown or missing keys).
        """
        try:
            data = json.loads(text)
            data["robots"] = tuple(data["robots"])
            return cls(**data)
        except (ValueError, KeyError, TypeError) as exc:
            raise InputError(f"--config: not a baseline config ({exc})") from None


@dataclass(frozen=True)
class BaselineProcess:
    """One baseline process: its name (log file stem) and its arguments after
    ``-m`` :data:`NODES_PROG`."""

    name: str
    args: tuple[str, ...]


def baseline_layout(cfg: BaselineConfig, config_path: Path,
                    processes: str | int) -> list[BaselineProcess]:
    """The baseline's processes in start order: listener, robots' processes, simulator.

    Args:
        cfg: the baseline's settings.
        config_path: where ``cfg`` is written (every process reads it).
        processes: ``"per-robot"`` or the number of group processes.

    Returns:
        The processes; per-robot gives one navigator and (with commanders) one commander
        process per robot, K gives K groups holding both.
    """
    conf = ("--config", str(config_path))
    out = [BaselineProcess("listener", ("listener", *conf))]
    if processes == PER_ROBOT:
        for ns in cfg.robots:
            out.append(BaselineProcess(f"nav_{ns}", ("group", *conf, "--namespaces", ns,
                                                     "--navigators")))
        if cfg.commanders:
            for ns in cfg.robots:
                out.append(BaselineProcess(f"cmd_{ns}", ("group", *conf, "--namespaces", ns,
                                                         "--commanders")))
    else:
        for g, group in enumerate(split_groups(cfg.robots, int(processes)), start=1):
            roles = ("--navigators", "--commanders") if cfg.commanders else ("--navigators",)
            out.append(BaselineProcess(f"group_{g}", ("group", *conf, "--namespaces",
                                                      ",".join(group), *roles)))
    out.append(BaselineProcess("sim", ("sim", *conf)))
    return out


def make_config(n: int, duration_s: float, run_dir: Path, *, world: str = "slim_blockage",
                robot: str = "turtlebot3_waffle", prefix: str = "Srobot",
                commanders: bool = True,
                goal_period_s: float = DEFAULT_GOAL_PERIOD_S) -> BaselineConfig:
    """A baseline config for ``n`` robots, with the lidar of ``robot`` and the map of ``world``.

    Args:
        n: robots.
        duration_s: simulated seconds [s].
        run_dir: where the summary (and the map, if the world has none) goes.
        world: a world name or path (its map under ``maps/``, else rasterised).
        robot: a robot name or path (its lidar: beams, angles, ranges, rate).
        prefix: namespace prefix.
        commanders: with commanders.
        goal_period_s: simulated time a baseline goal takes [s].

    Raises:
        InputError: unknown world or robot.
    """
    from swarm_common import paths
    from swarm_scene.robot_model import load_robot
    from swarm_scene.world import resolve_world

    world_path = Path(resolve_world(world))
    map_yaml = paths.MAPS_DIR / f"{world_path.stem}.yaml"
    if not map_yaml.is_file():
        from swarm_scene.map_io import save_map
        from swarm_scene.rasterize import rasterize_world
        from swarm_scene.world import load_world

        map_yaml, _ = save_map(rasterize_world(load_world(world_path)), run_dir / "map")
    lidar = load_robot(robot).lidar
    control_rate = 10.0
    return BaselineConfig(
        robots=tuple(f"{prefix}{i}" for i in range(1, n + 1)),
        duration_s=float(duration_s),
        summary_path=str(run_dir / "baseline_summary.json"),
        map_yaml=str(map_yaml),
        commanders=commanders,
        control_rate_hz=control_rate,
        lidar_every=max(1, round(control_rate / float(lidar.rate_hz))),
        lidar_rate_hz=float(lidar.rate_hz),
        beams=int(lidar.samples),
        angle_min=float(lidar.angle_min),
        angle_max=float(lidar.angle_max),
        range_min=float(lidar.range_min),
        range_max=float(lidar.range_max),
        lidar_frame=lidar.frame,
        goal_period_s=goal_period_s,
    )


def _stop(procs: dict[str, subprocess.Popen], names: list[str]) -> dict[str, int]:
    """SIGINT to the named processes, SIGKILL to those still alive after ``STOP_WAIT_S``."""
    for name in names:
        if procs[name].poll() is None:
            procs[name].send_signal(signal.SIGINT)
    deadline = time.monotonic() + STOP_WAIT_S
    codes = {}
    for name in names:
        try:
            codes[name] = procs[name].wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            procs[name].kill()
            codes[name] = procs[name].wait()
    return codes


def _follow(procs: dict[str, subprocess.Popen], sim_log: Path,
            should_stop: Callable[[], bool],
            on_progress: Callable[[float, float | None], None] | None) -> bool:
    """Wait for the ``sim`` process's end, passing its progress lines on; stop it (SIGINT) when
    ``should_stop()`` or another process died (the run cannot complete then).

    Returns:
        Whether the run was interrupted.
    """
    sim, pos, partial, interrupted = procs["sim"], 0, "", False
    while sim.poll() is None:
        if should_stop() and not interrupted:
            interrupted = True
            sim.send_signal(signal.SIGINT)
        time.sleep(0.2)
        with open(sim_log, encoding="utf-8", errors="replace") as fh:
            fh.seek(pos)
            text = partial + fh.read()
            pos = fh.tell()
        *lines, partial = text.split("\n")
        for line in lines:
            m = PROGRESS_RE.search(line)
            if m and on_progress is not None:
                on_progress(float(m.group(1)), float(m.group(2)))
        others_dead = [n for n, p in procs.items() if n != "sim" and p.poll() is not None]
        if others_dead and not interrupted:
            interrupted = True  # a robot process died: the run cannot complete
            sim.send_signal(signal.SIGINT)
    return interrupted


def run_baseline(cfg: BaselineConfig, processes: str | int, run_dir: Path, *,
                 env: dict | None = None,
                 should_stop: Callable[[], bool] = lambda: False,
                 on_progress: Callable[[float, float | None], None] | None = None) -> dict:
    """Run the baseline once: start its processes, wait for the simulator's end, stop the rest.

    Args:
        cfg: the baseline's settings (``summary_path`` is written by the ``sim`` process).
        processes: ``"per-robot"`` or the number of group processes.
        run_dir: the config file and ``logs/<process>.log`` go here.
        env: the processes' environment (default: this one's).
        should_stop: polled; True stops the baseline early (SIGINT to every process).
        on_progress: called with (simulated s, RTF so far) as the simulator reports it.

    Returns:
        The simulator's summary plus ``processes`` (the layout), ``process_count``,
        ``exit_code`` (the simulator's: 0 done, 130 stopped, 1 failed), ``cpu_s`` and
        ``cpu_per_robot``, ``interrupted`` and ``logs``.
    """
    from swarm_up import shm

    logs = run_dir / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    config_path = run_dir / "baseline_config.json"
    config_path.write_text(cfg.encode())
    Path(cfg.summary_path).unlink(missing_ok=True)
    env = dict(os.environ if env is None else env, PYTHONUNBUFFERED="1",
               RCUTILS_COLORIZED_OUTPUT="0")
    layout = baseline_layout(cfg, config_path, processes)
    shm_before = shm.snapshot()
    procs: dict[str, subprocess.Popen] = {}
    interrupted = False
    try:
        for p in layout:
            with open(logs / f"{p.name}.log", "wb") as log:
                procs[p.name] = subprocess.Popen(
                    [sys.executable, "-m", NODES_PROG, *p.args], stdout=log,
                    stderr=subprocess.STDOUT, env=env, start_new_session=True)
        interrupted = _follow(procs, logs / "sim.log", should_stop, on_progress)
    finally:
        codes = _stop(procs, list(procs))
        shm.clean_after_run(shm_before)
    try:
        summary = json.loads(Path(cfg.summary_path).read_text())
    except (OSError, ValueError):
        summary = {"robots": len(cfg.robots), "ticks": None, "sim_time_s": None,
                   "wall_time_s": None, "rtf": None, "robot_ticks_per_s": None,
                   "late_ticks": None, "sim_cpu_s": None}
    n = len(cfg.robots)
    # Every other process printed its CPU time since its traffic began as its last line.
    reported = [CPU_RE.findall((logs / f"{p.name}.log").read_text(errors="replace"))
                for p in layout if p.name != "sim"]
    cpu_s = None
    if summary.get("sim_cpu_s") is not None and all(reported):
        cpu_s = summary["sim_cpu_s"] + sum(float(r[-1]) for r in reported)
    sim_s = summary.get("sim_time_s")
    summary.update(
        processes=processes,
        process_count=len(layout),
        exit_code=codes.get("sim"),
        cpu_s=cpu_s,
        cpu_per_robot=(cpu_s / (sim_s * n)) if cpu_s is not None and sim_s else None,
        interrupted=interrupted or bool(summary.get("interrupted")),
        logs=str(logs),
    )
    return summary


# ----------------------------------------------------------------------------------- commands
def build_parser() -> argparse.ArgumentParser:
    """``python -m swarm_bench.baseline run ...`` (the processes it starts are
    :mod:`swarm_bench.baseline_nodes`')."""
    p = cli.ArgumentParser(prog=f"python -m {PROG}", allow_abbrev=False,
                description="The messaging baseline of swarm-bench (see the module's doc).")
    sub = p.add_subparsers(dest="role", required=True)
    run = sub.add_parser("run", help="run the baseline once and print its figures as JSON")
    run.add_argument("--swarm-size", type=cli.positive_int, default=5, metavar="N")
    run.add_argument("--duration", type=cli.positive_float, default=10.0, metavar="SEC",
                     help="simulated seconds (default: %(default)s)")
    run.add_argument("--processes", type=processes_arg, default=None, metavar="per-robot|K",
                     help="layout (default: swarm-up's for N)")
    run.add_argument("--world", default="slim_blockage")
    run.add_argument("--robot", default="turtlebot3_waffle")
    run.add_argument("--no-commanders", dest="commanders", action="store_false")
    run.add_argument("--goal-period", type=cli.positive_float, default=DEFAULT_GOAL_PERIOD_S,
                     metavar="SEC", help="simulated seconds a goal takes (default: %(default)s)")
    run.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                     help="config and logs (default: runs/baseline-<timestamp>)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m swarm_bench.baseline``."""

    def body() -> int:
        args = build_parser().parse_args(argv)
        run_dir = args.run_dir or default_run_dir(prefix="baseline-")
        run_dir.mkdir(parents=True, exist_ok=True)
        cfg = make_config(args.swarm_size, args.duration, run_dir.resolve(),
                          world=args.world, robot=args.robot, commanders=args.commanders,
                          goal_period_s=args.goal_period)
        processes = args.processes or default_processes(args.swarm_size)
        result = run_baseline(cfg, processes, run_dir.resolve())
        print(json.dumps(result, indent=2))
        return 0 if result["exit_code"] == 0 else 1

    return run_cli(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
