"""A rank other than 0 of a swarm over several hosts (``swarm-up --hosts N --host-rank R``,
R > 0): this host's navigators and commanders, supervised as on one host.

Order (:func:`run_remote`): wait for rank 0's run identity on ``/swarm/run`` (up to
``--ready-timeout``), refuse (exit 2, one line) if this host's flags make another run or this
rank already runs elsewhere → write the params files of this host's robots → start the relay
of the robots' states when the host runs more than one group process (:mod:`swarm_up.relay`)
→ start their processes (group processes or one per robot) → supervise them (restart what
crashes, tell the simulator which robots a crashed process ran, carry out
``kill-nav``/``kill-robot`` faults of per-robot processes) and report to rank 0 once a second
→ end when rank 0 says its run ends (exit 0), when rank 0 falls silent for ``--rank-timeout``
(exit 1), or on Ctrl-C (exit 0).
"""

from __future__ import annotations

import signal
import time

from swarm_common.errors import EXIT_OK, EXIT_RUNTIME, InputError
from swarm_common.ranks import ENDING, REFUSED, STARTING, UP
from swarm_up.children import child_specs, relays_states
from swarm_up.hosts import HostLink, identity_of, new_session
from swarm_up.output import say, warn
from swarm_up.run_config import RunConfig
from swarm_up.rundir import RunError, load_nav_template, write_params_files
from swarm_up.supervisor import ResourceSampler, StopFlag, Supervisor

POLL_PERIOD_S = 0.1  # [s] wall: supervision cycle (restarts within 2 s)
DISCOVERY_GRACE_S = 3.0  # [s] wall: another session of this rank is heard within this


def _refuse(link: HostLink, line: str) -> InputError:
    link.report(REFUSED, line, force=True)
    link.spin(0.5)  # let the report go out before the process ends
    return InputError(line)


def wait_for_leader(cfg: RunConfig, link: HostLink, stop: StopFlag):
    """Wait for rank 0's identity; check it against this host's flags, then that this rank runs
    nowhere else.

    Returns:
        Rank 0's :class:`swarm_common.ranks.RunIdentity`, or None on Ctrl-C.

    Raises:
        InputError: the flags make another run (names the first setting that differs, both
            values), or this rank already runs (exit 2).
        RunError: no rank 0 within ``--ready-timeout``.
    """
    mine = identity_of(cfg)
    t0 = time.monotonic()
    heard = None
    while stop.signum is None:
        link.spin(0.1)
        link.report(STARTING)
        if link.identity is not None and link.identity.state == UP:
            heard = heard or time.monotonic()
            if time.monotonic() - heard >= DISCOVERY_GRACE_S:  # the ranks are heard by now
                break
        elif link.identity is not None and link.identity.state == ENDING:
            raise RunError(f"rank 0's run {link.identity.session} has ended; start rank 0 "
                           "first")
        if time.monotonic() - t0 > cfg.ready_timeout:
            raise RunError(f"no rank 0 on /swarm/run after {cfg.ready_timeout:g} s (is it "
                           "running, with the same ROS_DOMAIN_ID and discovery?)")
    else:
        return None
    diffs = mine.differences(link.identity)
    if diffs:
        flag, here, there = diffs[0]
        more = f" (and {len(diffs) - 1} more)" if len(diffs) > 1 else ""
        raise _refuse(link, f"{flag}: {here} on this host, {there} on rank 0{more}; every "
                            "host must run the same run flags")
    twins = link.others(cfg.rank, cfg.rank_timeout)
    if twins:
        t = twins[0]
        raise _refuse(link, f"--host-rank: rank {cfg.rank} already runs on host {t.host} "
                            f"(pid {t.pid}); every rank runs once")
    return link.identity


