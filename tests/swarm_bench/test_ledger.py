"""The cost ledger (swarm_bench/ledger.py): py-spy's raw stacks parsed, each sample given its
stage by its innermost matching frame, each process's CPU time split by its samples, and the
figures in ms per robot per simulated second."""

from __future__ import annotations

from pathlib import Path

import pytest

from swarm_bench import ledger
from swarm_bench.ledger import (
    RULES,
    STAGE_NAMES,
    build_ledger,
    mean_ledger,
    parse_raw,
    role_of,
    stage_of,
    write_ledger_plot,
)

ROOT = Path(__file__).resolve().parents[2]
SITE = "/v/lib/python3.11/site-packages"
SWARM_UP = 'process 100:"/v/bin/python3 /v/bin/swarm-up --swarm-size 4"'
SIM = 'process 101:"/v/bin/python3 /v/bin/swarm-sim --swarm-size 4"'
GROUP = 'process 102:"/v/bin/python3 -m swarm_up.group --robots Srobot1,Srobot2"'


def frame(function: str, path: str, line: int = 1) -> str:
    return f"{function} ({path}:{line})"


SPIN = frame("spin_once", f"{SITE}/rclpy/executors.py")
TICK = frame("NavigatorNode._tick", f"{ROOT}/swarm_nav/node.py")
STEP = frame("NavigatorCore.step", f"{ROOT}/swarm_nav/core.py")
RAW = "\n".join([
    # the group: planning inside the navigator's step, a publish from its tick, the step itself,
    # and the executor's own work
    f"{SWARM_UP};{GROUP};{SPIN};{TICK};{STEP};"
    f"{frame('cell_path', f'{ROOT}/swarm_nav/planner.py')} 30",
    f"{SWARM_UP};{GROUP};{SPIN};{TICK};"
    f"{frame('Publisher.publish', f'{SITE}/rclpy/publisher.py')} 10",
    f"{SWARM_UP};{GROUP};{SPIN};{TICK};{STEP} 10",
    f"{SWARM_UP};{GROUP};{SPIN} 50",
    # the simulator: physics and its lidar, called from the loop
    f"{SWARM_UP};{SIM};{frame('run', f'{ROOT}/swarm_sim/loop.py')};"
    f"{frame('step', f'{ROOT}/swarm_sim/engine.py')} 3",
    f"{SWARM_UP};{SIM};{frame('run', f'{ROOT}/swarm_sim/loop.py')};"
    f"{frame('step', f'{ROOT}/swarm_sim/engine.py')};"
    f"{frame('scan', f'{ROOT}/swarm_sim/lidar.py')} 1",
    "a line that is no stack",
    f"{SWARM_UP};{frame('run', f'{ROOT}/swarm_metrics/listener.py')} 4",
])


def test_raw_stacks_parse_to_the_innermost_process_and_its_frames():
    samples = list(parse_raw(RAW))
    assert len(samples) == 7
    first = samples[0]
    assert first.pid == 102 and "swarm_up.group" in first.cmdline and first.count == 30
    assert first.frames[0] == ("spin_once", f"{SITE}/rclpy/executors.py")
    assert first.frames[-1] == ("cell_path", f"{ROOT}/swarm_nav/planner.py")
    assert samples[-1].pid == 100 and samples[-1].frames == (
        ("run", f"{ROOT}/swarm_metrics/listener.py"),)


@pytest.mark.parametrize(("stack", "stage"), [
    ([SPIN, TICK, STEP, frame("cell_path", f"{ROOT}/swarm_nav/planner.py")], "planning"),
    ([SPIN, TICK, frame("Publisher.publish", f"{SITE}/rclpy/publisher.py")], "publishing"),
    ([SPIN, TICK, STEP], "navigation"),
    ([SPIN, frame("Executor._take_subscription", f"{SITE}/rclpy/executors.py")], "taking"),
    ([SPIN, frame("Executor._take_timer", f"{SITE}/rclpy/executors.py")], "executor"),
    ([frame("spin_forever", f"{ROOT}/swarm_ros/session.py")], "executor"),
    ([frame("SimulatorNode.spin", f"{ROOT}/swarm_sim/node.py")], "executor"),
    ([frame("SimulatorNode.publish_tick", f"{ROOT}/swarm_sim/node.py")], "messages"),
    ([SPIN], "executor"),
    ([frame("spin_batched", f"{ROOT}/swarm_up/answers.py")], "executor"),
    ([frame("spin_batched", f"{ROOT}/swarm_up/answers.py"),
      frame("AnswerBatch.flush", f"{ROOT}/swarm_up/answers.py")], "messages"),
    ([frame("SimEngine.scans", f"{ROOT}/swarm_sim/engine.py"),
      frame("SwarmSensors.footprints", f"{ROOT}/swarm_sim/sensors.py")], "lidar"),
    ([frame("step", f"{ROOT}/swarm_sim/engine.py"), frame("scan", f"{ROOT}/swarm_sim/lidar.py")],
     "lidar"),
    ([frame("collect", f"{ROOT}/swarm_sim/loop.py")], "lockstep"),
    ([frame("dwa_command", f"{ROOT}/swarm_nav/dwa.py")], "dwa"),
    ([frame("main", "/usr/lib/python3.11/threading.py")], "other"),
    ([], "unattributed"),
])
def test_a_sample_takes_the_stage_of_its_innermost_matching_frame(stack, stage):
    frames = [(f.split(" (")[0], f.split(" (")[1].rsplit(":", 1)[0]) for f in stack]
    assert stage_of(frames) == stage


