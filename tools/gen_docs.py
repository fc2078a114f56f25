"""Write the documentation's generated reference pages from the code.

    python tools/gen_docs.py           # rewrite the pages
    python tools/gen_docs.py --check   # exit 1 and name the pages that are out of date

Three pages of ``docs/reference/`` are written here and nowhere else, so they cannot drift from
the code (``tests/docs/test_generated.py`` fails when a page differs from this script's output):

- ``parameters.md``: every navigator parameter from :func:`swarm_nav.config.flat_defaults` (the
  table the node declares its ROS parameters from, and that ``params/navigator.yaml`` is checked
  against): name, type, default, unit, description, grouped by the settings dataclass it feeds.
- ``commands.md``: the ``--help`` of every console script in ``pyproject.toml``'s
  ``[project.scripts]``, each run in a subprocess through its entry point at a fixed width
  (``COLUMNS=100``), so the page follows the entry points when their modules move.
- ``topics.md``: every topic and service of :mod:`swarm_common.topics` (name, type, the QoS its
  writers offer, writers, readers, and the docstring after it as notes), its named QoS
  profiles, and the ``nav_status`` keys of :func:`swarm_common.nav_status.encode`.

Importable: the tests call :func:`pages` and compare.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import os
import re
import subprocess
import sys
import tomllib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
HELP_COLUMNS = 100  # [characters] the terminal width every --help is formatted for
REGENERATE = "python tools/gen_docs.py"

# The groups of flat_defaults(), in the order of params/navigator.yaml, with one line each.
GROUP_TEXT = {
    "navigator": "the control loop and replanning (`NavigatorConfig`)",
    "costmap": "the static costmap: nav2_costmap_2d's static and inflation layers "
               "(`CostmapConfig`)",
    "planner": "the global planner: optimal 8-connected grid search, NavFn and Smac names "
               "(`PlannerConfig`)",
    "dwa": "the local planner: DWA (Fox, Burgard and Thrun 1997) with DWB's names (`DwaConfig`)",
    "goal": "the goal checker and the final rotation (`GoalConfig`)",
    "perception": "the other robots seen in the scan (`PerceptionConfig`)",
    "holding": "goal-taken detection, the holding pattern, the queue and congestion rules "
               "(`HoldingConfig`)",
    "recovery": "the progress checker and the recoveries, the escape included "
                "(`RecoveryConfig`)",
    "traffic": "the traffic rules between robots that do not talk: keep right, yield "
               "(`TrafficConfig`)",
    "context": "the run context: set by `swarm-up` for each robot, not in "
               "`params/navigator.yaml`",
}

# Help text that depends on the machine it is printed on, made the same everywhere.
MACHINE_DEPENDENT = (
    (re.compile(r",\s+here\s+\d+\)"), ")"),  # swarm-up --processes: "number of cores, here 2"
)


# --------------------------------------------------------------------------- parameters
def _groups() -> dict[str, str]:
    """Flat parameter name -> the name of the settings dataclass it belongs to.

    Uses ``ParamInfo.group`` where the table carries it, else the fields of
    ``NavigatorConfig``: a field that is itself a dataclass is a group, named by the field.
    """
    from swarm_nav.config import NavigatorConfig, flat_defaults

    table = flat_defaults()
    if all(getattr(info, "group", None) for info in table.values()):
        return {name: info.group for name, info in table.items()}
    out: dict[str, str] = {}
    for f in dataclasses.fields(NavigatorConfig):
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else None
        if dataclasses.is_dataclass(default):
            for sub in dataclasses.fields(default):
                out[sub.metadata.get("param") or sub.name] = f.name
        else:
            out[f.metadata.get("param") or f.name] = "navigator"
    return {name: out.get(name, "navigator") for name in table}


def _context_params() -> dict[str, tuple]:
    """The navigator node's own parameters: name -> (default, unit, description).

    These are not algorithm settings: ``swarm-up`` sets them per robot (model, files, the
    handshake's waits), and the node declares them beside :func:`flat_defaults`.

    Raises:
        RuntimeError: the node has no such table (renamed or moved: update this function, so
            that the page does not silently lose them).
    """
    from swarm_nav import node

    for name in ("CONTEXT_PARAMS", "_CONTEXT_PARAMS"):
        table = getattr(node, name, None)
        if isinstance(table, dict):
            return dict(table)
    raise RuntimeError("swarm_nav.node declares no CONTEXT_PARAMS table; update "
                       "tools/gen_docs.py:_context_params to where the node's own parameters are")


def _md(text: str) -> str:
    """Text safe inside a Markdown table cell (no HTML, emphasis or cell break)."""
    text = text.replace("\\", "\\\\").replace("&", "&amp;")
    text = text.replace("<", "&lt;").replace(">", "&gt;").replace("|", "\\|")
    return text.replace("*", "\\*").replace("_", "\\_")


def _sentence(text: str) -> str:
    """``text`` with a capital first letter and a full stop."""
    return text[:1].upper() + text[1:] + "."


def _value(value) -> str:
    """A default as it is written in ``params/navigator.yaml``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return "''" if value == "" else value
    return repr(value)


def parameters_page() -> str:
    """The text of ``docs/reference/parameters.md``."""
    from swarm_nav.config import flat_defaults

    table = flat_defaults()
    groups = _groups()
    order = list(GROUP_TEXT)
    rows: dict[str, list[tuple[str, object, str, str]]] = {}
    for name, info in table.items():
        rows.setdefault(groups[name], []).append((name, info.default, info.unit,
                                                  info.description))
    for name, (default, unit, text) in _context_params().items():
        rows.setdefault("context", []).append((name, default, unit, text))
    lines = [
        "# Navigator parameters",
        "",
        "<!-- Generated by tools/gen_docs.py from swarm_nav.config.flat_defaults(); "
        f"do not edit: run {REGENERATE}. -->",
        "",
        "Every parameter of the navigator node `/<ns>/navigator`, as the node declares it "
        "(`ros2 param describe /Srobot1/navigator NAME` gives the same text). "
        "`params/navigator.yaml` is the template with these defaults; `swarm-up` writes one "
        "copy per robot into `RUN/params/<ns>.yaml`, fitted to the robot's model, and "
        "`swarm-up --nav-params FILE` replaces the template. Names are nav2's where nav2 has "
        "the concept. Unit `-`: a count, a flag or a ratio.",
        "",
        f"{len(table)} parameters in {len({groups[n] for n in table})} groups"
        + (f", and {len(rows.get('context', []))} of the run context." if "context" in rows
           else "."),
        "",
    ]
    for group in sorted(rows, key=lambda g: order.index(g) if g in order else len(order)):
        lines += [f"## {group}", "", _sentence(GROUP_TEXT.get(group, group)), "",
                  "| name | type | default | unit | description |",
                  "|---|---|---|---|---|"]
        for name, default, unit, text in rows[group]:
            lines.append(f'| <span id="{name}"></span>`{name}` | {type(default).__name__} '
                         f"| `{_value(default)}` | {_md(unit)} | {_md(text)} |")
        lines.append("")
    return "\n".join(lines)


# --------------------------------------------------------------------------- commands
def console_scripts(pyproject: Path = ROOT / "pyproject.toml") -> dict[str, str]:
    """Console script name -> ``module:function``, in ``[project.scripts]`` order."""
    with pyproject.open("rb") as fh:
        return dict(tomllib.load(fh)["project"]["scripts"])


def help_text(name: str, target: str) -> str:
    """The ``--help`` output of one console script, run through its entry point.

    Args:
        name: the command's name (``swarm-up``), given to it as ``argv[0]``.
        target: its entry point, ``module:function``.

    Returns:
        What it printed on stdout, with trailing blanks removed and machine-dependent figures
        (:data:`MACHINE_DEPENDENT`) replaced.

    Raises:
        RuntimeError: the command did not exit 0.
    """
    module, func = target.split(":")
    code = (f"import sys; sys.argv = [{name!r}, '--help']; from {module} import {func}; "
            f"sys.exit({func}())")
    env = dict(os.environ, COLUMNS=str(HELP_COLUMNS), LINES="50", PYTHONWARNINGS="ignore")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, env=env, timeout=120)
    if res.returncode != 0:
        raise RuntimeError(f"{name} --help exited {res.returncode}:\n{res.stderr}")
    text = "\n".join(line.rstrip() for line in res.stdout.strip("\n").splitlines())
    for pattern, replacement in MACHINE_DEPENDENT:
        text = pattern.sub(replacement, text)
    return text


