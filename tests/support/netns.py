"""Several hosts on one machine, for tests of what crosses a network (``swarm-up --hosts``).

:class:`Hosts` makes ``k`` network namespaces, each with one interface on a bridge that lives in
a namespace of its own (so nothing of the machine's own network changes), addresses
``10.231.<net>.1 .. k``, loopback up and a route for multicast (ROS 2's simple discovery). The
namespaces share ``/dev/shm``, so their DDS participants must not use shared memory:
:meth:`Hosts.env` sets ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` (with 4 MB socket buffers) and the
discovery range ``SUBNET``.
Needs root (``ip netns``); everything made is removed at the end.
"""

from __future__ import annotations

import os
import subprocess

SOCKET_BUFFER_BYTES = 4 * 1024 * 1024  # Fast DDS's UDP send and receive buffers [bytes]


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


class Hosts:
    """``with Hosts(k, tag) as hosts:`` ``k`` hosts ``hosts.names[i]`` at ``hosts.addr[i]``.

    Args:
        k: how many hosts.
        tag: makes the names unique on the machine (e.g. the test session's domain id).
    """

    def __init__(self, k: int, tag: int):
        self.k = k
        self.tag = tag
        self.names = [f"swh{tag}_{i}" for i in range(k)]
        self.bridge_ns = f"swh{tag}_br"
        net = tag % 250
        self.addr = [f"10.231.{net}.{i + 1}" for i in range(k)]

    def __enter__(self) -> Hosts:
        try:
            _ip("netns", "add", self.bridge_ns)
            _ip("-n", self.bridge_ns, "link", "add", "br0", "type", "bridge")
            _ip("-n", self.bridge_ns, "link", "set", "br0", "up")
            for i, ns in enumerate(self.names):
                _ip("netns", "add", ns)
                _ip("link", "add", "eth0", "netns", ns, "type", "veth", "peer", "name",
                    f"p{i}", "netns", self.bridge_ns)
                _ip("-n", self.bridge_ns, "link", "set", f"p{i}", "master", "br0")
                _ip("-n", self.bridge_ns, "link", "set", f"p{i}", "up")
                _ip("-n", ns, "addr", "add", f"{self.addr[i]}/24", "dev", "eth0")
                _ip("-n", ns, "link", "set", "eth0", "up")
                _ip("-n", ns, "link", "set", "lo", "up")
                _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", "eth0")
        except subprocess.CalledProcessError as exc:
            self.__exit__()
            raise RuntimeError(f"cannot make network namespaces: {' '.join(exc.cmd)}: "
                               f"{exc.stderr.strip()}") from None
        return self

    def __exit__(self, *exc) -> None:
        for ns in [*self.names, self.bridge_ns]:
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)

    def argv(self, i: int, argv: list[str]) -> list[str]:
        """``argv`` run in host ``i``."""
        return ["ip", "netns", "exec", self.names[i], *argv]

    def cut(self, i: int) -> None:
        """Host ``i`` loses its network (its interface goes down)."""
        _ip("-n", self.names[i], "link", "set", "eth0", "down")

    @staticmethod
    def env(base: dict | None = None) -> dict[str, str]:
        """The environment of a process on these hosts: UDP only, discovery on the subnet.

        The UDP sockets' buffers are 4 MB (``sockets_size``, Fast DDS 2.14's option of the
        built-in transports; the kernel caps it at ``net.core.rmem_max``): with the system's
        default 208 KB a 200-robot run over two hosts lost 15-25 % of its datagrams to full
        receive buffers (docs/guides/multi_host.md, "UDP socket buffers").
        """
        env = dict(os.environ if base is None else base)
        env.update(FASTDDS_BUILTIN_TRANSPORTS=f"UDPv4?sockets_size={SOCKET_BUFFER_BYTES}",
                   ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET")
        env.pop("ROS_LOCALHOST_ONLY", None)
        return env


def can_make_namespaces() -> bool:
    """Whether this process may make network namespaces (root with ``ip``)."""
    return os.geteuid() == 0 and subprocess.run(["ip", "netns", "list"],
                                                capture_output=True).returncode == 0
