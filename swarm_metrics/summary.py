"""The summary table of a run's figures (``metrics.json``) that ``swarm-up`` prints at the end,
with its per-workstation table; rich on a terminal, plain text otherwise."""

from __future__ import annotations

from pathlib import Path


def _fmt(value, unit: str = "", digits: int = 2) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        text = f"{value:.{digits}f}"
    else:
        text = str(value)
    return f"{text} {unit}".rstrip()


def _windows(metrics: dict) -> str:
    """``70 / 72 / 68 (min/mean 0.96)``: tasks per window, the last one marked when short."""
    counts = [str(c) for c in metrics["tasks_per_window"]]
    if metrics.get("task_windows_full", len(counts)) < len(counts):
        counts[-1] += "*"
    ratio = metrics.get("task_window_ratio_min")
    return " / ".join(counts) + (f" (min/mean {ratio:.2f})" if ratio is not None else "")


def _per_robot(spread: dict) -> str:
    """``0 / 5 / 19 (min / median / max), 12 robots without a task``."""
    out = (f"{_fmt(spread.get('min'))} / {_fmt(spread.get('median'), digits=1)} / "
           f"{_fmt(spread.get('max'))} (min / median / max)")
    idle = spread.get("without_task") or 0
    return out + (f", {idle} robot{'s' if idle != 1 else ''} without a task" if idle else "")


def _standstills(episodes: list[dict]) -> str:
    """``5 times (3 robots), 610 s; near loader2 3, (elsewhere) 2``."""
    robots = {e.get("robot") for e in episodes}
    total = sum(e.get("duration_s") or 0.0 for e in episodes)
    near: dict[str, int] = {}
    for e in episodes:
        key = e.get("near") or "(elsewhere)"
        near[key] = near.get(key, 0) + 1
    places = ", ".join(f"{k} {v}" for k, v in sorted(near.items(), key=lambda kv: -kv[1]))
    return f"{len(episodes)} times ({len(robots)} robots), {total:.0f} s; near {places}"


def _workstation_table(rows: list[dict]):
    """The per-workstation table of the summary (``workstations`` of ``--metrics``)."""
    from rich.table import Table

    table = Table(title="workstations")
    table.add_column("workstation", no_wrap=True)
    for name in ("goals", "visits", "aborted", "time to goal", "holding", "wait"):
        table.add_column(name, justify="right")
    for row in rows:
        table.add_row(str(row.get("name")), _fmt(row.get("goals")), _fmt(row.get("visits")),
                      _fmt(row.get("aborted")), _fmt(row.get("mean_time_to_goal_s"), "s", 1),
                      _fmt(row.get("holding_time_s"), "s", 1),
                      _fmt(row.get("mean_wait_s"), "s", 1))
    return table


def _skipped(entries: list[str], shown: int = 3) -> str:
    """``2: actor 'walker', road 'lane'``: how many world elements the simulator left out, and
    the first ``shown`` of them (every one is in the simulator's log)."""
    more = len(entries) - shown
    return (f"{len(entries)}: " + ", ".join(entries[:shown])
            + (f" and {more} more (see logs/sim.log)" if more > 0 else ""))


def _robots(metrics: dict) -> str:
    """``20``, or with a mixed fleet ``20 (12 turtlebot3_waffle, 4 turtlebot3_burger, ...)``."""
    fleet = metrics.get("fleet") or {}
    if len(fleet) <= 1:
        return _fmt(metrics.get("robots"))
    return (f"{_fmt(metrics.get('robots'))} ("
            + ", ".join(f"{count} {model}" for model, count in fleet.items()) + ")")


def _hosts_table(hosts: list[dict]):
    """One row per host of a run over several hosts (``swarm-up --hosts``)."""
    from rich.table import Table

    table = Table(title="hosts")
    for name in ("rank", "host", "robots", "CPU", "peak RSS", "restarts"):
        table.add_column(name, justify="left" if name == "host" else "right")
    for h in hosts:
        table.add_row(str(h.get("rank")), f"{h.get('host') or '?'}"
                      + (" (lost)" if h.get("lost") else ""), _fmt(h.get("robots")),
                      _fmt(h.get("cpu_percent"), "%", 0), _fmt(h.get("peak_rss_mb"), "MB", 0),
                      _fmt(h.get("restarts")))
    return table


