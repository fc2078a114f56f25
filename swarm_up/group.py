"""Several robots' navigators (and commanders) in one process, under one ``EventsExecutor``.

Every rclpy process is one DDS participant and costs about 75 MB; 100 of them on 2 cores stall
discovery, while 100 robots' nodes grouped into a few processes deliver every message.  Each
robot keeps its own nodes, parameters and state: grouping shares the process, not the navigator.
With ``--sensors`` (what swarm-up runs) the process renders its robots' scans from the
simulator's robot states and feeds its navigators (:mod:`swarm_up.feed`); the navigators'
answers to a control tick leave in one message (:mod:`swarm_up.answers`).

Usage (what ``swarm-up --processes K`` runs)::

    python -m swarm_up.group --namespaces Srobot1,Srobot3 --params-dir RUN/params \\
        --world slim_blockage --seed 0 --sensors --robot turtlebot3_waffle --swarm-size 4 \\
        [--commanders]

The params file of robot ``ns`` is ``<params-dir>/<ns>.yaml``, rooted at ``/<ns>/navigator``.

It lives in ``swarm_up``, beside the orchestrator that starts it, because it hosts both the
navigators (:mod:`swarm_nav.node`) and their clients, the commanders (:mod:`swarm_commander`):
the navigator package never imports its own client.
"""

from __future__ import annotations

import sys
from pathlib import Path

import rclpy
from rclpy.experimental import EventsExecutor

from swarm_common import cli
from swarm_common.errors import InputError, run_cli
from swarm_common.stamps import NS_PER_S
from swarm_nav.node import NavigatorNode
from swarm_nav.planner import share_cost_to_go
from swarm_ros.session import node_session, spin_forever
from swarm_up.answers import AnswerBatch, spin_batched
from swarm_up.clock import SharedClock
from swarm_up.feed import SensorFeed

PROG = "swarm_up.group"


def build_parser() -> cli.ArgumentParser:
    """The command line of a navigator group."""
    p = cli.ArgumentParser(prog=f"python -m {PROG}", description=__doc__.split("\n\n")[0])
    p.add_argument("--namespaces", required=True, type=cli.ros_names,
                   help="comma-separated robot namespaces without '/', e.g. Srobot1,Srobot2")
    p.add_argument("--params-dir", required=True, type=Path,
                   help="directory holding <ns>.yaml for every namespace")
    p.add_argument("--commanders", action="store_true",
                   help="also run a commander for every robot (random workstation route)")
    cli.add_shared(p, "--world", help="world of the commanders' route")
    cli.add_shared(p, "--seed", help="seed of the commanders' routes")
    p.add_argument("--loops", type=cli.non_negative_int, default=0,
                   help="commander route loops, 0 = forever")
    p.add_argument("--service-time", type=cli.non_negative_float, default=None, metavar="SEC",
                   help="simulated seconds a robot stays at a workstation it reached (the "
                   "commanders' --service-time; default: the world's service_time, else 0)")
    p.add_argument("--faults", default=None, metavar="FILE",
                   help="the run's fault schedule: carry out the kill-nav and kill-robot faults "
                   "of /swarm/events for these robots in-process (swarm_up.faults.GroupFaults); "
                   "coordinated commanders learn the coordinator's outages from it")
    p.add_argument("--coordinated", action="store_true",
                   help="the commanders ask the coordinator for their tasks "
                   "(swarm-up --coordination centralized)")
    p.add_argument("--coordinator-timeout", type=cli.positive_float, default=120.0,
                   help="wall seconds to wait for the coordinator before the commanders start")
    p.add_argument("--sensors", action="store_true",
                   help="render these robots' scans here and feed the navigators from the "
                   "simulator's /swarm/robot_states (swarm_up.feed); needs the run's --world, "
                   "--robot, --swarm-size, --name-prefix and --seed, as the simulator has them")
    cli.add_shared(p, "--robot", help="the run's robot or fleet (with --sensors)")
    p.add_argument("--swarm-size", type=cli.positive_int, default=None,
                   help="the run's robots, all hosts (with --sensors)")
    p.add_argument("--name-prefix", default="Srobot",
                   help="the run's namespace prefix (with --sensors)")
    p.add_argument("--states-rank", type=cli.non_negative_int, default=0, metavar="R",
                   help="with --sensors: read the states from rank R's relay "
                   "(/swarm/rank<R>/robot_states, swarm_up.relay) instead of the simulator's "
                   "/swarm/robot_states; 0 = the simulator's (default: %(default)s)")
    p.add_argument("--control-rate", type=cli.positive_float, default=10.0,
                   help="the simulator's control ticks per simulated second [Hz] (with "
                   "--sensors)")
    return p


