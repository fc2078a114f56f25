"""Route planning for the commander: which pose a robot visits next (pure: no ROS).

A *route* hands out one *loop* of stops at a time; the commander visits the stops of a loop in
order, one task per stop, and asks for the next loop when it is done.

- :class:`RandomRoute` visits every workstation once per loop in a seeded random order (a fresh
  permutation each loop, never the same workstation twice in a row across a loop boundary).
- :class:`FixedRoute` visits the stops of a route file (:func:`load_route`) in the file's order.
- :func:`build_route` makes either for one robot of a world (the commander's ``--route``).

All randomness comes from a ``numpy.random.Generator`` (STYLE.md point 11); :func:`route_rng`
derives one from the user's seed and the robot's namespace, so robots started with the same
``--seed`` still take different orders, and a rerun with the same seed repeats them exactly.
"""

from __future__ import annotations

import itertools
import math
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from swarm_common.errors import InputError, did_you_mean
from swarm_common.geometry import Pose2D, pose2d


@dataclass(frozen=True)
class RouteStop:
    """One place the commander sends the robot to.

    Attributes:
        name: the workstation's name, or ``waypoint<i>`` (1-based) for an unnamed waypoint.
        pose: ``Pose2D`` (3,) x [m], y [m], yaw [rad] in ``map``.
    """

    name: str
    pose: Pose2D


def stops_from_workstations(workstations) -> tuple[RouteStop, ...]:
    """Turn the workstations of a world's points of interest into route stops.

    Args:
        workstations: sequence of objects with ``.name`` (str) and ``.pose`` ((3,) x, y [m],
            yaw [rad] in ``map``), e.g. ``swarm_scene.poi.Workstation``.

    Returns:
        One :class:`RouteStop` per workstation, in the given order.
    """
    return tuple(RouteStop(str(w.name), pose2d(*np.asarray(w.pose, float)[:3]))
                 for w in workstations)


def route_rng(seed: int, namespace: str) -> np.random.Generator:
    """The commander's random generator for one robot.

    Args:
        seed: the user's ``--seed`` (a non-negative integer).
        namespace: the robot's namespace (``"Srobot3"``; a leading ``/`` is ignored).

    Returns:
        A ``numpy.random.Generator`` seeded from both, stable across Python runs (CRC-32 of the
        namespace, not the salted ``hash``).
    """
    if int(seed) < 0:
        raise ValueError(f"seed must be non-negative, got {seed}")
    tag = zlib.crc32(namespace.strip("/").encode("utf-8"))
    return np.random.default_rng(np.random.SeedSequence([int(seed), tag]))


class RandomRoute:
    """Every stop once per loop, in a fresh seeded random order each loop.

    The first stop of a loop is never the last stop of the loop before (when there are two stops
    or more), so a robot never gets sent to the workstation it is already parked at. The order is
    drawn uniformly among the permutations that satisfy this.

    Args:
        stops: the stops to visit (at least one).
        rng: the generator all randomness is drawn from.
    """

    def __init__(self, stops: Sequence[RouteStop], rng: np.random.Generator):
        if not stops:
            raise ValueError("a route needs at least one stop")
        self.stops = tuple(stops)
        self._rng = rng
        self._last: int | None = None

    def next_loop(self) -> tuple[RouteStop, ...]:
        """Draw the next loop's order.

        Returns:
            All stops, each once, in a new random order.
        """
        n = len(self.stops)
        order = self._rng.permutation(n)
        if n > 1 and order[0] == self._last:
            # Swapping the repeat with a uniformly chosen other position keeps the order uniform
            # over the permutations that do not start with the previous loop's last stop.
            j = int(self._rng.integers(1, n))
            order[0], order[j] = order[j], order[0]
        self._last = int(order[-1])
        return tuple(self.stops[i] for i in order)


class FixedRoute:
    """The same stops in the same order every loop (a route file).

    Args:
        stops: the stops to visit (at least one), in order.
    """

    def __init__(self, stops: Sequence[RouteStop]):
        if not stops:
            raise ValueError("a route needs at least one stop")
        self.stops = tuple(stops)

    def next_loop(self) -> tuple[RouteStop, ...]:
        """Returns: the stops, in the file's order."""
        return self.stops


def visits(route: RandomRoute | FixedRoute, loops: int = 0) -> Iterator[tuple[int, RouteStop]]:
    """Iterate over the visits of ``loops`` loops of a route.

    Args:
        route: where the loops come from.
        loops: number of loops; ``0`` loops forever.

    Yields:
        ``(loop, stop)``: the 1-based loop number and the stop to visit.
    """
    if loops < 0:
        raise ValueError(f"loops must be >= 0, got {loops}")
    counter = itertools.count(1) if loops == 0 else range(1, loops + 1)
    for loop in counter:
        for stop in route.next_loop():
            yield loop, stop


_ROUTE_KEYS = ("frame_id", "waypoints")
_WAYPOINT_KEYS = ("name", "x", "y", "yaw")


def world_service_time(world: str | Path) -> float:
    """[s] simulated: the ``service_time`` of a world's points of interest (0 without them).

    Raises:
        InputError: an unknown world (names ``--world``) or invalid points of interest.
    """
    from swarm_scene.poi import poi_for_world
    from swarm_scene.world import resolve_world

    try:
        world_path = resolve_world(world)
    except InputError as exc:
        raise InputError(f"--world: {exc}") from None
    poi = poi_for_world(world_path)
    return poi.service_time if poi is not None else 0.0


