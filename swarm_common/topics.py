"""Every topic between the swarm's processes: its name, its type and its QoS, written once.

The simulator, the navigators, the commanders, the coordinator, the orchestrator's metrics
listener and fault injection, the live view, the recorder and the benchmark's baseline (which
mirrors the real nodes' traffic) all take their topic names and QoS from here; the recorder also
writes :attr:`Topic.qos` into a recording's channel metadata (rosbag2's ``offered_qos_profiles``).

QoS is plain data (:class:`Qos`, in rosbag2's policy names) so that this module stays pure; a
node turns it into an ``rclpy`` profile with :func:`swarm_ros.qos.profile`.  :attr:`Topic.qos`
is what the writers offer.  A reader may ask for less or keep more: where one does, its profile
is named here too (``*_READER_QOS``), with the reason, and is compatible with the writer's
(a reliable writer serves best-effort readers; a transient-local writer serves volatile ones).

Names: absolute (``/clock``) or relative to the robot's namespace (``odom`` is
``/<ns>/odom``, :func:`robot_topic`).  Each topic also says who writes and who reads it
(:attr:`Topic.writers`, :attr:`Topic.readers`: plain words, a named reader QoS in brackets), and
the docstring after it says why it is as it is: ``docs/reference/topics.md`` is generated from
this module (``tools/gen_docs.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

RELIABLE, BEST_EFFORT = "reliable", "best_effort"
VOLATILE, TRANSIENT_LOCAL = "volatile", "transient_local"


@dataclass(frozen=True)
class Qos:
    """A QoS profile, keep-last, the other policies at the middleware's defaults.

    Attributes:
        depth: history depth [messages].
        reliability: :data:`RELIABLE` or :data:`BEST_EFFORT`.
        durability: :data:`VOLATILE` or :data:`TRANSIENT_LOCAL` (a late-joining reader gets
            up to ``depth`` messages sent before it matched).
    """

    depth: int
    reliability: str = RELIABLE
    durability: str = VOLATILE

    def as_dict(self) -> dict:
        """``history``, ``depth``, ``reliability``, ``durability`` in rosbag2's names."""
        return {"history": "keep_last", "depth": self.depth, "reliability": self.reliability,
                "durability": self.durability}


@dataclass(frozen=True)
class Topic:
    """One topic.

    Attributes:
        name: absolute (``/clock``) or relative to a robot's namespace (``odom``).
        type: the ROS 2 type name (``nav_msgs/msg/Odometry``).
        qos: what its writers offer.
        writers: who publishes it (plain words, for the reference page).
        readers: who subscribes to it (plain words; a reader's own QoS named in brackets).
    """

    name: str
    type: str
    qos: Qos
    writers: tuple[str, ...] = ()
    readers: tuple[str, ...] = ()


@dataclass(frozen=True)
class Service:
    """One service.

    Attributes:
        name: absolute, or relative to a robot's namespace (``navigator/cancel``).
        type: the ROS 2 type name (``std_srvs/srv/Trigger``).
        servers: who serves it; clients: who calls it (plain words).
    """

    name: str
    type: str
    servers: tuple[str, ...] = ()
    clients: tuple[str, ...] = ()


DEFAULT = Qos(10)
"""rclpy's default profile (a publisher created with depth 10): reliable, volatile."""
LATCHED = Qos(1, durability=TRANSIENT_LOCAL)
"""The last message, also for readers that join later (``/map``, ``plan``)."""
SENSOR_DATA = Qos(5, BEST_EFFORT)
"""rclpy's ``qos_profile_sensor_data``: best effort, depth 5."""

# --------------------------------------------------------------------------------- swarm-wide
CLOCK = Topic("/clock", "rosgraph_msgs/msg/Clock", Qos(10, durability=TRANSIENT_LOCAL),
              ("swarm_sim (every tick)",),
              ("every use_sim_time node (rclpy's time source: best effort, 1), one per group "
               "process", "swarm-up metrics (CLOCK_METRICS_READER_QOS)",
               "swarm_coordinator (CLOCK_COORDINATOR_READER_QOS)", "recorder"))
