"""An RViz2 configuration for a swarm: the map, every robot's model, scan and plan.

``swarm-up`` writes one for its robots into every run directory (``RUN/swarm.rviz``;
``rviz2 -d RUN/swarm.rviz``); ``docs/swarm.rviz`` is the one of the README's 20-robot run
(``tools/gen_docs.py``).  Every display reads a standard topic with the QoS its writer offers
(:mod:`swarm_common.topics`): ``/map``, and per robot ``/<ns>/robot_description`` (RobotModel,
TF Prefix ``<ns>``: the simulator's ``/tf`` prefixes each robot's frames with its namespace),
``/<ns>/scan`` and ``/<ns>/plan``; ``/swarm/markers`` (``swarm-up --markers``) is listed, off.
The property names are RViz2's (Jazzy's ``rviz_default_plugins``, as nav2_bringup's
``nav2_default_view.rviz`` writes them).
"""

from __future__ import annotations

from collections.abc import Sequence

import yaml

from swarm_common import topics
from swarm_common.topics import Qos, Topic, robot_topic

# tab10's colours, one per robot in turn (RViz2 writes colours as "R; G; B")
_COLOURS = ("31; 119; 180", "255; 127; 14", "44; 160; 44", "214; 39; 40", "148; 103; 189",
            "140; 86; 75", "227; 119; 194", "127; 127; 127", "188; 189; 34", "23; 190; 207")


def _topic(name: str, qos: Qos) -> dict:
    return {"Depth": qos.depth,
            "Durability Policy": "Transient Local" if qos.durability == topics.TRANSIENT_LOCAL
            else "Volatile",
            "History Policy": "Keep Last",
            "Reliability Policy": "Reliable" if qos.reliability == topics.RELIABLE
            else "Best Effort",
            "Value": name}


def _robot(ns: str, colour: str) -> dict:
    def name(t: Topic) -> str:
        return robot_topic(ns, t)

    return {"Class": "rviz_common/Group", "Enabled": True, "Name": ns, "Displays": [
        {"Class": "rviz_default_plugins/RobotModel", "Name": "RobotModel", "Enabled": True,
         "Value": True, "Alpha": 1, "Description Source": "Topic", "Description File": "",
         "Description Topic": _topic(name(topics.ROBOT_DESCRIPTION),
                                     topics.ROBOT_DESCRIPTION.qos),
         "TF Prefix": ns, "Visual Enabled": True, "Collision Enabled": False,
         "Update Interval": 0},
        {"Class": "rviz_default_plugins/LaserScan", "Name": "LaserScan", "Enabled": True,
         "Value": True, "Topic": _topic(name(topics.SCAN), topics.SCAN.qos),
         "Color Transformer": "FlatColor", "Color": colour, "Style": "Points",
         "Size (Pixels)": 3, "Decay Time": 0, "Use Fixed Frame": True},
        {"Class": "rviz_default_plugins/Path", "Name": "Plan", "Enabled": True, "Value": True,
         "Topic": _topic(name(topics.PLAN), topics.PLAN.qos), "Color": colour,
         "Line Style": "Lines", "Line Width": 0.03, "Buffer Length": 1, "Alpha": 1,
         "Pose Style": "None"},
    ]}


def rviz_config(namespaces: Sequence[str], goal_ns: str | None = None) -> str:
    """The configuration's YAML text.

    Args:
        namespaces: the robots' namespaces, without the leading slash.
        goal_ns: the robot the 2D Goal Pose tool sends to (default: the first).
    """
    goal_ns = goal_ns or (namespaces[0] if namespaces else "")
    displays = [
        {"Class": "rviz_default_plugins/Grid", "Name": "Grid", "Enabled": True, "Value": True,
         "Cell Size": 1, "Plane Cell Count": 40, "Color": "160; 160; 164", "Alpha": 0.5,
         "Reference Frame": "<Fixed Frame>", "Plane": "XY"},
        {"Class": "rviz_default_plugins/Map", "Name": "Map", "Enabled": True, "Value": True,
         "Topic": _topic(topics.MAP.name, topics.MAP.qos), "Color Scheme": "map",
         "Draw Behind": True, "Alpha": 1},
        {"Class": "rviz_default_plugins/TF", "Name": "TF", "Enabled": False, "Value": False,
         "Show Names": False, "Show Axes": True, "Show Arrows": False, "Marker Scale": 0.3,
         "Frame Timeout": 15},
        {"Class": "rviz_default_plugins/MarkerArray", "Name": "Swarm markers",
         "Enabled": False, "Value": False,
         "Topic": _topic(topics.MARKERS.name, topics.MARKERS.qos)},
        *(_robot(ns, _COLOURS[k % len(_COLOURS)]) for k, ns in enumerate(namespaces)),
    ]
    config = {
        "Panels": [
            {"Class": "rviz_common/Displays", "Name": "Displays", "Help Height": 0},
            {"Class": "rviz_common/Views", "Name": "Views"},
        ],
        "Visualization Manager": {
            "Class": "",
            "Displays": displays,
            "Enabled": True,
            "Global Options": {"Background Color": "48; 48; 48", "Fixed Frame": "map",
                               "Frame Rate": 30},
            "Name": "root",
            "Tools": [
                {"Class": "rviz_default_plugins/MoveCamera"},
                {"Class": "rviz_default_plugins/Select"},
                {"Class": "rviz_default_plugins/Measure", "Line color": "128; 128; 0"},
                {"Class": "rviz_default_plugins/SetGoal",
                 "Topic": _topic(robot_topic(goal_ns, topics.GOAL_POSE), topics.GOAL_POSE.qos)},
            ],
            "Value": True,
            "Views": {"Current": {"Class": "rviz_default_plugins/TopDownOrtho",
                                  "Name": "Current View", "Scale": 40, "X": 0, "Y": 0,
                                  "Target Frame": "<Fixed Frame>", "Value": "TopDownOrtho"},
                      "Saved": None},
        },
        "Window Geometry": {"Height": 900, "Width": 1400, "Hide Left Dock": False,
                            "Displays": {"collapsed": False}},
    }
    head = (f"# RViz2 configuration of {len(namespaces)} robots (swarm_viz/rviz_config.py): "
            "rviz2 -d THIS_FILE\n")
    return head + yaml.safe_dump(config, sort_keys=False, default_flow_style=False, width=99)
