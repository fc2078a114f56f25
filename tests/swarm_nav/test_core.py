"""The whole navigator in closed loop, in pure Python: states, aborts, passing, holding."""

import dataclasses
import math
import pathlib

import numpy as np
import pytest

from swarm_nav.config import NavigatorConfig
from swarm_nav.core import NavigatorCore, NavState, NavStatus
from swarm_nav.costmap import add_keepout, build_costmap
from swarm_nav.holding import holding_sites_from_poi, site_kinds_from_poi, workstation_kind
from swarm_nav.holding_behaviour import HoldingBehaviour
from swarm_scene.occupancy import OccupancyMap
from swarm_scene.poi import poi_for_world
from tests.swarm_nav.helpers import (
    SLIM_BLOCKAGE_WALLS,
    WAFFLE_FOOTPRINT,
    SimRobot,
    simulate,
    slim_blockage_map,
)

WORLDS = pathlib.Path(__file__).resolve().parents[2] / "worlds"
LOADER1 = np.array([-7.74575, -3.57766, math.pi])


@pytest.fixture(scope="module")
def occ() -> OccupancyMap:
    return slim_blockage_map()


def make_robot(occ, pose, index=1, sites=(), log=True) -> SimRobot:
    cfg = dataclasses.replace(NavigatorConfig(), robot_index=index)
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT, sites)
    core.set_map(occ)
    pose = np.asarray(pose, dtype=float)
    core.step(pose, 0.0, 0.0, 0.0)
    return SimRobot(core, pose, log=[] if log else None)


def assert_arrived(robot: SimRobot, goal):
    st = robot.core.status
    assert st.state == NavState.SUCCEEDED, (st, robot.pose)
    assert np.hypot(*(robot.pose[:2] - goal[:2])) <= 0.25
    assert abs(math.remainder(robot.pose[2] - goal[2], 2 * math.pi)) <= 0.25


# ------------------------------------------------------------------ states and aborts
def test_idle_until_a_goal(occ):
    r = make_robot(occ, [0.0, 0.0, math.pi])
    st = r.core.status
    assert isinstance(st, NavStatus)
    assert (st.state, st.goal_id, st.goal, st.reason) == (NavState.IDLE, "", None, "")
    assert r.core.step(r.pose, 0.0, 0.0, 0.1) == (0.0, 0.0)


@pytest.mark.parametrize("goal, reason", [
    ((20.0, 0.0, 0.0), "goal outside map"),
    ((0.0, -4.9, 0.0), "goal in obstacle"),     # inside the bottom wall
    ((6.5, -3.0, 0.0), "no path"),              # the closed pocket of slim_blockage
    ((-4.5, 2.0, 0.0), "no path"),              # inside the closed blockage
])
def test_bad_goals_abort_at_once_with_the_reason(occ, goal, reason):
    r = make_robot(occ, [0.0, 0.0, math.pi])
    r.core.set_goal(np.array(goal), "7.000000000", 1.0)
    st = r.core.status
    assert (st.state, st.reason, st.goal_id) == (NavState.ABORTED, reason, "7.000000000")
    assert r.core.status_key == (st.state, st.goal_id, st.reason)
    assert r.core.step(r.pose, 0.0, 0.0, 1.1) == (0.0, 0.0)


def test_a_goal_before_the_first_pose_plans_on_the_first_step(occ):
    core = NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT)
    core.set_map(occ)
    core.set_goal(np.array([6.5, -3.0, 0.0]), "g", 0.0)
    assert core.status.state == NavState.PLANNING
    core.step(np.array([0.0, 0.0, 0.0]), 0.0, 0.0, 0.1)
    assert (core.status.state, core.status.reason) == (NavState.ABORTED, "no path")


def test_no_map_aborts():
    core = NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT)
    core.set_goal(np.array([1.0, 0.0, 0.0]), "g", 0.0)
    assert (core.status.state, core.status.reason) == (NavState.ABORTED, "no map")


def test_cancel_and_replace(occ):
    r = make_robot(occ, [0.0, 0.0, math.pi])
    r.core.set_goal(np.array([-2.0, 0.0, 0.0]), "a", 0.0)
    assert r.core.status.state == NavState.DRIVING
    assert r.core.path is not None and r.core.status.distance_remaining == pytest.approx(2.0,
                                                                                           abs=0.05)
    r.core.set_goal(np.array([2.0, 1.0, 0.0]), "b", 1.0)
    assert (r.core.status.state, r.core.status.goal_id) == (NavState.DRIVING, "b")
    assert np.allclose(r.core.path[-1], [2.0, 1.0])
    assert r.core.status_key == (NavState.DRIVING, "b", "")
    r.core.cancel(2.0)
    assert r.core.status.state == NavState.CANCELED
    assert r.core.status_key == (NavState.CANCELED, "b", r.core.status.reason)
    assert r.core.step(r.pose, 0.0, 0.0, 2.1) == (0.0, 0.0)
    assert r.core.status.navigation_time == pytest.approx(1.0)


