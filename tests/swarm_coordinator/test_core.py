"""The coordinator's pure core: first come first served, waiting spots, hand-over, order."""

import itertools
import random

import pytest

from swarm_common.coordination import (
    Request,
    check_reservations,
    decode_assignment,
    decode_request,
    encode_assignment,
    encode_request,
)
from swarm_common.stamps import NS_PER_S
from swarm_coordinator.core import (
    CoordinatorConfig,
    CoordinatorCore,
    Spot,
    Station,
    spots_from_poi,
)

T = NS_PER_S  # 1 s
STATIONS = [Station("A", (0.0, 0.0, 0.0)), Station("B", (10.0, 0.0, 0.0))]
SPOTS = [Spot("A.0", (0.0, -1.0), "A"), Spot("B.0", (10.0, -1.0), "B"),
         Spot("park1", (5.0, 5.0)), Spot("park2", (9.0, 5.0)), Spot("park3", (1.0, 5.0))]


def make_core(routes: dict[str, list[str]], robots=None) -> CoordinatorCore:
    its = {ns: itertools.cycle(stops) for ns, stops in routes.items()}
    return CoordinatorCore(robots or list(routes), STATIONS, SPOTS, lambda ns: next(its[ns]),
                           CoordinatorConfig(period_ns=T // 10, handover_ticks=2), epoch="e1")


def ready(ns, t=0, seq=1):
    return Request(ns, seq, "ready", t)


def done(ns, target, t, seq, outcome="succeeded"):
    return Request(ns, seq, "done", t, outcome=outcome, target=target)


def reservations(events):
    return [e.values() for e in events if e.kind == "reservation"]


def test_first_come_first_served_in_robot_order_and_waiting_spots():
    core = make_core({"r1": ["A"], "r2": ["A"], "r3": ["A"], "r4": ["A"]})
    out, events = core.handle([ready("r3"), ready("r1"), ready("r4"), ready("r2")])
    by = {a.robot: a for a in out}
    assert by["r1"].kind == "go" and by["r1"].target == "A"
    # the others wait: A's own holding spot first, then the parking spots nearest A
    assert [by[r].kind for r in ("r2", "r3", "r4")] == ["wait"] * 3
    assert [by[r].target for r in ("r2", "r3", "r4")] == ["A.0", "park3", "park1"]
    assert all(by[r].waits_for == "A" for r in ("r2", "r3", "r4"))
    assert core.queue("A") == ("r2", "r3", "r4")
    assert core.holder_of("workstation:A") == "r1"
    assert len({a.target for a in out}) == 4  # no two robots to one place
    assert check_reservations(reservations(events)) == []


def test_a_batch_gives_the_same_answers_in_any_arrival_order():
    reqs = [ready(f"r{i}") for i in range(1, 6)]
    answers = set()
    for seed in range(5):
        random.Random(seed).shuffle(reqs)
        core = make_core({f"r{i}": ["A", "B"] for i in range(1, 6)})
        out, _ = core.handle(reqs)
        answers.add(tuple(sorted(encode_assignment(a) for a in out)))
    assert len(answers) == 1


def test_done_releases_and_hands_over_one_tick_later_before_the_answer():
    core = make_core({"r1": ["A", "B"], "r2": ["A", "B"]})
    core.handle([ready("r1"), ready("r2")])
    t = 40 * T
    out, events = core.handle([done("r1", "A", t, seq=2)])
    # the hand-over to r2 comes first, stamped one tick after the release
    assert [(a.robot, a.kind, a.target, a.reply_to) for a in out] == [
        ("r2", "go", "A", 0), ("r1", "go", "B", 2)]
    assert out[0].stamp_ns == t + 2 * T // 10 and out[1].stamp_ns == t
    res = [(e["robot"], e["action"], e["resource"], e["t"]) for e in reservations(events)]
    assert res == [("r1", "release", "workstation:A", "40.000000000"),
                   ("r2", "release", "spot:A.0", "40.200000000"),
                   ("r2", "reserve", "workstation:A", "40.200000000"),
                   ("r1", "reserve", "workstation:B", "40.000000000")]
    tasks = [e.values() for e in events if e.kind == "task"]
    assert tasks == [{"robot": "r1", "t": "40.000000000", "epoch": "e1", "workstation": "A",
                      "t_start": "0.000000000", "duration_s": "40.000"}]


def test_service_time_holds_the_workstation_and_stamps_the_next_goals_after_it():
    its = {ns: itertools.cycle(["A", "B"]) for ns in ("r1", "r2")}
    core = CoordinatorCore(["r1", "r2"], STATIONS, SPOTS, lambda ns: next(its[ns]),
                           CoordinatorConfig(period_ns=T // 10, handover_ticks=2,
                                             service_time_ns=15 * T), epoch="e1")
    _, first = core.handle([ready("r1"), ready("r2")])
    t = 40 * T
    out, events = core.handle([done("r1", "A", t, seq=2)])
    # r1 stays docked 15 s: A goes to r2 then (one hand-over later), r1 leaves for B then
    assert [(a.robot, a.kind, a.target, a.stamp_ns) for a in out] == [
        ("r2", "go", "A", t + 15 * T + 2 * T // 10), ("r1", "go", "B", t + 15 * T)]
    res = [(e["robot"], e["action"], e["resource"], e["t"]) for e in reservations(events)]
    assert res[0] == ("r1", "release", "workstation:A", "55.000000000")
    # the task ended at the arrival; the next one starts when the robot leaves
    tasks = [e.values() for e in events if e.kind == "task"]
    assert [(e["t"], e["duration_s"]) for e in tasks] == [("40.000000000", "40.000")]
    assert out[1].task_start_ns == t + 15 * T
    assert check_reservations(reservations(first + events)) == []
    # a goal that failed has no service: the workstation frees at once
    out, _ = core.handle([done("r1", "B", 80 * T, seq=3, outcome="failed")])
    assert out[-1].stamp_ns == 80 * T


def test_a_failed_goal_releases_without_counting_a_task():
    core = make_core({"r1": ["A", "B"]})
    core.handle([ready("r1")])
    out, events = core.handle([done("r1", "A", 5 * T, seq=2, outcome="failed")])
    assert [e.kind for e in events if e.kind == "task"] == []
    assert core.holder_of("workstation:A") is None
    assert out[0].target == "B"


def test_a_resent_request_gets_the_same_answer_again():
    core = make_core({"r1": ["A", "B"]})
    first, _ = core.handle([ready("r1")])
    again, events = core.handle([ready("r1")])
    assert again == first and events == []
    # copies within one batch are answered once
    assert len(make_core({"r1": ["A"]}).handle([ready("r1"), ready("r1")])[0]) == 1


def test_a_new_core_adopts_what_robots_report_and_queues_late_claims():
    core = make_core({"r1": ["B"], "r2": ["B"], "r3": ["A"]})
    # r1 drives to A (reserved by the old coordinator), r2 waits at B.0 for B
    out, events = core.handle([
        Request("r1", 0, "report", 50 * T, holds=("workstation:A",)),
        Request("r2", 0, "report", 50 * T, holds=("spot:B.0",), waits_for="B", since_ns=T),
    ])
    assert core.holder_of("workstation:A") == "r1"
    assert core.holder_of("spot:B.0") is None  # B was free: r2 got it at once
    assert core.holder_of("workstation:B") == "r2"
    assert [(a.robot, a.kind, a.target) for a in out] == [("r2", "go", "B")]
    # r3 claims A too (its report came late): it is sent to wait for A instead
    out, _ = core.handle([Request("r3", 0, "report", 51 * T, holds=("workstation:A",))])
    assert [(a.robot, a.kind, a.waits_for) for a in out] == [("r3", "wait", "A")]
    assert check_reservations(reservations(events)) == []


def test_a_new_core_takes_over_every_report_of_a_batch_before_answering():
    """A restarted coordinator's first batch: a ``done`` stamped before another robot's report
    is answered only after that report is taken over (robot by robot, r1 got A, for which r3
    had waited since 10 s; in a 10-robot run a robot got the spot another reported standing
    on)."""
    core = make_core({"r1": ["A"], "r2": ["B"], "r3": ["B"]})
    out, events = core.handle([
        Request("r1", 4, "done", 40 * T, outcome="succeeded", target="A",
                holds=("workstation:A",)),  # finished at A during the outage, next: A again
        Request("r2", 0, "report", 50 * T, holds=("workstation:B",)),
        Request("r3", 0, "report", 50 * T, holds=("spot:A.0",), waits_for="A", since_ns=10 * T),
    ])
    # r3 has waited for A since 10 s: A goes to it, and r1, in line now, waits on A.0
    assert core.holder_of("workstation:A") == "r3"
    assert core.holder_of("spot:A.0") == "r1"
    assert core.holder_of("workstation:B") == "r2"
    by = {a.robot: a for a in out}
    assert (by["r3"].kind, by["r3"].target) == ("go", "A")
    assert (by["r1"].kind, by["r1"].target, by["r1"].waits_for) == ("wait", "A.0", "A")
    assert check_reservations(reservations(events)) == []
    spots = [a.target for a in out if a.kind == "wait"]
    assert len(spots) == len(set(spots))


def test_a_new_core_queues_every_waiter_of_a_batch_before_handing_over():
    """A workstation free at the restart goes to the robot that has waited for it longest,
    whatever order their reports come in (robot by robot, the first report's robot got it: 10
    robots, seed 2, coordinator killed at 180 s and restarted at 210 s: loader5 went to Srobot1,
    parked in the hall since 124.5 s, over Srobot4 on loader5's holding spot since 105 s, and
    stood idle for the 74 s Srobot1 took to come)."""
    core = make_core({"r1": ["A"], "r2": ["A"], "r3": ["B"]})
    out, events = core.handle([
        Request("r1", 0, "report", 50 * T, holds=("spot:park1",), waits_for="A",
                since_ns=20 * T),
        Request("r2", 0, "report", 50 * T, holds=("spot:A.0",), waits_for="A", since_ns=10 * T),
        Request("r3", 0, "report", 50 * T, holds=("workstation:B",)),
    ])
    assert core.holder_of("workstation:A") == "r2"
    assert core.queue("A") == ("r1",)
    by = {a.robot: a for a in out}
    assert (by["r2"].kind, by["r2"].target) == ("go", "A")
    assert "r1" not in by or by["r1"].kind == "wait"
    assert check_reservations(reservations(events)) == []


def test_check_reservations_finds_double_holders():
    ev = [{"robot": "r1", "action": "reserve", "resource": "workstation:A", "epoch": "1"},
          {"robot": "r2", "action": "reserve", "resource": "workstation:A", "epoch": "1"},
          {"robot": "r2", "action": "reserve", "resource": "workstation:A", "epoch": "2"}]
    assert check_reservations(ev) == ["workstation:A reserved by r2 while r1 holds it"]


def test_long_random_run_never_double_books():
    rng = random.Random(3)
    robots = [f"r{i}" for i in range(1, 9)]
    routes = {ns: itertools.cycle(rng.sample(["A", "B"] * 3, 6)) for ns in robots}
    parking = [Spot(f"park{k}", (float(k), 5.0)) for k in range(1, 9)]  # a spot per robot
    core = CoordinatorCore(robots, STATIONS, SPOTS[:2] + parking, lambda ns: next(routes[ns]))
    out, events = core.handle([ready(ns) for ns in robots])
    all_events = list(events)
    current = {a.robot: a for a in out}
    seq = dict.fromkeys(robots, 1)
    t = 0
    for _ in range(200):
        t += T
        goers = [ns for ns, a in current.items() if a.kind == "go"]
        ns = rng.choice(goers)
        seq[ns] += 1
        out, events = core.handle([done(ns, current[ns].target, t, seq[ns])])
        all_events += events
        current.update({a.robot: a for a in out})
        places = [(a.kind, a.target) for a in current.values()]
        assert len(set(places)) == len(places)
    assert check_reservations(reservations(all_events)) == []


def test_spots_from_poi_on_slim_blockage():
    from swarm_common.paths import WORLDS_DIR
    from swarm_scene.poi import load_poi

    spots = spots_from_poi(load_poi(WORLDS_DIR / "slim_blockage.yaml"),
                           [[0.0, 0.0, 3.14], [1.0, 0.0, 3.14]])
    assert [s.id for s in spots][:2] == ["loader1.0", "loader2.0"]
    assert [s.id for s in spots][-2:] == ["park1", "park2"]
    hold = spots[0]
    assert hold.near == "loader1" and hold.yaw == pytest.approx(1.5707963, abs=1e-6)


def test_the_contract_round_trips_and_names_bad_keys():
    from swarm_common.coordination import ContractError

    req = Request("Srobot2", 7, "done", 12 * T + 5, "succeeded", "loader3",
                  ("workstation:loader3",), "", 0, 3 * T)
    assert decode_request(encode_request(req)) == req
    a = decode_assignment(encode_assignment(
        decode_assignment('{"robot":"r","seq":1,"reply_to":0,"kind":"go","target":"A",'
                          '"x":1,"y":2,"yaw":0.5,"stamp":"1.000000000"}')))
    assert a.pose == (1.0, 2.0, 0.5) and a.stamp_ns == T
    with pytest.raises(ContractError, match="kind"):
        decode_request('{"robot":"r","seq":1,"kind":"hello","stamp":"0.000000000"}')
    with pytest.raises(ContractError, match="stamp"):
        decode_request('{"robot":"r","seq":1,"kind":"ready","stamp":"1.5"}')
    with pytest.raises(ContractError, match="x"):
        decode_assignment('{"robot":"r","seq":1,"reply_to":0,"kind":"go","target":"A",'
                          '"x":NaN,"y":2,"yaw":0,"stamp":"1.000000000"}')



def test_the_next_in_line_moves_up_to_the_freed_holding_spot():
    core = make_core({"r1": ["A", "B"], "r2": ["A", "B"], "r3": ["A", "B"]})
    _, first = core.handle([ready("r1"), ready("r2"), ready("r3")])  # r2 at A.0, r3 parked
    out, events = core.handle([done("r1", "A", 40 * T, seq=2)])
    events = first + events
    assert [(a.robot, a.kind, a.target, a.stamp_ns) for a in out] == [
        ("r2", "go", "A", 40 * T + 2 * T // 10),
        ("r3", "wait", "A.0", 40 * T + 2 * T // 10),
        ("r1", "go", "B", 40 * T)]
    assert core.holder_of("spot:A.0") == "r3" and core.holder_of("spot:park3") is None
    assert check_reservations(reservations(events)) == []


# ------------------------------------------------------------------ the scheduler (nearest-free)
LOADERS = [Station("loader1", (0.0, 0.0, 0.0)), Station("loader2", (0.0, 4.0, 0.0)),
           Station("loader3", (0.0, 8.0, 0.0))]
LOADER_SPOTS = [Spot("loader1.0", (1.0, 0.0), "loader1"), Spot("wait1", (2.0, 4.0)),
                Spot("park1", (10.0, 0.0)), Spot("park2", (10.0, 4.0))]


def scheduler(routes, assignment="nearest-free", start_xy=None, silence_s=0.0):
    its = {ns: itertools.cycle(stops) for ns, stops in routes.items()}
    cfg = CoordinatorConfig(period_ns=T // 10, handover_ticks=1, assignment=assignment,
                            silence_timeout_ns=round(silence_s * T))
    return CoordinatorCore(list(routes), LOADERS, LOADER_SPOTS, lambda ns: next(its[ns]), cfg,
                           epoch="e1", start_xy=start_xy)


def test_scheduler_sends_a_robot_to_the_nearest_free_workstation_of_the_kind():
    # all three want loader1; r1 gets it, r2 (nearest loader2) and r3 (nearest loader3) are
    # sent to the free loaders nearest to where they start, by the distance rule
    start = {"r1": (5.0, 0.0), "r2": (5.0, 9.0), "r3": (5.0, 3.0)}
    core = scheduler({ns: ["loader1"] for ns in start}, start_xy=start)
    out, events = core.handle([ready("r1"), ready("r2"), ready("r3")])
    by = {a.robot: (a.kind, a.target) for a in out}
    assert by == {"r1": ("go", "loader1"), "r2": ("go", "loader3"), "r3": ("go", "loader2")}
    assert check_reservations(reservations(events)) == []


def test_route_assignment_queues_for_the_route_workstation_as_before():
    start = {"r1": (5.0, 0.0), "r2": (5.0, 9.0)}
    core = scheduler({ns: ["loader1"] for ns in start}, assignment="route", start_xy=start)
    out, _ = core.handle([ready("r1"), ready("r2")])
    by = {a.robot: (a.kind, a.target) for a in out}
    assert by == {"r1": ("go", "loader1"), "r2": ("wait", "loader1.0")}


def test_scheduler_never_sends_a_robot_back_to_the_workstation_it_has_just_left():
    # r2 wanted loader2 (r1's) and was sent to loader3; its route's next stop is loader3, where
    # it stands: it is sent to the nearest free other loader (loader2 is free again by then)
    core = scheduler({"r1": ["loader2", "loader1"], "r2": ["loader2", "loader3"]},
                     start_xy={"r1": (0.0, 3.0), "r2": (0.0, 5.0)})
    out, _ = core.handle([ready("r1"), ready("r2")])
    assert {a.robot: a.target for a in out} == {"r1": "loader2", "r2": "loader3"}
    core.handle([done("r1", "loader2", 10 * T, seq=2)])  # r1 to loader1, loader2 free
    out, _ = core.handle([done("r2", "loader3", 20 * T, seq=2)])
    assert [(a.robot, a.kind, a.target) for a in out] == [("r2", "go", "loader2")]
    # with every other loader taken it goes where its route says, although it has just left it
    core.handle([done("r2", "loader2", 30 * T, seq=3)])  # route: loader2 -> nearest: loader3
    assert core.robots["r2"].workstation == "loader3"


def test_a_freed_workstation_nobody_queued_for_goes_to_a_waiter_of_its_kind():
    # four robots, three loaders: r4 waits (for loader1, its route's); loader3 frees first,
    # nobody queued for it: it goes to r4, queued for another loader of the kind
    start = {"r1": (0.0, 0.5), "r2": (0.0, 4.5), "r3": (0.0, 8.5), "r4": (5.0, 0.0)}
    core = scheduler({"r1": ["loader1", "loader2"], "r2": ["loader2", "loader1"],
                      "r3": ["loader3", "loader1"], "r4": ["loader1", "loader2"]},
                     start_xy=start)
    out, first = core.handle([ready(ns) for ns in start])
    by = {a.robot: (a.kind, a.target, a.waits_for) for a in out}
    assert by["r4"] == ("wait", "loader1.0", "loader1")
    out, events = core.handle([done("r3", "loader3", 30 * T, seq=2)])
    assert (out[0].robot, out[0].kind, out[0].target, out[0].reply_to) == \
        ("r4", "go", "loader3", 0)
    assert out[0].stamp_ns == 30 * T + T // 10  # one tick after the release
    assert core.holder_of("workstation:loader3") == "r4"
    # r3's next stop (loader1) is taken, every loader is: it waits
    assert (out[1].robot, out[1].kind) == ("r3", "wait")
    assert check_reservations(reservations(first + events)) == []


def test_of_the_waiters_of_the_kind_the_nearest_gets_the_free_workstation():
    # r4 and r5 queue for loader1 (r4 first, at loader1's holding spot (1, 0)); r5 waits at
    # wait1 (2, 4). loader3 (0, 8) frees with nobody queued for it: the nearer r5 gets it.
    start = {"r1": (0.0, 0.5), "r2": (0.0, 4.5), "r3": (0.0, 8.5), "r4": (5.0, 0.0),
             "r5": (5.0, 1.0)}
    core = scheduler({"r1": ["loader1", "loader2"], "r2": ["loader2", "loader3"],
                      "r3": ["loader3", "loader1"], "r4": ["loader1", "loader2"],
                      "r5": ["loader1", "loader2"]}, start_xy=start)
    out, _ = core.handle([ready(ns) for ns in start])
    by = {a.robot: (a.kind, a.target) for a in out}
    assert by["r4"] == ("wait", "loader1.0") and by["r5"] == ("wait", "wait1")
    assert core.queue("loader1") == ("r4", "r5")
    out, _ = core.handle([done("r3", "loader3", 30 * T, seq=2)])
    assert (out[0].robot, out[0].kind, out[0].target) == ("r5", "go", "loader3")
    assert core.queue("loader1") == ("r4", "r3")  # r4 keeps its place; r3 now queues too
    # loader1 frees: its own queue first, whoever is nearer
    out, _ = core.handle([done("r1", "loader1", 40 * T, seq=2)])
    assert (out[0].robot, out[0].target) == ("r4", "loader1")


def test_a_dead_robot_loses_its_workstation_to_the_next_waiter():
    start = {"r1": (0.0, 0.5), "r2": (0.0, 4.5), "r3": (0.0, 8.5), "r4": (5.0, 0.0)}
    core = scheduler({ns: ["loader1", "loader2", "loader3"] for ns in start}, start_xy=start)
    _, first = core.handle([ready(ns) for ns in start])
    waiting = [ns for ns in start if core.robots[ns].waits_for]
    assert len(waiting) == 1
    holder = core.holder_of("workstation:loader1")
    dead_at = 50 * T
    alive = lambda ns, t: not (ns == holder and t >= dead_at)  # noqa: E731
    other = next(ns for ns in start if ns not in (holder, *waiting))
    target = core.robots[other].workstation
    out, events = core.handle([done(other, target, 60 * T, seq=2)], alive=alive)
    assert core.holder_of("workstation:loader1") != holder
    assert core.holder_of("workstation:loader1") == waiting[0]
    assert core.expired == 1
    assert check_reservations(reservations(first + events)) == []
    # how it noticed: the supervisor's word, at the first batch after the death
    lapses = [e.values() for e in events if e.kind == "lapse"]
    assert [(v["robot"], v["workstation"], v["reason"], v["t"]) for v in lapses] == [
        (holder, "loader1", "dead", "60.000000000")]


def test_a_silent_robot_loses_its_workstation_after_the_timeout_and_its_task_still_counts():
    start = {"r1": (0.0, 0.5), "r2": (0.0, 4.5)}
    core = scheduler({"r1": ["loader1", "loader2"], "r2": ["loader2", "loader1"]},
                     start_xy=start, silence_s=100.0)
    core.handle([ready("r1"), ready("r2")])
    core.handle([done("r2", "loader2", 50 * T, seq=2)])  # r2 goes to loader1? taken: nearest
    assert core.holder_of("workstation:loader1") == "r1"
    core.handle([done("r2", core.robots["r2"].workstation or "loader3", 99 * T, seq=3)])
    assert core.holder_of("workstation:loader1") == "r1"  # 99 s: not yet
    core.handle([done("r2", core.robots["r2"].workstation or "loader3", 101 * T, seq=4)])
    assert core.holder_of("workstation:loader1") != "r1"  # 101 s: lapsed
    _, events = core.handle([done("r1", "loader1", 120 * T, seq=2)])
    tasks = [e for e in events if e.kind == "task" and e.robot == "r1"]
    assert len(tasks) == 1 and tasks[0].fields["workstation"] == "loader1"


def test_spots_from_poi_puts_the_worlds_waiting_spots_before_the_hall():
    from swarm_scene.poi import poi_for_world
    from swarm_scene.world import resolve_world

    poi = poi_for_world(resolve_world("slim_blockage"))
    near = spots_from_poi(poi, [[0.0, 0.0]])
    hall = spots_from_poi(poi, [[0.0, 0.0]], near=False)
    assert [s.id for s in near if s.id.startswith("wait")] == [f"wait{k}" for k in range(1, 10)]
    assert not [s for s in hall if s.id.startswith("wait")]
    assert near[-1].id == hall[-1].id == "park1"


# ---------------------------------------------------------------------------------- pipelined
L_STATIONS = [Station("L1", (0.0, 0.0, 0.0)), Station("L2", (10.0, 0.0, 0.0)),
              Station("U1", (5.0, 10.0, 0.0))]


def pipelined_core(routes, start_xy, **cfg):
    its = {ns: itertools.cycle(stops) for ns, stops in routes.items()}
    cfg = {"period_ns": T // 10, "policy": "pipelined", "eta_speed": 1.0,
           "dock_clear_ns": 5 * T, **cfg}
    return CoordinatorCore(list(routes), L_STATIONS, SPOTS, lambda ns: next(its[ns]),
                           CoordinatorConfig(**cfg), epoch="e1", start_xy=start_xy)


def test_pipelined_sends_a_robot_at_once_when_its_window_begins_on_its_arrival():
    """Four robots whose route says L1 (L2 is of its kind): r1 (1 m from L1) gets L1's first
    window [1, 6) s and goes; r2 (9 m away) is sent too although L1 is booked, for its window
    begins on its arrival; r3 (2 m from L1, 8 m from L2) is in line at L1 for [6, 11) s, ahead
    of r2 (it arrives first), and waits at the spot nearest L1; r4 (at L2) goes to L2. Only the
    spot is reserved. When r1 is done, r3, first in line, goes from its spot."""
    core = pipelined_core({ns: ["L1"] for ns in ("r1", "r2", "r3", "r4")},
                          {"r1": (1.0, 0.0), "r2": (-9.0, 0.0), "r3": (2.0, 0.0),
                           "r4": (10.0, 0.0)})
    out, events = core.handle([ready(ns) for ns in ("r1", "r2", "r3", "r4")])
    assert [(a.robot, a.kind, a.target, a.stamp_ns) for a in out] == [
        ("r1", "go", "L1", 0), ("r2", "go", "L1", 0), ("r3", "wait", "park3", 0),
        ("r4", "go", "L2", 0)]
    assert core.windows("L1") == [(1 * T, 6 * T, "r1"), (6 * T, 11 * T, "r3"),
                                  (11 * T, 16 * T, "r2")]
    assert core.windows("L2") == [(0, 5 * T, "r4")]
    assert [e["resource"] for e in reservations(events)] == ["spot:park3"]
    out, events = core.handle([done("r1", "L1", 4 * T, seq=2)])
    assert (out[0].robot, out[0].kind, out[0].target, out[0].stamp_ns, out[0].reply_to) == (
        "r3", "go", "L1", 4 * T + T // 10, 0)
    assert ("r3", "release", "spot:park3") in [
        (e["robot"], e["action"], e["resource"]) for e in reservations(events)]


def test_pipelined_hands_over_by_arrival_time_not_by_who_asked_first():
    """r1 asks first but is 9 m away from L1; r2 asks later from 1 m: r2's window comes
    first."""
    core = pipelined_core({"r1": ["L1"], "r2": ["L1"]}, {"r1": (-9.0, 0.0), "r2": (1.0, 0.0)},
                          assignment="route")
    core.handle([ready("r1", t=0)])
    core.handle([ready("r2", t=2 * T)])
    assert [r for _, _, r in core.windows("L1")] == ["r2", "r1"]
    assert core.windows("L1")[0] == (3 * T, 8 * T, "r2")
    assert core.windows("L1")[1] == (9 * T, 14 * T, "r1")


def test_pipelined_done_ends_the_window_counts_the_task_and_applies_the_service_time():
    core = pipelined_core({"r1": ["L1", "U1"], "r2": ["L1"]},
                          {"r1": (1.0, 0.0), "r2": (2.0, 0.0)}, service_time_ns=15 * T,
                          assignment="route")
    core.handle([ready("r1"), ready("r2")])
    assert core.windows("L1") == [(1 * T, 21 * T, "r1"), (21 * T, 41 * T, "r2")]
    out, events = core.handle([done("r1", "L1", 3 * T, seq=2)])
    # r2, waiting in line, goes when r1 leaves at 3 + 15 s (one hand-over later); r1 leaves
    # for U1 then (path 5*sqrt(5) m straight: ETA 18 + 11.18 s)
    assert [(a.robot, a.target, a.stamp_ns) for a in out] == [
        ("r2", "L1", 18 * T + T // 10), ("r1", "U1", 18 * T)]
    assert [e.values()["workstation"] for e in events if e.kind == "task"] == ["L1"]
    assert core.windows("L1") == [(2 * T, 22 * T, "r2")]
    assert core.windows("U1")[0][0] == 18 * T + round(125 ** 0.5 * T)


def test_pipelined_never_reads_the_fault_schedule_a_silent_robot_loses_its_window_by_lease():
    core = pipelined_core({"r1": ["L1"], "r2": ["U1"], "r3": ["L1"]},
                          {"r1": (1.0, 0.0), "r2": (5.0, 10.0), "r3": (-5.0, 0.0)},
                          assignment="route", lease_ns=60 * T)
    core.handle([ready("r1"), ready("r2")], alive=lambda ns, t: ns != "r1")
    # the schedule says r1 is dead: the pipelined core does not know it
    assert [r for _, _, r in core.windows("L1")] == ["r1"]
    # r2 speaks at 30 s; r1, silent since its window began at 1 s, keeps it until 61 s
    core.handle([done("r2", "U1", 30 * T, seq=2)])
    assert [r for _, _, r in core.windows("L1")] == ["r1"]
    out, events = core.handle([ready("r3", t=62 * T)])
    assert core.expired == 1
    # noticed by the lease: 61 s after its window began, at the first batch after that
    assert [(e.robot, e.fields["workstation"], e.fields["reason"], e.t_ns)
            for e in events if e.kind == "lapse"] == [("r1", "L1", "lease", 62 * T)]
    assert [r for _, _, r in core.windows("L1")] == ["r3"]
    assert (out[0].robot, out[0].kind, out[0].target) == ("r3", "go", "L1")
    # r1 gets there after all: its task counts
    _, events = core.handle([done("r1", "L1", 70 * T, seq=2)])
    assert [e.values()["robot"] for e in events if e.kind == "task"] == ["r1"]


def test_pipelined_keeps_to_the_route_where_its_window_begins_on_arrival():
    """r1 stands 1 m from L2 but its route says L1 (9 m away), free on its arrival: L1, as the
    reserve policy would; it is not sent back to L2, which it has just left, either."""
    core = pipelined_core({"r1": ["L1", "L2", "L2"]}, {"r1": (9.0, 0.0)})
    out, _ = core.handle([ready("r1")])
    assert (out[0].target, core.windows("L1")) == ("L1", [(9 * T, 14 * T, "r1")])
    out, _ = core.handle([done("r1", "L1", 20 * T, seq=2)])
    assert out[0].target == "L2"
    out, _ = core.handle([done("r1", "L2", 40 * T, seq=3)])
    assert out[0].target == "L1"  # its route says L2, which it has just left


def test_pipelined_queue_at_holding_sends_everyone_to_its_workstation_at_once():
    """``queue_at`` holding: the robots of the first pipelined test, but r3, in line at L1
    behind r1, is sent to L1 too (its navigator holds there); the windows are the same."""
    core = pipelined_core({ns: ["L1"] for ns in ("r1", "r2", "r3", "r4")},
                          {"r1": (1.0, 0.0), "r2": (-9.0, 0.0), "r3": (2.0, 0.0),
                           "r4": (10.0, 0.0)}, queue_at="holding")
    out, events = core.handle([ready(ns) for ns in ("r1", "r2", "r3", "r4")])
    assert [(a.robot, a.kind, a.target) for a in out] == [
        ("r1", "go", "L1"), ("r2", "go", "L1"), ("r3", "go", "L1"), ("r4", "go", "L2")]
    assert [r for _, _, r in core.windows("L1")] == ["r1", "r3", "r2"]
    assert reservations(events) == []
    # r1 done: nobody waits at a spot, so nothing is handed over
    out, _ = core.handle([done("r1", "L1", 4 * T, seq=2)])
    assert [a.robot for a in out] == ["r1"]
    with pytest.raises(ValueError, match="queue_at"):
        CoordinatorConfig(queue_at="hall")
