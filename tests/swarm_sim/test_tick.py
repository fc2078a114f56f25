"""The tick gate's rules (swarm_sim/tick.py), without ROS: one test per rule of its docstring."""

import numpy as np
import pytest

from swarm_sim.tick import MANUAL_PRIORITY_S, RecordWindow, TickGate

P = 100_000_000  # [ns] one tick at 10 Hz


def started_gate(n=3, answering=None) -> TickGate:
    """A gate past the start gate: tick 0 stepped, tick 1 answered by ``answering``, stepped."""
    gate = TickGate(n)
    gate.advance(P)  # tick 0, stepped silently
    for i in range(n) if answering is None else answering:
        gate.answer(i, gate.t_ns, 0.1, 0.0, 0.0)
    gate.commands(0.0)
    gate.advance(P)
    return gate


# -- rule 1: answers -------------------------------------------------------------------------
def test_an_answer_stamped_with_the_tick_activates_and_is_applied():
    gate = TickGate(2)
    gate.advance(P)
    assert gate.answer(1, P, 0.2, -0.1, 0.0) is False
    assert gate.active.tolist() == [False, True]
    cmds = gate.commands(0.0)
    assert cmds.v.tolist() == [0.0, 0.2] and cmds.w.tolist() == [0.0, -0.1]
    assert cmds.late == [] and gate.answers == {}


@pytest.mark.parametrize("stamp", [P, 3 * P])  # an earlier tick's answer, a future one
def test_an_answer_to_another_tick_is_ignored(stamp):
    gate = started_gate(2)
    assert gate.t_ns == 2 * P
    gate.answer(0, stamp, 0.3, 0.0, 0.0)
    assert 0 not in gate.answers
    assert gate.awaited() == {0, 1}


def test_a_silenced_robots_answer_is_ignored():
    gate = started_gate(2)
    gate.silenced = {1}
    gate.answer(1, gate.t_ns, 0.3, 0.0, 0.0)
    assert 1 not in gate.answers


def test_an_answer_clears_lost_and_for_good():
    gate = started_gate(2)
    assert gate.lose(1, for_good=True) is True
    assert 1 in gate.lost and 1 in gate.for_good
    gate.answer(1, gate.t_ns, 0.0, 0.0, 0.0)
    assert 1 not in gate.lost and 1 not in gate.for_good


# -- rule 2: teleop priority -------------------------------------------------------------------
def test_a_manual_command_outranks_the_navigator_within_its_window_and_then_not():
    gate = started_gate(2)
    gate.answer(0, 0, 0.05, 0.5, now_s=100.0)  # zero stamp: manual
    gate.answer(0, gate.t_ns, 0.2, 0.0, 100.1)
    gate.answer(1, gate.t_ns, 0.1, 0.0, 100.1)
    cmds = gate.commands(100.0 + MANUAL_PRIORITY_S / 2)
    assert (cmds.v[0], cmds.w[0]) == (0.05, 0.5)  # teleop wins
    gate.advance(P)
    gate.answer(0, gate.t_ns, 0.2, 0.0, 101.0)
    gate.answer(1, gate.t_ns, 0.1, 0.0, 101.0)
    cmds = gate.commands(100.0 + 2 * MANUAL_PRIORITY_S)
    assert (cmds.v[0], cmds.w[0]) == (0.2, 0.0)  # teleop stopped coming: the navigator again
    assert 0 not in gate.manual


def test_a_manual_command_holds_until_replaced_for_a_robot_without_navigator():
    gate = started_gate(2, answering=[1])
    gate.answer(0, 0, 0.1, 0.0, 0.0)
    for k in range(3):
        gate.answer(1, gate.t_ns, 0.0, 0.0, 10.0 * k)
        assert gate.commands(10.0 * k).v[0] == 0.1
        gate.advance(P)


# -- rule 3: awaited ---------------------------------------------------------------------------
def test_awaited_are_the_active_robots_not_answered_excused_or_lost():
    gate = started_gate(4)
    gate.answer(0, gate.t_ns, 0.0, 0.0, 0.0)
    gate.lose(2)
    assert gate.awaited(excused={3}) == {1}
    gate.answer(1, gate.t_ns, 0.0, 0.0, 0.0)
    assert gate.awaited(excused={3}) == set()


def test_the_incremental_awaited_set_matches_the_full_one():
    gate = started_gate(5)
    known = gate.awaited()
    assert known == {0, 1, 2, 3, 4}
    for i in (4, 0, 2):
        gate.answer(i, gate.t_ns, 0.0, 0.0, 0.0)
        known = gate.awaited((), known)
        assert known == gate.awaited()
    gate.lose(1)
    gate.answer(3, gate.t_ns, 0.0, 0.0, 0.0)
    assert gate.awaited((), known) == set() == gate.awaited()


