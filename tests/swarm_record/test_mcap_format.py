"""The recording's file format (pure): topics, schemas, QoS metadata, CDR helpers, /tf, chunks.

Everything written here is read back with code that is not the writer's: ``rosbags`` (its
message-definition parser, its Jazzy type store with ``tf2_msgs``, its CDR codec), the ``mcap``
library's readers, ``yaml``, and ``rclpy``'s own serializer.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from swarm_common import cdr, topics
from swarm_record import mcap_format as rec

JAZZY = get_typestore(Stores.ROS2_JAZZY)
TYPES = sorted({t.type for t in rec.recorded_topics(("Srobot1",))})


def test_recorded_topics_of_a_swarm():
    topics = rec.recorded_topics(("Srobot1", "Srobot2"))
    names = [t.name for t in topics]
    assert names[:4] == ["/clock", "/map", "/swarm/events", "/tf"]
    assert len(names) == 4 + 2 * 6 and len(set(names)) == len(names)
    for ns in ("Srobot1", "Srobot2"):
        for suffix in ("scan", "odom", "ground_truth", "cmd_vel", "plan", "nav_status"):
            assert f"/{ns}/{suffix}" in names
    assert {t.type for t in topics if t.name.endswith("/tf")} == {"tf2_msgs/msg/TFMessage"}
    scan = next(t for t in topics if t.name == "/Srobot1/scan")
    assert scan.qos["reliability"] == "best_effort" and scan.robot == "Srobot1"


@pytest.mark.parametrize(("pattern", "expected"), [
    (None, 16),
    ("odom", 2),  # re.search: /Srobot1/odom, /Srobot2/odom
    ("^/Srobot1/", 6),
    ("/tf$|events", 2),
    ("^/nothing$", 0),
])
def test_select_topics(pattern, expected):
    assert len(rec.select_topics(rec.recorded_topics(("Srobot1", "Srobot2")), pattern)) == expected


def test_select_topics_rejects_a_bad_regex():
    with pytest.raises(re.error):
        rec.select_topics(rec.recorded_topics(("a",)), "(odom")


@pytest.mark.parametrize("type_name", TYPES)
def test_message_definition_parses_with_rosbags_and_matches_jazzy(type_name):
    """The ros2msg text (type + dependencies after 80 '=' and 'MSG: pkg/Type') gives the same
    fields as rosbags' own Jazzy definitions."""
    text = rec.message_definition(type_name)
    blocks = text.split(rec.DEFINITION_RULE + "\n")
    parsed = dict(get_types_from_msg(blocks[0], type_name))
    for block in blocks[1:]:
        head, _, body = block.partition("\n")
        assert head.startswith("MSG: ") and head.count("/") == 1
        pkg, name = head[5:].split("/")
        parsed.update(get_types_from_msg(body, f"{pkg}/msg/{name}"))
    for name, (consts, fields) in parsed.items():
        ref_consts, ref_fields = JAZZY.fielddefs[name]
        assert [f[0] for f in fields] == [f[0] for f in ref_fields], name
        assert sorted(c[0] for c in consts) == sorted(c[0] for c in ref_consts), name


def test_message_definition_lists_each_dependency_once():
    text = rec.message_definition("nav_msgs/msg/Odometry")
    heads = [ln for ln in text.splitlines() if ln.startswith("MSG: ")]
    assert len(heads) == len(set(heads)) == 9
    assert "MSG: std_msgs/Header" in heads and "MSG: geometry_msgs/Vector3" in heads


def test_qos_yaml_is_rosbag2s_version_9_format():
    profiles = [dict(history="keep_last", depth=10, reliability="reliable",
                     durability="transient_local"),
                dict(history="keep_all", depth=0, reliability="best_effort",
                     durability="volatile", deadline_ns=1_500_000_000)]
    doc = yaml.safe_load(rec.qos_yaml(profiles))
    assert doc[0] == {
        "history": "keep_last", "depth": 10, "reliability": "reliable",
        "durability": "transient_local",
        "deadline": {"sec": 9223372036, "nsec": 854775807},
        "lifespan": {"sec": 9223372036, "nsec": 854775807},
        "liveliness": "automatic",
        "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
        "avoid_ros_namespace_conventions": False,
    }
    assert doc[1]["deadline"] == {"sec": 1, "nsec": 500_000_000}
    assert doc[1]["history"] == "keep_all" and doc[1]["reliability"] == "best_effort"
    assert rec.qos_yaml([]) == "[]"


