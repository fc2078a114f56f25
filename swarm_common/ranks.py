"""The contract between the hosts of one swarm (``swarm-up --hosts N --host-rank R``), written
once.

Every host runs ``swarm-up`` with the same run flags and its own rank. Rank 0 publishes the
run's identity on ``/swarm/run`` (:class:`RunIdentity`, latched): every other rank compares it
with its own flags before it starts anything, and exits 2 naming the first setting that differs.
Every rank publishes a :class:`RankReport` on ``/swarm/ranks`` once a second (wall): it is
alive, which robots it runs, its CPU, memory and restarts; rank 0 puts them into its summary and
notices a rank that falls silent. Rank 0's identity with ``state: ending`` ends the other ranks.
Both are ``std_msgs/String`` whose ``data`` is one JSON object (names and QoS:
:mod:`swarm_common.topics`). Pure: no ROS import.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields

from swarm_common.coordination import load_object

UP, ENDING = "up", "ending"
STARTING, REFUSED = "starting", "refused"
RANK_STATES = (STARTING, UP, REFUSED, ENDING)

# what must be the same on every host: (field, the flag a user changes it with)
IDENTITY_SETTINGS = (
    ("hosts", "--hosts"), ("host_weights", "--host-weights"), ("swarm_size", "--swarm-size"),
    ("name_prefix", "--name-prefix"), ("fleet", "--robot"), ("seed", "--seed"),
    ("world", "--world"), ("map", "--map"), ("nav_template", "--nav-params"),
    ("coordination", "--coordination"), ("commanders", "--commanders"),
    ("faults", "--faults"), ("discovery_server", "--discovery-server"),
)


class RankContractError(ValueError):
    """A message that does not follow the contract (the reader drops it and warns)."""


@dataclass(frozen=True)
class RunIdentity:
    """What makes two hosts' flags the same run (rank 0 publishes its own).

    Attributes:
        hosts: ``--hosts``.
        host_weights: ``--host-weights`` (empty: equal).
        swarm_size: robots.
        name_prefix: their namespaces' prefix.
        fleet: every robot's model: its name, or ``sha256:<digest>`` of a model given by path.
        seed: ``--seed``.
        world: ``sha256:<digest>`` of the world file (hosts may keep it at different paths).
        map: ``sha256:<digest>`` of the map's YAML and image, or ``""`` (rasterised from the
            world).
        nav_template: ``sha256:<digest>`` of the navigator parameter template.
        coordination: ``decentralized`` | ``centralized``.
        commanders: ``--commanders``.
        faults: the fault schedule as text (its YAML), or ``""``.
        discovery_server: ``--discovery-server`` or ``""``.
        session: rank 0's run id (new at every start); not compared.
        state: ``up``, or ``ending`` once rank 0's run ends (the other ranks then end too).
    """

    hosts: int
    host_weights: tuple[float, ...]
    swarm_size: int
    name_prefix: str
    fleet: tuple[str, ...]
    seed: int
    world: str
    map: str
    nav_template: str
    coordination: str
    commanders: bool
    faults: str
    discovery_server: str
    session: str = ""
    state: str = UP

    def differences(self, other: RunIdentity) -> list[tuple[str, str, str]]:
        """The settings that differ, as ``(flag, this value, the other's value)``, in the
        order of :data:`IDENTITY_SETTINGS`; values shortened for one line."""
        out = []
        for name, flag in IDENTITY_SETTINGS:
            mine, theirs = getattr(self, name), getattr(other, name)
            if mine != theirs:
                out.append((flag, _show(mine), _show(theirs)))
        return out

    def encode(self) -> str:
        """The ``std_msgs/String.data`` (compact JSON)."""
        return json.dumps(asdict(self), separators=(",", ":"))

    @classmethod
    def decode(cls, text: str) -> RunIdentity:
        """Parse an identity.

        Raises:
            RankContractError: malformed (names the key).
        """
        d = _load(text)
        names = {f.name for f in fields(cls)}
        missing = sorted(names - set(d) - {"session", "state"})
        if missing:
            raise RankContractError(f"missing key {missing[0]!r}")
        try:
            return cls(**{k: tuple(v) if isinstance(v, list) else v
                          for k, v in d.items() if k in names})
        except TypeError as exc:
            raise RankContractError(str(exc)) from None


@dataclass(frozen=True)
class RankReport:
    """One rank's report, every second (wall).

    Attributes:
        rank: the rank.
        session: this ``swarm-up``'s run id (new at every start): two sessions of one rank
            are a rank started twice.
        host: the host's name.
        pid: ``swarm-up``'s process id there.
        robots: how many robots it runs.
        state: ``starting`` (waiting for rank 0), ``up``, ``refused`` (its flags differ:
            ``reason`` says how; it exits 2) or ``ending``.
        reason: why it refused or ends, else ``""``.
        cpu_percent: its processes' CPU [% of one core] over the run so far, or None.
        peak_rss_mb: their peak RSS summed [MB], or None.
        restarts: supervised restarts on this host.
        fault_restarts: those of ``restarts`` that the fault schedule caused.
    """

    rank: int
    session: str
    host: str
    pid: int
    robots: int
    state: str = STARTING
    reason: str = ""
    cpu_percent: float | None = None
    peak_rss_mb: float | None = None
    restarts: int = 0
    fault_restarts: int = 0

    def encode(self) -> str:
        """The ``std_msgs/String.data`` (compact JSON)."""
        return json.dumps(asdict(self), separators=(",", ":"))

    @classmethod
    def decode(cls, text: str) -> RankReport:
        """Parse a report.

        Raises:
            RankContractError: malformed.
        """
        d = _load(text)
        try:
            rep = cls(**{k: v for k, v in d.items() if k in {f.name for f in fields(cls)}})
        except TypeError as exc:
            raise RankContractError(str(exc)) from None
        if rep.state not in RANK_STATES or not isinstance(rep.rank, int) or rep.rank < 0:
            raise RankContractError(f"state {rep.state!r} or rank {rep.rank!r}")
        return rep


def _show(value) -> str:
    if isinstance(value, tuple | list):
        text = ",".join(map(str, value)) or "(none)"
    elif isinstance(value, str) and value.startswith("sha256:"):
        text = value[:19]  # the first 12 hex digits name a file's content well enough
    else:
        text = str(value) if value != "" else "(none)"
    return text if len(text) <= 60 else text[:57] + "..."


def _load(text: str) -> dict:
    return load_object(text, RankContractError)