"""Transient local, so that a reader that joins mid-run learns the simulated time at once, even
while the simulator holds a tick (a restarted coordinator batches requests by it); volatile
readers (every ``use_sim_time`` node) are served as before."""
CLOCK_COORDINATOR_READER_QOS = Qos(10, durability=TRANSIENT_LOCAL)
"""The coordinator answers a tick's requests once the simulator has published a later tick."""
CLOCK_METRICS_READER_QOS = Qos(1, BEST_EFFORT)
"""The metrics listener wants only the latest simulated time, and never to slow the writer."""
MAP = Topic("/map", "nav_msgs/msg/OccupancyGrid", LATCHED, ("swarm_sim (once)",),
            ("navigators", "swarm-up metrics (counts its bytes as communication)", "recorder"))
"""The map every navigator plans on; latched, as nav2's map server publishes it."""
EVENTS = Topic("/swarm/events", "diagnostic_msgs/msg/DiagnosticArray",
               Qos(1000, durability=TRANSIENT_LOCAL),
               ("swarm_sim: spawn, collision, late, fault",
                "swarm_coordinator: reservation, task, coordinator "
                "(EVENTS_COORDINATOR_WRITER_QOS)"),
               ("swarm-up metrics (and swarm-up's fault injection)",
                "group processes with --faults", "recorder"))
"""The simulator's spawns, collisions and faults; the metrics listener and fault injection read
it with this same profile.  Transient local on every side: a writer can match a reader before
the reader has matched the writer, and a volatile reader drops what the writer sent in between
(a fault's start lost so, once in 8 runs of tests/test_e2e_faults.py); a transient-local reader
asks for the writer's history when it matches."""
EVENTS_COORDINATOR_WRITER_QOS = Qos(100, durability=TRANSIENT_LOCAL)
"""The coordinator's writer of ``/swarm/events`` (a few events per task, reservations and its
"up"): transient local for the reason :data:`EVENTS` gives, with a shorter history."""
POSES = Topic("/swarm/poses", "geometry_msgs/msg/PoseArray", Qos(1),
              ("swarm_sim (every tick, while it has a reader)",),
              ("swarm-up live view (POSES_READER_QOS), while someone looks",))
"""The whole fleet's ground-truth poses in one message a tick.  The simulator publishes it, only
while someone subscribes, in ``map``: ``poses[i]`` is robot ``i`` (0-based) of the simulator's
namespaces, ``/<prefix>1`` ... ``/<prefix>N`` in that order; ``header.stamp`` is the tick's
simulated time.  A whole-fleet view (the dashboard) reads this one message instead of ``N``
odometry topics: one write and one wake-up a tick instead of ``N`` (docs/ARCHITECTURE.md, "The
live view").  The writer is reliable (it serves best-effort readers too, without
acknowledgements)."""
POSES_READER_QOS = Qos(POSES.qos.depth, BEST_EFFORT)
"""A live view reads the poses best effort: a late tick is replaced by the next one."""
MARKERS = Topic("/swarm/markers", "visualization_msgs/msg/MarkerArray", Qos(1),
                ("swarm-up live view (2 Hz, with --markers or --dashboard, while it has a "
                 "reader)",), ("RViz2", "Foxglove"))
"""Every robot's outline, heading and plan and the workstations' states, in ``map``."""
SUPERVISION = Topic("/swarm/supervision", "diagnostic_msgs/msg/DiagnosticStatus",
                    Qos(100, durability=TRANSIENT_LOCAL),
                    ("swarm-up's supervisor (every rank): robots whose navigator process "
                     "crashed", "swarm-up of rank 0: the robots of a lost rank"),
                    ("swarm_sim", "swarm_coordinator (robots gone for good)"))
