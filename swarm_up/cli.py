"""``swarm-up``: bring a whole swarm up with one command, supervise it and measure it (SPEC §2).

Order of work: validate every flag (exit 2 with one line naming it) → create the run directory
(``RUN/logs``, ``RUN/params``) → write one navigator params file per robot → start the metrics
node (in this process) → start the simulator, the navigators (one process per robot or ``K``
groups) and, with ``--commanders``, the commanders → show progress until every navigator is
ready → supervise (restart crashed navigators/commanders within 2 s) until the simulator ends
(``--duration``) or Ctrl-C → stop everything within 5 s → remove stale Fast DDS shared-memory
files → write ``--metrics`` (and ``RUN/metrics.json``) and print a summary table.

Exit codes: 0 success (the run ended by ``--duration`` or Ctrl-C), 2 bad input (also when the
simulator rejects its input, e.g. too many robots for the spawn area), 1 runtime failure (the
simulator crashed, navigators not ready within ``--ready-timeout``, a template missing).
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import math
import os
import re
import shutil
import signal
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from swarm_common import paths
from swarm_common.errors import EXIT_BAD_INPUT, EXIT_OK, EXIT_RUNTIME, InputError, did_you_mean
from swarm_common.errors import run_cli as _run_cli

PROG = "swarm-up"
PER_ROBOT = "per-robot"
# Default layout: one process per robot (and one per commander) up to this many robots, else
# one group per core.  Each rclpy process is a DDS participant of ~75 MB whose start costs ~1 s
# of CPU; 20 robots with commanders as 41 processes took minutes to come up on 2 cores.
PER_ROBOT_MAX = 8
DEFAULT_READY_TIMEOUT_S = 120.0
POLL_PERIOD_S = 0.1  # supervision poll [s] (10 Hz; restarts within 2 s need >= 5 Hz)
# [s] wall: the navigators' goal_wait_timeout with --commanders; below the simulator's
# command_timeout (3 s), so a commander slower than this is a goal-wait timeout, not a late tick.
COMMANDER_GOAL_WAIT_S = 2.5
NAME_PREFIX_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
SPAWNED_RE = re.compile(r"spawned\s+(\d+)\s+robots?", re.IGNORECASE)


class RunError(Exception):
    """A runtime failure (exit 1); the message is the one line shown, naming the logs."""


# ---------------------------------------------------------------------------------------- parsing
class _Parser(argparse.ArgumentParser):
    """argparse whose errors become one line on stderr (exit 2), not usage + message."""

    def error(self, message: str):  # noqa: D102 - argparse API
        raise InputError(message.removeprefix("argument "))


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return value


def _float(text: str, *, allow_zero: bool, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
    return value


def _rtf(text: str) -> float:
    return _float(text, allow_zero=True, what="a number >= 0 (0 = as fast as possible)")


def _positive_seconds(text: str) -> float:
    return _float(text, allow_zero=False, what="a positive number of seconds")


def _processes(text: str) -> str | int:
    if text == PER_ROBOT:
        return PER_ROBOT
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be 'per-robot' or a positive number of processes, got {text!r}"
        ) from None
    if value <= 0:
        raise argparse.ArgumentTypeError(
            f"must be 'per-robot' or a positive number of processes, got {text!r}"
        )
    return value


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a TCP port 1-65535, got {text!r}") from None
    if not 0 < value < 65536:
        raise argparse.ArgumentTypeError(f"must be a TCP port 1-65535, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-up`` argument parser (SPEC §2)."""
    cores = os.cpu_count() or 1
    p = _Parser(
        prog=PROG,
        allow_abbrev=False,
        description="Bring up a simulated swarm: the simulator, one navigator per robot "
        "(and commanders), supervise it, and measure it.",
        epilog="Exit codes: 0 success, 2 bad input, 1 runtime failure. "
        "Ctrl-C stops every process within 5 s.",
    )
    p.add_argument("--swarm-size", type=_positive_int, default=5, metavar="N",
                   help="number of robots (default: %(default)s)")
    p.add_argument("--world", default="slim_blockage", metavar="NAME|PATH",
                   help="a world under worlds/ or a Gazebo .world/.sdf path "
                   "(default: %(default)s)")
    p.add_argument("--map", type=Path, default=None, metavar="PATH",
                   help="map_server map YAML (default: the world's map under maps/, "
                   "else rasterised from the world)")
    p.add_argument("--robot", default="turtlebot3_waffle", metavar="NAME|PATH",
                   help="a robot under robots/ or a .urdf/.xacro path (default: %(default)s)")
    p.add_argument("--name-prefix", default="Srobot", metavar="PREFIX",
                   help="robot namespaces are /<PREFIX><i>, i = 1..N (default: %(default)s)")
    p.add_argument("--seed", type=_seed, default=0, metavar="S",
                   help="seed of every random choice (default: %(default)s)")
    p.add_argument("--rtf", type=_rtf, default=1.0, metavar="X",
                   help="real-time factor; 0 = as fast as possible (default: %(default)s)")
    p.add_argument("--duration", type=_positive_seconds, default=None, metavar="SEC",
                   help="simulated seconds to run (default: until Ctrl-C)")
    p.add_argument("--commanders", action="store_true",
                   help="start a commander for every robot (visits the workstations)")
    p.add_argument("--coordination", choices=("decentralized", "centralized"),
                   default="decentralized",
                   help="decentralized (default) or centralized (not implemented yet: exits 2)")
    p.add_argument("--metrics", type=Path, default=None, metavar="PATH",
                   help="write the run's figures as JSON here at exit (always also "
                   "RUN/metrics.json)")
    p.add_argument("--record", type=Path, default=None, metavar="PATH.mcap",
                   help="record the run to MCAP (not implemented yet: exits 2)")
    p.add_argument("--dashboard", type=_port, nargs="?", const=8765, default=None,
                   metavar="PORT", help="serve a live dashboard (not implemented yet: exits 2)")
    p.add_argument("--processes", type=_processes, default=None, metavar="per-robot|K",
                   help="one navigator process per robot, or K processes each hosting a group "
                   f"of robots (default: per-robot up to {PER_ROBOT_MAX} robots, else "
                   f"K = number of cores, here {cores})")
    view = p.add_mutually_exclusive_group()
    view.add_argument("--headless", dest="gui", action="store_false", default=False,
                      help="no window (the default)")
    view.add_argument("--gui", dest="gui", action="store_true",
                      help="open the PyBullet window")
    p.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                   help="where logs, params files and metrics go (default: runs/<timestamp>/)")
    p.add_argument("--ready-timeout", type=_positive_seconds, default=DEFAULT_READY_TIMEOUT_S,
                   metavar="SEC", help="wall seconds to wait for every navigator to be ready "
                   "(default: %(default)s)")
    p.add_argument("--nav-params", type=Path, default=None, metavar="PATH",
                   help="navigator parameter template (default: params/navigator.yaml)")
    return p