def _run(argv: list[str]) -> int:
    opts = build_parser().parse_args(argv)
    names = opts.namespaces
    files = {ns: opts.params_dir / f"{ns}.yaml" for ns in names}
    missing = [str(f) for f in files.values() if not f.is_file()]
    if missing:
        raise InputError(f"--params-dir: no params file {missing[0]}")
    routes, service = {}, 0.0
    if opts.commanders and not opts.coordinated:
        from swarm_commander.route import build_route, world_service_time

        routes = {ns: build_route(opts.world, opts.seed, ns) for ns in names}
        service = (opts.service_time if opts.service_time is not None
                   else world_service_time(opts.world))

    clock = None  # a SharedClock when this process holds more than one node
    batch = None  # the navigators' answers in one message a tick (with the clock's node)

    sensors = _sensors(opts) if opts.sensors else None
    if sensors is not None and not set(names) <= set(sensors[0]):
        raise InputError(f"--namespaces: {sorted(set(names) - set(sensors[0]))[0]} is no robot "
                         f"of a run of {opts.swarm_size} named {opts.name_prefix}<i>")

    def make_navigator(ns: str) -> NavigatorNode:
        node = NavigatorNode(namespace=f"/{ns}", fed=sensors is not None,
                             cli_args=["--ros-args", "--params-file", str(files[ns])])
        if clock is not None:
            clock.adopt(node)
        node.answers = batch
        return node

    share_cost_to_go(len(names))
    with node_session([PROG]) as owned:
        executor = EventsExecutor()
        if len(names) > 1 or opts.commanders:
            clock = SharedClock(f"/{names[0]}")
            executor.add_node(clock.node)
            owned.append(clock.node)
            batch = AnswerBatch(clock.node)
        nodes, runners = [], []
        navigators, commanders = {}, {}  # ns -> node; ns -> (node, runner): what faults may kill
        faults = None
        try:
            for ns in names:
                node = make_navigator(ns)
                executor.add_node(node)
                nodes.append(node)
                navigators[ns] = node
            if sensors is not None:
                feed_node = clock.node if clock is not None else nodes[0]
                SensorFeed(feed_node, navigators, *sensors,  # kept by its subscription
                           busy=batch.busy if batch is not None else None,
                           warn=feed_node.get_logger().warning,
                           topic=_states_topic(opts.states_rank))
            if opts.commanders and opts.coordinated:
                _add_coordinated_commanders(names, executor, nodes, runners, commanders,
                                            opts.coordinator_timeout, opts.faults)
            elif opts.commanders:
                from rclpy.logging import LoggingSeverity

                from swarm_commander.cli import CommanderConfig, CommanderRunner

                for ns in names:
                    nav = commander_node(ns)
                    nav.get_logger().set_level(LoggingSeverity.WARN)
                    runners.append(CommanderRunner(nav, routes[ns],
                                                   CommanderConfig(loops=opts.loops,
                                                                   service_time=service),
                                                   emit=lambda line: print(line, flush=True)))
                    runners[-1].finished.add_done_callback(_say_error(runners[-1]))
                    executor.add_node(nav)
                    nodes.append(nav)
                    commanders[ns] = (nav, runners[-1])
            if clock is not None:  # the commanders (each navigator was adopted at its creation)
                for node in nodes:
                    clock.adopt(node)
            print(f"{PROG}: {len(names)} navigators{' and commanders' if runners else ''} up: "
                  f"{','.join(names)}", flush=True)
            if opts.faults:
                from swarm_up.faults import GroupFaults

                def gone(node):
                    nodes.remove(node)
                    if clock is not None:
                        clock.forget(node)
                    runners[:] = [r for r in runners if r.nav is not node]

                def added(node):
                    nodes.append(node)
                    if clock is not None:
                        clock.adopt(node)

                faults = GroupFaults(executor, nodes[0].context, names[0], navigators,
                                     commanders, make_navigator, gone, added,
                                     emit=lambda line: print(line, flush=True))
                if batch is not None:
                    spin_batched(executor, nodes[0].context, batch, faults.service, 0.1)
                else:
                    context = nodes[0].context
                    while context.ok():
                        executor.spin_once(timeout_sec=0.1)
                        faults.service()
            elif batch is not None:
                spin_batched(executor, nodes[0].context, batch)
            else:
                spin_forever(executor, nodes[0].context)
        finally:  # the session then destroys the clock node and shuts the context down
            for runner in runners:
                runner.stop()
                if runner.started:
                    print(runner.summary(), flush=True)
            if faults is not None:
                faults.close()
            for node in nodes:
                node.destroy_node()
    return 0


def _states_topic(rank: int):
    """Where ``--states-rank`` says the states come from."""
    from swarm_common import topics

    return topics.rank_robot_states(rank) if rank else topics.ROBOT_STATES


