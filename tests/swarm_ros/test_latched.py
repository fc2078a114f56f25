"""LatchedReader, the workaround for eProsima/Fast-DDS#3822 (node tests, wall clock, in-process),
and the commanders' wait for the coordinator that uses it."""

from __future__ import annotations

import itertools
import time

import pytest
import rclpy
from std_msgs.msg import String

from swarm_commander.coordinated import wait_for_coordinator
from swarm_common import topics
from swarm_common.topics import LATCHED, Topic
from swarm_ros.latched import LatchedReader
from swarm_ros.qos import publisher
from tests.support.ros import ros_context, spin_until

pytestmark = pytest.mark.node

_COUNTER = itertools.count(1)


@pytest.fixture
def node():
    """A node on an executor of its own context: ``node.spin_for(s)`` spins it ``s`` wall
    seconds, ``node.spin_until(condition, timeout, what)`` as ``tests.support.ros``'s."""
    with ros_context() as (ctx, executor):
        n = rclpy.create_node(f"latched_test_{next(_COUNTER)}", context=ctx)
        executor.add_node(n)
        n.spin_for = lambda s: _spin(executor, s)
        n.spin_until = lambda *args: spin_until(executor, *args)
        yield n


def _spin(executor, seconds: float) -> None:
    """Spin for ``seconds`` wall."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.02)


def _topic() -> Topic:
    """A latched topic no earlier test used (their samples may linger in discovery)."""
    return Topic(f"/latched_test/state{next(_COUNTER)}", "std_msgs/msg/String", LATCHED)


def test_a_silent_topic_gets_a_new_reader_until_a_message_arrives(node):
    topic, got = _topic(), []
    reader = LatchedReader(node, String, topic, got.append, rematch_s=0.2)
    node.spin_for(1.0)
    assert not reader.received and reader.rematches >= 2  # nothing heard: made again
    writer = rclpy.create_node(f"latched_writer_{next(_COUNTER)}", context=node.context)
    try:
        publisher(writer, String, topic).publish(String(data="up"))  # before any match
        node.spin_until(lambda: bool(got), 20.0, "the latched message")
        assert [m.data for m in got] == ["up"]  # the remade reader takes the history
        assert reader.received
        node.spin_for(0.6)  # the timer would fire at least twice more
        made = reader.rematches
        node.spin_for(0.6)
        assert reader.rematches == made
        assert node.count_subscribers(topic.name) == 1  # the old readers are gone
    finally:
        writer.destroy_node()
    reader.destroy()
    assert node.count_subscribers(topic.name) == 0


def test_the_wait_counts_from_the_first_spin_not_from_the_making(node):
    """A group process makes all its nodes before it spins: a reader made 3.5 s before the
    first spin is not made again at once (rematch_s 3 s)."""
    reader = LatchedReader(node, String, _topic(), lambda msg: None, rematch_s=3.0)
    time.sleep(3.5)
    node.spin_for(0.5)
    assert reader.rematches == 0
    reader.destroy()


def test_a_period_that_is_not_positive_is_refused(node):
    with pytest.raises(ValueError, match="rematch_s"):
        LatchedReader(node, String, _topic(), lambda msg: None, rematch_s=0.0)


def test_the_wait_for_the_coordinator_takes_its_latched_state_and_leaves_no_reader(node):
    writer = rclpy.create_node(f"coordinator_{next(_COUNTER)}", context=node.context)
    try:
        publisher(writer, String, topics.COORDINATOR_STATE).publish(String(data="up"))
        assert wait_for_coordinator(node, 20.0, node.spin_for, rematch_s=0.2)
    finally:
        writer.destroy_node()
    assert node.count_subscribers(topics.COORDINATOR_STATE.name) == 0

