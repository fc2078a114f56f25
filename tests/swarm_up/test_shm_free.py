"""The processes that fault injection may SIGKILL, and the commanders, run Fast DDS without
shared memory (:func:`swarm_up.children.shm_free_env`): which children get it, what it sets, and
that such a process still talks to ordinary ones while it maps no ``/dev/shm`` file of Fast
DDS."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from dataclasses import replace

import pytest
from std_msgs.msg import String

from swarm_common.faults import parse_faults
from swarm_common.paths import FASTDDS_UDP_LOOPBACK_PROFILE, FASTDDS_UDP_ONLY_PROFILE
from swarm_up.children import (
    LOCALHOST_ONLY_ENV,
    PROFILES_ENV,
    RANGE_ENV,
    child_specs,
    shm_free_env,
)
from swarm_up.run_config import RunConfig
from tests.support.ros import ros_context, spin_until
from tests.swarm_up.test_params_files import cfg  # noqa: F401 - the RunConfig fixture


def test_localhost_becomes_a_loopback_only_udp_profile():
    env = shm_free_env({RANGE_ENV: "LOCALHOST", "ROS_DOMAIN_ID": "7"})
    assert env == {RANGE_ENV: "SUBNET", "ROS_DOMAIN_ID": "7",
                   PROFILES_ENV: str(FASTDDS_UDP_LOOPBACK_PROFILE)}


def test_localhost_only_counts_as_localhost_and_is_turned_off():
    # rcl lets ROS_LOCALHOST_ONLY=1 override the range ("'localhost_only' is enabled,
    # 'automatic_discovery_range' and 'static_peers' will be ignored"), and rmw then adds
    # shared memory again.
    env = shm_free_env({LOCALHOST_ONLY_ENV: "1"})
    assert env == {RANGE_ENV: "SUBNET", LOCALHOST_ONLY_ENV: "0",
                   PROFILES_ENV: str(FASTDDS_UDP_LOOPBACK_PROFILE)}


@pytest.mark.parametrize("given", [{}, {RANGE_ENV: "SUBNET"}, {RANGE_ENV: "SYSTEM_DEFAULT"}])
def test_other_ranges_keep_theirs_and_get_the_udp_only_profile(given):
    assert shm_free_env(given) == {**given, PROFILES_ENV: str(FASTDDS_UDP_ONLY_PROFILE)}


def test_a_profiles_file_of_the_user_is_kept():
    given = {RANGE_ENV: "LOCALHOST", PROFILES_ENV: "/home/me/dds.xml"}
    assert shm_free_env(given) == given


def test_the_profiles_are_bundled():
    for path in (FASTDDS_UDP_ONLY_PROFILE, FASTDDS_UDP_LOOPBACK_PROFILE):
        text = path.read_text()
        assert "<useBuiltinTransports>false</useBuiltinTransports>" in text
        assert "<type>UDPv4</type>" in text and "SHM" not in text


def shm_free_children(run: RunConfig) -> set[str]:
    """The names of the children of ``run`` that get a profile of their own."""
    return {s.name for s in child_specs(run)
            if s.env.get(PROFILES_ENV) != os.environ.get(PROFILES_ENV)}


def test_the_children_a_fault_kills_and_the_commanders_go_without_shared_memory(cfg):  # noqa: F811
    commanders = {f"cmd_{ns}" for ns in cfg.robots}
    assert commanders and cfg.commanders
    faults = parse_faults("kill-nav:2@10,kill-robot:3@20,freeze:1@5+5", cfg.robots)
    cfg = replace(cfg, faults=faults, coordination="centralized")
    assert shm_free_children(cfg) == {"coordinator", "nav_Srobot2", "nav_Srobot3"} | commanders
    # Without kill faults: the coordinator (anyone may kill it) and the commanders (their
    # traffic is light), every navigator keeps shared memory.
    cfg = replace(cfg, faults=parse_faults("freeze:1@5+5", cfg.robots))
    assert shm_free_children(cfg) == {"coordinator"} | commanders
    cfg = replace(cfg, coordination="decentralized")
    assert shm_free_children(cfg) == commanders


PEER = textwrap.dedent("""
    import os, sys, time
    import rclpy
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node("shm_free_peer")
    heard = []
    node.create_subscription(String, "/shm_free/in", lambda m: heard.append(m.data), 10)
    pub = node.create_publisher(String, "/shm_free/out", 10)
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not heard:
        pub.publish(String(data="from the peer"))
        rclpy.spin_once(node, timeout_sec=0.1)
    maps = open(f"/proc/{os.getpid()}/maps").read().splitlines()
    shm = sorted({line.split()[-1] for line in maps if "/dev/shm/fast" in line})
    print("heard", heard[:1], "shm", shm, flush=True)
    node.destroy_node()
    rclpy.shutdown()
""")


@pytest.mark.node
def test_a_shm_free_process_talks_to_ordinary_ones_and_maps_no_shm_file(tmp_path):
    # This test process is an ordinary participant (the session's range, LOCALHOST, with shared
    # memory); the peer runs with shm_free_env, as a killed-by-fault child would.
    env = shm_free_env(dict(os.environ))
    assert env[PROFILES_ENV] in (str(FASTDDS_UDP_LOOPBACK_PROFILE), str(FASTDDS_UDP_ONLY_PROFILE))
    heard = []
    with ros_context() as (ctx, ex):
        import rclpy

        node = rclpy.create_node("shm_free_probe", context=ctx)
        ex.add_node(node)
        pub = node.create_publisher(String, "/shm_free/in", 10)
        node.create_subscription(String, "/shm_free/out", lambda m: heard.append(m.data), 10)
        peer = subprocess.Popen([sys.executable, "-c", PEER], env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        try:
            spin_until(ex, lambda: heard, 30, "a message from the shm-free peer")
            while peer.poll() is None:  # until the peer hears us
                pub.publish(String(data="from the probe"))
                ex.spin_once(timeout_sec=0.1)
        finally:
            if peer.poll() is None:
                peer.kill()
            out = peer.communicate(timeout=10)[0]
    assert peer.returncode == 0, out
    assert "heard ['from the probe'] shm []" in out, out
    assert heard[0] == "from the peer"
