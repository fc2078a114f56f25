"""The live view of a run: the dashboard's web server (:mod:`swarm_viz.server`) and page
(``web/``), the fleet's state and the page's messages (:mod:`swarm_viz.fleet_view`, pure), the
ROS node that feeds them (:mod:`swarm_viz.node`) and ``/swarm/markers``
(:mod:`swarm_viz.markers`)."""
