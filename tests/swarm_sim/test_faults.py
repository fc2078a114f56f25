"""The simulator's fault state machine (swarm_sim.faults): transitions at simulated times."""

import numpy as np

from swarm_common.faults import parse_faults
from swarm_common.stamps import NS_PER_S
from swarm_sim.faults import SimFaults

NS = [f"Srobot{i}" for i in range(1, 5)]
TICK = NS_PER_S // 10


def _walk(spec, seconds, lidar_every=2, seed=0):
    """Advance tick by tick; return per tick (t, transitions, held, silenced, drops)."""
    faults = SimFaults(parse_faults(spec, tuple(NS)), NS, seed)
    out = []
    for k in range(round(seconds * 10) + 1):
        t = k * TICK
        due = faults.advance(t)
        drops = faults.draw_drops(k % lidar_every == 0)
        out.append((t / NS_PER_S, [(f.kind, ph) for f, ph in due], faults.held_still().copy(),
                    faults.silenced(), drops))
    return faults, out


def test_freeze_holds_exactly_its_interval():
    _, ticks = _walk("freeze:2@1.05+1", 3)
    held = [t for t, _, h, _, _ in ticks if h[1]]
    assert held[0] == 1.1 and held[-1] == 2.0  # first tick at or after 1.05 s, until 2.05 s
    assert len(held) == 10
    assert not any(h[[0, 2, 3]].any() for _, _, h, _, _ in ticks)
    starts = [t for t, due, *_ in ticks if ("freeze", "start") in due]
    ends = [t for t, due, *_ in ticks if ("freeze", "end") in due]
    assert starts == [1.1] and ends == [2.1]


def test_kill_robot_is_held_and_silenced_for_good():
    _, ticks = _walk("kill-robot:3@2", 5)
    dead = [t for t, _, h, s, _ in ticks if h[2] and s == {2}]
    assert dead[0] == 2.0 and dead[-1] == 5.0 and len(dead) == 31
    assert all(not h[2] and not s for t, _, h, s, _ in ticks if t < 2.0)


def test_kill_nav_silences_for_the_outage_without_holding():
    _, ticks = _walk("kill-nav:1@1+0.5", 3)
    silenced = [t for t, _, _, s, _ in ticks if 0 in s]
    assert silenced == [1.0, 1.1, 1.2, 1.3, 1.4]
    assert not any(h.any() for _, _, h, _, _ in ticks)  # stopped by zero commands, not held
    assert [t for t, due, *_ in ticks if due] == [1.0, 1.5]


def test_drop_loses_the_share_asked_for_reproducibly():
    faults, ticks = _walk("drop:4/odom:0.3@10+100,drop:2/scan:1@5+1", 200, seed=3)
    odom = [t for t, *_, d in ticks if 3 in d.odom]
    in_window = [t for t, *_ in ticks if 10.0 <= t < 110.0]
    assert all(10.0 <= t < 110.0 for t in odom)
    assert abs(len(odom) / len(in_window) - 0.3) < 0.05
    scans = [t for t, *_, d in ticks if 1 in d.scan]
    assert scans == [5.0, 5.2, 5.4, 5.6, 5.8]  # every lidar tick (every 2nd) of [5, 6)
    assert faults.dropped == {1: len(odom), 2: 5}
    again, ticks2 = _walk("drop:4/odom:0.3@10+100,drop:2/scan:1@5+1", 200, seed=3)
    assert [t for t, *_, d in ticks2 if 3 in d.odom] == odom
    _, other = _walk("drop:4/odom:0.3@10+100", 200, seed=4)
    assert [t for t, *_, d in other if 3 in d.odom] != odom


def test_excused_robots_are_those_losing_odom_or_scan():
    _, ticks = _walk("drop:1/scan:1@1+0.1,drop:2/odom:1@1+0.1,drop:3/cmd_vel:1@1+0.1", 2)
    at1 = next(d for t, *_, d in ticks if t == 1.0)
    assert at1.excused == {0, 1} and at1.cmd_vel == {2}


def test_overlapping_freezes_hold_until_the_last_ends():
    _, ticks = _walk("freeze:1@1+1,freeze:1@1.5+1", 3)
    held = [t for t, _, h, _, _ in ticks if h[0]]
    assert held[0] == 1.0 and held[-1] == 2.4
    assert np.isclose(len(held), 15)
