"""The recorder process of ``swarm-up --record``: the swarm's topics into one MCAP file.

``python -m swarm_record.recorder --out RUN.mcap --robots Srobot1,Srobot2 ...`` is started and
supervised by ``swarm-up`` before the simulator (docs/ARCHITECTURE.md, Recording).  It
subscribes with ``raw=True`` (the CDR bytes as they came, no conversion to Python messages) to
the topics of :func:`swarm_record.mcap_format.recorded_topics` that ``--topics`` selects, and
writes them with :class:`~swarm_record.mcap_format.McapRecording`; ``/tf`` is built from each
robot's ``odom`` and ``ground_truth`` (:class:`~swarm_record.mcap_format.TfBuilder`).

No message of ``/clock``, ``odom`` or ``ground_truth`` is lost under ``--rtf 0``, whatever
stalls the recorder: every subscription keeps up to :data:`QUEUE_DEPTH` messages, and the
recorder publishes on ``/swarm/record/progress`` (:data:`swarm_common.topics.RECORD_PROGRESS`)
the latest tick of which all of them have come (:class:`~swarm_record.mcap_format.TickProgress`),
by which the simulator holds a tick while the recorder is more than two ticks behind: the
writers keep 10, so a message lost on the way (a frozen reader's shared-memory port is reset
after a second) is sent again from its writer's history before newer ones push it out.  With
faults (``--progress clock``), a muted robot skips ticks and the window follows ``/clock``
alone.  Scans are best effort, as the simulator publishes them.

Log and publish times are simulated time (as ``ros2 bag record --use-sim-time``): a message's
``header.stamp`` when it has one (the value itself for ``/clock``), else the latest ``/clock``.

The simulator's start gate holds the first tick until the recorder's subscriptions to its topics
are matched; it sees only its writers' side of each match, so one of those subscriptions is made
last, once every other one has matched its writer on the recorder's side (a reader drops what
comes before it has: once, under load, a recording lost every robot's first two ticks of
``odom`` and ``ground_truth``).

On SIGINT or SIGTERM, or when its parent process has gone, it takes what is still queued (up to
:data:`DRAIN_S`), writes the file's summary and exits 0.  Killed, it leaves every finished chunk.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time

from swarm_common import cdr, cli, topics
from swarm_common.errors import run_cli
from swarm_common.topics import Qos
from swarm_record import mcap_format as rec

PROG = "swarm-up-record"
QUEUE_DEPTH = 2000  # [messages] per subscription: 40 s of odometry at RTF 5 (10 Hz ticks)
DRAIN_S = 1.0  # [s] wall spent taking the queued messages after a stop
PARENT_CHECK_S = 0.5  # [s] wall between checks that swarm-up still runs
READY_LINE = "recorder ready"
"""Printed (with the number of subscriptions) once every subscription exists; ``swarm-up``
starts the simulator after it."""

_NO_HEADER = {"diagnostic_msgs/msg/DiagnosticStatus"}  # log time = the latest /clock


def _stamp(data: bytes) -> int:
    """A message's header stamp [ns], 0 if it cannot be read."""
    try:
        return cdr.header_stamp(data)
    except ValueError:
        return 0


def build_parser():
    """The recorder's argument parser (started by ``swarm-up``, not by users)."""
    p = cli.ArgumentParser(prog=PROG, description="Record a swarm's topics to MCAP (started "
                           "by swarm-up --record).")
    p.add_argument("--out", required=True, help="the .mcap file to write")
    p.add_argument("--robots", required=True, help="namespaces, comma-separated")
    p.add_argument("--topics", default=None, metavar="REGEX",
                   help="record only topics whose name matches (re.search)")
    p.add_argument("--lidar", default="0,0,0,0", metavar="X,Y,Z,YAW[;X,Y,Z,YAW...]",
                   help="lidar pose in base_footprint [m, rad]; or one per robot, in --robots' "
                   "order, separated by ';' (a mixed fleet)")
    p.add_argument("--lidar-frame", default="base_scan",
                   help="lidar link name; or one per robot, comma-separated")
    p.add_argument("--meta", default="{}", help="JSON object: the run's metadata record")
    p.add_argument("--chunk-size", type=cli.positive_int, default=rec.CHUNK_SIZE,
                   help="chunk size [bytes]")
    p.add_argument("--compression", choices=("zstd", "lz4", "none"), default="zstd")
    p.add_argument("--progress", choices=("ticks", "clock"), default="ticks",
                   help="what /swarm/record/progress follows: ticks (every /clock, odom and "
                   "ground_truth it reads, the default) or clock (only /clock: a run with "
                   "faults, whose muted robots skip ticks)")
    p.add_argument("--control-rate", type=cli.positive_float, default=10.0, metavar="HZ",
                   help="the simulator's control ticks per simulated second, to count lost "
                   "ticks [10]")
    return p


