"""Settings of the navigator: one frozen dataclass per algorithm, a unit on every field.

Every field is also a ROS parameter of the navigator node. The flat parameter name is nav2's where
nav2 has the concept (``robot_radius``, ``inflation_radius``, ``cost_scaling_factor`` of
nav2_costmap_2d; ``tolerance``, ``allow_unknown`` of NavFn; ``max_vel_x``, ``acc_lim_x``,
``vx_samples``, ``sim_time`` and the ``<Critic>.scale`` weights of DWB; ``xy_goal_tolerance`` of
the goal checker; ``required_movement_radius`` of the progress checker; ``backup_dist`` of the
BackUp behaviour ...), and the field's metadata carries it together with the unit and a
description. :meth:`NavigatorConfig.from_flat` builds the whole configuration from such a flat dict
and :func:`flat_defaults` lists every name with its default, unit and description, so the node
declares its parameters from this one place and ``params/navigator.yaml`` is checked against it.

Defaults are the nav2 multi-robot defaults the thesis used with the TurtleBot3 waffle
(``shared/reference/seed_facts.md``), except where a field's description says why it differs.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

from swarm_common.errors import InputError, did_you_mean


def _p(default, unit: str, description: str, name: str | None = None, check: str = ""):
    """A dataclass field carrying its ROS parameter name, unit and description.

    Args:
        default: the default value (its Python type is the parameter's type).
        unit: the unit, e.g. ``"m/s"``; ``"-"`` for counts, flags and ratios.
        description: one line for ``ros2 param describe``.
        name: the flat ROS parameter name; the field's own name when ``None``.
        check: ``">0"``, ``">=0"``, ``"<=0"`` or ``""`` (no check), validated by ``from_flat``.
    """
    meta = {"unit": unit, "description": description, "param": name, "check": check}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class CostmapConfig:
    """The static costmap (nav2_costmap_2d static + inflation layers).

    Cost values are nav2's (``nav2_costmap_2d/cost_values.hpp``).
    """

    LETHAL_OBSTACLE: ClassVar[int] = 254
    INSCRIBED_INFLATED_OBSTACLE: ClassVar[int] = 253
    NO_INFORMATION: ClassVar[int] = 255
    FREE_SPACE: ClassVar[int] = 0

    robot_radius: float = _p(0.22, "m", "radius of the robot for inflation (nav2 robot_radius)",
                             check=">0")
    inflation_radius: float = _p(0.55, "m", "distance from obstacles over which cost decays",
                                 check=">0")
    cost_scaling_factor: float = _p(3.0, "1/m", "exponential decay rate of the inflation cost",
                                    check=">0")
    lethal_cost_threshold: int = _p(100, "-", "occupancy value (0..100) from which a cell is "
                                    "lethal", check=">0")
    track_unknown_space: bool = _p(True, "-", "keep unknown cells as NO_INFORMATION (else free)")


@dataclass(frozen=True)
class PlannerConfig:
    """The global A* planner (NavFn-like behaviour, Smac-2D-like cost penalty)."""

    tolerance: float = _p(0.5, "m", "plan to the nearest free cell within this of a goal in the "
                          "inflation (NavFn tolerance); a goal inside an obstacle is refused",
                          check=">=0")
    allow_unknown: bool = _p(False, "-", "plan through unknown cells (NavFn's default is true; "
                             "false here: the lidar cannot vouch for unknown space)")
    cost_penalty: float = _p(2.0, "-", "step cost = length * (1 + cost_penalty * cost / 252) "
                             "(Smac 2D cost_penalty)", check=">=0")
    shortcut_max_cost: int = _p(128, "-", "line-of-sight shortcuts only over cells cheaper than "
                                "this (or than the segment's ends)", check=">0")
    path_resolution: float = _p(0.1, "m", "spacing of the points of the published path",
                                check=">0")
    start_escape_radius: float = _p(0.5, "m", "a start inside the inscribed zone escapes to the "
                                    "nearest free cell within this", check=">=0")
    overlay_astar: bool = _p(True, "-", "replan around the robots seen with A* guided by the "
                             "static map's cost-to-go (a cheapest path, not always the one of "
                             "equal cost the whole-map search follows) instead of repairing "
                             "that search")


@dataclass(frozen=True)
class DwaConfig:
    """The local planner: dynamic window approach (Fox, Burgard, Thrun 1997) with DWB's names.

    ``decel_lim_*`` are negative, as in DWB.  The angular limit is the 1.0 rad/s nav2 used for the
    waffle (the robot can do 1.82 rad/s).
    """

    max_vel_x: float = _p(0.26, "m/s", "maximum forward speed", check=">0")
    min_vel_x: float = _p(0.0, "m/s", "minimum forward speed (negative allows reversing)")
    max_vel_theta: float = _p(1.0, "rad/s", "maximum absolute rotational speed", check=">0")
    acc_lim_x: float = _p(2.5, "m/s^2", "linear acceleration limit", check=">0")
    acc_lim_theta: float = _p(3.2, "rad/s^2", "rotational acceleration limit", check=">0")
    decel_lim_x: float = _p(-2.5, "m/s^2", "linear deceleration limit (negative, as DWB)",
                            check="<0")
    decel_lim_theta: float = _p(-3.2, "rad/s^2", "rotational deceleration limit (negative)",
                                check="<0")
    vx_samples: int = _p(20, "-", "number of linear velocity samples", check=">0")
    vtheta_samples: int = _p(20, "-", "number of rotational velocity samples", check=">0")
    sim_time: float = _p(1.7, "s", "rollout horizon of each sampled trajectory", check=">0")
    sim_granularity: float = _p(0.05, "m", "linear step between collision checks along a rollout",
                                check=">0")
    angular_sim_granularity: float = _p(0.1, "rad", "angular step between collision checks",
                                        check=">0")
    footprint_padding: float = _p(0.05, "m", "safety margin around the footprint box that no "
                                  "obstacle point may enter (includes 2 sigma of the lidar's "
                                  "1 cm noise)", check=">=0")
    wall_escape_padding: float = _p(0.02, "m", "when no motion keeps footprint_padding because a "
                                    "wall is that near, motions may come this near to the walls "
                                    "(the static map and the scan points on it; never to anything "
                                    "else)", check=">=0")
    lookahead_dist: float = _p(0.8, "m", "distance along the path of the point the robot steers "
                               "to", check=">0")
    path_dist_scale: float = _p(2.0, "1/m", "weight of the rollout end's distance to the path",
                                name="PathDist.scale", check=">=0")
    goal_dist_scale: float = _p(3.0, "1/m", "weight of the rollout end's distance to the "
                                "lookahead point", name="GoalDist.scale", check=">=0")
    path_align_scale: float = _p(0.4, "1/rad", "weight of the heading error at the rollout end",
                                 name="PathAlign.scale", check=">=0")
    obstacle_scale: float = _p(1.5, "-", "weight of the clearance term", name="BaseObstacle.scale",
                               check=">=0")
    obstacle_influence: float = _p(0.3, "m", "gap to obstacles below which clearance costs",
                                   name="BaseObstacle.influence_distance", check=">0")
    speed_scale: float = _p(0.3, "-", "weight of (max_vel_x - v) / max_vel_x (Fox et al.'s "
                            "velocity term)", name="Speed.scale", check=">=0")


@dataclass(frozen=True)
class GoalConfig:
    """The goal checker (nav2 SimpleGoalChecker, stateful) and the final rotation."""

    xy_goal_tolerance: float = _p(0.25, "m", "goal reached within this distance", check=">0")
    yaw_goal_tolerance: float = _p(0.25, "rad", "goal reached within this yaw error", check=">0")
    rotate_to_heading_angular_vel: float = _p(1.0, "rad/s", "rotational speed of the final "
                                              "in-place rotation (RPP's name)", check=">0")
    min_rotate_to_heading_angular_vel: float = _p(0.15, "rad/s", "... never slower than this (it "
                                                  "slows down to stop at the goal yaw)",
                                                  check=">0")
    rotate_to_heading_check_angle: float = _p(0.3, "rad", "each tick of the final rotation checks "
                                              "this much turn (or what is left) against the scan",
                                              check=">0")


@dataclass(frozen=True)
class PerceptionConfig:
    """The other robots seen in the scan: which points are theirs, and their velocities."""

    static_point_tolerance: float = _p(0.15, "m", "a scan point this close to a static obstacle "
                                       "belongs to the map, not to a robot", check=">=0")
    velocity_baseline: float = _p(1.0, "s", "velocities of the robots seen come from the centres "
                                  "seen about this long ago", check=">0")
    velocity_min_baseline: float = _p(0.35, "s", "... but at least this long ago (shorter "
                                      "baselines amplify the lidar's noise)", check=">0")
    velocity_history: float = _p(1.5, "s", "centres seen up to this long ago are kept for that",
                                 check=">0")


@dataclass(frozen=True)
class HoldingConfig:
    """Goal-occupied detection and the holding pattern."""

    goal_occupied_radius: float = _p(0.4, "m", "scan points of another robot within this of the "
                                     "goal mean it is taken", check=">0")
    goal_occupied_min_points: int = _p(3, "-", "that many such points make the goal occupied",
                                       check=">0")
    goal_detection_range: float = _p(2.5, "m", "the goal is judged only from this close, in line "
                                     "of sight", check=">0")
    yield_radius: float = _p(1.0, "m", "another robot within this of our goal, nearer to it and "
                             "driving toward it came first: we yield", check=">=0")
    yield_margin: float = _p(0.3, "m", "... nearer by at least this", check=">=0")
    crowd_radius: float = _p(1.2, "m", "robots standing within this of our goal ...",
                             check=">=0")
    crowd_limit: int = _p(1, "-", "... this many, all nearer to it than we are and not on another "
                          "workstation or its holding points (within holding_arrive_tolerance), "
                          "make a queue: we hold as if the goal were taken (0 = never)",
                          check=">=0")
    congestion_distance: float = _p(3.0, "m", "robots standing on this much of the path ahead ...",
                                    check=">=0")
    congestion_radius: float = _p(0.7, "m", "... centred within this of it, in a narrow place "
                                  "(nearer a wall than staging_wall_clearance), off workstations "
                                  "and holding spots ...", check=">=0")
    congestion_limit: int = _p(3, "-", "... this many, make the way congested: we hold back at a "
                               "staging point (0 = never)", check=">=0")
    congestion_wait: float = _p(15.0, "s", "... for at least this long, stretched by "
                                "robot_index % 5 quarters, then try again", check=">=0")
    starvation_time: float = _p(300.0, "s", "a robot that has reached no goal yet and has held "
                                "this long for its goal is held back by congestion no more "
                                "(0 = always held back) ...", check=">=0")
    starvation_congestion_limit: int = _p(6, "-", "... but by this many robots standing on "
                                          "its way, as congestion_limit (0 = by none)",
                                          check=">=0")
    patience_time: float = _p(0.0, "s", "a robot that has held this long for its current goal "
                              "(whatever it reached before) no longer holds for the crowd rule "
                              "and is held back by congestion only as a starving robot "
                              "(starvation_congestion_limit) (0 = never)", check=">=0")
    swap_range: float = _p(2.5, "m", "a holding robot that sees, in line of sight and within "
                           "this, another workstation of its goal's kind free (as judged for "
                           "its own goal) takes that one instead (0 = never)", check=">=0")
    moving_speed: float = _p(0.08, "m/s", "a robot seen moving faster than this toward the goal "
                             "is approaching it, away from it is leaving it", check=">=0")
    workstation_match_radius: float = _p(0.3, "m", "a goal this close to a workstation uses its "
                                         "holding spot or loop", check=">=0")
    holding_distance: float = _p(1.5, "m", "a goal that is no workstation holds this far back "
                                 "along its path", check=">0")
    holding_arrive_tolerance: float = _p(0.35, "m", "a holding point counts as reached within "
                                         "this", check=">0")
    holding_target_check_range: float = _p(2.5, "m", "a holding point this close is checked for "
                                           "another robot standing on it (a taken loop point is "
                                           "skipped, a taken spot replaced by a staging point)",
                                           check=">=0")
    holding_retry_period: float = _p(5.0, "s", "time between retries while holding", check=">0")
    free_confirm_time: float = _p(1.0, "s", "the goal must be seen free this long before retrying",
                                  check=">=0")
    staging_distance: float = _p(2.5, "m", "a robot whose holding spot is taken too waits at "
                                 "least this far from the goal", check=">=0")
    staging_clearance: float = _p(1.2, "m", "... and this far from every robot seen",
                                  check=">=0")
    workstation_clearance: float = _p(1.0, "m", "... and this far from every workstation and "
                                      "holding point", check=">=0")
    staging_search_radius: float = _p(12.0, "m", "... within this of where it is", check=">0")
    staging_wall_clearance: float = _p(1.6, "m", "... and, where there is such a place, this far "
                                       "from every wall: in the open, not in a corridor that "
                                       "others drive through", check=">=0")
    make_room_distance: float = _p(0.8, "m", "a waiting robot with another robot this close ...",
                                   check=">=0")
    make_room_time: float = _p(4.0, "s", "... for this long moves to a staging point to make "
                               "room", check=">0")
    workstation_keepout_radius: float = _p(0.45, "m", "paths to elsewhere avoid discs of this "
                                           "radius about workstations and holding points",
                                           check=">=0")
    workstation_keepout_cost: int = _p(180, "-", "costmap cost of those discs (< 253: passable "
                                       "if there is no other way)", check=">=0")
    occupied_timeout: float = _p(600.0, "s", "a goal seen taken, in sight, by a robot that has "
                                 "not moved for this long (none seen moving within "
                                 "2 x goal_occupied_radius of it) is given up: aborted with the "
                                 "reason (a robot that died there); 0 = never", check=">=0")


@dataclass(frozen=True)
class RecoveryConfig:
    """Progress checking and recoveries.

    The nav2 sequence is clear costmaps, spin 1.57 rad, wait 5 s, back up 0.30 m at 0.05 m/s.  The
    back-up runs at 0.10 m/s and the wait is 2 s here: in a swarm a slow recovery keeps the other
    robots blocked, and the waffle brakes from 0.10 m/s in 4 cm.
    """

    required_movement_radius: float = _p(0.5, "m", "progress checker: move this far ...",
                                         check=">0")
    movement_time_allowance: float = _p(10.0, "s", "... within this time (nav2)", check=">0")
    stuck_time: float = _p(2.0, "s", "the local planner finding no safe motion this long means "
                           "stuck", check=">0")
    still_vel_x: float = _p(0.02, "m/s", "a command slower than this ...", check=">=0")
    still_vel_theta: float = _p(0.1, "rad/s", "... and turning slower than this is no motion "
                                "(counts toward stuck_time)", check=">=0")
    backup_dist: float = _p(0.30, "m", "back-up distance (nav2 BackUp)", check=">0")
    backup_speed: float = _p(0.10, "m/s", "back-up speed (nav2: 0.05)", check=">0")
    spin_dist: float = _p(1.57, "rad", "spin angle (nav2 Spin)", check=">0")
    wait_duration: float = _p(2.0, "s", "wait time (nav2 Wait: 5 s), stretched by robot_index % 3",
                              check=">=0")
    time_allowance: float = _p(10.0, "s", "a recovery behaviour gives up after this", check=">0")
    escape_clearance: float = _p(0.15, "m", "a robot stuck after a whole cycle of recoveries "
                                 "with an obstacle nearer than this escapes (widens its smallest "
                                 "gap) instead of waiting, until it has this much", check=">=0")
    escape_padding: float = _p(0.03, "m", "an escape comes no nearer than this to anything "
                               "(nor nearer than it is)", check=">=0")
    escape_speed: float = _p(0.08, "m/s", "fastest forward or backward speed of an escape",
                             check=">0")
    escape_turn: float = _p(0.6, "rad/s", "fastest turn of an escape", check=">0")


@dataclass(frozen=True)
class TrafficConfig:
    """The traffic rules between robots that do not talk: keep right, and who yields.

    Keep right: a robot shifts its local path to its right while a robot comes toward it on it.
    Yield: in a face-to-face deadlock the robot the rule picks retreats off the other's way (a
    place at least ``yield_clearance`` off the other's line, reached by a short detour) and waits
    until its path is clear.
    """

    keep_right_offset: float = _p(0.35, "m", "shift of the path to the right when a robot is "
                                  "ahead (traffic rule, no communication)", check=">=0")
    keep_right_distance: float = _p(2.5, "m", "a robot nearer than this ahead triggers the shift",
                                    check=">=0")
    deadlock_distance: float = _p(0.9, "m", "a robot this close ahead while stuck is a "
                                  "face-to-face deadlock", check=">0")
    yield_axis_angle: float = _p(0.3, "rad", "direction of the yield rule: the robot whose "
                                 "bearing to the other points along it yields")
    yield_clearance: float = _p(0.7, "m", "a yielding robot retreats this far off the line the "
                                "other robot comes along", check=">0")
    yield_search_radius: float = _p(4.0, "m", "how far a yielding robot looks for a place to "
                                    "retreat to", check=">0")
    yield_timeout: float = _p(20.0, "s", "a yielding robot resumes after this at the latest",
                              check=">0")
    yield_retreat_spacing: float = _p(0.75, "m", "retreat places tried are at least this far "
                                      "apart", check=">=0")
    yield_retreat_tries: int = _p(4, "-", "at most this many retreat places are planned to",
                                  check=">0")
    yield_detour_factor: float = _p(3.0, "-", "a retreat path may be at most this times the "
                                    "straight distance ...", check=">0")
    yield_detour_slack: float = _p(1.0, "m", "... plus this", check=">=0")
    yield_arrive_tolerance: float = _p(0.3, "m", "a retreat place counts as reached within this "
                                       "(the drive there also ends after half of yield_timeout, "
                                       "or when stuck for stuck_time)", check=">0")
    yield_clear_distance: float = _p(2.5, "m", "a waiting robot resumes when no robot is seen on "
                                     "this much of its path ahead ...", check=">0")
    yield_clear_margin: float = _p(0.1, "m", "... within robot_radius plus this of it ...",
                                   check=">=0")
    yield_clear_time: float = _p(1.5, "s", "... for this long ...", check=">=0")
    yield_min_wait: float = _p(1.0, "s", "... and it has waited at least this", check=">=0")


@dataclass(frozen=True)
class NavigatorConfig:
    """The whole navigator: one sub-configuration per algorithm, plus the loop's own settings."""

    costmap: CostmapConfig = field(default_factory=CostmapConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    dwa: DwaConfig = field(default_factory=DwaConfig)
    goal: GoalConfig = field(default_factory=GoalConfig)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    holding: HoldingConfig = field(default_factory=HoldingConfig)
    recovery: RecoveryConfig = field(default_factory=RecoveryConfig)
    traffic: TrafficConfig = field(default_factory=TrafficConfig)
    control_period: float = _p(0.1, "s", "period of step() calls (the simulator's control tick)",
                               check=">0")
    robot_index: int = _p(0, "-", "index i of the namespace /<prefix><i>; staggers recovery waits",
                          check=">=0")
    max_path_deviation: float = _p(1.0, "m", "replan when the robot is farther than this from "
                                   "its path", check=">0")
    blocked_replan_time: float = _p(4.0, "s", "replan around a moving obstacle that blocks the "
                                    "path ahead this long", check=">0")
    stationary_replan_time: float = _p(1.0, "s", "replan around a standing robot (or a new "
                                       "static obstacle) on the path ahead after this",
                                       check=">0")
    blocked_check_distance: float = _p(2.0, "m", "how far ahead along the path blockage is "
                                       "checked", check=">0")
    scan_max_age: float = _p(1.0, "s", "the robots seen in a scan older than this judge neither "
                             "the goal nor the path ahead", check=">0")
    obstacle_window: float = _p(1.2, "m", "the static map's obstacle boundary within this (per "
                                "axis) of the robot joins the scan as the DWA's obstacles",
                                check=">0")
    prediction_step: float = _p(0.3, "s", "robots seen moving are also put where they will be "
                                "this and twice this after the scan (plus the scan's age) ...",
                                check=">=0")
    prediction_max: float = _p(1.0, "s", "... but at most this far ahead", check=">=0")

    @classmethod
    def from_flat(cls, flat: dict[str, Any]) -> NavigatorConfig:
        """Build the configuration from flat ROS parameter names; missing names keep defaults.

        Args:
            flat: parameter name (as in :func:`flat_defaults`) -> value.

        Returns:
            The validated configuration.

        Raises:
            InputError: an unknown name (with a did-you-mean), a value of the wrong type, or a
                value out of range; the message starts with the parameter name.
        """
        known = _flat_fields()
        for key in flat:
            if key not in known:
                raise InputError(f"{key}: unknown navigator parameter{did_you_mean(key, known)}")
        groups: dict[str | None, dict[str, Any]] = {}
        for key, (group, f) in known.items():
            if key in flat:
                groups.setdefault(group, {})[f.name] = _coerce(key, flat[key], f)
        subs = {g: _SUBCONFIGS[g](**groups.get(g, {})) for g in _SUBCONFIGS}
        if subs["costmap"].inflation_radius < subs["costmap"].robot_radius:
            raise InputError("inflation_radius: must be >= robot_radius")
        if subs["dwa"].min_vel_x >= subs["dwa"].max_vel_x:
            raise InputError("min_vel_x: must be < max_vel_x")
        return cls(**subs, **groups.get(None, {}))

    def to_flat(self) -> dict[str, Any]:
        """The flat parameter name -> value dict of this configuration (inverse of from_flat)."""
        out = {}
        for key, (group, f) in _flat_fields().items():
            obj = self if group is None else getattr(self, group)
            out[key] = getattr(obj, f.name)
        return out


_SUBCONFIGS = {
    "costmap": CostmapConfig,
    "planner": PlannerConfig,
    "dwa": DwaConfig,
    "goal": GoalConfig,
    "perception": PerceptionConfig,
    "holding": HoldingConfig,
    "recovery": RecoveryConfig,
    "traffic": TrafficConfig,
}


@dataclass(frozen=True)
class ParamInfo:
    """One flat navigator parameter as the node declares it: its default (whose type is the
    parameter's), unit and one-line description, as :func:`_p` gave them."""

    default: Any
    unit: str
    description: str


def _flat_fields() -> dict[str, tuple[str | None, dataclasses.Field]]:
    out: dict[str, tuple[str | None, dataclasses.Field]] = {}
    for group, sub in _SUBCONFIGS.items():
        for f in dataclasses.fields(sub):
            out[f.metadata["param"] or f.name] = (group, f)
    for f in dataclasses.fields(NavigatorConfig):
        if f.name not in _SUBCONFIGS:
            out[f.metadata["param"] or f.name] = (None, f)
    return out


def flat_defaults() -> dict[str, ParamInfo]:
    """Every navigator parameter: flat ROS name -> default, unit and description.

    The node declares its ROS parameters from this dict; ``params/navigator.yaml`` lists the same
    names.
    """
    return {
        key: ParamInfo(f.default, f.metadata["unit"], f.metadata["description"])
        for key, (_, f) in _flat_fields().items()
    }


def _coerce(key: str, value: Any, f: dataclasses.Field) -> Any:
    """Convert a parameter value to the field's type and check its range; InputError if bad."""
    kind = type(f.default)
    if kind is bool:
        if not isinstance(value, bool):
            raise InputError(f"{key}: must be true or false, got {value!r}")
        return value
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{key}: must be a number, got {value!r}")
    if kind is int:
        if float(value) != int(value):
            raise InputError(f"{key}: must be an integer, got {value!r}")
        value = int(value)
    else:
        value = float(value)
        if not math.isfinite(value):
            raise InputError(f"{key}: must be finite, got {value!r}")
    check = f.metadata["check"]
    ok = {">0": value > 0, ">=0": value >= 0, "<0": value < 0, "": True}[check]
    if not ok:
        bound = {">0": "> 0", ">=0": ">= 0", "<0": "< 0"}[check]
        raise InputError(f"{key}: must be {bound}, got {value!r}")
    return value