# ------------------------------------------------------------------------------------- validation
@dataclass(frozen=True)
class RunConfig:
    """Everything a run needs, validated.

    Attributes:
        robots: namespaces without ``/`` (``Srobot1`` ...).
        name_prefix: their common prefix (``Srobot``).
        world_path: the world file.
        world_name: its stem, for reports.
        robot: the robot's name, or an absolute path.
        map_path: map YAML (None: rasterise or let the simulator do it).
        poi_path: points-of-interest YAML beside the world (None: there is none).
        seed: seed.
        rtf: real-time factor (0 = as fast as possible).
        duration: simulated seconds, or None (until Ctrl-C) [s].
        commanders: start commanders.
        coordination: ``decentralized``.
        metrics_path: ``--metrics`` file or None.
        groups: None for one process per robot, else the robots of every group process.
        gui: open the PyBullet window.
        run_dir: absolute run directory.
        ready_timeout: [s] wall.
        nav_template: navigator parameter template.
    """

    robots: tuple[str, ...]
    name_prefix: str
    world_path: Path
    world_name: str
    robot: str
    map_path: Path | None
    poi_path: Path | None
    seed: int
    rtf: float
    duration: float | None
    commanders: bool
    coordination: str
    metrics_path: Path | None
    groups: tuple[tuple[str, ...], ...] | None
    gui: bool
    run_dir: Path
    ready_timeout: float
    nav_template: Path


def _optional(module: str, name: str):
    """``module.name`` if that module (written by another package) exists yet, else None."""
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name == module:
            return None
        raise
    return getattr(mod, name, None)


def _prefix(flag: str, exc: InputError) -> InputError:
    msg = str(exc)
    return InputError(msg if msg.startswith(flag) else f"{flag}: {msg}")


def resolve_world(value: str) -> Path:
    """The world file for ``--world`` (a name under ``worlds/`` or a path).

    Uses ``swarm_common.world.resolve_world`` when it exists, else looks the file up itself.

    Raises:
        InputError: unknown name or missing file (names ``--world``).
    """
    _resolve = _optional("swarm_common.world", "resolve_world")
    if _resolve is not None:
        try:
            return Path(_resolve(value)).resolve()
        except InputError as exc:
            raise _prefix("--world", exc) from None
    as_path = Path(value)
    if as_path.suffix in (".world", ".sdf") or os.sep in value:
        if not as_path.is_file():
            raise InputError(f"--world: no such file {value!r}")
        return as_path.resolve()
    candidate = paths.WORLDS_DIR / f"{value}.world"
    if candidate.is_file():
        return candidate
    names = sorted(p.stem for p in paths.WORLDS_DIR.glob("*.world"))
    raise InputError(
        f"--world: unknown world {value!r}{did_you_mean(value, names)} "
        f"(known: {', '.join(names) or 'none'})"
    )


