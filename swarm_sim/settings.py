"""What ``swarm-sim`` is asked to run: its flags, their validation, and the world it loads.

Pure (no ROS): bad input fails here, before ROS starts, with one line (exit 2).  The node that
runs the world is :mod:`swarm_sim.node`.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from dataclasses import dataclass

from swarm_common import cli, topics
from swarm_common.errors import InputError

READER_GRACE_S = 10.0  # [s] wall: how long the start gate waits for --wait-for-reader to match


@dataclass(frozen=True)
class SimSettings:
    """What ``swarm-sim`` was asked to run (command-line flags, validated).

    Attributes:
        world: world name under ``worlds/`` or a path to a ``.world``/``.sdf``.
        robot: robot name under ``robots/`` or a path to a ``.urdf``/``.xacro``; or a mixed
            fleet ``NAME:COUNT,...`` or fleet ``.yaml`` (:mod:`swarm_scene.fleet`).
        swarm_size: number of robots N [-].
        name_prefix: namespace prefix; robot i (1..N) is ``/<prefix><i>``.
        seed: seed of the simulator's random generator (lidar noise).
        rtf: real-time factor to pace to; 0 runs as fast as possible [-].
        duration: simulated seconds to run, or None for until Ctrl-C [s].
        map_path: map_server YAML to publish on ``/map``, or None for the world's map.
        summary: path of the JSON summary written at exit, or None.
        control_rate: control ticks per simulated second [Hz].
        stall_report: wall seconds a tick may wait before the robots it waits for are
            reported (and again every as long); it goes on waiting [s].
        wait_for: robots that must have answered before simulated time starts (the start gate;
            ``swarm-up`` passes N) [-].
        wait_for_reader: a node (``name`` or ``/ns/name``) whose subscriptions to the
            simulator's topics must be matched before simulated time starts (``swarm-up
            --record`` passes its recorder), or None; given up after ``READER_GRACE_S``.
        reader_subscriptions: how many subscriptions of ``wait_for_reader`` to the simulator's
            topics it waits for: those discovered so far are not all of them while discovery
            runs (``swarm-up`` passes the recorder's count,
            :func:`swarm_record.mcap_format.simulator_readers`) [-].
        record_window: hold each tick until the recorder's ``/swarm/record/progress`` is at
            most this many ticks behind (``swarm-up --record`` passes
            :data:`swarm_common.topics.RECORD_WINDOW_TICKS`), or 0 for never; not waited for
            once the progress has no writer (the recorder is gone) [ticks].
        gui: open PyBullet's window.
        tf: publish ``/tf``, ``/tf_static`` and every robot's ``robot_description``
            (:mod:`swarm_sim.tf_publisher`).
        faults: the ``--faults`` SPEC (inline syntax or YAML path, :mod:`swarm_common.faults`),
            or None.
    """

    world: str = "slim_blockage"
    robot: str = "turtlebot3_waffle"
    swarm_size: int = 5
    name_prefix: str = "Srobot"
    seed: int = 0
    rtf: float = 1.0
    duration: float | None = None
    map_path: str | None = None
    summary: str | None = None
    control_rate: float = 10.0  # [Hz]
    stall_report: float = 10.0  # [s] wall
    wait_for: int = 0  # [robots]
    wait_for_reader: str | None = None
    reader_subscriptions: int = 1  # [subscriptions]
    record_window: int = 0  # [ticks]
    gui: bool = False
    faults: str | None = None
    tf: bool = True


def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-sim`` argument parser."""
    p = cli.ArgumentParser(
        prog="swarm-sim",
        description="The swarm simulator node (/swarm_sim): loads a Gazebo world and a URDF "
        "robot, spawns N robots and publishes /clock, /map, /<ns>/scan, /<ns>/odom, "
        "/<ns>/ground_truth, /swarm/events, /tf, /tf_static and /<ns>/robot_description; "
        "drives robots from /<ns>/cmd_vel (geometry_msgs/TwistStamped); serves the "
        "simulation_interfaces services /swarm_sim/get_simulation_state, "
        "set_simulation_state, step_simulation, get_entities, get_entity_state... "
        "(docs/guides/ros2_tools.md).",
        epilog="ROS arguments may follow --ros-args. Exit codes: 0 success, 2 bad input, "
        "1 runtime failure.")
    cli.add_shared(p, "--world",
                   help="world name under worlds/ or path to a .world/.sdf [slim_blockage]")
    cli.add_shared(p, "--robot",
                   help="robot name under robots/ or path to a .urdf/.xacro; or a mixed fleet "
                   "NAME:COUNT,NAME:COUNT,... whose counts add up to --swarm-size, or a fleet "
                   ".yaml file; the models are interleaved over the robot numbers "
                   "[turtlebot3_waffle]")
    cli.add_shared(p, "--swarm-size", default=5, help="number of robots [5]")
    cli.add_shared(p, "--name-prefix",
                   help=f"namespace prefix, a ROS name ({cli.ROS_NAME_RULE}) [Srobot]")
    cli.add_shared(p, "--seed", help="random seed (lidar noise) [0]")
    p.add_argument("--rtf", type=cli.non_negative_float, default=1.0, metavar="X",
                   help="real-time factor to pace to; 0 = as fast as possible [1.0]")
    p.add_argument("--duration", type=cli.positive_float, default=None, metavar="SEC",
                   help="simulated seconds to run [until Ctrl-C]")
    p.add_argument("--map", default=None, metavar="PATH",
                   help="map_server YAML to publish on /map [maps/<world>.yaml, else rasterised]")
    p.add_argument("--summary", default=None, metavar="PATH",
                   help="write a JSON summary of the run here at exit")
    p.add_argument("--control-rate", type=cli.positive_float, default=10.0, metavar="HZ",
                   help="control ticks per simulated second [10]")
    p.add_argument("--stall-report", type=cli.positive_float, default=10.0, metavar="SEC",
                   help="a tick that has waited this many wall seconds for its answers (or a "
                   "fault's acknowledgement) says which; it goes on waiting: no wall-clock "
                   "timeout decides anything simulated [10]")
    p.add_argument("--wait-for", type=cli.non_negative_int, default=0, metavar="K",
                   help="hold simulated time at the first tick until K robots answer it [0]")
    p.add_argument("--wait-for-reader", default=None, metavar="NODE",
                   help="also hold the first tick until NODE's subscriptions to the simulator's "
                   f"topics are matched (given up after {READER_GRACE_S:g} s) [none]")
    p.add_argument("--reader-subscriptions", type=cli.positive_int, default=1, metavar="K",
                   help="with --wait-for-reader: wait until NODE has K subscriptions to the "
                   "simulator's topics, all matched [1]")
    p.add_argument("--record-window", type=cli.non_negative_int, default=0, metavar="TICKS",
                   help="hold each tick until the recorder's /swarm/record/progress is at most "
                   "TICKS ticks behind (swarm-up --record passes "
                   f"{topics.RECORD_WINDOW_TICKS}); 0: never [0]")
    p.add_argument("--faults", default=None, metavar="SPEC",
                   help="inject faults at simulated times: KIND[:TARGET]@TIME[+DURATION],... "
                   "or a YAML file (kinds kill-nav, kill-robot, freeze, drop, kill-coordinator; "
                   "see docs/guides/faults.md) [none]")
    p.add_argument("--gui", action="store_true",
                   help="open the PyBullet window (default headless)")
    p.add_argument("--headless", action="store_true", help="run without a window (the default)")
    p.add_argument("--no-tf", dest="tf", action="store_false",
                   help="do not publish /tf, /tf_static and each robot's robot_description "
                   "(default: published; /tf only while it has a subscriber)")
    return p


