"""The run loop of ``swarm-up``: start the children, supervise them, show progress, stop, report.

Order of work (:func:`run`): read the navigator template → create the run directory
(``RUN/logs``, ``RUN/params``) → write one navigator params file per robot → start the metrics
node (in this process) → start the simulator, the navigators (one process per robot or ``K``
groups) and, with ``--commanders``, the commanders → show progress until every navigator is
ready → supervise (restart crashed navigators/commanders within 2 s) until the simulator ends
(``--duration``) or Ctrl-C → stop everything within 5 s → remove stale Fast DDS shared-memory
files → write ``--metrics`` (and ``RUN/metrics.json``) and print a summary table.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from swarm_common.errors import EXIT_BAD_INPUT, EXIT_OK, EXIT_RUNTIME
from swarm_common.faults import KILL_NAV
from swarm_metrics.summary import print_summary
from swarm_scene.fleet import describe_fleet
from swarm_up import PROG
from swarm_up.children import child_specs
from swarm_up.output import ProgressView, say, warn
from swarm_up.run_config import PER_ROBOT, RunConfig
from swarm_up.rundir import RunError, load_nav_template, prepare_map, write_params_files
from swarm_up.supervisor import LogTail, ResourceSampler, StopFlag, Supervisor

POLL_PERIOD_S = 0.1  # supervision poll [s] (10 Hz; restarts within 2 s need >= 5 Hz)
SPAWNED_RE = re.compile(r"spawned\s+(\d+)\s+robots?", re.IGNORECASE)


def _last_line(path: Path) -> str:
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


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
        from swarm_metrics.listener import (
            MetricsListener,  # rclpy: imported only when a run starts
        )

        self.cfg = cfg
        self.logs = cfg.run_dir / "logs"
        self.specs = child_specs(cfg)
        self.n = len(cfg.robots)
        self.t0 = time.monotonic()
        self.listener = MetricsListener(cfg.robots, self.t0)
        self.live = None  # the dashboard and /swarm/markers (swarm_viz.server)
        if cfg.markers or cfg.dashboard_port is not None or cfg.foxglove_port is not None:
            from swarm_viz.server import LiveView

            self.live = LiveView(cfg, self.listener)
        self.sup = Supervisor(on_restart=self._on_restart)
        self.sampler = ResourceSampler(self.sup, robots=len(cfg.local_robots))
        self.view = ProgressView(self.n, tty=sys.stdout.isatty())
        self.all_ready = False
        self._last_report = time.monotonic()
        self._report_mark: tuple[float, float] | None = None  # (wall, sim) of the last line
        self._sim_tail = LogTail(self.logs / "sim.log")
        self._spawned_from_log = 0
        self._navigators = {s.name for s in self.specs if s.kind in ("nav", "group")}
        self._dead: dict[str, int] = {}  # exited, not to be restarted -> exit code
        self.faults = None  # swarm_up.faults.ProcessFaults, with --faults
        self._announcer = None  # swarm_up.faults.Announcer: made with --faults or at a crash
        self.link = None  # swarm_up.hosts.HostLink, with --hosts above 1
        self.identity = None  # the run's identity it publishes then
        self._ranks_said: set[tuple[int, str, str]] = set()  # (rank, session, state) reported
        self._lost_ranks: set[int] = set()
        self._faults_seen = 0  # fault events of the recorder's log handled so far

    def _log_of(self, name: str) -> Path:
        return self.logs / f"{name}.log"

    def _on_restart(self, ev) -> None:
        warn(f"{ev.name} exited with code {ev.code}; restarted "
              f"(restart {self.sup.children[ev.name].restarts}); logs: {self._log_of(ev.name)}")

    def start(self) -> None:
        """Start the metrics node, then the simulator, navigators and commanders, in order.

        Raises:
            RunError: a command could not be started.
            InputError: another rank 0 of this run is up (``--hosts``).
        """
        if self.cfg.hosts > 1:
            self._start_link()
        self.listener.start()
        if self.cfg.faults:
            from swarm_up.faults import ProcessFaults

            per_robot = self.cfg.local_robots if self.cfg.groups is None else ()
            self.faults = ProcessFaults(self.sup, per_robot, self._announce().ack, say,
                                        serving=self._coordinators_serving)
        if self.live is not None:
            url = self.live.start()
            if url is not None:
                say(f"dashboard: {url}")
            if self.live.foxglove is not None:
                say(f"foxglove: {self.live.foxglove.url} (Foxglove or Lichtblick: Open "
                    "connection, Foxglove WebSocket)")
        for spec in self.specs:
            try:
                self.sup.start(spec)
            except OSError as exc:
                raise RunError(f"cannot start {spec.argv[0]}: {exc.strerror}") from None
            if spec.kind == "record":
                self._wait_for_recorder(spec)

    def _wait_for_recorder(self, spec, timeout_s: float = 60.0) -> None:
        """Hold the start of the simulator until the recorder's subscriptions exist, so that
        it is matched (and ``ground_truth`` published) from the first tick on.

        Raises:
            RunError: the recorder exited or did not get ready within ``timeout_s`` wall s.
        """
        from swarm_record.recorder import READY_LINE

        tail, deadline = LogTail(spec.log_path), time.monotonic() + timeout_s
        while not any(line.startswith(READY_LINE) for line in tail.lines()):
            proc = self.sup.children[spec.name].proc
            if proc is not None and proc.poll() is not None:
                raise RunError(f"the recorder exited with code {proc.returncode}: "
                               f"{_last_line(spec.log_path)} (logs: {spec.log_path})")
            if time.monotonic() > deadline:
                raise RunError(f"the recorder was not ready after {timeout_s:g} s; "
                               f"logs: {spec.log_path}")
            time.sleep(0.05)
        say(f"recording to {self.cfg.record_path}")

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
            if ev.name == "record":
                self._dead[ev.name] = ev.code
                warn(f"the recorder exited with code {ev.code}; the recording ends here; "
                     f"logs: {self._log_of(ev.name)}")
                continue
            if not ev.restarted:
                self._dead[ev.name] = ev.code
                what = "keeps crashing, last exit code" if ev.gave_up else "exited with code"
                if self._commander_needed(ev):
                    return Outcome(EXIT_RUNTIME, f"{ev.name} {what} {ev.code} and is not "
                                   "restarted: the coordinator would wait for its robot for good; "
                                   f"logs: {self._log_of(ev.name)}", "commander failed")
                warn(f"{ev.name} {what} {ev.code}; not restarted; logs: {self._log_of(ev.name)}")
            self._say_lost(ev)
        if sim_code is not None:
            return self._sim_ended(sim_code)
        if self.link is not None:
            lost = self._watch_ranks()
            if lost is not None:
                return lost
        if self.faults is not None:
            self._handle_faults()
        if not self.all_ready:
            return self._progress()
        self.sampler.maybe_sample()
        self._report_progress()
        return None

    def _start_link(self) -> None:
        """Rank 0 of a run over several hosts: make sure no other rank 0 is up, then publish the
        run's identity (:mod:`swarm_up.hosts`)."""
        from swarm_common.errors import InputError
        from swarm_up.hosts import HostLink, identity_of, new_session
        from swarm_up.remote import DISCOVERY_GRACE_S

        session = new_session()
        self.link = HostLink(0, len(self.cfg.local_robots), session)
        self.link.spin(DISCOVERY_GRACE_S)
        twins = self.link.others(0, self.cfg.rank_timeout)
        other = self.link.identity
        if twins or (other is not None and other.session != session and other.state == "up"):
            where = f" on host {twins[0].host} (pid {twins[0].pid})" if twins else ""
            raise InputError(f"--host-rank: rank 0 of this run already runs{where}; every "
                             "rank runs once")
        self.identity = identity_of(self.cfg, session)
        self.link.publish_identity(self.identity)
        self.link.report("up", force=True)
        say(f"rank 0 of {self.cfg.hosts}: {len(self.cfg.local_robots)} robots here, "
            + ", ".join(f"rank {r}: {len(rob)}" for r, rob in enumerate(self.cfg.host_robots)
                        if r) + " (robot i on host i mod N unless --host-weights)")

    def _watch_ranks(self) -> Outcome | None:
        """Rank 0: report, and watch the other ranks: say once when one refuses, comes up or
        ends; a rank silent for ``--rank-timeout`` after it was heard is lost: the run ends
        (exit 1) or goes on without its robots (``--on-rank-loss continue``)."""
        link = self.link
        link.spin(0.0)
        res = self.sampler.result()
        per = res.get("peak_rss_mb_per_robot")
        link.report("up", resources={"cpu_percent": res.get("cpu_percent"),
                                     "peak_rss_mb": per * len(self.cfg.local_robots)
                                     if per else None}, restarts=self.sup.restarts)
        twins = [t for t in link.others(0, self.cfg.rank_timeout) if t.session < link.session]
        if twins:  # another rank 0 came up meanwhile (discovery was slow): the one with the
            # greater run id goes (a rule both sides agree on)
            return Outcome(EXIT_BAD_INPUT, f"--host-rank: rank 0 of this run already runs on "
                           f"host {twins[0].host} (pid {twins[0].pid}); every rank runs once",
                           "rank started twice")
        now = time.monotonic()
        for rank, (rep, t) in sorted(link.latest().items()):
            if rank == 0 or rank >= self.cfg.hosts or rank in self._lost_ranks:
                continue
            key = (rank, rep.session, rep.state)
            if key not in self._ranks_said:
                self._ranks_said.add(key)
                if rep.state == "refused":
                    warn(f"rank {rank} on host {rep.host} refused to join: {rep.reason}")
                elif rep.state == "up":
                    say(f"rank {rank} is up on host {rep.host} ({rep.robots} robots)")
            silent = now - t > self.cfg.rank_timeout
            was_up = (rank, rep.session, "up") in self._ranks_said
            if was_up and (silent or rep.state == "ending"):
                why = (f"silent for {self.cfg.rank_timeout:g} s (its swarm-up or the network "
                       "is gone)" if silent else f"ended ({rep.reason or 'stopped'})")
                return self._rank_lost(rank, rep, why)
        return None

    def _rank_lost(self, rank: int, rep, why: str) -> Outcome | None:
        from swarm_common.supervision import RobotsLost

        self._lost_ranks.add(rank)
        robots = self.cfg.host_robots[rank]
        line = (f"rank {rank} (host {rep.host}, {len(robots)} robots: {', '.join(robots[:4])}"
                f"{' ...' if len(robots) > 4 else ''}) lost: {why}")
        self._announce().lost(RobotsLost(robots, line, for_good=True))
        if self.cfg.on_rank_loss == "end":
            return Outcome(EXIT_RUNTIME, f"{line}; the run ends (--on-rank-loss end)",
                           "rank lost")
        warn(f"{line}; going on without its robots (--on-rank-loss continue)")
        return None

    def hosts_figures(self) -> list[dict]:
        """One row per host for the metrics (``hosts``): rank, host, robots, CPU, peak RSS,
        restarts (rank 0's own, the others' from their last report)."""
        import socket

        res = self.sampler.result()
        per = res.get("peak_rss_mb_per_robot")
        rows = [{"rank": 0, "host": socket.gethostname(), "robots": len(self.cfg.local_robots),
                 "cpu_percent": res.get("cpu_percent"),
                 "peak_rss_mb": round(per * len(self.cfg.local_robots), 1) if per else None,
                 "restarts": self.sup.restarts,
                 "fault_restarts": self.faults.fault_restarts if self.faults else 0,
                 "lost": False}]
        latest = self.link.latest() if self.link is not None else {}
        for rank in range(1, self.cfg.hosts):
            rep = latest.get(rank, (None, 0))[0]
            rows.append({"rank": rank, "host": rep.host if rep else None,
                         "robots": len(self.cfg.host_robots[rank]),
                         "cpu_percent": rep.cpu_percent if rep else None,
                         "peak_rss_mb": rep.peak_rss_mb if rep else None,
                         "restarts": rep.restarts if rep else None,
                         "fault_restarts": rep.fault_restarts if rep else None,
                         "lost": rank in self._lost_ranks})
        return rows

    def _announce(self):
        """The :class:`swarm_up.faults.Announcer`, made when first needed."""
        if self._announcer is None:
            from swarm_up.faults import Announcer

            self._announcer = Announcer()
        return self._announcer

    def _commander_needed(self, ev) -> bool:
        """Whether the run cannot go on after ``ev``, a child that ended and is not restarted:
        a commander process of a centralized run that failed (not one a fault killed). Its
        robot would never ask the coordinator again, which then waits for it at every sync and
        never gets back a workstation it holds: the run would hang rather than end."""
        state = self.sup.children[ev.name]
        return (state.spec.kind == "cmd" and self.cfg.coordination == "centralized"
                and ev.code != EXIT_OK and not (ev.planned or state.retired)
                and not self.sup.stopping)

    def _say_lost(self, ev) -> None:
        """A navigator process that crashed (not one a fault killed): tell the simulator that
        its robots are gone, so that no tick waits for them until they answer again (the
        lockstep has no wall-clock timeout; :mod:`swarm_common.supervision`)."""
        spec = self.sup.children[ev.name].spec
        if ev.planned or self.sup.stopping or spec.kind not in ("nav", "group"):
            return
        from swarm_common.supervision import RobotsLost

        self._announce().lost(RobotsLost(spec.robots, f"{ev.name} exited with code {ev.code}",
                                         for_good=not ev.restarted))

    def _handle_faults(self) -> None:
        """Carry out the process side of the faults the simulator announced since last time."""
        with self.listener.lock:
            log = self.listener.recorder.fault_log
            new, self._faults_seen = log[self._faults_seen:], len(log)
        for ev in new:
            self.faults.handle(ev)
        self.faults.poll()

    def _coordinators_serving(self) -> frozenset[str]:
        """The epochs of the coordinators that announced themselves serving so far."""
        with self.listener.lock:
            return frozenset(self.listener.recorder.coordinator_serving)

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
            say(f"t = {sim_s:.0f}{of} s simulated, RTF {rtf:.2f}, goals reached {reached}, "
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
            say(f"all {self.n} navigators ready in {elapsed:.1f} s; "
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
            say(f"stopping ({ended_by}) ...")
        self.sampler.maybe_sample(force=True)
        if self.link is not None and self.identity is not None:  # the other ranks end too
            from dataclasses import replace

            self.link.publish_identity(replace(self.identity, state="ending"))
            self.link.report("ending", reason=ended_by, force=True)
            self.link.spin(0.2)
        self.sup.stop()
        wall = time.monotonic() - self.t0
        if self.live is not None:
            self.live.stop()
        if not self.listener.stop():
            warn("the metrics node's teardown is stuck in the middleware (Fast DDS); the run's "
                 "figures are complete, swarm-up ends without finalizing it")
        if self._announcer is not None:
            self._announcer.close()
        if self.link is not None:
            self.link.close()
        return wall

    def _map_deliveries(self, summary) -> dict[str, int]:
        """``/map`` copies each robot's navigator received: one per start of its process, and
        in a group process one more per navigator a ``kill-nav`` fault recreated in-process (a
        per-robot process killed by one is restarted, so its starts count it)."""
        out = {ns: 1 for ns in self.cfg.robots}
        for state in self.sup.children.values():
            if state.spec.kind in ("nav", "group"):
                for ns in state.spec.robots:
                    out[ns] = max(1, state.starts)
        if self.cfg.groups is not None:
            faults = summary.extras.get("faults") if isinstance(summary.extras, Mapping) else None
            for entry in (faults or {}).get("log") or []:
                if (isinstance(entry, Mapping) and entry.get("kind") == KILL_NAV
                        and entry.get("phase") == "start" and entry.get("robot") in out):
                    out[entry["robot"]] += 1
        return out

    def _workstations(self) -> tuple[dict, dict]:
        """The world's workstations for the metrics: name -> docking x, y [m] in ``map``, and
        name -> holding points [(x, y) ...]; none without a points-of-interest file."""
        if self.cfg.poi_path is None:
            return {}, {}
        from swarm_scene.poi import load_poi

        poi = load_poi(self.cfg.poi_path)  # validated at start: cannot fail here
        return ({ws.name: (float(ws.pose[0]), float(ws.pose[1])) for ws in poi.workstations},
                {ws.name: [tuple(map(float, p)) for p in ws.holding] for ws in poi.workstations})

    def report(self, outcome: Outcome, wall_s: float) -> dict:
        """Merge the simulator's summary, write the metrics files, print the summary table."""
        from swarm_metrics.aggregate import RunFacts, aggregate, load_sim_summary

        cfg = self.cfg
        summary, warnings = load_sim_summary(cfg.run_dir / "sim_summary.json")
        if outcome.code == EXIT_OK:
            for w in warnings:
                warn(w)
        stations, holding = self._workstations()
        hosts = self.hosts_figures() if cfg.hosts > 1 else []
        # every host's supervisor: a restart anywhere decides the run as much as one here
        restarts = sum(h["restarts"] or 0 for h in hosts) if hosts else self.sup.restarts
        fault_restarts = (sum(h["fault_restarts"] or 0 for h in hosts) if hosts
                          else self.faults.fault_restarts if self.faults is not None else 0)
        with self.listener.lock:
            metrics = aggregate(self.listener.recorder, summary, RunFacts(
                world=cfg.world_name, seed=cfg.seed, coordination=cfg.coordination,
                wall_time_s=wall_s, resources=self.sampler.result(), restarts=restarts,
                fault_restarts=fault_restarts, map_deliveries=self._map_deliveries(summary),
                workstations=stations, holding=holding, models=cfg.models,
                map_path=str(cfg.map_path) if cfg.map_path is not None else None,
                extra={"ended_by": outcome.ended_by, "run_dir": str(cfg.run_dir),
                       "processes": PER_ROBOT if cfg.groups is None else len(cfg.groups),
                       "commanders": cfg.commanders, "rtf_requested": cfg.rtf,
                       "service_time_s": cfg.service_time,
                       **({"hosts": hosts} if hosts else {}),
                       **({"recording": str(cfg.record_path)} if cfg.record_path else {})}))
        files = [cfg.run_dir / "metrics.json"]
        if cfg.metrics_path:
            files.append(cfg.metrics_path)
        for path in files:
            path.write_text(json.dumps(metrics, indent=2) + "\n")
        if outcome.code == EXIT_OK or self.all_ready:
            print_summary(metrics, files)
        return metrics


def kernels_cached(package: Path) -> bool:
    """Whether numba's cache in ``package/__pycache__`` is fresh for every ``*_kernels.py``.

    numba keys a cache index (``<module>.<function>-<line>.py311.nbi``) by its source's
    modification time and size, and compiles again when they differ: a checkout or an edit makes
    the cache stale while its files stay (a checkout that kept an older ``__pycache__`` had all
    five navigators of a bench's first run compile the kernels at once, 90 s inside its wall
    time, because only the presence of an index was checked). Here a source counts as cached
    when its newest index is not older than the source.
    """
    for src in package.glob("*_kernels.py"):
        indexes = list((package / "__pycache__").glob(f"{src.stem}.*.nbi"))
        if not indexes or max(i.stat().st_mtime for i in indexes) < src.stat().st_mtime:
            return False
    return True


def warm_up_kernels() -> None:
    """When numba's cache holds no fresh navigator kernels (:func:`kernels_cached`), compile them
    (about 15 s) in one short-lived process before any navigator starts (:mod:`swarm_nav.jit`),
    instead of every navigator process compiling them at once; with a cache, each process loads
    them."""
    import importlib.util

    where = importlib.util.find_spec("swarm_nav").submodule_search_locations or []
    if all(kernels_cached(Path(d)) for d in where):
        return
    say("compiling the navigator's kernels (once per machine, about 15 s)")
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "swarm_nav.jit"], capture_output=True,
                          text=True, check=False)
    if proc.returncode != 0:  # the navigators compile them themselves, then say why if it fails
        say(f"warning: could not compile the navigator's kernels: "
            f"{(proc.stderr.strip().splitlines() or ['?'])[-1]}")
    else:
        say(f"compiled the navigator's kernels in {time.monotonic() - t0:.0f} s")


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

    if cfg.discovery_server:  # swarm-up's own participants are the server's clients too
        from swarm_up.children import DISCOVERY_ENV

        os.environ[DISCOVERY_ENV] = cfg.discovery_server
    if cfg.peers:  # before swarm-up's own participants; its children inherit it
        from swarm_up.children import limit_discovery

        limit_discovery(os.environ, cfg.peers)
    if not cfg.leader:
        from swarm_up.remote import run_remote

        (cfg.run_dir / "logs").mkdir(parents=True, exist_ok=True)
        return run_remote(prepare_map(cfg))
    template = load_nav_template(cfg.nav_template)
    (cfg.run_dir / "logs").mkdir(parents=True, exist_ok=True)
    (cfg.run_dir / "params").mkdir(parents=True, exist_ok=True)
    cfg = prepare_map(cfg)
    write_params_files(cfg, template)
    if cfg.tf:  # rviz2 -d RUN/swarm.rviz: the map, every robot's model, scan and plan
        from swarm_viz.rviz_config import rviz_config

        (cfg.run_dir / "swarm.rviz").write_text(rviz_config(cfg.robots))
    if cfg.faults:
        from swarm_common.faults import dump_faults
        from swarm_up.children import faults_file

        dump_faults(cfg.faults, faults_file(cfg))
        say(f"faults: {', '.join(f.label() for f in cfg.faults)}")
    layout = (f"{PER_ROBOT} processes" if cfg.groups is None
              else f"{len(cfg.groups)} group processes")
    mix = describe_fleet(cfg.models).partition(" ")[2]  # "(12 turtlebot3_waffle, ...)" or ""
    say(f"{len(cfg.robots)} robots{' ' + mix if mix else ''} in {cfg.world_name}, seed "
        f"{cfg.seed}, rtf {cfg.rtf:g}, {layout}; logs in {cfg.run_dir / 'logs'}")

    warm_up_kernels()
    shm_before = shm.snapshot()
    orch = Orchestrator(cfg)
    stop = StopFlag()
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
        removed = shm.clean_after_run(shm_before, ignore_pids=frozenset({os.getpid()}))
        for sig, handler in old_handlers.items():
            signal.signal(sig, handler)
    if removed:
        say(f"removed {len(removed)} stale shared-memory files from /dev/shm")
    orch.report(outcome, wall_s)
    if cfg.record_path is not None and cfg.record_path.is_file():
        size_mb = cfg.record_path.stat().st_size / 2**20
        say(f"recording: {cfg.record_path} ({size_mb:.1f} MB); pictures: swarm-plot "
            f"{cfg.record_path}")
    if outcome.error:
        print(f"{PROG}: error: {outcome.error}", file=sys.stderr, flush=True)
    if orch.listener.stuck:  # finalizing the middleware would wait on the same lock
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(outcome.code)
    return outcome.code