"""swarm-up's supervisor names robots whose navigator process is gone
(:mod:`swarm_common.supervision`); the simulator stops waiting for them.  Transient local on both
sides: a word sent before the reader matched is still delivered."""
RECORD_PROGRESS = Topic("/swarm/record/progress", "rosgraph_msgs/msg/Clock", LATCHED,
                        ("recorder (swarm-up --record): each tick it has in full",),
                        ("swarm_sim (the lockstep's record window)",))
"""The latest tick of which the recorder has taken ``/clock`` and every robot's ``odom`` and
``ground_truth`` it reads (only ``/clock`` in a run with faults).  The simulator holds a tick
until the recorder is at most ``RECORD_WINDOW_TICKS`` (2) ticks behind, whatever stalls the
recorder.  Latched (transient local, the latest tick): the recorder publishes a tick only once,
when it has it in full, and may do so before its writer has matched the simulator's reader on its
own side (discovery is not symmetric); the reader then still gets it from the writer's history,
where a volatile one waited for it for ever (CI stop 44)."""
RECORD_WINDOW_TICKS = 2  # [ticks] swarm-up --record passes it as swarm-sim --record-window
RUN = Topic("/swarm/run", "std_msgs/msg/String", LATCHED,
            ("swarm-up of rank 0 (--hosts)",), ("swarm-up of every other rank",))
"""Rank 0's run identity (:class:`swarm_common.ranks.RunIdentity`), and ``state: ending`` when
its run ends; only with ``--hosts`` above 1."""
RANKS = Topic("/swarm/ranks", "std_msgs/msg/String", Qos(100, durability=TRANSIENT_LOCAL),
              ("swarm-up of every rank (--hosts), once a second",),
              ("swarm-up of every rank",))
"""Every rank's report (:class:`swarm_common.ranks.RankReport`): alive, its robots, CPU,
memory, restarts; transient local, so a rank that starts later hears the others at once. The
topic has no key, so a reader keeps one history for all the ranks' writers: its depth (100) must
hold a report of every rank between two takes (with depth 1, a busy rank 2 of 3 kept taking
rank 1's report over rank 0's, and judged rank 0 silent)."""
FAULT_ACKS = Topic("/swarm/fault_acks", "diagnostic_msgs/msg/DiagnosticStatus",
                   Qos(100, durability=TRANSIENT_LOCAL),
                   ("swarm-up's fault injection", "group processes with --faults"),
                   ("swarm_sim",))
"""Transient local on both sides (the simulator's reader too): an acknowledgement published
before the simulator's reader had matched its writer is delivered when it matches."""
ROBOT_STATES = Topic("/swarm/robot_states", "sensor_msgs/msg/PointCloud2", DEFAULT,
                     ("swarm_sim (every tick, while it has a reader)",),
                     ("group processes: they render their robots' scans and feed their "
                      "navigators from it",))
"""Every robot's state at a tick in one message (:class:`swarm_common.cdr.RobotStatesWriter`):
a point per robot in robot index order, its pose x, y, yaw in ``map`` and velocity v, w (the
simulator's ``float64`` values) and which of its ``odom`` and ``scan`` the simulator writes at
this tick (``published``: a fault mutes them); ``header.stamp`` is the tick.  A group process
renders its robots' scans from it with the simulator's own sensor code
(:mod:`swarm_sim.sensors`) and hands each navigator the odometry and scan it would have read
(:mod:`swarm_up.feed`), so the simulator writes a robot's ``odom`` and ``scan`` only while that
topic has a reader (a navigator in its own process, a recorder, ``ros2 topic echo``)."""
RANK_ROBOT_STATES = Topic("/swarm/rank<R>/robot_states", "sensor_msgs/msg/PointCloud2", DEFAULT,
                          ("swarm-up on rank R > 0 (its relay of /swarm/robot_states)",),
                          ("that host's group processes",))