# ------------------------------------------------------------------ closed loop
def test_drives_around_the_slim_blockage_to_the_goal(occ):
    r = make_robot(occ, [-2.5, 0.0, math.pi])
    goal = np.array([-6.6, 0.0, math.pi / 2])
    r.core.set_goal(goal, "g", 0.0)
    versions = r.core.path_version
    res = simulate([r], SLIM_BLOCKAGE_WALLS, 90.0)
    assert_arrived(r, goal)
    assert res["min_wall_gap"] > 0.0
    assert r.core.path_version == versions          # planned once, on the goal
    st = r.core.status
    assert st.recoveries == 0 and st.holding_time == 0.0
    assert 9.0 / 0.26 < st.navigation_time < 60.0   # ~9.4 m around the blockage
    assert st.distance_remaining == 0.0


def test_the_closed_loop_is_deterministic(occ):
    logs = []
    for _ in range(2):
        r = make_robot(occ, [0.0, 0.0, math.pi])
        r.core.set_goal(np.array([-2.0, -3.0, 0.0]), "g", 0.0)
        simulate([r], SLIM_BLOCKAGE_WALLS, 30.0, seed=3)
        logs.append(r.log)
    assert logs[0] == logs[1]


@pytest.mark.parametrize("a0, b0", [
    ((-6.5, -3.9, 0.0), (-2.5, -3.9, math.pi)),      # head-on on the passage's centre line
    ((-7.0, -4.2, 0.0), (-2.0, -3.6, math.pi)),      # offset starts
    ((-4.5, -3.92, 0.0), (-2.0, -3.92, math.pi)),    # one already in the passage
])
def test_two_robots_swap_ends_of_the_passage_below_the_blockage(occ, a0, b0):
    a = make_robot(occ, a0, index=1)
    b = make_robot(occ, b0, index=2)
    ga = np.array([b0[0], b0[1], 0.0])
    gb = np.array([a0[0], a0[1], math.pi])
    a.core.set_goal(ga, "a", 0.0)
    b.core.set_goal(gb, "b", 0.0)
    res = simulate([a, b], SLIM_BLOCKAGE_WALLS, 90.0, seed=1)
    assert_arrived(a, ga)
    assert_arrived(b, gb)
    assert res["contact_ticks"] == 0
    assert res["min_separation"] > 0.05       # footprints never touch (5 cm to spare)
    assert res["min_wall_gap"] > 0.0


def test_robots_see_each_other(occ):
    """The thesis' navigators listened to the wrong scan topic and never saw each other."""
    a = make_robot(occ, [-6.5, -3.9, 0.0], index=1)
    b = SimRobot(None, np.array([-5.0, -3.9, math.pi]))
    simulate([a, b], SLIM_BLOCKAGE_WALLS, 0.1, until_done=False)
    seen = a.core.robots_seen
    assert len(seen) == 1
    assert np.hypot(*(seen[0].centre - (b.pose[:2] + [0.064, 0.0]))) < 0.12


# ------------------------------------------------------------------ holding
def test_holds_while_the_workstation_is_taken_then_takes_it(occ):
    spot = np.array([-6.6, -2.6])
    parked = SimRobot(None, LOADER1.copy())                  # another robot on loader 1
    r = make_robot(occ, [-2.5, -3.9, math.pi], sites=[(LOADER1, spot[None, :])])
    r.core.set_goal(LOADER1, "g", 0.0)
    states = []

    def on_tick(t, robots):
        states.append(r.core.status.state)
        if t >= 40.0:
            parked.pose = np.array([8.0, 8.0, 0.0])          # it leaves
    res = simulate([r, parked], SLIM_BLOCKAGE_WALLS, 120.0, on_tick=on_tick, until_done=False)
    assert NavState.HOLDING in states
    first_hold = states.index(NavState.HOLDING)
    assert all(s == NavState.HOLDING for s in states[first_hold + 150:400])  # waited at the spot
    assert r.log[390][1:3] == pytest.approx(spot, abs=0.4)
    assert_arrived(r, LOADER1)
    assert res["contact_ticks"] == 0 and res["min_separation"] > 0.1
    assert r.core.status.holding_time > 15.0


@pytest.mark.parametrize("timeout", [20.0, 0.0])
def test_gives_up_a_workstation_a_robot_stands_on_without_moving(occ, timeout):
    # A robot that died on loader 1 never leaves: after occupied_timeout [s] in sight of it the
    # goal is given up with the reason; occupied_timeout 0 holds for ever.
    spot = np.array([-6.6, -2.6])
    dead = SimRobot(None, LOADER1.copy())
    base = NavigatorConfig()
    cfg = dataclasses.replace(base, robot_index=1, holding=dataclasses.replace(
        base.holding, occupied_timeout=timeout))
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT, [(LOADER1, spot[None, :])])
    core.set_map(occ)
    r = SimRobot(core, np.array([-4.0, -3.9, math.pi]), log=[])
    core.step(r.pose, 0.0, 0.0, 0.0)
    core.set_goal(LOADER1, "g", 0.0)
    res = simulate([r, dead], SLIM_BLOCKAGE_WALLS, 60.0, until_done=True)
    states = [row[-1] for row in r.log]
    first_hold = states.index("HOLDING") * 0.1  # [s] it held first
    st = core.status
    if timeout == 0.0:
        assert st.state == NavState.HOLDING and st.holding_time > 40.0, st
    else:
        assert st.state == NavState.ABORTED, st
        assert st.reason == "goal occupied by a robot that has not moved for 20 s"
        # the timeout runs once the taken goal is in sight without a break: from the holding
        # spot, reached a few seconds after the robot began to hold (24.1 s of holding here)
        assert timeout <= st.holding_time <= timeout + 10.0, st
        assert st.navigation_time == pytest.approx(first_hold + st.holding_time, abs=0.2)
        assert r.v == pytest.approx(0.0, abs=0.05)  # stopped
    assert np.hypot(*(r.pose[:2] - LOADER1[:2])) > 0.6
    assert res["contact_ticks"] == 0


