"""One swarm over several hosts: which robot runs where, the run's identity, and the link
between the hosts' ``swarm-up`` processes (docs/guides/multi_host.md).

``swarm-up [run flags] --hosts N --host-rank R`` on every host. DDS carries every topic between
the hosts (the same ``ROS_DOMAIN_ID``; simple discovery, or Fast DDS's Discovery Server with
``--discovery-server``); this module adds no transport, only the few words the ``swarm-up``
processes exchange (:mod:`swarm_common.ranks`): rank 0's run identity, which every other rank
checks before it starts anything, and every rank's report once a second.
"""

from __future__ import annotations

import hashlib
import os
import socket
import time
import uuid
from collections.abc import Sequence
from pathlib import Path

from swarm_common.ranks import RankContractError, RankReport, RunIdentity

REPORT_PERIOD_S = 1.0  # [s] wall between two reports of a rank


def assign_robots(robots: Sequence[str], hosts: int,
                  weights: Sequence[float] = ()) -> tuple[tuple[str, ...], ...]:
    """Which robots each host runs: robot after robot, to the host whose share is furthest
    behind its weight (the smallest (robots it has + 1) / weight; the lower rank on a tie).
    With equal weights, robot ``i`` (0-based) runs on host ``i mod N``: robots are dealt, as
    the group processes of one host are (:func:`swarm_up.args.split_groups`), because robots
    with neighbouring numbers spawn side by side and meet the same crowds, and the lockstep
    waits for the slowest host.

    Args:
        robots: the namespaces, in robot order.
        hosts: N >= 1.
        weights: one positive weight per host (a host twice as fast gets twice the robots);
            empty: equal.

    Returns:
        The robots of every rank, each in robot order.
    """
    w = list(weights) if weights else [1.0] * hosts
    out: list[list[str]] = [[] for _ in range(hosts)]
    for ns in robots:
        k = min(range(hosts), key=lambda h: ((len(out[h]) + 1) / w[h], h))
        out[k].append(ns)
    return tuple(tuple(r) for r in out)


def file_digest(*paths: Path) -> str:
    """``sha256:<hex>`` of the files' bytes, in order."""
    h = hashlib.sha256()
    for path in paths:
        h.update(Path(path).read_bytes())
    return f"sha256:{h.hexdigest()}"


def _map_files(map_yaml: Path) -> list[Path]:
    import yaml

    image = (yaml.safe_load(map_yaml.read_text()) or {}).get("image", "")
    files = [map_yaml]
    if image:
        files.append((map_yaml.parent / image) if not Path(image).is_absolute() else Path(image))
    return [f for f in files if f.is_file()]


def identity_of(cfg, session: str = "") -> RunIdentity:
    """The run identity of a validated :class:`swarm_up.run_config.RunConfig`."""
    from swarm_common.faults import dump_faults

    def model(name: str) -> str:
        return file_digest(Path(name)) if os.sep in name else name

    faults = ""
    if cfg.faults:
        tmp = cfg.run_dir / ".faults_identity.yaml"
        tmp.parent.mkdir(parents=True, exist_ok=True)
        dump_faults(cfg.faults, tmp)
        faults = tmp.read_text()
        tmp.unlink()
    return RunIdentity(
        hosts=cfg.hosts, host_weights=tuple(cfg.host_weights), swarm_size=len(cfg.robots),
        name_prefix=cfg.name_prefix, fleet=tuple(model(m) for m in cfg.models), seed=cfg.seed,
        world=file_digest(cfg.world_path),
        map=file_digest(*_map_files(cfg.map_path)) if cfg.map_path is not None else "",
        nav_template=file_digest(cfg.nav_template) if cfg.nav_template.is_file() else "",
        coordination=cfg.coordination, commanders=cfg.commanders, faults=faults,
        discovery_server=cfg.discovery_server or "", session=session)


def new_session() -> str:
    """A run id for one ``swarm-up`` start (fixed length)."""
    return uuid.uuid4().hex[:12]


