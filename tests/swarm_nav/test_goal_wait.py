"""The goal-wait handshake (swarm_nav.goal_wait), pure: when a tick waits, and for how long."""

from swarm_nav.goal_wait import POLL_S, GoalWait

TICK = 100_000_000  # [ns]


class Timers:
    """Stand-ins for a node's timers: what was started and stopped."""

    def __init__(self):
        self.running: list = []

    def start(self, period_s, callback):
        self.running.append((period_s, callback))
        return self.running[-1]

    def stop(self, timer):
        self.running.remove(timer)


def _ended_at(t_ns: int, timeout_s: float = 2.5, timers: Timers | None = None) -> GoalWait:
    timers = timers or Timers()
    gw = GoalWait(timeout_s, timers.start, timers.stop)
    gw.answered(t_ns - TICK, terminal=False)
    gw.answered(t_ns, terminal=True)
    return gw


def test_the_first_tick_after_a_goal_ended_waits_once_for_a_connected_commander():
    gw = _ended_at(10 * TICK)
    assert not gw.needed(10 * TICK, False, lambda: True)  # the ending tick itself
    assert gw.needed(11 * TICK, False, lambda: True)
    assert not gw.needed(11 * TICK, True, lambda: True)  # the goal came
    assert not gw.needed(11 * TICK, False, lambda: False)  # no commander
    gw.hold(11 * TICK, 0.0, lambda t: None)
    assert gw.poll(11 * TICK, 3.0, commander=True)  # timed out: answered without a goal
    gw.answered(11 * TICK, terminal=True)
    assert not gw.needed(12 * TICK, False, lambda: True)  # once per ended goal


def test_a_running_goal_never_waits_and_the_commander_is_asked_last():
    gw = GoalWait(2.5, Timers().start, Timers().stop)
    gw.answered(5 * TICK, terminal=False)
    asked = []
    assert not gw.needed(6 * TICK, False, lambda: asked.append(1) or True)
    assert asked == []


def test_a_wait_ends_at_the_timeout_and_is_counted_or_when_the_commander_leaves():
    timers = Timers()
    gw = _ended_at(10 * TICK, timeout_s=2.5, timers=timers)
    polled = []
    gw.hold(11 * TICK, 100.0, polled.append)
    gw.hold(11 * TICK, 100.5, polled.append)  # already waiting: one timer
    assert [p for p, _ in timers.running] == [POLL_S]
    timers.running[0][1]()
    assert polled == [11 * TICK]
    assert not gw.poll(11 * TICK, 101.0, commander=True)
    assert gw.poll(11 * TICK, 102.5, commander=True)
    assert gw.timeouts == 1 and timers.running == []  # over: the timer is stopped
    assert not gw.needed(11 * TICK, False, lambda: True)  # over: the tick is answered
    gw = _ended_at(10 * TICK)
    gw.hold(11 * TICK, 100.0, lambda t: None)
    assert gw.poll(11 * TICK, 100.1, commander=False)
    assert gw.timeouts == 0


def test_no_goal_coming_lifts_the_wait_only_after_a_goal_ended():
    gw = GoalWait(2.5, Timers().start, Timers().stop)
    assert not gw.no_goal_coming()
    gw = _ended_at(10 * TICK)
    assert gw.no_goal_coming()
    assert not gw.needed(11 * TICK, False, lambda: True)
