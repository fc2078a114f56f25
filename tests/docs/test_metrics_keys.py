"""docs/reference/metrics.md against real metrics.json files: no key undocumented, none invented.

The samples in ``tests/docs/data/`` are copies of ``swarm-up --metrics`` files (a decentralized
run, a centralized one, one with faults and ``--record``; ``data/README.md`` says how they were
made). A key is a dotted path; the page writes a dict keyed by robot, model, topic or fault kind
once with a placeholder (``per_robot.<ns>.tasks``) and a list's entries as ``name[].field``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "reference" / "metrics.md"
SAMPLES = sorted((Path(__file__).parent / "data").glob("metrics_*.json"))
ROW = re.compile(r"^\| `([^`]+)` \|")
PLACEHOLDER = re.compile(r"^<[a-z]+>$")


def documented_keys(text: str) -> set[str]:
    """The keys of the page's tables: the first cell of every row, in backticks."""
    return {m.group(1) for line in text.splitlines() if (m := ROW.match(line))}


def placeholder_prefixes(keys: set[str]) -> dict[str, str]:
    """Dotted prefix -> placeholder, for every dict the page writes with a placeholder."""
    out = {}
    for key in keys:
        parts = key.split(".")
        for i, part in enumerate(parts):
            if PLACEHOLDER.match(part):
                out[".".join(parts[:i])] = part
    return out


def flatten(value, prefixes: dict[str, str], path: str = "") -> set[str]:
    """The dotted keys of a metrics dict, children of placeholder dicts replaced.

    An empty dict or list is a key of its own (``faults_by_kind`` of a run without faults).
    """
    if isinstance(value, dict) and value:
        out = set()
        for key, child in value.items():
            name = prefixes.get(path, key)
            out |= flatten(child, prefixes, f"{path}.{name}" if path else name)
        return out
    if isinstance(value, list) and any(isinstance(v, dict) for v in value):
        out = set()
        for entry in value:
            out |= flatten(entry, prefixes, f"{path}[]")
        return out
    return {path}


def documented(key: str, keys: set[str]) -> bool:
    """A key of the page, or an empty dict or list whose entries the page documents."""
    return key in keys or any(k.startswith((f"{key}.", f"{key}[]")) for k in keys)


@pytest.fixture(scope="module")
def keys():
    return documented_keys(PAGE.read_text())


@pytest.fixture(scope="module")
def samples(keys):
    prefixes = placeholder_prefixes(keys)
    return {p.name: flatten(json.loads(p.read_text()), prefixes) for p in SAMPLES}


def test_there_are_samples_of_each_mode():
    names = {p.name for p in SAMPLES}
    assert {"metrics_decentralized.json", "metrics_centralized.json",
            "metrics_faults.json"} <= names


@pytest.mark.parametrize("sample", [p.name for p in SAMPLES])
def test_every_key_of_a_real_file_is_documented(sample, samples, keys):
    missing = sorted(k for k in samples[sample] if not documented(k, keys))
    assert not missing, f"{sample}: keys not in docs/reference/metrics.md: {missing}"


def test_every_documented_key_exists(samples, keys):
    seen = set().union(*samples.values())
    invented = sorted(keys - seen)
    assert not invented, f"docs/reference/metrics.md documents keys no sample has: {invented}"


def test_flatten_replaces_placeholders():
    prefixes = {"per_robot": "<ns>"}
    doc = {"per_robot": {"Srobot1": {"tasks": 1}, "Srobot2": {"tasks": 2}},
           "standstills": [{"robot": "Srobot1"}], "task_times_s": [1.0], "fleet": {}}
    flat = flatten(doc, prefixes)
    assert flat == {"per_robot.<ns>.tasks", "standstills[].robot", "task_times_s", "fleet"}
    assert documented("fleet", {"fleet.<model>"})
    assert not documented("fleets", {"fleet.<model>"})
