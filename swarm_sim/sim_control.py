"""Playing, pausing and stepping the simulator, and finding its entities, without ROS.

The state machine of ``simulation_interfaces`` (``SimulationState``: playing, paused, stopped)
as the simulator's loop (:class:`swarm_sim.loop.SimLoop`) obeys it: a tick starts only while
playing, or while paused with steps to take (``StepSimulation``).  A pause takes effect between
ticks, never inside one: the tick in progress is finished (its answers collected, the world
stepped) before the loop holds.  Nothing simulated depends on when, in wall time, a pause
came or how long it lasted, so a run paused and stepped through a stretch is the run that was
not paused (the lockstep already makes every tick wait for its answers however long they take).

``stopped`` ends the run (the loop stops as at its ``--duration``; the summary is written): the
standard's "stopped" also resets, and a run cannot be reset, because its navigators and commanders
hold state the simulator cannot rewind.  The ROS services are :mod:`swarm_sim.sim_services`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

# simulation_interfaces/msg/SimulationState (the values are the standard's)
STOPPED, PLAYING, PAUSED, QUITTING = 0, 1, 2, 3
STATE_NAMES = {STOPPED: "stopped", PLAYING: "playing", PAUSED: "paused", QUITTING: "quitting"}


class TransitionError(ValueError):
    """A state change that cannot be made; ``code`` is SetSimulationState's result code."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code


@dataclass
class SimControl:
    """Whether the loop may start a tick, and the requests waiting for a tick boundary.

    Attributes:
        state: one of :data:`PLAYING`, :data:`PAUSED`, :data:`STOPPED`.
        steps_left: ticks still to take while paused (``StepSimulation``).
        at_boundary: the loop is holding between two ticks (set by the loop).
        waiting: opaque requests answered when the loop next holds at a boundary (a pause,
            a finished stepping).
        paused_wall_s: [s] wall the loop has held, in all (a pause counts in the run's wall
            time; a paced run's clock skips it).
    """

    state: int = PLAYING
    steps_left: int = 0
    at_boundary: bool = False
    waiting: list = field(default_factory=list)
    paused_wall_s: float = 0.0

    def may_tick(self) -> bool:
        """Whether the loop may start the next tick."""
        return self.state == PLAYING or (self.state == PAUSED and self.steps_left > 0)

    def set_state(self, target: int) -> bool:
        """Change to ``target``.

        Returns:
            True if the answer must wait for the loop to hold (a pause of a running loop).

        Raises:
            TransitionError: already there (``ALREADY_IN_TARGET_STATE``), or a transition the
                run cannot make (``INCORRECT_TRANSITION``: out of stopped; ``quitting`` and
                ``stopped`` are the same here and both end the run).
        """
        if target == self.state:
            raise TransitionError("ALREADY_IN_TARGET_STATE",
                                  f"already {STATE_NAMES.get(target, target)}")
        if self.state == STOPPED:
            raise TransitionError("INCORRECT_TRANSITION",
                                  "the run has stopped (a run cannot be reset or restarted)")
        if target in (STOPPED, QUITTING):
            self.state, self.steps_left = STOPPED, 0
            return False
        if target == PAUSED:
            self.state = PAUSED
            return not self.at_boundary
        if target == PLAYING:
            self.state, self.steps_left = PLAYING, 0
            return False
        raise TransitionError("INCORRECT_TRANSITION",
                              f"unknown or unsupported state {target}")

    def step(self, steps: int) -> bool:
        """Take ``steps`` ticks, then hold again.

        Returns:
            True if the answer must wait until the ticks are taken (``steps`` > 0).

        Raises:
            TransitionError: not paused (``RESULT_INCORRECT_STATE``).
        """
        if self.state != PAUSED:
            raise TransitionError("RESULT_INCORRECT_STATE",
                                  f"StepSimulation needs a paused simulation; it is "
                                  f"{STATE_NAMES.get(self.state, self.state)}")
        self.steps_left += int(steps)
        return steps > 0

    def ticked(self) -> None:
        """One tick was taken."""
        if self.steps_left > 0:
            self.steps_left -= 1

    def settled(self) -> bool:
        """Whether the requests in :attr:`waiting` may be answered now: the loop holds at a
        boundary with no step left, or it has stopped."""
        return self.state == STOPPED or (self.at_boundary and not self.may_tick())


