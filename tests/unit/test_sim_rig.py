"""SimulatedArm's choices before anything starts: default channels, a missing SocketCAN interface, an
unknown transport."""

from __future__ import annotations

import os

import pytest

from akarm import BusError, load_robot
from akarm.testing.rig import SimulatedArm, default_channel, missing_interfaces

from .conftest import ROBOTS

PLANAR2 = ROBOTS / "planar2.yaml"


def test_the_default_channels() -> None:
    planar2, biarm = load_robot(PLANAR2), load_robot(ROBOTS / "biarm.yaml")
    assert default_channel(planar2, "socketcan") == "vcan0"
    assert default_channel(biarm, "socketcan") == {"left": "vcan0", "right": "vcan1"}
    a, b = default_channel(planar2, "akarm_local"), default_channel(planar2, "akarm_local")
    assert a != b and str(os.getpid()) in a


def test_a_missing_socketcan_interface_is_named() -> None:
    config = load_robot(ROBOTS / "biarm.yaml").with_bus(interface="socketcan", channel={"left": "vcan8",
                                                                                        "right": "vcan9"})
    why = missing_interfaces(config)
    assert why is not None and "vcan8, vcan9" in why
    assert missing_interfaces(config.with_bus(interface="akarm_local")) is None
    with pytest.raises(BusError, match="vcan8, vcan9"):
        SimulatedArm.start(ROBOTS / "biarm.yaml", "socketcan", channel={"left": "vcan8", "right": "vcan9"})


def test_an_unknown_transport_is_refused() -> None:
    with pytest.raises(Exception, match="unknown transport 'pcan'"):
        SimulatedArm.start(PLANAR2, "pcan")