def test_first_come_first_served_at_a_workstation(occ):
    spot = np.array([-6.6, -2.6])
    sites = [(LOADER1, spot[None, :])]
    near = make_robot(occ, [-6.0, -4.3, math.pi], index=1, sites=sites)
    far = make_robot(occ, [-4.0, -3.9, math.pi], index=2, sites=sites)
    near.core.set_goal(LOADER1, "n", 0.0)
    far.core.set_goal(LOADER1, "f", 0.0)
    far_states = []
    res = simulate([near, far], SLIM_BLOCKAGE_WALLS, 40.0, until_done=False,
                   on_tick=lambda t, rs: far_states.append(far.core.status.state))
    assert_arrived(near, LOADER1)
    assert far.core.status.state == NavState.HOLDING
    assert np.hypot(*(far.pose[:2] - LOADER1[:2])) > 0.6        # never parks on top of it
    assert res["contact_ticks"] == 0 and res["min_separation"] > 0.05
    assert NavState.SUCCEEDED not in far_states


def test_replans_around_a_robot_standing_on_the_path(occ):
    r = make_robot(occ, [0.0, 2.0, 0.0])
    standing = SimRobot(None, np.array([1.6, 2.0, math.pi / 2]))
    goal = np.array([3.5, 2.0, 0.0])
    r.core.set_goal(goal, "g", 0.0)
    first = r.core.path_version
    res = simulate([r, standing], SLIM_BLOCKAGE_WALLS, 40.0, until_done=False,
                   on_tick=lambda t, rs: None)
    assert_arrived(r, goal)
    assert r.core.path_version > first                      # it planned around it
    assert res["contact_ticks"] == 0 and res["min_separation"] > 0.1
    assert r.core.status.recoveries == 0


def test_a_waiting_robot_makes_room(occ):
    spot = np.array([-6.0, 2.0])
    ws = np.array([-7.74575, 0.97297, math.pi])
    parked = SimRobot(None, ws.copy())                      # loader 3 is taken
    r = make_robot(occ, [-6.0, 4.5, -math.pi / 2], sites=[(ws, spot[None, :])])
    r.core.set_goal(ws, "g", 0.0)
    visitor = SimRobot(None, np.array([8.0, 8.0, 0.0]))
    waited = []

    def on_tick(t, robots):
        hp = r.core._holding.pattern
        if hp is not None and hp.phase.value == "wait" and not waited:
            waited.append(t)
            visitor.pose = np.array([r.pose[0] + 0.6, r.pose[1], math.pi])  # comes close
    simulate([r, parked, visitor], SLIM_BLOCKAGE_WALLS, 60.0, on_tick=on_tick, until_done=False)
    assert waited, "never waited at the holding spot"
    assert r.core.status.state == NavState.HOLDING
    assert np.hypot(*(r.pose[:2] - visitor.pose[:2])) > 1.0     # moved away from the visitor
    assert np.hypot(*(r.pose[:2] - ws[:2])) >= 2.0              # and stays off the busy dock


# ------------------------------------------------------------------ prediction vs padding
def _box_points(cx: float, cy: float) -> np.ndarray:
    """The outline of a 0.266 m square robot centred at (cx, cy), facing +x, 1 cm apart."""
    t = np.linspace(-0.133, 0.133, 27)
    ends = [np.column_stack((np.full_like(t, cx + sx * 0.133), cy + t)) for sx in (-1, 1)]
    sides = [np.column_stack((cx + t, np.full_like(t, cy + sy * 0.133))) for sy in (-1, 1)]
    return np.vstack(ends + sides)


def test_a_robot_predicted_into_our_footprint_does_not_unlock_driving_into_another(occ):
    """Found at 100 robots (a collision in loader1's queue): a robot perceived as moving toward
    us is predicted *inside* our footprint. DWA relaxes its padding to the current gap when the
    robot already is that near (so that it can leave a tight spot); a predicted point there
    relaxed it against the real robot standing 6.5 cm in front, and we drove into it."""
    from swarm_nav.dwa import Footprint, footprint_gaps
    from tests.swarm_nav.helpers import rollout

    pose = np.array([2.0, 3.0, 0.0])
    core = NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT)
    core.set_map(occ)
    core.step(pose, 0.0, 0.0, 0.0)
    core.set_goal(np.array([6.0, 3.0, 0.0]), "g", 0.0)
    # in front: a standing robot whose rear face is 0.065 m from our front edge (x_max 0.069)
    ahead = _box_points(pose[0] + 0.069 + 0.065 + 0.133, pose[1])
    # behind: a robot 8 cm off our rear edge (beyond the 5 cm padding), seen 0.25 m farther back
    # a second ago, so "driving at us" at 0.25 m/s: predicted 0.5 cm off and 7 cm into the rear
    # half of our footprint
    behind_now = _box_points(pose[0] - 0.197 - 0.08 - 0.133, pose[1])
    core.on_scan(np.vstack((ahead, behind_now - [0.25, 0.0])), 0.1)
    core.step(pose, 0.0, 0.0, 0.1)
    core.on_scan(np.vstack((ahead, behind_now)), 1.1)
    assert any(np.hypot(*r.velocity) > 0.1 for r in core.robots_seen)
    v, w = core.step(pose, 0.0, 0.0, 1.1)
    fp = Footprint.from_polygon(WAFFLE_FOOTPRINT)
    x, y, th = rollout(pose, np.array([v]), np.array([w]), np.linspace(0.05, 1.7, 34))
    gaps = footprint_gaps(x[0], y[0], th[0], ahead, fp)
    assert gaps.min() >= NavigatorConfig().dwa.footprint_padding - 1e-6, (v, w, gaps.min())