def run_remote(cfg: RunConfig) -> int:
    """Run this host's share of the swarm until rank 0's run ends.

    Returns:
        The exit code: 0 (rank 0 ended the run, or Ctrl-C), 1 (rank 0 lost, or a start
        failure).

    Raises:
        InputError: this host's flags differ from rank 0's, or this rank already runs (2).
        RunError: no rank 0 within ``--ready-timeout``; a command could not be started.
    """
    from swarm_up import shm

    local = cfg.local_robots
    say(f"rank {cfg.rank} of {cfg.hosts}: {len(local)} robots ({', '.join(local[:4])}"
        f"{' ...' if len(local) > 4 else ''}); logs in {cfg.run_dir / 'logs'}")
    template = load_nav_template(cfg.nav_template)
    (cfg.run_dir / "logs").mkdir(parents=True, exist_ok=True)
    stop = StopFlag()
    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    shm_before = shm.snapshot()
    link = HostLink(cfg.rank, len(local), new_session(),
                    faults=bool(cfg.faults) and cfg.groups is None)
    sup = Supervisor(on_restart=lambda ev: warn(f"{ev.name} exited with code {ev.code}; "
                                                f"restarted"))
    sampler = ResourceSampler(sup, robots=len(local))
    announcer = None
    relay = None
    joined = False  # past the checks: rank 0 counts this rank's end as a loss
    code = EXIT_OK
    try:
        identity = wait_for_leader(cfg, link, stop)
        if identity is None:
            return EXIT_OK
        joined = True
        say(f"rank 0 is up (run {identity.session}); starting this host's robots")
        write_params_files(cfg, template)
        if cfg.faults:  # this host's group processes and commanders read it
            from swarm_common.faults import dump_faults
            from swarm_up.children import faults_file

            dump_faults(cfg.faults, faults_file(cfg))
        if relays_states(cfg):  # before the group processes: they wait for its states
            from swarm_up.relay import StatesRelay

            relay = StatesRelay(cfg.rank, link.context)
            say(f"relaying the robots' states to this host's {len(cfg.groups)} group processes "
                f"on {relay.topic}")
        for spec in child_specs(cfg):
            try:
                sup.start(spec)
            except OSError as exc:
                raise RunError(f"cannot start {spec.argv[0]}: {exc.strerror}") from None
        faults = None
        if cfg.faults and cfg.groups is None:
            from swarm_up.faults import Announcer, ProcessFaults

            announcer = Announcer()
            faults = ProcessFaults(sup, local, announcer.ack, say, coordinator=False)
        leader_seen = time.monotonic()
        while stop.signum is None:
            for ev in sup.poll():
                spec = sup.children[ev.name].spec
                if not ev.restarted:
                    warn(f"{ev.name} exited with code {ev.code}; not restarted")
                if not ev.planned and spec.kind in ("nav", "group"):
                    from swarm_common.supervision import RobotsLost
                    from swarm_up.faults import Announcer

                    announcer = announcer or Announcer()
                    announcer.lost(RobotsLost(spec.robots, f"{ev.name} exited with code "
                                                           f"{ev.code} (rank {cfg.rank})",
                                              for_good=not ev.restarted))
            link.spin(0.0)
            twins = [t for t in link.others(cfg.rank, cfg.rank_timeout)
                     if t.session < link.session and t.state == UP]
            if twins:  # came up meanwhile (discovery was slow): the one with the greater run
                # id goes (a rule both sides agree on; the later start is mostly refused above)
                raise InputError(f"--host-rank: rank {cfg.rank} already runs on host "
                                 f"{twins[0].host} (pid {twins[0].pid}); every rank runs once")
            if faults is not None:
                for ev in link.fault_events():
                    faults.handle(ev)
            sampler.maybe_sample()
            res = sampler.result()
            per = res.get("peak_rss_mb_per_robot")
            link.report(UP, resources={"cpu_percent": res.get("cpu_percent"),
                                       "peak_rss_mb": per * len(local) if per else None},
                        restarts=sup.restarts,
                        fault_restarts=faults.fault_restarts if faults is not None else 0)
            ident = link.identity
            if ident is not None and (ident.state == ENDING or ident.session
                                      != identity.session):
                say(f"rank 0's run ended{'' if ident.state == ENDING else ' (a new run began)'};"
                    " stopping this host's robots")
                break
            leader = link.latest().get(0)
            if leader is not None:
                leader_seen = max(leader_seen, leader[1])
            if time.monotonic() - leader_seen > cfg.rank_timeout:
                warn(f"rank 0 silent for {cfg.rank_timeout:g} s (its process or the network is "
                     "gone); stopping this host's robots")
                code = EXIT_RUNTIME
                break
            time.sleep(POLL_PERIOD_S)
        return code
    finally:
        sampler.maybe_sample(force=True)
        sup.stop()
        if joined:
            link.report(ENDING, force=True)
            link.spin(0.2)
        if relay is not None:  # before its context is shut down
            relay.close()
        link.close()
        if announcer is not None:
            announcer.close()
        for s, h in old.items():
            signal.signal(s, h)
        shm.clean_after_run(shm_before)