def resolve_robot(value: str) -> str:
    """Check ``--robot`` (a name under ``robots/`` or a ``.urdf``/``.xacro`` path).

    Uses ``swarm_common.robot_model.load_robot`` when it exists (it parses the model).

    Returns:
        The name as given, or the absolute path of a robot given by path.

    Raises:
        InputError: unknown name, missing or unreadable file (names ``--robot``).
    """
    as_path = Path(value)
    is_path = os.sep in value or value.endswith((".urdf", ".xacro"))
    load_robot = _optional("swarm_common.robot_model", "load_robot")
    if load_robot is not None:
        try:
            load_robot(as_path.resolve() if is_path else value)
        except InputError as exc:
            raise _prefix("--robot", exc) from None
    elif is_path:
        if not as_path.is_file():
            raise InputError(f"--robot: no such file {value!r}")
    else:
        names = sorted(p.name.split(".")[0] for p in paths.ROBOTS_DIR.glob("*.urdf*"))
        if value not in names:
            raise InputError(
                f"--robot: unknown robot {value!r}{did_you_mean(value, names)} "
                f"(known: {', '.join(names) or 'none'})"
            )
    return str(as_path.resolve()) if is_path else value


def _check_world_and_fit(world_path: Path, robot: str, n: int) -> None:
    """Load the world and, when it has a spawn area, check that ``n`` robots fit in it.

    Raises:
        InputError: a malformed world (names ``--world``), or too many robots (names
            ``--swarm-size`` and says how many fit).
    """
    from swarm_common.poi import poi_for_world
    from swarm_common.robot_model import load_robot
    from swarm_common.world import load_world, world_polygons
    from swarm_sim.engine import spawn_poses

    try:
        world = load_world(world_path)
    except InputError as exc:
        raise _prefix("--world", exc) from None
    poi = poi_for_world(world_path)
    if poi is not None and poi.spawn is not None:
        spawn_poses(poi.spawn, n, load_robot(robot).radius, world_polygons(world),
                    where=f"spawn area of {world.name}")


def _check_map(map_path: Path) -> Path:
    if not map_path.is_file():
        raise InputError(f"--map: no such file '{map_path}'")
    load_map = _optional("swarm_common.map_io", "load_map")
    if load_map is None:
        return map_path.resolve()
    try:
        load_map(map_path)
    except InputError as exc:
        raise _prefix("--map", exc) from None
    return map_path.resolve()


def _check_poi(world_path: Path) -> Path | None:
    poi = world_path.with_suffix(".yaml")
    if not poi.is_file():
        return None
    load_poi = _optional("swarm_common.poi", "load_poi")
    if load_poi is None:
        return poi
    load_poi(poi)  # InputError names the file
    return poi


def split_groups(robots: tuple[str, ...], k: int) -> tuple[tuple[str, ...], ...]:
    """Split robots into ``k`` contiguous groups whose sizes differ by at most one.

    Args:
        robots: namespaces.
        k: number of groups (clamped to 1..len(robots)).

    Returns:
        The groups, in robot order.
    """
    k = max(1, min(k, len(robots)))
    base, extra = divmod(len(robots), k)
    out, i = [], 0
    for g in range(k):
        size = base + (1 if g < extra else 0)
        out.append(tuple(robots[i:i + size]))
        i += size
    return tuple(out)


def validate(args: argparse.Namespace) -> RunConfig:
    """Turn parsed arguments into a :class:`RunConfig`, checking every flag and file.

    Raises:
        InputError: the first bad flag or file (the one line shown, naming it).
    """
    if not NAME_PREFIX_RE.match(args.name_prefix):
        raise InputError(
            f"--name-prefix: must start with a letter and hold only letters, digits and '_' "
            f"(a ROS name), got {args.name_prefix!r}"
        )
    if args.coordination == "centralized":
        raise InputError("--coordination: centralized is not implemented yet")
    if args.record is not None:
        raise InputError("--record: not implemented yet")
    if args.dashboard is not None:
        raise InputError("--dashboard: not implemented yet")
    if args.metrics is not None:
        parent = args.metrics.expanduser().resolve().parent
        if not parent.is_dir():
            raise InputError(f"--metrics: directory '{parent}' does not exist")
        if args.metrics.is_dir():
            raise InputError(f"--metrics: '{args.metrics}' is a directory")
    if args.run_dir is not None and args.run_dir.exists() and not args.run_dir.is_dir():
        raise InputError(f"--run-dir: '{args.run_dir}' exists and is not a directory")
    nav_template = args.nav_params if args.nav_params is not None else (
        paths.PARAMS_DIR / "navigator.yaml")
    if args.nav_params is not None and not args.nav_params.is_file():
        raise InputError(f"--nav-params: no such file '{args.nav_params}'")

    map_path = _check_map(args.map) if args.map is not None else None
    world_path = resolve_world(args.world)
    if map_path is None:
        default_map = paths.MAPS_DIR / f"{world_path.stem}.yaml"
        map_path = default_map if default_map.is_file() else None
    poi_path = _check_poi(world_path)
    robot = resolve_robot(args.robot)

    n = args.swarm_size
    _check_world_and_fit(world_path, robot, n)
    robots = tuple(f"{args.name_prefix}{i}" for i in range(1, n + 1))
    processes = args.processes
    if processes is None:
        processes = PER_ROBOT if n <= PER_ROBOT_MAX else (os.cpu_count() or 1)
    groups = None if processes == PER_ROBOT else split_groups(robots, int(processes))

    run_dir = args.run_dir if args.run_dir is not None else default_run_dir()
    return RunConfig(
        robots=robots,
        name_prefix=args.name_prefix,
        world_path=world_path,
        world_name=world_path.stem,
        robot=robot,
        map_path=map_path,
        poi_path=poi_path,
        seed=args.seed,
        rtf=args.rtf,
        duration=args.duration,
        commanders=args.commanders,
        coordination=args.coordination,
        metrics_path=args.metrics.expanduser().resolve() if args.metrics else None,
        groups=groups,
        gui=args.gui,
        run_dir=run_dir.expanduser().resolve(),
        ready_timeout=args.ready_timeout,
        nav_template=nav_template,
    )


