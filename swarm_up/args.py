"""``swarm-up``'s flags and their validation: the parser, :class:`RunConfig` and :func:`validate`.

Every flag is checked here, before anything is started or written: a bad one is an
:class:`~swarm_common.errors.InputError` naming it (exit 2, one line).  The world, robot, map,
points of interest and navigator template are loaded with the same strict loaders the simulator
and the navigators use, and the spawn area is checked to hold ``--swarm-size`` robots.
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import time
from pathlib import Path

from swarm_common import cli, paths
from swarm_common.errors import InputError
from swarm_scene import world as world_io
from swarm_scene.map_io import load_map
from swarm_scene.poi import poi_for_world
from swarm_scene.robot_model import load_robot
from swarm_scene.spawn import spawn_poses
from swarm_up import PROG
from swarm_up.run_config import PER_ROBOT, RunConfig
from swarm_up.rundir import check_nav_template, load_nav_template

# Default layout: one process per robot (and one per commander) up to this many robots, else one
# group process per core.  Each rclpy process is a DDS participant of ~75 MB whose start costs ~1 s
# of CPU; 20 robots with commanders as 41 processes took minutes to come up on 2 cores.  Groups are
# faster at small sizes too (5 robots on 2 cores, --commanders --rtf 0 --duration 300: RTF 7.8
# and 391 MB per robot per-robot, 14.0 and 135 MB as 2 groups, the same simulated run), but with
# 3 robots in groups a recording lost one robot's first 8 simulated s of cmd_vel (the recorder
# matched the group's writers late; the simulator's start gate waited only for its own).  The
# navigators' first answer now waits for the recorder (wait_for_cmd_vel_readers); per-robot stays
# the default here until a bench round measures the switch.
PER_ROBOT_MAX = 8
# Fast DDS gives the participants of one domain on one host the unicast ports
# 7410 + 250 * domain + 2 * id: participant 120 and up take the next domain's ports (RTPS
# 2.2, 9.6.1.1, PB 7400, DG 250, PG 2, d1 10), and a run of more (tried: more than about 120
# rclpy processes on one host) had its participants spill into other domains' discovery.
MAX_PARTICIPANTS_PER_HOST = 120
DEFAULT_READY_TIMEOUT_S = 120.0
RECORD_IN_RUN_DIR = Path("recording.mcap")  # --record without a path: in the run directory
DEFAULT_DASHBOARD_PORT = 8080
DEFAULT_FOXGLOVE_PORT = 8765  # Foxglove's default for its WebSocket protocol
DEFAULT_SWARM_SIZE = 5  # robots, without --swarm-size or a --robot mix


# ---------------------------------------------------------------------------------------- parsing
def processes_arg(text: str) -> str | int:
    """argparse type of ``--processes``: ``per-robot`` or a positive number of group processes."""
    if text == PER_ROBOT:
        return PER_ROBOT
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise argparse.ArgumentTypeError(
            f"must be 'per-robot' or a positive number of processes, got {text!r}")
    return value


def default_processes(n: int) -> str | int:
    """The process layout for ``n`` robots without ``--processes``: see :data:`PER_ROBOT_MAX`."""
    return PER_ROBOT if n <= PER_ROBOT_MAX else (os.cpu_count() or 1)


def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-up`` argument parser (docs/reference/contract.md#s2)."""
    p = cli.ArgumentParser(
        prog=PROG,
        allow_abbrev=False,
        description="Bring up a simulated swarm: the simulator, one navigator per robot "
        "(and commanders), supervise it, and measure it.",
        epilog="Exit codes: 0 success, 2 bad input, 1 runtime failure. "
        "Ctrl-C stops every process within 5 s.",
    )
    _add_run_flags(p)
    _add_output_flags(p)
    _add_process_flags(p)
    _add_host_flags(p)
    return p