@pytest.mark.parametrize("escape", [0.02, 0.05])
def test_a_robot_pinned_parallel_to_a_wall_escapes_it(occ, escape):
    """Found in a 20-robot shift (Srobot2 stood 742 s, and a jam of 11 robots grew around it):
    a robot stopped parallel to the blockage's wall, a degree toward it, at the edge of
    ``footprint_padding`` (the lidar's noise brings some wall points inside it). Every turn swings
    a corner nearer the wall and driving closes in on it, so the DWA refused every motion for
    ever. Its wall escape may come to ``wall_escape_padding`` of the walls: with the default
    0.02 m it leaves and arrives; with the escape no looser than the padding it stays pinned.
    (The escape from a knot, which a wall also starts after a whole cycle of recoveries, is off
    here: this is the wall escape alone.)"""
    cfg = NavigatorConfig()
    cfg = dataclasses.replace(cfg, dwa=dataclasses.replace(cfg.dwa, wall_escape_padding=escape),
                              recovery=dataclasses.replace(cfg.recovery, escape_clearance=0.0))
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT)
    core.set_map(occ)
    pose = np.array([-5.4623, 0.7392, math.radians(88.38)])  # the recorded pose
    core.step(pose, 0.0, 0.0, 0.0)
    r = SimRobot(core, pose, log=[])
    goal = np.array([-7.74575, 3.20313, math.pi])  # loader3, behind the robot to the west
    core.set_goal(goal, "g", 0.0)
    res = simulate([r], SLIM_BLOCKAGE_WALLS, 120.0)
    assert res["contact_ticks"] == 0 and res["min_wall_gap"] > 0.03
    if escape < cfg.dwa.footprint_padding:
        assert_arrived(r, goal)
        assert res["time"] < 60.0
    else:
        assert core.status.state != NavState.SUCCEEDED
        assert np.hypot(*(r.pose[:2] - [-5.4623, 0.7392])) < 0.1


@pytest.mark.parametrize("escape", [0.15, 0.0])
def test_a_robot_dithering_parallel_to_a_wall_escapes_it(occ, escape):
    """Found in a 20-robot shift (seed 1, Srobot5 from 951 s, alone for most of it): a robot
    stopped parallel to the blockage's east wall, 0.046 m from it, inside ``footprint_padding``.
    The DWA admitted only turns of +-0.017 and +-0.034 rad/s, so it dithered on the spot with
    "ok" commands (the wall escape runs only when the DWA finds no motion) and the recoveries
    could not move it: it stood 849 s, to the end of the shift. After a whole cycle of
    recoveries a wall within ``escape_clearance`` counts as a knot, and the escape
    (recovery.escape_command) takes it out of the padding; with ``escape_clearance`` 0 it stays
    where it is."""
    cfg = NavigatorConfig()
    cfg = dataclasses.replace(cfg, robot_index=5, recovery=dataclasses.replace(
        cfg.recovery, escape_clearance=escape))
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT)
    core.set_map(occ)
    pose = np.array([-3.5573, -2.5108, 1.7434])  # the recorded pose
    core.step(pose, 0.0, 0.0, 0.0)
    r = SimRobot(core, pose, log=[])
    goal = np.array([-7.74575, 3.20313, math.pi])  # loader4, round the blockage's south end
    core.set_goal(goal, "g", 0.0)
    res = simulate([r], SLIM_BLOCKAGE_WALLS, 120.0)
    assert res["contact_ticks"] == 0 and res["min_wall_gap"] > 0.02
    if escape:
        assert_arrived(r, goal)
    else:
        assert core.status.state != NavState.SUCCEEDED and core.status.recoveries >= 5
        assert np.hypot(*(r.pose[:2] - pose[:2])) < 0.5


# ------------------------------------------------------------------ obstacles (exact shortcuts)
def test_static_obstacle_window_from_its_cache_equals_filtering_the_whole_boundary(occ):
    r = make_robot(occ, [0.0, 0.0, math.pi], log=False)
    core = r.core
    boundary = core.costmap.boundary_points()
    win = core.cfg.obstacle_window
    rng = np.random.default_rng(7)
    pose = np.array([0.0, 0.0, 0.0])
    renewals = 0
    for _ in range(400):  # a random walk: small steps, and jumps past the cache's margin
        pose[:2] += rng.normal(0.0, 0.35 if rng.random() < 0.9 else 2.0, 2)
        pose[:2] = np.clip(pose[:2], [-8.0, -4.5], [9.0, 9.0])
        before = core._obs._centre
        got = core._obs.static_near(pose)
        renewals += core._obs._centre is not before
        m = (np.abs(boundary[:, 0] - pose[0]) < win) & (np.abs(boundary[:, 1] - pose[1]) < win)
        assert np.array_equal(got, boundary[m])  # the same points in the same order
    assert 20 < renewals < 400  # the cache was both reused and renewed


