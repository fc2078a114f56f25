"""Load a script of ``tools/`` as a module, for the tests of the tools."""

from __future__ import annotations

import importlib.util
from types import ModuleType

from swarm_common.paths import ROOT


def load_tool(name: str) -> ModuleType:
    """``tools/<name>.py`` imported as the module ``name`` (the tools are scripts, not a
    package)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
