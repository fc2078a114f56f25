"""The topics' QoS (swarm_common.topics) as rclpy profiles: the very profiles the nodes used
before they were written once, and every reader compatible with the writers it reads."""

from __future__ import annotations

import pytest
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

from swarm_common import topics
from swarm_common.topics import Qos
from swarm_record import mcap_format
from swarm_ros.qos import message_class, profile

RELIABLE, TL = ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL


@pytest.mark.parametrize(("qos", "rclpy_profile"), [
    (topics.DEFAULT, QoSProfile(depth=10)),
    (topics.DEFAULT, QoSProfile(depth=10, reliability=RELIABLE)),
    (topics.SENSOR_DATA, qos_profile_sensor_data),
    (topics.LATCHED, QoSProfile(depth=1, reliability=RELIABLE, durability=TL)),
    (topics.CMD_VEL.qos, QoSProfile(depth=300, reliability=RELIABLE, durability=TL)),
    (topics.CLOCK_METRICS_READER_QOS, QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                                                 reliability=ReliabilityPolicy.BEST_EFFORT)),
], ids=["default", "default-reliable", "sensor-data", "latched", "cmd-vel",
        "clock-metrics-reader"])
def test_profile_is_rclpys(qos, rclpy_profile):
    assert profile(qos) == rclpy_profile


READERS = [  # (topic, a reader's QoS)
    (topics.CLOCK, topics.CLOCK_METRICS_READER_QOS),
    (topics.EVENTS, topics.EVENTS.qos),
    (topics.POSES, topics.POSES_READER_QOS),
    (topics.COORDINATOR_REQUEST, topics.COORDINATOR_REQUEST_READER_QOS),
    (topics.COORDINATOR_REQUEST, topics.COMM_METRICS_READER_QOS),
    (topics.ASSIGNMENT, topics.ASSIGNMENT_READER_QOS),
    (topics.ASSIGNMENT, topics.COMM_METRICS_READER_QOS),
    (topics.CMD_VEL, topics.CMD_VEL_READER_QOS),
    (topics.NAV_STATUS, topics.NAV_STATUS_COMMANDER_READER_QOS),
    (topics.NAV_STATUS, topics.NAV_STATUS_METRICS_READER_QOS),
]


def _serves(writer: Qos, reader: Qos) -> bool:
    """DDS request/offered: a reliable reader needs a reliable writer, a transient-local reader
    a transient-local writer."""
    return ((reader.reliability == topics.BEST_EFFORT or writer.reliability == topics.RELIABLE)
            and (reader.durability == topics.VOLATILE
                 or writer.durability == topics.TRANSIENT_LOCAL))


@pytest.mark.parametrize(("topic", "reader"), READERS, ids=lambda v: getattr(v, "name", ""))
def test_every_reader_is_served_by_the_writer(topic, reader):
    assert _serves(topic.qos, reader)


def test_the_coordinators_events_writer_serves_the_events_readers():
    assert _serves(topics.EVENTS_COORDINATOR_WRITER_QOS, topics.EVENTS.qos)


def test_a_recording_offers_what_the_writers_offer():
    recorded = {t.name: t for t in mcap_format.recorded_topics(("Srobot1",))}
    for topic in topics.ROBOT_TOPICS:
        rec = recorded[topics.robot_topic("Srobot1", topic)]
        assert (rec.type, rec.qos) == (topic.type, topic.qos.as_dict())
    assert recorded["/swarm/events"].qos["depth"] == 1000


def test_every_topic_type_is_a_message_class():
    for topic in vars(topics).values():
        if isinstance(topic, topics.Topic):
            cls = message_class(topic.type)
            assert f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}" == topic.type
