"""Which package may import which (docs/ARCHITECTURE.md), checked on the source with ``ast``.

- ``swarm_common`` (the wire's contracts and small utilities) is the bottom layer: it imports no
  sibling package.  ``swarm_scene`` (the world, robot, map and fleet loaders) imports only
  ``swarm_common``; ``swarm_ros``, the ROS side every node shares, imports only
  ``swarm_common``.
- ``swarm_nav`` never imports ``swarm_commander``: the navigator does not know its own client
  (the process hosting both is ``swarm_up.group``).
- ``swarm_up`` never imports the simulator's engine or PyBullet: it checks ``--swarm-size``
  with ``swarm_scene.spawn`` and runs the simulator as a child process.
- The orchestrator (``swarm_up``) uses the metrics, the live view and the recording, never the
  benchmark (``swarm_bench``), which runs it; ``swarm_metrics``, ``swarm_viz`` and
  ``swarm_record`` import neither.
- No module imports itself through others: the import graph of all the packages (imports inside
  functions included) has no circle.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("swarm_common", "swarm_scene", "swarm_ros", "swarm_sim", "swarm_nav",
            "swarm_commander", "swarm_coordinator", "swarm_up", "swarm_metrics", "swarm_viz",
            "swarm_record", "swarm_bench")

# package -> module prefixes it must not import (any import statement, also inside a function)
FORBIDDEN = {
    "swarm_common": tuple(p for p in PACKAGES if p != "swarm_common"),
    "swarm_scene": tuple(p for p in PACKAGES if p not in ("swarm_common", "swarm_scene")),
    "swarm_ros": tuple(p for p in PACKAGES if p not in ("swarm_common", "swarm_ros")),
    "swarm_nav": ("swarm_commander",),
    "swarm_up": ("swarm_sim.engine", "pybullet", "swarm_bench"),
    "swarm_metrics": ("swarm_up", "swarm_bench", "swarm_viz", "swarm_record"),
    "swarm_viz": ("swarm_up", "swarm_bench", "swarm_record"),
    "swarm_record": ("swarm_up", "swarm_bench", "swarm_viz", "swarm_metrics"),
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


# ------------------------------------------------------------------------------------ circles
def module_name(path: Path) -> str:
    """``swarm_up/args.py`` -> ``swarm_up.args``; a package's ``__init__.py`` -> the package."""
    return path.parent.name if path.stem == "__init__" else f"{path.parent.name}.{path.stem}"


def import_graph(root: Path = ROOT, packages=PACKAGES) -> dict[str, set[str]]:
    """Module -> the modules of ``packages`` it imports (any import statement, also inside a
    function; ``from pkg import mod`` names the module ``pkg.mod``)."""
    paths = {module_name(p): p for pkg in packages for p in sorted((root / pkg).glob("*.py"))}
    graph = {}
    for name, path in paths.items():
        deps = set()
        for imported in imports_of(path):
            while imported and imported not in paths:
                imported = imported.rpartition(".")[0]  # pkg.mod.func -> pkg.mod
            if imported and imported != name:
                deps.add(imported)
        graph[name] = deps
    return graph


def find_circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One circle of ``graph`` as ``[a, b, ..., a]``, or None (depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == 1:
                return path[path.index(dep):] + [dep]
            if dep not in state:
                found = visit(dep)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_no_import_circle():
    circle = find_circle(import_graph())
    assert circle is None, "import circle: " + " -> ".join(circle)


def test_the_circle_check_finds_a_circle_through_a_function(tmp_path):
    pkg = tmp_path / "swarm_up"
    pkg.mkdir()
    (pkg / "args.py").write_text("from swarm_up.rundir import load\n")
    (pkg / "rundir.py").write_text("def load():\n    from swarm_up import args\n")
    (pkg / "cli.py").write_text("from swarm_up.args import load\n")
    graph = import_graph(tmp_path, ("swarm_up",))
    assert graph["swarm_up.cli"] == {"swarm_up.args"}
    assert find_circle(graph) == ["swarm_up.args", "swarm_up.rundir", "swarm_up.args"]