def _qos_dict(profile) -> dict:
    """rclpy ``QoSProfile`` -> the dict of :func:`swarm_record.mcap_format.qos_yaml`."""
    return {
        "history": profile.history.name.lower(),
        "depth": int(profile.depth),
        "reliability": profile.reliability.name.lower(),
        "durability": profile.durability.name.lower(),
        "deadline_ns": profile.deadline.nanoseconds,
        "lifespan_ns": profile.lifespan.nanoseconds,
        "liveliness": profile.liveliness.name.lower(),
        "lease_ns": profile.liveliness_lease_duration.nanoseconds,
    }


def _subscription_qos(offered: dict) -> Qos:
    """The recorder's reader of a topic whose writers offer ``offered`` (rosbag2's names): the
    same reliability and durability, and a queue of :data:`QUEUE_DEPTH`."""
    return Qos(QUEUE_DEPTH, offered["reliability"], offered["durability"])


def make_node(recording: rec.McapRecording, robots, selected, tf: rec.TfBuilder | None,
              progress: str = "ticks", period_ns: int = 100_000_000):
    """The recorder node (``/swarm_recorder``): raw subscriptions that write to ``recording``.

    Args:
        recording: the open file.
        robots: namespaces without ``/``.
        selected: the :class:`~swarm_record.mcap_format.RecordedTopic` to write.
        tf: builds ``/tf`` when it is selected, else None.
        progress: ``ticks``: ``/swarm/record/progress`` is the latest tick of which ``/clock``
            and every ``odom`` and ``ground_truth`` read has come
            (:class:`~swarm_record.mcap_format.TickProgress`); ``clock``: of ``/clock`` alone.
        period_ns: the simulator's control tick [ns].
    """
    from builtin_interfaces.msg import Time
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock

    from swarm_ros.qos import message_class, profile, publisher

    class RecorderNode(Node):
        def __init__(self):
            super().__init__(rec.RECORDER_NODE)
            # state
            self.clock_ns = 0
            self.recording = recording
            self.progress_pub = publisher(self, Clock, topics.RECORD_PROGRESS)
            self._tf_topic = next((t for t in selected if t.name == rec.TF_TOPIC), None)
            # subscriptions
            self.subs = []
            self._from_sim = []  # the subscriptions to the simulator's topics, made so far
            wanted = rec.recorder_subscriptions(robots, selected)
            tracked = [t.name for t in wanted if t.name == topics.CLOCK.name or (
                progress == "ticks" and t.robot
                and t.name.rsplit("/", 1)[-1] in rec.EVERY_TICK_ROBOT_TOPICS)]
            self.progress = rec.TickProgress(tracked, period_ns)
            sim = [t for t in wanted if rec.from_simulator(t)]
            # The simulator's start gate waits until all of these are matched, but it sees only
            # its writers' side: a reader drops what comes before it has matched the writer on
            # its own side. So one of them (a transient-local one where there is: its history
            # makes up for its own late match) is made only once every other one has matched
            # its writer here (:meth:`make_deferred`): until then the gate holds the first tick.
            self.deferred = min(sim, key=lambda t: t.qos.get("durability") != "transient_local",
                                default=None)
            for t in wanted:
                if t is not self.deferred:
                    self._subscribe(t, t.name in {s.name for s in selected})
            self._deferred_write = self.deferred is not None and self.deferred.name in {
                s.name for s in selected}

        def _subscribe(self, t: rec.RecordedTopic, write: bool) -> None:
            sub = self.create_subscription(message_class(t.type), t.name, self._callback(t, write),
                                           profile(_subscription_qos(t.qos)), raw=True)
            self.subs.append(sub)
            if rec.from_simulator(t):
                self._from_sim.append(sub)

        def make_deferred(self) -> bool:
            """Make the deferred subscription once every other subscription to the simulator's
            topics has matched its writer on the reader's side; True once it is made."""
            if self.deferred is None:
                return True
            if any(sub.get_publisher_count() < 1 for sub in self._from_sim):
                return False
            self._subscribe(self.deferred, self._deferred_write)
            print(f"every simulator topic matched; subscribed to {self.deferred.name} last",
                  flush=True)
            self.deferred = None
            return True

        def _callback(self, topic: rec.RecordedTopic, write: bool):
            name = topic.name
            suffix = name.rsplit("/", 1)[-1]
            feed = None
            if tf is not None and topic.robot and suffix in rec.TF_SOURCES:
                feed = tf.on_odom if suffix == topics.ODOM.name else tf.on_ground_truth
            is_clock = name == topics.CLOCK.name
            tracked = name in self.progress.last
            headerless = topic.type in _NO_HEADER
            ns = topic.robot

            def on_message(data: bytes) -> None:
                if headerless:
                    t_ns = self.clock_ns
                else:
                    t_ns = _stamp(data) or self.clock_ns
                    if is_clock and t_ns > self.clock_ns:
                        self.clock_ns = t_ns
                if write:
                    if name not in self.recording.channels:
                        self._register(topic)
                    self.recording.write(name, t_ns, data)
                if tracked:
                    done = self.progress.on_message(name, t_ns)
                    if done is not None:
                        sec, nsec = divmod(done, 1_000_000_000)
                        self.progress_pub.publish(Clock(clock=Time(sec=sec, nanosec=nsec)))
                if feed is not None:
                    out = feed(ns, data)
                    if out is not None:
                        if rec.TF_TOPIC not in self.recording.channels:
                            self._register(self._tf_topic)
                        self.recording.write(rec.TF_TOPIC, t_ns, out)

            return on_message

        def _register(self, topic: rec.RecordedTopic) -> None:
            infos = [] if topic.name == rec.TF_TOPIC else (
                self.get_publishers_info_by_topic(topic.name))
            profiles = []
            for info in infos:
                p = _qos_dict(info.qos_profile)
                if p["history"] not in ("keep_last", "keep_all"):  # not carried by discovery
                    p["history"], p["depth"] = topic.qos["history"], topic.qos["depth"]
                profiles.append(p)
            self.recording.add_channel(topic.name, topic.type,
                                       rec.qos_yaml(profiles or [dict(topic.qos)]))

    return RecorderNode()


