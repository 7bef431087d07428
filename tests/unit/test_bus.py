"""Buses as python-can users configure them: keyword arguments passed through, python-can's own
configuration sources honoured (the YAML first), and errors specific to the cause."""

from __future__ import annotations

import errno
import os
import sys
import types
from pathlib import Path

import can
import pytest

from akarm import ArgumentError, BusError, ConfigError
from akarm.buses.bus import no_answer_hint, open_bus, open_error
from akarm.cli import main
from akarm.config import BusConfig, parse_channel
from akarm.config.canconfig import python_can_settings
from akarm.robotfile.load import load_robot

from .conftest import ROBOTS

URDF = (ROBOTS / "planar2.urdf").resolve()
BASE = f"""\
name: t
urdf: {URDF}
defaults:
  limits: {{velocity: 3.0, acceleration: 15.0, jerk: 150.0}}
  gains: {{kp: 20.0, kd: 1.0}}
joints:
  - {{name: shoulder, can_id: 1, motor: AK80-9}}
  - {{name: elbow, can_id: 2, motor: AK60-6}}
"""


def robot(tmp_path: Path, buses: str = "") -> Path:
    path = tmp_path / "robot.yaml"
    path.write_text(BASE + buses)
    return path


# ----------------------------------------------------------------------------- keyword arguments


def test_a_near_miss_of_a_bus_key_is_still_an_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load_robot(robot(tmp_path, "buses:\n  arm: {chanel: can0, receive_own_messages: true, 2x: 1}\n"))
    messages = [p.message for p in info.value.problems]
    assert any("unknown key 'chanel' (did you mean 'channel'?)" in m for m in messages)
    assert any("'receive_own_messages' is set by akarm" in m for m in messages)
    assert any("'2x' is not a keyword argument name" in m for m in messages)


def test_cli_bus_kwargs_are_added_and_an_interface_change_drops_the_files(tmp_path: Path) -> None:
    config = load_robot(robot(tmp_path, "buses:\n  arm: {interface: pcan, channel: PCAN_USBBUS1, device_id: 3}\n"))
    same = config.with_bus(options={"state": "PASSIVE"})
    assert same.buses["arm"].options == {"device_id": 3, "state": "PASSIVE"}
    # the simulator's virtual bus has no use for a PCAN device ID
    other = config.with_bus(interface="virtual", channel="x", options={"rx_queue_size": 8})
    assert other.buses["arm"].options == {"rx_queue_size": 8}


def test_a_channel_mapping_must_name_the_robots_buses(capsys: pytest.CaptureFixture[str]) -> None:
    """-c left=vcan0,rihgt=vcan1 used to leave 'right' on the file's channel (socketcan can1: a real arm),
    and a stray comma was a ValueError from dict()."""
    config = load_robot(ROBOTS / "biarm.yaml")
    with pytest.raises(ArgumentError, match=r"no bus named 'rihgt' on robot 'biarm' \(did you mean 'right'\?\)"):
        config.with_bus(channel={"left": "vcan0", "rihgt": "vcan1"})
    moved = config.with_bus(channel=parse_channel("left=vcan0, right=vcan1"))
    assert [b.channel for b in moved.buses.values()] == ["vcan0", "vcan1"]
    for text, message in (("left=revA,", "'' is not BUS=CHANNEL"), ("left=,right=x", "'left=' is not BUS=CHANNEL"),
                          ("left=a,left=b", "name bus 'left' twice")):
        with pytest.raises(ArgumentError, match=message):
            parse_channel(text)
    assert main(["check", str(ROBOTS / "biarm.yaml"), "-c", "left=vcan0,rihgt=vcan1"]) != 0
    assert "no bus named 'rihgt'" in capsys.readouterr().err


