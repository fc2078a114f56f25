"""The child processes of a run, as :class:`~swarm_up.supervisor.ChildSpec`: the simulator, the
navigators (one process per robot, or group processes, :mod:`swarm_up.group`) and the
commanders, with their command lines and log files."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from swarm_up.run_config import RunConfig


def command(script: str, module: str, func: str = "main") -> list[str]:
    """The argv prefix that runs a console script.

    Looks the script up on ``PATH``, then beside this Python (the venv's ``bin/``), else runs
    ``module:func`` with this Python.
    """
    found = shutil.which(script) or shutil.which(script, path=str(Path(sys.executable).parent))
    if found:
        return [found]
    return [sys.executable, "-c", f"import sys; from {module} import {func}; sys.exit({func}())"]


PROFILES_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
"""The variable by which Fast DDS (2.14, rmw_fastrtps) loads an XML profiles file at start-up."""
RANGE_ENV = "ROS_AUTOMATIC_DISCOVERY_RANGE"
LOCALHOST_ONLY_ENV = "ROS_LOCALHOST_ONLY"  # deprecated in Jazzy; "1" overrides the range


STATIC_PEERS_ENV = "ROS_STATIC_PEERS"


def limit_discovery(environ, peers) -> None:
    """Make ``environ`` discover only this host and ``peers`` (``swarm-up --peers``).

    ROS 2 Jazzy's own variables: the range ``LOCALHOST`` (no multicast, unicast discovery of this
    host's participants) and ``ROS_STATIC_PEERS`` (unicast discovery of those addresses, whatever
    the range).  A participant with the default range on another host of the network sends its
    announcements by multicast, which no process of the run listens to, and is sent none.

    Args:
        environ: ``os.environ`` (swarm-up's own participants and, through it, its children's).
        peers: host names or IPv4 addresses.
    """
    environ[RANGE_ENV] = "LOCALHOST"
    environ[STATIC_PEERS_ENV] = ";".join(peers)
    environ.pop(LOCALHOST_ONLY_ENV, None)  # rcl lets it override the range


def shm_free_env(env: dict[str, str]) -> dict[str, str]:
    """``env`` for a process that fault injection may SIGKILL: Fast DDS without shared memory.

    A process killed while it held a shared-memory port's interprocess mutex can leave every
    other process that writes to that port blocked in ``Publisher.publish`` (seen once: the
    simulator stuck in ``SharedMemManager::Port::try_push`` -> ``regenerate_port``; Fast DDS
    2.14.5; docs/ARCHITECTURE.md "Known limits").  A process without the shared-memory
    transport owns no such port; the others reach it over loopback UDP.

    - Range ``LOCALHOST``: rmw_fastrtps 8.4 then sets the transports to shared memory + UDPv4
      whatever a profile says, so the process gets the range ``SUBNET`` and
      ``params/fastdds_udp_loopback.xml``: UDPv4 on the loopback interface only, discovery by
      unicast to 127.0.0.1; it hears and is heard by the same processes as under LOCALHOST.
      ``ROS_LOCALHOST_ONLY=1`` (which rcl lets override the range) counts as LOCALHOST, and is
      turned off for the process.
    - Any other range: ``params/fastdds_udp_only.xml``, UDPv4 alone instead of the built-in
      shared memory + UDPv4 (``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` would do the same, but not
      under LOCALHOST).
    - A profiles file the user set in ``FASTRTPS_DEFAULT_PROFILES_FILE`` is kept, and ``env``
      returned unchanged.

    Args:
        env: the children's environment.

    Returns:
        A copy of ``env`` for the process.
    """
    from swarm_common.paths import FASTDDS_UDP_LOOPBACK_PROFILE, FASTDDS_UDP_ONLY_PROFILE

    out = dict(env)
    if out.get(PROFILES_ENV):
        return out
    if out.get(LOCALHOST_ONLY_ENV) == "1" or out.get(RANGE_ENV, "").upper() == "LOCALHOST":
        if LOCALHOST_ONLY_ENV in out:  # set at all, it makes rcl warn: only when it was
            out[LOCALHOST_ONLY_ENV] = "0"
        out[RANGE_ENV] = "SUBNET"
        out[PROFILES_ENV] = str(FASTDDS_UDP_LOOPBACK_PROFILE)
    else:
        out[PROFILES_ENV] = str(FASTDDS_UDP_ONLY_PROFILE)
    return out


SHM_DEFAULTS = (512 * 1024, 512)
"""Fast DDS 2.14's shared-memory transport: a participant's segment [bytes] (what its writers'
messages wait in until every reader took them) and its port's queue [messages] (what waits to be
read by it)."""
SHM_SIZED_ABOVE = 100
"""Runs of more robots get a shared-memory transport sized to them (:func:`shm_sized_env`)."""
BUILTIN_TRANSPORTS_ENV = "FASTDDS_BUILTIN_TRANSPORTS"


def shm_sizes(robots: int) -> tuple[int, int]:
    """The shared-memory segment [bytes] and port queue [messages] for a run of ``robots``: at
    least Fast DDS's defaults (:data:`SHM_DEFAULTS`), else 8 KB of segment and 4 messages of
    queue per robot, rounded up to a power of two.

    Why: each lidar tick the simulator writes every robot's ``odom`` and ``scan`` (about 2.3 KB)
    at once, and each group process is sent those of its robots, the simulator every robot's
    ``cmd_vel``. With the defaults, 1,000 robots in 2 group processes overflowed them: the
    reliable topics then waited for Fast DDS to send again (its heartbeat, seconds), and a
    simulated second took 27 s of wall time with the cores two-thirds idle; sized so, 5.5 s
    (docs/results/scaling.md#1000-robots-on-one-host).
    """
    def pow2(n: int) -> int:
        return 1 << max(int(n) - 1, 1).bit_length()

    return (max(SHM_DEFAULTS[0], pow2(8 * 1024 * robots)),
            max(SHM_DEFAULTS[1], pow2(4 * robots)))


def shm_profile_xml(segment: int, queue: int, loopback: bool) -> str:
    """A Fast DDS profiles file: shared memory with ``segment`` bytes and a port queue of
    ``queue`` messages, and UDPv4 (on the loopback interface only when ``loopback``: the range
    LOCALHOST done as :func:`shm_free_env` does it, since under LOCALHOST rmw_fastrtps replaces
    a profile's transports by its own defaults).
    Format: https://fast-dds.docs.eprosima.com/en/v2.14.5/fastdds/xml_configuration/transports.html
    """
    udp = peers = ""
    if loopback:
        udp = ("<TTL>0</TTL><maxInitialPeersRange>120</maxInitialPeersRange>"
               "<interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>")
        peers = ("<builtin><initialPeersList><locator><udpv4><address>127.0.0.1</address>"
                 "</udpv4></locator></initialPeersList></builtin>")
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<!-- written by swarm-up for this run (swarm_up/children.py shm_sized_env) -->
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>swarm_shm</transport_id>
      <type>SHM</type>
      <segment_size>{segment}</segment_size>
      <port_queue_capacity>{queue}</port_queue_capacity>
    </transport_descriptor>
    <transport_descriptor>
      <transport_id>swarm_udp</transport_id>
      <type>UDPv4</type>{udp}
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="swarm_shm_participant" is_default_profile="true">
    <rtps>{peers}
      <userTransports>
        <transport_id>swarm_shm</transport_id>
        <transport_id>swarm_udp</transport_id>
      </userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


def shm_sized_env(env: dict[str, str], robots: int, profile: Path) -> dict[str, str]:
    """``env`` for the processes that carry a big run's bursts (the simulator, the group
    processes, the recorder): Fast DDS with a shared-memory transport sized to ``robots``
    (:func:`shm_sizes`), its profile written to ``profile``.

    ``env`` is returned unchanged for a run of at most :data:`SHM_SIZED_ABOVE` robots (the
    defaults hold), and whenever the user configured Fast DDS's transports or discovery
    (``FASTRTPS_DEFAULT_PROFILES_FILE``, ``FASTDDS_BUILTIN_TRANSPORTS``, ``ROS_STATIC_PEERS``,
    ``ROS_DISCOVERY_SERVER``): then they decide. Under the range LOCALHOST the process gets the
    range SUBNET and a profile that keeps UDP on the loopback interface, as :func:`shm_free_env`.
    """
    if robots <= SHM_SIZED_ABOVE or any(
            env.get(k) for k in (PROFILES_ENV, BUILTIN_TRANSPORTS_ENV, STATIC_PEERS_ENV,
                                 DISCOVERY_ENV)):
        return env
    out = dict(env)
    loopback = (out.get(LOCALHOST_ONLY_ENV) == "1"
                or out.get(RANGE_ENV, "").upper() == "LOCALHOST")
    if loopback:
        if LOCALHOST_ONLY_ENV in out:
            out[LOCALHOST_ONLY_ENV] = "0"
        out[RANGE_ENV] = "SUBNET"
    profile.write_text(shm_profile_xml(*shm_sizes(robots), loopback))
    out[PROFILES_ENV] = str(profile)
    return out


def fault_killed_robots(cfg: RunConfig) -> frozenset[str]:
    """The robots whose processes a ``kill-nav`` or ``kill-robot`` fault of the run kills."""
    return frozenset(f.robot for f in cfg.faults if f.kind in ("kill-nav", "kill-robot"))


def faults_file(cfg: RunConfig) -> Path:
    """``RUN/faults.yaml``: the run's fault schedule as given to the simulator."""
    return cfg.run_dir / "faults.yaml"


def child_specs(cfg: RunConfig):
    """The supervised processes of a run, in start order: simulator, coordinator (centralized
    mode: the child named ``coordinator``), navigators, commanders.

    Returns:
        A list of :class:`swarm_up.supervisor.ChildSpec`.
    """
    from swarm_up.supervisor import ChildSpec

    logs = cfg.run_dir / "logs"
    params = cfg.run_dir / "params"
    env = dict(os.environ, PYTHONUNBUFFERED="1", RCUTILS_COLORIZED_OUTPUT="0")
    if cfg.discovery_server:
        env[DISCOVERY_ENV] = cfg.discovery_server
    world = str(cfg.world_path)
    sim = sim_argv(cfg)
    specs = []
    # the processes that carry a big run's bursts: shared memory sized to the run
    burst_env = env if cfg.groups is None else shm_sized_env(env, len(cfg.robots),
                                                             params / "fastdds_shm.xml")
    if cfg.leader:  # rank 0 (or the only host): simulator, recorder, coordinator
        specs.append(ChildSpec("sim", tuple(sim), logs / "sim.log", kind="sim", restart=False,
                               env=burst_env))
        if cfg.record_path is not None:  # started first: swarm-up waits for it before the rest
            specs.insert(0, recorder_spec(cfg, burst_env))
        if cfg.discovery_server:  # first of all: every other process is its client
            specs.insert(0, discovery_server_spec(cfg, env))
    coordinated = cfg.coordination == "centralized"
    if coordinated and cfg.leader:
        specs.append(coordinator_spec(cfg, env))

    if cfg.groups is None:
        specs += _per_robot_specs(cfg, env)
    else:
        for g, group in enumerate(cfg.groups, start=1):
            argv = [sys.executable, "-m", "swarm_up.group", "--namespaces", ",".join(group),
                    "--params-dir", str(params), "--world", world, "--seed", str(cfg.seed),
                    # the robots' sensors rendered here (swarm_up.feed), as the simulator would
                    "--sensors", "--robot", cfg.robot, "--swarm-size", str(len(cfg.robots)),
                    "--name-prefix", cfg.name_prefix]
            if relays_states(cfg):
                argv += ["--states-rank", str(cfg.rank)]
            if cfg.commanders:
                argv += ["--commanders", "--service-time", repr(cfg.service_time)]
                if coordinated:
                    argv += ["--coordinated", "--coordinator-timeout", repr(cfg.ready_timeout)]
            if cfg.faults:
                argv += ["--faults", str(faults_file(cfg))]
            specs.append(ChildSpec(f"group_{g}", tuple(argv), logs / f"group_{g}.log",
                                   kind="group", robots=group, env=burst_env))
    return specs



def relays_states(cfg: RunConfig) -> bool:
    """Whether this host's ``swarm-up`` relays the robots' states to its group processes
    (:mod:`swarm_up.relay`): on a rank other than 0 with more than one group process."""
    return not cfg.leader and cfg.groups is not None and len(cfg.groups) > 1


def sim_argv(cfg: RunConfig) -> list[str]:
    """The simulator's command line (``swarm-sim``) for a run."""
    from swarm_common import topics
    from swarm_record.mcap_format import RECORDER_NODE, simulator_readers

    sim = command("swarm-sim", "swarm_sim.node") + [
        "--world", str(cfg.world_path), "--robot", cfg.robot,
        "--swarm-size", str(len(cfg.robots)), "--name-prefix", cfg.name_prefix,
        "--seed", str(cfg.seed), "--rtf", repr(cfg.rtf),
        # Simulated time starts when every navigator answers (the synchronous loop:
        # docs/reference/contract.md#s5-simulation).
        "--wait-for", str(len(cfg.robots)),
    ]
    if cfg.duration is not None:
        sim += ["--duration", repr(cfg.duration)]
    if cfg.map_path is not None:
        sim += ["--map", str(cfg.map_path)]
    sim += ["--summary", str(cfg.run_dir / "sim_summary.json")]
    if cfg.faults:
        sim += ["--faults", str(faults_file(cfg))]
    if cfg.gui:
        sim.append("--gui")
    if not cfg.tf:
        sim.append("--no-tf")
    readers = 0 if cfg.record_path is None else simulator_readers(cfg.robots, cfg.record_topics)
    if readers:  # the recorder gets the first tick on (docs/ARCHITECTURE.md)
        sim += ["--wait-for-reader", RECORDER_NODE, "--reader-subscriptions", str(readers)]
        sim += ["--record-window", str(topics.RECORD_WINDOW_TICKS)]  # a stalled recorder
    return sim


def _per_robot_specs(cfg: RunConfig, env: dict[str, str]) -> list:
    """One navigator process (and one commander process) per local robot.

    A robot that a fault kills gets processes that own no shared-memory port, and every
    commander runs without one too (:func:`shm_free_env`): a commander has been seen deaf to its
    navigator's ``nav_status`` (delivered by shared memory) for 120 s while the coordinator's
    ``state`` (loopback UDP) reached it, and in centralized mode the coordinator then waits for
    that robot's first word for good (docs/HISTORY.md, "A commander deaf to its navigator").
    Its traffic, a status at 2 Hz simulated and a goal per task, is light.
    """
    from swarm_up.supervisor import ChildSpec

    logs, params, specs = cfg.run_dir / "logs", cfg.run_dir / "params", []
    killed, free_env = fault_killed_robots(cfg), shm_free_env(env)
    robot_env = {ns: free_env if ns in killed else env for ns in cfg.local_robots}
    nav = command("swarm-nav", "swarm_nav.node")
    for ns in cfg.local_robots:
        argv = nav + ["--ros-args", "-r", f"__ns:=/{ns}",
                      "--params-file", str(params / f"{ns}.yaml")]
        specs.append(ChildSpec(f"nav_{ns}", tuple(argv), logs / f"nav_{ns}.log",
                               kind="nav", robots=(ns,), env=robot_env[ns]))
    if cfg.commanders:
        cmd = command("swarm-commander", "swarm_commander.cli")
        for ns in cfg.local_robots:
            argv = cmd + [ns, "--world", str(cfg.world_path), "--seed", str(cfg.seed),
                          "--wait-timeout", repr(cfg.ready_timeout),
                          "--service-time", repr(cfg.service_time)]
            if cfg.coordination == "centralized":
                argv.append("--coordinated")
                if cfg.faults:
                    argv += ["--faults", str(faults_file(cfg))]
            specs.append(ChildSpec(f"cmd_{ns}", tuple(argv), logs / f"cmd_{ns}.log",
                                   kind="cmd", robots=(ns,), env=free_env))
    return specs



def recorder_spec(cfg: RunConfig, env: dict[str, str]):
    """The recorder of ``--record`` (:mod:`swarm_record.recorder`), not restarted if it dies (a new
    one would truncate the file)."""
    import json

    from swarm_record.mcap_format import run_metadata
    from swarm_scene.poi import load_poi
    from swarm_scene.robot_model import load_robot
    from swarm_up.supervisor import ChildSpec

    models = {name: load_robot(name) for name in dict.fromkeys(cfg.models)}
    lidars = [models[name].lidar for name in cfg.models]
    if len(models) == 1:  # one mounting for every robot
        lidars = lidars[:1]
    mounts = [",".join(repr(float(v)) for v in (li.pose[0], li.pose[1], li.z, li.pose[2]))
              for li in lidars]
    frames = [li.frame for li in lidars]
    stations = []
    if cfg.poi_path is not None:
        stations = [{"name": w.name, "x": float(w.pose[0]), "y": float(w.pose[1]),
                     "yaw": float(w.pose[2]), "holding": w.holding.tolist()}
                    for w in load_poi(cfg.poi_path).workstations]
    meta = run_metadata(world=cfg.world_path, robot=cfg.robot, seed=cfg.seed,
                        robots=cfg.robots, workstations=stations, rtf=cfg.rtf,
                        models=cfg.models)
    argv = [sys.executable, "-m", "swarm_record.recorder", "--out", str(cfg.record_path),
            "--robots", ",".join(cfg.robots),
            "--lidar=" + ";".join(mounts), "--lidar-frame", ",".join(frames),
            "--meta", json.dumps(meta)]
    if cfg.record_topics is not None:
        argv += ["--topics", cfg.record_topics]
    if cfg.faults:  # a muted robot skips ticks of odom: the window follows /clock alone
        argv += ["--progress", "clock"]
    return ChildSpec("record", tuple(argv), cfg.run_dir / "logs" / "record.log", kind="record",
                     restart=False, env=env)
DISCOVERY_ENV = "ROS_DISCOVERY_SERVER"
"""The variable by which rmw_fastrtps makes a participant a client of Fast DDS's Discovery
Server (``HOST:PORT``; several servers separated by ``;``)."""


def discovery_server_spec(cfg: RunConfig, env: dict):
    """Fast DDS's Discovery Server of ``--discovery-server HOST:PORT`` (the wheel's
    ``fast-discovery-server``, server id 0 listening on HOST:PORT), restarted if it dies.

    The wheel's program finds its libraries only with ``LD_LIBRARY_PATH`` naming the
    environment's ``lib/`` and ``site-packages/ros_fastrtps.libs``."""
    import sysconfig

    from swarm_up.supervisor import ChildSpec

    host, _, port = cfg.discovery_server.rpartition(":")
    prefix = Path(sys.prefix)
    libs = [prefix / "lib", Path(sysconfig.get_paths()["purelib"]) / "ros_fastrtps.libs"]
    lib_env = dict(env, LD_LIBRARY_PATH=os.pathsep.join(
        [str(p) for p in libs] + [v for v in [env.get("LD_LIBRARY_PATH")] if v]))
    lib_env.pop(DISCOVERY_ENV, None)  # the server itself is no client
    program = (shutil.which("fast-discovery-server")
               or str(Path(sys.executable).parent / "fast-discovery-server"))
    argv = [program, "-i", "0", "-l", host, "-p", port]
    return ChildSpec("discovery", tuple(argv), cfg.run_dir / "logs" / "discovery.log",
                     kind="discovery", env=lib_env)


COORDINATOR = "coordinator"
"""The child name of the coordinator (``RUN/logs/coordinator.log``); fault injection finds it by
this name in the supervisor (``Supervisor.pid(COORDINATOR)``)."""


def coordinator_spec(cfg: RunConfig, env: dict):
    """The coordinator's :class:`~swarm_up.supervisor.ChildSpec` (restarted when it crashes).

    It always runs without Fast DDS shared memory (:func:`shm_free_env`): a ``kill-coordinator``
    fault, or anyone, may SIGKILL it, and its traffic (a few requests and answers per task) is
    light."""
    from swarm_up.supervisor import ChildSpec

    argv = command("swarm-coordinator", "swarm_coordinator.node") + [
        "--swarm-size", str(len(cfg.robots)), "--name-prefix", cfg.name_prefix,
        "--world", str(cfg.world_path), "--seed", str(cfg.seed), "--robot", cfg.robot,
        "--service-time", repr(cfg.service_time), *cfg.coordinator_args]
    if cfg.faults:
        argv += ["--faults", str(faults_file(cfg))]
    return ChildSpec(COORDINATOR, tuple(argv), cfg.run_dir / "logs" / f"{COORDINATOR}.log",
                     kind="coord", env=shm_free_env(env))
