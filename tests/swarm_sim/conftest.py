"""Fixtures shared by the simulator's engine tests: the bundled robots, the empty world, and
engines that are closed when the test ends."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_scene.robot_model import load_robot
from swarm_scene.world import load_world
from swarm_sim.engine import SimEngine


@pytest.fixture(scope="module")
def empty():
    return load_world("empty")  # a 20 x 20 m room: walls 10 m away from the origin


@pytest.fixture(scope="module")
def robots():
    """The bundled robot models by name."""
    return {name: load_robot(name)
            for name in ("turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd")}


@pytest.fixture
def make_engine():
    """``make(world, robot_or_robots, poses, **kwargs)`` builds an engine; every one is closed
    when the test ends."""
    engines: list[SimEngine] = []

    def make(world, robots, poses, **kwargs) -> SimEngine:
        engine = SimEngine(world, robots, np.asarray(poses, dtype=float), **kwargs)
        engines.append(engine)
        return engine

    yield make
    for engine in engines:
        engine.close()
