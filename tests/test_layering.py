"""Which package may import which (docs/ARCHITECTURE.md), checked on the source with ``ast``.

- ``swarm_common`` is the bottom layer: it imports no sibling package.
- ``swarm_nav`` never imports ``swarm_commander``: the navigator does not know its own client
  (the process hosting both is ``swarm_up.group``).
- ``swarm_up`` never imports the simulator's engine or PyBullet: it checks ``--swarm-size``
  with ``swarm_common.spawn`` and runs the simulator as a child process.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("swarm_common", "swarm_sim", "swarm_nav", "swarm_commander", "swarm_up")

# package -> module prefixes it must not import (any import statement, also inside a function)
FORBIDDEN = {
    "swarm_common": tuple(p for p in PACKAGES if p != "swarm_common"),
    "swarm_nav": ("swarm_commander",),
    "swarm_up": ("swarm_sim.engine", "pybullet"),
}


def imports_of(path: Path) -> set[str]:
    """Every module named by an import statement of the file (relative ones resolved)."""
    package = path.parent.name
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = f"{package}.{base}" if base else package
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    return out


def _cases():
    for package, banned in FORBIDDEN.items():
        for path in sorted((ROOT / package).glob("*.py")):
            yield pytest.param(path, banned, id=f"{package}/{path.name}")


@pytest.mark.parametrize(("path", "banned"), list(_cases()))
def test_package_imports_only_what_it_may(path, banned):
    bad = sorted(m for m in imports_of(path)
                 if any(m == b or m.startswith(f"{b}.") for b in banned))
    assert not bad, f"{path.relative_to(ROOT)} imports {bad}"


def test_the_check_sees_imports_inside_functions(tmp_path):
    pkg = tmp_path / "swarm_nav"
    pkg.mkdir()
    mod = pkg / "x.py"
    mod.write_text("def f():\n    from swarm_commander.route import build_route\n"
                   "    import pybullet as pb\n")
    assert {"swarm_commander.route", "pybullet"} <= imports_of(mod)
