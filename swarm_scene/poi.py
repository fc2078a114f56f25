"""Points of interest of a world (``worlds/<name>.yaml``): workstations, holding, spawn, points.

The loader is strict (STYLE.md point 9, after ir-sim): an unknown key anywhere is an error with a
did-you-mean, a wrong type or a missing field is an error naming the file and the field. The
schema (all coordinates in ``map``, metres and radians)::

    frame_id: map                 # optional; only "map" is accepted
    workstations:                 # optional list, may be empty
      - name: loader1             # required, unique
        x: -7.74575               # required [m]
        y: -3.57766               # required [m]
        yaw: 3.14159              # optional [rad], default 0
        holding:                  # optional: one [x, y] = a holding spot; >= 2 = a loop
          - [-6.6, -3.0]          #   driven in order (and back to the first) [m]
    spawn:                        # optional
      origin: [0.0, 0.0]          # required [m], the first robot, inside area
      spacing: 1.0                # optional [m], > 0, default 1.0
      yaw: 3.14159                # optional [rad], default 0
      area: [-3.0, -1.0, 8.5, 8.6]  # required [m]: xmin, ymin, xmax, ymax
    points:                       # optional named points: [x, y] or [x, y, yaw]
      unload: [5.0, 5.0]
    service_time: 0.0             # optional [s] simulated, >= 0, default 0: how long a robot
                                  #   stays docked at a workstation once it has reached it
    waiting:                      # optional: the coordinator's waiting spots near the
      - [-5.7, -2.4]              #   workstations, out of the lane: [x, y] or [x, y, yaw] [m]

``waiting`` is read only by the central coordinator (``--waiting-spots near``, the default):
where queued robots wait, besides each workstation's own holding spot. Without it, or with
``--waiting-spots hall``, they park on the spawn grid.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from swarm_common.errors import InputError, did_you_mean

TOP_KEYS = ("frame_id", "workstations", "spawn", "points", "waiting", "service_time")
WORKSTATION_KEYS = ("name", "x", "y", "yaw", "holding")
SPAWN_KEYS = ("origin", "spacing", "yaw", "area")


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array, dtype=float)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class Workstation:
    """A workstation: where a robot docks.

    Attributes:
        name: unique name, e.g. ``"loader1"``.
        pose: (3,) read-only docking pose x, y [m], yaw [rad] in ``map``.
        holding: (K, 2) read-only x, y [m] in ``map``: K = 0 none, K = 1 a holding spot,
            K >= 2 a loop driven in order (closing back to the first point).
    """

    name: str
    pose: np.ndarray
    holding: np.ndarray = field(default_factory=lambda: _frozen(np.zeros((0, 2))))

    @property
    def is_loop(self) -> bool:
        """True when ``holding`` is a loop (two or more points) rather than a spot."""
        return len(self.holding) >= 2


@dataclass(frozen=True)
class SpawnArea:
    """The grid robots are spawned on.

    Attributes:
        origin: (2,) x, y [m] in ``map`` of the first robot.
        spacing: grid spacing [m].
        yaw: heading of every robot [rad].
        area: (4,) xmin, ymin, xmax, ymax [m] in ``map`` the grid must stay in.
    """

    origin: np.ndarray
    spacing: float
    yaw: float
    area: np.ndarray

    def grid_points(self) -> np.ndarray:
        """(M, 2) x, y [m] of every grid node ``origin + spacing * (i, j)`` inside ``area``.

        Sorted by x, then y (the spawner decides the order robots take them in).
        """
        xmin, ymin, xmax, ymax = self.area
        tol = 1e-9
        i0 = math.ceil((xmin - self.origin[0]) / self.spacing - tol)
        i1 = math.floor((xmax - self.origin[0]) / self.spacing + tol)
        j0 = math.ceil((ymin - self.origin[1]) / self.spacing - tol)
        j1 = math.floor((ymax - self.origin[1]) / self.spacing + tol)
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        return np.column_stack((self.origin[0] + self.spacing * ii.ravel(),
                                self.origin[1] + self.spacing * jj.ravel()))


@dataclass(frozen=True)
class PointsOfInterest:
    """Everything a world's points of interest say.

    Attributes:
        workstations: in file order.
        spawn: the spawn grid, or None (then robots spawn in the largest free area).
        points: name → (2,) x, y [m] or (3,) x, y [m], yaw [rad], read-only, in ``map``.
        waiting: (K, 3) read-only waiting spots x, y [m], yaw [rad] in ``map`` for the central
            coordinator's queues (yaw 0 where the file gives none); (0, 3) when none.
        service_time: [s] simulated: how long a robot stays docked at a workstation it has
            reached (the workstation's service, the robot occupying it) before its next goal
            takes effect; 0 (the default): it leaves at once. ``swarm-up --service-time``
            overrides it (docs/guides/coordination.md, "Service time").
        source: the file read, or None.
    """

    workstations: tuple[Workstation, ...] = ()
    spawn: SpawnArea | None = None
    points: dict[str, np.ndarray] = field(default_factory=dict)
    waiting: np.ndarray = field(default_factory=lambda: _frozen(np.zeros((0, 3))))
    service_time: float = 0.0
    source: Path | None = None

    def workstation(self, name: str) -> Workstation:
        """The workstation called ``name``; InputError (with a did-you-mean) if there is none."""
        for ws in self.workstations:
            if ws.name == name:
                return ws
        names = [ws.name for ws in self.workstations]
        raise InputError(f"unknown workstation '{name}'{did_you_mean(name, names)}")


class _Checker:
    """Type checks that raise InputError naming the file and the field."""

    def __init__(self, where: str):
        self.where = where

    def fail(self, message: str) -> InputError:
        return InputError(f"{self.where}: {message}")

    def keys(self, mapping: dict, allowed: tuple[str, ...], ctx: str) -> None:
        for key in mapping:
            if key not in allowed:
                inside = f" in {ctx}" if ctx else ""
                raise self.fail(f"unknown key '{key}'{inside}{did_you_mean(str(key), allowed)}")

    def mapping(self, value, ctx: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(f"{ctx} must be a mapping of keys, got {_show(value)}")
        return value

    def number(self, value, ctx: str) -> float:
        if isinstance(value, str):  # PyYAML reads 1e3 (no dot) as a string: YAML 1.1
            try:
                value = float(value)
            except ValueError:
                pass
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(f"{ctx} must be a number, got {_show(value)}")
        if not math.isfinite(value):
            raise self.fail(f"{ctx} must be finite, got {value}")
        return float(value)

    def vector(self, value, lengths: tuple[int, ...], ctx: str, what: str) -> np.ndarray:
        if not isinstance(value, list | tuple) or len(value) not in lengths:
            raise self.fail(f"{ctx} must be {what}, got {_show(value)}")
        return np.array([self.number(v, f"{ctx}[{i}]") for i, v in enumerate(value)])

    def required(self, mapping: dict, key: str, ctx: str):
        if key not in mapping:
            raise self.fail(f"{ctx} is missing required key '{key}'")
        return mapping[key]


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _holding(check: _Checker, value, ctx: str) -> np.ndarray:
    if value is None:
        return np.zeros((0, 2))
    if isinstance(value, list) and len(value) == 2 and not any(
            isinstance(v, list | tuple | dict) for v in value):
        value = [value]  # a bare [x, y] is one holding spot
    if not isinstance(value, list):
        raise check.fail(f"{ctx} must be a list of [x, y] points, got {_show(value)}")
    points = [check.vector(p, (2,), f"{ctx}[{i}]", "[x, y]") for i, p in enumerate(value)]
    return np.array(points).reshape(-1, 2)


def _workstation(check: _Checker, value, ctx: str) -> Workstation:
    ws = check.mapping(value, ctx)
    check.keys(ws, WORKSTATION_KEYS, ctx)
    name = check.required(ws, "name", ctx)
    if not isinstance(name, str) or not name.strip():
        raise check.fail(f"{ctx}.name must be a non-empty string, got {_show(name)}")
    x = check.number(check.required(ws, "x", ctx), f"{ctx}.x")
    y = check.number(check.required(ws, "y", ctx), f"{ctx}.y")
    yaw = check.number(ws.get("yaw", 0.0), f"{ctx}.yaw")
    holding = _holding(check, ws.get("holding"), f"{ctx}.holding")
    return Workstation(name=name.strip(), pose=_frozen([x, y, yaw]), holding=_frozen(holding))


def _spawn(check: _Checker, value) -> SpawnArea:
    sp = check.mapping(value, "spawn")
    check.keys(sp, SPAWN_KEYS, "spawn")
    origin = check.vector(check.required(sp, "origin", "spawn"), (2,), "spawn.origin", "[x, y]")
    area = check.vector(check.required(sp, "area", "spawn"), (4,), "spawn.area",
                        "[xmin, ymin, xmax, ymax]")
    spacing = check.number(sp.get("spacing", 1.0), "spawn.spacing")
    yaw = check.number(sp.get("yaw", 0.0), "spawn.yaw")
    if spacing <= 0.0:
        raise check.fail(f"spawn.spacing must be positive [m], got {spacing:g}")
    if not (area[0] < area[2] and area[1] < area[3]):
        raise check.fail(f"spawn.area must be [xmin, ymin, xmax, ymax] with xmin < xmax and "
                         f"ymin < ymax, got {area.tolist()}")
    if not (area[0] <= origin[0] <= area[2] and area[1] <= origin[1] <= area[3]):
        raise check.fail(f"spawn.origin {origin.tolist()} is outside spawn.area "
                         f"{area.tolist()}")
    return SpawnArea(origin=_frozen(origin), spacing=spacing, yaw=yaw, area=_frozen(area))


def load_poi(path: str | Path) -> PointsOfInterest:
    """Load a points-of-interest YAML file, strictly.

    A file already loaded by this process with the same content is not parsed again: a group
    process of 50 robots loaded it 100 times at its start (each navigator, each commander's
    route), 20-30 ms of pure-Python YAML each. The result is immutable (frozen dataclasses,
    read-only arrays), so sharing it is safe.

    Args:
        path: the YAML file (schema in the module docstring).

    Returns:
        The :class:`PointsOfInterest`; an empty file gives an empty one.

    Raises:
        InputError: missing file, invalid YAML, an unknown key (with a did-you-mean, e.g.
            ``"f.yaml: unknown key 'xx' in workstations[2] (did you mean 'x'?)"``), a missing
            required field, a wrong type, a duplicate workstation or point name, a spawn origin
            outside its area.
    """
    path = Path(path)
    check = _Checker(str(path))
    if not path.is_file():
        raise check.fail("no such points-of-interest file")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise check.fail(f"cannot read: {exc}") from None
    return _parse_poi(path, text)


@functools.lru_cache(maxsize=16)
def _parse_poi(path: Path, text: str) -> PointsOfInterest:
    """:func:`load_poi` of the file ``path`` whose content is ``text`` (the cache key: the same
    text parses to the same points, a file that changed is parsed again)."""
    check = _Checker(str(path))
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise check.fail(f"invalid YAML{at}: {problem}") from None
    if doc is None:
        return PointsOfInterest(source=path)
    doc = check.mapping(doc, "the file")
    check.keys(doc, TOP_KEYS, "")
    frame = doc.get("frame_id", "map")
    if frame != "map":
        raise check.fail(f"frame_id must be 'map' (points are in the map frame), got "
                         f"{_show(frame)}")
    raw_ws = doc.get("workstations") or []
    if not isinstance(raw_ws, list):
        raise check.fail(f"workstations must be a list, got {_show(raw_ws)}")
    workstations = tuple(_workstation(check, w, f"workstations[{i}]")
                         for i, w in enumerate(raw_ws))
    seen: set[str] = set()
    for i, ws in enumerate(workstations):
        if ws.name in seen:
            raise check.fail(f"workstations[{i}]: duplicate name '{ws.name}'")
        seen.add(ws.name)
    spawn = _spawn(check, doc["spawn"]) if doc.get("spawn") is not None else None
    raw_points = doc.get("points") or {}
    raw_points = check.mapping(raw_points, "points")
    points = {}
    for name, value in raw_points.items():
        if not isinstance(name, str):
            raise check.fail(f"points: names must be strings, got {_show(name)}")
        points[name] = _frozen(check.vector(value, (2, 3), f"points.{name}",
                                            "[x, y] or [x, y, yaw]"))
    raw_waiting = doc.get("waiting") or []
    if not isinstance(raw_waiting, list):
        raise check.fail(f"waiting must be a list of [x, y] or [x, y, yaw] points, got "
                         f"{_show(raw_waiting)}")
    waiting = [check.vector(v, (2, 3), f"waiting[{i}]", "[x, y] or [x, y, yaw]")
               for i, v in enumerate(raw_waiting)]
    waiting = np.array([[*w[:2], w[2] if len(w) > 2 else 0.0] for w in waiting],
                       float).reshape(-1, 3)
    service = check.number(doc.get("service_time", 0.0), "service_time")
    if service < 0.0:
        raise check.fail(f"service_time must be >= 0 [s], got {service:g}")
    return PointsOfInterest(workstations=workstations, spawn=spawn, points=points,
                            waiting=_frozen(waiting), service_time=float(service), source=path)


def poi_for_world(world_path: str | Path) -> PointsOfInterest | None:
    """The points of interest beside a world: the ``.yaml`` with the same stem, if any.

    Args:
        world_path: the world file; ``worlds/a.world`` → ``worlds/a.yaml``.

    Returns:
        The loaded :class:`PointsOfInterest`, or None when there is no such file.

    Raises:
        InputError: the file exists but is invalid (see :func:`load_poi`).
    """
    candidate = Path(world_path).with_suffix(".yaml")
    return load_poi(candidate) if candidate.is_file() else None
