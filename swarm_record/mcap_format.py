"""What ``swarm-up --record`` writes, and how: the MCAP ``ros2`` profile, pure (no rclpy).

A recording is one MCAP file (https://mcap.dev/spec, profile ``ros2``, as rosbag2's MCAP
storage plugin writes it): messages in ``cdr`` encoding, one ``ros2msg`` schema per type (the
``.msg`` text of the type followed by every type it uses, each after a line of 80 ``=`` and
``MSG: pkg/Type``), and on every channel the metadata ``offered_qos_profiles`` (YAML, the
format of rosbag2's ``qos.cpp`` for bag version 9: policies by name) that ``ros2 bag play`` needs
to re-offer the topic and that the Python ``mcap_ros2`` writer leaves out.  The file is written
in compressed chunks of :data:`CHUNK_SIZE` bytes through an unbuffered file: a recorder killed
with SIGKILL leaves every chunk it finished readable.

This module holds the contract of a recording (:func:`recorded_topics`: the topics, types and
QoS of a run; :data:`META_NAME`: the run's description in an MCAP metadata record) and the pure
parts of the recorder (:class:`McapRecording`, :class:`TfBuilder`; the CDR bytes through
:mod:`swarm_common.cdr`).
:mod:`swarm_record.recorder` is its ROS shell; ``swarm-plot`` (:mod:`swarm_record.plot`) reads it.

The recorder does not subscribe to the simulator's live ``/tf`` (which goes out only while it
has a reader, and is off with ``--no-tf`` or without the built ``tf2_msgs``): it builds the
recording's ``tf2_msgs/msg/TFMessage`` from each robot's ``ground_truth`` and ``odom`` of one
tick (``map`` -> ``<ns>/odom`` -> ``<ns>/base_footprint`` -> ``<ns>/base_scan``, the live tree's
frames) and writes its CDR bytes itself (:func:`swarm_common.cdr.tf_message`), so a recording
has ``/tf`` whatever the run published.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from swarm_common import cdr, topics
from swarm_common.geometry import quaternion_to_yaw
from swarm_common.stamps import NS_PER_S

PROFILE = "ros2"
MESSAGE_ENCODING = "cdr"
SCHEMA_ENCODING = "ros2msg"
CHUNK_SIZE = 256 * 1024  # [bytes] uncompressed; ~0.5 s simulated at 20 robots, a few s at 3
META_NAME = "swarm_workbench"
"""Name of the MCAP metadata record that describes the run (:func:`run_metadata`)."""
RECORDER_NODE = "swarm_recorder"
"""The recorder's node name; the simulator's start gate waits until its readers are matched."""
TF_TOPIC = "/tf"
TF_TYPE = "tf2_msgs/msg/TFMessage"
DEFINITION_RULE = "=" * 80

_TF_QOS = topics.Qos(100)  # tf2_ros's TransformBroadcaster (reliable, volatile, depth 100)


@dataclass(frozen=True)
class RecordedTopic:
    """One topic of a recording.

    Attributes:
        name: absolute topic name (``/Srobot1/odom``).
        type: ROS 2 type name (``nav_msgs/msg/Odometry``).
        qos: the offered QoS in rosbag2's names (``history``, ``depth``, ``reliability``,
            ``durability``), used for the channel metadata when the publisher cannot be asked
            and by the recorder to choose its subscription.
        robot: the robot's namespace without ``/``, or ``""`` for a swarm-wide topic.
    """

    name: str
    type: str
    qos: dict
    robot: str = ""


def recorded_topics(robots: tuple[str, ...] | list[str]) -> tuple[RecordedTopic, ...]:
    """Every topic a recording of these robots may hold, swarm-wide ones first, each with the QoS
    its writers offer (:mod:`swarm_common.topics`).

    Args:
        robots: namespaces without ``/``.

    Returns:
        ``/clock``, ``/map``, ``/swarm/events``, ``/tf``, then each robot's ``scan``, ``odom``,
        ``ground_truth``, ``cmd_vel``, ``plan``, ``nav_status``.
    """
    out = [RecordedTopic(t.name, t.type, t.qos.as_dict())
           for t in (topics.CLOCK, topics.MAP, topics.EVENTS)]
    out.append(RecordedTopic(TF_TOPIC, TF_TYPE, _TF_QOS.as_dict()))
    for ns in robots:
        out += [RecordedTopic(topics.robot_topic(ns, t), t.type, t.qos.as_dict(), ns)
                for t in topics.ROBOT_TOPICS]
    return tuple(out)


def select_topics(topics, pattern: str | None) -> tuple[RecordedTopic, ...]:
    """The topics whose name matches ``pattern`` (``re.search``, as ``ros2 bag record -e``).

    Args:
        topics: :class:`RecordedTopic` sequence.
        pattern: a Python regular expression, or None for all.

    Raises:
        re.error: ``pattern`` is not a regular expression.
    """
    if pattern is None:
        return tuple(topics)
    rx = re.compile(pattern)
    return tuple(t for t in topics if rx.search(t.name))


TF_SOURCES = (topics.ODOM.name, topics.GROUND_TRUTH.name)
"""The robot topics (suffixes) the recorder builds ``/tf`` from."""
SIMULATOR_TOPICS = (topics.CLOCK.name, topics.MAP.name, topics.EVENTS.name)
SIMULATOR_ROBOT_TOPICS = (topics.SCAN.name, topics.ODOM.name, topics.GROUND_TRUTH.name)
"""The recorded topics that ``swarm-sim`` publishes (swarm_sim/node.py): swarm-wide names, and
each robot's suffixes."""

