"""A reader of a latched topic that is made again until its first message arrives.

Fast DDS can intermittently leave a late-joining reliable, transient-local reader without the
writer's history (eProsima/Fast-DDS#3822, open): the reader matches the writer but never gets the
sample the writer published before the match. On a topic written once (a coordinator's
``state``) or written only when something changes (a navigator waiting in the lockstep for this
very reader's node), nothing new comes to make up for it, and the reader waits for good. Making
the reader again is a new match, and the history is sent again; this is what
:class:`LatchedReader` does, every ``rematch_s`` wall seconds of spinning, until the first
message arrives (then it is a plain subscription).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.clock import Clock, ClockType

from swarm_common.topics import Qos, Topic
from swarm_ros.qos import subscription

__all__ = ["REMATCH_S", "LatchedReader"]

REMATCH_S = 10.0
"""[s] wall: how long a latched reader is spun without a message before it is made again; long
beside discovery on one host (well under a second), short beside the 120 s a commander waits for
its navigator or coordinator."""


class LatchedReader:
    """A subscription to ``topic`` on ``node``, made again every ``rematch_s`` wall seconds of
    spinning until its first message arrives (module docstring).

    The time counts from the reader's first check by its timer (the node's first spin), not from
    its making: a group process makes all its nodes before it spins any, and its readers would
    otherwise all be made again the moment it began to spin, before any could take what had
    arrived.  A remake is logged as a warning when the reader had matched a writer (the history
    was due), at debug level when no writer was there yet.

    Args:
        node: the ``rclpy`` node that owns the reader (and its steady-clock timer).
        msg_type: the message class.
        topic: the topic (:mod:`swarm_common.topics`).
        callback: ``callable(msg)``, called for every message, as a subscription's.
        rematch_s: [s] wall, > 0 (:data:`REMATCH_S`).
        ns, qos, raw: as :func:`swarm_ros.qos.subscription`.

    Raises:
        ValueError: ``rematch_s`` is not positive.
    """

    def __init__(self, node, msg_type, topic: Topic, callback: Callable, *,
                 rematch_s: float = REMATCH_S, ns: str | None = None, qos: Qos | None = None,
                 raw: bool = False):
        if not rematch_s > 0:
            raise ValueError(f"rematch_s must be > 0, got {rematch_s!r}")
        self._node = node
        self._make = lambda: subscription(node, msg_type, topic, self._on_message, ns=ns,
                                          qos=qos, raw=raw)
        self._callback = callback
        self._rematch_s = float(rematch_s)
        self.received = False
        """True once a message arrived."""
        self.rematches = 0
        """How many times the reader was made again."""
        self._watched_since: float | None = None  # [s] monotonic: the timer's first check
        self.subscription = self._make()
        """The ``rclpy`` subscription in use (a new one after each remake)."""
        self._timer = node.create_timer(self._rematch_s / 5, self._check,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _on_message(self, msg) -> None:
        self.received = True
        self._callback(msg)

    def _check(self) -> None:
        if self.received:
            self._stop_timer()
            return
        now = time.monotonic()
        if self._watched_since is None:
            self._watched_since = now
        if now - self._watched_since < self._rematch_s:
            return
        topic = self.subscription.topic_name
        writers = self.subscription.get_publisher_count()
        logger = self._node.get_logger()
        log = logger.warning if writers else logger.debug
        log(f"nothing on {topic} within {self._rematch_s:g} s (wall) of spinning its reader "
            f"({writers} writer(s) matched); making the reader again (eProsima/Fast-DDS#3822)")
        self._node.destroy_subscription(self.subscription)
        self.subscription = self._make()
        self._watched_since = now
        self.rematches += 1

    def _stop_timer(self) -> None:
        if self._timer is not None:
            self._node.destroy_timer(self._timer)
            self._timer = None

    def destroy(self) -> None:
        """Destroy the reader and its timer (the node lives on)."""
        self._stop_timer()
        self._node.destroy_subscription(self.subscription)
