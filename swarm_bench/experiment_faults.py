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
the concrete spec (``kill-robot:17@360``). Ties go to the lower robot number.
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
    out = [m.group("where") for m in _PLACED.finditer(spec)]
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


def resolve_spec(spec: str, summary_path: Path, docks: np.ndarray, prefix: str = "Srobot"
                 ) -> str:
    """The concrete spec of a placed one, from the no-fault run's simulator summary.

    Args:
        spec: the ``--fault-spec`` (returned as it is when it names no placement).
        summary_path: the no-fault run of the same seed's ``sim_summary.json``.
        docks: (K, 2) the world's docking positions [m].
        prefix: the robots' namespace prefix (robot i + 1 is ``<prefix><i + 1>``).

    Raises:
        InputError: that run or its track is missing, or ends before the fault.
    """
    places = placement_of(spec)
    if not places:
        return spec
    try:
        track = json.loads(Path(summary_path).read_text())["track"]
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(f"--fault-spec '{spec}': no track in '{summary_path}' (the no-fault "
                         "run of this seed must run first, in this experiment)") from None
    chosen: list[int] = []
    out = spec
    for m in list(_PLACED.finditer(spec)):
        after = spec[m.end():]
        at = re.match(r"(?:/[^@]*)?@(?P<at>[0-9.]+)", after)
        t = float(at.group("at")) if at else 0.0
        k = int(round(t / float(track.get("period_s") or 1.0))) - 1
        xy = track.get("xy") or []
        if not 0 <= k < len(xy):
            raise InputError(f"--fault-spec '{spec}': the no-fault run ended before {t:g} s")
        victim = choose_victim(np.asarray(xy[k], dtype=float), np.asarray(docks, float),
                               m.group("where"), tuple(chosen))
        chosen.append(victim)
        out = out.replace(m.group(0), f":{prefix}{victim + 1}", 1)
    return out