EVERY_TICK_ROBOT_TOPICS = (topics.ODOM.name, topics.GROUND_TRUTH.name)
"""A robot's topics the simulator publishes once every tick (reliable): with ``/clock``, the
streams whose progress the record window follows (:class:`TickProgress`)."""


class TickProgress:
    """The latest tick up to which every tracked stream has delivered: the record window's
    progress (:data:`swarm_common.topics.RECORD_PROGRESS`), the oldest of the streams' latest
    stamps.

    Each stream delivers in order (a reliable writer), one message a tick; a copy of a stamp
    already seen (the start gate's) counts once.  A stream that skips ticks has lost them for
    good: they are counted in ``lost``, and the progress goes on.

    Args:
        streams: the tracked streams' names (``/clock``, ``/<ns>/odom`` ...).
        period_ns: the tick [ns].
    """

    def __init__(self, streams, period_ns: int):
        self.streams = tuple(streams)
        self.period_ns = int(period_ns)
        self.last = dict.fromkeys(self.streams, 0)  # stream -> its latest stamp [ns]
        self.progress_ns = 0
        self.lost = 0
        self._behind = set(self.streams)  # the streams whose latest stamp is the progress

    def on_message(self, stream: str, stamp_ns: int) -> int | None:
        """One message of ``stream`` with ``stamp_ns``; returns the new progress [ns] when it
        advanced, else None.  Amortised O(1): the minimum is recomputed once a tick."""
        last = self.last.get(stream)
        if last is None or stamp_ns <= last:
            return None
        if last:
            self.lost += max(0, (stamp_ns - last) // self.period_ns - 1)
        self.last[stream] = stamp_ns
        self._behind.discard(stream)
        if self._behind:
            return None
        progress = min(self.last.values())
        self._behind = {k for k, v in self.last.items() if v == progress}
        if progress <= self.progress_ns:
            return None
        self.progress_ns = progress
        return progress


def recorder_subscriptions(robots, selected) -> tuple[RecordedTopic, ...]:
    """The topics the recorder subscribes to: the ``selected`` ones but ``/tf``, which it builds
    from every robot's ``odom`` and ``ground_truth`` (subscribed to as well when ``/tf`` is
    selected), and ``/clock`` whether selected or not (the log time of headerless messages; the
    progress of :data:`swarm_common.topics.RECORD_PROGRESS`).

    Args:
        robots: namespaces without ``/``.
        selected: the :class:`RecordedTopic` to write (:func:`select_topics`).
    """
    every = recorded_topics(robots)
    wanted = {t.name: t for t in selected if t.name != TF_TOPIC}
    if any(t.name == TF_TOPIC for t in selected):
        for t in every:
            if t.name.rsplit("/", 1)[-1] in TF_SOURCES:
                wanted.setdefault(t.name, t)
    for t in every:  # always: the log time of headerless messages, the record window's progress
        if t.name == topics.CLOCK.name:
            wanted.setdefault(t.name, t)
    return tuple(wanted.values())


def from_simulator(topic: RecordedTopic) -> bool:
    """Whether ``swarm-sim`` publishes ``topic`` (:data:`SIMULATOR_TOPICS`,
    :data:`SIMULATOR_ROBOT_TOPICS`)."""
    return topic.name in SIMULATOR_TOPICS or bool(
        topic.robot and topic.name.rsplit("/", 1)[-1] in SIMULATOR_ROBOT_TOPICS)


def simulator_readers(robots, pattern: str | None) -> int:
    """How many of the recorder's subscriptions (``--record-topics pattern``) are to topics the
    simulator publishes: the simulator's start gate waits until that many are matched
    (``swarm-sim --reader-subscriptions``), so that a subscription discovered late does not lose
    the first ticks.

    Raises:
        re.error: ``pattern`` is not a regular expression.
    """
    subs = recorder_subscriptions(robots, select_topics(recorded_topics(robots), pattern))
    return sum(1 for t in subs if from_simulator(t))


# ------------------------------------------------------------------------------------ metadata
def qos_yaml(profiles: list[dict]) -> str:
    """``offered_qos_profiles`` as rosbag2 writes it (``qos.cpp``, bag version 9).

    Args:
        profiles: one dict per publisher: ``history`` (``keep_last`` | ``keep_all``), ``depth``,
            ``reliability`` (``reliable`` | ``best_effort``), ``durability``
            (``volatile`` | ``transient_local``); optional ``deadline_ns``, ``lifespan_ns``,
            ``liveliness`` (``automatic``), ``lease_ns`` (default: infinite) [ns].

    Returns:
        A YAML sequence of mappings (``[]`` for no publisher).
    """
    if not profiles:
        return "[]"
    lines = []
    for p in profiles:
        lines.append(f"- history: {p['history']}")
        lines.append(f"  depth: {int(p['depth'])}")
        lines.append(f"  reliability: {p['reliability']}")
        lines.append(f"  durability: {p['durability']}")
        for key, ns_key in (("deadline", "deadline_ns"), ("lifespan", "lifespan_ns")):
            sec, nsec = _duration(p.get(ns_key))
            lines += [f"  {key}:", f"    sec: {sec}", f"    nsec: {nsec}"]
        lines.append(f"  liveliness: {p.get('liveliness', 'automatic')}")
        sec, nsec = _duration(p.get("lease_ns"))
        lines += ["  liveliness_lease_duration:", f"    sec: {sec}", f"    nsec: {nsec}"]
        lines.append("  avoid_ros_namespace_conventions: false")
    return "\n".join(lines) + "\n"


INFINITE_NS = 9223372036854775807  # RMW_DURATION_INFINITE [ns]


def _duration(ns: int | None) -> tuple[int, int]:
    ns = INFINITE_NS if ns is None or ns <= 0 or ns >= INFINITE_NS else int(ns)
    return ns // NS_PER_S, ns % NS_PER_S


def run_metadata(*, world: str, robot: str, seed: int, robots, workstations,
                 rtf: float, models=None) -> dict[str, str]:
    """The MCAP metadata record :data:`META_NAME` (all values strings, as MCAP requires).

    Args:
        world: the world file's path.
        robot: the robot name or path, or a mix ``NAME:COUNT,...`` (:mod:`swarm_scene.fleet`).
        seed: the run's seed.
        robots: namespaces without ``/``.
        workstations: ``[{"name", "x", "y", "yaw", "holding": [[x, y], ...]}, ...]`` in ``map``
            [m, rad], so that ``swarm-plot`` needs no world file.
        rtf: the requested real-time factor.
        models: the model of every robot (names or paths), index-aligned with ``robots``; None:
            every robot is ``robot``.  Written as ``robot_models``, each model's short name
            (:func:`swarm_scene.fleet.model_label`), comma-separated in ``robots``' order.
    """
    from swarm_scene.fleet import model_label

    models = (robot,) * len(robots) if models is None else models
    return {"world": str(world), "robot": str(robot), "seed": str(seed),
            "robots": ",".join(robots), "workstations": json.dumps(workstations),
            "rtf": repr(float(rtf)), "log_time": "simulated",
            "robot_models": ",".join(model_label(str(m)) for m in models)}


# --------------------------------------------------------------------------- message definitions
_BUILTIN = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
            "int32", "uint32", "int64", "uint64", "string", "wstring"}