def _odometry(stamp_ns, frame, child, pose):
    msg = JAZZY.types["nav_msgs/msg/Odometry"]
    h = JAZZY.types["std_msgs/msg/Header"]
    t = JAZZY.types["builtin_interfaces/msg/Time"]
    g = {n: JAZZY.types[f"geometry_msgs/msg/{n}"] for n in (
        "PoseWithCovariance", "Pose", "Point", "Quaternion", "TwistWithCovariance", "Twist",
        "Vector3")}
    x, y, yaw = pose
    value = msg(
        header=h(stamp=t(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=frame),
        child_frame_id=child,
        pose=g["PoseWithCovariance"](
            pose=g["Pose"](position=g["Point"](x=x, y=y, z=0.0),
                           orientation=g["Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                       w=math.cos(yaw / 2))),
            covariance=np.zeros(36)),
        twist=g["TwistWithCovariance"](
            twist=g["Twist"](linear=g["Vector3"](x=0.2, y=0.0, z=0.0),
                             angular=g["Vector3"](x=0.0, y=0.0, z=0.1)),
            covariance=np.zeros(36)))
    return bytes(JAZZY.serialize_cdr(value, "nav_msgs/msg/Odometry"))


@pytest.mark.parametrize(("frame", "child"), [
    ("map", "Srobot1/base_footprint"), ("Srobot12/odom", "Srobot12/base_footprint"),
    ("o", "b"), ("", "")])
def test_odometry_pose_reads_rosbags_cdr(frame, child):
    data = _odometry(12_300_000_000, frame, child, (1.25, -3.5, 2.0))
    stamp, pose = cdr.odometry_pose(data)
    assert stamp == 12_300_000_000
    assert pose[:3] == (1.25, -3.5, 0.0)
    assert pose[5] == pytest.approx(math.sin(1.0)) and pose[6] == pytest.approx(math.cos(1.0))
    assert cdr.header_stamp(data) == 12_300_000_000


def test_odometry_pose_reads_rclpy_cdr():
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message

    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 100
    msg.header.frame_id, msg.child_frame_id = "Srobot3/odom", "Srobot3/base_footprint"
    msg.pose.pose.position.x, msg.pose.pose.position.y = -0.5, 4.0
    msg.pose.pose.orientation.w = 1.0
    stamp, pose = cdr.odometry_pose(serialize_message(msg))
    assert stamp == 7_000_000_100 and pose == (-0.5, 4.0, 0.0, 0.0, 0.0, 0.0, 1.0)


def test_tf_message_cdr_decodes_with_rosbags_tf2_msgs():
    tfs = [rec.Transform(5_000_000_001, "map", "Srobot1/odom", (1.0, 2.0, 0.0),
                         (0.0, 0.0, 0.0, 1.0)),
           rec.Transform(5_000_000_001, "Srobot1/odom", "Srobot1/base_footprint",
                         (0.5, -0.25, 0.0), (0.0, 0.0, 0.6, 0.8)),
           rec.Transform(5_000_000_001, "Srobot1/base_footprint", "Srobot1/base_scan",
                         (-0.064, 0.0, 0.122), (0.0, 0.0, 0.0, 1.0))]
    msg = JAZZY.deserialize_cdr(cdr.tf_message(tfs), "tf2_msgs/msg/TFMessage")
    assert len(msg.transforms) == 3
    for got, want in zip(msg.transforms, tfs, strict=True):
        assert got.header.stamp.sec == 5 and got.header.stamp.nanosec == 1
        assert (got.header.frame_id, got.child_frame_id) == (want.parent, want.child)
        t, r = got.transform.translation, got.transform.rotation
        assert (t.x, t.y, t.z) == want.translation
        assert (r.x, r.y, r.z, r.w) == want.rotation
    empty = JAZZY.deserialize_cdr(cdr.tf_message([]), "tf2_msgs/msg/TFMessage")
    assert len(empty.transforms) == 0


def test_tf_builder_pairs_a_tick_once_and_composes_map_to_odom():
    builder = rec.TfBuilder(("Srobot1",), lidar_pose=(-0.064, 0.0, 0.12, 0.0))
    odom = _odometry(100_000_000, "Srobot1/odom", "Srobot1/base_footprint", (1.0, 0.0, 0.0))
    truth = _odometry(100_000_000, "map", "Srobot1/base_footprint", (2.0, 1.0, math.pi / 2))
    assert builder.on_odom("Srobot1", odom) is None  # waits for the tick's ground truth
    out = builder.on_ground_truth("Srobot1", truth)
    assert out is not None
    assert builder.on_odom("Srobot1", odom) is None  # the start gate's repeat: ignored
    msg = JAZZY.deserialize_cdr(out, "tf2_msgs/msg/TFMessage")
    frames = [(t.header.frame_id, t.child_frame_id) for t in msg.transforms]
    assert frames == [("map", "Srobot1/odom"), ("Srobot1/odom", "Srobot1/base_footprint"),
                      ("Srobot1/base_footprint", "Srobot1/base_scan")]
    # map->odom composed with odom->base_footprint gives the true pose (2, 1, pi/2).
    m2o, o2b = msg.transforms[0].transform, msg.transforms[1].transform
    th = 2 * math.atan2(m2o.rotation.z, m2o.rotation.w)
    x = m2o.translation.x + math.cos(th) * o2b.translation.x - math.sin(th) * o2b.translation.y
    y = m2o.translation.y + math.sin(th) * o2b.translation.x + math.cos(th) * o2b.translation.y
    assert (x, y, th) == pytest.approx((2.0, 1.0, math.pi / 2))
    assert msg.transforms[2].transform.translation.z == pytest.approx(0.12)


def test_tf_of_a_mixed_fleet_gives_every_robot_its_own_lidar_frame_and_mounting():
    builder = rec.TfBuilder(("Srobot1", "Srobot2"),
                            lidar_pose={"Srobot1": (-0.064, 0.0, 0.132, 0.0),
                                        "Srobot2": (0.0, 0.0, 0.168, 0.0)},
                            lidar_frame={"Srobot1": "base_scan", "Srobot2": "laser"})
    got = {}
    for ns in ("Srobot1", "Srobot2"):
        builder.on_odom(ns, _odometry(100_000_000, f"{ns}/odom", f"{ns}/base_footprint",
                                      (1.0, 0.0, 0.0)))
        out = builder.on_ground_truth(ns, _odometry(100_000_000, "map", f"{ns}/base_footprint",
                                                    (1.0, 0.0, 0.0)))
        lidar = JAZZY.deserialize_cdr(out, "tf2_msgs/msg/TFMessage").transforms[2]
        got[ns] = (lidar.child_frame_id, round(lidar.transform.translation.x, 3),
                   round(lidar.transform.translation.z, 3))
    assert got == {"Srobot1": ("Srobot1/base_scan", -0.064, 0.132),
                   "Srobot2": ("Srobot2/laser", 0.0, 0.168)}


def test_run_metadata_names_every_robots_model():
    meta = rec.run_metadata(world="w.world", robot="turtlebot3_waffle:1,/r/bot.urdf:1", seed=0,
                            robots=("Srobot1", "Srobot2"), workstations=[], rtf=0.0,
                            models=("turtlebot3_waffle", "/r/bot.urdf"))
    assert meta["robot_models"] == "turtlebot3_waffle,bot"
    assert rec.run_metadata(world="w", robot="turtlebot3_burger", seed=0, robots=("a", "b"),
                            workstations=[], rtf=1.0)["robot_models"] == ("turtlebot3_burger,"
                                                                          "turtlebot3_burger")


def _write(path, n, chunk_size):
    out = rec.McapRecording(path, chunk_size=chunk_size)
    out.add_metadata(rec.META_NAME, {"robots": "Srobot1"})
    out.add_channel("/Srobot1/odom", "nav_msgs/msg/Odometry",
                    rec.qos_yaml([topics.ODOM.qos.as_dict()]))
    for i in range(n):
        out.write("/Srobot1/odom", (i + 1) * 100_000_000,
                  _odometry((i + 1) * 100_000_000, "Srobot1/odom", "Srobot1/base_footprint",
                            (0.01 * i, 0.0, 0.0)))
    return out


def test_recording_reads_back_with_the_mcap_reader(tmp_path):
    path = tmp_path / "r.mcap"
    _write(path, 500, 16 * 1024).close()
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        header = reader.get_header()
        summary = reader.get_summary()
        msgs = list(reader.iter_messages())
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert header.profile == "ros2"
    assert len(msgs) == 500 and summary.statistics.message_count == 500
    assert len(summary.chunk_indexes) > 10  # chunked
    (schema,) = summary.schemas.values()
    assert (schema.name, schema.encoding) == ("nav_msgs/msg/Odometry", "ros2msg")
    (channel,) = summary.channels.values()
    assert channel.message_encoding == "cdr"
    assert yaml.safe_load(channel.metadata["offered_qos_profiles"])[0]["reliability"] == (
        "reliable")
    assert meta[rec.META_NAME] == {"robots": "Srobot1"}
    assert [m.log_time for _, _, m in msgs] == [(i + 1) * 100_000_000 for i in range(500)]


def test_a_killed_writer_leaves_every_finished_chunk(tmp_path):
    """No close(): as after SIGKILL.  A stream reader gets every message of the chunks written,
    then an error at the cut-off end (no summary, no footer)."""
    path = tmp_path / "killed.mcap"
    _write(path, 510, 16 * 1024)  # never closed; 16 KiB hold 22 odometry messages
    got, error = [], None
    with open(path, "rb") as fh:
        try:
            for record in StreamReader(fh).records:
                if type(record).__name__ == "Message":
                    got.append(record.log_time)
        except (McapError, EOFError) as exc:
            error = exc
    assert 480 <= len(got) < 510  # all but the chunk being built (< 16 KiB, < 23 messages)
    assert got == [(i + 1) * 100_000_000 for i in range(len(got))]  # in order, none missing
    assert error is None or isinstance(error, McapError | EOFError)


@pytest.mark.parametrize(("pattern", "subscriptions", "simulator"), [
    (None, 15, 9),  # all but /tf; the simulator's: /clock, /map, /swarm/events, scan/odom/gt x 2
    # /tf is built from both robots' odom and ground truth; /clock always (log times, progress)
    ("^/Srobot1/odom$|^/tf$", 5, 5),
    ("nav_status|cmd_vel", 5, 1),  # the navigators' topics, and /clock
    ("ground_truth|events", 4, 4),
])
def test_recorder_subscriptions_and_the_simulators_share(pattern, subscriptions, simulator):
    robots = ("Srobot1", "Srobot2")
    subs = rec.recorder_subscriptions(robots, rec.select_topics(rec.recorded_topics(robots),
                                                                 pattern))
    assert len(subs) == subscriptions and rec.TF_TOPIC not in {t.name for t in subs}
    assert rec.simulator_readers(robots, pattern) == simulator


@pytest.mark.parametrize(("topics", "gate"), [
    (["--record-topics", "^/Srobot1/odom$|^/tf$"], ["--wait-for-reader", "swarm_recorder",
                                                    "--reader-subscriptions", "5",
                                                    "--record-window", "2"]),
    # nothing of the simulator's is written, but the recorder reads /clock: the same gate
    (["--record-topics", "nav_status"], ["--wait-for-reader", "swarm_recorder",
                                         "--reader-subscriptions", "1", "--record-window", "2"]),
])
def test_swarm_up_tells_the_simulator_how_many_readers_to_wait_for(tmp_path, topics, gate):
    from swarm_up.args import build_parser, validate
    from swarm_up.children import child_specs

    cfg = validate(build_parser().parse_args(
        ["--swarm-size", "2", "--record", str(tmp_path / "r.mcap"), *topics,
         "--run-dir", str(tmp_path / "run")]))
    sim = next(s for s in child_specs(cfg) if s.name == "sim").argv
    at = sim.index("--wait-for-reader") if "--wait-for-reader" in sim else len(sim)
    assert list(sim[at:at + 6]) == gate


def test_tick_progress_is_the_oldest_streams_latest_tick_and_counts_skipped_ticks():
    p = rec.TickProgress(["/clock", "/a/odom", "/b/odom"], 100)
    feed = [("/clock", 100), ("/a/odom", 100), ("/b/odom", 100),  # tick 1 complete
            ("/clock", 100),  # the start gate's copy: counted once
            ("/clock", 200), ("/a/odom", 200), ("/b/odom", 200),
            ("/clock", 300), ("/a/odom", 500),  # /a/odom skipped 300 and 400: lost
            ("/b/odom", 300), ("/clock", 400), ("/b/odom", 400), ("/clock", 500),
            ("/b/odom", 500), ("/c/odom", 600)]  # not tracked
    got = [p.on_message(stream, t) for stream, t in feed]
    assert got == [None, None, 100, None, None, None, 200, None, None, 300, None, 400, None,
                   500, None]
    assert (p.progress_ns, p.lost) == (500, 2)
