"""A fault's victim chosen by where it stands (``swarm-experiment --fault-spec``), pure.

The protocol asks for the victim of a fault to be placed deliberately: in a dock corridor, at a
workstation, in the hall, not robot 3 wherever it happens to be. A fault spec may name a
*placement* instead of a robot::

    kill-robot:@station@360     the robot docked nearest a workstation at 360 s
    kill-robot:@approach@360    the robot nearest 1.5 m from a workstation (on its way in or
                                 holding there: the dock corridor)
    kill-robot:@hall@360        the robot farthest from every workstation
    kill-nav:@approach@360+2, drop:@station/scan:0.5@360+60   (any robot fault)

A run and its no-fault run of the same seed are the same simulation up to the fault (the same
seed gives the same run), so the victim is read off the no-fault run's ground truth at the
fault's time (the simulator's ``track``, :mod:`swarm_metrics.waiting`), and the fault run gets
the concrete spec (``kill-robot:17@360``). Ties go to the lower robot number. The no-fault run's
record keeps those positions (``victim_positions``), so a sweep sliced across sittings or
machines places its fault runs from the records alone.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from swarm_common.errors import InputError

PLACEMENTS = ("station", "approach", "hall")
APPROACH_M = 1.5
"""[m] from its nearest workstation's docking pose: the ``approach`` victim's distance."""
_PLACED = re.compile(r":@(?P<where>[a-z]+)(?=[@/])")


def placement_of(spec: str) -> list[str]:
    """The placements a spec names, in order (empty: it names robots only).

    Raises:
        InputError: an unknown placement (names ``--fault-spec``).
    """
    out = [where for _m, where, _t in _placed(spec)]
    for where in out:
        if where not in PLACEMENTS:
            raise InputError(f"--fault-spec: unknown placement '@{where}' in '{spec}' "
                             f"(placements: {', '.join('@' + p for p in PLACEMENTS)})")
    return out


def with_robot(spec: str, robot: int = 1) -> str:
    """``spec`` with every placement replaced by robot number ``robot`` (to check the rest of
    the spec with swarm-up's own parser before any run)."""
    return _PLACED.sub(f":{robot}", spec)


def choose_victim(xy: np.ndarray, docks: np.ndarray, where: str,
                  exclude: tuple[int, ...] = ()) -> int:
    """The index of the robot a placement picks.

    Args:
        xy: (N, 2) the robots' positions [m] in ``map`` at the fault's time.
        docks: (K, 2) the workstations' docking positions [m].
        where: one of :data:`PLACEMENTS`.
        exclude: robot indices already chosen (a spec with two placed faults).

    Returns:
        ``station``: the robot nearest a docking position; ``approach``: the one whose distance
        to its nearest docking position is nearest :data:`APPROACH_M`; ``hall``: the one
        farthest from every docking position. Ties: the lowest index.
    """
    d = np.hypot(xy[:, None, 0] - docks[None, :, 0], xy[:, None, 1] - docks[None, :, 1]).min(1)
    score = {"station": d, "approach": np.abs(d - APPROACH_M), "hall": -d}[where].astype(float)
    score[list(exclude)] = np.inf
    return int(np.argmin(score))


def _placed(spec: str):
    """Every placement of ``spec``: (its match, where, the fault's time [s] simulated)."""
    for m in _PLACED.finditer(spec):
        at = re.match(r"(?:/[^@]*)?@(?P<at>[0-9.]+)", spec[m.end():])
        yield m, m.group("where"), float(at.group("at")) if at else 0.0


def placed_times(spec: str) -> list[float]:
    """The times [s] simulated of ``spec``'s placed faults, in order (empty: none placed)."""
    return [t for _m, _where, t in _placed(spec)]


def time_key(t: float) -> str:
    """The key of a fault's time in :func:`positions_at`'s answer (``"360"``)."""
    return f"{t:g}"


def positions_at(summary_path: Path, times: list[float]) -> dict[str, list[list[float]]]:
    """The robots' positions at each of ``times`` in a no-fault run's simulator summary.

    Args:
        summary_path: the run's ``sim_summary.json`` (its ``track``: ``period_s`` and ``xy``,
            one (N, 2) list [m] in ``map`` per tick, the first at ``period_s``).
        times: [s] simulated.

    Returns:
        ``{time_key(t): (N, 2) list}`` [m], what a run's record keeps as
        ``victim_positions`` so that the fault runs can be placed from the records alone.

    Raises:
        InputError: the summary or its track is missing, or the run ended before a time.
    """
    try:
        track = json.loads(Path(summary_path).read_text())["track"]
        period, xy = float(track.get("period_s") or 1.0), track.get("xy") or []
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        raise InputError(f"no track in '{summary_path}'") from None
    out = {}
    for t in times:
        k = int(round(t / period)) - 1
        if not 0 <= k < len(xy):
            raise InputError(f"the run of '{summary_path}' ended before {t:g} s")
        out[time_key(t)] = xy[k]
    return out


def resolve_spec(spec: str, positions: dict[str, list], docks: np.ndarray,
                 prefix: str = "Srobot") -> str:
    """The concrete spec of a placed one, from the no-fault run of the same seed.

    Args:
        spec: the ``--fault-spec`` (returned as it is when it names no placement).
        positions: that run's robots' positions at the faults' times (:func:`positions_at`).
        docks: (K, 2) the world's docking positions [m].
        prefix: the robots' namespace prefix (robot i + 1 is ``<prefix><i + 1>``).

    Raises:
        InputError: ``positions`` lacks a fault's time.
    """
    chosen: list[int] = []
    out = spec
    for m, where, t in list(_placed(spec)):
        if time_key(t) not in positions:
            raise InputError(f"--fault-spec '{spec}': no positions at {t:g} s")
        victim = choose_victim(np.asarray(positions[time_key(t)], dtype=float),
                               np.asarray(docks, float), where, tuple(chosen))
        chosen.append(victim)
        out = out.replace(m.group(0), f":{prefix}{victim + 1}", 1)
    return out