TF_MESSAGE_MSG = "geometry_msgs/TransformStamped[] transforms\n"
"""``tf2_msgs/msg/TFMessage.msg`` (ros2/geometry2), written here since no wheel carries it."""
_EXTRA_MSG = {"tf2_msgs/TFMessage": TF_MESSAGE_MSG}


def _msg_text(pkg_type: str, share_dirs) -> str:
    if pkg_type in _EXTRA_MSG:
        return _EXTRA_MSG[pkg_type]
    pkg, name = pkg_type.split("/")
    for share in share_dirs:
        path = Path(share) / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text()
    raise FileNotFoundError(f"no definition of {pkg_type} under {list(map(str, share_dirs))}")


def _field_types(text: str, pkg: str) -> list[str]:
    """The non-builtin types that the fields of a ``.msg`` text use, as ``pkg/Type``."""
    out = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        type_token, _, rest = line.partition(" ")
        name = re.match(r"\s*[A-Za-z_]\w*", rest)
        if name and rest[name.end():].lstrip().startswith("="):
            continue  # a constant (builtin types only)
        base = re.sub(r"\[.*\]$", "", type_token)
        base = re.sub(r"<=\d+$", "", base)
        if base in _BUILTIN:
            continue
        if base == "Header":
            base = "std_msgs/Header"
        elif "/" not in base:
            base = f"{pkg}/{base}"
        out.append(base.replace("/msg/", "/"))
    return out