def build_route(world: str | Path, seed: int, ns: str,
                route: str | Path = "random") -> RandomRoute | FixedRoute:
    """The route of robot ``ns`` in a world: what ``swarm-commander`` and a group process run.

    Args:
        world: a world name under ``worlds/`` or a ``.world``/``.sdf`` path; its workstations
            come from the points-of-interest YAML beside it.
        seed: the user's seed (>= 0), mixed with ``ns`` (:func:`route_rng`).
        ns: the robot's namespace without a leading ``/``.
        route: ``"random"`` (every workstation once per loop, seeded order) or a route file
            (:func:`load_route`).

    Returns:
        A :class:`RandomRoute` or a :class:`FixedRoute`.

    Raises:
        InputError: an unknown world (names ``--world``), a world without workstations for a
            random route, or a malformed route file (names the file).
    """
    from swarm_scene.poi import poi_for_world
    from swarm_scene.world import resolve_world

    try:
        world_path = resolve_world(world)
    except InputError as exc:
        raise InputError(f"--world: {exc}") from None
    poi = poi_for_world(world_path)
    workstations = poi.workstations if poi is not None else ()
    if str(route) == "random":
        if not workstations:
            where = (f"none in {poi.source}" if poi is not None
                     else f"no {world_path.with_suffix('.yaml').name} beside it")
            raise InputError(f"--world: world {world_path.stem} has no workstations ({where})")
        return RandomRoute(stops_from_workstations(workstations), route_rng(seed, ns))
    return FixedRoute(load_route(route, workstations))


def load_route(path: str | Path, workstations=None) -> tuple[RouteStop, ...]:
    """Load a route file (strict: an unknown key is an error with a did-you-mean).

    The file is YAML::

        frame_id: map            # optional; only map
        waypoints:
          - loader3              # a workstation of the world, by name
          - {name: dock, x: 1.5, y: -2.0, yaw: 1.5708}   # a pose [m, m, rad] in map
          - {x: 0.0, y: 0.0, yaw: 0.0}                   # unnamed: "waypoint3"

    Args:
        path: the route file.
        workstations: the world's workstations (objects with ``.name`` and ``.pose`` (3,)), for
            waypoints given by name; ``None`` or empty if the world has none.

    Returns:
        The stops, in the file's order (at least one).

    Raises:
        InputError: the file is missing, is not YAML, or does not follow the format; the message
            starts with the file's path.
    """
    path = Path(path)
    where = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{where}: no such route file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{where}: cannot read route file: {exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark is not None else ""
        raise InputError(f"{where}: not valid YAML{line}") from None
    if not isinstance(data, dict):
        raise InputError(f"{where}: expected a mapping with 'waypoints', got {_kind(data)}")
    for key in data:
        if key not in _ROUTE_KEYS:
            raise InputError(f"{where}: unknown key '{key}'{did_you_mean(str(key), _ROUTE_KEYS)}")
    frame = data.get("frame_id", "map")
    if frame != "map":
        raise InputError(f"{where}: frame_id: only 'map' is supported, got {frame!r}")
    if "waypoints" not in data:
        raise InputError(f"{where}: missing key 'waypoints'")
    items = data["waypoints"]
    if not isinstance(items, list) or not items:
        raise InputError(f"{where}: waypoints: expected a non-empty list, got {_kind(items)}")
    by_name = {str(w.name): w for w in (workstations or ())}
    stops = []
    for i, item in enumerate(items, start=1):
        at = f"{where}: waypoints[{i}]"
        if isinstance(item, str):
            stops.append(_named_stop(item, by_name, at))
        elif isinstance(item, dict):
            stops.append(_pose_stop(item, i, at))
        else:
            raise InputError(f"{at}: expected a workstation name or a mapping with x, y, yaw, "
                             f"got {_kind(item)}")
    return tuple(stops)


def _named_stop(name: str, by_name: dict, at: str) -> RouteStop:
    if not by_name:
        raise InputError(f"{at}: '{name}' names a workstation, but the world has none")
    if name not in by_name:
        raise InputError(f"{at}: unknown workstation '{name}'{did_you_mean(name, by_name)}")
    return stops_from_workstations([by_name[name]])[0]


def _pose_stop(item: dict, index: int, at: str) -> RouteStop:
    for key in item:
        if key not in _WAYPOINT_KEYS:
            raise InputError(f"{at}: unknown key '{key}'{did_you_mean(str(key), _WAYPOINT_KEYS)}")
    values = []
    for key in ("x", "y", "yaw"):
        if key not in item:
            raise InputError(f"{at}: missing key '{key}'")
        value = item[key]
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise InputError(f"{at}: {key}: expected a finite number, got {value!r}")
        values.append(float(value))
    name = item.get("name", f"waypoint{index}")
    if not isinstance(name, str) or not name:
        raise InputError(f"{at}: name: expected a non-empty string, got {name!r}")
    return RouteStop(name, pose2d(*values))


def _kind(value) -> str:
    return "nothing" if value is None else type(value).__name__
