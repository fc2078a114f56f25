"""A group process's answers in one message a tick (swarm_up.answers), with a fake node and
executor: what is published, and when the loop flushes."""

from __future__ import annotations

from swarm_common import topics
from swarm_common.cdr import cmd_vel_batch
from swarm_up.answers import AnswerBatch, spin_batched


class FakePublisher:
    def __init__(self):
        self.sent = []

    def publish(self, buf):
        self.sent.append(cmd_vel_batch(buf))


class FakeNode:
    def __init__(self):
        self.publishers = {}

    def create_publisher(self, msg_type, name, profile):
        self.publishers[name] = (msg_type, profile, FakePublisher())
        return self.publishers[name][2]


def _batch():
    node = FakeNode()
    batch = AnswerBatch(node)
    _, profile, pub = node.publishers[topics.CMD_VEL_BATCH.name]
    return batch, profile, pub


def test_answers_of_one_tick_go_in_one_message_and_another_tick_flushes_them():
    batch, profile, pub = _batch()
    assert profile.depth == topics.CMD_VEL_BATCH.qos.depth
    assert not batch.pending
    batch.flush()  # nothing pending: nothing sent
    assert pub.sent == []
    batch.put("Srobot1", 300_000_000, 0.2, -0.5)
    batch.put("Srobot3", 300_000_000, 0.0, 1.0)
    assert batch.pending and pub.sent == []
    batch.put("Srobot5", 400_000_000, 0.1, 0.0)  # another tick: the first two go first
    assert len(pub.sent) == 1
    stamp, names, vw = pub.sent[0]
    assert (stamp, names, vw.tolist()) == (300_000_000, ["Srobot1", "Srobot3"],
                                           [[0.2, -0.5], [0.0, 1.0]])
    batch.flush()
    assert [s[:2] for s in pub.sent] == [(300_000_000, ["Srobot1", "Srobot3"]),
                                        (400_000_000, ["Srobot5"])]
    assert (batch.batches, batch.answers, batch.pending) == (2, 3, False)


class ScriptedExecutor:
    """Each ``spin_once`` runs the next step of a script (a callable, or None: nothing was
    ready), and records the timeout it was given; the context ends with the script."""

    def __init__(self, steps):
        self.steps = list(steps)
        self.timeouts = []

    def spin_once(self, timeout_sec):
        self.timeouts.append(timeout_sec)
        step = self.steps.pop(0)
        if step is not None:
            step()

    def ok(self):
        return bool(self.steps)


def test_the_loop_flushes_once_a_round_takes_in_nothing():
    batch, _, pub = _batch()
    t = 500_000_000
    ex = ScriptedExecutor([
        lambda: batch.put("a", t, 0.1, 0.0),  # an odom taken, answered
        lambda: batch.busy(),  # an odom taken, its scan not yet: no answer, still busy
        lambda: batch.put("b", t, 0.2, 0.0),
        None,  # nothing ready: the two answers go
        None,  # nothing pending: a long round
        lambda: batch.put("c", t + 100_000_000, 0.3, 0.0),
        lambda: None,  # a callback that is no navigator's input (a timer): flushes too
        None,
    ])
    services = []
    spin_batched(ex, ex, batch, service=lambda: services.append(len(pub.sent)), timeout_s=0.5)
    assert [s[1] for s in pub.sent] == [["a", "b"], ["c"]]
    assert ex.timeouts == [0.5, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.5]
    assert services == [0, 0, 0, 1, 1, 1, 2, 2]
