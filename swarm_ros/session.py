"""The life of a node process, as the Jazzy demos write it (STYLE.md point 7), written once:
``rclpy.init``, the nodes, spin; Ctrl-C, SIGTERM or a shutdown from elsewhere end it quietly;
every node is destroyed and the context shut down, whatever happened."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import rclpy
from rclpy.executors import ExternalShutdownException


@contextlib.contextmanager
def node_session(args: list[str] | None = None, **init_kwargs) -> Iterator[list]:
    """``rclpy.init(args, **init_kwargs)``; the block adds its nodes to the list it gets.

    On leaving the block: ``KeyboardInterrupt`` and ``ExternalShutdownException`` end it quietly,
    and so does any other exception once the context is shut down (a Ctrl-C while a node was
    being created or was publishing: rclpy then raises about the invalid context); every node
    in the list is destroyed (last first) and the context shut down (``try_shutdown``).  Any
    other exception goes on.

    Args:
        args: ``rclpy.init``'s arguments (ROS arguments included).
        **init_kwargs: more ``rclpy.init`` arguments (``context``, ``signal_handler_options``).
    """
    context = init_kwargs.get("context")
    rclpy.init(args=args, **init_kwargs)
    nodes: list = []
    try:
        yield nodes
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok(context=context):
            raise
    finally:
        for node in reversed(nodes):
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def spin_forever(executor, context) -> None:
    """Spin until the context shuts down (Ctrl-C, SIGTERM).

    ``EventsExecutor.spin()`` of this rclpy (7.1.6 wheels) delivered no message across processes
    in our tests while ``spin_once`` did, so we loop on ``spin_once``.
    """
    while context.ok():
        executor.spin_once(timeout_sec=0.5)