def test_navigators_of_one_process_share_the_static_costmaps_of_one_map(occ):
    """The 50 navigators of a group process get the same map: its static costmaps are built once
    (static_costmaps), equal to building them, read-only, and a different map gets its own."""
    sites = [((-5.0, -2.0, 0.0), [(-4.0, -2.0), (-4.0, -1.0)])]
    a = NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT, sites)
    b = NavigatorCore(dataclasses.replace(NavigatorConfig(), robot_index=2), WAFFLE_FOOTPRINT,
                      sites)
    copy = OccupancyMap(occ.data.copy(), occ.resolution, np.array(occ.origin, dtype=float))
    a.set_map(occ)
    b.set_map(copy)  # another message with the same content
    assert a.costmap is b.costmap and a._plan_cm is b._plan_cm
    cfg = NavigatorConfig()
    built = build_costmap(occ, cfg.costmap)
    planning = add_keepout(built, a._holding.avoid, cfg.holding.workstation_keepout_radius,
                           cfg.holding.workstation_keepout_cost)
    np.testing.assert_array_equal(a.costmap.costs, built.costs)
    np.testing.assert_array_equal(a.costmap.obstacle_distance, built.obstacle_distance)
    np.testing.assert_array_equal(a._plan_cm.costs, planning.costs)
    assert (a._plan_cm.costs != a.costmap.costs).any()  # the keep-out discs are there
    with pytest.raises(ValueError):
        a.costmap.costs[0, 0] = 0
    with pytest.raises(ValueError):
        a._plan_cm.obstacle_distance[0, 0] = 0.0
    other = copy.data.copy()
    other[occ.height // 2, occ.width // 2] = 100
    c = NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT, sites)
    c.set_map(OccupancyMap(other, occ.resolution, np.array(occ.origin, dtype=float)))
    assert c.costmap is not a.costmap
    assert c.costmap.costs[occ.height // 2, occ.width // 2] == 254
    d = NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT)  # no keep-out discs
    d.set_map(occ)
    assert d.costmap is a.costmap and d._plan_cm is d.costmap


# ------------------------------------------------------------------ congestion
@pytest.mark.parametrize("limit", [3, 0])
def test_a_robot_that_sees_a_queue_standing_in_the_corridor_ahead_holds_back_in_the_open(
        occ, limit):
    """The congestion rule (swarm_nav.holding.path_congested): a robot on its way down the
    corridor of slim_blockage's workstations to loader1 sees three robots standing in the lane
    ahead. It turns back to a staging point in the open, right of the blockage, instead of
    pressing into them; with ``congestion_limit`` 0 it drives on into the corridor."""
    cfg = NavigatorConfig()
    cfg = dataclasses.replace(cfg, holding=dataclasses.replace(cfg.holding,
                                                               congestion_limit=limit))
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT)
    core.set_map(occ)
    start = np.array([-6.6, 6.6, -math.pi / 2])
    core.step(start, 0.0, 0.0, 0.0)
    core.set_goal(LOADER1, "g", 0.0)
    me = SimRobot(core, start, log=[])
    queue = [SimRobot(None, np.array([x, y, -math.pi / 2]))
             for x, y in ((-6.7, 4.4), (-6.2, 3.7), (-7.2, 3.4))]
    targets = []
    simulate([me, *queue], SLIM_BLOCKAGE_WALLS, 12.0, until_done=False,
             on_tick=lambda t, rs: targets.append(core._target().copy()))
    open_ = [t for t in targets if core.costmap.distance_at(t[None, :])[0]
             >= cfg.holding.staging_wall_clearance]
    if limit:
        assert core.status.state == NavState.HOLDING
        assert open_, "never held back in the open"
        assert me.pose[1] > 4.8  # did not press on into the queue
    else:
        assert not open_ and core.status.state == NavState.DRIVING


@pytest.mark.parametrize(("reached", "held", "held_back"),
                         [(False, 299.0, True), (False, 300.0, False), (True, 300.0, True)])
def test_a_starving_robot_is_held_back_by_congestion_no_more(occ, reached, held, held_back):
    """``starvation_time`` 300 s (the default): the scene of the test above, for a robot that
    has held that long for its goal. If it has reached no goal since its navigator started, it
    presses on into the corridor as the robots inside it do; one that has reached a goal, or has
    held less, holds back. (The holding time and whether a goal was reached are set directly:
    the rule reads nothing else.)"""
    cfg = NavigatorConfig()
    assert cfg.holding.starvation_time == 300.0
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT)
    core.set_map(occ)
    start = np.array([-6.6, 6.6, -math.pi / 2])
    core.step(start, 0.0, 0.0, 0.0)
    core.set_goal(LOADER1, "g", 0.0)
    core._holding.reached_goal, core._holding_time = reached, held
    me = SimRobot(core, start, log=[])
    queue = [SimRobot(None, np.array([x, y, -math.pi / 2]))
             for x, y in ((-6.7, 4.4), (-6.2, 3.7), (-7.2, 3.4))]
    simulate([me, *queue], SLIM_BLOCKAGE_WALLS, 3.0, until_done=False)
    assert (core.status.state == NavState.HOLDING) is held_back
    assert (core._holding.target is not None) is held_back
    assert (me.pose[1] < start[1] - 0.3) is not held_back  # drove on down the corridor


