"""The one command-line helper of every command (STYLE.md point 16).

A command builds its flags on :class:`ArgumentParser`, whose usage errors raise
:class:`~swarm_common.errors.InputError` instead of printing usage and exiting; the command's
entry point wraps its body in :func:`~swarm_common.errors.run_cli`, which turns that error into
one line on stderr and exit code 2 (docs/reference/contract.md#s2)::

    swarm-up: error: --swarm-size: must be a positive integer, got '0'

The validators below are argparse ``type=`` callables: each returns the typed value or raises
:class:`argparse.ArgumentTypeError` with a message that argparse prefixes with the flag.

One ROS-name rule for every name a user gives (robot namespace prefixes, namespaces): see
:func:`is_ros_name`.
"""

from __future__ import annotations

import argparse
import math
import re

from swarm_common.errors import InputError, run_cli

__all__ = [
    "ROS_NAME_RULE",
    "ArgumentParser",
    "InputError",
    "finite_float",
    "is_ros_name",
    "is_ros_namespace",
    "non_negative_float",
    "non_negative_int",
    "port",
    "positive_float",
    "positive_int",
    "ros_name",
    "ros_names",
    "run_cli",
    "seed",
]

# ASCII only: ``[A-Za-z]`` is spelled out, so ``str.isalnum``'s non-ASCII letters do not pass.
_ROS_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
ROS_NAME_RULE = "letters, digits and '_', starting with a letter, no '__'"


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose usage errors are one :class:`InputError` line, not usage + exit.

    The message drops argparse's ``"argument "`` prefix so it starts with the flag, like every
    other input error: ``"--rtf: must be a number >= 0, got '-1'"``.
    """

    def error(self, message: str):  # noqa: D102 - argparse API
        raise InputError(message.removeprefix("argument "))


# ------------------------------------------------------------------------------------ names
def is_ros_name(text: str) -> bool:
    """Whether ``text`` is one ROS 2 name token (a node name, a namespace part, a prefix).

    The rule: ASCII letters, digits and ``_``; starts with a letter; no ``__``.  This is the
    ROS 2 design article "Topic and Service name mapping to DDS"
    (https://design.ros2.org/articles/topic_and_service_names.html): a token "must not start
    with a numeric character" and a name "must not contain any number of repeated underscores";
    ``__`` is reserved for ROS arguments such as ``__ns``.  We also refuse a leading ``_``
    (ROS allows it), as ``swarm-up`` always has: ``/_x1`` reads as private, not as a robot.

    Args:
        text: the candidate, without any ``/``.

    Returns:
        True if it is a valid name.
    """
    return bool(_ROS_NAME.fullmatch(text)) and "__" not in text


def is_ros_namespace(text: str) -> bool:
    """Whether ``text`` is a ROS namespace: :func:`is_ros_name` parts joined by ``/``.

    Args:
        text: the candidate; one leading ``/`` is allowed (``/fleet/Srobot3``).

    Returns:
        True if every part is a valid name (no empty part, no trailing ``/``).
    """
    return all(is_ros_name(part) for part in text.removeprefix("/").split("/"))


def ros_name(text: str) -> str:
    """argparse type: one ROS name (:func:`is_ros_name`), e.g. a namespace prefix ``Srobot``."""
    if not is_ros_name(text):
        raise argparse.ArgumentTypeError(f"must be a ROS name ({ROS_NAME_RULE}), got {text!r}")
    return text


def ros_names(text: str) -> tuple[str, ...]:
    """argparse type: a comma-separated list of ROS names; a leading ``/`` of each is dropped.

    Returns:
        The names, in order (at least one).
    """
    names = tuple(n.strip().strip("/") for n in text.split(",") if n.strip())
    if not names or not all(map(is_ros_name, names)):
        raise argparse.ArgumentTypeError(
            f"must be a comma-separated list of ROS names ({ROS_NAME_RULE}), got {text!r}")
    return names


# ---------------------------------------------------------------------------------- numbers
def _number(text: str, parse, ok, what: str):
    """``parse(text)`` if it parses and ``ok`` holds, else argparse's error naming ``what``."""
    try:
        value = parse(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
    if not ok(value):
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
    return value


def _int(text: str, ok, what: str) -> int:
    return _number(text, int, ok, what)


def _float(text: str, ok, what: str) -> float:
    return _number(text, float, lambda v: math.isfinite(v) and ok(v), what)


def positive_int(text: str) -> int:
    """argparse type: an integer > 0 (a count)."""
    return _int(text, lambda v: v > 0, "a positive integer")


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0 (a count that may be zero)."""
    return _int(text, lambda v: v >= 0, "an integer >= 0")


def seed(text: str) -> int:
    """argparse type: a random seed, an integer >= 0 (what ``numpy.random.default_rng`` takes)."""
    return non_negative_int(text)


def port(text: str) -> int:
    """argparse type: a TCP port, 1..65535."""
    return _int(text, lambda v: 0 < v < 65536, "a TCP port 1-65535")


def finite_float(text: str) -> float:
    """argparse type: any finite number (not nan, not inf)."""
    return _float(text, lambda v: True, "a finite number")


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    return _float(text, lambda v: v >= 0, "a number >= 0")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    return _float(text, lambda v: v > 0, "a positive number")


def positive_floats(text: str) -> tuple[float, ...]:
    """argparse type: a comma-separated list of finite numbers > 0 (``2,1,1``)."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(
            f"must be a comma-separated list of positive numbers, got {text!r}")
    return values


def host_port(text: str) -> str:
    """argparse type: ``HOST:PORT``, a host name or IPv4 address and a port 1..65535."""
    host, sep, port_text = text.strip().rpartition(":")
    try:
        ok = bool(sep and host and 0 < int(port_text) < 65536
                  and all(c.isalnum() or c in ".-" for c in host))
    except ValueError:
        ok = False
    if not ok:
        raise argparse.ArgumentTypeError(f"must be HOST:PORT (e.g. 10.0.0.1:11811), got {text!r}")
    return f"{host}:{int(port_text)}"


def hosts(text: str) -> tuple[str, ...]:
    """argparse type: ``HOST,HOST,...``, each a host name or IPv4 address (no port)."""
    items = tuple(h.strip() for h in text.split(","))
    if not all(h and all(c.isalnum() or c in ".-" for c in h) for h in items):
        raise argparse.ArgumentTypeError(f"must be HOST,HOST,... (host names or IPv4 addresses, "
                                         f"e.g. 10.0.0.2,10.0.0.3), got {text!r}")
    return items


# ------------------------------------------------------------------------------ shared flags
SHARED_FLAGS = {
    "--world": {"default": "slim_blockage", "metavar": "NAME|PATH"},
    "--robot": {"default": "turtlebot3_waffle", "metavar": "NAME|PATH|MIX"},
    "--seed": {"type": seed, "default": 0, "metavar": "S"},
    "--name-prefix": {"type": ros_name, "default": "Srobot", "metavar": "PREFIX"},
    "--swarm-size": {"type": positive_int, "metavar": "N"},
}
"""The flags several commands take, each defined once: type (validator), default, metavar."""


def add_shared(p: argparse.ArgumentParser, flag: str, help: str, **overrides) -> None:
    """Add one of :data:`SHARED_FLAGS` to ``p`` with the command's own ``help`` (and, say, its
    own ``default``)."""
    p.add_argument(flag, **{**SHARED_FLAGS[flag], **overrides}, help=help)