def _sensors(opts) -> tuple:
    """``--sensors``: every robot's namespace, the run's sensors
    (:class:`swarm_sim.sensors.SwarmSensors`, loaded as the simulator loads them:
    :func:`swarm_sim.settings.prepare`), each robot's scan geometry as its navigator reads it,
    and the control period [ns].

    Raises:
        InputError: a flag missing, or a world or robot that does not load.
    """
    from swarm_common.cdr import scan_reading
    from swarm_scene.fleet import fleet_models
    from swarm_scene.robot_model import load_robot
    from swarm_scene.world import load_world, resolve_world
    from swarm_sim.sensors import SwarmSensors

    for flag, value in (("--world", opts.world), ("--robot", opts.robot),
                        ("--swarm-size", opts.swarm_size)):
        if value is None:
            raise InputError(f"{flag}: needed with --sensors")
    world = load_world(resolve_world(opts.world))
    try:
        models = fleet_models(opts.robot, opts.swarm_size)
    except InputError as exc:
        raise InputError(f"--robot: {exc}") from None
    loaded = {name: load_robot(name) for name in dict.fromkeys(models)}
    fleet = [loaded[name] for name in models]
    sensors = SwarmSensors(world, fleet, opts.seed, 1.0 / opts.control_rate)
    meta = []
    for i in range(len(fleet)):
        pattern = sensors.kind_lidars[sensors.kind[i]].pattern
        meta.append(scan_reading(float(pattern.angles[0]), float(pattern.angle_increment),
                                 float(pattern.range_min), float(pattern.range_max)))
    names = [f"{opts.name_prefix}{i + 1}" for i in range(len(fleet))]
    return names, sensors, meta, round(NS_PER_S / opts.control_rate)


def _say_error(runner):
    """A callback for ``runner.finished``: print the runner's error at once (a commander that
    gave up leaves its navigator's tick waiting: the line says why)."""
    def say(_future):
        if runner.error:
            print(f"{PROG}: error: {runner.error}", flush=True)
    return say


def commander_node(ns: str, connect: bool = True):
    """The commander node of robot ``ns`` in a group process: a ``BasicNavigator`` on simulated
    time, without the parameter services and the type description service every rclpy node
    offers by default (REP 2011).  A commander has no parameter but ``use_sim_time``, and those
    seven services are 14 DDS endpoints per node that every process must discover: 700 per
    group of 50.  Creating 50 commanders took 0.59 s with them and 0.20 s without (alone on
    an idle machine; a quarter of a group's start at 100 robots in py-spy, under contention).
    The navigators keep theirs (``ros2 param`` works on them).
    """
    from swarm_commander.robot_navigator import BasicNavigator

    bool_ = rclpy.parameter.Parameter.Type.BOOL
    return BasicNavigator(
        node_name="commander", namespace=ns, connect=connect, start_parameter_services=False,
        parameter_overrides=[rclpy.parameter.Parameter("use_sim_time", bool_, True),
                             rclpy.parameter.Parameter("start_type_description_service", bool_,
                                                       False)])


def _add_coordinated_commanders(names, executor, nodes, runners, commanders: dict,
                                timeout_s: float, faults: str | None) -> None:
    """Wait (spinning the navigators) for the coordinator, then add a coordinated commander
    per robot: the navigators' start gate opens only once the coordinator is there.
    ``commanders`` (ns -> (node, runner), what faults may kill) gets each; ``faults``: the
    schedule's file (the coordinator's outages), or None."""
    from rclpy.logging import LoggingSeverity
    from rclpy.node import Node

    from swarm_commander.coordinated import (
        CoordinatedRunner,
        coordinated_config,
        wait_for_coordinator,
    )

    cfg = coordinated_config(faults)

    watch = Node("coordinator_watch", namespace=names[0])
    executor.add_node(watch)
    try:
        if not wait_for_coordinator(watch, timeout_s,
                                    lambda t: executor.spin_once(timeout_sec=t)):
            print(f"{PROG}: no coordinator after {timeout_s:g} s; commanders start anyway",
                  flush=True)
    finally:
        executor.remove_node(watch)
        watch.destroy_node()
    for ns in names:
        nav = commander_node(ns, connect=False)  # connects once it reaches the coordinator
        nav.get_logger().set_level(LoggingSeverity.WARN)
        runners.append(CoordinatedRunner(nav, cfg, emit=lambda line: print(line, flush=True)))
        runners[-1].finished.add_done_callback(_say_error(runners[-1]))
        executor.add_node(nav)
        nodes.append(nav)
        commanders[ns] = (nav, runners[-1])


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m swarm_up.group``."""
    return run_cli(PROG, lambda: _run(list(sys.argv[1:] if args is None else args)))


if __name__ == "__main__":
    sys.exit(main())