# -- entities -------------------------------------------------------------------------------
CATEGORY_ROBOT = 1  # simulation_interfaces/msg/EntityCategory
BOUNDS_EMPTY, BOUNDS_BOX, BOUNDS_CONVEX_HULL, BOUNDS_SPHERE = 0, 1, 2, 3


class FilterError(ValueError):
    """An entity filter the simulator does not support or cannot read; ``code`` is the
    ``Result`` code name."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code


def matching_entities(names, poses: np.ndarray, radii, *, pattern: str = "",
                      categories=(), tags=(), bounds_type: int = BOUNDS_EMPTY,
                      bounds_points=()) -> list[int]:
    """The robots an ``EntityFilters`` selects (every entity here is a robot).

    Args:
        names: (N) entity names (the robots' namespaces).
        poses: (N, 3) x [m], y [m], yaw [rad] in ``map``.
        radii: (N) each robot's circumscribed radius [m] (its footprint's).
        pattern: a regular expression searched in each name (``re.search``, which reads the
            POSIX extended expressions the standard names); empty: any.
        categories: ``EntityCategory`` values; empty: any; robots are ``CATEGORY_ROBOT``.
        tags: tags to match: entities have none, so a non-empty list is unsupported.
        bounds_type: ``Bounds.type``; a robot is selected when its footprint's circle overlaps
            the sphere (``TYPE_SPHERE``: centre, then radius in the second point's x) or the
            box (``TYPE_BOX``: two opposite corners) in the floor plane.
        bounds_points: ``Bounds.points`` as (x, y, z) tuples [m].

    Returns:
        Indices of the selected robots, in order.

    Raises:
        FilterError: a malformed expression or bounds, tags, convex-hull bounds.
    """
    try:
        rx = re.compile(pattern) if pattern else None
    except re.error as exc:
        raise FilterError("RESULT_OPERATION_FAILED", f"filter: not a regular expression: "
                          f"{exc}") from None
    if tags:
        raise FilterError("RESULT_FEATURE_UNSUPPORTED", "entities have no tags here")
    if categories and CATEGORY_ROBOT not in categories:
        return []
    keep = [i for i, name in enumerate(names) if rx is None or rx.search(name)]
    if bounds_type == BOUNDS_EMPTY:
        return keep
    pts = [tuple(float(v) for v in p) for p in bounds_points]
    if bounds_type == BOUNDS_SPHERE:
        if len(pts) != 2 or not pts[1][0] >= 0.0:
            raise FilterError("RESULT_OPERATION_FAILED",
                              "bounds: a sphere is 2 points (centre; radius in x >= 0)")
        (cx, cy, _), r = pts[0], pts[1][0]
        return [i for i in keep if math.hypot(poses[i, 0] - cx, poses[i, 1] - cy)
                <= r + radii[i]]
    if bounds_type == BOUNDS_BOX:
        if len(pts) != 2:
            raise FilterError("RESULT_OPERATION_FAILED", "bounds: a box is 2 opposite corners")
        lo = np.minimum(pts[0], pts[1])
        hi = np.maximum(pts[0], pts[1])
        out = []
        for i in keep:
            dx = max(lo[0] - poses[i, 0], 0.0, poses[i, 0] - hi[0])
            dy = max(lo[1] - poses[i, 1], 0.0, poses[i, 1] - hi[1])
            if math.hypot(dx, dy) <= radii[i]:
                out.append(i)
        return out
    raise FilterError("RESULT_FEATURE_UNSUPPORTED",
                      f"bounds type {bounds_type}: only sphere and box are supported")