def commands_page() -> str:
    """The text of ``docs/reference/commands.md``."""
    scripts = console_scripts()
    lines = [
        "# Commands",
        "",
        "<!-- Generated by tools/gen_docs.py from pyproject.toml's [project.scripts] and each "
        f"command's --help; do not edit: run {REGENERATE}. -->",
        "",
        "Every console script of the package, with its `--help` as printed at a width of "
        f"{HELP_COLUMNS} columns. Exit codes everywhere: `0` success, `2` bad input (one line "
        "on stderr naming the flag or file), `1` runtime failure (what failed and where the "
        "logs are).",
        "",
        "| command | entry point |",
        "|---|---|",
    ]
    lines += [f"| [`{name}`](#{name}) | `{target}` |" for name, target in scripts.items()]
    lines.append("")
    with ThreadPoolExecutor(max_workers=4) as pool:  # each --help starts a Python (~3 s)
        helps = pool.map(lambda item: help_text(*item), scripts.items())
        for name, text in zip(scripts, helps, strict=True):
            lines += [f"## {name}", "", "```text", text, "```", ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------- topics
TOPICS_INTRO = """\
Every topic and service of a running swarm: its type, the QoS its writers offer, who writes and
who reads it. Standard message types only ([contract](contract.md#s3)); `<ns>` is a robot's
namespace without the leading `/` (`Srobot3`). The conventions behind them (the synchronous
control loop, the goal handshake, the `nav_status` contract, frames) are in
[Architecture](../ARCHITECTURE.md#ros-conventions-chosen-by-us).

QoS is history keep-last with the depth given; *latched* means reliable, transient local, depth
1, as nav2's map server does it; *sensor data* is rclpy's `qos_profile_sensor_data` (best effort,
volatile, depth 5). A reader that asks for other QoS than the writer's names its profile in
brackets ([named QoS profiles](#named-qos-profiles)).

## Nodes

The writers and readers below are these nodes:

"""

# The nodes the writers and readers are: (who, node, process, what).
TOPICS_NODES = (
    ("swarm_sim", "`/swarm_sim`", "`swarm-sim` (child `sim` of `swarm-up`)", "the simulator"),
    ("navigators, the robot's navigator", "`/<ns>/navigator`",
     "`swarm-nav`, or a group process", "one robot's navigator"),
    ("commanders, the robot's commander", "`/<ns>/commander`",
     "`swarm-commander`, or a group process", "one robot's commander (nav2's `BasicNavigator`)"),
    ("group processes", "`/<ns>/clock` (the first robot's)",
     "`python -m swarm_up.group` (children `group_<k>` of `swarm-up`)",
     "several robots' navigators and commanders; the process's one `/clock` subscription and, "
     "with `--faults`, the in-process side of faults"),
    ("swarm_coordinator", "`/swarm_coordinator`", "`swarm-coordinator` (child `coordinator`)",
     "the coordinator, `--coordination centralized` only"),
    ("swarm-up metrics", "`/swarm_up_metrics`", "`swarm-up`",
     "the metrics listener (writes `metrics.json`); swarm-up's fault injection reads the "
     "events through it"),
    ("swarm-up's fault injection", "`/swarm_up_faults`", "`swarm-up`",
     "with `--faults`, the process side of faults for per-robot processes and the coordinator"),
    ("swarm-up live view", "`/swarm_up_fleet`", "`swarm-up`",
     "the dashboard and the RViz markers, `--dashboard` or `--markers` only"),
    ("recorder", "`/swarm_recorder`", "`python -m swarm_record.recorder` (child `record`)",
     "the recorder, `--record` only"),
)


TOPICS_OUTRO = """\
Nothing publishes `/tf`: every pose is already in `map` (odometry has no drift here). A recording
builds `/tf` for Foxglove ([dashboard and recording](../guides/dashboard_and_recording.md)).

The benchmark's messaging baseline (`swarm-bench --baseline`) runs the same topics with the same
types, QoS and rates, with relaying nodes in place of the simulator and the navigators.
"""


def _attribute_docs(path: Path) -> dict[str, str]:
    """Module-level name -> the docstring that follows its assignment (the string literal
    statement right after it, as Sphinx reads attribute docstrings), as one paragraph."""
    body = ast.parse(path.read_text()).body
    out: dict[str, str] = {}
    for node, nxt in zip(body, body[1:], strict=False):
        if not (isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)):
            continue
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) else [])
        for target in targets:
            if isinstance(target, ast.Name):
                out[target.id] = " ".join(inspect.cleandoc(nxt.value.value).split())
    return out


