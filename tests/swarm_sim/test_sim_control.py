"""Playing, pausing, stepping and the entity filters (swarm_sim/sim_control.py), and the loop
holding between ticks while paused (on test_loop's fake world and ports)."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_sim.sim_control import (
    BOUNDS_BOX,
    BOUNDS_CONVEX_HULL,
    BOUNDS_SPHERE,
    PAUSED,
    PLAYING,
    QUITTING,
    STOPPED,
    FilterError,
    SimControl,
    TransitionError,
    matching_entities,
)
from tests.swarm_sim.test_loop import P, make


def test_pause_waits_for_the_boundary_and_step_counts_ticks():
    c = SimControl()
    assert c.may_tick()
    assert c.set_state(PAUSED) is True  # the loop is inside a tick: answered at the boundary
    assert not c.may_tick() and not c.settled()
    c.at_boundary = True
    assert c.settled()
    assert c.step(2) is True and c.may_tick() and not c.settled()
    c.ticked()
    assert c.may_tick()
    c.ticked()
    assert not c.may_tick() and c.settled()
    assert c.step(0) is False  # nothing to take: answered at once
    assert c.set_state(PLAYING) is False and c.may_tick()


@pytest.mark.parametrize(("start", "target", "code"), [
    (PLAYING, PLAYING, "ALREADY_IN_TARGET_STATE"),
    (PAUSED, PAUSED, "ALREADY_IN_TARGET_STATE"),
    (STOPPED, PLAYING, "INCORRECT_TRANSITION"),
    (STOPPED, PAUSED, "INCORRECT_TRANSITION"),
    (PLAYING, 4, "INCORRECT_TRANSITION"),  # STATE_NO_WORLD: not a state one can ask for
])
def test_transitions_that_cannot_be_made_say_why(start, target, code):
    c = SimControl(state=start)
    with pytest.raises(TransitionError) as err:
        c.set_state(target)
    assert err.value.code == code


@pytest.mark.parametrize("target", [STOPPED, QUITTING])
def test_stopping_or_quitting_ends_the_run_from_playing_or_paused(target):
    for start in (PLAYING, PAUSED):
        c = SimControl(state=start, steps_left=3)
        assert c.set_state(target) is False
        assert c.state == STOPPED and not c.may_tick() and c.settled()


def test_stepping_needs_a_paused_simulation():
    with pytest.raises(TransitionError) as err:
        SimControl().step(1)
    assert err.value.code == "RESULT_INCORRECT_STATE"


def test_a_paused_and_stepped_loop_runs_the_same_ticks_as_one_that_was_not():
    plain, plain_engine, _ = make(3)
    plain.run(duration_s=2.0)

    loop, engine, ports = make(3)
    seen = {"held": 0, "script": []}

    def script(lp):
        c = lp.control
        if lp.gate.t_ns == 5 * P and c.state == PLAYING and not seen["script"]:
            c.set_state(PAUSED)
            seen["script"].append(("paused", engine.ticks))
        elif c.at_boundary and c.state == PAUSED:
            seen["held"] += 1
            if seen["held"] == 20:  # held 20 spins without a tick: step 3
                seen["script"].append(("step", engine.ticks))
                c.step(3)
            elif seen["held"] == 40:
                seen["script"].append(("play", engine.ticks))
                c.set_state(PLAYING)

    ports.on_spin.append(script)
    loop.run(duration_s=2.0)
    (_, t_pause), (_, t_step), (_, t_play) = seen["script"]
    # a pause that came inside a tick lets it finish; one between ticks holds at once
    assert t_step - t_pause in (0, 1)
    assert t_play == t_step + 3  # exactly the ticks asked for, then held again
    assert engine.ticks == plain_engine.ticks
    assert np.array_equal(engine.poses, plain_engine.poses)
    assert engine.commands == plain_engine.commands
    assert loop.control.paused_wall_s > 0.0


def test_a_stop_while_paused_ends_the_loop():
    loop, engine, ports = make(2)
    paused_at = []

    def script(lp):
        if lp.gate.t_ns == 3 * P and lp.control.state == PLAYING:
            lp.control.set_state(PAUSED)
            paused_at.append(lp.gate.t_ns)
        elif lp.control.at_boundary and lp.control.state == PAUSED:
            lp.control.set_state(STOPPED)

    ports.on_spin.append(script)
    ports.stopped = lambda: loop.control.state == STOPPED  # as the node's stopped() says
    loop.run(duration_s=10.0)
    assert loop.gate.t_ns - paused_at[0] in (0, P)


NAMES = ["Srobot1", "Srobot2", "Srobot10", "other"]
POSES = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 1.0], [10.0, 10.0, 0.0]])
RADII = [0.3, 0.3, 0.3, 0.3]


@pytest.mark.parametrize(("kw", "want"), [
    ({}, [0, 1, 2, 3]),
    ({"pattern": "^Srobot1"}, [0, 2]),
    ({"pattern": "1$"}, [0]),
    ({"pattern": "[0-9]{2}"}, [2]),
    ({"categories": [1]}, [0, 1, 2, 3]),
    ({"categories": [0, 5]}, []),
    ({"bounds_type": BOUNDS_SPHERE, "bounds_points": [(0, 0, 0), (1.8, 0, 0)]}, [0, 1]),
    ({"bounds_type": BOUNDS_SPHERE, "bounds_points": [(0, 0, 0), (1.6, 0, 0)]}, [0]),
    ({"bounds_type": BOUNDS_BOX, "bounds_points": [(-1, 2.8, -1), (1, 5, 1)]}, [2]),
    ({"bounds_type": BOUNDS_BOX, "bounds_points": [(9, 9, 0), (-1, -1, 0)]}, [0, 1, 2]),
    ({"pattern": "Srobot", "bounds_type": BOUNDS_SPHERE,
      "bounds_points": [(10, 10, 0), (50, 0, 0)]}, [0, 1, 2]),
])
def test_entity_filters_select_robots(kw, want):
    assert matching_entities(NAMES, POSES, RADII, **kw) == want


@pytest.mark.parametrize(("kw", "code"), [
    ({"pattern": "("}, "RESULT_OPERATION_FAILED"),
    ({"tags": ["forklift"]}, "RESULT_FEATURE_UNSUPPORTED"),
    ({"bounds_type": BOUNDS_CONVEX_HULL, "bounds_points": [(0, 0, 0)] * 3},
     "RESULT_FEATURE_UNSUPPORTED"),
    ({"bounds_type": BOUNDS_SPHERE, "bounds_points": [(0, 0, 0)]}, "RESULT_OPERATION_FAILED"),
    ({"bounds_type": BOUNDS_BOX, "bounds_points": []}, "RESULT_OPERATION_FAILED"),
])
def test_filters_the_simulator_cannot_apply_say_so(kw, code):
    with pytest.raises(FilterError) as err:
        matching_entities(NAMES, POSES, RADII, **kw)
    assert err.value.code == code


def test_every_standard_service_listed_has_its_handler():
    from swarm_common import topics
    from swarm_sim.sim_services import SimServices

    assert set(SimServices.HANDLERS) == set(topics.SIMULATION_SERVICES)
    assert all(callable(getattr(SimServices, m)) for m in SimServices.HANDLERS.values())
