"""The ``simulation_interfaces`` services of the simulator node ``/swarm_sim``.

The ROS simulation standard (``simulation_interfaces`` 1.x, the line Jazzy ships and Gazebo's
``ros_gz_sim`` implements; built here: :mod:`swarm_ros.built_interfaces`), with names relative
to the node as Gazebo's are (``/swarm_sim/get_simulation_state`` as ``/gzserver/...``):

=============================  ==================================================================
``~/get_simulator_features``   what is served (below)
``~/get_simulation_state``     playing, paused or stopped
``~/set_simulation_state``     play, pause (at the next tick boundary), stop (ends the run)
``~/step_simulation``          N ticks while paused; answered once they are taken
``~/get_entities``             the robots (names: their namespaces), filtered by name, category,
                               sphere or box bounds
``~/get_entity_state``         a robot's ground-truth pose and velocity in ``map``, stamped with
                               simulated time
``~/get_entities_states``      both at once
``~/get_entity_info``          category robot, its model
=============================  ==================================================================

Not served: spawning, deleting and setting entities, named poses, worlds, and
``ResetSimulation`` (a run's navigators and commanders hold state the simulator cannot rewind;
see :mod:`swarm_sim.sim_control`).

The simulator's executor (``EventsExecutor``) cannot defer an answer (no coroutine callbacks in
rclpy 7.1.6's), and a pause or a stepping is answered only once the loop holds between ticks; so
these services are not given to the executor: :meth:`SimServices.poll` takes their requests
from the simulator's waits (at most every ``POLL_S`` wall seconds) and answers each when it can.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from swarm_common import topics
from swarm_sim.sim_control import (
    PAUSED,
    PLAYING,
    QUITTING,
    STATE_NAMES,
    STOPPED,
    FilterError,
    SimControl,
    TransitionError,
    matching_entities,
)

POLL_S = 0.02  # [s] wall: the services' requests are taken at most this often


class SimServices:
    """The services of the node (the module docstring).

    ``HANDLERS`` names the method that answers each of
    :data:`swarm_common.topics.SIMULATION_SERVICES`.

    Args:
        node: the simulator node (:class:`swarm_sim.node.SimulatorNode`): its ``engine``,
            ``names``, ``gate`` (simulated time) and ``loop.control`` are read.
        models: (N) each robot's model name (``GetEntityInfo``'s description).
    """

    HANDLERS = {"get_simulator_features": "_features", "get_simulation_state": "_get_state",
                "set_simulation_state": "_set_state", "step_simulation": "_step",
                "get_entities": "_entities", "get_entity_state": "_entity_state",
                "get_entities_states": "_entities_states", "get_entity_info": "_entity_info"}

    def __init__(self, node, models):
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
        from rclpy.qos import qos_profile_services_default
        from rclpy.type_support import check_is_valid_srv_type
        from simulation_interfaces import srv

        self.node, self.models = node, list(models)
        self.control: SimControl = node.loop.control
        self._handlers: dict[str, Callable] = {
            name: getattr(self, method) for name, method in self.HANDLERS.items()}
        types = {name: getattr(srv, service.type.rsplit("/", 1)[1])
                 for name, service in topics.SIMULATION_SERVICES.items()}
        qos = qos_profile_services_default.get_c_qos_profile()
        self._services = []
        for name in topics.SIMULATION_SERVICES:
            check_is_valid_srv_type(types[name])  # loads its type support
            with node.handle:
                impl = _rclpy.Service(node.handle, types[name], f"~/{name}", qos)
            self._services.append((name, types[name], impl))
        self._last = -math.inf

    # -- taking and answering --------------------------------------------------------------------
    def poll(self, now: float | None = None) -> None:
        """Take the requests that came (at most every ``POLL_S``), answer those that can be,
        and the deferred ones once the loop holds between ticks (or has stopped)."""
        now = time.monotonic() if now is None else now
        control = self.control
        if control.waiting and control.settled():
            for send, response in control.waiting:
                send(response)
            control.waiting.clear()
        if now - self._last < POLL_S:
            return
        self._last = now
        for name, srv_type, impl in self._services:
            while True:
                taken = impl.service_take_request(srv_type.Request)
                if taken is None or taken[1] is None:
                    break
                request, header = taken
                response = srv_type.Response()
                def send(resp, impl=impl, header=header):
                    impl.service_send_response(resp, header.request_id
                                               if hasattr(header, "request_id") else header)
                try:
                    defer = self._handlers[name](request, response)
                except Exception as exc:  # noqa: BLE001 - a request we cannot read: say so
                    self._result(response, "RESULT_OPERATION_FAILED",
                                 f"{type(exc).__name__}: {exc}")
                    self.node.get_logger().warning(
                        f"simulation_interfaces: a {name} request failed: {exc}",
                        throttle_duration_sec=5.0)
                    defer = False
                if defer:
                    control.waiting.append((send, response))
                else:
                    send(response)

    def finish(self) -> None:
        """The run ends: answer every request still waiting (as filled in: OK).  The services
        stay up until the process ends: taking them down at once lost the answer to the
        "stopped" that ended the run (a test on a loaded machine)."""
        for send, response in self.control.waiting:
            send(response)
        self.control.waiting.clear()

    # -- the handlers: fill ``response``; True defers the answer to the next boundary ----------
    def _result(self, response, code: str, message: str = "") -> None:
        from simulation_interfaces.msg import Result

        # a Result code, or one of the service's own (SetSimulationState's, above 100)
        owner = Result if hasattr(Result, code) else type(response)
        response.result.result = getattr(owner, code)
        response.result.error_message = message

    def _features(self, request, response) -> bool:
        from simulation_interfaces.msg import SimulatorFeatures as F

        response.features.features = [
            F.ENTITY_STATE_GETTING, F.ENTITY_INFO_GETTING, F.ENTITY_CATEGORIES,
            F.ENTITY_BOUNDS_BOX, F.SIMULATION_STATE_GETTING, F.SIMULATION_STATE_SETTING,
            F.SIMULATION_STATE_PAUSE, F.STEP_SIMULATION_SINGLE, F.STEP_SIMULATION_MULTIPLE]
        response.features.custom_info = (
            "Swarm Workbench swarm_sim: entities are the robots (names: their namespaces); "
            "a step is one control tick; stopped ends the run (no reset); "
            "docs/guides/ros2_tools.md")
        return False

    def _get_state(self, request, response) -> bool:
        response.state.state = self.control.state
        self._result(response, "RESULT_OK")
        return False

    def _set_state(self, request, response) -> bool:
        target = int(request.state.state)
        try:
            defer = self.control.set_state(target)
        except TransitionError as exc:
            self._result(response, exc.code, str(exc))
            return False
        self._result(response, "RESULT_OK")
        if target in (STOPPED, QUITTING):  # the same here: the run ends
            self.node.log("warning", f"simulation_interfaces: {STATE_NAMES[STOPPED]} at t = "
                          f"{self.node.gate.t_ns / 1e9:.1f} s; the run ends")
        elif target in (PAUSED, PLAYING):
            self.node.log("info", f"simulation_interfaces: {STATE_NAMES[target]} at t = "
                          f"{self.node.gate.t_ns / 1e9:.1f} s")
        return defer

    def _step(self, request, response) -> bool:
        try:
            defer = self.control.step(int(request.steps))
        except TransitionError as exc:
            self._result(response, exc.code, str(exc))
            return False
        self._result(response, "RESULT_OK")
        return defer

    def _select(self, request, response) -> list[int] | None:
        f = request.filters
        node = self.node
        try:
            return matching_entities(
                node.names, node.engine.poses, [m.radius for m in node.engine.models],
                pattern=f.filter, categories=[c.category for c in f.categories],
                tags=list(f.tags.tags), bounds_type=f.bounds.type,
                bounds_points=[(p.x, p.y, p.z) for p in f.bounds.points])
        except FilterError as exc:
            self._result(response, exc.code, str(exc))
            return None

    def _entities(self, request, response) -> bool:
        picked = self._select(request, response)
        if picked is not None:
            response.entities = [self.node.names[i] for i in picked]
            self._result(response, "RESULT_OK")
        return False

    def _index(self, name: str, response) -> int | None:
        try:
            return self.node.names.index(name.strip("/"))
        except ValueError:
            self._result(response, "RESULT_NOT_FOUND", f"no entity '{name}' (the entities are "
                         "the robots' namespaces)")
            return None

    def _fill_state(self, state, i: int) -> None:
        from swarm_ros.messages import time_msg

        eng = self.node.engine
        x, y, yaw = (float(v) for v in eng.poses[i])
        v, w = float(eng.v[i]), float(eng.w[i])
        state.header.frame_id = "map"
        state.header.stamp = time_msg(self.node.gate.t_ns)
        state.pose.position.x, state.pose.position.y = x, y
        state.pose.orientation.z, state.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        state.twist.linear.x, state.twist.linear.y = v * math.cos(yaw), v * math.sin(yaw)
        state.twist.angular.z = w

    def _entity_state(self, request, response) -> bool:
        i = self._index(request.entity, response)
        if i is not None:
            self._fill_state(response.state, i)
            self._result(response, "RESULT_OK")
        return False

    def _entities_states(self, request, response) -> bool:
        from simulation_interfaces.msg import EntityState

        picked = self._select(request, response)
        if picked is not None:
            response.entities = [self.node.names[i] for i in picked]
            states = []
            for i in picked:
                state = EntityState()
                self._fill_state(state, i)
                states.append(state)
            response.states = states
            self._result(response, "RESULT_OK")
        return False

    def _entity_info(self, request, response) -> bool:
        from simulation_interfaces.msg import EntityCategory

        i = self._index(request.entity, response)
        if i is not None:
            response.info.category.category = EntityCategory.CATEGORY_ROBOT
            response.info.description = f"robot {self.node.names[i]} ({self.models[i]})"
            self._result(response, "RESULT_OK")
        return False