def message_definition(type_name: str, share_dirs=None) -> str:
    """The ``ros2msg`` schema text of a type, as rosbag2's message definition cache builds it.

    The type's own ``.msg`` text, then every type it uses (depth first, each once), each after
    ``DEFINITION_RULE`` and a line ``MSG: pkg/Type``.

    Args:
        type_name: ``pkg/msg/Type``.
        share_dirs: directories holding ``<pkg>/msg/<Type>.msg`` (default: this Python's
            ``share/``, where the ROS 2 wheels install them).

    Raises:
        FileNotFoundError: a type's ``.msg`` file is nowhere to be found.
    """
    import sys

    if share_dirs is None:
        share_dirs = [Path(sys.prefix) / "share"]
    top = type_name.replace("/msg/", "/")
    text = _msg_text(top, share_dirs)
    seen: list[str] = []
    stack = list(reversed(_field_types(text, top.split("/")[0])))
    parts = [text.rstrip("\n")]
    while stack:
        dep = stack.pop()
        if dep in seen or dep == top:
            continue
        seen.append(dep)
        dep_text = _msg_text(dep, share_dirs)
        parts.append(f"{DEFINITION_RULE}\nMSG: {dep}\n{dep_text.rstrip(chr(10))}")
        stack.extend(reversed(_field_types(dep_text, dep.split("/")[0])))
    return "\n".join(parts) + "\n"


# ----------------------------------------------------------------------------------------- /tf
class Transform(NamedTuple):
    """One ``geometry_msgs/TransformStamped``: ``child`` in ``parent`` (the tuple that
    :func:`swarm_common.cdr.tf_message` serializes).

    Attributes:
        stamp_ns: [ns] simulated time.
        parent: header frame id; child: child frame id.
        translation: (x, y, z) [m]; rotation: (qx, qy, qz, qw).
    """

    stamp_ns: int
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


