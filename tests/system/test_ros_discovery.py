"""Who sees the served arm: ``akarm serve`` at its default (ROS 2's LOCALHOST range, as
rmw_cyclonedds_cpp configures it), with ``--ros-loopback`` and with ``--ros-network``, against ROS 2
participants each configured as rmw_cyclonedds_cpp configures a node of one discovery range
(``akarm.ros.dds.ros2_config``): SUBNET (ROS 2's default, ``ROS_AUTOMATIC_DISCOVERY_RANGE`` unset),
LOCALHOST, either with the server's host as a static peer (``ROS_STATIC_PEERS``), SYSTEM_DEFAULT
(Cyclone's own defaults) and akarm's loopback configuration. A participant "sees" the arm when it
receives ``joint_states`` and its call of ``akarm/enable`` succeeds (tests/system/ros_reach.py).
docs/ros2.md's table "Who sees the arm" is this test's.

Where it runs (nothing leaves this machine): two network namespaces made here, joined by a veth
pair and by nothing else (10.231.9.1 ↔ 10.231.9.2). The server's namespace is "this host": its
loopback, and the veth as its default (multicast-capable) interface; the other namespace is
"another host". A SUBNET participant's multicast goes out on the veth, so into the other namespace
alone: no DDS packet reaches this machine's own interfaces or the network. The simulator runs in
this namespace (akarm_local is shared memory, the server's control socket a file).

Needs root (``ip netns``, veth); skipped, saying why, where it cannot make the namespaces.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

pytest.importorskip("cyclonedds")

from akarm.ros.dds import LOOPBACK_CONFIG, ros2_config
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot
from .test_serve import Served, unique
from .test_serve_network import SERVER_IP, Namespaces, ros_env

pytestmark = pytest.mark.slow
REACH = Path(__file__).with_name("ros_reach.py")

#: the clients, each as rmw_cyclonedds_cpp configures a ROS 2 node (None: Cyclone's own defaults)
CLIENTS: dict[str, str | None] = {
    "SUBNET": ros2_config("SUBNET"),
    "LOCALHOST": ros2_config("LOCALHOST"),
    "SUBNET+peer": ros2_config("SUBNET", (SERVER_IP,)),
    "LOCALHOST+peer": ros2_config("LOCALHOST", (SERVER_IP,)),
    "SYSTEM_DEFAULT": ros2_config("SYSTEM_DEFAULT"),
    "loopback": LOOPBACK_CONFIG,
}

#: who sees the arm: (server flags) -> {(where, client): sees}; "host": the server's namespace
EXPECTED: dict[tuple[str, ...], dict[tuple[str, str], bool]] = {
    (): {("host", "SUBNET"): True, ("host", "LOCALHOST"): True, ("host", "SUBNET+peer"): True,
         ("host", "LOCALHOST+peer"): True, ("host", "SYSTEM_DEFAULT"): False, ("host", "loopback"): True,
         ("other", "SUBNET"): False, ("other", "LOCALHOST"): False, ("other", "SUBNET+peer"): True,
         ("other", "LOCALHOST+peer"): True},
    ("--ros-loopback",): {
        ("host", "SUBNET"): False, ("host", "LOCALHOST"): True, ("host", "SUBNET+peer"): False,
        ("host", "LOCALHOST+peer"): True, ("host", "SYSTEM_DEFAULT"): False, ("host", "loopback"): True,
        ("other", "SUBNET"): False, ("other", "LOCALHOST"): False, ("other", "SUBNET+peer"): False,
        ("other", "LOCALHOST+peer"): False},
    ("--ros-network",): {
        ("host", "SUBNET"): True, ("host", "LOCALHOST"): True, ("host", "SUBNET+peer"): True,
        ("host", "LOCALHOST+peer"): True, ("host", "SYSTEM_DEFAULT"): True, ("host", "loopback"): False,
        ("other", "SUBNET"): True, ("other", "LOCALHOST"): False, ("other", "SUBNET+peer"): True,
        ("other", "LOCALHOST+peer"): True},
}


@pytest.fixture(scope="module")
def namespaces() -> Iterator[Namespaces]:
    if os.geteuid() != 0 or subprocess.run(["which", "ip"], capture_output=True).returncode != 0:
        pytest.skip("network namespaces need root and the ip command (iproute2)")
    with Namespaces("d") as ns:
        yield ns


def reach(ns: Namespaces, where: str, domain: int, namespace: str, config: str | None, seconds: float) -> dict:
    """Run tests/system/ros_reach.py in namespace ``where`` with Cyclone DDS configured by ``config``."""
    env = ros_env(**({"CYCLONEDDS_URI": config} if config is not None else {}))
    out = subprocess.run([*ns.run(where), sys.executable, str(REACH), "--domain", str(domain), "--namespace",
                          namespace, "--seconds", str(seconds)], capture_output=True, text=True, timeout=120, env=env)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1])


@pytest.mark.parametrize("flags", list(EXPECTED), ids=["default", "ros-loopback", "ros-network"])
def test_who_sees_the_served_arm(namespaces: Namespaces, tmp_path: Path, flags: tuple[str, ...]):
    robot = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)
    channel, domain, namespace = unique("reach"), 100 + os.getpid() % 100, unique("reach")
    expected = EXPECTED[flags]
    with SimulatorProcess(robot, channel=channel, pose="down"), \
            Served(channel, namespace, robot, domain, args=list(flags), prefix=namespaces.run(namespaces.server),
                   env=ros_env()) as srv:
        started = time.monotonic()
        start = "".join(srv.lines)
        assert "ROS 2 reaches" in start, start
        where = {"host": namespaces.server, "other": namespaces.peer}

        def one(case: tuple[str, str]) -> dict:
            # a participant that should see it does in well under a second; one that should not gets 6 s
            seconds = 15.0 if expected[case] else 6.0
            return reach(namespaces, where[case[0]], domain, namespace, CLIENTS[case[1]], seconds)

        with ThreadPoolExecutor(4) as pool:
            seen = dict(zip(expected, pool.map(one, expected), strict=True))
        if not flags:  # a ROS 2 shell opened later: rmw_cyclonedds_cpp's LOCALHOST stops pinging after 30 s
            time.sleep(max(0.0, started + 32.0 - time.monotonic()))
            seen["host", "SUBNET, 32 s later"] = later = reach(namespaces, namespaces.server, domain, namespace,
                                                               CLIENTS["SUBNET"], 5.0)
            assert later["first"] is not None and later["first"] < 2.0, later  # it pings every second
            expected = {**expected, ("host", "SUBNET, 32 s later"): True}
    table = "\n".join(f"{w:5} {c:15} {s}" for (w, c), s in seen.items())
    for case, sees in expected.items():
        got = seen[case]
        if sees:
            assert got["joint_states"] >= 20 and got["enable"] is True, f"{case} should see it:\n{table}"
        else:
            assert got["joint_states"] == 0 and got["enable"] is None, f"{case} should not see it:\n{table}"