class HostLink:
    """``swarm-up``'s node for the words between hosts, in a context of its own, spun (and
    published from) only by ``swarm-up``'s main thread (:meth:`spin`).

    Args:
        rank: this host's rank.
        robots: how many robots it runs.
        session: this start's run id.
        faults: also take the fault announcements of ``/swarm/events``
            (:meth:`fault_events`).

    Attributes:
        identity: rank 0's latest :class:`RunIdentity` (None before one arrived).
        reports: ``(rank, session) -> (RankReport, time.monotonic() received)``.
    """

    def __init__(self, rank: int, robots: int, session: str, faults: bool = False):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.signals import SignalHandlerOptions
        from std_msgs.msg import String

        from swarm_common import topics
        from swarm_ros.qos import publisher, subscription

        self.rank, self.robots, self.session = rank, robots, session
        self.host, self.pid = socket.gethostname(), os.getpid()
        self.identity: RunIdentity | None = None
        self.reports: dict[tuple[int, str], tuple[RankReport, float]] = {}
        self._string = String
        self._context = rclpy.Context()
        rclpy.init(context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self._node = Node(f"swarm_up_rank{rank}", context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._run_pub = publisher(self._node, String, topics.RUN) if rank == 0 else None
        self._report_pub = publisher(self._node, String, topics.RANKS)
        subscription(self._node, String, topics.RUN, self._on_run)
        subscription(self._node, String, topics.RANKS, self._on_report)
        self._faults: list = []
        if faults:
            from diagnostic_msgs.msg import DiagnosticArray

            subscription(self._node, DiagnosticArray, topics.EVENTS, self._on_events)
        self._last_report = -REPORT_PERIOD_S

    def _on_run(self, msg) -> None:
        try:
            self.identity = RunIdentity.decode(msg.data)
        except RankContractError:
            pass

    def _on_report(self, msg) -> None:
        try:
            rep = RankReport.decode(msg.data)
        except RankContractError:
            return
        self.reports[(rep.rank, rep.session)] = (rep, time.monotonic())

    def _on_events(self, msg) -> None:
        from swarm_common.faults import EVENT_NAME, FaultEvent

        for status in msg.status:
            if status.name == EVENT_NAME:
                ev = FaultEvent.decode({kv.key: kv.value for kv in status.values})
                if ev is not None and ev.kind:
                    self._faults.append(ev)

    def fault_events(self) -> list:
        """The fault announcements (:class:`swarm_common.faults.FaultEvent`) taken since the
        last call."""
        out, self._faults = self._faults, []
        return out

    @property
    def context(self):
        """Its ``rclpy`` context (one DDS participant), for another node of ``swarm-up``'s
        (:class:`swarm_up.relay.StatesRelay`)."""
        return self._context

    def spin(self, seconds: float = 0.0) -> None:
        """Take what has arrived (for up to ``seconds`` wall)."""
        end = time.monotonic() + seconds
        while True:
            self._executor.spin_once(timeout_sec=max(0.0, min(0.05, end - time.monotonic())))
            if time.monotonic() >= end:
                return

    def publish_identity(self, identity: RunIdentity) -> None:
        """Rank 0: publish the run's identity (latched)."""
        self._run_pub.publish(self._string(data=identity.encode()))

    def report(self, state: str, reason: str = "", resources: dict | None = None,
               restarts: int = 0, fault_restarts: int = 0, force: bool = False) -> None:
        """Publish this rank's report, at most once a :data:`REPORT_PERIOD_S` unless
        ``force``."""
        now = time.monotonic()
        if not force and now - self._last_report < REPORT_PERIOD_S:
            return
        self._last_report = now
        res = resources or {}
        rep = RankReport(rank=self.rank, session=self.session, host=self.host, pid=self.pid,
                         robots=self.robots, state=state, reason=reason,
                         cpu_percent=res.get("cpu_percent"), peak_rss_mb=res.get("peak_rss_mb"),
                         restarts=restarts, fault_restarts=fault_restarts)
        self._report_pub.publish(self._string(data=rep.encode()))

    def others(self, rank: int, within_s: float) -> list[RankReport]:
        """Reports of rank ``rank`` from other sessions than this one, heard within the last
        ``within_s`` wall seconds and not ended (another ``swarm-up`` with that rank)."""
        now = time.monotonic()
        return [rep for (r, s), (rep, t) in self.reports.items()
                if r == rank and s != self.session and now - t <= within_s
                and rep.state in ("starting", "up")]

    def latest(self) -> dict[int, tuple[RankReport, float]]:
        """The latest report of every rank (by arrival), with when it arrived."""
        out: dict[int, tuple[RankReport, float]] = {}
        for (rank, _), (rep, t) in self.reports.items():
            if rank not in out or t > out[rank][1]:
                out[rank] = (rep, t)
        return out

    def close(self) -> None:
        """Destroy the node and shut its context down (idempotent)."""
        if self._node is not None:
            self._executor.shutdown(timeout_sec=0)
            self._node.destroy_node()
            self._node = None
        if self._context.ok():
            self._context.try_shutdown()
