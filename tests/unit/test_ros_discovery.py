"""Whom the server's ROS 2 participant talks to, from ROS 2's environment variables, --ros-network and
--ros-loopback (akarm.ros.dds.discovery), configured as rmw_cyclonedds_cpp configures a ROS 2 node
(akarm.ros.dds.ros2_config): pure logic, no participant is made here. Who then reaches whom is
tests/system/test_ros_discovery.py's."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

pytest.importorskip("cyclonedds")

from akarm.errors import ArgumentError
from akarm.ros.dds import LOOPBACK, LOOPBACK_CONFIG, discovery, ros2_config


def parsed(config: str | None) -> ET.Element:
    assert config is not None
    return ET.fromstring(config)


def peers(root: ET.Element) -> list[str | None]:
    return [p.get("address") for p in root.iter("Peer")]


def test_by_default_ros_2s_localhost_as_rmw_cyclonedds_configures_it():
    d = discovery({})
    assert (d.range, d.peers, d.network, d.warnings) == ("LOCALHOST", (), False, ())
    root = parsed(d.config)
    assert not list(root.iter("NetworkInterface"))  # the default interface is kept
    assert root.findtext(".//AllowMulticast") == "false"
    assert root.findtext(".//ParticipantIndex") == "auto" and root.findtext(".//MaxAutoParticipantIndex") == "32"
    assert peers(root) == ["localhost"]
    # and, beyond rmw_cyclonedds_cpp's fragment, it keeps pinging this host: a later SUBNET node finds it
    assert root.findtext(".//InitialLocatorPruneDelay") == "inf" and root.findtext(".//SPDPInterval") == "1 s"
    assert ros2_config("LOCALHOST") == d.config.replace("<InitialLocatorPruneDelay>inf</InitialLocatorPruneDelay>"
                                                        "<SPDPInterval>1 s</SPDPInterval>", "")
    assert "this machine (any ROS 2 discovery range" in d.describe()
    assert "--ros-loopback" in d.describe() and "--ros-network" in d.describe()


@pytest.mark.parametrize("env", [{"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, {"ROS_LOCALHOST_ONLY": "1"},
                                 {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_LOCALHOST_ONLY": "1"},
                                 {"ROS_AUTOMATIC_DISCOVERY_RANGE": ""}])
def test_ros_2s_own_ways_of_saying_localhost(env):
    d = discovery(env)
    assert d.range == "LOCALHOST" and d.config == discovery({}).config and not d.network


def test_ros_loopback_keeps_it_on_the_loopback_interface_whatever_else_is_set():
    d = discovery({}, loopback=True)
    assert (d.range, d.source, d.network, d.warnings) == (LOOPBACK, "--ros-loopback", False, ())
    root = parsed(d.config)
    assert [i.get("address") for i in root.iter("NetworkInterface")] == ["127.0.0.1"]
    assert root.findtext(".//AllowMulticast") == "false" and peers(root) == ["127.0.0.1"]
    assert d.config == LOOPBACK_CONFIG and "loopback" in d.describe()
    env = {"CYCLONEDDS_URI": "file:///etc/open.xml", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
           "ROS_STATIC_PEERS": "10.0.0.2"}
    d = discovery(env, loopback=True)
    assert d.config == LOOPBACK_CONFIG and d.peers == ()
    assert d.warnings == ("CYCLONEDDS_URI, ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS ignored with "
                          "--ros-loopback",)
    with pytest.raises(ArgumentError, match="--ros-network and --ros-loopback contradict"):
        discovery({}, network=True, loopback=True)


def test_subnet_and_ros_network_open_it_as_rmw_cyclonedds_does():
    for d in (discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}), discovery({}, network=True),
              discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, network=True)):
        root = parsed(d.config)
        assert d.range == "SUBNET" and d.network and root.findtext(".//AllowMulticast") is None  # multicast on
        # rmw_cyclonedds_cpp gives SUBNET a participant index: a LOCALHOST node on the host finds it there
        assert root.findtext(".//ParticipantIndex") == "auto" and root.findtext(".//MaxAutoParticipantIndex") == "32"
        assert peers(root) == []
    assert discovery({}, network=True).source == "--ros-network"


def test_static_peers_are_added_and_anything_else_in_them_is_refused():
    d = discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": "10.0.0.2; robot-b.local;;"
                   '"/><Peer address="evil'})
    assert d.peers == ("10.0.0.2", "robot-b.local") and len(d.warnings) == 1 and "ignored" in d.warnings[0]
    assert peers(parsed(d.config)) == ["10.0.0.2", "robot-b.local"]
    local = discovery({"ROS_STATIC_PEERS": "10.0.0.2"})  # LOCALHOST with peers: ROS 2's layout, default interface
    root = parsed(local.config)
    assert local.range == "LOCALHOST" and local.network and not list(root.iter("NetworkInterface"))
    assert peers(root) == ["localhost", "10.0.0.2"]
    assert root.findtext(".//AllowMulticast") == "false"
    only = discovery({"ROS_LOCALHOST_ONLY": "1", "ROS_STATIC_PEERS": "10.0.0.2"})  # as rcl: peers ignored
    assert only.peers == () and only.config == discovery({}).config and "ignored" in only.warnings[0]


def test_off_talks_to_no_one_and_system_default_leaves_cyclone_alone():
    off = discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF", "ROS_STATIC_PEERS": "10.0.0.2"})
    root = parsed(off.config)
    assert off.range == "OFF" and off.peers == () and not off.network
    assert root.findtext(".//AllowMulticast") == "false" and root.findtext(".//ParticipantIndex") == "none"
    assert root.findtext(".//Tag", "").startswith("akarm_discovery_off_")
    system = discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"})
    assert system.range == "SYSTEM_DEFAULT" and system.config is None and system.network


def test_an_unknown_range_is_said_and_taken_as_localhost():
    d = discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "everywhere"})
    assert d.range == "LOCALHOST" and d.config == discovery({}).config
    assert "'everywhere' is not one of LOCALHOST, SUBNET, OFF, SYSTEM_DEFAULT" in d.warnings[0]


def test_a_users_cyclonedds_uri_wins_over_everything_but_ros_loopback():
    for network in (False, True):
        d = discovery({"CYCLONEDDS_URI": "file:///etc/my-cyclone.xml", "ROS_LOCALHOST_ONLY": "1"}, network=network)
        assert d.range == "CYCLONEDDS_URI" and d.config is None and "CYCLONEDDS_URI" in d.describe()
