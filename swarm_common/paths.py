"""Where the bundled data lives (the repository root of an editable install)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORLDS_DIR = ROOT / "worlds"
MAPS_DIR = ROOT / "maps"
ROBOTS_DIR = ROOT / "robots"
PARAMS_DIR = ROOT / "params"
ROBOT_PARAMS_DIR = PARAMS_DIR / "robots"
