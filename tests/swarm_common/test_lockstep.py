"""The goal handshake of the lockstep (swarm_common.lockstep), pure: which tick waits for what,
and that inside the lockstep no wait ends by the wall clock."""

from swarm_common.lockstep import (
    COMING,
    NONE_COMING,
    POLL_S,
    STALL_REPORT_S,
    GoalHandshake,
    poll_period,
)

TICK = 100_000_000  # [ns]


def _ended_at(t_ns: int, **kwargs) -> GoalHandshake:
    hs = GoalHandshake(**kwargs)
    hs.answered(t_ns - TICK, terminal=False)
    hs.answered(t_ns, terminal=True, outcome=True)
    return hs


def yes():
    return True


def no():
    return False


def test_the_first_tick_after_a_goal_ended_waits_once_for_a_connected_commander():
    hs = _ended_at(10 * TICK)
    assert not hs.awaits_goal(10 * TICK, False, yes)  # the ending tick itself
    assert hs.awaits_goal(11 * TICK, False, yes)
    assert not hs.awaits_goal(11 * TICK, True, yes)  # the goal came
    assert not hs.awaits_goal(11 * TICK, False, no)  # no commander
    hs.answered(11 * TICK, terminal=True)  # still ended: the same end, not a new one
    assert hs.awaits_goal(12 * TICK, False, yes)
    hs.answered(12 * TICK, terminal=False)  # a goal runs
    assert not hs.awaits_goal(13 * TICK, False, yes)


def test_a_running_goal_never_waits_and_the_commander_is_asked_last():
    hs = GoalHandshake()
    hs.answered(5 * TICK, terminal=False)
    asked = []
    assert not hs.awaits_goal(6 * TICK, False, lambda: asked.append(1) or True)
    assert not hs.holds_end(5 * TICK, False, lambda: asked.append(1) or True)
    assert asked == []


def test_in_the_lockstep_a_wait_never_ends_by_the_wall_clock_and_a_stall_is_only_reported():
    hs = _ended_at(10 * TICK, lockstep=True, timeout_s=0.5)
    hs.waiting(100.0)
    assert hs.poll(11 * TICK, 100.6, commander=True) == (False, None)  # past timeout_s
    over, stalled = hs.poll(11 * TICK, 100.0 + STALL_REPORT_S + 0.1, commander=True)
    assert not over and stalled is not None and stalled >= STALL_REPORT_S
    assert hs.poll(11 * TICK, 100.0 + STALL_REPORT_S + 0.2, commander=True) == (False, None)
    over, stalled = hs.poll(11 * TICK, 100.0 + 3 * STALL_REPORT_S, commander=True)
    assert not over and stalled is not None  # reported again, every STALL_REPORT_S
    assert hs.timeouts == 0
    assert hs.awaits_goal(11 * TICK, False, yes)  # still waiting
    # a lockstep commander that left (crashed, or stopped beyond DDS's lease) ends the wait:
    # counted, the tick goes on without the goal the run would have had
    assert hs.poll(11 * TICK, 200.0, commander=False) == (True, None)
    assert not hs.awaits_goal(11 * TICK, False, yes) and hs.timeouts == 1
    # out of the lockstep a commander that leaves is a script that ended: not counted
    user = _ended_at(10 * TICK, lockstep=False)
    user.waiting(0.0)
    assert user.poll(11 * TICK, 0.1, commander=False) == (True, None) and user.timeouts == 0


def test_out_of_the_lockstep_the_wait_ends_at_the_timeout_and_is_counted():
    hs = _ended_at(10 * TICK, lockstep=False, timeout_s=2.5)
    hs.waiting(100.0)
    hs.waiting(101.0)  # already waiting: the start stays
    assert hs.poll(11 * TICK, 102.0, commander=True) == (False, None)
    assert hs.poll(11 * TICK, 102.5, commander=True) == (True, None)
    assert hs.timeouts == 1
    assert not hs.awaits_goal(11 * TICK, False, yes)  # over: the tick is answered
    hs.answered(11 * TICK, terminal=False)
    hs.answered(15 * TICK, terminal=True)  # the next goal ends: a new wait
    assert hs.awaits_goal(16 * TICK, False, yes)


def test_no_goal_coming_lifts_the_wait_only_after_a_goal_ended():
    hs = GoalHandshake()
    assert not hs.said(NONE_COMING)
    hs = _ended_at(10 * TICK)
    assert hs.said(NONE_COMING)
    assert not hs.awaits_goal(11 * TICK, False, yes)


def test_the_end_of_a_goal_is_held_until_the_commander_says_a_word_when_asked_to():
    hs = _ended_at(10 * TICK, hold_goal_end=True)
    assert hs.holds_end(10 * TICK, False, yes)
    assert not hs.holds_end(10 * TICK, False, no)  # no commander: nothing to wait for
    assert not hs.holds_end(11 * TICK, False, yes)  # only the tick at which it ended
    assert not _ended_at(10 * TICK).holds_end(10 * TICK, False, yes)  # not asked to
    idle = GoalHandshake(hold_goal_end=True)
    idle.answered(10 * TICK, terminal=True)  # IDLE at the start: no goal ended
    assert not idle.holds_end(10 * TICK, False, yes) and idle.awaits_goal(11 * TICK, False, yes)
    # the word "a goal is coming": the end is answered, the next tick waits for the goal
    assert hs.said(COMING)
    assert not hs.holds_end(10 * TICK, False, yes)
    assert hs.awaits_goal(11 * TICK, False, yes)
    # a goal that arrived is a word too, and so is "none coming"
    hs = _ended_at(10 * TICK, hold_goal_end=True)
    assert not hs.holds_end(10 * TICK, True, yes)
    hs.goal_arrived()
    assert not hs.holds_end(10 * TICK, False, yes)
    hs = _ended_at(10 * TICK, hold_goal_end=True)
    hs.said(NONE_COMING)
    assert not hs.holds_end(10 * TICK, False, yes)
    assert not hs.awaits_goal(11 * TICK, False, yes)


def test_a_word_for_one_end_does_not_carry_over_to_the_next():
    hs = _ended_at(10 * TICK, hold_goal_end=True)
    hs.said(NONE_COMING)
    hs.answered(12 * TICK, terminal=False)  # the next goal runs ...
    hs.answered(20 * TICK, terminal=True, outcome=True)  # ... and ends
    assert hs.holds_end(20 * TICK, False, yes)
    assert hs.awaits_goal(21 * TICK, False, yes)


def test_a_goal_that_ends_at_the_tick_it_took_effect_is_a_new_end():
    hs = GoalHandshake(hold_goal_end=True)
    hs.answered(10 * TICK, terminal=True)  # IDLE at the start
    hs.answered(11 * TICK, terminal=True, outcome=True, goal_set=True)  # reached at once
    assert hs.holds_end(11 * TICK, False, yes)
    assert hs.awaits_goal(12 * TICK, False, yes)


def test_a_wait_is_polled_less_often_the_longer_it_lasts():
    """POLL_STEPS: 20 Hz for the first second, then 4 Hz, then 1 Hz from 5 s on."""
    assert [poll_period(w) for w in (0.0, 0.99, 1.0, 4.99, 5.0, 3600.0)] == [
        0.05, 0.05, 0.25, 0.25, 1.0, 1.0]
    assert poll_period(0.0) == POLL_S
    hs = _ended_at(TICK, lockstep=True)
    assert hs.waited(100.0) == 0.0
    hs.waiting(100.0)
    hs.waiting(101.0)  # a wait already runs: it is not restarted
    assert hs.waited(102.5) == 2.5
    hs.released()
    assert hs.waited(103.0) == 0.0
