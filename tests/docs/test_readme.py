"""README.md is a front door: short, the two fresh-machine commands first, no commit hashes."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
MAX_LINES = 250
HASH_LIKE = re.compile(r"\b[0-9a-f]{7,40}\b")
COMMANDS = (
    "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/swarm-up --swarm-size 20 "
    "--world slim_blockage --commanders --rtf 0 --duration 600",
    'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && .venv/bin/python -m pytest',
)
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def test_readme_is_short():
    assert len(README.splitlines()) <= MAX_LINES


def test_readme_names_no_commit():
    hits = [line for line in README.splitlines() if HASH_LIKE.search(line)]
    assert not hits, f"hash-like words in README.md (results go to docs/results/): {hits}"


def test_the_two_commands_come_first():
    head = README.splitlines()[:20]
    at = [head.index(cmd) for cmd in COMMANDS]
    assert at == sorted(at), "the set-up-and-run command comes before the test command"
    blocks = re.findall(r"```bash\n(.*?)```", README, re.S)
    assert [line for line in blocks[0].splitlines() if not line.startswith("#") and line] \
        == list(COMMANDS), "the first code block holds exactly the two commands"


def test_getting_started_gives_the_same_commands():
    page = (ROOT / "docs" / "getting_started.md").read_text()
    for cmd in COMMANDS:
        assert cmd in page.splitlines()


def test_readme_links_point_to_files():
    missing = [target for target in LINK.findall(README)
               if "://" not in target and not (ROOT / target).exists()]
    assert not missing, f"README.md links to missing files: {missing}"