"""On a rank ``R`` > 0 with more than one group process, ``/swarm/robot_states`` as the rank's
``swarm-up`` took it, written again byte for byte (:mod:`swarm_up.relay`) for that host's group
processes alone, so that one copy a tick crosses the network per host instead of one per
process (:func:`rank_robot_states` names it for a rank)."""


def rank_robot_states(rank: int) -> Topic:
    """:data:`RANK_ROBOT_STATES` of rank ``rank`` (``/swarm/rank1/robot_states``)."""
    return replace(RANK_ROBOT_STATES, name=RANK_ROBOT_STATES.name.replace("<R>", str(int(rank))))


CMD_VEL_BATCH = Topic("/swarm/cmd_vel_batch", "trajectory_msgs/msg/MultiDOFJointTrajectory",
                      Qos(300, durability=TRANSIENT_LOCAL),
                      ("group processes: their navigators' answers to a control tick",),
                      ("swarm_sim (CMD_VEL_BATCH_READER_QOS)",))
"""A group process's navigators' answers to one control tick in one message, in place of one
``cmd_vel`` per robot (:mod:`swarm_up.answers`): ``header.stamp`` is the tick answered,
``joint_names[i]`` a robot's namespace and ``points[0].velocities[i]`` its command in its own
``base_footprint`` (``linear.x``, ``angular.z``); no transforms, no accelerations.  The
simulator takes it as robot ``i``'s ``cmd_vel`` stamped with the tick, so it takes a message or
two per group a tick instead of one per robot.  A navigator alone in its process
(``swarm-nav``) answers on ``cmd_vel``; ``cmd_vel`` stays every robot's command topic (manual
driving, readers such as the recorder: a batched navigator also publishes it while it has a
reader besides the simulator).  Reliable and transient local on both sides, with the depth of
:data:`CMD_VEL`'s history, for the reason :data:`EVENTS` gives: an answer sent before the
simulator's reader matched comes from the writer's history, not lost."""
CMD_VEL_BATCH_READER_QOS = Qos(1000, durability=TRANSIENT_LOCAL)
"""The simulator's reader: one history for every group's writer (the topic has no key), so
deep enough for all of them between two takes."""

# ------------------------------------------------------------------- the coordinator's topics
COORDINATOR_REQUEST = Topic("/swarm/coordinator/request", "std_msgs/msg/String",
                            Qos(10, durability=TRANSIENT_LOCAL),
                            ("commanders: ready, done, report",),
                            ("swarm_coordinator (COORDINATOR_REQUEST_READER_QOS)",
                             "swarm-up metrics (COMM_METRICS_READER_QOS)"))
"""The commanders' requests (:mod:`swarm_common.coordination`).  Transient local: a reader that
matches late (the metrics listener counting the communication load) still gets the last ones."""
COORDINATOR_REQUEST_READER_QOS = Qos(100)
"""The coordinator reads the requests volatile (no stale request) and keeps a burst of them."""
COORDINATOR_STATE = Topic("/swarm/coordinator/state", "std_msgs/msg/String", LATCHED,
                          ("swarm_coordinator",), ("commanders", "swarm-up metrics"))
"""The coordinator's ``up`` with its epoch (new at every start) and robots."""
ASSIGNMENT = Topic("coordinator/assignment", "std_msgs/msg/String",
                   Qos(10, durability=TRANSIENT_LOCAL), ("swarm_coordinator: go, wait",),
                   ("the robot's commander (ASSIGNMENT_READER_QOS)",
                    "swarm-up metrics (COMM_METRICS_READER_QOS)"))
"""The coordinator's answer to one robot (relative: ``/<ns>/coordinator/assignment``).
Transient local writer: a late-matching metrics reader still counts the first answers."""
ASSIGNMENT_READER_QOS = Qos(10)
"""The commanders read volatile, so a restarted commander gets no stale assignment."""
COMM_METRICS_READER_QOS = Qos(100, durability=TRANSIENT_LOCAL)
"""The metrics listener's reader of the requests and assignments (it counts their sizes):
transient local, so requests and answers published before it matched are delivered from the
writers' history when it matches."""

