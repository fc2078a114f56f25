"""The run directory: ``RUN/logs``, ``RUN/params/<ns>.yaml`` (one navigator params file per
robot, from the template) and, when the world has no map, ``RUN/map.yaml`` rasterised from it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import yaml

from swarm_common.errors import InputError, read_yaml
from swarm_scene.map_io import save_map
from swarm_scene.rasterize import rasterize_world
from swarm_scene.world import load_world
from swarm_up.run_config import RunConfig

# Template keys that are not navigator algorithm parameters (swarm_nav.config): ROS's own
# use_sim_time and the node's context parameters (swarm_nav.node), which swarm-up sets per robot
# in navigator_params.  tests/swarm_up/test_validate.py holds this list to the node's.
CONTEXT_KEYS = frozenset({"use_sim_time", "robot", "poi_file", "map_yaml_path", "robot_name",
                          "wait_for_commander", "hold_goal_end", "wait_for_status_readers",
                          "wait_for_plan_readers",
                          "wait_for_cmd_vel_readers", "goal_wait_timeout"})


# Navigator parameters swarm-up sets under --coordination centralized, whatever the template says:
# the coordinator queues the robots (first come, first served, at its waiting spots), so the
# navigator's own queue rules must not queue them a second time. With them, robots held back from
# the free workstations reserved for them (the queue rule takes the robot the coordinator parks
# on a workstation's holding spot, nearer to it, for a queue; robots parked in the corridor can
# make the way "congested"; which rule cost how much was not separated): 10 robots, 300 s, seed
# 0 completed 29 tasks with 4 standstills of 60 s or more; without them 53 and none (55 at
# 8bb897c, before the rules). And the coordinator reserves one workstation for each robot: its
# navigator must not take another one instead (swap_range).
CENTRALIZED_OVERRIDES = {"crowd_limit": 0, "congestion_limit": 0, "swap_range": 0.0}
# Under the pipelined policy with --queue-at holding the coordinator parks nobody: the queue at a
# workstation is the navigators' holding pattern, with their queue rules; only the coordinator's
# choice of the workstation is kept (swap_range).
QUEUE_AT_HOLDING_OVERRIDES = {"swap_range": 0.0}


def centralized_overrides(coordinator_args) -> dict:
    """The navigator parameters swarm-up sets under ``--coordination centralized`` with these
    policy flags: :data:`QUEUE_AT_HOLDING_OVERRIDES` with ``--queue-at holding`` (which only
    ``--policy pipelined`` takes), else :data:`CENTRALIZED_OVERRIDES`."""
    args = list(coordinator_args)
    holding = "--queue-at" in args and args[args.index("--queue-at") + 1] == "holding"
    return dict(QUEUE_AT_HOLDING_OVERRIDES if holding else CENTRALIZED_OVERRIDES)


class RunError(Exception):
    """A runtime failure (exit 1); the message is the one line shown, naming the logs."""


def load_nav_template(path: Path) -> dict:
    """The ``ros__parameters`` of the navigator template (``navigator: ros__parameters: ...``).

    Raises:
        RunError: the default template is missing (an installation problem).
        InputError: the file is not such a template (names the file).
    """
    data = read_yaml(path, RunError(f"{path}: navigator parameter template missing"))
    if not isinstance(data, dict) or len(data) != 1:
        raise InputError(f"{path}: expected one top-level key 'navigator'")
    (root, body), = data.items()
    if root not in ("navigator", "/navigator", "/**", "**"):
        raise InputError(f"{path}: top-level key must be 'navigator', got {root!r}")
    if not isinstance(body, dict) or not isinstance(body.get("ros__parameters", {}), dict):
        raise InputError(f"{path}: expected 'navigator: ros__parameters: {{...}}'")
    return dict(body.get("ros__parameters") or {})


def check_nav_template(path: Path, params: dict) -> None:
    """Check a template's parameters with the navigator's own strict loader.

    Every key but :data:`CONTEXT_KEYS` goes through
    :meth:`swarm_nav.config.NavigatorConfig.from_flat`, as the node's parameters do: an unknown
    key is an error with a did-you-mean, a value of the wrong type or out of range too.

    Args:
        path: the template file, for the message.
        params: its ``ros__parameters`` (:func:`load_nav_template`).

    Raises:
        InputError: ``"<path>: <key>: unknown navigator parameter (did you mean '...'?)"`` and
            the like.
    """
    from swarm_nav.config import NavigatorConfig

    try:
        NavigatorConfig.from_flat({k: v for k, v in params.items() if k not in CONTEXT_KEYS})
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def robot_params(template: dict, model) -> dict:
    """The navigator parameters that describe the robot, fitted to one robot model.

    - ``robot_radius`` [m]: the model's :attr:`~swarm_scene.robot_model.RobotModel.
      costmap_radius` (nav2's ``robot_radius`` from ``params/robots/<model>.yaml``, else the
      footprint's circumscribed radius);
    - ``inflation_radius`` [m]: the template's, but at least ``robot_radius`` plus the
      template's own margin (its ``inflation_radius - robot_radius``);
    - ``max_vel_x``, ``min_vel_x``, ``max_vel_theta`` [m/s, rad/s], ``acc_lim_x``,
      ``acc_lim_theta``, ``decel_lim_x``, ``decel_lim_theta`` [m/s^2, rad/s^2], the final
      rotation's speeds and ``backup_speed``: the template's, but never beyond the model's
      limits (``params/robots/<model>.yaml``; the simulator clamps every command to them).

    A key missing from the template takes the navigator's default (:func:`swarm_nav.config.
    flat_defaults`).  For the TurtleBot3 waffle and ``params/navigator.yaml`` every value is the
    template's own (the template is written for it).

    Args:
        template: the template's ``ros__parameters``.
        model: the robot's :class:`~swarm_scene.robot_model.RobotModel`.

    Returns:
        ``{parameter: value}`` of the keys above.
    """
    from swarm_nav.config import flat_defaults

    defaults = flat_defaults()

    def get(key: str) -> float:
        return float(template.get(key, defaults[key].default))

    lim = model.limits
    radius = float(model.costmap_radius)
    margin = get("inflation_radius") - get("robot_radius")
    out = {
        "robot_radius": radius,
        "inflation_radius": max(get("inflation_radius"), round(radius + margin, 6)),
        "max_vel_x": min(get("max_vel_x"), lim.max_vel_x),
        "min_vel_x": max(get("min_vel_x"), lim.min_vel_x),
        "max_vel_theta": min(get("max_vel_theta"), lim.max_vel_theta),
        "acc_lim_x": min(get("acc_lim_x"), lim.acc_lim_x),
        "acc_lim_theta": min(get("acc_lim_theta"), lim.acc_lim_theta),
        "decel_lim_x": max(get("decel_lim_x"), -lim.acc_lim_x),
        "decel_lim_theta": max(get("decel_lim_theta"), -lim.acc_lim_theta),
        "rotate_to_heading_angular_vel": min(get("rotate_to_heading_angular_vel"),
                                             lim.max_vel_theta),
        "min_rotate_to_heading_angular_vel": min(get("min_rotate_to_heading_angular_vel"),
                                                 lim.max_vel_theta),
    }
    if lim.min_vel_x < 0.0:  # a base that cannot reverse is not asked to (the recovery clamps)
        out["backup_speed"] = min(get("backup_speed"), -lim.min_vel_x)
    return out


def navigator_params(template: dict, ns: str, index: int, cfg: RunConfig,
                     model=None) -> dict:
    """One robot's params file content, rooted at ``/<ns>/navigator``.

    Args:
        template: the template's ``ros__parameters``.
        ns: namespace without ``/``.
        index: the robot's number i (1..N).
        cfg: the run.
        model: the robot's :class:`~swarm_scene.robot_model.RobotModel` (None: loaded from
            ``cfg.models[index - 1]``).

    Returns:
        ``{"/<ns>/navigator": {"ros__parameters": {...template, use_sim_time, robot_name,
        robot_index, poi_file, map_yaml_path (""), robot, and the robot's size and limits
        (:func:`robot_params`)}}}`` (paths absolute, "" if none).
    """
    from swarm_scene.robot_model import load_robot

    name = cfg.models[index - 1]
    recorded = _recorded_robot_topics(cfg, ns)
    params = dict(template)
    params.update(robot_params(template, model if model is not None else load_robot(name)))
    params.update(
        use_sim_time=True,
        robot_name=ns,
        robot_index=index,
        poi_file=str(cfg.poi_path) if cfg.poi_path else "",
        # The map is distributed centrally on /map, as in the thesis; a navigator that should
        # read a file of its own gets map_yaml_path set by hand.
        map_yaml_path="",
        robot=name,
        # With commanders, simulated time starts once each robot's commander is connected, and
        # each goal takes effect at a fixed tick, however long the commander takes: the same
        # seed gives the same run (swarm_common.lockstep).
        wait_for_commander=bool(cfg.commanders),
        # Centralized: the coordinator answers a tick's requests together, once it has them all
        hold_goal_end=bool(cfg.commanders) and cfg.coordination == "centralized",
        # swarm-up's metrics listener, the commander and the recorder must hear every status,
        # and the simulator and the recorder every command: the first answer (also of a
        # navigator restarted by a fault) waits for them
        wait_for_status_readers=1 + int(bool(cfg.commanders)) + int("nav_status" in recorded),
        wait_for_cmd_vel_readers=1 + int("cmd_vel" in recorded),
        # the plan is built only while it has a reader: the recorder's must be there from the start
        wait_for_plan_readers=int("plan" in recorded),
    )
    if cfg.coordination == "centralized":
        params.update(centralized_overrides(cfg.coordinator_args))
    return {f"/{ns}/navigator": {"ros__parameters": params}}


def _recorded_robot_topics(cfg: RunConfig, ns: str) -> frozenset[str]:
    """The topics of robot ``ns`` that ``--record`` / ``--record-topics`` record, by suffix
    (``cmd_vel``, ``nav_status``, ...); empty without ``--record``."""
    if cfg.record_path is None:
        return frozenset()
    from swarm_record.mcap_format import recorded_topics, select_topics

    return frozenset(t.name.rsplit("/", 1)[-1]
                     for t in select_topics(recorded_topics((ns,)), cfg.record_topics)
                     if t.robot == ns)


def write_params_files(cfg: RunConfig, template: dict) -> list[Path]:
    """Write ``RUN/params/<ns>.yaml`` for every robot.

    Returns:
        The files, in robot order.
    """
    out_dir = cfg.run_dir / "params"
    out_dir.mkdir(parents=True, exist_ok=True)
    files = []
    local = set(cfg.local_robots)
    for i, ns in enumerate(cfg.robots, start=1):
        if ns not in local:  # another host's robot (--hosts): its host writes its file
            continue
        path = out_dir / f"{ns}.yaml"
        path.write_text(yaml.safe_dump(navigator_params(template, ns, i, cfg), sort_keys=False))
        files.append(path)
    return files


def prepare_map(cfg: RunConfig) -> RunConfig:
    """If there is no map, rasterise the world into ``RUN/map.yaml``.

    Returns:
        ``cfg`` with ``map_path`` set (unchanged when it had one).
    """
    if cfg.map_path is not None:
        return cfg
    yaml_path, _ = save_map(rasterize_world(load_world(cfg.world_path)), cfg.run_dir / "map")
    return replace(cfg, map_path=Path(yaml_path).resolve())

