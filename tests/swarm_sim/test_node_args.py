"""``swarm-sim``'s flags: the shared parser and the one ROS-name rule of ``swarm-up``."""

import subprocess
import sys

import pytest

from swarm_common.errors import InputError
from swarm_sim.settings import parse_settings


def test_defaults_are_typed():
    s = parse_settings([])
    assert (s.swarm_size, s.name_prefix, s.seed, s.rtf, s.duration) == (5, "Srobot", 0, 1.0, None)
    assert (s.control_rate, s.stall_report, s.wait_for) == (10.0, 10.0, 0)
    assert type(s.swarm_size) is int and type(s.rtf) is float


# swarm-up has always refused these; the simulator used to take "_x" and non-ASCII letters.
@pytest.mark.parametrize("prefix", ["_x", "Sröbot", "робот", "3robot", "my-robot", "a__b"])
def test_simulator_rejects_what_swarm_up_rejects(prefix):
    from swarm_up.args import build_parser

    with pytest.raises(InputError, match="^--name-prefix: must be a ROS name"):
        build_parser().parse_args(["--name-prefix", prefix])
    with pytest.raises(InputError, match="^--name-prefix: must be a ROS name"):
        parse_settings(["--name-prefix", prefix])


@pytest.mark.parametrize(("args", "message"), [
    (["--swarm-size", "0"], "--swarm-size: must be a positive integer, got '0'"),
    (["--rtf", "nan"], "--rtf: must be a number >= 0, got 'nan'"),
    (["--duration", "0"], "--duration: must be a positive number, got '0'"),
    (["--wait-for", "-1"], "--wait-for: must be an integer >= 0, got '-1'"),
    (["--control-rate", "fast"], "--control-rate: must be a positive number, got 'fast'"),
])
def test_bad_numbers(args, message):
    with pytest.raises(InputError) as err:
        parse_settings(args)
    assert str(err.value) == message


def test_bad_prefix_exits_2_with_one_line_as_a_process():
    res = subprocess.run([sys.executable, "-m", "swarm_sim.node", "--name-prefix", "_x"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        "swarm-sim: error: --name-prefix: must be a ROS name (letters, digits and '_', starting "
        "with a letter, no '__'), got '_x'"]


def test_a_mix_gives_the_engine_every_robots_model_as_swarm_up_interleaves_it():
    from swarm_scene.fleet import fleet_models
    from swarm_sim.settings import prepare

    mix = "turtlebot3_waffle:3,turtlebot3_burger:2,linorobot2_2wd:1"
    engine, _, namespaces, spawned, _ = prepare(parse_settings(
        ["--robot", mix, "--swarm-size", "6", "--world", "empty"]))
    try:
        assert [m.name for m in engine.models] == list(fleet_models(mix, 6))
        assert namespaces == [f"Srobot{i}" for i in range(1, 7)]
        assert spawned.endswith("; robots: 6 (3 turtlebot3_waffle, 2 turtlebot3_burger, "
                                "1 linorobot2_2wd)")
    finally:
        engine.close()


def test_a_mix_that_does_not_add_up_exits_2_with_one_line_as_a_process():
    res = subprocess.run([sys.executable, "-m", "swarm_sim.node", "--swarm-size", "3", "--robot",
                          "turtlebot3_waffle:1,turtlebot3_burger:1"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        "swarm-sim: error: --robot: the counts of 'turtlebot3_waffle:1,turtlebot3_burger:1' add "
        "up to 2, not to --swarm-size 3"]


# -- the start gate's reader (swarm-up --record) -------------------------------------------------


class _Pub:
    def __init__(self, topic, matched):
        self.topic_name, self.matched = topic, matched

    def get_subscription_count(self):
        return self.matched


class _Gate:
    """What ``SimulatorNode.reader_matched`` reads of its node: the reader's subscriptions
    discovered so far, and this node's publishers with their matched counts."""

    def __init__(self, need, discovered, matched=1, progress=None):
        self.settings = parse_settings(["--wait-for-reader", "swarm_recorder",
                                        "--reader-subscriptions", str(need)])
        topics = ["/clock", "/Srobot1/odom", "/Srobot1/ground_truth", "/Srobot2/odom"]
        self.publishers = [_Pub(t, matched) for t in topics]
        self.discovered = topics[:discovered]
        # the record window's progress subscription and its matched writers, or None
        self._progress_sub = None if progress is None else _Progress(progress)

    def get_subscriber_names_and_types_by_node(self, name, ns):
        assert (name, ns) == ("swarm_recorder", "/")
        return [(t, ["nav_msgs/msg/Odometry"]) for t in self.discovered]

    def count_subscribers(self, topic):
        return 1


@pytest.mark.parametrize(("need", "discovered", "matched", "opens"), [
    (3, 1, 1, False),  # one of three discovered and matched: the others would lose ticks
    (3, 2, 1, False),
    (3, 3, 1, True),
    (3, 3, 0, False),  # discovered, not matched yet
    (1, 1, 1, True),
])
def test_the_gate_waits_for_every_subscription_of_the_reader(need, discovered, matched, opens):
    from swarm_sim.node import SimulatorNode

    gate = _Gate(need, discovered, matched)
    assert SimulatorNode.reader_matched(gate, float("inf")) is opens
    assert SimulatorNode.reader_matched(gate, 0.0) is True  # given up


class _Progress:
    def __init__(self, writers):
        self.writers = writers

    def get_publisher_count(self):
        return self.writers


@pytest.mark.parametrize(("writers", "opens"), [(0, False), (1, True)])
def test_the_gate_waits_for_the_recorders_progress_writer(writers, opens):
    from swarm_sim.node import SimulatorNode

    gate = _Gate(3, 3, 1, progress=writers)
    assert SimulatorNode.reader_matched(gate, float("inf")) is opens
    assert SimulatorNode.reader_matched(gate, 0.0) is True  # given up


def test_reader_subscriptions_must_be_positive():
    with pytest.raises(InputError, match="^--reader-subscriptions: must be a positive integer"):
        parse_settings(["--reader-subscriptions", "0"])
