"""swarm_nav.jit.warm_up reaches every compiled kernel the Python code calls, once per process."""

import re
from pathlib import Path

from numba.core.registry import CPUDispatcher

import swarm_nav
from swarm_nav import (
    core_kernels,
    costmap_kernels,
    dwa_kernels,
    jit,
    perception_kernels,
    planner_kernels,
)

KERNEL_MODULES = (core_kernels, costmap_kernels, dwa_kernels, perception_kernels, planner_kernels)


def test_warm_up_compiles_or_loads_every_kernel_the_python_code_calls():
    jit.warm_up()  # the test session already did (tests/conftest.py): returns at once
    assert jit.warm_up() == 0.0
    here = Path(swarm_nav.__file__).parent
    python = "".join(p.read_text() for p in here.glob("*.py") if not p.stem.endswith("_kernels"))
    called = {f"{mod.__name__}.{name}": fn
              for mod in KERNEL_MODULES for name, fn in vars(mod).items()
              if isinstance(fn, CPUDispatcher) and fn.__module__ == mod.__name__
              and re.search(rf"\.{name}\(", python)}
    assert len(called) >= 14  # the scan finds them (14 since the perception's one-step
    # wrappers moved to tests/swarm_nav/perception_steps.py; the kernels call the others)
    assert [name for name, fn in called.items() if not fn.signatures] == []