def _add_run_flags(p: argparse.ArgumentParser) -> None:
    """What runs: the swarm, the world, the robots, time, commanders and coordination."""
    cli.add_shared(p, "--swarm-size", default=None,
                   help=f"number of robots (default: {DEFAULT_SWARM_SIZE}, or the total of a "
                   "--robot mix)")
    cli.add_shared(p, "--world", help="a world under worlds/ or a Gazebo .world/.sdf path "
                   "(default: %(default)s)")
    p.add_argument("--map", type=Path, default=None, metavar="PATH",
                   help="map_server map YAML (default: the world's map under maps/, "
                   "else rasterised from the world)")
    cli.add_shared(p, "--robot",
                   help="a robot under robots/ or a .urdf/.xacro path; or a mixed fleet "
                   "NAME:COUNT,NAME:COUNT,... (e.g. turtlebot3_waffle:12,turtlebot3_burger:4,"
                   "linorobot2_2wd:4; the counts add up to --swarm-size) or a fleet .yaml "
                   "file (docs/guides/robots_and_fleets.md); the models are interleaved over "
                   "the robot numbers (default: %(default)s)")
    cli.add_shared(p, "--name-prefix",
                   help="robot namespaces are /<PREFIX><i>, i = 1..N (default: %(default)s)")
    cli.add_shared(p, "--seed", help="seed of every random choice (default: %(default)s)")
    p.add_argument("--rtf", type=cli.non_negative_float, default=1.0, metavar="X",
                   help="real-time factor; 0 = as fast as possible (default: %(default)s)")
    p.add_argument("--duration", type=cli.positive_float, default=None, metavar="SEC",
                   help="simulated seconds to run (default: until Ctrl-C)")
    p.add_argument("--commanders", action="store_true",
                   help="start a commander for every robot (visits the workstations)")
    p.add_argument("--service-time", type=cli.non_negative_float, default=None, metavar="SEC",
                   help="with --commanders: simulated seconds a robot stays docked at a "
                   "workstation it reached before it leaves (default: the world's "
                   "service_time, else 0)")
    p.add_argument("--coordination", choices=("decentralized", "centralized"),
                   default="decentralized",
                   help="decentralized (default): every robot chooses its tasks; centralized: "
                   "a coordinator (swarm-coordinator, child 'coordinator') assigns tasks and "
                   "reserves workstations and waiting spots; needs --commanders")
    from swarm_coordinator.node import add_policy_args

    add_policy_args(p.add_argument_group(
        "centralized coordination", "the coordinator's policy (with --coordination "
        "centralized; docs/guides/coordination.md)"), defaults=False)


def _add_output_flags(p: argparse.ArgumentParser) -> None:
    """What the run writes and serves: metrics, recording, dashboard, Foxglove, markers."""
    p.add_argument("--metrics", type=Path, default=None, metavar="PATH",
                   help="write the run's figures as JSON here at exit (always also "
                   "RUN/metrics.json)")
    p.add_argument("--record", type=Path, nargs="?", const=RECORD_IN_RUN_DIR, default=None,
                   metavar="PATH.mcap",
                   help="record the run to a rosbag2-compatible MCAP file (Foxglove, "
                   "ros2 bag info/play, swarm-plot); without PATH: RUN/recording.mcap")
    p.add_argument("--record-topics", default=None, metavar="REGEX",
                   help="with --record: only the topics whose name matches REGEX (Python "
                   "re.search), e.g. 'odom|ground_truth|/tf|events'")
    p.add_argument("--dashboard", type=cli.port, nargs="?", const=DEFAULT_DASHBOARD_PORT,
                   default=None, metavar="PORT",
                   help="serve a live web dashboard on http://127.0.0.1:PORT/ (default port "
                   f"{DEFAULT_DASHBOARD_PORT}); also publishes /swarm/markers")
    p.add_argument("--foxglove", type=cli.port, nargs="?", const=DEFAULT_FOXGLOVE_PORT,
                   default=None, metavar="PORT",
                   help="serve the run live to Foxglove or Lichtblick over the Foxglove "
                   "WebSocket protocol on ws://127.0.0.1:PORT (default port "
                   f"{DEFAULT_FOXGLOVE_PORT}): map, robots, scans, plans, workstations, "
                   "collisions, nav_status, simulated clock; goals published on "
                   "/<ns>/goal_pose drive that robot (docs/guides/foxglove.md)")
    p.add_argument("--markers", action="store_true",
                   help="publish /swarm/markers (visualization_msgs/MarkerArray in map) for "
                   "RViz2 or Foxglove")
    p.add_argument("--no-tf", dest="tf", action="store_false",
                   help="do not publish /tf, /tf_static and each robot's robot_description "
                   "(default: published; /tf only while it has a subscriber)")


