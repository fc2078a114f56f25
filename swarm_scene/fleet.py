"""Which robot model each robot of a swarm is: ``--robot`` as one model or a mix.

The contract: docs/reference/contract.md#s2, #s4.

``--robot`` of ``swarm-up`` and ``swarm-sim`` takes

- one model, ``NAME|PATH`` (a robot under ``robots/`` or a ``.urdf``/``.xacro`` path): every
  robot is that model;
- a mix, ``NAME:COUNT,NAME:COUNT,...`` (``turtlebot3_waffle:12,turtlebot3_burger:4,
  linorobot2_2wd:4``), whose counts add up to the swarm size; a ``PATH:COUNT`` entry is split at
  its last ``:``, and a path may not contain ``,``;
- a fleet file, a ``.yaml``/``.yml`` path with the same mix as a list (relative robot paths are
  relative to the file)::

      fleet:
        - {robot: turtlebot3_waffle, count: 12}
        - {robot: turtlebot3_burger, count: 4}

The models of a mix are spread evenly over the robot numbers (:func:`interleave`, a Bresenham-
style rule: deterministic; robot 1 is the most numerous model, the first listed of a tie), so
that each model is mixed through the spawn grid instead of standing in a block.

Pure: no ROS, no robot loading (the callers load each model with
:func:`swarm_scene.robot_model.load_robot`).  Errors are :class:`InputError` messages without the
flag; the commands prefix ``--robot: ``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from swarm_common.errors import InputError, check_keys, did_you_mean, read_yaml

FLEET_SUFFIXES = (".yaml", ".yml")
_ENTRY_KEYS = ("robot", "count")


def is_fleet_file(text: str) -> bool:
    """Whether ``--robot``'s value names a fleet file (ends in ``.yaml`` or ``.yml``)."""
    return text.strip().lower().endswith(FLEET_SUFFIXES)


def parse_fleet(text: str) -> tuple[tuple[str, int | None], ...]:
    """Parse ``--robot``'s value into (model, count) entries, in the order given.

    Args:
        text: ``NAME|PATH``, ``NAME:COUNT,NAME:COUNT,...`` or a fleet file's path (module
            docstring).

    Returns:
        ``((model, None),)`` for one model (every robot is it), else one ``(model, count)`` per
        entry; a model is a name under ``robots/`` or a path (relative paths of a fleet file made
        relative to the working directory).

    Raises:
        InputError: an empty entry, an entry without ``:COUNT`` in a mix, a count that is not a
            positive integer, a model given twice, or a fleet file that is missing, not YAML, has
            an unknown key (did-you-mean) or no entries.
    """
    text = text.strip()
    if not text:
        raise InputError("empty; expected NAME|PATH or NAME:COUNT,NAME:COUNT,...")
    if is_fleet_file(text):
        return _read_fleet_file(Path(text).expanduser())
    items = text.split(",")
    if len(items) == 1 and ":" not in text:
        return ((text, None),)
    entries = []
    for item in items:
        item = item.strip()
        if not item:
            raise InputError(f"empty entry in '{text}'; expected NAME:COUNT,NAME:COUNT,...")
        model, sep, count = item.rpartition(":")
        if not sep or not model.strip():
            raise InputError(f"'{item}': a mix needs NAME:COUNT for every model")
        entries.append((model.strip(), _count(count.strip(), item)))
    _no_repeats(entries)
    return tuple(entries)


def fleet_models(text: str, n: int) -> tuple[str, ...]:
    """The model of every robot, robot 1 first, for ``--robot text`` and ``n`` robots.

    Args:
        text: ``--robot``'s value (:func:`parse_fleet`).
        n: the swarm size (``--swarm-size``).

    Returns:
        (n,) model names or paths, as given: one model repeated, or a mix interleaved
        (:func:`interleave`).

    Raises:
        InputError: :func:`parse_fleet`'s errors, or counts whose sum is not ``n``.
    """
    entries = parse_fleet(text)
    if entries[0][1] is None:
        return (entries[0][0],) * n
    total = sum(count for _, count in entries)
    if total != n:
        raise InputError(f"the counts of '{text}' add up to {total}, not to --swarm-size {n}")
    return interleave(entries)


def fleet_total(text: str) -> int | None:
    """The number of robots a mix or fleet file names (None for one model: any number).

    Raises:
        InputError: :func:`parse_fleet`'s errors.
    """
    entries = parse_fleet(text)
    return None if entries[0][1] is None else sum(count for _, count in entries)