def test_every_rule_names_a_stage_and_every_package_path_exists():
    for stage, fragment, _ in RULES:
        assert stage in STAGE_NAMES
        if fragment.startswith("swarm_"):
            base = ROOT / fragment
            assert base.exists() or any(base.parent.glob(base.name + "*")), fragment


def test_roles_from_command_lines():
    assert role_of("/v/bin/python3 /v/bin/swarm-sim --x") == "sim"
    assert role_of("/v/bin/python3 -m swarm_up.group --robots a") == "group"
    assert role_of("/v/bin/python3 /v/bin/swarm-up --swarm-size 4") == "swarm-up"
    assert role_of("/v/bin/python3 /v/bin/swarm-nav --ros-args") == "navigator"
    assert role_of("/usr/bin/something") == "other"


def test_each_process_cpu_is_split_by_its_samples_per_robot_per_simulated_second():
    # 4 robots, 10 simulated s: 1 CPU s is 25 ms per robot per simulated second
    cpu = {102: 4.0, 101: 0.8, 100: 0.4, 103: 0.2}  # 103: a process py-spy never sampled
    roles = {102: "group", 101: "sim", 100: "swarm-up", 103: "coordinator"}
    led = build_ledger(parse_raw(RAW), cpu, roles, robots=4, sim_s=10.0)
    assert led["unit"] == "ms of CPU per robot per simulated second"
    assert led["samples"] == 108
    assert led["total"] == pytest.approx(5.4 * 25)
    group = led["roles"]["group"]
    assert group["total"] == pytest.approx(100.0)
    assert group["stages"] == pytest.approx({"planning": 30.0, "navigation": 10.0,
                                             "publishing": 10.0, "executor": 50.0})
    assert list(group["stages"]) == [k for k in STAGE_NAMES if k in group["stages"]]
    assert led["roles"]["sim"]["stages"] == pytest.approx({"physics": 15.0, "lidar": 5.0})
    assert led["roles"]["swarm-up"]["stages"] == pytest.approx({"metrics": 10.0})
    assert led["roles"]["coordinator"]["stages"] == pytest.approx({"unsampled": 5.0})
    assert sum(led["stages"].values()) == pytest.approx(led["total"])
    assert list(led["roles"])[0] == "group"  # the costliest first
    with pytest.raises(ValueError, match="must be positive"):
        build_ledger([], cpu, roles, robots=0, sim_s=10.0)


def test_the_mean_of_runs_counts_a_missing_stage_as_zero():
    a = build_ledger(parse_raw(RAW), {102: 4.0}, {102: "group"}, 4, 10.0)
    b = build_ledger(parse_raw(RAW), {101: 0.8}, {101: "sim"}, 4, 10.0)
    mean = mean_ledger([a, b])
    assert mean["runs"] == 2 and mean["total"] == pytest.approx((100.0 + 20.0) / 2)
    assert mean["roles"]["group"]["stages"]["planning"] == pytest.approx(15.0)
    assert mean["stages"]["lidar"] == pytest.approx(2.5)
    assert mean_ledger([]) is None


def test_the_chart_is_a_png(tmp_path):
    led = build_ledger(parse_raw(RAW), {102: 4.0, 101: 0.8}, {}, 4, 10.0)
    path = tmp_path / "ledger.png"
    write_ledger_plot(path, [{"size": 4, "ledger": led}, {"size": 8, "ledger": led}], "t")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_missing_py_spy_is_a_one_line_input_error(monkeypatch, tmp_path):
    monkeypatch.setattr(ledger.sys, "executable", str(tmp_path / "python"))
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(ledger.InputError, match=r"^--ledger: py-spy is not installed"):
        ledger.py_spy_path()
