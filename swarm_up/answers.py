"""A group process's answers to a control tick, one message for all its navigators.

The simulator waits for every navigator's answer to a tick (docs/ARCHITECTURE.md, "Synchronous
control loop").  Taking one ``cmd_vel`` per robot a tick was nearly half of the simulator's CPU
at 100 robots (py-spy: its executor's ``spin_once``), on the critical path of every tick; a group
process's navigators hand their answers to an :class:`AnswerBatch` instead, which publishes them
as one :data:`swarm_common.topics.CMD_VEL_BATCH` message once the process has nothing more to
take in (:func:`spin_batched`).  The answers and the ticks are the same; only their envelope
changes.

Used by :mod:`swarm_up.group` and, to carry the same traffic, by the messaging baseline's group
processes (:mod:`swarm_bench.baseline_nodes`).
"""

from __future__ import annotations

from trajectory_msgs.msg import MultiDOFJointTrajectory

from swarm_common import topics
from swarm_common.cdr import CmdVelBatchWriter
from swarm_ros.qos import publisher


class AnswerBatch:
    """The answers of one group process's navigators to the current tick, until flushed.

    Args:
        node: the node that publishes the batches (the group's clock node).

    Attributes:
        activity: bumped by every answer and every input a navigator takes in
            (:meth:`busy`): :func:`spin_batched` flushes once a round of the executor left it
            unchanged.
        batches: batches published so far; answers: answers carried in them.
    """

    def __init__(self, node):
        self._pub = publisher(node, MultiDOFJointTrajectory, topics.CMD_VEL_BATCH)
        self._writer = CmdVelBatchWriter()
        self._stamp = 0
        self._names: list[str] = []
        self._vw: list[tuple[float, float]] = []
        self.activity = 0
        self.batches = 0
        self.answers = 0

    @property
    def pending(self) -> bool:
        """Answers wait to be published."""
        return bool(self._names)

    def busy(self) -> None:
        """A navigator took in a message (its answer may follow in this round)."""
        self.activity += 1

    def put(self, ns: str, stamp_ns: int, v: float, w: float) -> None:
        """Robot ``ns``'s answer to tick ``stamp_ns`` [ns]: ``v`` [m/s], ``w`` [rad/s].  An
        answer to another tick than the pending ones' flushes those first (one stamp a
        batch)."""
        if self._names and stamp_ns != self._stamp:
            self.flush()
        self._stamp = stamp_ns
        self._names.append(ns)
        self._vw.append((v, w))
        self.activity += 1

    def flush(self) -> None:
        """Publish the pending answers (nothing when there are none)."""
        if not self._names:
            return
        self._pub.publish(self._writer.write(self._stamp, self._names, self._vw))
        self.batches += 1
        self.answers += len(self._names)
        self._names, self._vw = [], []


def spin_batched(executor, context, batch: AnswerBatch, service=None,
                 timeout_s: float = 0.5) -> None:
    """Spin until ``context`` shuts down, publishing ``batch`` once a round of the executor
    took in nothing for the navigators (the process has caught up with the tick's messages).

    Args:
        executor: the group's executor (``spin_once`` loop, as
            :func:`swarm_ros.session.spin_forever`).
        context: the rclpy context.
        batch: the group's answers.
        service: called after every round (fault injection's duties), or None.
        timeout_s: [s] wall, the longest round while nothing is pending.
    """
    while context.ok():
        seen = batch.activity
        executor.spin_once(timeout_sec=0.0 if batch.pending else timeout_s)
        if batch.pending and batch.activity == seen:
            batch.flush()
        if service is not None:
            service()