def test_bus_kwargs_on_the_command_line(tmp_path: Path, channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    path = str(robot(tmp_path))
    assert main(["check", path, "-i", "virtual", "-c", channel, "--bus-kwargs", "rx_queue_size=64",
                 "preserve_timestamps=True"]) == 0
    assert f"virtual:{channel} @ 1000 kbit/s rx_queue_size=64 preserve_timestamps=True" in capsys.readouterr().out
    with pytest.raises(SystemExit) as e:
        main(["check", path, "--bus-kwargs", "not-a-pair"])
    assert e.value.code == 2 and "'not-a-pair' is not KEY=VALUE" in capsys.readouterr().err


# ----------------------------------------------------------------------------- python-can's configuration


def test_environment_fills_what_the_yaml_leaves_out(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CAN_INTERFACE", "pcan")
    monkeypatch.setenv("CAN_CHANNEL", "PCAN_USBBUS2")
    monkeypatch.setenv("CAN_BITRATE", "500000")
    bus = load_robot(robot(tmp_path)).buses["arm"]  # no `buses:` at all
    assert (bus.interface, bus.channel, bus.bitrate) == ("pcan", "PCAN_USBBUS2", 500_000)
    assert bus.python_can == ("interface", "channel", "bitrate")
    # the YAML takes precedence, key by key
    bus = load_robot(robot(tmp_path, "buses:\n  arm: {interface: socketcan, channel: can1}\n")).buses["arm"]
    assert (bus.interface, bus.channel, bus.bitrate, bus.python_can) == ("socketcan", "can1", 500_000, ("bitrate",))
    # a bus's own variables (python-can's context: the bus name) before the general ones
    monkeypatch.setenv("CAN_CHANNEL_arm", "PCAN_USBBUS7")
    assert load_robot(robot(tmp_path)).buses["arm"].channel == "PCAN_USBBUS7"
    # and the command line before all
    assert load_robot(robot(tmp_path), interface="virtual", channel="x").buses["arm"].python_can == ("bitrate",)


def test_config_files_and_their_sections(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    conf = tmp_path / "can.conf"
    conf.write_text("[default]\ninterface = kvaser\nchannel = 0\nbitrate = 1000000\n\n"
                    "[aux]\ninterface = gs_usb\nchannel = can0\nindex = 1\n")
    monkeypatch.setattr(can.util, "CONFIG_FILES", [str(conf)])
    text = (BASE + "buses:\n  arm:\n  aux:\n").replace("motor: AK80-9}", "motor: AK80-9, bus: arm}").replace(
        "motor: AK60-6}", "motor: AK60-6, bus: aux}")
    path = tmp_path / "two.yaml"
    path.write_text(text)
    config = load_robot(path)
    arm, aux = config.buses["arm"], config.buses["aux"]
    assert (arm.interface, arm.channel, arm.bitrate) == ("kvaser", "0", 1_000_000)
    # section [aux] for bus aux, with an interface-specific keyword argument
    assert (aux.interface, aux.channel, aux.options) == ("gs_usb", "can0", {"index": 1})
    assert python_can_settings("aux")["index"] == 1


def test_a_bad_interface_from_python_can_configuration_says_where_it_came_from(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CAN_INTERFACE", "socketcann")
    with pytest.raises(ConfigError) as info:
        load_robot(robot(tmp_path))
    (p,) = info.value.problems
    assert "'socketcann' is not a python-can interface (did you mean 'socketcan'?)" in p.message
    assert "from python-can's configuration" in p.message
    monkeypatch.setenv("CAN_CONFIG", "{not json")
    with pytest.raises(ConfigError, match="python-can's configuration cannot be read"):
        load_robot(robot(tmp_path))


# ----------------------------------------------------------------------------- errors specific to the cause


def test_errno_97_means_no_can_in_this_kernel_not_a_link_to_bring_up() -> None:
    e = open_error(BusConfig("arm"), OSError(errno.EAFNOSUPPORT, "Address family not supported by protocol"))
    assert "this kernel has no CAN support" in str(e) and "modprobe can can_raw" in e.fix and "gs_usb" in e.fix
    assert "ip link set" not in str(e)


@pytest.mark.parametrize(("code", "channel", "fragment", "fix"), [
    (errno.ENODEV, "vcan3", "there is no such network interface", "sudo ip link add dev vcan3 type vcan"),
    (errno.ENODEV, "can1", "there is no such network interface", "sudo ip link set can1 up type can bitrate 1000000"),
    (errno.ENETDOWN, "can1", "the interface is down", "sudo ip link set can1 up type can bitrate 1000000"),
    (errno.EPERM, "can1", "not allowed", "permissions"),
])
def test_oserrors_by_errno(code: int, channel: str, fragment: str, fix: str) -> None:
    e = open_error(BusConfig("arm", channel=channel), OSError(code, "x"))
    assert fragment in e.what and fix in e.fix and f"'{channel}'" in e.what


def test_interface_problems() -> None:
    with pytest.raises(BusError) as info:
        open_bus(BusConfig("arm", "socketcann", "can0"))
    assert "'socketcann' is not a python-can interface (did you mean 'socketcan'?)" in str(info.value)
    missing = open_error(BusConfig("arm", "gs_usb", "x"), can.CanInterfaceNotImplementedError(
        "Cannot import module can.interfaces.gs_usb for CAN interface 'gs_usb': No module named 'usb'"))
    assert "cannot load what it needs" in missing.what and "pip install gs_usb" in missing.fix
    library = open_error(BusConfig("arm", "pcan", "PCAN_USBBUS1"), OSError("pcanbasic library not found."))
    assert "pcanbasic library not found" in library.what and "driver library" in library.fix
    wrong = open_error(BusConfig("arm", "kvaser", "0"), TypeError("__init__() got an unexpected keyword 'x'"))
    assert "does not take these arguments" in wrong.what and "--bus-kwargs" in wrong.fix


# ----------------------------------------------------------------------------- nothing answers


def test_no_answer_on_virtual_and_on_hardware() -> None:
    assert "only reaches buses of this same process" in no_answer_hint(BusConfig("arm", "virtual", "x"))
    hw = no_answer_hint(BusConfig("arm", "socketcan", "can0"))
    assert "powered" in hw and "akarm scan -i socketcan -c can0" in hw


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="SO_RCVBUF's doubling and limits are Linux's")
def test_a_socketcan_bus_gets_a_receive_queue_of_seconds_not_milliseconds() -> None:
    """grow_receive_buffer on a bus's socket (an AF_UNIX pair stands in for a CAN socket: the option is
    the same): the kernel grants twice the size asked, capped at rmem_max without CAP_NET_ADMIN."""
    import socket

    from akarm.buses.bus import RECEIVE_BUFFER, grow_receive_buffer

    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_DGRAM)
    with a, b:
        bus = types.SimpleNamespace(socket=a)
        before = a.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        granted = grow_receive_buffer(bus)
        assert granted == a.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        rmem_max = int(Path("/proc/sys/net/core/rmem_max").read_text())
        privileged = os.geteuid() == 0
        assert granted == 2 * (RECEIVE_BUFFER if privileged else min(RECEIVE_BUFFER, rmem_max)), (before, granted)
        assert granted > before or not privileged
    assert grow_receive_buffer(types.SimpleNamespace()) == 0  # a bus without a socket (virtual, a USB adapter)