def _add_process_flags(p: argparse.ArgumentParser) -> None:
    """How it runs: faults, the process layout, the window, the run directory, timeouts."""
    cores = os.cpu_count() or 1
    p.add_argument("--faults", default=None, metavar="SPEC",
                   help="inject faults at simulated times: a comma-separated list of "
                   "KIND[:TARGET]@TIME[+DURATION] (kill-nav:3@60, kill-robot:3@60, "
                   "freeze:2@30+20, drop:2/scan:0.5@30+20, kill-coordinator@120[+10]) or a "
                   "YAML file (docs/guides/faults.md)")
    p.add_argument("--processes", type=processes_arg, default=None, metavar="per-robot|K",
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
    p.add_argument("--ready-timeout", type=cli.positive_float, default=DEFAULT_READY_TIMEOUT_S,
                   metavar="SEC", help="wall seconds to wait for every navigator to be ready "
                   "(default: %(default)s)")
    p.add_argument("--nav-params", type=Path, default=None, metavar="PATH",
                   help="navigator parameter template (default: params/navigator.yaml)")


def _add_host_flags(p: argparse.ArgumentParser) -> None:
    """Several hosts (docs/guides/multi_host.md)."""
    hosts = p.add_argument_group(
        "several hosts", "one swarm over N hosts: run swarm-up with the same run flags on every "
        "host, each with its own --host-rank (docs/guides/multi_host.md)")
    hosts.add_argument("--hosts", type=cli.positive_int, default=1, metavar="N",
                       help="hosts the swarm runs on (default: %(default)s)")
    hosts.add_argument("--host-rank", type=cli.non_negative_int, default=0, metavar="R",
                       help="this host's rank, 0..N-1; rank 0 runs the simulator, the metrics, "
                       "the coordinator, the dashboard and the recorder (default: %(default)s)")
    hosts.add_argument("--host-weights", type=cli.positive_floats, default=None,
                       metavar="W,W,...",
                       help="one weight per host: robot after robot goes to the host whose "
                       "share is furthest behind its weight (default: equal: robot i on host "
                       "i mod N)")
    hosts.add_argument("--discovery-server", type=cli.host_port, default=None,
                       metavar="HOST:PORT",
                       help="use Fast DDS's Discovery Server at HOST:PORT (rank 0 starts it; "
                       "HOST must be rank 0's address) instead of multicast discovery")
    hosts.add_argument("--peers", type=cli.hosts, default=None, metavar="HOST,HOST,...",
                       help="the run's other hosts: discover only this host and these "
                       "(no multicast), so a ROS process elsewhere on the network, even on the "
                       "same ROS_DOMAIN_ID, neither sees the run nor is seen by it "
                       "(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, ROS_STATIC_PEERS; "
                       "docs/guides/multi_host.md)")
    hosts.add_argument("--rank-timeout", type=cli.positive_float, default=10.0, metavar="SEC",
                       help="wall seconds a rank may be silent before it counts as lost "
                       "(default: %(default)s)")
    hosts.add_argument("--on-rank-loss", choices=("end", "continue"), default="end",
                       help="when a rank is lost: end the run (exit 1, metrics written) or "
                       "continue without its robots (default: %(default)s)")



# ------------------------------------------------------------------------------------- validation
def _prefix(flag: str, exc: InputError) -> InputError:
    msg = str(exc)
    return InputError(msg if msg.startswith(flag) else f"{flag}: {msg}")


def resolve_world(value: str) -> Path:
    """The world file for ``--world`` (a name under ``worlds/`` or a path).

    Raises:
        InputError: unknown name or missing file (names ``--world``).
    """
    try:
        return Path(world_io.resolve_world(value)).resolve()
    except InputError as exc:
        raise _prefix("--world", exc) from None


def resolve_robot(value: str) -> str:
    """Check one robot model (a name under ``robots/`` or a ``.urdf``/``.xacro`` path) by
    loading it.

    Returns:
        The name as given, or the absolute path of a robot given by path.

    Raises:
        InputError: unknown name, missing or unreadable file (names ``--robot``).
    """
    as_path = Path(value)
    is_path = os.sep in value or value.endswith((".urdf", ".xacro"))
    try:
        load_robot(as_path.resolve() if is_path else value)
    except InputError as exc:
        raise _prefix("--robot", exc) from None
    return str(as_path.resolve()) if is_path else value


def resolve_fleet(value: str, swarm_size: int | None) -> tuple[str, tuple[str, ...], int]:
    """Check ``--robot`` (one model, a mix ``NAME:COUNT,...`` or a fleet file) and the swarm
    size against it, loading every model (:mod:`swarm_scene.fleet`).

    Args:
        value: ``--robot``'s value.
        swarm_size: ``--swarm-size``, or None when not given (then the mix's total, or
            :data:`DEFAULT_SWARM_SIZE` for one model).

    Returns:
        ``(robot, fleet, n)``: ``--robot`` as the simulator gets it (:attr:`RunConfig.robot`),
        the model of every robot (empty for one model) and the number of robots.

    Raises:
        InputError: a malformed mix or fleet file, a count that is not a positive integer, an
            unknown or unloadable model, or counts that do not add up to ``--swarm-size`` (names
            ``--robot``).
    """
    from swarm_scene import fleet as fleet_io

    try:
        entries = fleet_io.parse_fleet(value)
    except InputError as exc:
        raise _prefix("--robot", exc) from None
    if entries[0][1] is None:
        n = swarm_size if swarm_size is not None else DEFAULT_SWARM_SIZE
        return resolve_robot(entries[0][0]), (), n
    entries = tuple((resolve_robot(model), count) for model, count in entries)
    robot = fleet_io.format_fleet(entries)
    n = swarm_size if swarm_size is not None else sum(count for _, count in entries)
    try:
        models = fleet_io.fleet_models(robot, n)
    except InputError as exc:
        raise _prefix("--robot", exc) from None
    return robot, models, n


def _check_world_and_fit(world_path: Path, poi, robot: str, n: int,
                         models: tuple[str, ...] = ()) -> None:
    """Load the world and, when it has a spawn area, check that ``n`` robots fit in it (spaced
    for the largest of ``models``, else for ``robot``).

    Raises:
        InputError: a malformed world (names ``--world``), or too many robots (names
            ``--swarm-size`` and says how many fit).
    """
    try:
        world = world_io.load_world(world_path)
    except InputError as exc:
        raise _prefix("--world", exc) from None
    if poi is not None and poi.spawn is not None:
        radius = max(load_robot(m).radius for m in (models or (robot,)))
        spawn_poses(poi.spawn, n, radius, world_io.world_polygons(world),
                    where=f"spawn area of {world.name} ({poi.source})")


def _check_map(map_path: Path) -> Path:
    if not map_path.is_file():
        raise InputError(f"--map: no such file '{map_path}'")
    try:
        load_map(map_path)
    except InputError as exc:
        raise _prefix("--map", exc) from None
    return map_path.resolve()




def _check_nav_template(path: Path) -> None:
    """Load the navigator template strictly (:func:`swarm_up.rundir.check_nav_template`).

    Raises:
        InputError: not a template, or a misspelt or invalid parameter (names ``--nav-params``,
            the file and the key).
    """
    try:
        check_nav_template(path, load_nav_template(path))
    except InputError as exc:
        raise _prefix("--nav-params", exc) from None


def _check_fitted_params(path: Path, models) -> None:
    """Check the navigator parameters of every model as :func:`swarm_up.rundir.robot_params`
    fits them to it (e.g. a template ``min_vel_x`` at or above a slow robot's top speed).

    Raises:
        InputError: names ``--robot``, the model and the parameter.
    """
    from swarm_nav.config import NavigatorConfig
    from swarm_up.rundir import CONTEXT_KEYS, robot_params

    template = load_nav_template(path)
    for model in dict.fromkeys(models):
        params = {**template, **robot_params(template, load_robot(model))}
        try:
            NavigatorConfig.from_flat({k: v for k, v in params.items() if k not in CONTEXT_KEYS})
        except InputError as exc:
            raise InputError(f"--robot: {model}: the navigator parameters fitted to it from "
                             f"{path} are not valid: {exc}") from None


def split_groups(robots: tuple[str, ...], k: int) -> tuple[tuple[str, ...], ...]:
    """Deal robots round-robin into ``k`` groups whose sizes differ by at most one.

    Robot ``i`` (0-based) goes to group ``i % k``. Dealt, not cut into contiguous runs: robots
    with neighbouring numbers spawn side by side and tend to meet the same crowds, and the
    lockstep tick waits for the slowest group, so contiguous groups (Srobot1-50, Srobot51-100)
    ran one process at 100 % CPU and the other at 47 % in a 100-robot profile
    (shared/reference/profile_100.md).

    Args:
        robots: namespaces.
        k: number of groups (clamped to 1..len(robots)).

    Returns:
        The groups; each keeps the robots' order.
    """
    k = max(1, min(k, len(robots)))
    return tuple(tuple(robots[g::k]) for g in range(k))


def participants(n: int, commanders: bool, coordinator: bool, recorder: bool,
                 groups: int | None = None, leader: bool = True, hosts: int = 1,
                 discovery_server: bool = False) -> int:
    """The DDS participants (one per rclpy context) one host runs: the navigators and
    commanders of its ``n`` robots (a process each, or ``groups`` group processes), swarm-up's
    announcer of fault acknowledgements and lost robots, and its link to the other hosts
    (``hosts`` above 1); rank 0 (``leader``) also the simulator, swarm-up's metrics listener,
    the coordinator, the recorder and the Discovery Server."""
    robots = (2 * n if commanders else n) if groups is None else groups
    own = 1 + int(hosts > 1)
    if leader:
        own += 1 + 1 + int(coordinator) + int(recorder) + int(discovery_server)
    return robots + own


def _check_participants(n: int, commanders: bool, coordinator: bool, recorder: bool,
                        leader: bool = True, hosts: int = 1,
                        discovery_server: bool = False) -> None:
    """``--processes per-robot`` only as far as one host serves the participants."""
    need = participants(n, commanders, coordinator, recorder, None, leader, hosts,
                        discovery_server)
    if need > MAX_PARTICIPANTS_PER_HOST:
        raise InputError(
            f"--processes: per-robot runs {n} robots as {need} DDS participants (a process "
            f"each for every navigator{' and commander' if commanders else ''}), more than the "
            f"{MAX_PARTICIPANTS_PER_HOST} Fast DDS serves on one host; use --processes K (K "
            f"group processes, the default above {PER_ROBOT_MAX} robots)")


def validate(args: argparse.Namespace) -> RunConfig:
    """Turn parsed arguments into a :class:`RunConfig`, checking every flag and file.

    Raises:
        InputError: the first bad flag or file (the one line shown, naming it).
    """
    policy = _check_modes(args)
    _check_outputs(args)
    nav_template = _check_nav_params(args)

    map_path = _check_map(args.map) if args.map is not None else None
    world_path = resolve_world(args.world)
    if map_path is None:
        map_path = paths.default_map_for(world_path)
    poi = poi_for_world(world_path)  # a bad file: InputError names it
    _check_workstations(args, world_path, poi)
    robot, fleet, n = resolve_fleet(args.robot, args.swarm_size)
    if nav_template.is_file():
        _check_fitted_params(nav_template, fleet or (robot,))
    _check_world_and_fit(world_path, poi, robot, n, fleet)
    robots = tuple(f"{args.name_prefix}{i}" for i in range(1, n + 1))
    host_robots, weights = _check_hosts(args, robots)
    local = host_robots[args.host_rank] if host_robots else robots
    processes = args.processes
    if processes is None:
        processes = default_processes(len(local))
    groups = None if processes == PER_ROBOT else split_groups(local, int(processes))
    if groups is None:
        _check_participants(len(local), args.commanders, args.coordination == "centralized",
                            args.record is not None, args.host_rank == 0, args.hosts,
                            args.discovery_server is not None)

    faults = check_faults(args.faults, robots, args.name_prefix, args.duration)
    _check_peers(args, faults)
    run_dir = args.run_dir if args.run_dir is not None else default_run_dir()
    record_path = check_record(args.record, args.record_topics, robots,
                               run_dir.expanduser().resolve())
    return RunConfig(
        robots=robots,
        name_prefix=args.name_prefix,
        world_path=world_path,
        world_name=world_path.stem,
        robot=robot,
        map_path=map_path,
        poi_path=None if poi is None else poi.source,
        seed=args.seed,
        rtf=args.rtf,
        duration=args.duration,
        commanders=args.commanders,
        coordination=args.coordination,
        coordinator_args=policy,
        service_time=(args.service_time if args.service_time is not None
                      else poi.service_time if poi is not None else 0.0),
        metrics_path=args.metrics.expanduser().resolve() if args.metrics else None,
        groups=groups,
        gui=args.gui,
        run_dir=run_dir.expanduser().resolve(),
        ready_timeout=args.ready_timeout,
        nav_template=nav_template,
        faults=faults,
        record_path=record_path,
        record_topics=args.record_topics,
        dashboard_port=args.dashboard,
        foxglove_port=args.foxglove,
        markers=args.markers or args.dashboard is not None,
        tf=args.tf,
        fleet=fleet,
        hosts=args.hosts,
        rank=args.host_rank,
        host_robots=host_robots,
        host_weights=weights,
        discovery_server=args.discovery_server,
        peers=tuple(args.peers or ()),
        rank_timeout=args.rank_timeout,
        on_rank_loss=args.on_rank_loss,
    )


def _check_modes(args: argparse.Namespace) -> list[str]:
    """The coordination flags agree; returns the coordinator's policy argv.

    Raises:
        InputError: a policy flag without centralized coordination, centralized or
            ``--service-time`` without commanders.
    """
    from swarm_coordinator.node import policy_argv

    policy = policy_argv(args)
    if policy and args.coordination != "centralized":
        raise InputError(f"{policy[0]}: needs --coordination centralized (only the "
                         "coordinator has a policy)")
    if args.coordination == "centralized" and not args.commanders:
        raise InputError("--coordination: centralized needs --commanders (the coordinator "
                         "assigns the commanders' tasks)")
    pipelined_only = [f"--{k.replace('_', '-')}" for k in ("eta_speed", "dock_clear", "lease",
                                                            "queue_at")
                      if getattr(args, k, None) is not None]
    if pipelined_only and getattr(args, "policy", None) != "pipelined":
        raise InputError(f"{pipelined_only[0]}: needs --policy pipelined (the reserve policy "
                         "has no time windows)")
    if args.service_time is not None and not args.commanders:
        raise InputError("--service-time: needs --commanders (a robot stays at a workstation "
                         "its commander sent it to)")
    return policy


def _check_workstations(args: argparse.Namespace, world_path: Path, poi) -> None:
    """Commanders have workstations to visit (each takes a random route over the world's
    workstations: :func:`swarm_commander.route.make_route`).

    Raises:
        InputError: ``--commanders`` on a world without workstations (names the flag, the world
            and where its workstations would be).
    """
    if not args.commanders:
        return
    if poi is None or not poi.workstations:
        where = (f"none in {poi.source.name}" if poi is not None and poi.source is not None
                 else f"no {world_path.with_suffix('.yaml').name} beside it")
        raise InputError(f"--commanders: world {world_path.stem} has no workstations to visit "
                         f"({where}); run it without --commanders, or add workstations")


def _check_outputs(args: argparse.Namespace) -> None:
    """The ports, the metrics file and the run directory can be used.

    Raises:
        InputError: a port taken or twice, a metrics path in no directory, a run directory
            that is a file.
    """
    if args.dashboard is not None:
        from swarm_viz.server import check_port

        check_port(args.dashboard)
    if args.foxglove is not None:
        from swarm_viz.server import check_port

        if args.foxglove == args.dashboard:
            raise InputError(f"--foxglove: port {args.foxglove} is --dashboard's")
        check_port(args.foxglove, flag="--foxglove")
    if args.metrics is not None:
        parent = args.metrics.expanduser().resolve().parent
        if not parent.is_dir():
            raise InputError(f"--metrics: directory '{parent}' does not exist")
        if args.metrics.is_dir():
            raise InputError(f"--metrics: '{args.metrics}' is a directory")
    if args.run_dir is not None and args.run_dir.exists() and not args.run_dir.is_dir():
        raise InputError(f"--run-dir: '{args.run_dir}' exists and is not a directory")


def _check_nav_params(args: argparse.Namespace) -> Path:
    """The navigator's parameter template (``--nav-params`` or the default), checked.

    Raises:
        InputError: ``--nav-params`` names no file, or the template is malformed.
    """
    nav_template = args.nav_params if args.nav_params is not None else (
        paths.PARAMS_DIR / "navigator.yaml")
    if args.nav_params is not None and not args.nav_params.is_file():
        raise InputError(f"--nav-params: no such file '{args.nav_params}'")
    if nav_template.is_file():  # the default one missing is an installation problem (exit 1)
        _check_nav_template(nav_template)
    return nav_template


def _check_hosts(args: argparse.Namespace, robots: tuple[str, ...]
                 ) -> tuple[tuple[tuple[str, ...], ...], tuple[float, ...]]:
    """Check ``--hosts``, ``--host-rank`` and ``--host-weights``.

    Returns:
        ``(host_robots, weights)``: the robots of every rank (empty with one host) and the
        weights (empty: equal).

    Raises:
        InputError: a rank not below N, a weight per host missing or extra, or a host left
            without a robot.
    """
    from swarm_up.hosts import assign_robots

    n_hosts = args.hosts
    if args.host_rank >= n_hosts:
        raise InputError(f"--host-rank: {args.host_rank} is not a rank of {n_hosts} host(s) "
                         f"(0..{n_hosts - 1})")
    weights = tuple(args.host_weights or ())
    if weights and len(weights) != n_hosts:
        raise InputError(f"--host-weights: {len(weights)} weight(s) for {n_hosts} hosts")
    if n_hosts == 1:
        return (), weights
    host_robots = assign_robots(robots, n_hosts, weights)
    empty = [r for r, rob in enumerate(host_robots) if not rob]
    if empty:
        raise InputError(f"--hosts: rank {empty[0]} would run no robot ({len(robots)} robots "
                         f"over {n_hosts} hosts{' with these weights' if weights else ''})")
    return host_robots, weights


def _check_peers(args: argparse.Namespace, faults) -> None:
    """``--peers`` only between several hosts, without the Discovery Server, without faults
    that kill processes, and without centralized coordination.

    A process a fault may SIGKILL, and the coordinator, run without Fast DDS's shared memory,
    which under the range LOCALHOST rmw_fastrtps does not allow
    (:func:`swarm_up.children.shm_free_env`): such a process could not reach the peers, and the
    coordinator must reach every host's commanders.

    Raises:
        InputError: one of those combinations.
    """
    if args.peers is None:
        return
    if args.hosts < 2:
        raise InputError("--peers: only with --hosts N > 1 (the other hosts' addresses)")
    if args.discovery_server is not None:
        raise InputError("--peers: not with --discovery-server (the server already decides "
                         "who is discovered)")
    if args.coordination == "centralized":
        raise InputError("--peers: not with --coordination centralized (the coordinator runs "
                         "without shared memory, which the discovery range LOCALHOST does not "
                         "allow, and could not reach the other hosts)")
    from swarm_common.faults import KILL_COORDINATOR, KILL_NAV, KILL_ROBOT

    killing = [f.label() for f in faults if f.kind in (KILL_NAV, KILL_ROBOT, KILL_COORDINATOR)]
    if killing:
        raise InputError(f"--peers: not with faults that kill a process ({killing[0]}): such a "
                         "process runs without shared memory, which the discovery range "
                         "LOCALHOST does not allow")


def check_faults(spec: str | None, robots: tuple[str, ...], prefix: str,
                 duration: float | None) -> tuple:
    """Parse ``--faults`` (:func:`swarm_common.faults.parse_faults`).

    Raises:
        InputError: a malformed spec or file (names ``--faults``).
    """
    if spec is None:
        return ()
    from swarm_common.faults import parse_faults

    try:
        return parse_faults(spec, robots, prefix, duration)
    except InputError as exc:
        raise _prefix("--faults", exc) from None


def check_record(record: Path | None, topics: str | None, robots: tuple[str, ...],
                 run_dir: Path) -> Path | None:
    """Check ``--record`` and ``--record-topics``.

    Args:
        record: ``--record``'s value (:data:`RECORD_IN_RUN_DIR` without a path), or None.
        topics: ``--record-topics``'s regular expression, or None.
        robots: the namespaces (the topics a regex may match).
        run_dir: the run directory (absolute).

    Returns:
        The recording's absolute path, or None without ``--record``.

    Raises:
        InputError: ``--record-topics`` without ``--record``, not a regular expression or
            matching no topic; a recording path that does not end in ``.mcap``, is a
            directory or lies in a missing directory.
    """
    from swarm_record.mcap_format import recorded_topics, select_topics

    if record is None:
        if topics is not None:
            raise InputError("--record-topics: needs --record")
        return None
    if topics is not None:
        try:
            chosen = select_topics(recorded_topics(robots), topics)
        except re.error as exc:
            raise InputError(f"--record-topics: not a regular expression: {exc}") from None
        if not chosen:
            raise InputError(f"--record-topics: '{topics}' matches no recorded topic (/clock, "
                             f"/map, /swarm/events, /tf, /{robots[0]}/scan|odom|ground_truth|"
                             "cmd_vel|plan|nav_status ...)")
    if record is RECORD_IN_RUN_DIR:
        return run_dir / RECORD_IN_RUN_DIR
    path = record.expanduser()
    if path.suffix != ".mcap":
        raise InputError(f"--record: '{record}' must end in .mcap")
    if path.is_dir():
        raise InputError(f"--record: '{record}' is a directory")
    if not path.resolve().parent.is_dir():
        raise InputError(f"--record: directory '{path.resolve().parent}' does not exist")
    return path.resolve()


def default_run_dir(base: Path | None = None, prefix: str = "") -> Path:
    """``runs/<prefix><YYYYmmdd-HHMMSS>`` (``-2``, ``-3`` ... if taken) under ``base`` (cwd)."""
    base = Path("runs") if base is None else base
    stamp = prefix + time.strftime("%Y%m%d-%H%M%S")
    candidate, i = base / stamp, 1
    while candidate.exists():
        i += 1
        candidate = base / f"{stamp}-{i}"
    return candidate


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
    logger = logging.getLogger("swarm_scene")
    handler, propagate = _Collect(), logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        return validate(args), handler.lines
    finally:
        logger.removeHandler(handler)
        logger.propagate = propagate