def print_summary(metrics: dict, metrics_files: list[Path]) -> None:
    """Print the run's figures as a table (rich; plain text when not a terminal)."""
    from rich.console import Console
    from rich.table import Table

    col = metrics.get("collisions") or {}
    rows = [
        ("robots", _robots(metrics)),
        ("world / seed", f"{metrics.get('world')} / {metrics.get('seed')}"),
        ("spawned", _fmt(metrics.get("spawn"))),
        *([("world elements skipped", _skipped(metrics["world_skipped"]))]
          if metrics.get("world_skipped") else []),
        ("coordination", _fmt(metrics.get("coordination"))),
        ("simulated time", _fmt(metrics.get("sim_time_s"), "s", 1)),
        ("wall time", _fmt(metrics.get("wall_time_s"), "s", 1)),
        ("real-time factor", _fmt(metrics.get("rtf"))),
        ("robot-ticks per wall second", _fmt(metrics.get("robot_ticks_per_s"), "", 0)),
        ("spawn to all ready", _fmt(metrics.get("spawn_to_ready_s"), "s")),
        ("tasks completed", _fmt(metrics.get("tasks_completed"))),
        ("throughput", _fmt(metrics.get("throughput_per_hour"), "tasks/h", 1)),
        *([(f"tasks per {_fmt(metrics.get('task_window_s'), '', 0)} s window",
            _windows(metrics))] if metrics.get("tasks_per_window") else []),
        *([("tasks per robot", _per_robot(metrics["tasks_per_robot"]))]
          if metrics.get("tasks_per_robot") else []),
        ("goals reached / aborted",
         f"{_fmt(metrics.get('goals_reached'))} / {_fmt(metrics.get('goals_aborted'))}"
         + (f"; {metrics['goals_at_another_workstation']} at another workstation"
            if metrics.get("goals_at_another_workstation") else "")),
        ("collisions robot-robot / wall",
         f"{_fmt(col.get('robot_robot'))} / {_fmt(col.get('robot_wall'))}"),
        ("min separation", _fmt(metrics.get("min_separation_m"), "m")),
        ("mean time to goal", _fmt(metrics.get("mean_time_to_goal_s"), "s", 1)),
        ("time holding", _fmt(metrics.get("holding_time_s"), "s", 1)),
        *([("standing still >= 60 s", _standstills(metrics["standstills"]))]
          if metrics.get("standstills") else []),
        *([("waiting at coordinator's spots", _fmt(metrics.get("coordinator_wait_s"), "s", 1)),
           ("reservation conflicts", _fmt(metrics.get("reservation_conflicts")))]
          if metrics.get("coordination") == "centralized" else []),
        ("late ticks", _fmt(metrics.get("late_ticks"))),
        ("goal-wait timeouts / late goals",
         f"{_fmt(metrics.get('goal_wait_timeouts'))} / {_fmt(metrics.get('late_goals'))}"),
        ("reproducible (seed alone decides)", {True: "yes", False: "no", None: "unknown"}.get(
            metrics.get("reproducible"), "unknown")),
        ("communication load (central)",
         f"{_fmt(metrics.get('comm_messages_per_s'), 'msg/s', 2)}, "
         f"{_fmt(metrics.get('comm_bytes_per_s'), 'B/s', 0)}"),
        ("CPU (100 % = one core)", _fmt(metrics.get("cpu_percent"), "%", 0)),
        ("peak RSS per robot", _fmt(metrics.get("peak_rss_mb_per_robot"), "MB", 1)),
        ("restarts", _fmt(metrics.get("restarts"))),
    ]
    if metrics.get("faults"):
        by_kind = metrics.get("faults_by_kind") or {}
        rows.append(("faults injected", ", ".join(f"{k} {v}" for k, v in by_kind.items())))
        if metrics.get("fault_messages_dropped"):
            rows.append(("messages dropped by faults", _fmt(metrics["fault_messages_dropped"])))
    table = Table(title="swarm-up summary", show_header=False)
    table.add_column("figure")
    table.add_column("value", justify="right")
    for name, value in rows:
        table.add_row(name, value)
    console = Console()
    console.print(table)
    stations = metrics.get("workstations") or []
    if any(row.get("goals") for row in stations):
        console.print(_workstation_table(stations))
    if metrics.get("hosts"):
        console.print(_hosts_table(metrics["hosts"]))
    for path in metrics_files:
        print(f"metrics: {path}", flush=True)

