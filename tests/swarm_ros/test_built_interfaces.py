"""The interface packages built here (swarm_ros/built_interfaces.py): what is built, and what
happens without a compiler or after a failed build (no real build: those are monkeypatched)."""

from __future__ import annotations

import pytest

from swarm_ros import built_interfaces as bi


def test_the_session_built_both_packages_and_check_says_so(capsys):
    # tests/conftest.py builds them before the session (as swarm-up does before a run)
    assert bi.main(["--check"]) == 0
    out = capsys.readouterr().out
    assert "tf2_msgs: built" in out and "simulation_interfaces: built" in out
    from simulation_interfaces.msg import SimulatorFeatures
    from tf2_msgs.msg import TFMessage

    assert SimulatorFeatures.STEP_SIMULATION_MULTIPLE == 32 and TFMessage().transforms == []


def test_a_changed_definition_is_not_taken_for_built(monkeypatch):
    assert bi.built("tf2_msgs")
    monkeypatch.setattr(bi, "source_digest", lambda package: "0" * 64)
    assert not bi.built("tf2_msgs")


def _no_build(*args, **kwargs):
    raise AssertionError("nothing may be built")


def test_without_a_compiler_nothing_is_built_and_one_line_says_what_is_missing(monkeypatch):
    monkeypatch.setattr(bi, "built", lambda package: False)
    monkeypatch.setattr(bi, "build", _no_build)
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.delenv("CXX", raising=False)
    monkeypatch.setattr(bi.shutil, "which", lambda name, *a, **k: None)
    said: list[str] = []
    got = bi.ensure(say=said.append)
    assert got.ready == frozenset() and "no C/C++ compiler" in got.missing
    assert len(said) == 1
    assert said[0].startswith("warning: tf2_msgs, simulation_interfaces not available: no C/C++")
    assert "/tf and the simulation_interfaces services are off" in said[0]


def test_a_failed_build_is_said_and_not_tried_again_until_asked(monkeypatch, tmp_path):
    (tmp_path / "share").mkdir()
    monkeypatch.setattr(bi, "prefix", lambda: tmp_path)
    monkeypatch.setattr(bi, "built", lambda package: False)
    monkeypatch.setattr(bi, "missing_prerequisite", lambda: None)
    calls = []

    def failing(package, log):
        calls.append(package)
        raise RuntimeError(f"{package}: 'cmake --build' failed (exit 2)")

    monkeypatch.setattr(bi, "build", failing)
    said: list[str] = []
    first = bi.ensure(say=said.append)
    assert calls == ["tf2_msgs"] and first.ready == frozenset()
    assert said[0].startswith("building tf2_msgs, simulation_interfaces")
    assert "the build failed: tf2_msgs: 'cmake --build' failed" in said[1]
    said.clear()
    again = bi.ensure(say=said.append)
    assert calls == ["tf2_msgs"] and again.ready == frozenset()
    assert len(said) == 1 and "their last build failed" in said[0]
    bi.ensure(say=said.append, retry=True)
    assert calls == ["tf2_msgs", "tf2_msgs"]


@pytest.mark.parametrize("package", bi.PACKAGES)
def test_each_definition_is_shipped_with_its_licence(package):
    assert (bi.SOURCES / package / "LICENSE").is_file()
    assert (bi.SOURCES / package / "package.xml").is_file()
    assert len(bi.source_digest(package)) == 64
