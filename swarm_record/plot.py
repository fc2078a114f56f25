"""``swarm-plot``: pictures of a recorded run (docs/reference/contract.md#s2).

``swarm-plot RUN_DIR|FILE.mcap [-o OUT.png]`` reads a recording of ``swarm-up --record`` and
draws two PNG figures (matplotlib, Agg backend):

1. ``OUT.png``: every robot's trajectory (``ground_truth``, else ``odom``) over the map, one
   colour per robot, its start (circle) and end (triangle); collisions from ``/swarm/events``
   (red crosses); the workstations, named; their holding spots (squares) and where robots
   started to hold (``nav_status`` HOLDING, diamonds).
2. ``OUT-tasks.png``: tasks completed over simulated time (the throughput curve; a task is a
   goal reached, counted once per goal id as in ``--metrics``, :mod:`swarm_metrics.aggregate`).

A ``RUN_DIR`` is a ``swarm-up`` run directory that holds its recording: the file named by
``"recording"`` in its ``metrics.json``, else ``RUN_DIR/recording.mcap`` (what ``swarm-up
--record`` without a path writes), else the only ``*.mcap`` in it.  A recording cut short (a
killed run) is read up to its last complete chunk.

Reading is split from drawing: :func:`read_run` returns a :class:`RunTrace` of plain arrays.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from swarm_common import cdr, cli, topics
from swarm_common.errors import InputError, run_cli
from swarm_common.events import COLLISION, CollisionEvent
from swarm_common.nav_status import NavState, decode
from swarm_record import mcap_format as rec

PROG = "swarm-plot"
FIG_SIZE = (10.0, 8.0)  # [in] trajectories figure
DPI = 120
ROBOT_COLORS = "tab10"  # matplotlib colormap; cycles after 10 robots (tab20 above 10)


@dataclass
class RunTrace:
    """What a recording holds for the pictures, in ``map``.

    Attributes:
        robots: namespaces, in the order of the run.
        paths: robot -> (K, 3) array of t [s simulated], x, y [m].
        collisions: (C, 2) x, y [m] of every collision event.
        holding_starts: robot -> (H, 2) x, y [m] where it entered HOLDING.
        tasks: sorted simulated times [s] at which a goal was reached (once per goal id).
        workstations: ``[{"name", "x", "y", "yaw", "holding"}, ...]`` from the run's metadata.
        grid: occupancy (H, W) int8 (-1 unknown, 0..100), row 0 at the map origin, or None.
        origin: (x, y) [m] of the grid's cell (0, 0) corner; resolution: [m/cell].
        duration_s: [s] simulated time of the last message.
        world: the world's name (from the metadata), or "".
        truncated: the file ended before its summary (a killed recorder).
    """

    robots: list[str] = field(default_factory=list)
    paths: dict[str, np.ndarray] = field(default_factory=dict)
    collisions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    holding_starts: dict[str, np.ndarray] = field(default_factory=dict)
    tasks: list[float] = field(default_factory=list)
    workstations: list[dict] = field(default_factory=list)
    grid: np.ndarray | None = None
    origin: tuple[float, float] = (0.0, 0.0)
    resolution: float = 0.05
    duration_s: float = 0.0
    world: str = ""
    truncated: bool = False


# --------------------------------------------------------------------------------------- reading
def find_recording(path: Path) -> Path:
    """The recording of a run directory, or ``path`` itself if it is a file (module docstring).

    Raises:
        InputError: no such file or directory, not an ``.mcap`` file, or no recording in it.
    """
    if path.is_file():
        if path.suffix != ".mcap":
            raise InputError(f"RUN: '{path}' is not an .mcap file")
        return path
    if not path.is_dir():
        raise InputError(f"RUN: no such file or directory '{path}'")
    metrics = path / "metrics.json"
    if metrics.is_file():
        try:
            named = json.loads(metrics.read_text()).get("recording")
        except (ValueError, AttributeError):
            named = None
        if named and Path(named).is_file():
            return Path(named)
    if (path / "recording.mcap").is_file():
        return path / "recording.mcap"
    found = sorted(path.glob("*.mcap"))
    if len(found) == 1:
        return found[0]
    if not found:
        raise InputError(f"RUN: no recording in '{path}' (record with swarm-up --record)")
    raise InputError(f"RUN: {len(found)} .mcap files in '{path}'; name one")


def _records(fh):
    """Every (schema, channel, message) of the file in file order; stops quietly at a cut-off
    end.  Returns a generator; ``truncated`` is set on it through the holder list."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas, channels = {}, {}
    state = {"truncated": False, "metadata": {}}

    def gen():
        try:
            for record in StreamReader(fh, emit_chunks=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    ch = channels[record.channel_id]
                    yield schemas.get(ch.schema_id), ch, record
                elif type(record).__name__ == "Metadata":
                    state["metadata"][record.name] = dict(record.metadata)
        except (McapError, EOFError, ValueError, KeyError, OSError) as exc:
            state["truncated"] = True
            state["error"] = str(exc)

    return gen(), state


class _TraceReader:
    """What :func:`read_run` takes from a recording's messages, one message at a time."""

    def __init__(self):
        from mcap_ros2.decoder import DecoderFactory

        self._factory = DecoderFactory()
        self._decoders: dict[int, object] = {}
        self.truth: dict[str, list] = {}
        self.odom: dict[str, list] = {}
        self.collisions: list[tuple[float, float]] = []
        self.holding_t: dict[str, list[float]] = {}
        self.reached: dict[tuple[str, str], float] = {}
        self.last_state: dict[str, NavState | None] = {}
        self.trace = RunTrace()
        self.last_t = 0

    def _decoded(self, schema, channel, message):
        fn = self._decoders.get(channel.id)
        if fn is None:
            fn = self._decoders[channel.id] = self._factory.decoder_for(
                channel.message_encoding, schema)
        return fn(message.data)

    def take(self, schema, channel, message) -> None:
        """One recorded message: a pose, a status, the events or the map."""
        topic = channel.topic
        self.last_t = max(self.last_t, message.log_time)
        parts = topic.strip("/").split("/")
        if len(parts) == 2 and parts[1] in (topics.GROUND_TRUTH.name, topics.ODOM.name):
            stamp, pose = cdr.odometry_pose(message.data)
            rows = self.truth if parts[1] == topics.GROUND_TRUTH.name else self.odom
            rows.setdefault(parts[0], []).append((stamp / 1e9, pose[0], pose[1]))
        elif len(parts) == 2 and parts[1] == topics.NAV_STATUS.name:
            self._take_status(parts[0], self._decoded(schema, channel, message),
                              message.log_time)
        elif topic == topics.EVENTS.name:
            for status in self._decoded(schema, channel, message).status:
                if status.name == COLLISION:
                    ev = CollisionEvent.decode({kv.key: kv.value for kv in status.values})
                    if ev is not None:
                        self.collisions.append((ev.x, ev.y))
        elif topic == topics.MAP.name and self.trace.grid is None:
            info = (msg := self._decoded(schema, channel, message)).info
            self.trace.grid = np.frombuffer(bytes(np.asarray(msg.data, dtype=np.int8)),
                                            dtype=np.int8).reshape(info.height, info.width)
            self.trace.origin = (info.origin.position.x, info.origin.position.y)
            self.trace.resolution = info.resolution

    def _take_status(self, ns: str, msg, log_time: int) -> None:
        status = decode({kv.key: kv.value for kv in msg.values}, msg.message)
        t = (status.stamp_ns if status.stamp_ns is not None else log_time) / 1e9
        if status.state == NavState.SUCCEEDED and status.goal_id:
            self.reached.setdefault((ns, status.goal_id), t)
        if status.state == NavState.HOLDING and self.last_state.get(ns) != NavState.HOLDING:
            self.holding_t.setdefault(ns, []).append(t)
        self.last_state[ns] = status.state

    def finish(self, state: dict, path: Path) -> RunTrace:
        """The trace, with the recording's metadata (``state`` of :func:`_records`).

        Raises:
            InputError: no trajectory in the recording.
        """
        trace = self.trace
        meta = state["metadata"].get(rec.META_NAME, {})
        trace.truncated = state["truncated"]
        trace.world = Path(meta.get("world", "")).stem
        try:
            trace.workstations = json.loads(meta.get("workstations", "[]"))
        except ValueError:
            trace.workstations = []
        source = self.truth if self.truth else self.odom
        if not source:
            raise InputError(f"RUN: '{path}' holds no ground_truth or odom messages to draw")
        order = [r for r in meta.get("robots", "").split(",") if r in source]
        trace.robots = order + sorted(r for r in source if r not in order)
        for ns, rows in source.items():
            arr = np.asarray(sorted(set(rows)), dtype=float)
            trace.paths[ns] = arr
            times = self.holding_t.get(ns, [])
            if times and len(arr):
                idx = np.clip(np.searchsorted(arr[:, 0], times), 0, len(arr) - 1)
                trace.holding_starts[ns] = arr[idx, 1:3]
        trace.collisions = np.asarray(self.collisions, dtype=float).reshape(-1, 2)
        trace.tasks = sorted(self.reached.values())
        trace.duration_s = self.last_t / 1e9
        return trace


def read_run(path: Path) -> RunTrace:
    """Read a recording into a :class:`RunTrace`.

    Args:
        path: the ``.mcap`` file.

    Raises:
        InputError: not an MCAP file, or no trajectory in it (``ground_truth`` and ``odom`` were
            not recorded).
    """
    reader = _TraceReader()
    with open(path, "rb") as fh:
        if fh.read(8) != b"\x89MCAP0\r\n":
            raise InputError(f"RUN: '{path}' is not an MCAP file")
        fh.seek(0)
        messages, state = _records(fh)
        for schema, channel, message in messages:
            reader.take(schema, channel, message)
    return reader.finish(state, path)


# --------------------------------------------------------------------------------------- drawing
def robot_colors(n: int) -> list[tuple[float, float, float]]:
    """One RGB colour per robot: tab10 up to 10 robots, tab20 up to 20, then cycled."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if n <= 10 else "tab20"]
    return [tuple(cmap(i % cmap.N)[:3]) for i in range(n)]


def plot_trajectories(trace: RunTrace, out: Path) -> None:
    """Draw figure 1 (module docstring) to ``out`` (PNG)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=FIG_SIZE, dpi=DPI)
    if trace.grid is not None:
        h, w = trace.grid.shape
        x0, y0 = trace.origin
        shade = np.where(trace.grid < 0, 0.85, 1.0 - np.clip(trace.grid, 0, 100) / 100.0)
        ax.imshow(shade, cmap="gray", vmin=0.0, vmax=1.0, origin="lower", interpolation="nearest",
                  extent=(x0, x0 + w * trace.resolution, y0, y0 + h * trace.resolution))
    for ns, color in zip(trace.robots, robot_colors(len(trace.robots)), strict=True):
        xy = trace.paths[ns][:, 1:3]
        ax.plot(xy[:, 0], xy[:, 1], "-", color=color, lw=1.6, label=ns)
        ax.plot(*xy[0], "o", color=color, ms=6)
        ax.plot(*xy[-1], "^", color=color, ms=7, mec="black", mew=0.5)
        hold = trace.holding_starts.get(ns)
        if hold is not None and len(hold):
            ax.plot(hold[:, 0], hold[:, 1], "D", color=color, ms=6, mec="black", mew=0.8)
    for i, ws in enumerate(trace.workstations):
        ax.plot(ws["x"], ws["y"], "s", color="black", ms=9, mfc="none", mew=1.5,
                label="workstation" if i == 0 else None)
        ax.annotate(ws["name"], (ws["x"], ws["y"]), textcoords="offset points", xytext=(6, 6),
                    fontsize=8, weight="bold")
        spots = np.asarray(ws.get("holding") or [], dtype=float).reshape(-1, 2)
        if len(spots):
            ax.plot(spots[:, 0], spots[:, 1], "s", color="0.4", ms=5, mfc="none",
                    label="holding spot" if i == 0 else None)
    if len(trace.collisions):
        ax.plot(trace.collisions[:, 0], trace.collisions[:, 1], "x", color="red", ms=11, mew=2.5,
                label=f"collision ({len(trace.collisions)})")
    if any(len(v) for v in trace.holding_starts.values()):
        ax.plot([], [], "D", color="white", mec="black", label="started holding")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (map)")
    ax.set_ylabel("y [m] (map)")
    cut = " (recording cut short)" if trace.truncated else ""
    ax.set_title(f"{trace.world or 'run'}: {len(trace.robots)} robots, "
                 f"{trace.duration_s:.0f} s simulated{cut}")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def plot_tasks(trace: RunTrace, out: Path) -> None:
    """Draw figure 2 (tasks completed over simulated time) to ``out`` (PNG)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 4.5), dpi=DPI)
    t = np.asarray([0.0, *trace.tasks, max(trace.duration_s, *trace.tasks, 0.0)])
    n = np.asarray([0, *range(1, len(trace.tasks) + 1), len(trace.tasks)])
    ax.step(t, n, where="post", color="tab:blue", lw=2)
    hours = trace.duration_s / 3600.0
    rate = len(trace.tasks) / hours if hours > 0 else 0.0
    ax.set_xlabel("simulated time [s]")
    ax.set_ylabel("tasks completed")
    ax.set_title(f"{len(trace.tasks)} tasks in {trace.duration_s:.0f} s simulated "
                 f"({rate:.0f} tasks/h)")
    ax.grid(alpha=0.3)
    ax.set_xlim(left=0.0)
    ax.set_ylim(bottom=0)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def output_paths(recording: Path, out: Path | None) -> tuple[Path, Path]:
    """``(trajectories, tasks)`` PNGs: ``OUT.png`` and ``OUT-tasks.png``; by default
    ``<recording stem>-trajectories.png`` and ``<recording stem>-tasks.png`` beside it."""
    if out is None:
        base = recording.with_name(recording.stem)
        return (base.with_name(base.name + "-trajectories.png"),
                base.with_name(base.name + "-tasks.png"))
    return out, out.with_name(out.stem + "-tasks.png")


def build_parser():
    """The ``swarm-plot`` argument parser."""
    p = cli.ArgumentParser(
        prog=PROG,
        description="Pictures of a recorded run: trajectories over the map (one colour per "
        "robot; collisions, workstations, holding spots) and tasks completed over simulated "
        "time.",
        epilog="RUN is a recording (.mcap, from swarm-up --record) or a swarm-up run directory "
        "holding one (the file named in its metrics.json, else RUN/recording.mcap, else its "
        "only .mcap file). Exit codes: 0 success, 2 bad input, 1 runtime failure.")
    p.add_argument("run", type=Path, metavar="RUN_DIR|FILE.mcap",
                   help="the recording or the run directory")
    p.add_argument("-o", "--output", type=Path, default=None, metavar="OUT.png",
                   help="trajectories PNG; the tasks figure goes to OUT-tasks.png (default: "
                   "<recording>-trajectories.png and <recording>-tasks.png beside the file)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-plot``; returns the exit code."""

    def body() -> int:
        args = build_parser().parse_args(argv)
        if args.output is not None:
            if args.output.suffix.lower() != ".png":
                raise InputError(f"--output: '{args.output}' must end in .png")
            if not args.output.expanduser().resolve().parent.is_dir():
                raise InputError(f"--output: directory '{args.output.parent}' does not exist")
        path = find_recording(args.run.expanduser())
        import matplotlib

        matplotlib.use("Agg")
        print(f"{PROG}: reading {path} ...", flush=True)
        trace = read_run(path)
        traj, tasks = output_paths(path, args.output)
        plot_trajectories(trace, traj)
        plot_tasks(trace, tasks)
        cut = "; the recording was cut short (read to its last complete chunk)" if (
            trace.truncated) else ""
        print(f"{PROG}: {len(trace.robots)} robots, {trace.duration_s:.0f} s simulated, "
              f"{len(trace.tasks)} tasks, {len(trace.collisions)} collisions{cut}", flush=True)
        print(f"{PROG}: wrote {traj} and {tasks}", flush=True)
        return 0

    return run_cli(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