class TfBuilder:
    """Pairs each robot's ``ground_truth`` and ``odom`` of one tick into its ``/tf`` message.

    Per robot and tick: ``map`` -> ``<ns>/odom`` = ground truth composed with the inverse of the
    odometry pose (planar: x, y, yaw), ``<ns>/odom`` -> ``<ns>/base_footprint`` = the odometry
    pose, ``<ns>/base_footprint`` -> ``<ns>/<lidar frame>`` = the lidar's mounting pose.  Each
    tick is emitted once (the start gate re-publishes its tick; repeats are ignored).

    Args:
        robots: namespaces without ``/``.
        lidar_pose: (x, y, z [m], yaw [rad]) of the lidar in ``base_footprint``; or a mapping
            namespace -> that (a mixed fleet).
        lidar_frame: its link name (``base_scan``); or a mapping namespace -> that.
    """

    def __init__(self, robots, lidar_pose=(0.0, 0.0, 0.0, 0.0), lidar_frame="base_scan"):
        poses = lidar_pose if isinstance(lidar_pose, Mapping) else dict.fromkeys(
            robots, lidar_pose)
        frames = lidar_frame if isinstance(lidar_frame, Mapping) else dict.fromkeys(
            robots, lidar_frame)
        self._lidar = {ns: ((float(x), float(y), float(z)),
                            (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)))
                       for ns, (x, y, z, yaw) in poses.items()}
        self._frame = dict(frames)
        self._pending: dict[str, dict[int, list]] = {ns: {} for ns in robots}
        self._done: dict[str, int] = {ns: -1 for ns in robots}

    def on_odom(self, ns: str, data: bytes) -> bytes | None:
        """An ``odom`` message; returns the tick's ``TFMessage`` CDR once both halves are in."""
        return self._add(ns, 0, data)

    def on_ground_truth(self, ns: str, data: bytes) -> bytes | None:
        """A ``ground_truth`` message; as :meth:`on_odom`."""
        return self._add(ns, 1, data)

    def _add(self, ns: str, which: int, data: bytes) -> bytes | None:
        stamp, pose = cdr.odometry_pose(data)
        if stamp <= self._done[ns]:
            return None
        pending = self._pending[ns]
        pair = pending.setdefault(stamp, [None, None])
        pair[which] = pose
        if pair[0] is None or pair[1] is None:
            return None
        self._done[ns] = stamp
        for old in [s for s in pending if s <= stamp]:
            del pending[old]
        return cdr.tf_message(self.transforms(ns, stamp, pair[0], pair[1]))

    def transforms(self, ns: str, stamp: int, odom, truth) -> list[Transform]:
        """The three transforms of robot ``ns`` at ``stamp`` from its odom and true poses."""
        yo, yt = quaternion_to_yaw(*odom[3:]), quaternion_to_yaw(*truth[3:])
        th = yt - yo
        c, s = math.cos(th), math.sin(th)
        tx = truth[0] - (c * odom[0] - s * odom[1])
        ty = truth[1] - (s * odom[0] + c * odom[1])
        return [
            Transform(stamp, "map", f"{ns}/odom", (tx, ty, 0.0),
                      (0.0, 0.0, math.sin(th / 2.0), math.cos(th / 2.0))),
            Transform(stamp, f"{ns}/odom", f"{ns}/base_footprint", tuple(odom[:3]),
                      tuple(odom[3:])),
            Transform(stamp, f"{ns}/base_footprint", f"{ns}/{self._frame[ns]}",
                      *self._lidar[ns]),
        ]


# ---------------------------------------------------------------------------------- the writer
class _RawFile:
    """An unbuffered binary file for the MCAP writer: every record it hands over is in the
    kernel at once, so a SIGKILL loses at most the chunk being built."""

    def __init__(self, path: Path):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        self._pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        os.close(self._fd)


class McapRecording:
    """An MCAP file in the ``ros2`` profile, written in chunks (the ``mcap`` library's writer).

    Args:
        path: the file (created or truncated).
        chunk_size: [bytes] uncompressed size at which a chunk is written.
        compression: ``zstd``, ``lz4`` or ``none``.
    """

    def __init__(self, path: Path, chunk_size: int = CHUNK_SIZE, compression: str = "zstd"):
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self._file = _RawFile(self.path)
        self._writer = Writer(self._file, chunk_size=chunk_size,
                              compression=CompressionType[compression.upper()])
        self._writer.start(profile=PROFILE, library="swarm-workbench (mcap-python)")
        self._schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self._closed = False

    def add_channel(self, topic: str, type_name: str, qos_profiles_yaml: str,
                    definition: str | None = None) -> int:
        """Register ``topic`` (once); returns its channel id.

        Args:
            topic: absolute name.
            type_name: ``pkg/msg/Type``.
            qos_profiles_yaml: :func:`qos_yaml` of its publishers.
            definition: the ``ros2msg`` text (default: :func:`message_definition`).
        """
        if topic in self.channels:
            return self.channels[topic]
        schema = self._schemas.get(type_name)
        if schema is None:
            text = definition if definition is not None else message_definition(type_name)
            schema = self._writer.register_schema(type_name, SCHEMA_ENCODING, text.encode())
            self._schemas[type_name] = schema
        cid = self._writer.register_channel(
            topic, MESSAGE_ENCODING, schema, {"offered_qos_profiles": qos_profiles_yaml})
        self.channels[topic] = cid
        self.counts[topic] = 0
        return cid

    def write(self, topic: str, t_ns: int, data: bytes) -> None:
        """One message of a registered topic at log (and publish) time ``t_ns`` [ns]."""
        self._writer.add_message(self.channels[topic], t_ns, data, t_ns)
        self.counts[topic] += 1

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        """A metadata record, written at once (outside the chunks)."""
        self._writer.add_metadata(name, values)

    def close(self) -> None:
        """Write the last chunk, the summary and the footer (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()