def default_run_dir(base: Path | None = None) -> Path:
    """``runs/<YYYYmmdd-HHMMSS>`` (with ``-2``, ``-3`` ... if taken) under ``base`` (cwd)."""
    base = Path("runs") if base is None else base
    stamp = time.strftime("%Y%m%d-%H%M%S")
    candidate, i = base / stamp, 1
    while candidate.exists():
        i += 1
        candidate = base / f"{stamp}-{i}"
    return candidate


# ------------------------------------------------------------------------------ run directory
def load_nav_template(path: Path) -> dict:
    """The ``ros__parameters`` of the navigator template (``navigator: ros__parameters: ...``).

    Raises:
        RunError: the default template is missing (an installation problem).
        InputError: the file is not such a template (names the file).
    """
    if not path.is_file():
        raise RunError(f"{path}: navigator parameter template missing")
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"{path}: not readable YAML ({exc})".splitlines()[0]) from None
    if not isinstance(data, dict) or len(data) != 1:
        raise InputError(f"{path}: expected one top-level key 'navigator'")
    (root, body), = data.items()
    if root not in ("navigator", "/navigator", "/**", "**"):
        raise InputError(f"{path}: top-level key must be 'navigator', got {root!r}")
    if not isinstance(body, dict) or not isinstance(body.get("ros__parameters", {}), dict):
        raise InputError(f"{path}: expected 'navigator: ros__parameters: {{...}}'")
    return dict(body.get("ros__parameters") or {})


def navigator_params(template: dict, ns: str, index: int, cfg: RunConfig) -> dict:
    """One robot's params file content, rooted at ``/<ns>/navigator``.

    Args:
        template: the template's ``ros__parameters``.
        ns: namespace without ``/``.
        index: the robot's number i (1..N).
        cfg: the run.

    Returns:
        ``{"/<ns>/navigator": {"ros__parameters": {...template, use_sim_time, robot_name,
        robot_index, poi_file, map_yaml_path (""), robot}}}`` (paths absolute, "" if none).
    """
    params = dict(template)
    params.update(
        use_sim_time=True,
        robot_name=ns,
        robot_index=index,
        poi_file=str(cfg.poi_path) if cfg.poi_path else "",
        # The map is distributed centrally on /map, as in the thesis; a navigator that should
        # read a file of its own gets map_yaml_path set by hand.
        map_yaml_path="",
        robot=cfg.robot,
        # With commanders, simulated time starts once each robot's commander is connected, and
        # each goal takes effect at a fixed tick: the same seed gives the same run.
        wait_for_commander=bool(cfg.commanders),
        # Our commanders answer every ended goal at once; a loaded machine may delay that answer
        # by seconds of wall time, and a wait that times out would make the run irreproducible.
        goal_wait_timeout=COMMANDER_GOAL_WAIT_S if cfg.commanders else 0.5,
    )
    return {f"/{ns}/navigator": {"ros__parameters": params}}


def write_params_files(cfg: RunConfig, template: dict) -> list[Path]:
    """Write ``RUN/params/<ns>.yaml`` for every robot.

    Returns:
        The files, in robot order.
    """
    out_dir = cfg.run_dir / "params"
    out_dir.mkdir(parents=True, exist_ok=True)
    files = []
    for i, ns in enumerate(cfg.robots, start=1):
        path = out_dir / f"{ns}.yaml"
        path.write_text(yaml.safe_dump(navigator_params(template, ns, i, cfg), sort_keys=False))
        files.append(path)
    return files


