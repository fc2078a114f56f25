"""``rclpy`` QoS profiles of :class:`swarm_common.topics.Qos` (the one place that converts)."""

from __future__ import annotations

import importlib
from functools import cache

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from swarm_common.topics import (
    BEST_EFFORT,
    RELIABLE,
    TRANSIENT_LOCAL,
    VOLATILE,
    Qos,
    Topic,
    robot_topic,
)

_RELIABILITY = {RELIABLE: ReliabilityPolicy.RELIABLE, BEST_EFFORT: ReliabilityPolicy.BEST_EFFORT}
_DURABILITY = {VOLATILE: DurabilityPolicy.VOLATILE,
               TRANSIENT_LOCAL: DurabilityPolicy.TRANSIENT_LOCAL}


@cache
def profile(qos: Qos) -> QoSProfile:
    """The ``rclpy.qos.QoSProfile`` of ``qos``: keep last ``qos.depth``, its reliability and
    durability, every other policy at rclpy's default.

    Raises:
        KeyError: an unknown reliability or durability name.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=qos.depth,
                      reliability=_RELIABILITY[qos.reliability],
                      durability=_DURABILITY[qos.durability])


def _name(topic: Topic, ns: str | None) -> str:
    return topic.name if ns is None else robot_topic(ns, topic)


def publisher(node, msg_type, topic: Topic, ns: str | None = None, qos: Qos | None = None):
    """``node.create_publisher`` for ``topic``.

    Args:
        node: the ``rclpy`` node.
        msg_type: the message class (of ``topic.type``).
        topic: the topic (:mod:`swarm_common.topics`).
        ns: a robot's namespace: the topic is ``/<ns>/<name>``; None: its name as it is
            (absolute, or relative to the node's namespace).
        qos: the profile, if not ``topic.qos`` (a reader's, say).
    """
    return node.create_publisher(msg_type, _name(topic, ns), profile(qos or topic.qos))


def subscription(node, msg_type, topic: Topic, callback, ns: str | None = None,
                 qos: Qos | None = None, raw: bool = False):
    """``node.create_subscription`` for ``topic`` (arguments as :func:`publisher`'s; ``raw``:
    the callback gets the CDR bytes)."""
    return node.create_subscription(msg_type, _name(topic, ns), callback,
                                    profile(qos or topic.qos), raw=raw)


def message_class(type_name: str):
    """The message class of a ROS 2 type name (``nav_msgs/msg/Odometry`` -> its class).

    Raises:
        ModuleNotFoundError, AttributeError: no such message type is installed.
    """
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)