QUEUE_OF_3 = ((-6.7, 4.4), (-6.2, 3.7), (-7.2, 3.4))  # the tests above
QUEUE_OF_6 = ((-6.3, 5.7), (-7.1, 5.2), (-6.2, 4.8), (-7.0, 4.3), (-6.3, 3.9), (-7.2, 3.5))


def _starving_robot_before_a_queue(occ, cfg, spots, reached=False, held=300.0):
    """A robot that has reached no goal (``reached``) and held 300 s (``held``), on its way down
    the corridor to loader1 (the tests above), with robots standing at ``spots``; after 3 s:
    its core and its pose."""
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT)
    core.set_map(occ)
    start = np.array([-6.6, 6.6, -math.pi / 2])
    core.step(start, 0.0, 0.0, 0.0)
    core.set_goal(LOADER1, "g", 0.0)
    core._holding.reached_goal, core._holding_time = reached, held
    me = SimRobot(core, start, log=[])
    queue = [SimRobot(None, np.array([x, y, -math.pi / 2])) for x, y in spots]
    simulate([me, *queue], SLIM_BLOCKAGE_WALLS, 3.0, until_done=False)
    return core, me.pose


@pytest.mark.parametrize(("spots", "held_back"), [(QUEUE_OF_3, False), (QUEUE_OF_6, True)])
def test_a_starving_robot_is_held_back_by_a_long_queue(occ, spots, held_back):
    """``starvation_congestion_limit`` 6 (the default): a starving robot (the test above) that
    sees 6 robots standing in the corridor ahead holds back all the same; 3 do not hold it."""
    cfg = NavigatorConfig()
    assert cfg.holding.starvation_congestion_limit == 6
    core, pose = _starving_robot_before_a_queue(occ, cfg, spots)
    assert (core.status.state == NavState.HOLDING) is held_back
    assert (pose[1] < 6.6 - 0.3) is not held_back  # drove on down the corridor


@pytest.mark.parametrize(("patience", "held", "held_back"),
                         [(0.0, 500.0, True), (120.0, 119.0, True), (120.0, 120.0, False)])
def test_an_impatient_robot_is_held_back_by_congestion_no_more(occ, patience, held, held_back):
    """``patience_time`` (off by default): the scene of the tests above, for a robot that has
    reached goals before. Once it has held ``patience_time`` for its goal it presses on past
    a queue of 3, as a starving robot does; with the rule off, or before, it holds back."""
    cfg = NavigatorConfig()
    assert cfg.holding.patience_time == 0.0
    cfg = dataclasses.replace(cfg, holding=dataclasses.replace(cfg.holding,
                                                               patience_time=patience))
    core, pose = _starving_robot_before_a_queue(occ, cfg, QUEUE_OF_3, reached=True, held=held)
    assert (core.status.state == NavState.HOLDING) is held_back
    assert (pose[1] < 6.6 - 0.3) is not held_back  # drove on down the corridor


def test_a_starving_robot_keeps_the_congestion_rule_off_when_it_is_off(occ):
    """``congestion_limit`` 0 (``--coordination centralized``) turns the rule off for every
    robot: ``starvation_congestion_limit`` does not turn it on for a starving one."""
    cfg = NavigatorConfig()
    cfg = dataclasses.replace(cfg, holding=dataclasses.replace(cfg.holding, congestion_limit=0))
    core, _ = _starving_robot_before_a_queue(occ, cfg, QUEUE_OF_6)
    assert core.status.state != NavState.HOLDING


def _loaders():
    """slim_blockage's holding sites, their kinds and the workstations by name."""
    poi = poi_for_world(WORLDS / "slim_blockage.world")
    ws = {w.name: np.asarray(w.pose, dtype=float) for w in poi.workstations}
    return holding_sites_from_poi(poi), site_kinds_from_poi(poi), ws


def test_workstations_of_one_kind_share_their_name_before_the_number():
    assert [workstation_kind(n) for n in ("loader3", "loader_12", "rack-2", "cnc 4")] == [
        "loader", "loader", "rack", "cnc"]
    assert [workstation_kind(n) for n in ("packing", "assembly_west", "7")] == [
        "packing", "assembly_west", "7"]
    assert site_kinds_from_poi(None) == []
    sites, kinds, _ = _loaders()
    assert kinds == ["loader"] * 6 and len(sites) == 6
    with pytest.raises(ValueError, match="site_kinds: 2 kinds for 6 holding sites"):
        NavigatorCore(NavigatorConfig(), WAFFLE_FOOTPRINT, sites, ["loader", "loader"])