def prepare_map(cfg: RunConfig) -> RunConfig:
    """If there is no map, rasterise the world into ``RUN/map.yaml`` (when the modules exist).

    Returns:
        ``cfg`` with ``map_path`` set, or unchanged (the simulator then rasterises it).
    """
    if cfg.map_path is not None:
        return cfg
    save_map = _optional("swarm_common.map_io", "save_map")
    rasterize_world = _optional("swarm_common.rasterize", "rasterize_world")
    load_world = _optional("swarm_common.world", "load_world")
    if save_map is None or rasterize_world is None or load_world is None:
        return cfg
    yaml_path, _ = save_map(rasterize_world(load_world(cfg.world_path)), cfg.run_dir / "map")
    return replace(cfg, map_path=Path(yaml_path).resolve())


# ------------------------------------------------------------------------------- child commands
def command(script: str, module: str, func: str = "main") -> list[str]:
    """The argv prefix that runs a console script.

    Looks the script up on ``PATH``, then beside this Python (the venv's ``bin/``), else runs
    ``module:func`` with this Python.
    """
    found = shutil.which(script) or shutil.which(script, path=str(Path(sys.executable).parent))
    if found:
        return [found]
    return [sys.executable, "-c", f"import sys; from {module} import {func}; sys.exit({func}())"]


def child_specs(cfg: RunConfig):
    """The supervised processes of a run, in start order: simulator, navigators, commanders.

    Returns:
        A list of :class:`swarm_up.supervisor.ChildSpec`.
    """
    from swarm_up.supervisor import ChildSpec

    logs = cfg.run_dir / "logs"
    params = cfg.run_dir / "params"
    env = dict(os.environ, PYTHONUNBUFFERED="1", RCUTILS_COLORIZED_OUTPUT="0")
    world = str(cfg.world_path)
    sim = command("swarm-sim", "swarm_sim.node") + [
        "--world", world, "--robot", cfg.robot, "--swarm-size", str(len(cfg.robots)),
        "--name-prefix", cfg.name_prefix,
        "--seed", str(cfg.seed), "--rtf", repr(cfg.rtf),
        # Simulated time starts when every navigator answers (SPEC §5's synchronous loop).
        "--wait-for", str(len(cfg.robots)),
    ]
    if cfg.duration is not None:
        sim += ["--duration", repr(cfg.duration)]
    if cfg.map_path is not None:
        sim += ["--map", str(cfg.map_path)]
    sim += ["--summary", str(cfg.run_dir / "sim_summary.json")]
    if cfg.gui:
        sim.append("--gui")
    specs = [ChildSpec("sim", tuple(sim), logs / "sim.log", kind="sim", restart=False, env=env)]

    if cfg.groups is None:
        nav = command("swarm-nav", "swarm_nav.node")
        for ns in cfg.robots:
            argv = nav + ["--ros-args", "-r", f"__ns:=/{ns}",
                          "--params-file", str(params / f"{ns}.yaml")]
            specs.append(ChildSpec(f"nav_{ns}", tuple(argv), logs / f"nav_{ns}.log",
                                   kind="nav", robots=(ns,), env=env))
        if cfg.commanders:
            cmd = command("swarm-commander", "swarm_commander.cli")
            for ns in cfg.robots:
                argv = cmd + [ns, "--world", world, "--seed", str(cfg.seed),
                              "--wait-timeout", repr(cfg.ready_timeout)]
                specs.append(ChildSpec(f"cmd_{ns}", tuple(argv), logs / f"cmd_{ns}.log",
                                       kind="cmd", robots=(ns,), env=env))
    else:
        for g, group in enumerate(cfg.groups, start=1):
            argv = [sys.executable, "-m", "swarm_nav.group", "--namespaces", ",".join(group),
                    "--params-dir", str(params)]
            if cfg.commanders:
                argv += ["--commanders", "--world", world, "--seed", str(cfg.seed)]
            specs.append(ChildSpec(f"group_{g}", tuple(argv), logs / f"group_{g}.log",
                                   kind="group", robots=group, env=env))
    return specs


# ------------------------------------------------------------------------------------- output
class ProgressView:
    """Spawn and readiness progress: a rich progress bar on a terminal, else plain lines.

    Args:
        total: number of robots.
        tty: draw bars (True) or print a line on every change (False).
    """

    def __init__(self, total: int, tty: bool):
        self.total = total
        self._last = (-1, -1)
        self._progress = None
        if tty:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._progress = Progress(
                TextColumn("{task.description:<18}"), BarColumn(), MofNCompleteColumn(),
                TimeElapsedColumn(), transient=False,
            )
            self._spawn = self._progress.add_task("robots spawned", total=total)
            self._ready = self._progress.add_task("navigators ready", total=total)
            self._progress.start()

    def update(self, spawned: int, ready: int) -> None:
        """Show ``spawned``/``ready`` of ``total`` (spawned is at least ready)."""
        spawned = max(spawned, ready)
        if (spawned, ready) == self._last:
            return
        if self._progress is not None:
            self._progress.update(self._spawn, completed=spawned)
            self._progress.update(self._ready, completed=ready)
        else:
            if spawned != self._last[0]:
                print(f"robots spawned: {spawned}/{self.total}", flush=True)
            if ready != self._last[1]:
                print(f"navigators ready: {ready}/{self.total}", flush=True)
        self._last = (spawned, ready)

    def close(self) -> None:
        """Stop drawing (idempotent)."""
        if self._progress is not None:
            self._progress.stop()
            self._progress = None