def main(argv: list[str] | None = None) -> int:
    """Entry point (``python -m swarm_record.recorder``); returns the exit code."""

    def body() -> int:
        args = build_parser().parse_args(argv)
        robots = tuple(r for r in args.robots.split(",") if r)
        selected = rec.select_topics(rec.recorded_topics(robots), args.topics)
        poses = [tuple(float(v) for v in part.split(",")) for part in args.lidar.split(";")]
        frames = args.lidar_frame.split(",")
        tf = (rec.TfBuilder(robots, poses[0] if len(poses) == 1 else dict(
                  zip(robots, poses, strict=True)),
                  frames[0] if len(frames) == 1 else dict(zip(robots, frames, strict=True)))
              if any(t.name == rec.TF_TOPIC for t in selected) else None)
        return _record(args, robots, selected, tf)

    return run_cli(PROG, body)


def _record(args, robots, selected, tf) -> int:
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions

    from swarm_ros.session import node_session

    stop = {"why": None}

    def on_signal(signum, frame):
        stop["why"] = signal.Signals(signum).name

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    parent = os.getppid()
    recording = rec.McapRecording(args.out, chunk_size=args.chunk_size,
                                  compression=args.compression)
    meta = json.loads(args.meta)
    if meta:
        recording.add_metadata(rec.META_NAME, {k: str(v) for k, v in meta.items()})
    with node_session([], signal_handler_options=SignalHandlerOptions.NO) as nodes:
        node = make_node(recording, robots, selected, tf, args.progress,
                         round(1e9 / args.control_rate))
        nodes.append(node)
        executor = EventsExecutor()
        executor.add_node(node)
        print(f"{READY_LINE}: {len(node.subs)} subscriptions, writing {args.out}", flush=True)
        next_check = time.monotonic() + PARENT_CHECK_S
        try:
            while stop["why"] is None and rclpy.ok():
                executor.spin_once(timeout_sec=0.1)
                node.make_deferred()
                now = time.monotonic()
                if now >= next_check:
                    next_check = now + PARENT_CHECK_S
                    if os.getppid() != parent:
                        stop["why"] = "parent gone"
            until = time.monotonic() + DRAIN_S
            while time.monotonic() < until and rclpy.ok():
                executor.spin_once(timeout_sec=0.05)
        finally:
            recording.close()
            executor.shutdown()
    total = sum(recording.counts.values())
    size_mb = os.path.getsize(args.out) / 2**20
    lost = node.progress.lost
    print(f"recorded {total} messages on {len(recording.counts)} topics to {args.out} "
          f"({size_mb:.1f} MB; stopped: {stop['why']}"
          + (f"; {lost} ticks of /clock, odom or ground_truth lost" if lost else "") + ")",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