def test_a_lost_robot_that_answered_this_tick_is_not_lost():
    gate = started_gate(2)
    gate.answer(1, gate.t_ns, 0.0, 0.0, 0.0)
    assert gate.lose(1) is False
    assert 1 not in gate.lost
    assert gate.lose(0) is True and gate.lose(0) is False  # said once


# -- rule 4: late ------------------------------------------------------------------------------
def test_a_lost_robot_is_late_stopped_and_inactive_until_it_answers_again():
    gate = started_gate(3)
    gate.answer(0, gate.t_ns, 0.2, 0.0, 0.0)
    gate.answer(2, gate.t_ns, 0.2, 0.0, 0.0)
    gate.lose(1)
    assert gate.awaited() == set()
    cmds = gate.commands(0.0)
    assert cmds.late == [1] and cmds.v.tolist() == [0.2, 0.0, 0.2]
    assert gate.late_ticks.tolist() == [0, 1, 0] and not gate.active[1]
    gate.advance(P)
    assert gate.awaited() == {0, 2}  # no longer awaited
    assert gate.answer(1, gate.t_ns, 0.0, 0.0, 0.0) is True  # answers again: announce it
    assert gate.active[1] and 1 not in gate.lost


def test_an_excused_robot_is_not_late():
    gate = started_gate(2)
    gate.answer(0, gate.t_ns, 0.0, 0.0, 0.0)
    cmds = gate.commands(0.0, excused={1})
    assert cmds.late == [] and gate.active[1] and gate.late_ticks[1] == 0


# -- rule 5: the start gate --------------------------------------------------------------------
def test_the_start_gate_opens_at_want_answering_robots():
    gate = TickGate(3)
    gate.advance(P)
    assert not gate.started(2)
    gate.answer(0, P, 0.0, 0.0, 0.0)
    assert not gate.started(2)
    assert gate.answer(2, P, 0.0, 0.0, 0.0) is False  # first answers are not "again"
    assert gate.started(2) and not gate.started(3) and gate.started(0)


# -- rule 6: rejoin ----------------------------------------------------------------------------
def test_rejoining_robots_are_awaited_unless_given_up_for_good():
    gate = started_gate(3)
    gate.kill(1)
    gate.rejoin |= {1, 2}
    assert gate.rejoining() == {1, 2}
    gate.lose(2, for_good=True)
    assert gate.rejoining() == {1}
    gate.answer(1, gate.t_ns, 0.0, 0.0, 0.0)
    assert gate.rejoining() == set() and gate.active[1]


# -- rule 7: faults ----------------------------------------------------------------------------
def test_a_killed_robots_answer_is_dropped_and_it_is_not_awaited():
    gate = started_gate(2)
    gate.answer(1, gate.t_ns, 0.3, 0.0, 0.0)
    gate.kill(1)
    assert 1 not in gate.answers and not gate.active[1]
    gate.answer(0, gate.t_ns, 0.0, 0.0, 0.0)
    assert gate.awaited() == set()
    assert gate.commands(0.0).late == []


def test_a_lost_command_keeps_the_previous_one():
    gate = started_gate(2)
    gate.answer(0, gate.t_ns, 0.2, 0.1, 0.0)
    gate.answer(1, gate.t_ns, 0.3, 0.0, 0.0)
    gate.commands(0.0)
    gate.advance(P)
    gate.answer(0, gate.t_ns, 0.0, 0.0, 0.0)
    gate.answer(1, gate.t_ns, 0.1, 0.0, 0.0)
    cmds = gate.commands(0.0, cmd_dropped={0})
    assert (cmds.v[0], cmds.w[0]) == (0.2, 0.1) and cmds.v[1] == 0.1


def test_ticks_count_every_step_from_tick_zero():
    gate = TickGate(1)
    gate.advance(P)
    gate.advance(P)
    assert (gate.ticks, gate.t_ns) == (2, 2 * P)
    assert np.array_equal(gate.late_ticks, [0])


# -- rule 8: the record window -----------------------------------------------------------------
def test_the_record_window_holds_a_tick_until_the_recorder_is_close_enough():
    window = RecordWindow(2, P)
    assert window.holds(3 * P)  # nothing recorded yet
    window.progress(P)
    assert not window.holds(3 * P) and window.holds(4 * P)
    window.progress(0)  # out of order: the latest counts
    assert window.recorded_ns == P
    window.give_up()
    assert not window.holds(100 * P)


def test_no_record_window_never_holds():
    assert not RecordWindow(0, P).holds(10 * P)
