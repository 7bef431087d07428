"""Whom the server's ROS 2 participant talks to, from ROS 2's environment variables and --ros-network
(akarm.ros.dds.discovery): pure logic, no participant is made here."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

pytest.importorskip("cyclonedds")

from akarm.ros.dds import LOOPBACK_CONFIG, discovery


def parsed(config: str | None) -> ET.Element:
    assert config is not None
    return ET.fromstring(config)


def test_by_default_only_the_loopback_interface_without_multicast():
    d = discovery({})
    assert (d.range, d.peers, d.network, d.warnings) == ("LOCALHOST", (), False, ())
    root = parsed(d.config)
    assert [i.get("address") for i in root.iter("NetworkInterface")] == ["127.0.0.1"]
    assert root.findtext(".//AllowMulticast") == "false"
    assert [p.get("address") for p in root.iter("Peer")] == ["127.0.0.1"]
    assert d.config == LOOPBACK_CONFIG
    assert "loopback" in d.describe() and "--ros-network" in d.describe()


@pytest.mark.parametrize("env", [{"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, {"ROS_LOCALHOST_ONLY": "1"},
                                 {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_LOCALHOST_ONLY": "1"},
                                 {"ROS_AUTOMATIC_DISCOVERY_RANGE": ""}])
def test_ros_2s_own_ways_of_saying_this_machine_only(env):
    d = discovery(env)
    assert d.range == "LOCALHOST" and d.config == LOOPBACK_CONFIG and not d.network


def test_subnet_and_ros_network_open_it_with_cyclones_multicast_defaults():
    for d in (discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}), discovery({}, network=True),
              discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, network=True)):
        assert d.range == "SUBNET" and d.network and d.config is None  # Cyclone's defaults: multicast
    assert discovery({}, network=True).source == "--ros-network"


def test_static_peers_are_added_and_anything_else_in_them_is_refused():
    d = discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": "10.0.0.2; robot-b.local;;"
                   '"/><Peer address="evil'})
    assert d.peers == ("10.0.0.2", "robot-b.local") and len(d.warnings) == 1 and "ignored" in d.warnings[0]
    assert [p.get("address") for p in parsed(d.config).iter("Peer")] == ["10.0.0.2", "robot-b.local"]
    local = discovery({"ROS_STATIC_PEERS": "10.0.0.2"})  # LOCALHOST with peers: ROS 2's layout, default interface
    root = parsed(local.config)
    assert local.range == "LOCALHOST" and local.network and not list(root.iter("NetworkInterface"))
    assert [p.get("address") for p in root.iter("Peer")] == ["localhost", "10.0.0.2"]
    assert root.findtext(".//AllowMulticast") == "false"
    only = discovery({"ROS_LOCALHOST_ONLY": "1", "ROS_STATIC_PEERS": "10.0.0.2"})  # as rcl: peers ignored
    assert only.peers == () and only.config == LOOPBACK_CONFIG and "ignored" in only.warnings[0]


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
    assert d.range == "LOCALHOST" and d.config == LOOPBACK_CONFIG
    assert "'everywhere' is not one of LOCALHOST, SUBNET, OFF, SYSTEM_DEFAULT" in d.warnings[0]


def test_a_users_cyclonedds_uri_wins_over_everything():
    for network in (False, True):
        d = discovery({"CYCLONEDDS_URI": "file:///etc/my-cyclone.xml", "ROS_LOCALHOST_ONLY": "1"}, network=network)
        assert d.range == "CYCLONEDDS_URI" and d.config is None and "CYCLONEDDS_URI" in d.describe()