def _fmt(value, unit: str = "", digits: int = 2) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        text = f"{value:.{digits}f}"
    else:
        text = str(value)
    return f"{text} {unit}".rstrip()


def print_summary(metrics: dict, metrics_files: list[Path]) -> None:
    """Print the run's figures as a table (rich; plain text when not a terminal)."""
    from rich.console import Console
    from rich.table import Table

    col = metrics.get("collisions") or {}
    rows = [
        ("robots", _fmt(metrics.get("robots"))),
        ("world / seed", f"{metrics.get('world')} / {metrics.get('seed')}"),
        ("coordination", _fmt(metrics.get("coordination"))),
        ("simulated time", _fmt(metrics.get("sim_time_s"), "s", 1)),
        ("wall time", _fmt(metrics.get("wall_time_s"), "s", 1)),
        ("real-time factor", _fmt(metrics.get("rtf"))),
        ("robot-ticks per wall second", _fmt(metrics.get("robot_ticks_per_s"), "", 0)),
        ("spawn to all ready", _fmt(metrics.get("spawn_to_ready_s"), "s")),
        ("tasks completed", _fmt(metrics.get("tasks_completed"))),
        ("throughput", _fmt(metrics.get("throughput_per_hour"), "tasks/h", 1)),
        ("goals reached / aborted",
         f"{_fmt(metrics.get('goals_reached'))} / {_fmt(metrics.get('goals_aborted'))}"),
        ("collisions robot-robot / wall",
         f"{_fmt(col.get('robot_robot'))} / {_fmt(col.get('robot_wall'))}"),
        ("min separation", _fmt(metrics.get("min_separation_m"), "m")),
        ("mean time to goal", _fmt(metrics.get("mean_time_to_goal_s"), "s", 1)),
        ("time holding", _fmt(metrics.get("holding_time_s"), "s", 1)),
        ("late ticks", _fmt(metrics.get("late_ticks"))),
        ("goal-wait timeouts", _fmt(metrics.get("goal_wait_timeouts"))),
        ("reproducible (seed alone decides)", {True: "yes", False: "no", None: "unknown"}.get(
            metrics.get("reproducible"), "unknown")),
        ("CPU (100 % = one core)", _fmt(metrics.get("cpu_percent"), "%", 0)),
        ("peak RSS per robot", _fmt(metrics.get("peak_rss_mb_per_robot"), "MB", 1)),
        ("restarts", _fmt(metrics.get("restarts"))),
    ]
    table = Table(title="swarm-up summary", show_header=False)
    table.add_column("figure")
    table.add_column("value", justify="right")
    for name, value in rows:
        table.add_row(name, value)
    console = Console()
    console.print(table)
    for path in metrics_files:
        print(f"metrics: {path}", flush=True)


# ------------------------------------------------------------------------------------------ run
class _StopFlag:
    """Set by SIGINT/SIGTERM; the main loop polls it."""

    def __init__(self):
        self.signum: int | None = None

    def __call__(self, signum, _frame):
        if self.signum is None:
            self.signum = signum


class _LogTail:
    """Reads what a growing log file gained since the last call."""

    def __init__(self, path: Path):
        self.path = path
        self._pos = 0
        self._partial = ""

    def lines(self) -> list[str]:
        try:
            with open(self.path, encoding="utf-8", errors="replace") as fh:
                fh.seek(self._pos)
                chunk = fh.read()
                self._pos = fh.tell()
        except OSError:
            return []
        text = self._partial + chunk
        *done, self._partial = text.split("\n")
        return done


def _last_line(path: Path) -> str:
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def _say(text: str) -> None:
    print(f"{PROG}: {text}", flush=True)


def _warn(text: str) -> None:
    print(f"{PROG}: warning: {text}", file=sys.stderr, flush=True)


@dataclass
class Outcome:
    """How a run ended: exit code, the error line (if any) and a short reason for the metrics."""

    code: int = EXIT_OK
    error: str = ""
    ended_by: str = "interrupted"


