"""The generated reference pages equal what tools/gen_docs.py writes from today's code."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
HINT = "out of date: run python tools/gen_docs.py and commit the page"


def _load_generator():
    spec = importlib.util.spec_from_file_location("gen_docs", ROOT / "tools" / "gen_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen_docs = _load_generator()


def _flatten(d, prefix=""):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def test_parameters_page_is_up_to_date():
    page = ROOT / "docs" / "reference" / "parameters.md"
    assert page.read_text() == gen_docs.parameters_page(), f"{page.name} {HINT}"


def test_every_template_key_is_on_the_parameters_page():
    doc = yaml.safe_load((ROOT / "params" / "navigator.yaml").read_text())
    template = _flatten(doc["navigator"]["ros__parameters"])
    page = (ROOT / "docs" / "reference" / "parameters.md").read_text()
    names = set(re.findall(r'<span id="([^"]+)"></span>`\1`', page))
    missing = sorted(set(template) - names)
    assert not missing, f"params/navigator.yaml keys missing from parameters.md: {missing}"


def test_parameters_page_gives_type_default_and_unit():
    page = (ROOT / "docs" / "reference" / "parameters.md").read_text()
    row = next(line for line in page.splitlines() if '<span id="inflation_radius">' in line)
    assert "| float | `0.55` | m |" in row


@pytest.mark.e2e
def test_commands_page_is_up_to_date():
    page = ROOT / "docs" / "reference" / "commands.md"
    assert page.read_text() == gen_docs.commands_page(), f"{page.name} {HINT}"


def test_commands_page_lists_every_console_script():
    page = (ROOT / "docs" / "reference" / "commands.md").read_text()
    for name in gen_docs.console_scripts():
        assert f"\n## {name}\n" in page, f"{name} missing from commands.md: {HINT}"


def test_rviz_config_is_up_to_date_and_names_only_topics_the_swarm_has():
    import yaml

    from swarm_common import topics

    page = ROOT / "docs" / "swarm.rviz"
    assert page.read_text() == gen_docs.rviz_page(), f"{page.name} {HINT}"
    config = yaml.safe_load(page.read_text())["Visualization Manager"]
    assert config["Global Options"]["Fixed Frame"] == "map"
    groups = [d for d in config["Displays"] if d["Class"] == "rviz_common/Group"]
    assert [g["Name"] for g in groups] == [f"Srobot{i}" for i in range(1, 21)]
    known = {t.name: t for t in vars(topics).values() if isinstance(t, topics.Topic)}
    for group in groups:
        model, scan, plan = group["Displays"]
        assert model["TF Prefix"] == group["Name"]
        for display, topic in ((model["Description Topic"], topics.ROBOT_DESCRIPTION),
                               (scan["Topic"], topics.SCAN), (plan["Topic"], topics.PLAN)):
            assert display["Value"] == f"/{group['Name']}/{topic.name}"
            assert topic.name in known  # a topic of swarm_common.topics, with its writer's QoS
            durable = topic.qos.durability == topics.TRANSIENT_LOCAL
            assert (display["Durability Policy"] == "Transient Local") == durable
            best_effort = topic.qos.reliability == topics.BEST_EFFORT
            assert (display["Reliability Policy"] == "Best Effort") == best_effort


def test_topics_page_is_up_to_date():
    page = ROOT / "docs" / "reference" / "topics.md"
    assert page.read_text() == gen_docs.topics_page(), f"{page.name} {HINT}"


def test_every_topic_and_service_says_who_writes_and_reads_it():
    from swarm_common import topics

    found = [(k, v) for k, v in vars(topics).items()
             if isinstance(v, topics.Topic | topics.Service)]
    assert len(found) >= 17  # 16 topics and the navigator's cancel service when written
    for name, t in found:
        who = (t.writers, t.readers) if isinstance(t, topics.Topic) else (t.servers, t.clients)
        assert all(who), f"swarm_common.topics.{name}: say who writes and who reads it"


def test_topics_page_links_every_named_qos_it_uses():
    page = (ROOT / "docs" / "reference" / "topics.md").read_text()
    used = set(re.findall(r"\(#([a-z_]+_qos)\)", page))
    anchors = set(re.findall(r'<span id="([a-z_]+)"></span>', page))
    assert used and used <= anchors
