"""A big run's simulator, group processes and recorder get Fast DDS shared memory sized to the run
(:func:`swarm_up.children.shm_sized_env`): the sizes, who gets them and when, and that Fast DDS
takes the profile (a peer with it maps a segment of the size asked for and talks to an ordinary
participant of the session's range)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from dataclasses import replace

import pytest
from std_msgs.msg import String

from swarm_up.children import (
    BUILTIN_TRANSPORTS_ENV,
    DISCOVERY_ENV,
    LOCALHOST_ONLY_ENV,
    PROFILES_ENV,
    RANGE_ENV,
    SHM_DEFAULTS,
    SHM_SIZED_ABOVE,
    STATIC_PEERS_ENV,
    child_specs,
    shm_profile_xml,
    shm_sized_env,
    shm_sizes,
)
from tests.support.ros import ros_context, spin_until
from tests.swarm_up.test_params_files import cfg  # noqa: F401 - the RunConfig fixture

NS = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"


def test_sizes_are_the_defaults_up_to_64_robots_then_grow_by_powers_of_two():
    assert shm_sizes(1) == shm_sizes(64) == SHM_DEFAULTS == (512 * 1024, 512)
    assert shm_sizes(101) == (1 << 20, 512)
    assert shm_sizes(1000) == (8 << 20, 4096)
    assert shm_sizes(1025) == (16 << 20, 8192)


def test_small_runs_and_runs_the_user_configured_keep_their_environment(tmp_path):
    profile = tmp_path / "p.xml"
    base = {RANGE_ENV: "SUBNET", "ROS_DOMAIN_ID": "3"}
    assert shm_sized_env(base, SHM_SIZED_ABOVE, profile) is base
    for key in (PROFILES_ENV, BUILTIN_TRANSPORTS_ENV, STATIC_PEERS_ENV, DISCOVERY_ENV):
        given = {**base, key: "set by the user"}
        assert shm_sized_env(given, 1000, profile) is given
    assert not profile.exists()


def test_a_big_run_gets_its_profile_and_localhost_becomes_loopback_udp(tmp_path):
    profile = tmp_path / "p.xml"
    env = shm_sized_env({RANGE_ENV: "SUBNET", "ROS_DOMAIN_ID": "3"}, 1000, profile)
    assert env == {RANGE_ENV: "SUBNET", "ROS_DOMAIN_ID": "3", PROFILES_ENV: str(profile)}
    shm = ET.parse(profile).getroot().find(f"{NS}transport_descriptors")
    assert [d.findtext(f"{NS}type") for d in shm] == ["SHM", "UDPv4"]
    assert (shm[0].findtext(f"{NS}segment_size"),
            shm[0].findtext(f"{NS}port_queue_capacity")) == (str(8 << 20), "4096")
    assert shm[1].find(f"{NS}interfaceWhiteList") is None
    env = shm_sized_env({LOCALHOST_ONLY_ENV: "1"}, 1000, profile)
    assert env == {RANGE_ENV: "SUBNET", LOCALHOST_ONLY_ENV: "0", PROFILES_ENV: str(profile)}
    udp = ET.parse(profile).getroot().find(f"{NS}transport_descriptors")[1]
    assert udp.findtext(f"{NS}interfaceWhiteList/{NS}address") == "127.0.0.1"


def test_only_the_simulator_and_the_group_processes_of_a_big_group_run_get_it(cfg):  # noqa: F811
    robots = tuple(f"Srobot{i}" for i in range(1, 202))
    (cfg.run_dir / "params").mkdir(parents=True)
    big = replace(cfg, robots=robots, groups=(robots[::2], robots[1::2]))

    def sized(run):
        return {s.name for s in child_specs(run)
                if s.env.get(PROFILES_ENV, "").endswith("fastdds_shm.xml")}

    if any(os.environ.get(k) for k in (PROFILES_ENV, BUILTIN_TRANSPORTS_ENV, STATIC_PEERS_ENV,
                                        DISCOVERY_ENV)):
        pytest.skip("the session's environment configures Fast DDS itself")
    assert sized(big) == {"sim", "group_1", "group_2"}
    assert sized(replace(big, robots=robots[:100], groups=(robots[:50], robots[50:100]))) == set()
    assert sized(replace(big, groups=None)) == set()  # per-robot processes: small bursts


PEER = textwrap.dedent("""
    import os, time
    import rclpy
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node("shm_sized_peer")
    heard = []
    node.create_subscription(String, "/shm_sized/in", lambda m: heard.append(m.data), 10)
    pub = node.create_publisher(String, "/shm_sized/out", 10)
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not heard:
        pub.publish(String(data="from the peer"))
        rclpy.spin_once(node, timeout_sec=0.1)
    maps = open(f"/proc/{os.getpid()}/maps").read().splitlines()
    shm = {line.split()[-1] for line in maps if "/dev/shm/fastrtps_" in line}
    biggest = max((os.path.getsize(f) for f in shm if os.path.exists(f)), default=0)
    print("heard", heard[:1], "biggest segment", biggest, flush=True)
    node.destroy_node()
    rclpy.shutdown()
""")


@pytest.mark.node
def test_fast_dds_takes_the_profile_and_the_peer_talks_to_ordinary_participants(tmp_path):
    # This test process is an ordinary participant of the session's range (LOCALHOST, default
    # shared memory); the peer runs as a big run's simulator or group process would.
    env = shm_sized_env(dict(os.environ), 1000, tmp_path / "fastdds_shm.xml")
    if PROFILES_ENV not in env:
        pytest.skip("the session's environment configures Fast DDS itself")
    heard = []
    with ros_context() as (ctx, ex):
        import rclpy

        node = rclpy.create_node("shm_sized_probe", context=ctx)
        ex.add_node(node)
        pub = node.create_publisher(String, "/shm_sized/in", 10)
        node.create_subscription(String, "/shm_sized/out", lambda m: heard.append(m.data), 10)
        peer = subprocess.Popen([sys.executable, "-c", PEER], env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        try:
            spin_until(ex, lambda: heard, 30, "a message from the peer")
            while peer.poll() is None:  # until the peer hears us
                pub.publish(String(data="from the probe"))
                ex.spin_once(timeout_sec=0.1)
        finally:
            if peer.poll() is None:
                peer.kill()
            out = peer.communicate(timeout=10)[0]
    assert peer.returncode == 0, out
    assert "heard ['from the probe']" in out, out
    biggest = int(out.split("biggest segment")[1].split()[0])
    assert biggest >= 8 << 20, out  # its own segment: 8 MB asked (plus Fast DDS's overhead)
    assert heard[0] == "from the peer"
    assert "<segment_size>8388608</segment_size>" in shm_profile_xml(8 << 20, 4096, True)