def parse_settings(argv: list[str]) -> SimSettings:
    """Parse and validate ``swarm-sim`` flags (ROS arguments already removed).

    Raises:
        InputError: a flag's value is malformed or out of range.
    """
    a = build_parser().parse_args(argv)
    return SimSettings(
        world=a.world, robot=a.robot, swarm_size=a.swarm_size, name_prefix=a.name_prefix,
        seed=a.seed, rtf=a.rtf, duration=a.duration, map_path=a.map, summary=a.summary,
        control_rate=a.control_rate, stall_report=a.stall_report, wait_for=a.wait_for,
        wait_for_reader=a.wait_for_reader, reader_subscriptions=a.reader_subscriptions,
        record_window=a.record_window, gui=a.gui, faults=a.faults, tf=a.tf,
    )


def prepare(settings: SimSettings):
    """Load everything and spawn, before ROS starts, so bad input fails fast and quietly.

    Returns:
        ``(engine, occ, namespaces, spawned, world)``: ``spawned`` says where the robots went
        (:func:`swarm_scene.spawn.describe_spawn`); ``world`` is the loaded world, whose
        ``skipped`` names what of it is not simulated.

    Raises:
        InputError: a missing or malformed world, robot, map or points of interest, bad prefix, or
            more robots than fit.
    """
    from swarm_common.paths import default_map_for
    from swarm_scene.fleet import describe_fleet, fleet_models
    from swarm_scene.map_io import load_map
    from swarm_scene.poi import poi_for_world
    from swarm_scene.rasterize import rasterize_world
    from swarm_scene.robot_model import load_robot
    from swarm_scene.spawn import (
        choose_free_region,
        describe_spawn,
        spawn_poses,
        spawn_poses_free,
    )
    from swarm_scene.world import load_world, resolve_world, world_polygons
    from swarm_sim.engine import EngineConfig, SimEngine

    if not cli.is_ros_name(settings.name_prefix):
        raise InputError(f"--name-prefix: must be a ROS name ({cli.ROS_NAME_RULE}), got "
                         f"{settings.name_prefix!r}")
    world_path = resolve_world(settings.world)
    world = load_world(world_path)
    try:
        names = fleet_models(settings.robot, settings.swarm_size)
    except InputError as exc:
        raise InputError(f"--robot: {exc}") from None
    robots = {name: load_robot(name) for name in dict.fromkeys(names)}
    robot = robots[names[0]] if len(robots) == 1 else [robots[name] for name in names]
    radius = max(model.radius for model in robots.values())  # [m] spaced for the largest
    poi = poi_for_world(world_path)
    default_map = default_map_for(world_path)
    if settings.map_path is not None:
        occ = load_map(settings.map_path)
    elif default_map is not None:
        occ = load_map(default_map)
    else:
        occ = rasterize_world(world)
    polygons = world_polygons(world)
    from_spawn_area = poi is not None and poi.spawn is not None
    region = None
    if from_spawn_area:
        poses = spawn_poses(poi.spawn, settings.swarm_size, radius, polygons,
                            where=f"spawn area of {world.name}")
    else:
        region = choose_free_region(occ)
        poses = spawn_poses_free(occ, settings.swarm_size, radius, polygons,
                                 where=f"free region of {world.name}", region=region)
    config = EngineConfig(control_period=1.0 / settings.control_rate)
    engine = SimEngine(world, robot, poses, seed=settings.seed, config=config, gui=settings.gui)
    namespaces = [f"{settings.name_prefix}{i + 1}" for i in range(settings.swarm_size)]
    spawned = describe_spawn(engine.poses, from_spawn_area,
                             None if poi is None or poi.source is None else poi.source.name,
                             region)
    if len(robots) > 1:
        spawned += f"; robots: {describe_fleet(names)}"
    return engine, occ, namespaces, spawned, world


@contextlib.contextmanager
def held_warnings():
    """Hold back log records of the loaders; emit them only if the block succeeds."""
    records: list[logging.LogRecord] = []

    class _Hold(logging.Handler):
        def emit(self, record):
            records.append(record)

    root = logging.getLogger()
    hold = _Hold(logging.WARNING)
    root.addHandler(hold)
    try:
        yield
    finally:
        root.removeHandler(hold)
    for record in records:
        print(f"swarm-sim: warning: {record.getMessage()}", file=sys.stderr)


def fault_schedule(settings: SimSettings, namespaces: list[str]) -> tuple:
    """The ``--faults`` schedule (:func:`swarm_common.faults.parse_faults`); empty without it.

    Raises:
        InputError: ``--faults`` is malformed or names what the run does not have.
    """
    from swarm_common.faults import parse_faults

    if settings.faults is None:
        return ()
    try:
        return parse_faults(settings.faults, tuple(namespaces), settings.name_prefix,
                            settings.duration)
    except InputError as exc:
        raise InputError(f"--faults: {exc}") from None