TF = Topic("/tf", "tf2_msgs/msg/TFMessage", Qos(100),
           ("swarm_sim (every tick, while it has a reader; --no-tf: never)",),
           ("RViz2, tf2_echo, anyone",))
"""Every robot's ``<ns>/odom`` -> ``<ns>/base_footprint`` of the tick, one message a tick, stamped
with simulated time; tf2's dynamic broadcaster QoS (reliable, volatile, depth 100).  Frames are
prefixed with the robot's namespace, so one ``/tf`` holds the whole swarm."""
TF_STATIC = Topic("/tf_static", "tf2_msgs/msg/TFMessage", Qos(1, durability=TRANSIENT_LOCAL),
                  ("swarm_sim (once, at start)",), ("RViz2, tf2_echo, anyone",))
"""Every robot's ``map`` -> ``<ns>/odom`` (identity: odometry is exact) and its URDF's joints
(``<ns>/base_footprint`` -> ``<ns>/base_link`` -> ``<ns>/base_scan``...; movable joints at
zero), one latched message; tf2's static broadcaster QoS."""
# --------------------------------------------------------------------------- a robot's topics
ODOM = Topic("odom", "nav_msgs/msg/Odometry", DEFAULT, ("swarm_sim (every tick)",),
             ("the robot's navigator", "recorder"))
"""``odom`` -> ``base_footprint``; starts at the spawn pose in ``map`` (no drift)."""
GROUND_TRUTH = Topic("ground_truth", "nav_msgs/msg/Odometry", DEFAULT,
                     ("swarm_sim (every tick, while it has a reader)",), ("recorder (for /tf)",))
"""The robot's true pose in ``map``."""
SCAN = Topic("scan", "sensor_msgs/msg/LaserScan", SENSOR_DATA, ("swarm_sim (on lidar ticks)",),
             ("the robot's navigator", "swarm-up live view (while a browser shows that robot)",
              "recorder"))
"""Frame ``<ns>/base_scan``, or the model's lidar link."""
CMD_VEL = Topic("cmd_vel", "geometry_msgs/msg/TwistStamped",
                Qos(300, durability=TRANSIENT_LOCAL),
                ("the robot's navigator (one per tick, stamped with the tick)",
                 "anyone, with a zero stamp (manual driving, applied at once)"),
                ("swarm_sim (CMD_VEL_READER_QOS)", "recorder"))
"""The navigator's writer: reliable and transient-local with 300 messages (30 s simulated at
10 Hz), like ``/rosout``, so that a reader that asks for transient-local (the recorder) gets the
commands sent before it matched.  A writer matches a reader before the reader matches the
writer; what the writer sends in between, a volatile reader drops (23 ticks of one robot in one
CI run, the navigator's start gate passed on the writer's side)."""
CMD_VEL_READER_QOS = DEFAULT
"""The simulator reads ``cmd_vel`` volatile: it wants each tick's command, not a history."""
PLAN = Topic("plan", "nav_msgs/msg/Path", LATCHED,
             ("the robot's navigator (built only while it has a reader)",),
             ("swarm-up live view, while someone looks", "recorder"))
"""The global path in ``map``."""
NAV_STATUS = Topic("nav_status", "diagnostic_msgs/msg/DiagnosticStatus",
                   Qos(100, durability=TRANSIENT_LOCAL),
                   ("the robot's navigator (on every change of state and at 2 Hz simulated)",),
                   ("the robot's commander (NAV_STATUS_COMMANDER_READER_QOS)",
                    "swarm-up metrics (NAV_STATUS_METRICS_READER_QOS)", "recorder"))
