"""Project-wide checks: the pure core stays ROS-free, and lint is part of the suite."""

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ROS_SHELLS = {"node.py", "sim_services.py", "tf_publisher.py"}  # the simulator's ROS side


def _pure_modules():
    mods = [p for pkg in ("swarm_common", "swarm_scene")
            for p in sorted((ROOT / pkg).glob("*.py"))]
    for pkg in ("swarm_sim", "swarm_nav", "swarm_coordinator"):
        mods += [p for p in sorted((ROOT / pkg).glob("*.py")) if p.name not in ROS_SHELLS]
    return mods


@pytest.mark.parametrize("path", _pure_modules(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_core_module_imports_no_ros(path):
    tree = ast.parse(path.read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module.split(".")[0])
    ros = {m for m in imported if m in ("rclpy", "builtin_interfaces") or m.endswith("_msgs")
           or m.endswith("_srvs")}
    assert not ros, f"{path.name} imports {sorted(ros)}; keep the core pure"


def test_ruff_clean():
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    assert ruff, "ruff is part of the test extra; install with pip install -e '.[test]'"
    res = subprocess.run([ruff, "check", "--quiet", str(ROOT)], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
