"""What every part of the orchestrator agrees on about a run: :class:`RunConfig`, built and
checked by :func:`swarm_up.args.validate` and read by :mod:`swarm_up.rundir`,
:mod:`swarm_up.children` and :mod:`swarm_up.orchestrator` (a module of its own, so that none of
them imports another for it)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

PER_ROBOT = "per-robot"
"""``--processes per-robot``: one navigator (and commander) process per robot."""


@dataclass(frozen=True)
class RunConfig:
    """Everything a run needs, validated.

    Attributes:
        robots: namespaces without ``/`` (``Srobot1`` ...).
        name_prefix: their common prefix (``Srobot``).
        world_path: the world file.
        world_name: its stem, for reports.
        robot: ``--robot`` as the simulator gets it: the robot's name or absolute path, or a
            mix ``NAME:COUNT,...`` in the order given (a fleet file's entries so; paths
            absolute).
        map_path: map YAML (None: rasterise or let the simulator do it).
        poi_path: points-of-interest YAML beside the world (None: there is none).
        seed: seed.
        rtf: real-time factor (0 = as fast as possible).
        duration: simulated seconds, or None (until Ctrl-C) [s].
        commanders: start commanders.
        coordination: ``decentralized`` | ``centralized`` (with commanders).
        coordinator_args: the coordinator's policy flags given to swarm-up (``--assignment``
            ...), passed on to ``swarm-coordinator`` as they are.
        service_time: [s] simulated: how long a robot stays docked at a workstation it reached
            (``--service-time``, else the world's ``service_time``).
        metrics_path: ``--metrics`` file or None.
        groups: None for one process per robot, else the robots of every group process.
        gui: open the PyBullet window.
        run_dir: absolute run directory.
        ready_timeout: [s] wall.
        nav_template: navigator parameter template.
        faults: the ``--faults`` schedule (:func:`swarm_common.faults.parse_faults`); empty:
            none.
        record_path: ``--record`` MCAP file (None: no recording).
        record_topics: ``--record-topics`` regular expression (None: every topic).
        dashboard_port: serve the dashboard on this port of 127.0.0.1 (None: no dashboard).
        foxglove_port: serve the Foxglove WebSocket protocol on this port of 127.0.0.1
            (None: no Foxglove server; :mod:`swarm_viz.foxglove_view`).
        markers: publish ``/swarm/markers`` (also on with the dashboard).
        tf: the simulator publishes ``/tf``, ``/tf_static`` and ``robot_description``
            (:mod:`swarm_sim.tf_publisher`).
        fleet: the model of every robot (name or absolute path), index-aligned with
            ``robots`` (:func:`swarm_scene.fleet.fleet_models`); empty: every robot is
            ``robot``.
        hosts: the hosts the swarm runs on (``--hosts``), one ``swarm-up`` each.
        rank: this host's rank (``--host-rank``); rank 0 runs the simulator, the metrics, the
            coordinator, the dashboard and the recorder.
        host_robots: the robots of every rank (:func:`swarm_up.hosts.assign_robots`); empty
            with one host.
        host_weights: ``--host-weights``, one per host (empty: equal).
        discovery_server: ``HOST:PORT`` of Fast DDS's Discovery Server (rank 0 starts it), or
            None for ROS 2's simple discovery.
        peers: ``--peers``, the other hosts' addresses: every process of this host discovers
            only this host and them (:func:`swarm_up.children.limit_discovery`); empty: the
            discovery range as it is.
        rank_timeout: [s] wall a rank may be silent before it counts as lost.
        on_rank_loss: ``end`` (rank 0 ends the run, exit 1) or ``continue`` (its robots are
            gone: not waited for).
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
    faults: tuple = ()
    record_path: Path | None = None
    record_topics: str | None = None
    dashboard_port: int | None = None
    foxglove_port: int | None = None
    markers: bool = False
    tf: bool = True
    fleet: tuple[str, ...] = ()
    hosts: int = 1
    rank: int = 0
    host_robots: tuple[tuple[str, ...], ...] = ()
    host_weights: tuple[float, ...] = ()
    discovery_server: str | None = None
    peers: tuple[str, ...] = ()
    rank_timeout: float = 10.0
    on_rank_loss: str = "end"
    coordinator_args: tuple[str, ...] = ()
    service_time: float = 0.0

    @property
    def local_robots(self) -> tuple[str, ...]:
        """The robots whose navigators and commanders run on this host."""
        return self.host_robots[self.rank] if self.host_robots else self.robots

    @property
    def leader(self) -> bool:
        """Whether this host is rank 0 (simulator, metrics, coordinator, live view, recorder)."""
        return self.rank == 0

    @property
    def models(self) -> tuple[str, ...]:
        """The model (name or absolute path) of every robot, index-aligned with ``robots``."""
        return self.fleet if self.fleet else (self.robot,) * len(self.robots)
