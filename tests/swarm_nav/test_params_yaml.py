"""The navigator's parameters: one place (swarm_nav.config), one template (params/*.yaml)."""

import dataclasses
import re

import pytest
import yaml

from swarm_common.errors import InputError
from swarm_nav.config import (
    CostmapConfig,
    DwaConfig,
    GoalConfig,
    HoldingConfig,
    NavigatorConfig,
    PerceptionConfig,
    PlannerConfig,
    RecoveryConfig,
    TrafficConfig,
    flat_defaults,
)

SUBCONFIGS = (CostmapConfig, PlannerConfig, DwaConfig, GoalConfig, PerceptionConfig,
              HoldingConfig, RecoveryConfig, TrafficConfig)


def _flatten(d, prefix=""):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


@pytest.fixture(scope="module")
def template(repo_root):
    path = repo_root / "params" / "navigator.yaml"
    return path, yaml.safe_load(path.read_text())


def test_template_keys_equal_flat_defaults(template):
    _, doc = template
    params = _flatten(doc["navigator"]["ros__parameters"])
    assert set(params) == set(flat_defaults())


def test_template_values_are_the_defaults(template):
    _, doc = template
    params = _flatten(doc["navigator"]["ros__parameters"])
    for key, info in flat_defaults().items():
        assert params[key] == info.default, key
        assert type(params[key]) is type(info.default), key


def test_template_has_a_unit_comment_on_every_key(template):
    path, _ = template
    keys = set(flat_defaults())
    seen = set()
    for line in path.read_text().splitlines():
        m = re.match(r"^\s+([A-Za-z_.]+):\s*(\S+)\s*#\s*\[([^\]]+)\]", line)
        if m and m.group(1) in keys:
            assert m.group(3) == flat_defaults()[m.group(1)].unit
            seen.add(m.group(1))
    assert seen == keys


def test_every_field_has_unit_and_description():
    for cls in (*SUBCONFIGS, NavigatorConfig):
        for f in dataclasses.fields(cls):
            if f.name in ("costmap", "planner", "dwa", "goal", "perception", "holding",
                          "recovery", "traffic"):
                continue
            assert f.metadata["unit"], f"{cls.__name__}.{f.name} has no unit"
            assert f.metadata["description"], f"{cls.__name__}.{f.name} has no description"


def test_nav2_defaults():
    cfg = NavigatorConfig()
    assert cfg.costmap.robot_radius == 0.22
    assert cfg.costmap.inflation_radius == 0.55
    assert cfg.costmap.cost_scaling_factor == 3.0
    assert (CostmapConfig.LETHAL_OBSTACLE, CostmapConfig.INSCRIBED_INFLATED_OBSTACLE) == (254, 253)
    assert cfg.planner.tolerance == 0.5
    assert (cfg.dwa.max_vel_x, cfg.dwa.max_vel_theta) == (0.26, 1.0)
    assert (cfg.dwa.acc_lim_x, cfg.dwa.acc_lim_theta) == (2.5, 3.2)
    assert (cfg.dwa.vx_samples, cfg.dwa.vtheta_samples, cfg.dwa.sim_time) == (20, 20, 1.7)
    assert (cfg.goal.xy_goal_tolerance, cfg.goal.yaw_goal_tolerance) == (0.25, 0.25)
    assert cfg.recovery.required_movement_radius == 0.5
    assert cfg.recovery.movement_time_allowance == 10.0
    assert cfg.recovery.backup_dist == 0.30


def test_from_flat_defaults_and_round_trip():
    assert NavigatorConfig.from_flat({}) == NavigatorConfig()
    flat = NavigatorConfig().to_flat()
    assert set(flat) == set(flat_defaults())
    flat.update({"max_vel_x": 0.22, "PathDist.scale": 5.0, "robot_index": 7,
                 "track_unknown_space": False, "vx_samples": 10.0})
    cfg = NavigatorConfig.from_flat(flat)
    assert cfg.dwa.max_vel_x == 0.22
    assert cfg.dwa.path_dist_scale == 5.0
    assert cfg.robot_index == 7
    assert cfg.costmap.track_unknown_space is False
    assert cfg.dwa.vx_samples == 10 and isinstance(cfg.dwa.vx_samples, int)
    assert NavigatorConfig.from_flat(cfg.to_flat()) == cfg


@pytest.mark.parametrize("flat, fragment", [
    ({"max_vel_xx": 0.2}, "did you mean 'max_vel_x'"),
    ({"max_vel_x": -0.1}, "max_vel_x: must be > 0"),
    ({"max_vel_x": "fast"}, "max_vel_x: must be a number"),
    ({"vx_samples": 2.5}, "vx_samples: must be an integer"),
    ({"allow_unknown": 1}, "allow_unknown: must be true or false"),
    ({"decel_lim_x": 2.5}, "decel_lim_x: must be < 0"),
    ({"inflation_radius": 0.1}, "inflation_radius: must be >= robot_radius"),
    ({"sim_time": float("nan")}, "sim_time: must be finite"),
])
def test_from_flat_rejects_bad_values(flat, fragment):
    with pytest.raises(InputError) as exc:
        NavigatorConfig.from_flat(flat)
    assert fragment in str(exc.value)
    assert str(exc.value).startswith(next(iter(flat)))


def test_configs_are_frozen():
    cfg = NavigatorConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.dwa.max_vel_x = 1.0
