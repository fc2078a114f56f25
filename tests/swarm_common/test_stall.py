"""The one stall-reporting wait (swarm_common/stall.py), on a fake clock."""

import pytest

from swarm_common.stall import StallReport, wait_until


class FakeClock:
    """A wall clock that moves only when spun."""

    def __init__(self, step: float = 0.5):
        self.now, self.step = 0.0, step

    def __call__(self) -> float:
        return self.now

    def spin(self) -> None:
        self.now += self.step


def test_a_report_is_due_once_per_period():
    stall = StallReport(10.0, since_s=0.0)
    assert stall.due(9.9) is None
    assert stall.due(10.0) == 10.0
    assert stall.due(15.0) is None
    assert stall.due(35.0) == 35.0  # periods skipped: one report
    assert stall.due(39.0) is None and stall.due(40.0) == 40.0


def test_begin_end_and_not_waiting():
    stall = StallReport(5.0)
    assert stall.due(100.0) is None and stall.waited(100.0) == 0.0
    stall.begin(100.0)
    stall.begin(103.0)  # already waiting: the first begin counts
    assert stall.due(105.0) == 5.0
    stall.end()
    stall.begin(200.0)
    assert stall.due(204.0) is None and stall.due(205.0) == 5.0


def test_a_period_must_not_be_negative_and_zero_reports_at_every_check():
    with pytest.raises(ValueError, match="every_s"):
        StallReport(-1.0)
    stall = StallReport(0.0, since_s=0.0)
    assert [stall.due(t) for t in (0.0, 0.1, 0.1)] == [0.0, 0.1, 0.1]


def test_wait_until_spins_until_done_and_reports_the_stall():
    clock = FakeClock(0.5)
    reports = []
    ok = wait_until(lambda: clock.now >= 25.0, clock.spin, report=reports.append, every_s=10.0,
                    clock=clock)
    assert ok is True and clock.now == 25.0
    assert reports == [10.0, 20.0]


def test_wait_until_runs_its_duties_on_their_periods():
    clock = FakeClock(0.25)
    runs = []
    wait_until(lambda: clock.now >= 2.0, clock.spin, report=None,
               duties=((0.5, lambda: runs.append(("a", clock.now))),
                       (1.0, lambda: runs.append(("b", clock.now)))), clock=clock)
    assert [t for k, t in runs if k == "a"] == [0.5, 1.0, 1.5]
    assert [t for k, t in runs if k == "b"] == [1.0]


def test_a_stop_ends_the_wait_before_done():
    clock = FakeClock(1.0)
    ok = wait_until(lambda: False, clock.spin, report=None, stopped=lambda: clock.now >= 3.0,
                    clock=clock)
    assert ok is False and clock.now == 3.0


def test_done_at_once_does_not_spin():
    spins = []
    assert wait_until(lambda: True, lambda: spins.append(1), report=None) is True
    assert spins == []