class Orchestrator:
    """One run: starts the children, watches them, and reports (see :func:`run`).

    Args:
        cfg: the validated run (params files already written).
    """

    def __init__(self, cfg: RunConfig):
        from swarm_up.metrics import MetricsListener
        from swarm_up.supervisor import ResourceSampler, Supervisor

        self.cfg = cfg
        self.logs = cfg.run_dir / "logs"
        self.specs = child_specs(cfg)
        self.n = len(cfg.robots)
        self.t0 = time.monotonic()
        self.listener = MetricsListener(cfg.robots, self.t0)
        self.sup = Supervisor(on_restart=self._on_restart)
        self.sampler = ResourceSampler(self.sup, robots=self.n)
        self.view = ProgressView(self.n, tty=sys.stdout.isatty())
        self.all_ready = False
        self._last_report = time.monotonic()
        self._report_mark: tuple[float, float] | None = None  # (wall, sim) of the last line
        self._sim_tail = _LogTail(self.logs / "sim.log")
        self._spawned_from_log = 0
        self._navigators = {s.name for s in self.specs if s.kind in ("nav", "group")}
        self._dead: dict[str, int] = {}  # exited, not to be restarted -> exit code

    def _log_of(self, name: str) -> Path:
        return self.logs / f"{name}.log"

    def _on_restart(self, ev) -> None:
        _warn(f"{ev.name} exited with code {ev.code}; restarted "
              f"(restart {self.sup.children[ev.name].restarts}); logs: {self._log_of(ev.name)}")

    def start(self) -> None:
        """Start the metrics node, then the simulator, navigators and commanders, in order.

        Raises:
            RunError: a command could not be started.
        """
        self.listener.start()
        for spec in self.specs:
            try:
                self.sup.start(spec)
            except OSError as exc:
                raise RunError(f"cannot start {spec.argv[0]}: {exc.strerror}") from None

    def step(self) -> Outcome | None:
        """One supervision cycle (restarts, progress, readiness); an :class:`Outcome` at the end.

        Returns:
            None while the run goes on.
        """
        sim_code = None
        for ev in self.sup.poll():
            if ev.name == "sim":
                sim_code = ev.code
                continue
            if not ev.restarted:
                self._dead[ev.name] = ev.code
                what = "keeps crashing, last exit code" if ev.gave_up else "exited with code"
                _warn(f"{ev.name} {what} {ev.code}; not restarted; logs: {self._log_of(ev.name)}")
        if sim_code is not None:
            return self._sim_ended(sim_code)
        if not self.all_ready:
            return self._progress()
        self.sampler.maybe_sample()
        self._report_progress()
        return None

    def _report_progress(self, every_s: float = 10.0) -> None:
        """One line every ``every_s`` wall seconds: simulated time, RTF, goals, collisions."""
        now = time.monotonic()
        if now - self._last_report < every_s:
            return
        with self.listener.lock:
            rec = self.listener.recorder
            sim_s = rec.last_sim_time_s
            reached, aborted = rec.goal_totals()
            hits = sum(rec.collision_events.values())
        if sim_s is None:
            return
        if self._report_mark is not None:
            wall0, sim0 = self._report_mark
            rtf = (sim_s - sim0) / max(now - wall0, 1e-9)
            of = "" if self.cfg.duration is None else f" / {self.cfg.duration:g}"
            _say(f"t = {sim_s:.0f}{of} s simulated, RTF {rtf:.2f}, goals reached {reached}, "
                 f"aborted {aborted}, collisions {hits}")
        self._report_mark = (now, sim_s)
        self._last_report = now

    def _sim_ended(self, code: int) -> Outcome:
        sim_log = self._log_of("sim")
        if code == 0:
            return Outcome(ended_by="duration")
        if code == EXIT_BAD_INPUT:
            line = re.sub(r"^swarm-sim: (error: )?", "", _last_line(sim_log))
            return Outcome(EXIT_BAD_INPUT, f"{line} (logs: {sim_log})",
                           "simulator rejected its input")
        return Outcome(EXIT_RUNTIME, f"simulator exited with code {code}; logs: {sim_log}",
                       "simulator crashed")

    def _progress(self) -> Outcome | None:
        for line in self._sim_tail.lines():
            m = SPAWNED_RE.search(line)
            if m:
                self._spawned_from_log = max(self._spawned_from_log, int(m.group(1)))
        spawned, ready = self.listener.snapshot()
        self.view.update(min(self.n, max(spawned, self._spawned_from_log)), ready)
        self.sampler.maybe_sample()
        elapsed = time.monotonic() - self.t0
        if ready >= self.n:
            self.all_ready = True
            self.view.close()
            _say(f"all {self.n} navigators ready in {elapsed:.1f} s; "
                 + ("running until Ctrl-C" if self.cfg.duration is None else
                    f"running {self.cfg.duration:g} simulated s (Ctrl-C stops)"))
            return None
        if self._navigators and self._navigators <= self._dead.keys():
            first = sorted(self._navigators)[0]
            return Outcome(EXIT_RUNTIME, f"every navigator process exited ({first}: code "
                           f"{self._dead[first]}); logs: {self.logs}", "navigators failed")
        if elapsed > self.cfg.ready_timeout:
            with self.listener.lock:
                missing = self.listener.recorder.not_ready()
            shown = ", ".join(missing[:5]) + (" ..." if len(missing) > 5 else "")
            return Outcome(EXIT_RUNTIME, f"{len(missing)} of {self.n} navigators not ready after "
                           f"{self.cfg.ready_timeout:g} s ({shown}); logs: {self.logs}",
                           "ready timeout")
        return None

    def shutdown(self, ended_by: str) -> float:
        """Stop every child (within 5 s) and the metrics node.

        Returns:
            The run's wall time, start to the children's end [s].
        """
        self.view.close()
        if self.sup.children:
            _say(f"stopping ({ended_by}) ...")
        self.sampler.maybe_sample(force=True)
        self.sup.stop()
        wall = time.monotonic() - self.t0
        self.listener.stop()
        return wall

    def report(self, outcome: Outcome, wall_s: float) -> dict:
        """Merge the simulator's summary, write the metrics files, print the summary table."""
        from swarm_up.aggregate import aggregate, load_sim_summary

        cfg = self.cfg
        summary, warnings = load_sim_summary(cfg.run_dir / "sim_summary.json")
        if outcome.code == EXIT_OK:
            for w in warnings:
                _warn(w)
        with self.listener.lock:
            metrics = aggregate(
                self.listener.recorder, summary, world=cfg.world_name, seed=cfg.seed,
                coordination=cfg.coordination, wall_time_s=wall_s,
                resources=self.sampler.result(), restarts=self.sup.restarts,
                extra={"ended_by": outcome.ended_by, "run_dir": str(cfg.run_dir),
                       "processes": PER_ROBOT if cfg.groups is None else len(cfg.groups),
                       "commanders": cfg.commanders, "rtf_requested": cfg.rtf},
            )
        files = [cfg.run_dir / "metrics.json"]
        if cfg.metrics_path:
            files.append(cfg.metrics_path)
        for path in files:
            path.write_text(json.dumps(metrics, indent=2) + "\n")
        if outcome.code == EXIT_OK or self.all_ready:
            print_summary(metrics, files)
        return metrics


