"""The scene: how a world, a robot, a map and a fleet are read, and where robots are spawned.

Loaders of Gazebo SDF worlds (:mod:`swarm_scene.world`, meshes in :mod:`swarm_scene.meshes`,
``model://`` and ``file://`` in :mod:`swarm_scene.resources`), URDF/xacro robots
(:mod:`swarm_scene.robot_model`), map_server maps (:mod:`swarm_scene.map_io` into
:class:`swarm_scene.occupancy.OccupancyMap`, or rasterised from the world by
:mod:`swarm_scene.rasterize`), points of interest (:mod:`swarm_scene.poi`), mixed fleets
(:mod:`swarm_scene.fleet`) and spawn poses (:mod:`swarm_scene.spawn`).

Pure, as :mod:`swarm_common` is: no ``rclpy``, no ``*_msgs`` (a test checks it).  It imports
only :mod:`swarm_common` (errors, geometry, paths); what goes over the wire lives there.
"""