@pytest.mark.parametrize("kinds", ["poi", "none", "other", "off"])
def test_a_holding_robot_takes_the_free_workstation_beside_its_taken_goal(occ, kinds):
    """loader4 and loader5 are taken by robots that stay; loader3, 2.23 m below loader4, is
    free. A robot sent to loader4 holds at loader4's spot (the gap toward loader3) and, seeing
    loader3 free within ``swap_range`` (2.5 m), docks there instead: SUCCEEDED, with loader3 as
    the goal in its status and a note naming both. Without kinds (``kinds`` "none"), with every
    loader but loader4 of another kind ("other") or with ``swap_range`` 0 ("off") it holds for
    loader4, as docs/reference/contract.md#s5-navigation says."""
    sites, site_kinds, ws = _loaders()
    if kinds == "none":
        site_kinds = []
    elif kinds == "other":
        site_kinds = ["loader" if i == 3 else "unloader" for i in range(len(sites))]
    cfg = dataclasses.replace(NavigatorConfig(), robot_index=1)
    if kinds == "off":
        cfg = dataclasses.replace(cfg, holding=dataclasses.replace(cfg.holding, swap_range=0.0))
    core = NavigatorCore(cfg, WAFFLE_FOOTPRINT, sites, site_kinds)
    core.set_map(occ)
    start = np.array([-6.3, 5.0, -math.pi / 2])
    core.step(start, 0.0, 0.0, 0.0)
    core.set_goal(ws["loader4"], "g", 0.0)
    me = SimRobot(core, start, log=[])
    parked = [SimRobot(None, ws[n].copy()) for n in ("loader4", "loader5")]
    res = simulate([me, *parked], SLIM_BLOCKAGE_WALLS, 60.0, until_done=True)
    assert res["contact_ticks"] == 0 and res["min_separation"] > 0.05
    st = core.status
    if kinds == "poi":
        assert_arrived(me, ws["loader3"])
        assert st.goal_id == "g" and core.swaps == 1
        assert st.goal == pytest.approx(tuple(ws["loader3"]), abs=1e-9)
        assert st.reason == ("took the workstation at (-7.746, 0.973), free while the goal at "
                             "(-7.746, 3.203) was taken")
    else:
        assert st.state == NavState.HOLDING and core.swaps == 0, st
        assert st.goal == pytest.approx(tuple(ws["loader4"]), abs=1e-9)
        assert np.hypot(*(me.pose[:2] - ws["loader3"][:2])) > 0.6


def test_a_robot_that_took_another_workstation_and_came_back_to_its_own_reports_no_swap(occ):
    """The scene above; once the robot has taken loader3, a robot docks there and loader4's
    leaves: the robot takes loader4 back, and reaches its own goal without a note."""
    sites, site_kinds, ws = _loaders()
    core = NavigatorCore(dataclasses.replace(NavigatorConfig(), robot_index=1),
                         WAFFLE_FOOTPRINT, sites, site_kinds)
    core.set_map(occ)
    start = np.array([-6.3, 5.0, -math.pi / 2])
    core.step(start, 0.0, 0.0, 0.0)
    core.set_goal(ws["loader4"], "g", 0.0)
    me = SimRobot(core, start, log=[])
    on4, on5 = SimRobot(None, ws["loader4"].copy()), SimRobot(None, ws["loader5"].copy())

    def on_tick(t, robots):
        if core.swaps == 1 and np.allclose(on4.pose, ws["loader4"]):
            on4.pose = ws["loader3"].copy()  # the one on loader4 "moves" onto loader3, once
    res = simulate([me, on4, on5], SLIM_BLOCKAGE_WALLS, 90.0, until_done=True, on_tick=on_tick)
    assert res["contact_ticks"] == 0
    assert core.swaps == 2
    assert_arrived(me, ws["loader4"])
    assert core.status.reason == ""


@pytest.mark.parametrize("came_from_loader3", [True, False])
def test_a_holding_robot_never_takes_the_workstation_it_came_from(occ, came_from_loader3):
    """A robot docked at loader3 and is sent on to loader4, which is taken (loader2 and loader5
    too). It does not turn back to loader3, free behind it: that would be a task without a
    trip. The same robot, standing there without having reached loader3 as a goal, takes it."""
    sites, site_kinds, ws = _loaders()
    core = NavigatorCore(dataclasses.replace(NavigatorConfig(), robot_index=1),
                         WAFFLE_FOOTPRINT, sites, site_kinds)
    core.set_map(occ)
    start = np.array([-6.6, ws["loader3"][1], math.pi])
    core.step(start, 0.0, 0.0, 0.0)
    me = SimRobot(core, start, log=[])
    parked = [SimRobot(None, ws[n].copy()) for n in ("loader2", "loader4", "loader5")]
    core.set_goal(ws["loader3"] if came_from_loader3 else ws["loader4"], "g1", 0.0)
    docked = []

    def on_tick(t, robots):
        if core.status.goal_id == "g1" and core.status.state == NavState.SUCCEEDED:
            docked.append(me.pose.copy())
            if came_from_loader3:
                core.set_goal(ws["loader4"], "g2", t)
    res = simulate([me, *parked], SLIM_BLOCKAGE_WALLS, 90.0, until_done=False, on_tick=on_tick)
    assert res["contact_ticks"] == 0
    assert docked and np.hypot(*(docked[0][:2] - ws["loader3"][:2])) <= 0.25
    if came_from_loader3:
        assert core.status.goal_id == "g2"
        assert core.status.state == NavState.HOLDING and core.swaps == 0, core.status
    else:
        assert_arrived(me, ws["loader3"])
        assert core.swaps == 1