def run(cfg: RunConfig) -> int:
    """Run the swarm described by ``cfg`` until it ends.

    Returns:
        The exit code: 0 (ended by ``--duration`` or Ctrl-C), 1 (runtime failure), 2 (the
        simulator rejected its input).

    Raises:
        RunError: the navigator template is missing.
        InputError: the navigator template or the world is malformed.
    """
    from swarm_up import shm

    template = load_nav_template(cfg.nav_template)
    (cfg.run_dir / "logs").mkdir(parents=True, exist_ok=True)
    (cfg.run_dir / "params").mkdir(parents=True, exist_ok=True)
    cfg = prepare_map(cfg)
    write_params_files(cfg, template)
    layout = (f"{PER_ROBOT} processes" if cfg.groups is None
              else f"{len(cfg.groups)} group processes")
    _say(f"{len(cfg.robots)} robots in {cfg.world_name}, seed {cfg.seed}, rtf {cfg.rtf:g}, "
         f"{layout}; logs in {cfg.run_dir / 'logs'}")

    shm_before = shm.snapshot()
    orch = Orchestrator(cfg)
    stop = _StopFlag()
    old_handlers = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    outcome = None
    try:
        orch.start()
        while True:
            if stop.signum is not None:
                outcome = Outcome(ended_by="interrupted")
                break
            outcome = orch.step()
            if outcome is not None:
                break
            time.sleep(POLL_PERIOD_S)
    except RunError as exc:
        outcome = Outcome(EXIT_RUNTIME, str(exc), "failed to start")
    finally:
        wall_s = orch.shutdown(outcome.ended_by if outcome else "error")
        # Our metrics node still maps the segments of peers that died; that use does not count.
        removed = shm.clean_stale(shm_before, ignore_pids=frozenset({os.getpid()}))
        for sig, handler in old_handlers.items():
            signal.signal(sig, handler)
    if removed:
        _say(f"removed {len(removed)} stale shared-memory files from /dev/shm")
    orch.report(outcome, wall_s)
    if outcome.error:
        print(f"{PROG}: error: {outcome.error}", file=sys.stderr, flush=True)
    return outcome.code


class _Collect(logging.Handler):
    """Keeps the log records of the shared loaders while the flags are checked."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(record.getMessage())


def validate_quietly(args: argparse.Namespace) -> tuple[RunConfig, list[str]]:
    """:func:`validate`, holding back the loaders' warnings (so bad input gives one line).

    Returns:
        The config and the warnings the loaders logged.
    """
    logger = logging.getLogger("swarm_common")
    handler, propagate = _Collect(), logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        return validate(args), handler.lines
    finally:
        logger.removeHandler(handler)
        logger.propagate = propagate


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-up``; returns the exit code (0, 1 or 2)."""

    def body() -> int:
        args = build_parser().parse_args(argv)
        cfg, warnings = validate_quietly(args)
        for line in dict.fromkeys(warnings):
            _warn(line)
        try:
            return run(cfg)
        except RunError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr, flush=True)
            return EXIT_RUNTIME

    return _run_cli(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