def interleave(entries: Sequence[tuple[str, int]]) -> tuple[str, ...]:
    """Spread a mix's models evenly over robots 1..N (Bresenham-style, deterministic).

    Robot ``k`` (0-based) is the model ``t`` whose count lags its share most:
    ``(k + 1) * count_t - placed_t * N`` largest, the earlier listed on a tie (integers only,
    so no rounding decides).  Every model gets exactly its count, and after any ``k`` robots
    each model's number is within one of ``k * count_t / N``.

    Args:
        entries: ``(model, count)`` pairs, counts > 0.

    Returns:
        (N,) the models, N the sum of the counts: ``a:3,b:1`` gives ``a a b a``,
        ``waffle:12,burger:4,lino:4`` gives ``W B W L W`` four times over.
    """
    counts = [int(c) for _, c in entries]
    n = sum(counts)
    placed = [0] * len(counts)
    out = []
    for k in range(n):
        lags = [(k + 1) * c - p * n for c, p in zip(counts, placed, strict=True)]
        t = max(range(len(counts)), key=lambda j: (lags[j], -j))
        placed[t] += 1
        out.append(entries[t][0])
    return tuple(out)


def model_label(model: str) -> str:
    """A model's short name: a name as given, a path by its file name without suffixes."""
    if "/" not in model and "\\" not in model and not Path(model).suffix:
        return model
    name = Path(model).name
    for suffix in (".urdf.xacro", ".urdf", ".xacro"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def fleet_counts(models: Sequence[str]) -> dict[str, int]:
    """``{label: count}`` of a fleet's models (:func:`model_label`), in order of first robot."""
    out: dict[str, int] = {}
    for model in models:
        label = model_label(model)
        out[label] = out.get(label, 0) + 1
    return out


def describe_fleet(models: Sequence[str]) -> str:
    """``"20 (12 turtlebot3_waffle, 4 turtlebot3_burger, 4 linorobot2_2wd)"``; ``"20"`` when
    every robot is the same model."""
    counts = fleet_counts(models)
    if len(counts) <= 1:
        return str(len(models))
    return f"{len(models)} (" + ", ".join(f"{c} {m}" for m, c in counts.items()) + ")"


def format_fleet(entries: Sequence[tuple[str, int | None]]) -> str:
    """The ``--robot`` text of :func:`parse_fleet`'s entries: ``NAME:COUNT,...`` in their order,
    or the one model alone; :func:`parse_fleet` of it gives the entries back (a fleet file is
    passed on to the simulator so)."""
    if len(entries) == 1 and entries[0][1] is None:
        return entries[0][0]
    return ",".join(f"{model}:{count}" for model, count in entries)


# ------------------------------------------------------------------------------------- helpers
def _count(text: str, item: str) -> int:
    if not text.isdigit() or int(text) <= 0:
        raise InputError(f"'{item}': the count must be a positive integer, got '{text}'")
    return int(text)


def _no_repeats(entries) -> None:
    seen = set()
    for model, _ in entries:
        if model in seen:
            raise InputError(f"'{model}' is listed twice; give each model once with its count")
        seen.add(model)


def _read_fleet_file(path: Path) -> tuple[tuple[str, int], ...]:
    """The entries of a fleet file (module docstring), paths made relative to the cwd."""
    data = read_yaml(path, InputError(f"{path}: no such fleet file"))
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a mapping with the key 'fleet'")
    for key in data:
        if key != "fleet":
            raise InputError(f"{path}: unknown key '{key}'{did_you_mean(str(key), ['fleet'])}")
    items = data.get("fleet")
    if not isinstance(items, list) or not items:
        raise InputError(f"{path}: 'fleet' must be a non-empty list of {{robot, count}}")
    entries = []
    for k, item in enumerate(items):
        where = f"{path}: fleet[{k}]"
        if not isinstance(item, dict):
            raise InputError(f"{where}: expected {{robot: NAME|PATH, count: N}}")
        check_keys(where, item, _ENTRY_KEYS, _ENTRY_KEYS)
        model, count = str(item["robot"]).strip(), item["count"]
        if isinstance(count, bool) or not isinstance(count, int) or count <= 0:
            raise InputError(f"{where}: count must be a positive integer, got {count!r}")
        if "/" in model or Path(model).suffix:  # a path: relative to the fleet file
            model = str((path.parent / Path(model).expanduser()).resolve())
        entries.append((model, count))
    try:
        _no_repeats(entries)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
    return tuple(entries)