def _rst(text: str) -> str:
    """reStructuredText inline markup as Markdown: ``code`` and :role:`target` (``~``: its last
    part) as code spans."""
    text = re.sub(r"``(.+?)``", r"`\1`", text)
    text = re.sub(r":\w+:`~([^`]+)`", lambda m: f"`{m.group(1).split('.')[-1]}`", text)
    text = re.sub(r":\w+:`([^`]+)`", r"`\1`", text)
    return text


_QOS_NAME = re.compile(r"\b([A-Z][A-Z_]*_QOS)\b")


def _who(words: tuple[str, ...]) -> str:
    """Writers or readers as one table cell; a named QoS profile links to its row."""
    cell = "; ".join(words) if words else "-"
    cell = cell.replace("|", "\\|")
    return _QOS_NAME.sub(lambda m: f"[`{m.group(1)}`](#{m.group(1).lower()})", cell)


def _qos_cells(qos) -> str:
    """``reliability | durability | depth`` of a :class:`swarm_common.topics.Qos`."""
    return " | ".join((qos.reliability.replace("_", " "), qos.durability.replace("_", " "),
                       str(qos.depth)))


def topics_page() -> str:
    """The text of ``docs/reference/topics.md``."""
    from swarm_common import topics
    from swarm_common.nav_status import NavState, NavStatusRecord, encode

    docs = _attribute_docs(ROOT / "swarm_common" / "topics.py")
    named = {k: v for k, v in vars(topics).items() if isinstance(v, topics.Topic)}
    services = {k: v for k, v in vars(topics).items() if isinstance(v, topics.Service)}
    profiles = {k: v for k, v in vars(topics).items() if isinstance(v, topics.Qos)}

    def shown(t) -> str:
        return t.name if t.name.startswith("/") else f"/<ns>/{t.name}"

    groups = {
        "Swarm-wide topics": [k for k, t in named.items()
                              if t.name.startswith("/") and "coordinator" not in t.name],
        "A robot's topics": [k for k, t in named.items()
                             if not t.name.startswith("/") and "coordinator" not in t.name],
        "Centralized coordination": [k for k, t in named.items() if "coordinator" in t.name],
    }
    lines = [
        "# Topics and services",
        "",
        "<!-- Generated by tools/gen_docs.py from swarm_common/topics.py; do not edit: run "
        f"{REGENERATE}. -->",
        "",
        TOPICS_INTRO,
        "| who | node | process | what |",
        "|---|---|---|---|",
        *(f"| {' | '.join(row)} |" for row in TOPICS_NODES),
        "",
    ]
    for title, keys in groups.items():
        lines += [f"## {title}", ""]
        if title == "Centralized coordination":
            lines += ["Only with `--coordination centralized`. Every message is a "
                      "`std_msgs/String` whose `data` is JSON (the records of "
                      "`swarm_common/coordination.py`); the coordinator also writes "
                      "`/swarm/events` (above).", ""]
        lines += ["| topic | type | reliability | durability | depth | writers | readers |",
                  "|---|---|---|---|---|---|---|"]
        for key in keys:
            t = named[key]
            lines.append(f"| `{shown(t)}` | `{t.type}` | {_qos_cells(t.qos)} | "
                         f"{_who(t.writers)} | {_who(t.readers)} |")
        lines.append("")
        if title == "A robot's topics":
            lines += ["| service | type | servers | clients |", "|---|---|---|---|"]
            for v in services.values():
                lines.append(f"| `/<ns>/{v.name}` | `{v.type}` | {_who(v.servers)} | "
                             f"{_who(v.clients)} |")
            lines.append("")
        notes = [(shown(named[k]), docs[k]) for k in keys if k in docs]
        if title == "A robot's topics":
            notes += [(f"/<ns>/{v.name}", docs[k]) for k, v in services.items() if k in docs]
        if notes:
            lines += ["Notes:", ""]
            lines += [f"- `{name}`: {_rst(text)}" for name, text in notes]
            lines.append("")
        if title == "A robot's topics":
            full = NavStatusRecord(NavState.IDLE, "", 0, (0.0, 0.0, 0.0), 0.0, 0.0, 0, 0.0, 0,
                                   "")
            keys_text = ", ".join(f"`{k}`" for k in encode(full))
            states = " ".join(s.value for s in NavState)
            lines += [f"`nav_status` carries the state in `message` (`{states}`) and in "
                      f"`values` {keys_text}, all strings "
                      "(`swarm_common.nav_status.encode`); the contract is "
                      "`swarm_common/nav_status.py`.", ""]
    lines += ["## The simulator's services", "",
              "The ROS simulation standard (`simulation_interfaces`; "
              "[the ROS 2 tools](../guides/ros2_tools.md#the-simulation_interfaces-services) "
              "says what each does here).", "",
              "| service | type | servers | clients |", "|---|---|---|---|"]
    for v in topics.SIMULATION_SERVICES.values():
        lines.append(f"| `{v.name}` | `{v.type}` | {_who(v.servers)} | {_who(v.clients)} |")
    lines.append("")
    lines += ["## Named QoS profiles", "",
              "| name | reliability | durability | depth | what |", "|---|---|---|---|---|"]
    for key, q in profiles.items():
        lines.append(f'| <span id="{key.lower()}"></span>`{key}` | {_qos_cells(q)} | '
                     f"{_rst(docs.get(key, ''))} |")
    lines += ["", TOPICS_OUTRO]
    return "\n".join(lines)


def rviz_page() -> str:
    """``docs/swarm.rviz``: the RViz2 configuration of the README's 20-robot run."""
    from swarm_viz.rviz_config import rviz_config

    return rviz_config([f"Srobot{i}" for i in range(1, 21)])


# --------------------------------------------------------------------------- main
def pages() -> dict[Path, Callable[[], str]]:
    """Every generated page: its path -> the function that writes its text."""
    return {
        DOCS / "reference" / "parameters.md": parameters_page,
        DOCS / "reference" / "commands.md": commands_page,
        DOCS / "reference" / "topics.md": topics_page,
        DOCS / "swarm.rviz": rviz_page,
    }


def main(argv: list[str] | None = None) -> int:
    """Rewrite the generated pages, or with ``--check`` only compare them; 1 if any differ."""
    parser = argparse.ArgumentParser(prog="gen_docs", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 when a page is out of date")
    args = parser.parse_args(argv)
    stale = []
    for path, make in pages().items():
        text = make()
        if not path.exists() or path.read_text() != text:
            stale.append(path.relative_to(ROOT))
            if not args.check:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
    for path in stale:
        print(f"{'out of date' if args.check else 'wrote'}: {path}")
    return 1 if (args.check and stale) else 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
