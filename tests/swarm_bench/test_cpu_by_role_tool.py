"""tools/cpu_by_role.py (the scaling pages' CPU by role): a sample names each process's role."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import psutil

from swarm_common.paths import ROOT


def _tool():
    spec = importlib.util.spec_from_file_location("cpu_by_role", ROOT / "tools" / "cpu_by_role.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_sample_gives_each_process_of_the_tree_its_role_and_cpu():
    tool = _tool()
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)",
                              "swarm_up.group"])  # its command line names a group process
    try:
        cpu: dict[int, tuple[str, float]] = {}
        tool.sample(psutil.Process(), cpu)
        assert cpu[child.pid][0] == "group"
        assert all(seconds >= 0.0 for _, seconds in cpu.values())
        assert tool.by_role(cpu)["group"] >= 0.0
    finally:
        child.kill()
        child.wait()
