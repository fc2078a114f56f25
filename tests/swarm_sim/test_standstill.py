"""Standstill episodes from per-tick poses (pure): when a robot rests 60 s or more, and where."""

import numpy as np
import pytest

from swarm_sim.standstill import StandstillTracker


def _run(track, xs, ys=None, dt=0.1, t0=0.0):
    """Feed one robot's x (and y) per tick; ticks at t0 + dt, t0 + 2 dt, ..."""
    ys = np.zeros(len(xs)) if ys is None else ys
    for k, (x, y) in enumerate(zip(xs, ys, strict=True), start=1):
        track.update(t0 + k * dt, np.array([[x, y, 0.0]]))


def test_a_rest_of_70_s_between_two_drives_is_one_episode_where_it_stood():
    track = StandstillTracker(np.array([[0.0, 0.0, 0.0]]))
    drive = np.linspace(0.0, 5.0, 101)[1:]  # 10 s at 0.5 m/s
    # 10 s driving, 70 s at rest at x = 5 (jitter 5 cm, turning in place is resting), drive on
    rest = 5.0 + 0.03 * np.sin(np.arange(700))
    _run(track, np.concatenate((drive, rest, 5.0 + drive)))
    (ep,) = track.finish()
    assert ep.robot == 0 and not ep.open
    # the anchor is the first tick within 0.1 m of where it stayed: x = 4.95 at 9.9 s; the
    # episode ends at the last tick within 0.1 m of it (x = 5.05 at 80.1 s)
    assert ep.start_s == pytest.approx(9.9) and ep.x == pytest.approx(4.95) and ep.y == 0.0
    assert ep.duration_s == pytest.approx(70.2)


def test_short_rests_and_slow_driving_are_no_episode():
    track = StandstillTracker(np.array([[0.0, 0.0, 0.0]]))
    # 59 s at rest, then 100 s creeping at 1 cm/s (leaves the 0.1 m circle every 10 s)
    _run(track, np.concatenate((np.zeros(590), 0.2 + 0.001 * np.arange(1000))))
    assert track.finish() == []


def test_an_episode_open_at_the_end_is_closed_there_and_kept_once():
    poses = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 1.0]])
    track = StandstillTracker(poses, t0=100.0)
    for k in range(1, 651):  # 65 s: robot 0 drives at 1 m/s, robot 1 stands
        track.update(100.0 + 0.1 * k, np.array([[0.1 * k, 0.0, 0.0], [3.0, 4.0, 1.0 + k]]))
    (ep,) = track.finish()
    assert (ep.robot, ep.start_s, ep.x, ep.y, ep.open) == (1, 100.0, 3.0, 4.0, True)
    assert ep.duration_s == pytest.approx(65.0)
    assert len(track.finish()) == 1  # finishing again adds nothing