"""The navigator's writer: reliable and transient-local with 100 messages (50 s simulated at
2 Hz), for the reason :data:`CMD_VEL` has one: a reader whose side matched late still gets every
status, not the last alone, and so every goal, even one that ended, or whose navigator was
killed, before the reader matched."""
NAV_STATUS_COMMANDER_READER_QOS = Qos(10, durability=TRANSIENT_LOCAL)
"""The commander's reader: 10, so no transition is lost in a burst."""
NAV_STATUS_METRICS_READER_QOS = Qos(100, durability=TRANSIENT_LOCAL)
"""The metrics listener's reader keeps 100 per robot, 50 simulated seconds of statuses at 2 Hz,
so a listener thread that falls behind under load still sees every SUCCEEDED before the next
goal's status (tests/swarm_metrics/test_listener.py)."""
GOAL_POSE = Topic("goal_pose", "geometry_msgs/msg/PoseStamped", DEFAULT,
                  ("the robot's commander", "anyone (ros2 topic pub, RViz's goal tool)"),
                  ("the robot's navigator",))
"""A new goal replaces the current one."""

ROBOT_DESCRIPTION = Topic("robot_description", "std_msgs/msg/String", LATCHED,
                          ("swarm_sim (once, at start; --no-tf: never)",),
                          ("RViz2's RobotModel (TF Prefix: the namespace)",))
"""The robot's URDF after xacro, unprefixed link names, as ``robot_state_publisher`` latches
it; RViz2's RobotModel display draws it with TF Prefix ``<ns>``."""

# ------------------------------------------------------------------------- a robot's services
CANCEL = Service("navigator/cancel", "std_srvs/srv/Trigger", ("the robot's navigator",),
                 ("the robot's commander (cancelTask; centralized: also \"no next goal\")",
                  "anyone"))
"""Cancels the current goal; while no goal runs, ends the navigator's wait for the next one."""
CANCEL_SERVICE = CANCEL.name
"""The name of :data:`CANCEL`, as ``create_service`` and ``create_client`` take it."""
GOAL_COMING = Service("navigator/goal_coming", "std_srvs/srv/Trigger",
                      ("the robot's navigator",),
                      ("the robot's commander (centralized: once the coordinator has its "
                       "request)",))
"""The commander has taken in the goal that ended and its next goal is coming: the tick at which
the goal ended may be answered (``hold_goal_end``, :mod:`swarm_common.lockstep`)."""
GOAL_COMING_SERVICE = GOAL_COMING.name
"""The name of :data:`GOAL_COMING`."""

# ------------------------------------------------------------------ the simulator's services
SIMULATION_SERVICES = {
    name: Service(f"/swarm_sim/{name}", f"simulation_interfaces/srv/{kind}", ("swarm_sim",),
                  ("test harnesses, anyone",))
    for name, kind in (
        ("get_simulator_features", "GetSimulatorFeatures"),
        ("get_simulation_state", "GetSimulationState"),
        ("set_simulation_state", "SetSimulationState"),
        ("step_simulation", "StepSimulation"),
        ("get_entities", "GetEntities"),
        ("get_entity_state", "GetEntityState"),
        ("get_entities_states", "GetEntitiesStates"),
        ("get_entity_info", "GetEntityInfo"),
    )
}
"""The ROS simulation standard's services the simulator serves (``simulation_interfaces`` 1.x,
names relative to the node as Gazebo's ``ros_gz_sim`` has them under ``/gzserver``), by their
name in the node: :mod:`swarm_sim.sim_services` says what each does here."""

ROBOT_TOPICS = (SCAN, ODOM, GROUND_TRUTH, CMD_VEL, PLAN, NAV_STATUS)
"""A robot's topics that a recording holds, in its order."""


def robot_topic(ns: str, topic: Topic | str) -> str:
    """The absolute name of a robot's topic (``robot_topic("Srobot3", ODOM)`` is
    ``/Srobot3/odom``)."""
    name = topic.name if isinstance(topic, Topic) else topic
    return f"/{ns.strip('/')}/{name}"


def assignment_topic(ns: str) -> str:
    """The absolute assignment topic of robot ``ns`` (``/Srobot3/coordinator/assignment``)."""
    return robot_topic(ns, ASSIGNMENT)
