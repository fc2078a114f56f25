"""The simulator's run summary (``swarm-sim --summary``) from its engine and its tick gate.

Pure (no ROS): :func:`summarize` reads the engine's per-robot counters, the gate's late ticks
and the loop's log, and builds the :class:`swarm_common.sim_summary.SimSummary` record that
``swarm-up`` reads back into ``metrics.json``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from swarm_common.sim_summary import CollisionCounts, RobotSummary, SimSummary
from swarm_common.stamps import NS_PER_S
from swarm_sim.standstill import StandstillTracker


@dataclass
class RunLog:
    """What the simulator's loop records beside the engine and the gate.

    Attributes:
        standstills: robots at rest for 60 s or more (:mod:`swarm_sim.standstill`).
        wall_timeline: [k] wall seconds from the start gate to simulated second k + 1 (two runs
            of one seed do the same simulated work, so the ratio of their timelines shows what
            else differed) [s].
        dropped: malformed messages dropped [-].
        fault_log: every fault transition applied, in order (``fault``, ``kind``, ``phase``,
            ``robot``, ``t`` [s], and ``x``, ``y`` [m] where the robot was).
        track: [k] every robot's x, y [m] in ``map`` (rounded to the centimetre) at simulated
            second k + 1: the ground truth the metrics' waiting measure reads
            (:mod:`swarm_metrics.waiting`).
    """

    standstills: StandstillTracker
    wall_timeline: list[float] = field(default_factory=list)
    dropped: int = 0
    fault_log: list[dict] = field(default_factory=list)
    track: list = field(default_factory=list)

    def sample(self, t_ns: int, poses) -> None:
        """Keep the robots' positions at whole simulated seconds (``t_ns`` [ns], ``poses``
        (N, 3) x, y [m], yaw [rad]): one (N, 2) array a second (16 bytes a robot; Python
        lists of floats cost 50 MB at 1,000 robots over 300 s)."""
        if t_ns % NS_PER_S == 0 and t_ns > 0:
            self.track.append(np.round(np.asarray(poses, dtype=float)[:, :2], 2))


def summarize(engine, gate, namespaces: list[str], log: RunLog, faults, wall_s: float,
              spawn: str | None = None, world_skipped: tuple[str, ...] = ()) -> SimSummary:
    """The run's figures for ``--summary`` (:mod:`swarm_common.sim_summary`).

    Args:
        engine: the :class:`swarm_sim.engine.SimEngine` after the run.
        gate: the run's :class:`swarm_sim.tick.TickGate`.
        namespaces: (N) robot namespaces, index-aligned with the engine.
        log: the loop's :class:`RunLog`.
        faults: the :class:`swarm_sim.faults.SimFaults` of the run, or None.
        wall_s: [s] wall time of the simulation loop.
        spawn: where the robots went (:func:`swarm_sim.settings.prepare`'s ``spawned``), the
            extra ``spawn``.
        world_skipped: the world's skip report (``World.skipped``), the extra
            ``world_skipped``.
    """
    sim_s = gate.t_ns / NS_PER_S
    fleet: dict[str, int] = {}  # model name -> robots of it, in order of first robot
    for model in engine.models:
        fleet[model.name] = fleet.get(model.name, 0) + 1
    extras = {"wall_timeline_s": list(log.wall_timeline),
              "fleet": fleet,
              "spawn": spawn,
              "world_skipped": list(world_skipped),
              "standstills": [{"robot": namespaces[e.robot], "start_s": e.start_s,
                               "duration_s": e.duration_s, "x": e.x, "y": e.y,
                               "open": e.open} for e in log.standstills.finish()],
              "track": {"period_s": 1.0, "xy": [xy.tolist() for xy in log.track]}}
    if faults is not None:
        extras["faults"] = {
            "injected": [f.label() for f in faults.faults],
            "messages_dropped": {str(k): v for k, v in faults.dropped.items()},
            "log": log.fault_log,
        }
    per_robot = {
        ns: RobotSummary(distance_m=round(float(engine.distance[i]), 3),
                         collisions=int(engine.collisions[i]),
                         late_ticks=int(gate.late_ticks[i]))
        for i, ns in enumerate(namespaces)
    }
    n = len(namespaces)
    return SimSummary(
        robots=n,
        ticks=int(engine.ticks),
        sim_time_s=round(sim_s, 3),
        wall_time_s=round(wall_s, 3),
        rtf=round(sim_s / wall_s, 3) if wall_s > 0 else None,
        robot_ticks_per_s=round(n * engine.ticks / wall_s, 1) if wall_s > 0 else None,
        late_ticks=int(gate.late_ticks.sum()),
        dropped_messages=log.dropped,
        collisions=CollisionCounts(**engine.collision_counts),
        min_separation_m=(round(engine.min_separation, 4)
                          if math.isfinite(engine.min_separation) else None),
        per_robot=per_robot,
        extras=extras,
    )