# ------------------------------------------------------------------ knots
KNOT = {  # 100 robots on slim_blockage, seed 0, at 300 s: x, y [m], yaw [deg], goal loader
    64: (0.87, 6.98, -14, 6), 32: (1.02, 6.74, 150, 6), 43: (1.29, 6.44, 132, 4),
    34: (1.01, 6.25, 116, 6)}


@pytest.mark.parametrize("escape", [0.15, 0.0])
def test_robots_packed_body_to_body_in_the_open_escape_the_knot(occ, escape):
    """Found in a 30-minute shift of 100 robots: these four stood body to body (gaps of 5 cm,
    the DWA's padding) in the open hall from 177 s to the end, cycling nav2's recoveries and
    yields. No arc of the DWA's horizon keeps the padding, nor do back-up and spin, and a
    yield that cannot start its retreat only waited where it stood. With the escape
    (``escape_clearance`` 0.15 m) each robot slides out of the knot and goes its way; without
    it (0) the knot holds."""
    poi = poi_for_world(WORLDS / "slim_blockage.world")
    sites = holding_sites_from_poi(poi)
    loaders = {int(w.name[6:]): np.asarray(w.pose, dtype=float) for w in poi.workstations}
    robots = []
    for i, (x, y, deg, loader) in KNOT.items():
        cfg = NavigatorConfig()
        cfg = dataclasses.replace(cfg, robot_index=i, recovery=dataclasses.replace(
            cfg.recovery, escape_clearance=escape))
        core = NavigatorCore(cfg, WAFFLE_FOOTPRINT, sites)
        core.set_map(occ)
        pose = np.array([x, y, math.radians(deg)])
        core.step(pose, 0.0, 0.0, 0.0)
        core.set_goal(loaders[loader], f"g{i}", 0.0)
        robots.append(SimRobot(core, pose, log=None))
    res = simulate(robots, SLIM_BLOCKAGE_WALLS, 150.0, until_done=False)
    assert res["contact_ticks"] == 0 and res["min_separation"] > 0.02
    left = [float(np.hypot(*(r.pose[:2] - KNOT[i][:2])))
            for i, r in zip(KNOT, robots, strict=True)]
    if escape > 0:
        assert min(left) > 3.0, left  # every one on its way to the corridor, or there
    else:
        assert sorted(left)[1] < 0.5, left  # two or more still in the knot


@pytest.mark.parametrize(("fixed", "patience", "arrives"),
                         [(True, 0.0, True), (False, 0.0, False), (False, 10.0, True)])
def test_a_robot_waiting_for_the_next_workstation_is_no_queue_for_this_one(occ, fixed, patience,
                                                                          arrives, monkeypatch):
    """Found in 30-minute shifts of 100 robots (16 robots without a task, every one sent to
    loader1, 2 or 3): loader4's holding spot is 1.115 m from loader3, within ``crowd_radius``
    and nearer than loader3's own spot (1.179 m). A robot waiting there for loader4 (taken)
    made loader3 "crowded" for the robot at loader3's spot, which then held on with loader3
    free. Robots on another workstation's spot no longer count (``holding.goal_crowded``'s
    ``elsewhere``); counted (``fixed`` False), loader3 stays free and unreached, unless the
    robot is impatient (``patience_time`` 10 s: it holds 10 s for the "queue", then goes in)."""
    if not fixed:
        monkeypatch.setattr(HoldingBehaviour, "_other_sites", lambda self, goal_xy: None)
    poi = poi_for_world(WORLDS / "slim_blockage.world")
    sites = holding_sites_from_poi(poi)
    ws = {w.name: (np.asarray(w.pose, dtype=float), np.asarray(w.holding, dtype=float))
          for w in poi.workstations}
    robots = []
    for i, (pose, goal) in enumerate([
            (ws["loader4"][0], None),                                           # on loader4
            (np.array([*ws["loader4"][1][0], math.pi / 2]), ws["loader4"][0]),  # waits for it
            (np.array([*ws["loader3"][1][0], math.pi / 2]), ws["loader3"][0])], start=1):
        base = NavigatorConfig()
        cfg = dataclasses.replace(base, robot_index=i, holding=dataclasses.replace(
            base.holding, patience_time=patience))
        core = NavigatorCore(cfg, WAFFLE_FOOTPRINT, sites)
        core.set_map(occ)
        core.step(pose, 0.0, 0.0, 0.0)
        if goal is not None:
            core.set_goal(goal, f"g{i}", 0.0)
        robots.append(SimRobot(core, pose.copy(), log=None))
    res = simulate(robots, SLIM_BLOCKAGE_WALLS, 60.0, until_done=False)
    assert res["contact_ticks"] == 0 and res["min_separation"] > 0.02
    waiting, third = robots[1], robots[2]
    assert waiting.core.status.state == NavState.HOLDING  # loader4 stays taken
    assert np.hypot(*(waiting.pose[:2] - ws["loader4"][1][0])) < 0.4
    if arrives:
        assert_arrived(third, ws["loader3"][0])
    else:
        assert third.core.status.state == NavState.HOLDING
        assert np.hypot(*(third.pose[:2] - ws["loader3"][1][0])) < 0.4
